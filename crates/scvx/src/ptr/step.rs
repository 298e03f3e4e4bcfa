//! One PTR iteration: linearize, solve the subproblem, judge the step, update the trust region.

use super::*;

impl Ptr {
    /// The subproblem's constraint values at the reference: `A`'s values (`st.nz`) from the
    /// discretization, the nodal constraints' Jacobians and the peak rows, and the
    /// right-hand sides `st.b` in deviation form.
    pub(super) fn linearize_constraints(&self, st: &mut Iterate) {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let (u0, s0, vp0, _) = self.layout();
        self.eval_nodal(&st.xb, &st.ub, &mut st.ev, &st.lam_vb, true);
        self.fill_peaks(&st.dbar, &mut st.ev, GridAt::Reference);
        fill_values(&self.sources, &st.dbar, &st.ev, &st.ev.peak_vals, &mut st.nz);
        // Deviation form: the unknowns are Δz = z − z̄ (ν and buffers keep their values), so
        // the constant rows `A z ≤ b` become `A Δz ≤ b − A z̄`. The objective then carries no
        // λ_tr‖z̄‖² offset, which at large λ_tr would swamp Clarabel's relative gap tolerance.
        st.zbar[..u0].copy_from_slice(&st.xb);
        st.zbar[u0..s0].copy_from_slice(&st.ub);
        st.zbar[s0..vp0].copy_from_slice(&st.sb);
        st.b.copy_from_slice(&self.b);
        for c in 0..vp0 {
            for p in self.a_colptr[c]..self.a_colptr[c + 1] {
                st.b[self.a_rowval[p]] -= st.nz[p] * st.zbar[c];
            }
        }
        // Rows linearised at z̄ have their right-hand sides directly in deviation form:
        // dynamics `… = x̄_{k+1} − x_prop_k` (the defect), inequalities `∇g·Δz − ν ≤ −g(z̄)`,
        // cones `[r + ν; g(z̄) + ∇g·Δz]`.
        st.b[..(nn - 1) * n].copy_from_slice(&st.dbar.defect);
        for nr in &self.nodal_rows {
            let g = st.ev.values[self.g_offsets[nr.eval].0 + nr.output];
            st.b[nr.row] = if nr.cone { g } else { -g };
        }
        for (p, g) in self.peaks.iter().zip(&st.ev.peak_g) {
            st.b[p.row] = -g;
        }
        st.linearized = true;
    }

    /// One iteration from the linearized reference: solve the subproblem, judge its step,
    /// move the reference and the trust region, and say whether the solve ends.
    pub(super) fn step_in(&mut self, st: &mut Iterate) -> Result<Iteration, PtrError> {
        let it = st.history.len() + 1;
        // A copy (plain numbers, no allocation), so `self` stays free for the evaluations.
        let mut set = self.settings.clone();
        if !self.cost_on {
            // Polishing short steps is for an objective with little left to gain; without
            // one every prediction is "little", and the rule would freeze the steps.
            set.eps_flat = 0.0;
        }
        let set = &set;
        if !st.linearized {
            self.linearize_constraints(st);
        }
        self.fill_objective(st);
        self.fill_p(st, set.quasi_newton, set.exact_hessian);
        let mut record = Iteration::pending(it, st.tf, st.lam_tr, !self.cost_on);
        if let Err(status) = self.solve_step(st, set, &mut record) {
            return Ok(self.finish(st, record, status));
        }
        // The step, moved out of `st` for the rest of the iteration (no copy, no allocation).
        let z = std::mem::take(&mut st.sol_x);
        let judged = self.judge(st, set, &z, record);
        st.sol_x = z;
        match judged? {
            (record, Some(status)) => Ok(self.finish(st, record, status)),
            (record, None) => {
                st.history.push(record.clone());
                if locally_infeasible(&st.history, set) {
                    // Recorded again, with its status.
                    st.history.pop();
                    return Ok(self.finish(st, record, PtrStatus::LocallyInfeasible));
                }
                Ok(record)
            }
        }
    }

    /// Damped BFGS update (Powell) of each element's Hessian approximation from the last
    /// evaluated point `st.zc` (with `st.dcand` and `st.ev` at it) and the reference, with
    /// the last subproblem's duals: `y_e = (A_e(z) − A_e(z̄))ᵀ λ`.
    /// `P`'s values: the trust-region diagonal, plus the curvature blocks — the quasi-Newton
    /// blocks that are ready when `qn`, the exact nodal curvature when `exact`.
    pub(super) fn fill_p(&self, st: &mut Iterate, qn: bool, exact: bool) {
        st.pvals.fill(0.0);
        for (c, w) in st.inv_s2.iter().enumerate() {
            st.pvals[self.p_diag[c]] = 2.0 * st.lam_tr * w;
        }
        st.curv.model_ready.fill(false);
        if qn || exact {
            self.fill_curvature(st, qn, exact);
        }
    }

    /// Records the final iteration with its status.
    pub(super) fn finish(
        &self,
        st: &mut Iterate,
        mut record: Iteration,
        status: PtrStatus,
    ) -> Iteration {
        record.status = Some(status);
        st.status = Some(status);
        st.history.push(record.clone());
        record
    }
}

/// Whether the last [`infeasible_window`](PtrSettings::infeasible_window) iterations of
/// `history` all broke a constraint (their references: the accepted steps' candidates, the
/// last accepted one for a refused step) by about as much — the largest violation at most
/// twice the least — while neither the violation nor the final time made progress: the
/// second half's least violation is not 10 % below the first half's, and its least final
/// time not 0.1 % below. Violations are relative to their tolerances (`eps_vb`,
/// `eps_defect`). A walk that trades violations for time (the final time falling) or whose
/// violations still move by factors is not stuck.
pub(super) fn locally_infeasible(history: &[Iteration], set: &PtrSettings) -> bool {
    let w = set.infeasible_window;
    if w < 2 || history.len() < w {
        return false;
    }
    let first = history.len() - w;
    // The reference each record leaves: its own values when accepted, else the last
    // accepted one's (a refused candidate's violations are not the trajectory's).
    let mut reference = None;
    let mut violation = [f64::INFINITY; 2];
    let mut time = [f64::INFINITY; 2];
    let mut largest: f64 = 0.0;
    for (j, r) in history.iter().enumerate() {
        if r.accepted {
            let m = (r.max_violation / set.eps_vb).max(r.max_defect / set.eps_defect);
            reference = Some((m, r.final_time));
        }
        let Some(at) = j.checked_sub(first) else { continue };
        let Some((m, t)) = reference else { return false };
        if m.is_nan() || m <= 1.0 {
            return false;
        }
        let half = usize::from(at >= w / 2);
        violation[half] = violation[half].min(m);
        time[half] = time[half].min(t);
        largest = largest.max(m);
    }
    let pinned = largest <= 2.0 * violation[0].min(violation[1]);
    pinned && violation[1] >= 0.9 * violation[0] && time[1] >= time[0] * (1.0 - 1e-3)
}
