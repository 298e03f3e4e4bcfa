//! Judging a subproblem's step: its model terms, the merit at the candidate, backtracking
//! along the step, the exact-penalty prices, and the trust region's update — the part of an
//! iteration after the subproblem.

use super::*;

/// What the subproblem's solution says about its own step.
#[derive(Debug, Clone, Copy)]
struct StepModel {
    /// Σ|ν| over the virtual controls, and its price Σ λ_vc|ν|.
    j_vc: f64,
    vc_cost: f64,
    /// Σ max(0, ν_b) over the buffers, and its price.
    j_vb: f64,
    vb_cost: f64,
    /// ‖Δz‖²_S, the trust-region measure of the step.
    j_tr: f64,
    /// The quadratic model term ½ΔzᵀHΔz of the prediction (0 without quasi-Newton).
    quad: f64,
}

impl Iteration {
    /// The record of iteration `it` before its subproblem is solved (`feasibility`: its cost
    /// is dropped).
    pub(super) fn pending(it: usize, final_time: f64, lam_tr: f64, feasibility: bool) -> Iteration {
        Iteration {
            iteration: it,
            feasibility,
            accepted: false,
            cost: f64::NAN,
            j_tr: f64::NAN,
            j_vc: f64::NAN,
            j_vb: f64::NAN,
            max_defect: f64::NAN,
            max_violation: f64::NAN,
            final_time,
            rho: f64::NAN,
            predicted: f64::NAN,
            corrected: false,
            lam_tr,
            tr_gradient: f64::NAN,
            discretization_ms: 0.0,
            subproblem_ms: 0.0,
            subproblem_iterations: 0,
            subproblem_status: SubproblemStatus::SetupFailed,
            status: None,
        }
    }
}

impl Ptr {
    /// The subproblem's linear objective `q`: the time weight on the dilations, the final
    /// state's cost, and the prices of the virtual controls and buffers.
    pub(super) fn fill_objective(&self, st: &mut Iterate) {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let (_, s0, vp0, _) = self.layout();
        let dtau = 1.0 / (nn - 1) as f64;
        st.q.fill(0.0);
        if self.cost_on {
            for k in 0..nn - 1 {
                st.q[s0 + k] += self.ocp.time_weight * dtau;
            }
            for &(i, w) in &self.ocp.final_cost {
                st.q[(nn - 1) * n + i] += w;
            }
        }
        for (i, qi) in st.q.iter_mut().enumerate().skip(vp0) {
            *qi = if i < self.vb0 { st.lam_vc[(i - vp0) % n] } else { st.lam_vb[i - self.vb0] };
        }
    }

    /// Solves the subproblem into `st.sol_x`, once more without the quasi-Newton blocks if
    /// they made it fail; the subproblem's time goes into `record`.
    pub(super) fn solve_step(
        &mut self,
        st: &mut Iterate,
        set: &PtrSettings,
        record: &mut Iteration,
    ) -> Result<(), PtrStatus> {
        let t_sub = Instant::now();
        let mut outcome = self.solve_subproblem(st, &set.subproblem, record);
        if outcome.is_err() && st.curv.model_ready.iter().any(|&r| r) {
            // The curvature blocks made the subproblem too hard for both solvers (a badly
            // conditioned BFGS block): forget them and solve this iteration first-order.
            st.hess_ready.fill(false);
            self.fill_p(st, false, false);
            if let Some(native) = st.native.as_mut() {
                native.reset();
            }
            outcome = self.solve_subproblem(st, &set.subproblem, record);
        }
        record.subproblem_ms = t_sub.elapsed().as_secs_f64() * 1e3;
        st.timings.subproblem_ms += record.subproblem_ms;
        outcome
    }

    fn step_model(&self, st: &Iterate, z: &[f64], curved: bool) -> StepModel {
        let (n, nv, vb0) = (self.ocp.dynamics.n_x(), self.n_vars, self.vb0);
        let (_, _, vp0, _) = self.layout();
        let mut quad = 0.0;
        if curved {
            let blocks = st.curv.model.iter().zip(&st.curv.model_ready);
            for (el, (h, ready)) in self.elements.iter().zip(blocks) {
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
        StepModel {
            j_vc: z[vp0..vb0].iter().map(|v| v.abs()).sum(),
            vc_cost: z[vp0..vb0].iter().enumerate().map(|(i, v)| st.lam_vc[i % n] * v.abs()).sum(),
            j_vb: z[vb0..nv].iter().map(|v| v.max(0.0)).sum(),
            vb_cost: z[vb0..nv].iter().zip(&st.lam_vb).map(|(v, w)| w * v.max(0.0)).sum(),
            j_tr: (0..vp0).map(|i| z[i] * z[i] * st.inv_s2[i]).sum(),
            quad,
        }
    }

    /// Judges the step `z` of iteration `record`: merit, acceptance (with backtracking),
    /// prices, the new reference and trust region; the status if the solve ends here.
    pub(super) fn judge(
        &mut self,
        st: &mut Iterate,
        set: &PtrSettings,
        z: &[f64],
        mut record: Iteration,
    ) -> Result<(Iteration, Option<PtrStatus>), PtrError> {
        let (u0, _, vp0, _) = self.layout();
        let qn = set.quasi_newton;
        for i in 0..vp0 {
            st.zc[i] = st.zbar[i] + z[i];
        }
        let model = self.step_model(st, z, qn || set.exact_hessian);
        record.tr_gradient = (0..vp0)
            .map(|c| (2.0 * st.lam_tr * st.inv_s2[c].sqrt() * z[c]).abs())
            .fold(0.0, f64::max);
        // The duals price defects in the Lagrangian merit and weight the quasi-Newton pairs.
        if qn || set.exact_hessian || matches!(set.merit, Merit::Lagrangian { .. }) {
            st.duals.copy_from_slice(&st.sol_z);
        }
        let (m, ms) = self.evaluate(&st.zc, &mut st.dcand, &mut st.ev, (&st.lam_vc, &st.lam_vb))?;
        record.discretization_ms = ms;
        st.timings.discretization_ms += ms;
        let (mut jc, mut tfc, mut max_defect, mut max_violation) = m;
        let mut cost = self.cost(&st.zc[..u0], tfc);
        let phibar = st.jbar + merit_shift(set.merit, &st.dbar.defect, &st.duals, &st.lam_vc);
        let phi = jc + merit_shift(set.merit, &st.dcand.defect, &st.duals, &st.lam_vc);
        let predicted = phibar - (cost + model.vc_cost + model.vb_cost + model.quad);
        let mut rho = if predicted.abs() > 1e-14 { (phibar - phi) / predicted } else { 1.0 };
        let mut accept = match set.trust_region {
            TrustRegionUpdate::Constant => true,
            TrustRegionUpdate::Adaptive { eta } => rho >= eta[0] || predicted.abs() <= 1e-14,
        };
        let mut j_tr = model.j_tr;
        let mut corrected = false;
        if let (true, TrustRegionUpdate::Adaptive { eta }) =
            (set.second_order_correction, set.trust_region)
            && rho < eta[2]
            && predicted > 1e-14
            && let Some((m, r, jtr)) =
                self.correct(st, set, z, (phibar, predicted, rho, eta[0]), &mut record)?
        {
            (jc, tfc, max_defect, max_violation) = m;
            cost = self.cost(&st.zc[..u0], tfc);
            (rho, j_tr, accept, corrected) = (r, jtr, true, true);
        }
        let mut backtracked = false;
        if let (false, TrustRegionUpdate::Adaptive { eta }, true) =
            (accept, set.trust_region, set.backtracking)
            && let Some((m, r, alpha)) =
                self.backtrack(st, set, z, eta[0].max(1e-4), (phibar, predicted), &mut record)?
        {
            (jc, tfc, max_defect, max_violation) = m;
            cost = self.cost(&st.zc[..u0], tfc);
            rho = r;
            j_tr *= alpha * alpha;
            accept = true;
            backtracked = true;
        }
        record = Iteration {
            accepted: accept,
            cost,
            j_tr,
            j_vc: model.j_vc,
            j_vb: model.j_vb,
            max_defect,
            max_violation,
            final_time: tfc,
            rho,
            predicted,
            corrected,
            ..record
        };
        let repriced = self.reprice(st, set, z);
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
        let status = if accept {
            st.jbar = jc;
            self.take_step(st, set, &record, (backtracked, repriced))
        } else {
            self.refuse_step(st, set)
        };
        if status.is_some() {
            return Ok((record, status));
        }
        // The reference merit under the (possibly new) prices, so ρ stays consistent.
        if repriced {
            let prices = (&st.lam_vc[..], &st.lam_vb[..]);
            st.jbar = self
                .merit(&st.xb, &st.ub, &st.sb, &st.dbar, &mut st.ev, prices, GridAt::Reference)
                .0;
        }
        let done = record.iteration >= set.max_iterations;
        Ok((record, done.then_some(PtrStatus::MaxIterations)))
    }

    /// Backtracks along the step before paying for another subproblem: `z̄ + α·Δz` stays
    /// inside the (convex) constraints and the convex model predicts at least α·predicted.
    /// The first α ∈ {½, ¼} whose ratio reaches `least` and lowers the merit: its merit
    /// values, ratio and α (the candidate left in `st.zc`, `st.dcand`).
    fn backtrack(
        &mut self,
        st: &mut Iterate,
        set: &PtrSettings,
        z: &[f64],
        least: f64,
        (phibar, predicted): (f64, f64),
        record: &mut Iteration,
    ) -> Result<Option<(MeritValues, f64, f64)>, PtrError> {
        let (u0, s0, vp0, _) = self.layout();
        for alpha in [0.5, 0.25] {
            for i in 0..vp0 {
                st.zc[i] = st.zbar[i] + alpha * z[i];
            }
            let ms = self.propagate(&st.zc, &mut st.dcand)?;
            record.discretization_ms += ms;
            st.timings.discretization_ms += ms;
            // The constraint terms of the merit are nonnegative: a point whose cost and
            // priced defects alone fall short of the decrease asked for fails with them,
            // and its constraints are not evaluated (the same decisions, bit for bit).
            let (xc, uc, sc) = (&st.zc[..u0], &st.zc[u0..s0], &st.zc[s0..vp0]);
            let shift = merit_shift(set.merit, &st.dcand.defect, &st.duals, &st.lam_vc);
            let partial = self.cost(xc, self.final_time(sc))
                + self.defect_price(&st.dcand, &st.lam_vc)
                + shift;
            let prices = (&st.lam_vc[..], &st.lam_vb[..]);
            if predicted > 0.0 && (phibar - partial) / (alpha * predicted) < least {
                // (Debug builds check the bound against the whole merit.)
                debug_assert!({
                    let m = self.merit(xc, uc, sc, &st.dcand, &mut st.ev, prices, GridAt::Other);
                    let phi = m.0 + shift;
                    phi >= partial && (phibar - phi) / (alpha * predicted) < least
                });
                continue;
            }
            let m = self.merit(xc, uc, sc, &st.dcand, &mut st.ev, prices, GridAt::Other);
            let phi = m.0 + shift;
            let r = (phibar - phi) / (alpha * predicted);
            if r >= least && phi < phibar {
                return Ok(Some((m, r, alpha)));
            }
        }
        Ok(None)
    }

    /// Exact-penalty prices: the ℓ1 penalty is exact only above the constraint's multiplier,
    /// so a row whose subproblem bought virtual control (or a buffer) at this price is priced
    /// too low — double it. Nonlinear defects after a step are a curvature effect that
    /// shrinks with the step and does not raise prices (raising them there makes
    /// second-order defects dominate the merit and stalls the trust region: the Maratos
    /// effect). Whether any price moved.
    fn reprice(&self, st: &mut Iterate, set: &PtrSettings, z: &[f64]) -> bool {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let (_, _, vp0, _) = self.layout();
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
        for (w, v) in st.lam_vb.iter_mut().zip(&z[self.vb0..self.n_vars]) {
            if *v > set.eps_vb && *w < set.lam_vc_max {
                *w = (*w * 2.0).min(set.lam_vc_max);
                repriced = true;
            }
        }
        repriced
    }

    /// The accepted candidate becomes the reference; converged if the step was short and
    /// every constraint holds, otherwise the trust region adapts to the step's ratio.
    fn take_step(
        &self,
        st: &mut Iterate,
        set: &PtrSettings,
        record: &Iteration,
        (backtracked, repriced): (bool, bool),
    ) -> Option<PtrStatus> {
        let (u0, s0, vp0, _) = self.layout();
        st.xb.copy_from_slice(&st.zc[..u0]);
        st.ub.copy_from_slice(&st.zc[u0..s0]);
        st.sb.copy_from_slice(&st.zc[s0..vp0]);
        std::mem::swap(&mut st.dbar, &mut st.dcand);
        // The interval values were last evaluated at this candidate (its merit, or the
        // quasi-Newton update), and its full discretization's grid is the defects-only one's,
        // bit for bit: they are the new reference's.
        st.ev.fgrid_reference = true;
        st.linearized = false;
        st.tf = record.final_time;
        // A short accepted step: the published PTR's criterion. It does not certify
        // stationarity — the subproblem's optimality gives ‖∇L‖ ≈ 2λ_tr‖Δz‖_S, which a heavy
        // λ_tr keeps large while the step is short (see `quasi_newton`).
        let stationary = record.j_tr < set.eps_tr;
        // Nearly feasible with little left to gain by the model: polish with short steps.
        let flat = record.predicted.abs() < set.eps_flat * record.cost.abs().max(1.0)
            && record.max_defect < 1e3 * set.eps_defect
            && record.max_violation < 1e3 * set.eps_vb;
        if stationary && record.max_defect < set.eps_defect && record.max_violation < set.eps_vb {
            return Some(PtrStatus::Converged);
        }
        if let TrustRegionUpdate::Adaptive { eta } = set.trust_region {
            // Not while the step bought buffers or virtual control (its prices doubled): the
            // model is paying for violations then, not running out of gains, and a trust
            // region quadrupling each iteration outruns prices doubling — the steps grow too
            // short to repair a violation the subproblem keeps buying, up to λ_tr's cap (the
            // seed's tutorial statement stalled so 1.3e-6 over a waypoint's tolerance).
            if flat && !repriced {
                st.lam_tr = (st.lam_tr * 4.0).min(set.lam_tr_max);
            } else if backtracked || record.rho < eta[1] {
                st.lam_tr = (st.lam_tr * 2.0).min(set.lam_tr_max);
            } else if record.rho > eta[2] {
                st.lam_tr = (st.lam_tr * 0.5).max(set.lam_tr_min);
            }
        }
        None
    }

    /// A refused step: the trust region tightens, or the solve has stalled at its tightest.
    fn refuse_step(&self, st: &mut Iterate, set: &PtrSettings) -> Option<PtrStatus> {
        if st.lam_tr >= set.lam_tr_max {
            return Some(PtrStatus::Stalled);
        }
        st.lam_tr = (st.lam_tr * 2.0).min(set.lam_tr_max);
        None
    }
}
