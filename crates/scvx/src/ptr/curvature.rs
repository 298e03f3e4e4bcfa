//! The exact curvature in the subproblem's objective: the Lagrangian's Hessian at the
//! reference, weighted by the last subproblem's duals, one block per segment — the
//! dynamics' `Σ y_i ∇²x_prop,i` over `x_k, u_k, s_k, u_{k+1}` (the second-order adjoint,
//! [`crate::Dynamics::segment_hessian`]) and the nodal constraints' `Σ y_i ∇²g_i` at node k
//! (symbolic second derivatives).
//!
//! Sign convention (the subproblem's `A z + s = b`, `s ∈ K`, duals `y ∈ K*`, stationarity
//! `q + P z + Aᵀy = 0`): a dynamics row `A_k x_k + B⁻[u_k; s_k] + B⁺u_{k+1} − x_{k+1} + …`
//! is the linearization of `x_prop(z) − x_{k+1}`, its curvature `+y ∇²x_prop`; an inequality
//! row `∇g·Δz − ν ≤ −g(z̄)` is that of `g(z) − ν ≤ 0`, its curvature `+y ∇²g`; a ball's cone
//! row `s = g(z̄) + ∇g·Δz` has the Lagrangian term `−y·g(z)` and the curvature `−y ∇²g`.

use armature_symbolic::HessianWorkspace;

use crate::SegmentHessianWorkspace;

use super::psd::clip_below;
use super::*;

/// The least eigenvalue of a projected block, relative to the smallest trust-region weight in
/// it: the subproblem stays strictly convex in every direction.
const PSD_FLOOR: f64 = 0.1;

/// Where each segment's and each nodal evaluation block's Hessian lands in the element
/// blocks.
#[derive(Debug, Default)]
pub(super) struct ExactHessian {
    /// Per evaluation block (`g_offsets` order): its element (node) and, per lower-triangle
    /// Hessian nonzero of its function, the element-local `(a, b)` position.
    blocks: Vec<(usize, Vec<(usize, usize)>)>,
    /// Per segment, per entry of `z = [x_k | u_k | s_k | u_{k+1}]`: its element-local
    /// position (`None`: a column through which the segment is linear).
    pub(super) segments: Vec<Vec<Option<usize>>>,
    /// Per primal column: how many element blocks hold it (each takes that share of its
    /// trust-region weight into its block).
    holders: Vec<f64>,
    /// Per subproblem row: a dynamics or nodal row (its curvature is exact, so the quasi-Newton pairs
    /// leave it out). Empty when the exact curvature is off.
    pub(super) exact_rows: Vec<bool>,
}

/// Scratch of the exact curvature (allocated once per solve; empty when off).
#[derive(Debug, Default)]
pub(super) struct CurvatureScratch {
    /// Per element: the exact block at the reference (`d×d`, row-major).
    pub(super) exact: Vec<Vec<f64>>,
    /// Per element: the block the subproblem's `P` holds (quasi-Newton plus exact, projected
    /// onto the PSD cone) and whether there is one.
    pub(super) model: Vec<Vec<f64>>,
    pub(super) model_ready: Vec<bool>,
    /// Per nodal value (`g_offsets` layout): the weight of its Hessian.
    weights: Vec<f64>,
    hws: Vec<HessianWorkspace>,
    dynamics: Option<SegmentHessianWorkspace>,
    segment: Vec<f64>,
    input: Vec<f64>,
    values: Vec<f64>,
    hessian: Vec<f64>,
    eig_v: Vec<f64>,
    eig_l: Vec<f64>,
    /// Per column of a block: its share of the trust-region diagonal.
    shares: Vec<f64>,
    /// The interval constraints' peak rows' share.
    pub(super) peaks: super::peak_curvature::PeakCurvatureScratch,
    /// The peak rows' vertex curvature's.
    pub(super) envelope: super::peak_envelope::EnvelopeScratch,
}

impl ExactHessian {
    /// Adds each nodal constraint's Hessian columns to its node's element (columns sorted;
    /// the elements hold the columns through which each segment's dynamics are nonlinear)
    /// and records where each segment's and each nodal Hessian's entries go.
    pub(super) fn place(
        v: &VarLayout,
        ocp: &Ocp,
        eval_node: &[usize],
        nodal_rows: &[NodalRow],
        rows: usize,
        elements: &mut [Element],
    ) -> Self {
        let col = |k: usize, i: usize| if i < v.n { v.x(k, i) } else { v.u(k, i - v.n) };
        let blocks_of = || ocp.nodal.iter().flat_map(|c| c.nodes.iter().map(move |&k| (c, k)));
        for (c, k) in blocks_of() {
            let cols = &mut elements[k].cols;
            for (r, cc) in c.function.hessian_pattern().lower().entries() {
                for i in [r, cc] {
                    if !cols.contains(&col(k, i)) {
                        cols.push(col(k, i));
                    }
                }
            }
        }
        for el in elements.iter_mut() {
            el.cols.sort_unstable();
        }
        let blocks = blocks_of()
            .zip(eval_node)
            .map(|((c, k), &node)| {
                let cols = &elements[node].cols;
                let at = |i: usize| cols.binary_search(&col(k, i)).expect("placed above");
                let map = c.function.hessian_pattern().lower().entries();
                (node, map.map(|(r, cc)| (at(r), at(cc))).collect())
            })
            .collect();
        let segments = (0..v.nn - 1)
            .map(|k| {
                let cols = &elements[k].cols;
                let z = (0..v.n)
                    .map(|i| v.x(k, i))
                    .chain((0..v.m).map(|i| v.u(k, i)))
                    .chain(std::iter::once(v.s(k)))
                    .chain((0..v.m).map(|i| v.u(k + 1, i)));
                z.map(|c| cols.binary_search(&c).ok()).collect()
            })
            .collect();
        let mut exact_rows = vec![false; rows];
        exact_rows[..(v.nn - 1) * v.n].fill(true);
        for nr in nodal_rows {
            exact_rows[nr.row] = true;
        }
        let mut holders = vec![0.0; v.vp0];
        for el in elements.iter() {
            for &c in &el.cols {
                holders[c] += 1.0;
            }
        }
        ExactHessian { blocks, segments, holders, exact_rows }
    }
}

impl Ptr {
    /// The exact curvature's scratch (empty unless `exact_hessian`).
    pub(super) fn curvature_scratch(&self) -> CurvatureScratch {
        let square = |e: &Element| vec![0.0; e.cols.len() * e.cols.len()];
        let dmax = self.elements.iter().map(|e| e.cols.len()).max().unwrap_or(0);
        let mut scratch = CurvatureScratch {
            model: self.elements.iter().map(square).collect(),
            model_ready: vec![false; self.elements.len()],
            eig_v: vec![0.0; dmax * dmax],
            eig_l: vec![0.0; dmax],
            shares: vec![0.0; dmax],
            ..CurvatureScratch::default()
        };
        if self.settings.exact_hessian {
            let fs = || self.ocp.nodal.iter().map(|c| &c.function);
            let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
            scratch.exact = self.elements.iter().map(square).collect();
            scratch.weights = vec![0.0; self.g_len.0];
            scratch.hws = fs().map(|f| f.hessian_workspace()).collect();
            scratch.input = vec![0.0; n + m];
            scratch.values = vec![0.0; fs().map(|f| f.n_outputs()).max().unwrap_or(0)];
            scratch.hessian = vec![0.0; fs().map(|f| f.hessian_pattern().nnz()).max().unwrap_or(0)];
            scratch.dynamics = Some(self.ocp.dynamics.segment_hessian_workspace());
            scratch.segment = vec![0.0; (n + 2 * m + 1).pow(2)];
            scratch.peaks = self.peak_curvature_scratch();
            scratch.envelope = self.envelope_scratch();
        }
        scratch
    }

    /// `st.curv.exact`: each segment's dynamics curvature, then each node's nodal one, at
    /// the reference with the last subproblem's duals.
    pub(super) fn exact_curvature(&self, st: &mut Iterate) {
        for h in &mut st.curv.exact {
            h.fill(0.0);
        }
        self.dynamics_curvature(st);
        self.nodal_curvature(st);
        self.peak_curvature(st);
        self.peak_envelope_curvature(st);
    }

    /// Each segment's `yᵀ∇²x_prop` (its dynamics rows' duals) into its element block. A
    /// segment whose evaluation fails (a non-finite reference) contributes nothing.
    fn dynamics_curvature(&self, st: &mut Iterate) {
        let n = self.ocp.dynamics.n_x();
        let Some(ws) = st.curv.dynamics.as_mut() else { return };
        for (k, map) in self.exact.segments.iter().enumerate() {
            let y = &st.duals[k * n..(k + 1) * n];
            if y.iter().all(|&x| x == 0.0) {
                continue;
            }
            let h = &mut st.curv.segment;
            let dy = &self.ocp.dynamics;
            if dy.segment_hessian(&st.dbar, k, &st.ub, st.sb[k], y, ws, h).is_err()
                || h.iter().any(|x| !x.is_finite())
            {
                continue;
            }
            let (nz, d) = (map.len(), self.elements[k].cols.len());
            let block = &mut st.curv.exact[k];
            for (a, pa) in map.iter().enumerate() {
                for (b, pb) in map.iter().enumerate() {
                    if let (Some(pa), Some(pb)) = (pa, pb) {
                        block[pa * d + pb] += h[a * nz + b];
                    }
                }
            }
        }
    }

    /// Each node's `Σ ±y_i ∇²g_i` (see the module's sign convention) into its element
    /// block. A block whose evaluation fails contributes nothing.
    fn nodal_curvature(&self, st: &mut Iterate) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let cs = &mut st.curv;
        cs.weights.fill(0.0);
        for nr in &self.nodal_rows {
            let sign = if nr.cone { -1.0 } else { 1.0 };
            cs.weights[self.g_offsets[nr.eval].0 + nr.output] += sign * st.duals[nr.row];
        }
        for (e, &(ci, k)) in self.nodal_blocks.iter().enumerate() {
            let f = &self.ocp.nodal[ci].function;
            let (vo, nout, nnz) = (self.g_offsets[e].0, f.n_outputs(), f.hessian_pattern().nnz());
            let w = &cs.weights[vo..vo + nout];
            if w.iter().all(|&x| x == 0.0) {
                continue;
            }
            cs.input[..n].copy_from_slice(&st.xb[k * n..(k + 1) * n]);
            cs.input[n..].copy_from_slice(&st.ub[k * m..(k + 1) * m]);
            let (vals, h) = (&mut cs.values[..nout], &mut cs.hessian[..nnz]);
            if f.eval_hessian(&cs.input, w, &mut cs.hws[ci], vals, None, h).is_err()
                || h.iter().any(|x| !x.is_finite())
            {
                continue;
            }
            let (node, map) = &self.exact.blocks[e];
            let d = self.elements[*node].cols.len();
            let block = &mut cs.exact[*node];
            for (&(a, b), &x) in map.iter().zip(h.iter()) {
                block[a * d + b] += x;
                if a != b {
                    block[b * d + a] += x;
                }
            }
        }
    }

    /// The subproblem's curvature blocks `st.curv.model`: each element's quasi-Newton block
    /// (when ready) plus its exact block, convexified with the trust region when an exact
    /// part is in it (a BFGS block alone is positive definite already); added to `st.pvals`
    /// (which holds the trust-region diagonal).
    pub(super) fn fill_curvature(&self, st: &mut Iterate, qn: bool, exact: bool) {
        if exact {
            self.exact_curvature(st);
        }
        for (e, el) in self.elements.iter().enumerate() {
            let d = el.cols.len();
            let cs = &mut st.curv;
            let block = &mut cs.model[e];
            let with_qn = qn && st.hess_ready[e];
            cs.model_ready[e] = (with_qn || exact) && d > 0;
            if !cs.model_ready[e] {
                continue;
            }
            if with_qn {
                block.copy_from_slice(&st.hess[e]);
            } else {
                block.fill(0.0);
            }
            if exact {
                // `H + D` projected (D: the block's share of the trust-region diagonal), less
                // `D`: P = Σ proj(H_e + D_e) + the rest of the diagonal stays positive
                // semidefinite while an indefinite H keeps its negative curvature wherever
                // the trust region outweighs it.
                for (b, x) in block.iter_mut().zip(&cs.exact[e]) {
                    *b += x;
                }
                let shares = &mut cs.shares[..d];
                for (share, &c) in shares.iter_mut().zip(&el.cols) {
                    *share = 2.0 * st.lam_tr * st.inv_s2[c] / self.exact.holders[c];
                }
                for (a, share) in shares.iter().enumerate() {
                    block[a * d + a] += share;
                }
                let least = shares.iter().copied().fold(f64::INFINITY, f64::min);
                clip_below(block, d, PSD_FLOOR * least, &mut cs.eig_v, &mut cs.eig_l);
                for (a, share) in shares.iter().enumerate() {
                    block[a * d + a] -= share;
                }
            }
            for a in 0..d {
                for b in a..d {
                    st.pvals[el.pidx[a * d + b]] += block[a * d + b];
                }
            }
        }
    }
}
