//! The curvature of a peak row's vertex: the second-order term that holding the parabola's
//! weights leaves out.
//!
//! A peak row bounds `ĝ = max_θ p(θ)·g` over its cell, with `g = (g(c−1), g(c), g(c+1))` the
//! constraint at three grid points and `p(θ)` the parabola's Lagrange weights
//! (`evaluate.rs`). Its linearization holds θ at the vertex (the envelope theorem: the
//! vertex's own motion is of second order), so it under-estimates `ĝ` after every step —
//! `ĝ` is a maximum of linear functions of `g`, convex — and a subproblem that rides the
//! bound ends each step over it between the grid points. Where the vertex lies strictly
//! inside its range, the second derivative of the maximum is
//!
//! ```text
//! ∇²_g ĝ = −p′(θ) p′(θ)ᵀ / (p″·g),   p′(θ) = (θ − ½, −2θ, θ + ½),   p″·g = g(c−1) − 2g(c) + g(c+1) < 0
//! ```
//!
//! (positive semidefinite, rank one), and through the grid's sensitivities the row adds
//! `y·a aᵀ / (−p″·g)` to its segment's block, `a = Σ_i p′_i ∇_z g(t_i)` and `y ≥ 0` its dual:
//! the Lagrangian's Hessian then holds the row's whole second derivative (with
//! `peak_curvature.rs`'s `y·Σ w_i G_iᵀ∇²g G_i`), as an SQP step needs to converge at second
//! order where the motion rides a limit between the grid points. Clamped vertices (a cell
//! edge) and convex parabolas add nothing; nor do the columns through which the segment is
//! linear (its block does not hold them — a state's own value at the segment's start, for
//! a bound on that state). The vertices and the interval constraints' Jacobians are the
//! reference's, from `fill_peaks` (which evaluates the Jacobians at all three of an interior
//! vertex's points).

use super::peak_curvature::sensitivities;
use super::*;

/// Scratch of the vertex curvature (allocated once per solve).
#[derive(Debug, Default)]
pub(super) struct EnvelopeScratch {
    /// The grid sensitivities `G` at one point (`n × dz`, row-major) and `a` (`dz`).
    g: Vec<f64>,
    a: Vec<f64>,
}

impl Ptr {
    /// The vertex curvature's scratch for this problem.
    pub(super) fn envelope_scratch(&self) -> EnvelopeScratch {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let dz = n + 2 * m + 1;
        EnvelopeScratch { g: vec![0.0; n * dz], a: vec![0.0; dz] }
    }

    /// Each peak row's vertex curvature `y·a aᵀ / (−p″·g)` at the reference into its
    /// segment's block of `st.curv.exact` (the columns the block holds). Rows with a zero
    /// dual, switched off, or whose vertex is not inside its range add nothing.
    pub(super) fn peak_envelope_curvature(&self, st: &mut Iterate) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let dz = n + 2 * m + 1;
        for (i, p) in self.peaks.iter().enumerate() {
            let y = st.duals[p.row];
            if y <= 0.0 || !y.is_finite() || !self.row_active(&st.ev, p) {
                continue;
            }
            let Some(v) = st.ev.vertices[i].filter(|v| v.interior) else { continue };
            let sc = &mut st.curv.envelope;
            if !self.envelope_gradient(p, v, (&st.dbar, &st.ev), sc) {
                continue;
            }
            let scale = y / -v.second_difference;
            let (map, d) = (&self.exact.segments[p.seg], self.elements[p.seg].cols.len());
            let block = &mut st.curv.exact[p.seg];
            for (ia, pa) in map.iter().enumerate().take(dz) {
                let Some(pa) = pa else { continue };
                for (ib, pb) in map.iter().enumerate().take(dz) {
                    let Some(pb) = pb else { continue };
                    block[pa * d + pb] += scale * sc.a[ia] * sc.a[ib];
                }
            }
        }
    }

    /// Peak row `p`'s `a = Σ_i p′_i(θ) ∇_z g(t_i)` over its vertex `v`'s three points into
    /// `sc.a`; whether it is finite.
    fn envelope_gradient(
        &self,
        p: &PeakRow,
        v: Vertex,
        (d, ev): (&Discretization, &NodalEval),
        sc: &mut EnvelopeScratch,
    ) -> bool {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (dz, stride, pts) = (n + 2 * m + 1, self.ocp.dynamics.grid_stride(), d.grid_points);
        let th = v.theta;
        sc.a.fill(0.0);
        for (k, w) in [th - 0.5, -2.0 * th, th + 0.5].into_iter().enumerate() {
            let point = v.centre - 1 + k;
            let base = (p.seg * pts + point) * stride;
            sensitivities(&d.grid[base..base + stride], n, m, &mut sc.g);
            match p.of {
                PeakOf::State(r) => {
                    for (a, g) in sc.a.iter_mut().zip(&sc.g[r * dz..(r + 1) * dz]) {
                        *a += w * p.sign * g;
                    }
                }
                PeakOf::Function { c, out } => {
                    let meta = &self.intervals[c];
                    let at = (p.seg - meta.first) * pts + point;
                    let jac = &ev.fjac[meta.jac0 + at * meta.nnz..][..meta.nnz];
                    for &(r, jq) in &meta.deps[out] {
                        for (a, g) in sc.a.iter_mut().zip(&sc.g[r * dz..(r + 1) * dz]) {
                            *a += w * jac[jq] * g;
                        }
                    }
                }
            }
        }
        sc.a.iter().all(|x| x.is_finite())
    }
}
