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
//! a bound on that state), nor the peak rows of a whole segment of an interval constraint
//! (`Sampling::Peak`), whose vertex would need the constraint at every grid point.

use armature_symbolic::Workspace;

use super::evaluate::vertex;
use super::peak_curvature::sensitivities;
use super::*;

/// Scratch of the vertex curvature (allocated once per solve).
#[derive(Debug, Default)]
pub(super) struct EnvelopeScratch {
    /// Per interval constraint, its evaluation workspace.
    ws: Vec<Workspace>,
    input: Vec<f64>,
    /// The three stencil points' values (`nout` each) and Jacobian nonzeros (`nnz` each).
    values: Vec<f64>,
    jac: Vec<f64>,
    /// The grid sensitivities `G` at one point (`n × dz`, row-major) and `a` (`dz`).
    g: Vec<f64>,
    a: Vec<f64>,
}

impl Ptr {
    /// The vertex curvature's scratch for this problem.
    pub(super) fn envelope_scratch(&self) -> EnvelopeScratch {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let fs = || self.ocp.interval_constraints.iter().map(|c| &c.function);
        let dz = n + 2 * m + 1;
        EnvelopeScratch {
            ws: fs().map(|f| f.workspace()).collect(),
            input: vec![0.0; n + m],
            values: vec![0.0; 3 * fs().map(|f| f.n_outputs()).max().unwrap_or(0)],
            jac: vec![0.0; 3 * fs().map(|f| f.jacobian_pattern().nnz()).max().unwrap_or(0)],
            g: vec![0.0; n * dz],
            a: vec![0.0; dz],
        }
    }

    /// Each peak row's vertex curvature `y·a aᵀ / (−p″·g)` at the reference into its
    /// segment's block of `st.curv.exact` (the columns the block holds). Rows with a zero
    /// dual, switched off, at a segment's peak of an interval constraint (its values would
    /// be needed at every grid point) or whose evaluation fails add nothing.
    pub(super) fn peak_envelope_curvature(&self, st: &mut Iterate) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (dz, pts) = (n + 2 * m + 1, st.dbar.grid_points);
        if pts < 3 {
            return;
        }
        for p in &self.peaks {
            let y = st.duals[p.row];
            if y <= 0.0 || !y.is_finite() || !self.row_active(&st.ev, p) {
                continue;
            }
            let Some(curv) = self.envelope_gradient(p, &st.dbar.grid, pts, &mut st.curv.envelope)
            else {
                continue;
            };
            let scale = y / -curv;
            let (map, d) = (&self.exact.segments[p.seg], self.elements[p.seg].cols.len());
            let block = &mut st.curv.exact[p.seg];
            let a = &st.curv.envelope.a;
            for (ia, pa) in map.iter().enumerate().take(dz) {
                let Some(pa) = pa else { continue };
                for (ib, pb) in map.iter().enumerate().take(dz) {
                    let Some(pb) = pb else { continue };
                    block[pa * d + pb] += scale * a[ia] * a[ib];
                }
            }
        }
    }

    /// Peak row `p`'s `a = Σ_i p′_i ∇_z g(t_i)` into `sc.a` and its parabola's second
    /// difference, where its vertex lies strictly inside its range; `None` otherwise.
    fn envelope_gradient(
        &self,
        p: &PeakRow,
        grid: &[f64],
        pts: usize,
        sc: &mut EnvelopeScratch,
    ) -> Option<f64> {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (dz, stride) = (n + 2 * m + 1, self.ocp.dynamics.grid_stride());
        let at = |j: usize| &grid[(p.seg * pts + j) * stride..(p.seg * pts + j + 1) * stride];
        let v = match p.of {
            PeakOf::State(r) => vertex(pts, p.at, &|j| p.sign * at(j)[r] - p.bound),
            PeakOf::Function { c, out } => {
                let j = p.at?;
                let centre = j.clamp(1, pts - 2);
                let f = &self.ocp.interval_constraints[c].function;
                let (nout, nnz) = (f.n_outputs(), f.jacobian_pattern().nnz());
                for k in 0..3 {
                    sc.input[..n].copy_from_slice(&at(centre - 1 + k)[..n]);
                    sc.input[n..].fill(0.0);
                    let vals = &mut sc.values[k * nout..(k + 1) * nout];
                    let jac = &mut sc.jac[k * nnz..(k + 1) * nnz];
                    f.eval(&sc.input, &mut sc.ws[c], vals, Some(jac)).ok()?;
                }
                let v = vertex(pts, Some(j), &|q| sc.values[(q + 1 - centre) * nout + out]);
                debug_assert_eq!(v.centre, centre);
                v
            }
        };
        if !v.interior || !v.second_difference.is_finite() {
            return None;
        }
        let th = v.theta;
        let dp = [th - 0.5, -2.0 * th, th + 0.5];
        sc.a.fill(0.0);
        for (k, w) in dp.into_iter().enumerate() {
            sensitivities(at(v.centre - 1 + k), n, m, &mut sc.g);
            match p.of {
                PeakOf::State(r) => {
                    for (a, g) in sc.a.iter_mut().zip(&sc.g[r * dz..(r + 1) * dz]) {
                        *a += w * p.sign * g;
                    }
                }
                PeakOf::Function { c, out } => {
                    let nnz = self.ocp.interval_constraints[c].function.jacobian_pattern().nnz();
                    let jac = &sc.jac[k * nnz..(k + 1) * nnz];
                    for &(r, jq) in &self.intervals[c].deps[out] {
                        for (a, g) in sc.a.iter_mut().zip(&sc.g[r * dz..(r + 1) * dz]) {
                            *a += w * jac[jq] * g;
                        }
                    }
                }
            }
        }
        sc.a.iter().all(|x| x.is_finite()).then_some(v.second_difference)
    }
}
