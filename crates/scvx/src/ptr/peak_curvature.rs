//! The interval constraints' curvature in the subproblem: for each peak row `g_o(x(t_i)) ≤ 0`
//! at grid point `t_i` of segment `k`, its dual `y ≥ 0` times `Gᵀ∇²g_o G`, with
//! `G = ∂x(t_i)/∂[x_k | u_k | s_k | u_{k+1}]` the integration grid's sensitivities, into
//! segment k's element block.
//!
//! This is the Lagrangian's Hessian of the row less the term `∇g_o·∂²x(t_i)/∂z²` (the flow's
//! own curvature, weighted by the constraint's gradient). What it adds is the curvature of
//! `g` in the states, which the linear row alone misses: for an orientation range held as
//! `(‖log‖² − tol²)/(2 tol)` it is `≈ JᵀJ/tol` — at a 0.1° range, 600 times the angle's
//! own scale — and a subproblem without it predicts a step's change of orientation so badly
//! that the merit's ratio, and with it the trust region, collapses (BENCHMARKS.md).
//!
//! A row's value is a weighted sum over its stencil's grid points (a parabola's vertex, a
//! grid point's cubic margin: `evaluate.rs`), so its curvature is `y·Σ w_i G_iᵀ∇²g_o G_i`
//! with the weights held fixed. Rows share grid points (neighbouring stencils, several
//! outputs), so the weights are gathered per point and each point's Hessian, summed over
//! its constraints and outputs, is sandwiched once. Interval constraints read only the states (checked in
//! `start`), so their Hessian's state block is all there is.

use armature_symbolic::HessianWorkspace;

use super::*;

/// Scratch of the peak rows' curvature (allocated once per solve; empty when off).
#[derive(Debug, Default)]
pub(super) struct PeakCurvatureScratch {
    hws: Vec<HessianWorkspace>,
    input: Vec<f64>,
    values: Vec<f64>,
    hessian: Vec<f64>,
    /// Per interval constraint, grid point and output (laid out as `NodalEval::fgrid`): the
    /// rows' weights `Σ y·w_i` on that point's value.
    point_weights: Vec<f64>,
    /// The states in which some interval constraint is curved (its Hessian's state rows).
    curved: Vec<usize>,
    /// `Σ_c ∇²(w_c·g_c)` over the states at one grid point (dense `n×n`), the sensitivities
    /// `G` (`n × dz`, row-major), and `∇²g·G`.
    hx: Vec<f64>,
    g: Vec<f64>,
    hg: Vec<f64>,
    /// A segment's `Σ_i G_iᵀ H_i G_i` over its grid points (`dz × dz`, upper triangle).
    sum: Vec<f64>,
}

impl Ptr {
    /// The peak rows' curvature scratch for this problem.
    pub(super) fn peak_curvature_scratch(&self) -> PeakCurvatureScratch {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let fs = || self.ocp.interval_constraints.iter().map(|c| &c.function);
        let dz = n + 2 * m + 1;
        let mut curved: Vec<usize> = fs()
            .flat_map(|f| f.hessian_pattern().lower().entries().collect::<Vec<_>>())
            .flat_map(|(a, b)| [a, b])
            .filter(|&a| a < n)
            .collect();
        curved.sort_unstable();
        curved.dedup();
        let grid_values = self.intervals.iter().map(|i| i.val0 + i.points * i.nout).max();
        PeakCurvatureScratch {
            hws: fs().map(|f| f.hessian_workspace()).collect(),
            input: vec![0.0; n + m],
            values: vec![0.0; fs().map(|f| f.n_outputs()).max().unwrap_or(0)],
            hessian: vec![0.0; fs().map(|f| f.hessian_pattern().nnz()).max().unwrap_or(0)],
            point_weights: vec![0.0; grid_values.unwrap_or(0)],
            curved,
            hx: vec![0.0; n * n],
            g: vec![0.0; n * dz],
            hg: vec![0.0; n * dz],
            sum: vec![0.0; dz * dz],
        }
    }

    /// Each active interval-constraint peak row's `y·Σ w_i G_iᵀ∇²g_o G_i` at the reference
    /// (`st.dbar`'s grid) into its segment's block of `st.curv.exact`. The rows' weights are
    /// gathered per grid point first, so each point costs one Hessian evaluation per
    /// constraint and one product `GᵀHG` whatever the number of rows whose stencils cover it.
    /// A point whose evaluation fails contributes nothing of that constraint.
    pub(super) fn peak_curvature(&self, st: &mut Iterate) {
        let pts = st.dbar.grid_points;
        let sc = &mut st.curv.peaks;
        sc.point_weights.fill(0.0);
        for (i, p) in self.peaks.iter().enumerate() {
            let PeakOf::Function { c, out } = p.of else { continue };
            let y = st.duals[p.row];
            if y <= 0.0 || !y.is_finite() || !self.row_active(&st.ev, p) {
                continue;
            }
            let meta = &self.intervals[c];
            let (first, w) = st.ev.stencils[i];
            for (j, &wj) in w.iter().enumerate().filter(|(_, w)| **w != 0.0) {
                if first + j < pts {
                    let point = (p.seg - meta.first) * pts + first + j;
                    sc.point_weights[meta.val0 + point * meta.nout + out] += y * wj;
                }
            }
        }
        for seg in 0..self.ocp.nodes - 1 {
            if self.segment_peak_curvature(seg, pts, &st.dbar.grid, sc) {
                let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
                let dz = n + 2 * m + 1;
                let (map, d) = (&self.exact.segments[seg], self.elements[seg].cols.len());
                let block = &mut st.curv.exact[seg];
                for (a, pa) in map.iter().enumerate() {
                    let Some(pa) = pa else { continue };
                    for (b, pb) in map.iter().enumerate() {
                        let Some(pb) = pb else { continue };
                        block[pa * d + pb] += sc.sum[a.min(b) * dz + a.max(b)];
                    }
                }
            }
        }
    }

    /// Segment `seg`'s `Σ_i G_iᵀ H_i G_i` over its grid points into `sc.sum` (upper
    /// triangle), with `H_i = Σ_c ∇²(w_c·g_c)` at point `i` by the gathered weights; whether
    /// any point had weight.
    fn segment_peak_curvature(
        &self,
        seg: usize,
        pts: usize,
        grid: &[f64],
        sc: &mut PeakCurvatureScratch,
    ) -> bool {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (dz, stride) = (n + 2 * m + 1, self.ocp.dynamics.grid_stride());
        sc.sum.fill(0.0);
        let mut touched = false;
        for point in 0..pts {
            let base = (seg * pts + point) * stride;
            let at = &grid[base..base + stride];
            sc.hx.fill(0.0);
            let mut any = false;
            for (c, meta) in self.intervals.iter().enumerate() {
                if seg < meta.first || seg >= meta.last {
                    continue;
                }
                let w0 = meta.val0 + ((seg - meta.first) * pts + point) * meta.nout;
                any |= self.add_state_hessian(c, w0, at, sc);
            }
            if any {
                sensitivities(at, n, m, &mut sc.g);
                add_sandwich(sc, n, dz);
                touched = true;
            }
        }
        touched
    }

    /// Adds `∇²(w·g_c)` over the states at grid point `at` (its block `[x, Φ, B⁻, B⁺]`) to
    /// `sc.hx`, with the weights `sc.point_weights[w0..]`; whether it did (not when the
    /// weights are zero or the evaluation fails).
    fn add_state_hessian(
        &self,
        c: usize,
        w0: usize,
        at: &[f64],
        sc: &mut PeakCurvatureScratch,
    ) -> bool {
        let n = self.ocp.dynamics.n_x();
        let f = &self.ocp.interval_constraints[c].function;
        let nout = f.n_outputs();
        let weights = &sc.point_weights[w0..w0 + nout];
        if weights.iter().all(|&x| x == 0.0) {
            return false;
        }
        sc.input[..n].copy_from_slice(&at[..n]);
        sc.input[n..].fill(0.0);
        let nnz = f.hessian_pattern().nnz();
        let (vals, h) = (&mut sc.values[..nout], &mut sc.hessian[..nnz]);
        if f.eval_hessian(&sc.input, weights, &mut sc.hws[c], vals, None, h).is_err()
            || h.iter().any(|x| !x.is_finite())
        {
            return false;
        }
        for ((a, b), &x) in f.hessian_pattern().lower().entries().zip(h.iter()) {
            if a < n && b < n {
                sc.hx[a * n + b] += x;
                if a != b {
                    sc.hx[b * n + a] += x;
                }
            }
        }
        true
    }
}

/// `sc.sum += Gᵀ(hx·G)` (upper triangle), over the curved states only.
fn add_sandwich(sc: &mut PeakCurvatureScratch, n: usize, dz: usize) {
    let PeakCurvatureScratch { curved, hx, g, hg, sum, .. } = sc;
    for &r in curved.iter() {
        for j in 0..dz {
            hg[r * dz + j] = curved.iter().map(|&q| hx[r * n + q] * g[q * dz + j]).sum();
        }
    }
    for a in 0..dz {
        for b in a..dz {
            sum[a * dz + b] += curved.iter().map(|&r| g[r * dz + a] * hg[r * dz + b]).sum::<f64>();
        }
    }
}

/// The sensitivities `G = ∂x(t_i)/∂[x_k | u_k | s_k | u_{k+1}]` (`n × (n + 2m + 1)`,
/// row-major) from a grid point's block `[x, Φ, B⁻, B⁺]`.
pub(super) fn sensitivities(grid: &[f64], n: usize, m: usize, g: &mut [f64]) {
    let (mc, dz) = (m + 1, n + 2 * m + 1);
    let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * mc);
    for r in 0..n {
        let row = &mut g[r * dz..(r + 1) * dz];
        row[..n].copy_from_slice(&grid[phi0 + r * n..phi0 + (r + 1) * n]);
        row[n..n + mc].copy_from_slice(&grid[bm0 + r * mc..bm0 + (r + 1) * mc]);
        row[n + mc..].copy_from_slice(&grid[bp0 + r * mc..bp0 + r * mc + m]);
    }
}
