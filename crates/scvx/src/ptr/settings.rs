//! Settings of the PTR loop and of its convex subproblems, with their validation.

use schemars::JsonSchema;
use serde::Deserialize;

use super::*;

/// PTR settings with documented defaults, deserializable from data (every field optional,
/// unknown keys refused).
///
/// # Example
/// ```
/// use armature_scvx::{Merit, PtrSettings};
///
/// let mut settings = PtrSettings::default();
/// settings.quasi_newton = true;
/// settings.merit = Merit::Lagrangian { sigma: 0.5 };
/// assert!(settings.validate().is_ok());
///
/// // The same settings as data (any serde format; TOML in the CLI's `[settings]`).
/// let json = r#"{ "quasi_newton": true, "merit": { "lagrangian": { "sigma": 0.5 } } }"#;
/// let parsed: PtrSettings = serde_json::from_str(json).unwrap();
/// assert_eq!(parsed, settings);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
#[non_exhaustive]
pub struct PtrSettings {
    /// Initial trust-region weight λ_tr. Default 1.
    pub lam_tr: f64,
    /// Bounds of λ_tr. Default [1e-4, 1e6].
    pub lam_tr_min: f64,
    /// Bounds of λ_tr.
    pub lam_tr_max: f64,
    /// Cap of the per-row virtual-control and buffer weights. Default 1e6.
    pub lam_vc_max: f64,
    /// Initial virtual-buffer weight λ_vb of nodal constraints, relative to the time weight
    /// (per buffer; doubles when the subproblem buys that buffer, up to `lam_vc_max`).
    /// Default 0.3.
    pub lam_vb: f64,
    /// Convergence: largest nodal violation. Default 1e-6.
    pub eps_vb: f64,
    /// Initial virtual-control weight λ_vc per state row (exact-penalty weight: it must
    /// exceed the dynamics multipliers, and doubles when the subproblem buys virtual control;
    /// a heavier start makes the merit dominated by second-order defects and slows the trust
    /// region — 0.3 suits a time weight of 1 on the seed problem). Default 0.3.
    pub lam_vc: f64,
    /// Convergence: `‖Δz‖²` (scaled) of an accepted step. Default 1e-5 (OpenSCvx's
    /// `ep_tr` is 1e-4; the measurements behind the default are in the crate's
    /// BENCHMARKS.md).
    pub eps_tr: f64,
    /// Convergence: largest nonlinear defect. Default 1e-6.
    pub eps_defect: f64,
    /// Polishing: with [`TrustRegionUpdate::Adaptive`], an accepted step whose predicted
    /// merit decrease is below `eps_flat·max(1, |cost|)`, at a candidate within 1000× the
    /// defect and violation tolerances, quadruples λ_tr. Where the model
    /// sees that little left to gain, long steps only trade second-order defects for ever
    /// smaller gains (a redundant arm's self-motion is such a flat valley: without this rule
    /// the seed arm creeps 1e-4 s per iteration to the iteration cap); short steps repair the
    /// defects instead, and the solve converges by `eps_tr`, `eps_defect` and `eps_vb`. 0
    /// turns it off; so does a dropped cost ([`Ptr::restore_feasibility_only`]). Default
    /// 3e-3 (chosen on the benchmark suite, BENCHMARKS.md).
    pub eps_flat: f64,
    /// How the trust-region weight evolves. Default `Adaptive { eta: [0, 0.1, 0.5] }`.
    pub trust_region: TrustRegionUpdate,
    /// Iteration cap. Default 200 (OpenSCvx's `k_max`).
    pub max_iterations: usize,
    /// Iterations over which a solve whose constraints stay violated must make progress on
    /// them: when every reference of the last `infeasible_window` iterations breaks a
    /// constraint (by more than `eps_vb`, or a defect by more than `eps_defect`) and the least
    /// violation of the window's second half is not 10 % below that of its first half, the
    /// solve stops as [`PtrStatus::LocallyInfeasible`](crate::PtrStatus::LocallyInfeasible):
    /// the exact penalty is stationary where a constraint is violated (its linearizations
    /// conflict with the others' near this trajectory; another initial guess may not). 0 turns
    /// the test off. Default 16 (BENCHMARKS.md: no solve of the benchmark suite that
    /// converges comes near it; solves stuck a few millimetres off a waypoint stop after
    /// 16 iterations of it instead of running to the cap).
    pub infeasible_window: usize,
    /// Integrator settings.
    pub discretization: DiscretizationSettings,
    /// Settings of the convex subproblems' solvers.
    pub subproblem: SubproblemSettings,
    /// Time step of the dense trajectory in the result (s), 1e-6 to 1. Default 0.01. The
    /// dense checks between the nodes sample at most [`crate::DENSE_CHECK_DT`] apart
    /// whatever this is.
    pub dense_dt: f64,
    /// Largest violation of a continuous-time constraint on the dense trajectory that a
    /// converged solve may keep (in the constraint's units; default 1e-4), and of a nodal
    /// constraint or a fixed final value on the re-integrated motion: above it the named
    /// layer reports [`PtrStatus::ViolatedBetweenNodes`].
    pub dense_tolerance: f64,
    /// With [`TrustRegionUpdate::Adaptive`]: before rejecting a step, try it scaled by ½ and
    /// ¼ (each costs a discretization, not a subproblem); a scaled step is accepted when its
    /// ρ against the scaled prediction passes η₀ and the merit decreases, and λ_tr then
    /// doubles. On the seed arm this cuts the iterations by 20–35 %. Default true.
    pub backtracking: bool,
    /// Add a partitioned quasi-Newton (damped BFGS) model of the Lagrangian's Hessian to the
    /// subproblem's objective: one dense block per segment over the columns through which
    /// its dynamics and nodal constraints are nonlinear, updated from the change of the
    /// constraint Jacobians weighted by the subproblem's duals. With
    /// [`Merit::Lagrangian`] it reaches markedly lower final times on the seed arm (a
    /// first-order PTR stops where its trust region keeps the steps short, not at a
    /// stationary point), at about 1.5× the cost per subproblem and more iterations.
    /// Default false.
    pub quasi_newton: bool,
    /// Add the exact Hessian of the Lagrangian to the subproblem's objective, one block per
    /// segment, projected onto the positive-semidefinite cone (eigenvalues clipped at zero):
    /// the dynamics' `Σ y_i ∇²x_prop,i` over the segment's `x_k, u_k, s_k, u_{k+1}` (the
    /// second-order adjoint on the integration grid, [`crate::Dynamics::segment_hessian`])
    /// and the nodal constraints' `Σ y_i ∇²g_i` (symbolic second derivatives), both weighted
    /// by the last subproblem's duals `y` at the reference. A first-order subproblem cannot
    /// see that its step leaves a curved constraint at second order (a 7-joint arm's
    /// configurations that hold a pose form a curve; the dilation multiplies the controls),
    /// so the merit rejects its long steps and the trust region stops it short of the
    /// optimum. With `quasi_newton` too, the damped BFGS blocks model what is left (the
    /// peak rows between the nodes). The interval constraints' peak rows add `y·Gᵀ∇²g G`
    /// (their curvature in the states through the grid's sensitivities `G`): without it a
    /// 0.1° orientation range, whose squared form curves as `1/tol`, collapses the trust
    /// region. Default true (chosen on the benchmark suite, `BENCHMARKS.md`).
    pub exact_hessian: bool,
    /// With [`TrustRegionUpdate::Adaptive`]: when a step's ratio ρ falls short of η₂ (the
    /// trust region would not widen), solve its second-order correction — the same
    /// subproblem with each nonlinear row's constant moved by the error the step left in it
    /// (`b′ = h(z̄ + Δz) + A·Δz`) — and take the corrected candidate if its ratio against
    /// the same prediction is higher. Second-order defects then no longer spoil the ratio of
    /// a good step (the Maratos effect). Costs one more discretization where tried, and a
    /// Newton solve or one more subproblem ([`correction_solve`](Self::correction_solve)).
    /// Default true.
    pub second_order_correction: bool,
    /// How the second-order correction's step is computed. Default
    /// [`CorrectionSolve::FactorizationThenResolve`].
    pub correction_solve: CorrectionSolve,
    /// The merit function that accepts or rejects steps. Default [`Merit::ExactPenalty`].
    pub merit: Merit,
}

/// How the second-order correction's step is computed
/// ([`PtrSettings::second_order_correction`]). As data: `"resolve"`, `"factorization"` or `"factorization_then_resolve"`.
///
/// The corrected subproblem differs from the step's only in its right-hand sides, by the
/// second-order error the step left. An interior-point SQP (IPOPT) computes such a
/// correction on the step's own KKT factorization; a second interior-point solve finds the
/// corrected subproblem's exact solution, with the rows that the correction makes active,
/// at the cost of a whole subproblem (about 12 interior-point iterations on the suite's
/// arms, as many as the step's own solve).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum CorrectionSolve {
    /// The corrected subproblem solved again (the native interior point warm-started from
    /// the step's duals).
    Resolve,
    /// The step's solution moved to the corrected right-hand sides by one Newton solve on
    /// the native interior point's last factorization
    /// ([`InteriorPoint::moved_solution`](crate::ipm::InteriorPoint::moved_solution)):
    /// the corrected subproblem's solution to second order while its active set is the
    /// step's (approximately where a second-order cone is active); no correction when the
    /// step came from Clarabel.
    Factorization,
    /// [`Factorization`](Self::Factorization) first; when its candidate does not beat the
    /// step and the step would be rejected (ρ < η₀), [`Resolve`](Self::Resolve) as well.
    /// On the benchmark suite it keeps the medians of `Resolve`'s iterations and final
    /// times at about 80 % of its solve time (`BENCHMARKS.md`, 2026-12-07). The default.
    #[default]
    FactorizationThenResolve,
}

/// Merit function of the step acceptance (with [`TrustRegionUpdate::Adaptive`]). As data:
/// `"exact_penalty"` or `{ lagrangian = { sigma = 0.5 } }`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Merit {
    /// `J = cost + Σ λ_vc,i·|defect_i| + Σ λ_vb·max(0, violation)`: the ℓ1 exact penalty.
    /// Second-order defects of a good step count at full price (the Maratos effect), which
    /// keeps steps short.
    ExactPenalty,
    /// `J − Σ (1 − σ)·λ_vc,i·|defect_i| − Σ ŷ_i·defect_i` with the dynamics duals `y` of the
    /// current subproblem clipped to `ŷ_i ∈ [−σλ_vc,i, σλ_vc,i]`: the first-order cost of
    /// repairing each defect at the next iteration replaces most of its ℓ1 price (σ keeps a
    /// fraction). The clip keeps each defect's price nonnegative, so the merit is bounded
    /// below (with the raw duals a row whose dual exceeds σλ_vc rewards a growing defect).
    Lagrangian {
        /// Fraction σ ∈ [0, 1] of the ℓ1 price kept. Default 0.5.
        #[serde(default = "half")]
        sigma: f64,
    },
}

/// Which interior-point solver solves the convex subproblems.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SubproblemSolver {
    /// [`crate::ipm::InteriorPoint`], warm-started from the previous subproblem. A solve
    /// that does not reach the tolerance at a heavy trust-region weight (λ_tr > 1e3) is
    /// retried cold with the objective divided by λ_tr (and its absolute gap tolerance
    /// alike, see [`crate::ipm::InteriorPoint::set_objective_scale`]), and the rest of the
    /// run then solves scaled; otherwise, or if that fails too, Clarabel solves the
    /// subproblem.
    #[default]
    InteriorPoint,
    /// Clarabel for every subproblem (cold starts: Clarabel has no warm start).
    Clarabel,
}

/// Settings of the convex subproblems: which solver, and each solver's own settings.
///
/// # Example
/// ```
/// use armature_scvx::{PtrSettings, SubproblemSolver};
///
/// let mut settings = PtrSettings::default();
/// settings.subproblem.solver = SubproblemSolver::Clarabel;
/// settings.subproblem.clarabel.max_iterations = 100;
/// settings.subproblem.interior_point.max_iterations = 80;
/// assert!(settings.validate().is_ok());
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
#[non_exhaustive]
pub struct SubproblemSettings {
    /// The solver. Default [`SubproblemSolver::InteriorPoint`]: on the seed problem it
    /// solves the first-order subproblems in less than half of Clarabel's time (warm starts)
    /// and allocates nothing. Primal solutions agree with Clarabel's within the tolerance;
    /// duals agree where they are unique. Where they are not (a CTCS integral pinned at 0 by
    /// both its initial condition and its lower bound leaves its row's multiplier free along
    /// a ray), the quasi-Newton model and the Lagrangian merit, which use the duals, can take
    /// a different path than with Clarabel; first-order PTR with the exact-penalty merit
    /// takes the same one.
    pub solver: SubproblemSolver,
    /// Inexact solves: far from the optimum a step only has to decrease the merit, so the
    /// native interior point solves each subproblem to the tolerance
    /// `inexact · |predicted| / max(1, |cost|)` of the last iteration's predicted merit
    /// decrease, at most [`loosest_tolerance`](Self::loosest_tolerance) and at least its
    /// own [`IpmSettings::tolerance`] (which the last iterations, whose predicted decrease
    /// vanishes, reach). 0 solves every subproblem to that tolerance. Default 1e-3.
    pub inexact: f64,
    /// The loosest tolerance of an inexact solve (the first subproblem's). Default 1e-5.
    pub loosest_tolerance: f64,
    /// The native interior point's settings (also used when it is only the first try).
    pub interior_point: IpmSettings,
    /// Clarabel's settings (the fallback, or the solver).
    pub clarabel: ClarabelSettings,
}

impl Default for SubproblemSettings {
    fn default() -> Self {
        SubproblemSettings {
            solver: SubproblemSolver::default(),
            inexact: 1e-3,
            loosest_tolerance: 1e-5,
            interior_point: IpmSettings::default(),
            clarabel: ClarabelSettings::default(),
        }
    }
}

impl SubproblemSettings {
    /// The tolerance of the next subproblem after `last` (see [`inexact`](Self::inexact)).
    pub(super) fn inexact_tolerance(&self, last: Option<&Iteration>) -> f64 {
        let tight = self.interior_point.tolerance;
        if self.inexact == 0.0 {
            return tight;
        }
        let wanted = last.map_or(f64::INFINITY, |it| {
            let relative = it.predicted.abs() / it.cost.abs().max(1.0);
            // A record without a prediction (a failed solve) asks for the tight tolerance.
            if relative.is_finite() { self.inexact * relative } else { tight }
        });
        wanted.min(self.loosest_tolerance).max(tight)
    }
}

/// The settings of Clarabel that armature exposes; the rest keep Clarabel's defaults, except
/// presolve, which is off so that data can be updated in place between iterations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default, deny_unknown_fields)]
#[non_exhaustive]
pub struct ClarabelSettings {
    /// Absolute and relative duality-gap and feasibility tolerance. Default 1e-8 (Clarabel's).
    pub tolerance: f64,
    /// Tolerance (absolute and relative) of the iterative refinement of each KKT solve.
    /// Default 1e-9 (Clarabel's own 1e-13 refines directions far below what the tolerance
    /// above can use; see the crate's BENCHMARKS.md).
    pub refinement_tolerance: f64,
    /// Iteration cap. Default 200.
    pub max_iterations: u32,
    /// Ruiz equilibration. Default on.
    pub equilibrate: bool,
}

impl Default for ClarabelSettings {
    fn default() -> Self {
        ClarabelSettings {
            tolerance: 1e-8,
            refinement_tolerance: 1e-9,
            max_iterations: 200,
            equilibrate: true,
        }
    }
}

impl ClarabelSettings {
    pub(super) fn to_clarabel(&self) -> DefaultSettings<f64> {
        DefaultSettings {
            verbose: false,
            presolve_enable: false,
            max_iter: self.max_iterations,
            tol_gap_abs: self.tolerance,
            tol_gap_rel: self.tolerance,
            tol_feas: self.tolerance,
            iterative_refinement_reltol: self.refinement_tolerance,
            iterative_refinement_abstol: self.refinement_tolerance,
            equilibrate_enable: self.equilibrate,
            ..DefaultSettings::default()
        }
    }
}

/// A setting that cannot be used, with the field and the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("PTR setting `{field}` {reason}")]
pub struct SettingsError {
    /// The field.
    pub field: &'static str,
    /// Why.
    pub reason: &'static str,
}

impl PtrSettings {
    /// Checks every field.
    ///
    /// # Errors
    /// [`SettingsError`] naming the first unusable field.
    pub fn validate(&self) -> Result<(), SettingsError> {
        self.validate_weights()?;
        let bad = |field, reason| Err(SettingsError { field, reason });
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if !(1..=crate::MAX_SUBSTEPS).contains(&self.discretization.substeps) {
            return bad("discretization.substeps", "must be 1 to 1000");
        }
        if let crate::Integrator::DormandPrince { rtol, atol } = self.discretization.integrator
            && !(rtol.is_finite() && rtol > 0.0 && atol.is_finite() && atol > 0.0)
        {
            return bad(
                "discretization.integrator.dormand_prince",
                "tolerances rtol and atol must be positive",
            );
        }
        if let TrustRegionUpdate::Adaptive { eta } = self.trust_region
            && !(eta.iter().all(|e| e.is_finite()) && eta[0] <= eta[1] && eta[1] <= eta[2])
        {
            return bad("trust_region.adaptive.eta", "must be finite and non-decreasing");
        }
        if let Merit::Lagrangian { sigma } = self.merit
            && !(0.0..=1.0).contains(&sigma)
        {
            return bad("merit.lagrangian.sigma", "must lie in [0, 1]");
        }
        self.validate_subproblem()
    }

    /// The weights, tolerances and steps that must be positive, and their orders.
    fn validate_weights(&self) -> Result<(), SettingsError> {
        let positive = [
            ("lam_tr", self.lam_tr),
            ("lam_tr_min", self.lam_tr_min),
            ("lam_tr_max", self.lam_tr_max),
            ("lam_vc", self.lam_vc),
            ("lam_vc_max", self.lam_vc_max),
            ("lam_vb", self.lam_vb),
            ("eps_vb", self.eps_vb),
            ("eps_tr", self.eps_tr),
            ("eps_defect", self.eps_defect),
            ("dense_dt", self.dense_dt),
            ("dense_tolerance", self.dense_tolerance),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(SettingsError { field, reason: "must be a positive finite number" });
            }
        }
        let bad = |field, reason| Err(SettingsError { field, reason });
        if !(self.lam_tr_min <= self.lam_tr && self.lam_tr <= self.lam_tr_max) {
            return bad("lam_tr", "must lie between lam_tr_min and lam_tr_max");
        }
        if self.lam_vc > self.lam_vc_max || self.lam_vb > self.lam_vc_max {
            return bad("lam_vc_max", "must be at least lam_vc and lam_vb");
        }
        if !(self.eps_flat.is_finite() && self.eps_flat >= 0.0) {
            return bad("eps_flat", "must be a finite number ≥ 0");
        }
        if !(1e-6..=1.0).contains(&self.dense_dt) {
            return bad("dense_dt", "must be 1e-6 to 1 s");
        }
        Ok(())
    }

    /// The subproblem solvers' settings.
    fn validate_subproblem(&self) -> Result<(), SettingsError> {
        let (ip, cl) = (&self.subproblem.interior_point, &self.subproblem.clarabel);
        let positive = [
            ("subproblem.interior_point.tolerance", ip.tolerance),
            ("subproblem.clarabel.tolerance", cl.tolerance),
            ("subproblem.clarabel.refinement_tolerance", cl.refinement_tolerance),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(SettingsError { field, reason: "must be a positive finite number" });
            }
        }
        let nonnegative = [
            ("subproblem.inexact", self.subproblem.inexact),
            ("subproblem.loosest_tolerance", self.subproblem.loosest_tolerance),
            ("subproblem.interior_point.regularization", ip.regularization),
            ("subproblem.interior_point.warm_start_margin", ip.warm_start_margin),
        ];
        for (field, v) in nonnegative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(SettingsError { field, reason: "must be a finite number ≥ 0" });
            }
        }
        let bad = |field, reason| Err(SettingsError { field, reason });
        if !ip.warm_start_centring.is_finite() {
            return bad("subproblem.interior_point.warm_start_centring", "must be finite");
        }
        if ip.max_iterations == 0 {
            return bad("subproblem.interior_point.max_iterations", "must be at least 1");
        }
        if cl.max_iterations == 0 {
            return bad("subproblem.clarabel.max_iterations", "must be at least 1");
        }
        Ok(())
    }
}

impl Default for PtrSettings {
    fn default() -> Self {
        PtrSettings {
            lam_tr: 1.0,
            lam_tr_min: 1e-4,
            lam_tr_max: 1e6,
            lam_vc: 0.3,
            lam_vc_max: 1e6,
            lam_vb: 0.3,
            eps_vb: 1e-6,
            eps_tr: 1e-5,
            eps_defect: 1e-6,
            eps_flat: 3e-3,
            trust_region: TrustRegionUpdate::Adaptive { eta: default_eta() },
            max_iterations: 200,
            infeasible_window: 16,
            discretization: DiscretizationSettings::default(),
            subproblem: SubproblemSettings::default(),
            dense_dt: 0.01,
            dense_tolerance: 1e-4,
            backtracking: true,
            quasi_newton: false,
            exact_hessian: true,
            second_order_correction: true,
            correction_solve: CorrectionSolve::default(),
            merit: Merit::ExactPenalty,
        }
    }
}

/// Trust-region policy. As data: `"constant"` or `{ adaptive = { eta = [0, 0.1, 0.5] } }`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TrustRegionUpdate {
    /// Penalized trust region as published (Reynolds, Szmuk et al.; OpenSCvx's
    /// `ConstantProximalWeight`): every step is accepted and λ_tr stays fixed; the
    /// virtual-control penalty drives feasibility.
    Constant,
    /// Accept or reject by the actual/predicted merit ratio ρ with thresholds η₀ < η₁ < η₂:
    /// reject below η₀ (λ_tr doubles, so the next subproblem differs), double λ_tr below η₁,
    /// halve it above η₂. Slower than `Constant` on the reference problems so far: second-
    /// order defects weighted by λ_vc keep ρ low, so λ_tr stays high.
    Adaptive {
        /// The thresholds. Default [0, 0.1, 0.5].
        #[serde(default = "default_eta")]
        eta: [f64; 3],
    },
}

fn half() -> f64 {
    0.5
}

fn default_eta() -> [f64; 3] {
    [0.0, 0.1, 0.5]
}
