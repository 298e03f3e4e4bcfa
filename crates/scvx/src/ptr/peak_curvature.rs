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
//! with the weights held fixed. Interval constraints read only the states (checked in
//! `start`), so their Hessian's state block is all there is.

use armature_symbolic::HessianWorkspace;

use super::*;

/// Scratch of the peak rows' curvature (allocated once per solve; empty when off).
#[derive(Debug, Default)]
pub(super) struct PeakCurvatureScratch {
    hws: Vec<HessianWorkspace>,
    input: Vec<f64>,
    weights: Vec<f64>,
    values: Vec<f64>,
    hessian: Vec<f64>,
    /// `∇²g_o` over the states (dense `n×n`) and the sensitivities `G` (`n × dz`, row-major),
    /// and `∇²g_o·G`.
    hx: Vec<f64>,
    g: Vec<f64>,
    hg: Vec<f64>,
    /// A row's `Σ w_i G_iᵀ∇²g_o G_i` over its stencil (`dz × dz`).
    sum: Vec<f64>,
}

impl Ptr {
    /// The peak rows' curvature scratch for this problem.
    pub(super) fn peak_curvature_scratch(&self) -> PeakCurvatureScratch {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let fs = || self.ocp.interval_constraints.iter().map(|c| &c.function);
        let dz = n + 2 * m + 1;
        PeakCurvatureScratch {
            hws: fs().map(|f| f.hessian_workspace()).collect(),
            input: vec![0.0; n + m],
            weights: vec![0.0; fs().map(|f| f.n_outputs()).max().unwrap_or(0)],
            values: vec![0.0; fs().map(|f| f.n_outputs()).max().unwrap_or(0)],
            hessian: vec![0.0; fs().map(|f| f.hessian_pattern().nnz()).max().unwrap_or(0)],
            hx: vec![0.0; n * n],
            g: vec![0.0; n * dz],
            hg: vec![0.0; n * dz],
            sum: vec![0.0; dz * dz],
        }
    }

    /// Each active interval-constraint peak row's `y·Σ w_i G_iᵀ∇²g_o G_i` at the reference (`st.dbar`'s
    /// grid) into its segment's block of `st.curv.exact`. A row whose evaluation fails
    /// contributes nothing.
    pub(super) fn peak_curvature(&self, st: &mut Iterate) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (stride, pts) = (self.ocp.dynamics.grid_stride(), st.dbar.grid_points);
        let dz = n + 2 * m + 1;
        for (i, p) in self.peaks.iter().enumerate() {
            let PeakOf::Function { c, out } = p.of else { continue };
            let y = st.duals[p.row];
            if y <= 0.0 || !y.is_finite() || !self.row_active(&st.ev, p) {
                continue;
            }
            let (first, w) = st.ev.stencils[i];
            st.curv.peaks.sum.fill(0.0);
            let points = w.iter().enumerate().filter(|(_, w)| **w != 0.0);
            let points = points.map(|(j, &wj)| (first + j, wj)).filter(|&(j, _)| j < pts);
            for (point, wj) in points {
                let base = (p.seg * pts + point) * stride;
                let grid = &st.dbar.grid[base..base + stride];
                self.add_point_curvature(c, out, y * wj, grid, &mut st.curv.peaks);
            }
            // Into the segment's block, over the entries the element holds.
            let sc = &st.curv.peaks;
            let (map, d) = (&self.exact.segments[p.seg], self.elements[p.seg].cols.len());
            let block = &mut st.curv.exact[p.seg];
            for (a, pa) in map.iter().enumerate() {
                let Some(pa) = pa else { continue };
                for (b, pb) in map.iter().enumerate() {
                    let Some(pb) = pb else { continue };
                    block[pa * d + pb] += sc.sum[a * dz + b];
                }
            }
        }
    }

    /// Adds `weight·Gᵀ∇²g_o G` at one grid point (its block `[x, Φ, B⁻, B⁺]`) to `sc.sum`
    /// (`dz × dz`); nothing when the evaluation fails.
    fn add_point_curvature(
        &self,
        c: usize,
        out: usize,
        weight: f64,
        grid: &[f64],
        sc: &mut PeakCurvatureScratch,
    ) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let dz = n + 2 * m + 1;
        let f = &self.ocp.interval_constraints[c].function;
        sc.input[..n].copy_from_slice(&grid[..n]);
        sc.input[n..].fill(0.0);
        let nout = f.n_outputs();
        sc.weights[..nout].fill(0.0);
        sc.weights[out] = weight;
        let nnz = f.hessian_pattern().nnz();
        let (vals, h) = (&mut sc.values[..nout], &mut sc.hessian[..nnz]);
        if f.eval_hessian(&sc.input, &sc.weights[..nout], &mut sc.hws[c], vals, None, h).is_err()
            || h.iter().any(|x| !x.is_finite())
        {
            return;
        }
        sc.hx.fill(0.0);
        for ((a, b), &x) in f.hessian_pattern().lower().entries().zip(h.iter()) {
            if a < n && b < n {
                sc.hx[a * n + b] += x;
                if a != b {
                    sc.hx[b * n + a] += x;
                }
            }
        }
        sensitivities(grid, n, m, &mut sc.g);
        // ∇²g·G, then Gᵀ(∇²g·G).
        for r in 0..n {
            for j in 0..dz {
                sc.hg[r * dz + j] = (0..n).map(|q| sc.hx[r * n + q] * sc.g[q * dz + j]).sum();
            }
        }
        for a in 0..dz {
            for b in 0..dz {
                sc.sum[a * dz + b] +=
                    (0..n).map(|r| sc.g[r * dz + a] * sc.hg[r * dz + b]).sum::<f64>();
            }
        }
    }
}

/// The sensitivities `G = ∂x(t_i)/∂[x_k | u_k | s_k | u_{k+1}]` (`n × (n + 2m + 1)`,
/// row-major) from a grid point's block `[x, Φ, B⁻, B⁺]`.
fn sensitivities(grid: &[f64], n: usize, m: usize, g: &mut [f64]) {
    let (mc, dz) = (m + 1, n + 2 * m + 1);
    let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * mc);
    for r in 0..n {
        let row = &mut g[r * dz..(r + 1) * dz];
        row[..n].copy_from_slice(&grid[phi0 + r * n..phi0 + (r + 1) * n]);
        row[n..n + mc].copy_from_slice(&grid[bm0 + r * mc..bm0 + (r + 1) * mc]);
        row[n + mc..].copy_from_slice(&grid[bp0 + r * mc..bp0 + r * mc + m]);
    }
}
