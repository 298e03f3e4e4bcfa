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

    pub(super) fn step_in(&mut self, st: &mut Iterate) -> Result<Iteration, PtrError> {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let (u0, s0, vp0, _) = self.layout();
        let nv = self.n_vars;
        let n_primal = vp0;
        let dtau = 1.0 / (nn - 1) as f64;
        let it = st.history.len() + 1;
        // A copy (plain numbers, no allocation), so `self` stays free for the evaluations.
        let set = &self.settings.clone();
        if !st.linearized {
            self.linearize_constraints(st);
        }
        st.q.fill(0.0);
        for k in 0..nn - 1 {
            st.q[s0 + k] += self.ocp.time_weight * dtau;
        }
        for &(i, w) in &self.ocp.final_cost {
            st.q[(nn - 1) * n + i] += w;
        }
        for (i, qi) in st.q.iter_mut().enumerate().skip(vp0) {
            *qi = if i < self.vb0 { st.lam_vc[(i - vp0) % n] } else { st.lam_vb[i - self.vb0] };
        }
        let qn = set.quasi_newton;
        self.fill_p(st, qn);
        let mut record = Iteration {
            iteration: it,
            accepted: false,
            cost: f64::NAN,
            j_tr: f64::NAN,
            j_vc: f64::NAN,
            j_vb: f64::NAN,
            max_defect: f64::NAN,
            max_violation: f64::NAN,
            final_time: st.tf,
            rho: f64::NAN,
            lam_tr: st.lam_tr,
            tr_gradient: f64::NAN,
            discretization_ms: 0.0,
            subproblem_ms: 0.0,
            subproblem_iterations: 0,
            subproblem_status: "SetupFailed",
            status: None,
        };
        let t_sub = Instant::now();
        let mut outcome = self.solve_subproblem(st, &set.subproblem, &mut record);
        if outcome.is_err() && qn && st.hess_ready.iter().any(|&r| r) {
            // The quasi-Newton blocks made the subproblem too hard for both solvers (a badly
            // conditioned BFGS block): forget them and solve this iteration first-order.
            st.hess_ready.fill(false);
            self.fill_p(st, false);
            if let Some(ipm) = st.ipm.as_mut() {
                ipm.reset();
            }
            outcome = self.solve_subproblem(st, &set.subproblem, &mut record);
        }
        record.subproblem_ms = t_sub.elapsed().as_secs_f64() * 1e3;
        st.timings.subproblem_ms += record.subproblem_ms;
        if let Err(status) = outcome {
            return Ok(self.finish(st, record, status));
        }
        let z = &st.sol_x;
        for i in 0..n_primal {
            st.zc[i] = st.zbar[i] + z[i];
        }
        let j_vc: f64 = z[vp0..self.vb0].iter().map(|v| v.abs()).sum();
        let vc_cost: f64 =
            z[vp0..self.vb0].iter().enumerate().map(|(i, v)| st.lam_vc[i % n] * v.abs()).sum();
        let j_vb: f64 = z[self.vb0..nv].iter().map(|v| v.max(0.0)).sum();
        let vb_cost: f64 =
            z[self.vb0..nv].iter().zip(&st.lam_vb).map(|(v, w)| w * v.max(0.0)).sum();
        let j_tr: f64 = (0..n_primal).map(|i| z[i] * z[i] * st.inv_s2[i]).sum();
        record.tr_gradient = (0..n_primal)
            .map(|c| (2.0 * st.lam_tr * st.inv_s2[c].sqrt() * z[c]).abs())
            .fold(0.0, f64::max);
        // The quadratic model term ½ΔzᵀHΔz of the prediction.
        let mut quad = 0.0;
        if qn {
            for ((el, h), ready) in self.elements.iter().zip(&st.hess).zip(&st.hess_ready) {
                if *ready {
                    let d = el.cols.len();
                    for a in 0..d {
                        for b in 0..d {
                            quad += 0.5 * z[el.cols[a]] * h[a * d + b] * z[el.cols[b]];
                        }
                    }
                }
            }
        }
        // The duals price defects in the Lagrangian merit and weight the quasi-Newton pairs.
        if qn || matches!(set.merit, Merit::Lagrangian { .. }) {
            st.duals.copy_from_slice(&st.sol_z);
        }
        let (m, ms) = self.evaluate(&st.zc, &mut st.dcand, &mut st.ev, (&st.lam_vc, &st.lam_vb))?;
        record.discretization_ms = ms;
        st.timings.discretization_ms += ms;
        let (mut jc, mut tfc, mut max_defect, mut max_violation) = m;
        let mut cost = self.cost(&st.zc[..u0], tfc);
        // The Lagrangian merit's shift of the ℓ1 merit (zero for the exact penalty).
        let (lam_vc, duals) = (&st.lam_vc, &st.duals);
        let adj = |d: &[f64]| -> f64 {
            let Merit::Lagrangian { sigma } = set.merit else { return 0.0 };
            lagrangian_shift(d, duals, lam_vc, sigma)
        };
        let phibar = st.jbar + adj(&st.dbar.defect);
        let phi = jc + adj(&st.dcand.defect);
        let predicted = phibar - (cost + vc_cost + vb_cost + quad);
        let mut rho = if predicted.abs() > 1e-14 { (phibar - phi) / predicted } else { 1.0 };
        let mut accept = match set.trust_region {
            TrustRegionUpdate::Constant => true,
            TrustRegionUpdate::Adaptive { eta } => rho >= eta[0] || predicted.abs() <= 1e-14,
        };
        let mut j_tr = j_tr;
        let mut backtracked = false;
        if let (false, TrustRegionUpdate::Adaptive { eta }, true) =
            (accept, set.trust_region, set.backtracking)
        {
            // Backtrack along the step before paying for another subproblem: z̄ + α·Δz stays
            // inside the (convex) constraints; the convex model predicts at least α·predicted.
            let least = eta[0].max(1e-4);
            for alpha in [0.5, 0.25] {
                for i in 0..n_primal {
                    st.zc[i] = st.zbar[i] + alpha * z[i];
                }
                let ms = self.propagate(&st.zc, &mut st.dcand)?;
                record.discretization_ms += ms;
                st.timings.discretization_ms += ms;
                // The constraint terms of the merit are nonnegative: a point whose cost and
                // priced defects alone fall short of the decrease asked for fails with them,
                // and its constraints are not evaluated (the same decisions, bit for bit).
                let (xc, uc, sc) = (&st.zc[..u0], &st.zc[u0..s0], &st.zc[s0..vp0]);
                let partial = self.cost(xc, self.final_time(sc))
                    + self.defect_price(&st.dcand, &st.lam_vc)
                    + adj(&st.dcand.defect);
                let prices = (&st.lam_vc[..], &st.lam_vb[..]);
                if predicted > 0.0 && (phibar - partial) / (alpha * predicted) < least {
                    // (Debug builds check the bound against the whole merit.)
                    debug_assert!({
                        let m =
                            self.merit(xc, uc, sc, &st.dcand, &mut st.ev, prices, GridAt::Other);
                        let phi = m.0 + adj(&st.dcand.defect);
                        phi >= partial && (phibar - phi) / (alpha * predicted) < least
                    });
                    continue;
                }
                let m = self.merit(xc, uc, sc, &st.dcand, &mut st.ev, prices, GridAt::Other);
                let phi = m.0 + adj(&st.dcand.defect);
                let r = (phibar - phi) / (alpha * predicted);
                if r >= least && phi < phibar {
                    (jc, tfc, max_defect, max_violation) = m;
                    cost = self.cost(&st.zc[..u0], tfc);
                    rho = r;
                    j_tr *= alpha * alpha;
                    accept = true;
                    backtracked = true;
                    break;
                }
            }
        }
        record = Iteration {
            accepted: accept,
            cost,
            j_tr,
            j_vc,
            j_vb,
            max_defect,
            max_violation,
            final_time: tfc,
            rho,
            ..record
        };
        // Exact-penalty prices: the ℓ1 penalty is exact only above the constraint's
        // multiplier, so a row whose subproblem bought virtual control (or a buffer) at this
        // price is priced too low — double it. Nonlinear defects after a step are a curvature
        // effect that shrinks with the step and does not raise prices (raising them there
        // makes second-order defects dominate the merit and stalls the trust region: the
        // Maratos effect).
        let mut repriced = false;
        let nseg = (nn - 1) * n;
        for r in 0..n {
            let used = (0..nn - 1)
                .map(|k| z[vp0 + k * n + r] + z[vp0 + nseg + k * n + r])
                .fold(0.0, f64::max);
            if used > set.eps_defect && st.lam_vc[r] < set.lam_vc_max {
                st.lam_vc[r] = (st.lam_vc[r] * 2.0).min(set.lam_vc_max);
                repriced = true;
            }
        }
        for (w, v) in st.lam_vb.iter_mut().zip(&z[self.vb0..nv]) {
            if *v > set.eps_vb && *w < set.lam_vc_max {
                *w = (*w * 2.0).min(set.lam_vc_max);
                repriced = true;
            }
        }
        // Candidates were priced from their defects alone; the point that becomes the
        // reference (or feeds the quasi-Newton pair) needs its transition matrices.
        if accept || qn {
            let ms = self.linearize(&st.zc, &mut st.dcand)?;
            record.discretization_ms += ms;
            st.timings.discretization_ms += ms;
        }
        if qn {
            self.update_hessian(st);
        }
        if accept {
            st.xb.copy_from_slice(&st.zc[..u0]);
            st.ub.copy_from_slice(&st.zc[u0..s0]);
            st.sb.copy_from_slice(&st.zc[s0..vp0]);
            std::mem::swap(&mut st.dbar, &mut st.dcand);
            // The interval values were last evaluated at this candidate (its merit, or the
            // quasi-Newton update), and its full discretization's grid is the defects-only
            // one's, bit for bit: they are the new reference's.
            st.ev.fgrid_reference = true;
            st.linearized = false;
            (st.jbar, st.tf) = (jc, tfc);
            // A short accepted step: the published PTR's criterion. It does not certify
            // stationarity — the subproblem's optimality gives ‖∇L‖ ≈ 2λ_tr‖Δz‖_S, which a
            // heavy λ_tr keeps large while the step is short (see `quasi_newton`).
            let stationary = j_tr < set.eps_tr;
            if stationary && max_defect < set.eps_defect && max_violation < set.eps_vb {
                return Ok(self.finish(st, record, PtrStatus::Converged));
            }
            if let TrustRegionUpdate::Adaptive { eta } = set.trust_region {
                if backtracked || rho < eta[1] {
                    st.lam_tr = (st.lam_tr * 2.0).min(set.lam_tr_max);
                } else if rho > eta[2] {
                    st.lam_tr = (st.lam_tr * 0.5).max(set.lam_tr_min);
                }
            }
        } else {
            if st.lam_tr >= set.lam_tr_max {
                return Ok(self.finish(st, record, PtrStatus::Stalled));
            }
            st.lam_tr = (st.lam_tr * 2.0).min(set.lam_tr_max);
        }
        // The reference merit under the (possibly new) prices, so ρ stays consistent.
        if repriced {
            st.jbar = self
                .merit(
                    &st.xb,
                    &st.ub,
                    &st.sb,
                    &st.dbar,
                    &mut st.ev,
                    (&st.lam_vc, &st.lam_vb),
                    GridAt::Reference,
                )
                .0;
        }
        if it >= set.max_iterations {
            return Ok(self.finish(st, record, PtrStatus::MaxIterations));
        }
        st.history.push(record.clone());
        Ok(record)
    }

    /// Damped BFGS update (Powell) of each element's Hessian approximation from the last
    /// evaluated point `st.zc` (with `st.dcand` and `st.ev` at it) and the reference, with
    /// the last subproblem's duals: `y_e = (A_e(z) − A_e(z̄))ᵀ λ`.
    /// `P`'s values: the trust-region diagonal, plus the quasi-Newton blocks that are ready
    /// when `qn`.
    pub(super) fn fill_p(&self, st: &mut Iterate, qn: bool) {
        st.pvals.fill(0.0);
        for (c, w) in st.inv_s2.iter().enumerate() {
            st.pvals[self.p_diag[c]] = 2.0 * st.lam_tr * w;
        }
        if !qn {
            return;
        }
        for ((el, h), ready) in self.elements.iter().zip(&st.hess).zip(&st.hess_ready) {
            if !*ready {
                continue;
            }
            let d = el.cols.len();
            for a in 0..d {
                for b in a..d {
                    st.pvals[el.pidx[a * d + b]] += h[a * d + b];
                }
            }
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
