//! The penalized-trust-region (PTR) loop; its convex subproblems go to the native
//! interior point ([`crate::ipm`], warm-started) with Clarabel as fallback and option.
//!
//! # Subproblem
//! Variables `z = [X (N·n) | U (N·m) | S (N) | ν⁺ ((N−1)·n) | ν⁻ ((N−1)·n)]`, around the
//! reference `z̄` with its discretization:
//!
//! ```text
//! minimise   w_t·Δτ·Σ_{k<N−1} s_k  +  λ_vc·Σ(ν⁺ + ν⁻)  +  λ_tr·‖(X, U, S) − (X̄, Ū, S̄)‖²
//! subject to x_{k+1} = A_k x_k + B⁻_k [u_k; s_k] + B⁺_k u_{k+1} + c_k + ν⁺_k − ν⁻_k
//!            (c_k = x_prop_k − A_k x̄_k − B⁻_k [ū_k; s̄_k] − B⁺_k ū_{k+1})
//!            fixed initial / final state components, s_{N−1} = s_{N−2},
//!            box bounds on x, u, s, and ν± ≥ 0.
//! ```
//!
//! The trust-region norm is measured in scaled variables `(z − z̄)/S` with
//! `S = max(1, (max − min)/2)` from each variable's bounds, so a dilation with range [0.1, 10]
//! may move as far, relative to its range, as an acceleration in [−1, 1].
//!
//! The constraint matrix's pattern is built once with a value source per nonzero; each
//! iteration refills the values, which the native interior point factors in its fixed
//! pattern (and Clarabel, when used, takes as an in-place update with presolve off).
//!
//! The subproblem is solved in deviation form (unknowns `Δz = z − z̄`), so its objective
//! carries no `λ_tr‖z̄‖²` offset that would swamp the solver's relative tolerances at large λ_tr.
//! Nodal constraints are either entrywise inequalities (linearised, with a virtual buffer
//! each) or balls `‖g‖ ≤ r` kept as second-order cones around the linearised `g`.
//!
//! # Interval bounds
//! A state row listed in [`Ocp::interval_bounds`] gets, per segment and finite bound, one more
//! buffered inequality: its *peak* on the segment. The discretization records the trajectory
//! and its sensitivities `[Φ | B⁻ | B⁺](t_j)` at the integration grid's points
//! `t_j = τ_k + j·Δτ/substeps` ([`Discretization::grid`]). The peak is the largest value of
//! `±x_r(t_j)`, refined by the parabola through it and its two neighbours (the vertex, when
//! the parabola is concave and the vertex lies between them):
//! `x̂_r = Σ_i w_i x_r(t_i)` with the parabola's Lagrange weights at the vertex. The row is
//! `±Σ_i w_i ∂x_r(t_i)/∂z · Δz − ν_b ≤ bound ∓ x̂_r`: by the envelope theorem the vertex's
//! value moves with `z` as the parabola does at a fixed vertex, so the weights are held.
//!
//! Why: a CTCS integral `∫ max(0, x_r − x_max)` guarantees the bound in continuous time, but
//! where the trajectory touches the bound inside a segment its integrand is zero around the
//! contact and so is its linearization. The subproblem then pushes through the bound, the
//! merit rejects or shrinks the step, and a first-order loop creeps along the bound. On the
//! seed arm, whose time-optimal velocities ride their limits inside segments, the peak rows
//! take PTR from T = 1.553 s (a short-step stop after a run of such rejections) to 1.278 s,
//! with iteration counts that no longer swing with every setting.
//!
//! [`Ocp::interval_constraints`] do the same for nonlinear state constraints `g(x) ≤ 0`: per
//! segment and output, the peak of `g_o(x(t_j))` over the grid, refined the same way, and the
//! row `Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z · Δz − ν_b ≤ −ĝ_o` ([`IntervalConstraint`]). The
//! values are computed at every grid point, the Jacobians only at the stencils' points. On
//! the seed's collision variant (clearances of every capsule pair, also as a ReLU CTCS
//! integral and at the nodes) these rows take the default solve from 70 to 32 iterations
//! and the median over the 3 × 3 settings neighbourhood from 95 to 56, to lower final times
//! (1.432 s against 1.480 s at the default point): the integral's linearization switches on
//! and off where the arm grazes the ball between two nodes, and the merit ratio of each step
//! swung with it. Each row couples a segment's states, controls and dilation, so the
//! subproblem's KKT factor grows (on the seed, about 27 % more nonzeros, 24 % more work).
//!
//! With an activation distance ([`IntervalConstraint::activation`]) a segment's rows sit out
//! of the subproblem while all its peaks lie further than that below the bound: their
//! coefficients are zeroed, and the interior point, told which rows may be switched off,
//! factors K without them (one analysis per set of switched-off rows, cached). Rows that far
//! from their bound are slack, so the steps are nearly always the same; the merit still
//! prices every peak, and the CTCS integral and the nodal rows still hold the segment. On
//! the seed's collision variant (2 cm), only the segments where the arm passes the ball keep
//! their rows — one at the end — and the solve does 12 % fewer instructions on the same
//! iterates.
//!
//! # Acceptance
//! By default ([`TrustRegionUpdate::Adaptive`]) the merit
//! `J(z) = w_t·t_f(z) + Σ λ_vc,i·|defect_i(z)| + Σ λ_vb·max(0, violation)` and the
//! subproblem's prediction `L(z*)` give `ρ = (J(z̄) − J(z*)) / (J(z̄) − L(z*))`; a step with
//! `ρ < η₀` is rejected and λ_tr doubles (so the next subproblem differs — no identical
//! re-solves), otherwise λ_tr adapts (×2 below η₁, ×½ above η₂). The published PTR
//! ([`TrustRegionUpdate::Constant`]) accepts every step. A row whose subproblem bought virtual
//! control (or a buffer) gets a doubled price — the ℓ1 penalty is exact only above the
//! multiplier. Converged when an accepted step has `‖Δz‖²_S < ε_tr`, the largest nonlinear
//! defect is below `ε_defect` and the largest nodal violation below `ε_vb`.
//!
//! A short step is not a stationary point: with a heavy λ_tr the step is short while the
//! Lagrangian's gradient (≈ 2λ_tr·S⁻²Δz at the subproblem's optimum) is not small. On the
//! seed arm the first-order loop stops at T = 1.553 s; run on with ε_tr = 1e-12 it is still
//! creeping down (1.426 s after 400 iterations). [`PtrSettings::quasi_newton`] adds a damped
//! BFGS model of the Lagrangian's Hessian per segment (`P` gains one dense block per segment
//! over the columns where the segment's rows are nonlinear; the pairs are
//! `s = z − z̄`, `y = (A(z) − A(z̄))ᵀλ` with the subproblem's duals λ), and
//! [`Merit::Lagrangian`] prices a defect by its dual instead of its full ℓ1 weight; together
//! they reach T = 1.268 s on the same problem. [`Ocp::interval_bounds`] on the velocities
//! (see "Interval bounds" above) takes the first-order loop itself to T = 1.278 s.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT, SolverStatus,
    SupportedConeT, ZeroConeT,
};
use std::time::Instant;

use crate::ipm::{Cones, InteriorPoint, IpmSettings, IpmStatus};

use serde::Serialize;

use crate::{
    Discretization, DiscretizationError, DiscretizationSettings, DiscretizationWorkspace, Dynamics,
};

/// The optimal control problem in dynamics form.
#[derive(Debug, Clone)]
pub struct Ocp {
    /// Compiled dynamics.
    pub dynamics: Dynamics,
    /// Number of nodes N (≥ 2).
    pub nodes: usize,
    /// State bounds (±∞ for none).
    pub x_min: Vec<f64>,
    /// State bounds.
    pub x_max: Vec<f64>,
    /// Control bounds.
    pub u_min: Vec<f64>,
    /// Control bounds.
    pub u_max: Vec<f64>,
    /// Fixed initial components (`None` = free).
    pub x_initial: Vec<Option<f64>>,
    /// Fixed final components (`None` = free).
    pub x_final: Vec<Option<f64>>,
    /// Bounds of the time dilation `s` (total time = s·1 for a uniform grid).
    pub s_min: f64,
    /// Bounds of the time dilation.
    pub s_max: f64,
    /// Bounds of the final time `Δτ·Σ_{k<N−1} s_k` (a linear constraint; `(0, ∞)` for none).
    pub final_time: (f64, f64),
    /// Weight of the final time in the cost (0: fixed-time feasibility).
    pub time_weight: f64,
    /// Linear cost on final-state components `(state index, weight)`: a positive weight
    /// minimizes `x_{N−1}[i]`, a negative one maximizes it.
    pub final_cost: Vec<(usize, f64)>,
    /// CTCS increments `(state row, ε, first node, last node)`: `y_{k+1} − y_k ≤ ε` for the
    /// segments of the interval.
    pub increments: Vec<(usize, f64, usize, usize)>,
    /// Nodal constraints, linearised each iteration with virtual buffers.
    pub nodal: Vec<NodalConstraint>,
    /// State rows whose bounds `x_min ≤ x(t) ≤ x_max` are also enforced between the nodes,
    /// at each segment's peak: the largest (smallest) value of the row on the integration
    /// grid, refined by the parabola through the grid points around it, linearized through
    /// the grid's sensitivities (Danskin: the peak's time held fixed) and bounded with a
    /// virtual buffer. A CTCS integral of the positive part keeps a bound in continuous
    /// time but its linearization is blind where the trajectory touches the bound (the
    /// integrand has no gradient there), so a subproblem pushes through it and the merit
    /// rejects the step; a peak row shows the subproblem the bound with a full gradient.
    pub interval_bounds: Vec<usize>,
    /// Nonlinear state constraints `g(x(t)) ≤ 0` enforced between the nodes the same way:
    /// per segment and output, one buffered row at the output's peak on the integration
    /// grid (see [`IntervalConstraint`]).
    pub interval_constraints: Vec<IntervalConstraint>,
}

/// A constraint `g(x(t)) ≤ 0` (entrywise) on the states between the nodes of segments
/// `first..last`, enforced at each segment's peak of each output.
///
/// # Math
/// On segment k, `g_o` is evaluated at the integration grid's points `t_j`; its largest value,
/// refined by the parabola through the best point and its neighbours, `ĝ_o = Σ_i w_i g_o(x(t_i))`,
/// gives the buffered row `Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z · Δz − ν_b ≤ −ĝ_o` with the grid's
/// sensitivities `∂x(t_i)/∂z = [Φ | B⁻ | B⁺](t_i)` and the weights held (the envelope theorem
/// for the vertex, Danskin's for the grid maximum).
///
/// Why: a CTCS integral of `max(0, g)` keeps `g ≤ 0` in continuous time, but where the
/// trajectory only touches the constraint between the nodes its linearization is blind or
/// switches on and off (the ReLU's kink), and the merit ratio of a step swings; a peak row
/// gives the subproblem the constraint's full gradient where it is tightest. Use it for
/// clearances (`margin − distance`) and other state constraints the motion rides.
///
/// The named layer builds them from [`BetweenNodes`](crate::BetweenNodes) (see its example).
///
/// # Errors
/// [`Ptr::start`] returns [`PtrError::IntervalConstraint`] if `g` depends on the controls,
/// the segments are not within the problem's nodes or the activation distance is not
/// positive.
#[derive(Debug, Clone)]
pub struct IntervalConstraint {
    /// Name for diagnostics.
    pub name: String,
    /// `g`, compiled against the groups `[states], [controls]` of the dynamics; it may only
    /// read the states.
    pub function: armature_symbolic::Function,
    /// First segment (= its first node).
    pub first: usize,
    /// One past the last segment (= the last node of the interval); `first < last ≤ N − 1`.
    pub last: usize,
    /// Activation distance (in `g`'s units), or `None` to keep every row. A segment's rows
    /// are switched off while all of its peaks lie more than this below the bound
    /// (`max_o ĝ_o < −activation` at the reference): their coefficients are zeroed, so the
    /// subproblem drops them and the interior point factors a smaller KKT matrix (see
    /// [`crate::ipm::InteriorPoint::with_switchable_rows`]). The segment stays watched — by
    /// the merit, which prices every peak's violation, by the CTCS integral and the nodal
    /// rows — and its rows come back at the first reference where a peak comes within the
    /// distance. Choose it above what one step can move `g`: rows far from their bound are
    /// slack in every subproblem, so dropping them does not change the steps. For
    /// clearances, a few centimetres (the seed's collision variant: 2 cm, same iterates).
    pub activation: Option<f64>,
}

impl IntervalConstraint {
    /// Whether `g` reads an input past the first `states` (the states come first, the
    /// controls after them): an interval constraint may read the states only, because the
    /// grid records the states and their sensitivities.
    pub fn reads_controls(&self, states: usize) -> bool {
        self.function.jacobian_pattern().entries().any(|(_, col)| col >= states)
    }
}

/// A (generally nonconvex) constraint on `g(x_k, u_k)` at listed nodes.
#[derive(Debug, Clone)]
pub struct NodalConstraint {
    /// Name for diagnostics.
    pub name: String,
    /// `g`, compiled against the groups `[states], [controls]` of the dynamics.
    pub function: armature_symbolic::Function,
    /// Nodes where it holds.
    pub nodes: Vec<usize>,
    /// What it says about `g`.
    pub kind: NodalKind,
    /// With [`NodalKind::Inequality`]: a name per entry of `g`, under which
    /// [`PtrResult::violations`] reports the entry (entries that share a name, together).
    /// One vector constraint evaluates what its entries share once per node — the seed
    /// arm's collision pairs share the forward kinematics — where one constraint per entry
    /// would repeat it for each. Empty: the constraint is reported as one under `name` (as
    /// it must be with [`NodalKind::Ball`]).
    pub output_names: Vec<String>,
}

/// The meaning of a [`NodalConstraint`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum NodalKind {
    /// `g ≤ 0` entrywise, linearised: `g(z̄) + ∇g·(z − z̄) ≤ ν_b` per entry.
    Inequality,
    /// `‖g‖₂ ≤ radius` (e.g. `g = p_ee − waypoint`), linearised inside the norm only:
    /// `‖g(z̄) + ∇g·(z − z̄)‖ ≤ radius + ν_b`, a second-order cone. Keeping the norm exact
    /// (the prox-linear model) captures the ball's curvature, which a linearised norm would
    /// leave to the trust region.
    Ball {
        /// The radius.
        radius: f64,
    },
}

/// PTR settings with documented defaults.
#[derive(Debug, Clone, PartialEq, Serialize)]
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
    /// `ep_tr` is 1e-4). Against 1e-6: over the seed arm's wide settings grid (100 runs)
    /// 12 runs stop earlier and none later, 7 of them within 0.05 % of the same final time,
    /// 4 at 0.4–2.4 % above it and one at 8 %, all meeting the task; the random double
    /// integrators reach the iteration cap once instead of 15 times (see the scvx README).
    pub eps_tr: f64,
    /// Convergence: largest nonlinear defect. Default 1e-6.
    pub eps_defect: f64,
    /// How the trust-region weight evolves. Default `Adaptive { eta: [0, 0.1, 0.5] }`.
    pub trust_region: TrustRegionUpdate,
    /// Iteration cap. Default 200 (OpenSCvx's `k_max`): over λ_tr ∈ {0.5, 1, 2} × substeps
    /// ∈ {8, 10, 12} around the defaults, the seed arm's first-order solves converge in 23 to
    /// 178 iterations (5 of those 18 runs take more than 100).
    pub max_iterations: usize,
    /// Integrator settings.
    pub discretization: DiscretizationSettings,
    /// Settings of the convex subproblem solver (Clarabel).
    pub subproblem: SubproblemSettings,
    /// Time step of the dense propagation in post-processing (s). Default 0.01.
    pub dense_dt: f64,
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
    /// The merit function that accepts or rejects steps. Default [`Merit::ExactPenalty`].
    pub merit: Merit,
}

/// Merit function of the step acceptance (with [`TrustRegionUpdate::Adaptive`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
        /// Fraction σ ∈ [0, 1] of the ℓ1 price kept.
        sigma: f64,
    },
}

/// Which interior-point solver solves the convex subproblems.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SubproblemSolver {
    /// [`crate::ipm::InteriorPoint`], warm-started from the previous subproblem. A solve
    /// that does not reach the tolerance at a heavy trust-region weight (λ_tr > 1e3) is
    /// retried cold with the objective divided by λ_tr (and its absolute gap tolerance
    /// alike, see [`crate::ipm::InteriorPoint::set_objective_scale`]), and the rest of the
    /// run then solves scaled; otherwise, or if that fails too, Clarabel solves the
    /// subproblem. (The retry is a safeguard: the one seed case that needed it failed on the
    /// interior point's former objective-gap test, and since the complementarity-gap test
    /// no first-order run of the seed's neighbourhood grids reaches the cap.)
    InteriorPoint,
    /// Clarabel for every subproblem (cold starts: Clarabel has no warm start).
    Clarabel,
}

/// Settings of the interior-point solver of each convex subproblem. Clarabel's other
/// settings keep its defaults, except presolve, which is off so that data can be updated in
/// place between iterations.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SubproblemSettings {
    /// The solver. Default [`SubproblemSolver::InteriorPoint`]: on the seed problem it
    /// solves the first-order subproblems in less than half of Clarabel's time (warm starts:
    /// 10–11 interior-point iterations per subproblem against 17–19) and allocates nothing.
    /// Primal solutions agree with Clarabel's within the tolerance; duals agree where they
    /// are unique. Where they are not (a CTCS integral pinned at 0 by both its initial
    /// condition and its lower bound leaves its row's multiplier free along a ray), the
    /// quasi-Newton model and the Lagrangian merit, which use the duals, can take a
    /// different path than with Clarabel; first-order PTR with the exact-penalty merit
    /// takes the same one.
    pub solver: SubproblemSolver,
    /// Absolute and relative duality-gap and feasibility tolerance. Default 1e-8 (Clarabel's).
    /// The native interior point measures the gap as the complementarity `sᵀz` (see
    /// [`crate::ipm::IpmSettings::tolerance`]).
    pub tolerance: f64,
    /// Tolerance (absolute and relative) of Clarabel's iterative refinement of each KKT
    /// solve. Default 1e-9: Clarabel's own 1e-13 spends ~20 % of the seed solve refining directions
    /// far below what the tolerance above can use, for the same iterates.
    pub refinement_tolerance: f64,
    /// Clarabel's iteration cap. Default 200.
    pub max_iterations: u32,
    /// The native interior point's iteration cap; when it is reached, the native solver
    /// retries with the objective scaled, then Clarabel solves the subproblem instead.
    /// Default 50 (the seed problem's subproblems take 6–21).
    pub interior_point_max_iterations: u32,
    /// Clarabel's Ruiz equilibration. Default on. (The native solver works on the scaled
    /// data as given.)
    pub equilibrate: bool,
}

impl Default for SubproblemSettings {
    fn default() -> Self {
        SubproblemSettings {
            solver: SubproblemSolver::InteriorPoint,
            tolerance: 1e-8,
            refinement_tolerance: 1e-9,
            max_iterations: 200,
            interior_point_max_iterations: 50,
            equilibrate: true,
        }
    }
}

impl SubproblemSettings {
    fn interior_point(&self) -> IpmSettings {
        IpmSettings {
            tolerance: self.tolerance,
            max_iterations: self.interior_point_max_iterations,
            ..IpmSettings::default()
        }
    }

    fn clarabel(&self) -> DefaultSettings<f64> {
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
            ("subproblem.tolerance", self.subproblem.tolerance),
            ("subproblem.refinement_tolerance", self.subproblem.refinement_tolerance),
            ("dense_dt", self.dense_dt),
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
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if self.subproblem.max_iterations == 0 {
            return bad("subproblem.max_iterations", "must be at least 1");
        }
        if self.subproblem.interior_point_max_iterations == 0 {
            return bad("subproblem.interior_point_max_iterations", "must be at least 1");
        }
        if self.discretization.substeps == 0 {
            return bad("discretization.substeps", "must be at least 1");
        }
        if let crate::Integrator::DormandPrince { rtol, atol } = self.discretization.integrator
            && !(rtol.is_finite() && rtol > 0.0 && atol.is_finite() && atol > 0.0)
        {
            return bad("discretization.integrator", "Dormand–Prince tolerances must be positive");
        }
        if let TrustRegionUpdate::Adaptive { eta } = self.trust_region
            && !(eta.iter().all(|e| e.is_finite()) && eta[0] <= eta[1] && eta[1] <= eta[2])
        {
            return bad("trust_region.eta", "must be finite and non-decreasing");
        }
        if let Merit::Lagrangian { sigma } = self.merit
            && !(0.0..=1.0).contains(&sigma)
        {
            return bad("merit.sigma", "must lie in [0, 1]");
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
            trust_region: TrustRegionUpdate::Adaptive { eta: [0.0, 0.1, 0.5] },
            max_iterations: 200,
            discretization: DiscretizationSettings::default(),
            subproblem: SubproblemSettings::default(),
            dense_dt: 0.01,
            backtracking: true,
            quasi_newton: false,
            merit: Merit::ExactPenalty,
        }
    }
}

/// Trust-region policy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
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
        /// The thresholds.
        eta: [f64; 3],
    },
}

/// How a solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PtrStatus {
    /// Both criteria met.
    Converged,
    /// The iteration cap was reached.
    MaxIterations,
    /// λ_tr hit its cap without an acceptable step.
    Stalled,
    /// Clarabel reported the subproblem infeasible.
    SubproblemInfeasible,
    /// Clarabel failed numerically.
    NumericalFailure,
}

impl PtrStatus {
    /// The status as a stable snake-case word (`converged`, `max_iterations`, `stalled`,
    /// `subproblem_infeasible`, `numerical_failure`).
    pub fn as_str(self) -> &'static str {
        match self {
            PtrStatus::Converged => "converged",
            PtrStatus::MaxIterations => "max_iterations",
            PtrStatus::Stalled => "stalled",
            PtrStatus::SubproblemInfeasible => "subproblem_infeasible",
            PtrStatus::NumericalFailure => "numerical_failure",
        }
    }
}

/// One iteration's record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Iteration {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Whether the step was accepted.
    pub accepted: bool,
    /// Cost of the candidate (time weight × final time).
    pub cost: f64,
    /// ‖Δz‖² of the step (scaled variables).
    pub j_tr: f64,
    /// Σ|ν| of the subproblem (virtual control).
    pub j_vc: f64,
    /// Σ max(0, ν_b) of the subproblem (virtual buffers of nodal constraints).
    pub j_vb: f64,
    /// Largest nonlinear defect of the candidate.
    pub max_defect: f64,
    /// Largest nodal-constraint violation of the candidate.
    pub max_violation: f64,
    /// Final time of the candidate.
    pub final_time: f64,
    /// Actual / predicted merit reduction.
    pub rho: f64,
    /// λ_tr used.
    pub lam_tr: f64,
    /// How hard the trust region holds the step back: `max_i |2λ_tr·Δz_i/S_i|`, the
    /// gradient of the trust-region term at the step in scaled variables. The subproblem's
    /// optimality makes it part of the Lagrangian's gradient at the reference, so it is
    /// near zero only near a stationary point; a short step with a large value was kept
    /// short by a heavy λ_tr. The PTR stopping rule does not require it to be small.
    pub tr_gradient: f64,
    /// Wall time of the candidate's discretization (ms).
    pub discretization_ms: f64,
    /// Wall time of the subproblem: data update (or setup) and solve (ms).
    pub subproblem_ms: f64,
    /// Interior-point iterations of the subproblem.
    pub subproblem_iterations: u32,
    /// Clarabel's status of the subproblem (`Solved`, `AlmostSolved`, …).
    pub subproblem_status: &'static str,
    /// Set on the final iteration: how the solve ended.
    pub status: Option<PtrStatus>,
}

/// The outcome: the last accepted trajectory, its violations and the history.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PtrResult {
    /// How it ended.
    pub status: PtrStatus,
    /// States (N×n, row-major).
    pub x: Vec<f64>,
    /// Controls (N×m).
    pub u: Vec<f64>,
    /// Dilations (N).
    pub s: Vec<f64>,
    /// `Δτ·Σ s_k`.
    pub final_time: f64,
    /// Per-iteration records.
    pub history: Vec<Iteration>,
    /// Largest violation of every constraint at the returned trajectory: the dynamics of
    /// each state row, then each nodal constraint in definition order.
    pub violations: Vec<Violation>,
    /// The largest positive entry of `violations`, if any: what a non-converged solve
    /// still violates, and where.
    pub max_violation: Option<Violation>,
    /// Wall-clock totals.
    pub timings: Timings,
}

#[derive(Debug, Clone, Copy)]
enum Source {
    Const(f64),
    A(usize),
    Bm(usize),
    Bp(usize),
    /// A nodal-constraint Jacobian nonzero (index into the per-iteration buffer).
    G(usize),
    /// Its negative (cone rows: `s = b − A z`).
    NegG(usize),
    /// A coefficient of an interval-bound peak row (index into the per-iteration buffer).
    Peak(usize),
}

/// One interval row: the peak on segment `seg` of state `r` against its upper (`sign` +1)
/// or lower (−1) bound, or of an interval constraint's output (`sign` +1, bound 0).
#[derive(Debug, Clone)]
struct PeakRow {
    seg: usize,
    of: PeakOf,
    sign: f64,
    bound: f64,
    row: usize,
    /// Its coefficients: offsets into a grid block (`[x, Φ, B⁻, B⁺]`), in `peak_src` — of
    /// the state row's entry, or (function rows) of row 0's entry in the column, with the
    /// column's row stride in `peak_stride`.
    src: std::ops::Range<usize>,
}

/// What a [`PeakRow`] bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum PeakOf {
    /// A state row ([`Ocp::interval_bounds`]).
    State(usize),
    /// Output `out` of interval constraint `c` ([`Ocp::interval_constraints`]).
    Function { c: usize, out: usize },
}

/// Per interval constraint: where its grid values and Jacobians sit in [`NodalEval`], and
/// for each output the state rows it reads with their Jacobian nonzero index.
#[derive(Debug, Clone)]
struct IntervalMeta {
    first: usize,
    last: usize,
    nout: usize,
    nnz: usize,
    /// Offset of `(segment first, point 0)` in `NodalEval::fgrid` (values, `nout` per point)
    /// and `NodalEval::fjac` (`nnz` per point).
    val0: usize,
    jac0: usize,
    /// Offset of its first grid point in `NodalEval::fjac_at`, and its number of points.
    pt0: usize,
    points: usize,
    /// [`IntervalConstraint::activation`] (∞ for none), and the index of its first segment in
    /// `NodalEval::segment_peak`.
    activation: f64,
    seg0: usize,
    deps: Vec<Vec<(usize, usize)>>,
}

/// λ_tr above which a failed native solve is retried with the objective divided by λ_tr
/// (see `solve_subproblem`).
const HEAVY_TRUST_REGION: f64 = 1e3;

/// Scale of the initial quasi-Newton block, `γ·S⁻²` with `γ` this times Nocedal and
/// Wright's `‖y‖²/yᵀs` (in the trust-region scaling): their estimate sits near the largest
/// curvature, and a tenth of it let the seed arm take longer first steps.
const QN_INITIAL_SCALE: f64 = 0.1;

/// One element of the partitioned quasi-Newton Hessian: the columns through which the rows
/// of one segment (its dynamics and the nodal constraints at its first node) are nonlinear.
#[derive(Debug, Clone)]
struct Element {
    /// Subproblem columns (primal variables).
    cols: Vec<usize>,
    /// For `a ≤ b`, the index in `P`'s values of entry `(cols[a], cols[b])`, row-major `d×d`.
    pidx: Vec<usize>,
}

/// Scratch for evaluating the nodal constraints (allocated once per solve).
#[derive(Debug)]
struct NodalEval {
    /// Per-lane scratch (one lane per rayon worker; see [`for_lanes`]).
    lanes: Vec<EvalLane>,
    values: Vec<f64>,
    jac: Vec<f64>,
    /// Per buffer (nodal, then interval-bound peaks): its positive violation.
    violation: Vec<f64>,
    /// Coefficients of the interval-bound rows (`Source::Peak`) at the last `fill_peaks`.
    peak_vals: Vec<f64>,
    /// Each interval-bound row's `sign·x̂ − bound` at the last `fill_peaks`.
    peak_g: Vec<f64>,
    /// Interval constraints: their values and (when linearized) Jacobian nonzeros at every
    /// grid point of their segments (see [`IntervalMeta`]).
    fgrid: Vec<f64>,
    fjac: Vec<f64>,
    /// Per grid point of `fgrid`: its Jacobian is needed by the current `fill_peaks`.
    fjac_at: Vec<bool>,
    /// The grid points whose Jacobians `fill_peaks` evaluates (capacity: every point).
    stencil_points: Vec<usize>,
    /// Per peak row: the first grid point of its stencil and its weights, at the last
    /// `fill_peaks`.
    stencils: Vec<(usize, [f64; 3])>,
    /// `fgrid` holds the interval constraints' values at the reference (`Iterate::dbar`):
    /// set when they are evaluated there, or when the candidate they were evaluated at is
    /// accepted; cleared by an evaluation anywhere else and by a parameter change.
    fgrid_reference: bool,
    /// Per interval constraint and segment: its largest peak at the last `fill_peaks`.
    segment_peak: Vec<f64>,
}

/// Where an evaluation of the interval constraints is: at the reference, whose values
/// [`NodalEval::fgrid`] may already hold, or anywhere else.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum GridAt {
    Reference,
    Other,
}

/// One lane's evaluation scratch: a workspace per nodal and per interval constraint, and the
/// function input `[x; u]`.
#[derive(Debug)]
struct EvalLane {
    ws: Vec<armature_symbolic::Workspace>,
    iws: Vec<armature_symbolic::Workspace>,
    input: Vec<f64>,
}

/// Where one nodal constraint row sits: its evaluation block and its subproblem row.
#[derive(Debug, Clone, Copy)]
struct NodalRow {
    output: usize,
    row: usize,
    /// Index of its (constraint, node) evaluation block in `g_offsets`.
    eval: usize,
    /// A cone row (`b = g(z̄) − ∇g·z̄`) rather than an inequality (`b = ∇g·z̄ − g(z̄)`).
    cone: bool,
}

/// The PTR solver for one [`Ocp`], with its subproblem pattern built once.
#[derive(Debug)]
pub struct Ptr {
    ocp: Ocp,
    settings: PtrSettings,
    n_vars: usize,
    a_colptr: Vec<usize>,
    a_rowval: Vec<usize>,
    sources: Vec<Source>,
    b: Vec<f64>,
    /// Row index of the first dynamics row (ZeroCone rows come first).
    n_zero: usize,
    n_nonneg: usize,
    dws: DiscretizationWorkspace,
    /// Start of the virtual-buffer variables.
    vb0: usize,
    nodal_rows: Vec<NodalRow>,
    /// Interval-bound rows and the grid offsets of their coefficients.
    peaks: Vec<PeakRow>,
    peak_src: Vec<usize>,
    /// Row stride of each function peak coefficient's column in a grid block (`peak_src`
    /// order; unused for state rows).
    peak_stride: Vec<usize>,
    intervals: Vec<IntervalMeta>,
    /// Per (constraint, node) evaluation: offset of its values and Jacobian nonzeros.
    g_offsets: Vec<(usize, usize)>,
    /// The (constraint, node) of each evaluation, in `g_offsets` order.
    nodal_blocks: Vec<(usize, usize)>,
    g_len: (usize, usize),
    /// Per virtual buffer: its evaluation block and output (`None` for a ball's norm).
    buffers: Vec<(usize, usize, Option<usize>)>,
    /// Sizes of the second-order cones (after the nonnegative rows).
    socs: Vec<usize>,
    /// Upper-triangular pattern of the subproblem's `P` (diagonal plus the quasi-Newton
    /// element blocks).
    p_colptr: Vec<usize>,
    p_rowval: Vec<usize>,
    /// Index in `P`'s values of each primal column's diagonal.
    p_diag: Vec<usize>,
    /// Quasi-Newton elements of the Lagrangian's Hessian.
    elements: Vec<Element>,
    /// Element of each subproblem row (`usize::MAX`: a row with constant coefficients).
    row_elem: Vec<usize>,
    /// The running (or last) solve.
    state: Option<Box<Iterate>>,
}

impl Ptr {
    fn layout(&self) -> (usize, usize, usize, usize) {
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        (nn * n, nn * n + nn * m, nn * n + nn * m + nn, (nn - 1) * n)
    }

    /// Builds the solver (the subproblem pattern is computed here, once).
    pub fn new(ocp: Ocp, settings: PtrSettings) -> Ptr {
        let (n, m, nn) = (ocp.dynamics.n_x(), ocp.dynamics.n_u(), ocp.nodes);
        let mc = m + 1;
        let x0 = 0;
        let u0 = nn * n;
        let s0 = u0 + nn * m;
        let vp0 = s0 + nn;
        let vm0 = vp0 + (nn - 1) * n;
        let vb0 = vm0 + (nn - 1) * n;
        let n_buffers: usize = ocp
            .nodal
            .iter()
            .map(|c| {
                c.nodes.len()
                    * match c.kind {
                        NodalKind::Inequality => c.function.n_outputs(),
                        NodalKind::Ball { .. } => 1,
                    }
            })
            .sum();
        let interval_rows: Vec<usize> =
            ocp.interval_bounds.iter().copied().filter(|&r| r < n).collect();
        let n_peaks: usize = interval_rows
            .iter()
            .map(|&r| {
                (nn - 1)
                    * (usize::from(ocp.x_max[r].is_finite())
                        + usize::from(ocp.x_min[r].is_finite()))
            })
            .sum();
        // Interval constraints: one row per segment and output (segments clamped here,
        // checked in `start`).
        let seg_range =
            |c: &IntervalConstraint| c.first.min(nn - 1)..c.last.clamp(c.first.min(nn - 1), nn - 1);
        let n_fpeaks: usize = ocp
            .interval_constraints
            .iter()
            .map(|c| seg_range(c).len() * c.function.n_outputs())
            .sum();
        let n_peaks = n_peaks + n_fpeaks;
        let n_vars = vb0 + n_buffers + n_peaks;
        // Evaluation buffers of the nodal constraints, per (constraint, node).
        let (mut g_offsets, mut nodal_blocks) = (Vec::new(), Vec::new());
        let (mut gv, mut gj) = (0, 0);
        for (ci, c) in ocp.nodal.iter().enumerate() {
            for &k in &c.nodes {
                g_offsets.push((gv, gj));
                nodal_blocks.push((ci, k));
                gv += c.function.n_outputs();
                gj += c.function.jacobian_pattern().nnz();
            }
        }
        let mut trip: Vec<(usize, usize, Source)> = Vec::new();
        let mut b = Vec::new();
        let mut row = 0;
        // Dynamics rows: A x_k − x_{k+1} + B⁻[u_k; s_k] + B⁺ u_{k+1} + ν⁺ − ν⁻ = −c_k, with
        // only the structurally nonzero entries of A and B± (the transition pattern).
        let tp = ocp.dynamics.transition_pattern();
        for k in 0..nn - 1 {
            for r in 0..n {
                for j in (0..n).filter(|&j| tp.contains(r, j)) {
                    trip.push((row, x0 + k * n + j, Source::A(k * n * n + r * n + j)));
                }
                trip.push((row, x0 + (k + 1) * n + r, Source::Const(-1.0)));
                for i in (0..m).filter(|&i| tp.contains(r, n + i)) {
                    trip.push((row, u0 + k * m + i, Source::Bm(k * n * mc + r * mc + i)));
                    trip.push((row, u0 + (k + 1) * m + i, Source::Bp(k * n * mc + r * mc + i)));
                }
                trip.push((row, s0 + k, Source::Bm(k * n * mc + r * mc + m)));
                trip.push((row, vp0 + k * n + r, Source::Const(1.0)));
                trip.push((row, vm0 + k * n + r, Source::Const(-1.0)));
                b.push(0.0);
                row += 1;
            }
        }
        for (i, v) in ocp.x_initial.iter().enumerate() {
            if let Some(v) = v {
                trip.push((row, x0 + i, Source::Const(1.0)));
                b.push(*v);
                row += 1;
            }
        }
        for (i, v) in ocp.x_final.iter().enumerate() {
            if let Some(v) = v {
                trip.push((row, x0 + (nn - 1) * n + i, Source::Const(1.0)));
                b.push(*v);
                row += 1;
            }
        }
        trip.push((row, s0 + nn - 1, Source::Const(1.0)));
        trip.push((row, s0 + nn - 2, Source::Const(-1.0)));
        b.push(0.0);
        row += 1;
        let n_zero = row;
        // Inequalities `a·z ≤ b` as rows of the nonnegative cone.
        let ineq = |col: usize,
                    sign: f64,
                    bound: f64,
                    trip: &mut Vec<(usize, usize, Source)>,
                    b: &mut Vec<f64>,
                    row: &mut usize| {
            if bound.is_finite() {
                trip.push((*row, col, Source::Const(sign)));
                b.push(sign * bound);
                *row += 1;
            }
        };
        for k in 0..nn {
            for i in 0..n {
                ineq(x0 + k * n + i, 1.0, ocp.x_max[i], &mut trip, &mut b, &mut row);
                ineq(x0 + k * n + i, -1.0, ocp.x_min[i], &mut trip, &mut b, &mut row);
            }
            for i in 0..m {
                ineq(u0 + k * m + i, 1.0, ocp.u_max[i], &mut trip, &mut b, &mut row);
                ineq(u0 + k * m + i, -1.0, ocp.u_min[i], &mut trip, &mut b, &mut row);
            }
            ineq(s0 + k, 1.0, ocp.s_max, &mut trip, &mut b, &mut row);
            ineq(s0 + k, -1.0, ocp.s_min, &mut trip, &mut b, &mut row);
        }
        let dtau = 1.0 / (nn - 1) as f64;
        for (sign, bound) in [(1.0, ocp.final_time.1), (-1.0, ocp.final_time.0)] {
            if bound.is_finite() && (sign > 0.0 || bound > 0.0) {
                for k in 0..nn - 1 {
                    trip.push((row, s0 + k, Source::Const(sign * dtau)));
                }
                b.push(sign * bound);
                row += 1;
            }
        }
        for &(r, eps, first, last) in &ocp.increments {
            for k in first..last.min(nn - 1) {
                trip.push((row, x0 + (k + 1) * n + r, Source::Const(1.0)));
                trip.push((row, x0 + k * n + r, Source::Const(-1.0)));
                b.push(eps);
                row += 1;
            }
        }
        // Nodal rows ∇g·z − ν_b ≤ ∇g·z̄ − g(z̄) (values refilled per iteration).
        // Entries of output `out` of a (constraint, node) Jacobian as subproblem columns.
        let jac_row = |c: &NodalConstraint, k: usize, goff: usize, out: usize| {
            let p = c.function.jacobian_pattern();
            let mut v = Vec::new();
            for col in 0..p.ncols() {
                for nzi in p.col_ptr()[col]..p.col_ptr()[col + 1] {
                    if p.row_idx()[nzi] == out {
                        let var = if col < n { x0 + k * n + col } else { u0 + k * m + (col - n) };
                        v.push((var, goff + nzi));
                    }
                }
            }
            v
        };
        let mut nodal_rows = Vec::new();
        let mut buffers = Vec::new();
        let mut eval = 0;
        let mut ball_evals = Vec::new();
        for (ci, c) in ocp.nodal.iter().enumerate() {
            for &k in &c.nodes {
                let (_, goff) = g_offsets[eval];
                match c.kind {
                    NodalKind::Inequality => {
                        for out in 0..c.function.n_outputs() {
                            for (var, i) in jac_row(c, k, goff, out) {
                                trip.push((row, var, Source::G(i)));
                            }
                            trip.push((row, vb0 + buffers.len(), Source::Const(-1.0)));
                            nodal_rows.push(NodalRow { output: out, row, eval, cone: false });
                            buffers.push((eval, ci, Some(out)));
                            b.push(0.0);
                            row += 1;
                        }
                    }
                    NodalKind::Ball { .. } => {
                        ball_evals.push((ci, k, eval, vb0 + buffers.len()));
                        buffers.push((eval, ci, None));
                    }
                }
                eval += 1;
            }
        }
        // Interval-bound rows: sign·∇x̂_r·Δz − ν_b ≤ bound − sign·x̂_r (values per iteration).
        let mut peaks = Vec::new();
        let mut peak_src = Vec::new();
        let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * mc);
        let mut pb = vb0 + n_buffers;
        for k in 0..nn - 1 {
            for &r in &interval_rows {
                for (sign, bound) in [(1.0, ocp.x_max[r]), (-1.0, -ocp.x_min[r])] {
                    if !bound.is_finite() {
                        continue;
                    }
                    let start = peak_src.len();
                    let mut push =
                        |col: usize, off: usize, trip: &mut Vec<(usize, usize, Source)>| {
                            trip.push((row, col, Source::Peak(peak_src.len())));
                            peak_src.push(off);
                        };
                    for j in (0..n).filter(|&j| tp.contains(r, j)) {
                        push(x0 + k * n + j, phi0 + r * n + j, &mut trip);
                    }
                    for i in (0..m).filter(|&i| tp.contains(r, n + i)) {
                        push(u0 + k * m + i, bm0 + r * mc + i, &mut trip);
                        push(u0 + (k + 1) * m + i, bp0 + r * mc + i, &mut trip);
                    }
                    push(s0 + k, bm0 + r * mc + m, &mut trip);
                    trip.push((row, pb, Source::Const(-1.0)));
                    peaks.push(PeakRow {
                        seg: k,
                        of: PeakOf::State(r),
                        sign,
                        bound,
                        row,
                        src: start..peak_src.len(),
                    });
                    b.push(0.0);
                    row += 1;
                    pb += 1;
                }
            }
        }
        let mut peak_stride = vec![0; peak_src.len()];
        // Interval constraints: Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z·Δz − ν_b ≤ −ĝ_o, over the
        // columns some state row read by g_o depends on.
        let (mut intervals, mut val0, mut jac0, mut pt0) = (Vec::new(), 0, 0, 0);
        let pts = settings.discretization.substeps + 1;
        for (ci, c) in ocp.interval_constraints.iter().enumerate() {
            let jp = c.function.jacobian_pattern();
            let (nout, nnz) = (c.function.n_outputs(), jp.nnz());
            let mut deps = vec![Vec::new(); nout];
            for col in 0..jp.ncols().min(n) {
                for q in jp.col_ptr()[col]..jp.col_ptr()[col + 1] {
                    deps[jp.row_idx()[q]].push((col, q));
                }
            }
            let segs = seg_range(c);
            for k in segs.clone() {
                for (out, dep) in deps.iter().enumerate() {
                    let start = peak_src.len();
                    let reads = |col: usize| dep.iter().any(|&(r, _)| tp.contains(r, col));
                    let mut push = |col: usize, off: usize, stride: usize, trip: &mut Vec<_>| {
                        trip.push((row, col, Source::Peak(peak_src.len())));
                        peak_src.push(off);
                        peak_stride.push(stride);
                    };
                    for j in (0..n).filter(|&j| reads(j)) {
                        push(x0 + k * n + j, phi0 + j, n, &mut trip);
                    }
                    for i in (0..m).filter(|&i| reads(n + i)) {
                        push(u0 + k * m + i, bm0 + i, mc, &mut trip);
                        push(u0 + (k + 1) * m + i, bp0 + i, mc, &mut trip);
                    }
                    push(s0 + k, bm0 + m, mc, &mut trip);
                    trip.push((row, pb, Source::Const(-1.0)));
                    peaks.push(PeakRow {
                        seg: k,
                        of: PeakOf::Function { c: ci, out },
                        sign: 1.0,
                        bound: 0.0,
                        row,
                        src: start..peak_src.len(),
                    });
                    b.push(0.0);
                    row += 1;
                    pb += 1;
                }
            }
            intervals.push(IntervalMeta {
                first: segs.start,
                last: segs.end,
                nout,
                nnz,
                val0,
                jac0,
                pt0,
                points: segs.len() * pts,
                activation: c.activation.unwrap_or(f64::INFINITY),
                seg0: pt0 / pts,
                deps,
            });
            pt0 += segs.len() * pts;
            val0 += segs.len() * pts * nout;
            jac0 += segs.len() * pts * nnz;
        }
        for c in vp0..n_vars {
            ineq(c, -1.0, 0.0, &mut trip, &mut b, &mut row);
        }
        let n_nonneg = row - n_zero;
        // Balls: [radius + ν_b; g(z̄) + ∇g·(z − z̄)] in the second-order cone.
        let mut socs = Vec::new();
        for &(ci, k, ev, buffer) in &ball_evals {
            let c = &ocp.nodal[ci];
            let NodalKind::Ball { radius } = c.kind else { continue };
            trip.push((row, buffer, Source::Const(-1.0)));
            b.push(radius);
            row += 1;
            let (_, goff) = g_offsets[ev];
            for out in 0..c.function.n_outputs() {
                for (var, i) in jac_row(c, k, goff, out) {
                    trip.push((row, var, Source::NegG(i)));
                }
                nodal_rows.push(NodalRow { output: out, row, eval: ev, cone: true });
                b.push(0.0);
                row += 1;
            }
            socs.push(1 + c.function.n_outputs());
        }
        trip.sort_by_key(|t| (t.1, t.0));
        let mut a_colptr = vec![0; n_vars + 1];
        for t in &trip {
            a_colptr[t.1 + 1] += 1;
        }
        for c in 0..n_vars {
            a_colptr[c + 1] += a_colptr[c];
        }
        let a_rowval: Vec<usize> = trip.iter().map(|t| t.0).collect();
        let sources: Vec<Source> = trip.iter().map(|t| t.2).collect();
        // Quasi-Newton elements: segment k owns its dynamics rows and the nodal rows at node
        // k; its columns are those of x_k, u_k, s_k, u_{k+1} with a varying coefficient in
        // one of its rows (a state that only feeds itself, like a CTCS integral, has none).
        let mut row_elem = vec![usize::MAX; row];
        for (k, re) in row_elem.iter_mut().take((nn - 1) * n).enumerate() {
            *re = k / n;
        }
        // Evaluation blocks are numbered (constraint, node) in order: the node of each.
        let eval_node: Vec<usize> =
            ocp.nodal.iter().flat_map(|c| c.nodes.iter().copied()).collect();
        for nr in &nodal_rows {
            row_elem[nr.row] = eval_node[nr.eval];
        }
        for p in &peaks {
            row_elem[p.row] = p.seg;
        }
        let mut elements = Vec::with_capacity(nn);
        for k in 0..nn {
            let mut cand: Vec<usize> = (x0 + k * n..x0 + (k + 1) * n)
                .chain(u0 + k * m..u0 + (k + 1) * m)
                .chain(std::iter::once(s0 + k))
                .collect();
            if k + 1 < nn {
                cand.extend(u0 + (k + 1) * m..u0 + (k + 2) * m);
            }
            let cols: Vec<usize> = cand
                .into_iter()
                .filter(|&c| {
                    settings.quasi_newton
                        && (a_colptr[c]..a_colptr[c + 1]).any(|p| {
                            row_elem[a_rowval[p]] == k
                                && match sources[p] {
                                    Source::Const(_) => false,
                                    // A column of A that is only its own diagonal is constant (1).
                                    Source::A(i) => {
                                        let (r, j) = ((i % (n * n)) / n, i % n);
                                        r != j || (0..n).any(|rr| rr != j && tp.contains(rr, j))
                                    }
                                    _ => true,
                                }
                        })
                })
                .collect();
            elements.push(Element { cols, pidx: Vec::new() });
        }
        // P's pattern: every primal diagonal plus each element's upper triangle.
        let n_primal = vp0;
        let mut pairs: Vec<(usize, usize)> = (0..n_primal).map(|c| (c, c)).collect();
        for el in &elements {
            for (a, &ca) in el.cols.iter().enumerate() {
                for &cb in &el.cols[a..] {
                    pairs.push((ca.min(cb), ca.max(cb)));
                }
            }
        }
        let p_pattern = crate::sparse::CscPattern::from_entries(n_vars, pairs);
        let find = |r: usize, c: usize| p_pattern.position(r, c);
        let p_diag: Vec<usize> = (0..n_primal).map(|c| find(c, c)).collect();
        for el in &mut elements {
            let d = el.cols.len();
            el.pidx = vec![usize::MAX; d * d];
            for a in 0..d {
                for b in a..d {
                    let (ca, cb) = (el.cols[a], el.cols[b]);
                    el.pidx[a * d + b] = find(ca.min(cb), ca.max(cb));
                }
            }
        }
        let crate::sparse::CscPattern { colptr: p_colptr, rowval: p_rowval } = p_pattern;
        let dws = ocp.dynamics.workspace();
        Ptr {
            ocp,
            settings,
            n_vars,
            a_colptr,
            a_rowval,
            sources,
            b,
            n_zero,
            n_nonneg,
            dws,
            vb0,
            nodal_rows,
            peaks,
            peak_src,
            peak_stride,
            intervals,
            g_offsets,
            nodal_blocks,
            g_len: (gv, gj),
            buffers,
            socs,
            p_colptr,
            p_rowval,
            p_diag,
            elements,
            row_elem,
            state: None,
        }
    }

    /// Sizes of the convex subproblem (fixed at construction). The reduced KKT matrix's
    /// come from the interior point of the running (or last) solve; before the first solve
    /// one is analysed for them.
    pub fn dimensions(&self) -> SubproblemDimensions {
        let running =
            self.state.as_ref().and_then(|st| st.ipm.as_ref()).map(|ipm| ipm.kkt_nonzeros());
        SubproblemDimensions {
            variables: self.n_vars,
            equality_rows: self.n_zero,
            inequality_rows: self.n_nonneg,
            second_order_cones: self.socs.len(),
            cone_rows: self.socs.iter().sum(),
            nonzeros: self.a_rowval.len(),
            hessian_nonzeros: self.p_rowval.len(),
            reduced_kkt_nonzeros: running
                .or_else(|| self.interior_point().ok().map(|ipm| ipm.kkt_nonzeros())),
        }
    }

    /// The native interior point for this subproblem pattern.
    fn interior_point(&self) -> Result<InteriorPoint, crate::ipm::IpmError> {
        let cones = Cones { zero: self.n_zero, nonneg: self.n_nonneg, soc: self.socs.clone() };
        // Each node's states, controls and dilation are its stage; virtual controls and
        // buffers take theirs from the rows they enter (the KKT ordering's hint).
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (u0, s0, vp0, _) = self.layout();
        let stages: Vec<Option<usize>> = (0..self.n_vars)
            .map(|c| match c {
                c if c < u0 => Some(c / n),
                c if c < s0 => Some((c - u0) / m),
                c if c < vp0 => Some(c - s0),
                _ => None,
            })
            .collect();
        InteriorPoint::new(
            self.n_vars,
            (&self.p_colptr, &self.p_rowval),
            self.b.len(),
            (&self.a_colptr, &self.a_rowval),
            cones,
            self.settings.subproblem.interior_point(),
        )?
        .with_stages(&stages)?
        .with_switchable_rows(
            &self
                .peaks
                .iter()
                .filter(|p| {
                    let PeakOf::Function { c, .. } = p.of else { return false };
                    self.intervals[c].activation.is_finite()
                })
                .map(|p| p.row)
                .collect::<Vec<_>>(),
        )
    }

    /// The problem.
    pub fn ocp(&self) -> &Ocp {
        &self.ocp
    }

    /// Sets parameter `name` to `value` (row-major) in every compiled function that reads
    /// it — the dynamics, the nodal and the interval constraints — and returns how many do.
    /// Nothing is recompiled and the subproblem's pattern and solver are kept: the next
    /// [`start`](Self::start) or [`solve`](Self::solve) uses the new value (a re-solve, e.g.
    /// after moving a waypoint, may start from the previous solution).
    ///
    /// # Errors
    /// [`PtrError::UnknownParameter`] if no function reads `name`; a value of the wrong
    /// length or not finite ([`PtrError::Parameter`]).
    pub fn set_parameter(&mut self, name: &str, value: &[f64]) -> Result<usize, PtrError> {
        let mut count = 0;
        if self.ocp.dynamics.function().parameter_names().any(|p| p == name) {
            self.ocp.dynamics.set_parameter(name, value).map_err(PtrError::Parameter)?;
            count += 1;
        }
        let functions = self.ocp.nodal.iter_mut().map(|c| &mut c.function);
        for f in functions.chain(self.ocp.interval_constraints.iter_mut().map(|c| &mut c.function))
        {
            if f.parameter_names().any(|p| p == name) {
                f.set_parameter(name, value).map_err(PtrError::Parameter)?;
                count += 1;
            }
        }
        if count == 0 {
            return Err(PtrError::UnknownParameter(name.to_string()));
        }
        // A running solve's reference was linearised with the old value: it must restart.
        if let Some(st) = self.state.as_mut() {
            st.status.get_or_insert(PtrStatus::MaxIterations);
            st.linearized = false;
            st.ev.fgrid_reference = false;
        }
        Ok(count)
    }

    /// Evaluates every nodal constraint at `(x, u)` into the buffers (values, with `jac` their
    /// Jacobians, and per-buffer violations); returns `(Σ w·violation, largest violation)`.
    fn eval_nodal(
        &self,
        x: &[f64],
        u: &[f64],
        ev: &mut NodalEval,
        weights: &[f64],
        jac: bool,
    ) -> (f64, f64) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let blocks = &self.nodal_blocks;
        let offsets = |e: usize| if e < blocks.len() { self.g_offsets[e] } else { self.g_len };
        let weight = |e: usize| self.ocp.nodal[blocks[e].0].function.instruction_count();
        let lanes = self.eval_lanes(&mut ev.lanes);
        let (values, jacs) = (&mut ev.values[..], &mut ev.jac[..]);
        for_lanes(lanes, blocks.len(), weight, offsets, values, jacs, |lane, range, vals, jv| {
            let (v0, j0) = offsets(range.start);
            for e in range {
                let (ci, k) = blocks[e];
                let f = &self.ocp.nodal[ci].function;
                let (nout, nnz) = (f.n_outputs(), f.jacobian_pattern().nnz());
                lane.input[..n].copy_from_slice(&x[k * n..(k + 1) * n]);
                lane.input[n..n + m].copy_from_slice(&u[k * m..(k + 1) * m]);
                let (vo, jo) = self.g_offsets[e];
                let out = &mut vals[vo - v0..vo - v0 + nout];
                let jac = jac.then(|| &mut jv[jo - j0..jo - j0 + nnz]);
                // Compiled against the dynamics' groups: evaluation cannot fail on sizes.
                if f.eval(&lane.input[..n + m], &mut lane.ws[ci], out, jac).is_err() {
                    out.fill(f64::INFINITY);
                }
            }
        });
        let (mut sum, mut max) = (0.0, 0.0f64);
        for (i, &(eval, ci, out)) in self.buffers.iter().enumerate() {
            let c = &self.ocp.nodal[ci];
            let vo = self.g_offsets[eval].0;
            let v = match (out, c.kind) {
                (Some(o), _) => ev.values[vo + o],
                (None, NodalKind::Ball { radius }) => {
                    let g = &ev.values[vo..vo + c.function.n_outputs()];
                    g.iter().map(|v| v * v).sum::<f64>().sqrt() - radius
                }
                (None, NodalKind::Inequality) => 0.0,
            };
            ev.violation[i] = v.max(0.0);
            sum += weights[i] * v.max(0.0);
            max = max.max(v);
        }
        (sum, max)
    }

    /// The interval-bound rows' coefficients at `d` (with its grid sensitivities) into
    /// `ev.peak_vals`: `sign·Σ w_i ∂x_r(t_i)/∂z` over the peak's stencil; their values
    /// `sign·x̂ − bound` into `ev.peak_g`.
    fn fill_peaks(&self, d: &Discretization, ev: &mut NodalEval, at: GridAt) {
        let (stride, pts) = (self.ocp.dynamics.grid_stride(), d.grid_points);
        self.eval_interval(d, ev, at);
        // Each peak, and each interval constraint's largest peak per segment (its activation).
        ev.segment_peak.fill(f64::NEG_INFINITY);
        for (i, p) in self.peaks.iter().enumerate() {
            let (g, first, w) = self.peak(d, ev, p);
            (ev.peak_g[i], ev.stencils[i]) = (g, (first, w));
            if let PeakOf::Function { c, .. } = p.of {
                let k = self.intervals[c].seg0 + p.seg - self.intervals[c].first;
                ev.segment_peak[k] = ev.segment_peak[k].max(g);
            }
        }
        // Jacobians only at the active rows' stencil points, once each.
        self.stencil_jacobians(d, ev);
        for (i, p) in self.peaks.iter().enumerate() {
            let (first, w) = ev.stencils[i];
            let base = (p.seg * pts + first) * stride;
            match p.of {
                PeakOf::State(_) => {
                    for q in p.src.clone() {
                        let off = base + self.peak_src[q];
                        let v: f64 = (0..3)
                            .filter(|&i| w[i] != 0.0)
                            .map(|i| w[i] * d.grid[off + i * stride])
                            .sum();
                        ev.peak_vals[q] = p.sign * v;
                    }
                }
                PeakOf::Function { c, out } => {
                    // Σ_i w_i Σ_r ∂g_o/∂x_r(t_i) · ∂x_r(t_i)/∂z_col; zero when switched off.
                    let meta = &self.intervals[c];
                    ev.peak_vals[p.src.clone()].fill(0.0);
                    if !self.row_active(ev, p) {
                        continue;
                    }
                    for (i, &wi) in w.iter().enumerate().filter(|(_, w)| **w != 0.0) {
                        let point = (p.seg - meta.first) * pts + first + i;
                        let jac = &ev.fjac[meta.jac0 + point * meta.nnz..][..meta.nnz];
                        let block = base + i * stride;
                        for q in p.src.clone() {
                            let (off, rs) = (block + self.peak_src[q], self.peak_stride[q]);
                            let v: f64 = meta.deps[out]
                                .iter()
                                .map(|&(r, jq)| jac[jq] * d.grid[off + r * rs])
                                .sum();
                            ev.peak_vals[q] += wi * v;
                        }
                    }
                }
            }
        }
    }

    /// Whether interval-constraint peak row `p` is in the subproblem at the last
    /// `fill_peaks`: its constraint's largest peak on its segment lies within the
    /// constraint's activation distance of the bound ([`IntervalConstraint::activation`]).
    fn row_active(&self, ev: &NodalEval, p: &PeakRow) -> bool {
        let PeakOf::Function { c, .. } = p.of else { return true };
        let meta = &self.intervals[c];
        ev.segment_peak[meta.seg0 + p.seg - meta.first] > -meta.activation
    }

    /// The interval constraints' values at every grid point of their segments of `d`, into
    /// `ev.fgrid`; nothing to do when `d` is the reference's and `ev.fgrid` already holds its
    /// values (`at`).
    fn eval_interval(&self, d: &Discretization, ev: &mut NodalEval, at: GridAt) {
        if at == GridAt::Reference && ev.fgrid_reference {
            return;
        }
        let (lanes, grid, jacs) = (self.eval_lanes(&mut ev.lanes), &mut ev.fgrid, &mut ev.fjac);
        self.eval_grid(d, lanes, (grid, jacs), ev.fjac_at.len(), |i| i, false);
        ev.fgrid_reference = at == GridAt::Reference;
    }

    /// The interval constraints' Jacobians at the grid points of the active peak rows'
    /// stencils (`ev.stencils`, at `d`), each point once, into `ev.fjac`; `ev.fjac_at` marks
    /// them.
    fn stencil_jacobians(&self, d: &Discretization, ev: &mut NodalEval) {
        let pts = d.grid_points;
        ev.fjac_at.fill(false);
        for (p, &(first, w)) in self.peaks.iter().zip(&ev.stencils) {
            if let PeakOf::Function { c, .. } = p.of {
                if !self.row_active(ev, p) {
                    continue;
                }
                let meta = &self.intervals[c];
                for (i, _) in w.iter().enumerate().filter(|(_, w)| **w != 0.0) {
                    ev.fjac_at[meta.pt0 + (p.seg - meta.first) * pts + first + i] = true;
                }
            }
        }
        ev.stencil_points.clear();
        let marked = ev.fjac_at.iter().enumerate().filter(|(_, at)| **at);
        ev.stencil_points.extend(marked.map(|(gp, _)| gp));
        let (points, lanes) = (&ev.stencil_points, self.eval_lanes(&mut ev.lanes));
        let (grid, jacs) = (&mut ev.fgrid, &mut ev.fjac);
        self.eval_grid(d, lanes, (grid, jacs), points.len(), |i| points[i], true);
    }

    /// The interval constraints at the grid points `point(0)`, …, `point(count − 1)`
    /// (ascending, numbered as `fjac_at`) of `d` on the `lanes`: values into `grid` and, with
    /// `jac`, Jacobian nonzeros into `jacs` (`NodalEval::fgrid` and `fjac`).
    fn eval_grid(
        &self,
        d: &Discretization,
        lanes: &mut [EvalLane],
        (grid, jacs): (&mut [f64], &mut [f64]),
        count: usize,
        point: impl Fn(usize) -> usize + Sync,
        jac: bool,
    ) {
        let offsets = |i: usize| self.grid_offsets(if i < count { point(i) } else { usize::MAX });
        for_lanes(
            lanes,
            count,
            |_| 1,
            offsets,
            grid,
            jacs,
            |lane, range, vals, jv| {
                let (v0, j0) = offsets(range.start);
                for i in range {
                    let (vo, jo) = offsets(i);
                    let jac = jac.then(|| &mut jv[jo - j0..]);
                    self.interval_point(d, lane, point(i), &mut vals[vo - v0..], jac);
                }
            },
        );
    }

    /// Offsets in `NodalEval::fgrid` and `NodalEval::fjac` of grid point `gp` (numbered
    /// across the interval constraints, as `fjac_at`); past the last point, the buffers'
    /// lengths.
    fn grid_offsets(&self, gp: usize) -> (usize, usize) {
        let mut end = (0, 0);
        for meta in &self.intervals {
            if gp < meta.pt0 + meta.points {
                let i = gp - meta.pt0;
                return (meta.val0 + i * meta.nout, meta.jac0 + i * meta.nnz);
            }
            end = (meta.val0 + meta.points * meta.nout, meta.jac0 + meta.points * meta.nnz);
        }
        end
    }

    /// Grid point `gp`'s interval constraint at `d` with `lane`'s scratch: its values into
    /// `vals` (from the start) and, with `jac`, its Jacobian nonzeros into `jac`.
    fn interval_point(
        &self,
        d: &Discretization,
        lane: &mut EvalLane,
        gp: usize,
        vals: &mut [f64],
        jac: Option<&mut [f64]>,
    ) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let (stride, pts) = (self.ocp.dynamics.grid_stride(), d.grid_points);
        // The first constraint's points start at 0, so some constraint holds `gp`.
        let c = self.intervals.iter().rposition(|meta| meta.pt0 <= gp).unwrap_or(0);
        let (meta, point) = (&self.intervals[c], gp - self.intervals[c].pt0);
        let base = ((meta.first + point / pts) * pts + point % pts) * stride;
        // The controls are not read (checked in `start`).
        lane.input[..n].copy_from_slice(&d.grid[base..base + n]);
        lane.input[n..n + m].fill(0.0);
        let vals = &mut vals[..meta.nout];
        let jac = jac.map(|j| &mut j[..meta.nnz]);
        let f = &self.ocp.interval_constraints[c].function;
        if f.eval(&lane.input[..n + m], &mut lane.iws[c], vals, jac).is_err() {
            vals.fill(f64::INFINITY);
        }
    }

    /// The evaluation lanes to use: all of them when the settings ask for parallel work, else
    /// the first.
    fn eval_lanes<'a>(&self, lanes: &'a mut [EvalLane]) -> &'a mut [EvalLane] {
        let count = if self.settings.discretization.parallel { lanes.len() } else { 1 };
        &mut lanes[..count.max(1)]
    }

    /// The peak of an interval row on `d`'s grid (interval constraints: their values in
    /// `ev.fgrid`): `(sign·x̂ − bound, first grid point of the stencil, its weights)`.
    fn peak(&self, d: &Discretization, ev: &NodalEval, p: &PeakRow) -> (f64, usize, [f64; 3]) {
        let pts = d.grid_points;
        match p.of {
            PeakOf::State(r) => {
                let stride = self.ocp.dynamics.grid_stride();
                let base = p.seg * pts * stride + r;
                peak_of(pts, |j| p.sign * d.grid[base + j * stride] - p.bound)
            }
            PeakOf::Function { c, out } => {
                let meta = &self.intervals[c];
                let v0 = meta.val0 + (p.seg - meta.first) * pts * meta.nout + out;
                peak_of(pts, |j| ev.fgrid[v0 + j * meta.nout])
            }
        }
    }

    /// Σ w·(positive violation) of the interval-bound peaks at `d` and the largest
    /// violation; each peak's positive violation into `ev.violation` after the nodal ones.
    fn eval_peaks(
        &self,
        d: &Discretization,
        ev: &mut NodalEval,
        weights: &[f64],
        at: GridAt,
    ) -> (f64, f64) {
        let nb = self.buffers.len();
        self.eval_interval(d, ev, at);
        let (mut sum, mut max) = (0.0, 0.0f64);
        for (i, p) in self.peaks.iter().enumerate() {
            let v = self.peak(d, ev, p).0;
            ev.violation[nb + i] = v.max(0.0);
            sum += weights[nb + i] * v.max(0.0);
            max = max.max(v);
        }
        (sum, max)
    }

    /// Propagates the primal point `z = [X | U | S]` (defects only, into `d`) and returns its
    /// merit (see [`merit`](Self::merit)) with the propagation's wall time in ms.
    fn evaluate(
        &mut self,
        z: &[f64],
        d: &mut Discretization,
        ev: &mut NodalEval,
        prices: (&[f64], &[f64]),
    ) -> Result<(MeritValues, f64), DiscretizationError> {
        let ms = self.propagate(z, d)?;
        let (u0, s0, vp0, _) = self.layout();
        let (x, u, s) = (&z[..u0], &z[u0..s0], &z[s0..vp0]);
        Ok((self.merit(x, u, s, d, ev, prices, GridAt::Other), ms))
    }

    /// Propagates the primal point `z = [X | U | S]` (defects only, into `d`); the wall time
    /// in ms.
    fn propagate(&mut self, z: &[f64], d: &mut Discretization) -> Result<f64, DiscretizationError> {
        let (u0, s0, vp0, _) = self.layout();
        let (x, u, s) = (&z[..u0], &z[u0..s0], &z[s0..vp0]);
        let t = Instant::now();
        self.ocp.dynamics.defects(x, u, s, &self.settings.discretization, &mut self.dws, d)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }

    /// The full discretization (with the state-transition matrices) at `z` into `d`; its
    /// wall time in ms.
    fn linearize(&mut self, z: &[f64], d: &mut Discretization) -> Result<f64, DiscretizationError> {
        let (u0, s0, vp0, _) = self.layout();
        let (x, u, s) = (&z[..u0], &z[u0..s0], &z[s0..vp0]);
        let t = Instant::now();
        self.ocp.dynamics.discretize(x, u, s, &self.settings.discretization, &mut self.dws, d)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    }

    /// Merit `(J, t_f, max defect, max nodal violation)` of a trajectory (`at`: whether it
    /// is the reference).
    #[allow(clippy::too_many_arguments)]
    fn merit(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        d: &Discretization,
        ev: &mut NodalEval,
        (lam_vc, lam_vb): (&[f64], &[f64]),
        at: GridAt,
    ) -> MeritValues {
        let tf = self.final_time(s);
        let l1 = self.defect_price(d, lam_vc);
        let max = d.defect.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let (viol, max_viol) = self.eval_nodal(x, u, ev, lam_vb, false);
        let (pviol, max_pviol) = self.eval_peaks(d, ev, lam_vb, at);
        (self.cost(x, tf) + l1 + viol + pviol, tf, max, max_viol.max(max_pviol))
    }

    /// The final time of the dilations `s` (N).
    fn final_time(&self, s: &[f64]) -> f64 {
        let nn = self.ocp.nodes;
        let dtau = 1.0 / (nn - 1) as f64;
        dtau * s[..nn - 1].iter().sum::<f64>()
    }

    /// The merit's price of `d`'s defects, `Σ λ_vc,i·|defect_i|`.
    fn defect_price(&self, d: &Discretization, lam_vc: &[f64]) -> f64 {
        let n = self.ocp.dynamics.n_x();
        d.defect.iter().enumerate().map(|(i, x)| lam_vc[i % n] * x.abs()).sum()
    }

    /// The objective: time weight × final time plus the final-state cost.
    fn cost(&self, x: &[f64], tf: f64) -> f64 {
        let last = (self.ocp.nodes - 1) * self.ocp.dynamics.n_x();
        self.ocp.time_weight * tf
            + self.ocp.final_cost.iter().map(|&(i, w)| w * x[last + i]).sum::<f64>()
    }

    /// Runs PTR from the guess `(x, u, s)` (N×n, N×m, N) to the end: [`start`](Self::start),
    /// then [`step`](Self::step) until a step reports a final status.
    ///
    /// # Errors
    /// Unusable settings, guesses of the wrong size or not finite, a dynamics evaluation
    /// error. Solver outcomes (not converged, infeasible subproblem) are data in the result.
    pub fn solve(&mut self, x: &[f64], u: &[f64], s: &[f64]) -> Result<PtrResult, PtrError> {
        self.solve_with(x, u, s, |_, _| {})
    }

    /// Like [`solve`](Self::solve), calling `observer` after every iteration with its record
    /// and the current reference trajectory (the last accepted one): the hook through which
    /// progress is printed ([`IterationTable`]) or streamed.
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn solve_with(
        &mut self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        mut observer: impl FnMut(&Iteration, &Trajectory<'_>),
    ) -> Result<PtrResult, PtrError> {
        self.start(x, u, s)?;
        loop {
            let it = self.step()?;
            if let Some(t) = self.trajectory() {
                observer(&it, &t);
            }
            if it.status.is_some() {
                break;
            }
        }
        self.result().ok_or(PtrError::NotRunning)
    }

    /// Sets the reference to the guess `(x, u, s)` (N×n, N×m, N), discretizes it and resets
    /// the weights and the history; [`step`](Self::step) then iterates. Reuses every buffer
    /// (and the subproblem solver) of an earlier solve of this `Ptr`.
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn start(&mut self, x: &[f64], u: &[f64], s: &[f64]) -> Result<(), PtrError> {
        self.settings.validate()?;
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        if let Some(&row) = self.ocp.interval_bounds.iter().find(|&&r| r >= n) {
            return Err(PtrError::IntervalBoundRow { row, states: n });
        }
        for c in &self.ocp.nodal {
            let bad = |reason| Err(PtrError::NodalConstraint { name: c.name.clone(), reason });
            let names = c.output_names.len();
            if names > 0 && matches!(c.kind, NodalKind::Ball { .. }) {
                return bad("a ball constraint is one constraint: its entries take no names");
            }
            if names > 0 && names != c.function.n_outputs() {
                return bad("output_names must name every entry of g, or none");
            }
        }
        for c in &self.ocp.interval_constraints {
            let bad = |reason| Err(PtrError::IntervalConstraint { name: c.name.clone(), reason });
            if !(c.first < c.last && c.last < nn) {
                return bad("its segments first..last must satisfy first < last ≤ N − 1");
            }
            if c.function.n_inputs() != n + m {
                return bad("it must be compiled against the groups [states], [controls]");
            }
            if c.reads_controls(n) {
                return bad(
                    "it reads the controls; an interval constraint may read the states only",
                );
            }
            if c.activation.is_some_and(|a| a.is_nan() || a <= 0.0) {
                return bad("its activation distance must be positive (or None)");
            }
        }
        for (what, v, len) in [("x", x, nn * n), ("u", u, nn * m), ("s", s, nn)] {
            if v.len() != len {
                return Err(PtrError::GuessSize { what, expected: len, got: v.len() });
            }
            if let Some(index) = v.iter().position(|v| !v.is_finite()) {
                return Err(PtrError::GuessNotFinite { what, index });
            }
        }
        let mut st = match self.state.take() {
            Some(st) => st,
            None => Box::new(self.iterate()),
        };
        st.xb.copy_from_slice(x);
        st.ub.copy_from_slice(u);
        st.sb.copy_from_slice(s);
        let t0 = Instant::now();
        let disc = self.ocp.dynamics.discretize(
            x,
            u,
            s,
            &self.settings.discretization,
            &mut self.dws,
            &mut st.dbar,
        );
        st.timings =
            Timings { discretization_ms: t0.elapsed().as_secs_f64() * 1e3, ..Timings::default() };
        disc?;
        st.lam_vc.fill(self.settings.lam_vc);
        st.lam_vb.fill(self.settings.lam_vb);
        st.lam_tr = self.settings.lam_tr;
        // A new solve does not warm-start from the last one's subproblem.
        if let Some(ipm) = st.ipm.as_mut() {
            ipm.reset();
        }
        st.hess_ready.fill(false);
        st.scale_objective = false;
        st.linearized = false;
        st.history.clear();
        st.history.reserve(self.settings.max_iterations);
        st.status = None;
        st.ev.fgrid_reference = false;
        let prices = (&st.lam_vc[..], &st.lam_vb[..]);
        (st.jbar, st.tf, _, _) =
            self.merit(x, u, s, &st.dbar, &mut st.ev, prices, GridAt::Reference);
        self.state = Some(st);
        Ok(())
    }

    /// One PTR iteration: linearize at the reference, solve the convex subproblem, accept or
    /// reject the candidate, update the weights. The record's `status` is set on the final
    /// iteration (converged, iteration cap, stalled, subproblem infeasible or failed).
    ///
    /// # Errors
    /// [`PtrError::NotRunning`] before [`start`](Self::start) or after a final iteration; a
    /// dynamics evaluation error.
    pub fn step(&mut self) -> Result<Iteration, PtrError> {
        let mut st = self.state.take().ok_or(PtrError::NotRunning)?;
        let out =
            if st.status.is_some() { Err(PtrError::NotRunning) } else { self.step_in(&mut st) };
        self.state = Some(st);
        out
    }

    /// The current reference trajectory (the last accepted one), once started.
    pub fn trajectory(&self) -> Option<Trajectory<'_>> {
        self.state.as_ref().map(|st| Trajectory {
            nodes: self.ocp.nodes,
            x: &st.xb,
            u: &st.ub,
            s: &st.sb,
            final_time: st.tf,
        })
    }

    /// The result so far: the reference trajectory, its constraint violations, the history
    /// and the status (`MaxIterations` while still running).
    pub fn result(&mut self) -> Option<PtrResult> {
        let mut st = self.state.take()?;
        let violations = self.violations(&mut st);
        let max_violation = violations
            .iter()
            .filter(|v| v.value > 0.0)
            .max_by(|a, b| a.value.total_cmp(&b.value))
            .cloned();
        let r = PtrResult {
            status: st.status.unwrap_or(PtrStatus::MaxIterations),
            x: st.xb.clone(),
            u: st.ub.clone(),
            s: st.sb.clone(),
            final_time: st.tf,
            history: st.history.clone(),
            violations,
            max_violation,
            timings: st.timings,
        };
        self.state = Some(st);
        Some(r)
    }

    /// Largest violation of each constraint at the reference: the dynamics defect of each
    /// state row (over its segments) and each nodal constraint (over its nodes).
    fn violations(&self, st: &mut Iterate) -> Vec<Violation> {
        let (n, nn) = (self.ocp.dynamics.n_x(), self.ocp.nodes);
        let mut out = Vec::new();
        for r in 0..n {
            let (k, d) = (0..nn - 1)
                .map(|k| (k, st.dbar.defect[k * n + r].abs()))
                .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
            out.push(Violation {
                constraint: format!(
                    "dynamics of {}",
                    self.ocp.dynamics.state_name(r).unwrap_or("state")
                ),
                value: d,
                node: Some(k),
            });
        }
        let zeros = vec![0.0; st.lam_vb.len()];
        self.eval_nodal(&st.xb, &st.ub, &mut st.ev, &zeros, false);
        let mut i = 0;
        for c in &self.ocp.nodal {
            let per_node = match c.kind {
                NodalKind::Inequality => c.function.n_outputs(),
                NodalKind::Ball { .. } => 1,
            };
            // One report per distinct entry name, else one for the whole constraint: each
            // entry's report.
            let first = out.len();
            let mut slot = Vec::with_capacity(per_node);
            for o in 0..per_node {
                let name = c.output_names.get(o).unwrap_or(&c.name);
                match out[first..].iter().position(|v| v.constraint == *name) {
                    Some(i) => slot.push(first + i),
                    None => {
                        slot.push(out.len());
                        out.push(Violation { constraint: name.clone(), value: 0.0, node: None });
                    }
                }
            }
            if slot.is_empty() {
                out.push(Violation { constraint: c.name.clone(), value: 0.0, node: None });
            }
            for &k in &c.nodes {
                for &o in &slot {
                    let worst = &mut out[o];
                    if st.ev.violation[i] > worst.value || worst.node.is_none() {
                        worst.value = worst.value.max(st.ev.violation[i]);
                        worst.node = Some(k);
                    }
                    i += 1;
                }
            }
        }
        // Interval bounds: the worst peak of each state row over the segments (the node is
        // the segment's first).
        self.eval_peaks(&st.dbar, &mut st.ev, &zeros, GridAt::Reference);
        let nb = self.buffers.len();
        // The worst peak of each interval constraint likewise.
        // (One entry per state row or interval constraint, whichever output.)
        let key = |of: PeakOf| match of {
            PeakOf::State(r) => (0, r),
            PeakOf::Function { c, .. } => (1, c),
        };
        let mut keys: Vec<(u8, usize)> = self.peaks.iter().map(|p| key(p.of)).collect();
        keys.sort_unstable();
        keys.dedup();
        for k in keys {
            let constraint = match k {
                (0, r) => format!(
                    "bounds of {} between nodes",
                    self.ocp.dynamics.state_name(r).unwrap_or("state")
                ),
                (_, c) => format!("{} between nodes", self.ocp.interval_constraints[c].name),
            };
            let mut worst = Violation { constraint, value: 0.0, node: None };
            for (i, p) in self.peaks.iter().enumerate().filter(|(_, p)| key(p.of) == k) {
                let v = st.ev.violation[nb + i];
                if v > worst.value || worst.node.is_none() {
                    (worst.value, worst.node) = (v, Some(p.seg));
                }
            }
            out.push(worst);
        }
        out
    }

    /// An empty discretization for this problem (with the integration grid when it has
    /// interval bounds).
    fn output(&self) -> Discretization {
        let nn = self.ocp.nodes;
        if self.peaks.is_empty() {
            self.ocp.dynamics.output(nn)
        } else {
            self.ocp.dynamics.output_with_grid(nn, self.settings.discretization.substeps)
        }
    }

    /// Buffers and subproblem data of a solve (allocated once per `Ptr`).
    fn iterate(&self) -> Iterate {
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        let pts = self.settings.discretization.substeps + 1;
        let (u0, s0, vp0, _) = self.layout();
        let n_primal = vp0;
        // Trust-region scale per variable: S = max(1, range/2) from its bounds (OpenSCvx's
        // affine scaling), so the region is measured in comparable units.
        let scale_of = |lo: f64, hi: f64| {
            if lo.is_finite() && hi.is_finite() { (0.5 * (hi - lo)).max(1.0) } else { 1.0 }
        };
        let inv_s2: Vec<f64> = (0..n_primal)
            .map(|i| {
                let sc = if i < u0 {
                    scale_of(self.ocp.x_min[i % n], self.ocp.x_max[i % n])
                } else if i < s0 {
                    scale_of(
                        self.ocp.u_min[(i - u0) % m.max(1)],
                        self.ocp.u_max[(i - u0) % m.max(1)],
                    )
                } else {
                    scale_of(self.ocp.s_min, self.ocp.s_max)
                };
                1.0 / (sc * sc)
            })
            .collect();
        let dmax = self.elements.iter().map(|e| e.cols.len()).max().unwrap_or(0);
        let mut cones: Vec<SupportedConeT<f64>> =
            vec![ZeroConeT(self.n_zero), NonnegativeConeT(self.n_nonneg)];
        cones.extend(self.socs.iter().map(|&d| SecondOrderConeT(d)));
        Iterate {
            xb: vec![0.0; nn * n],
            ub: vec![0.0; nn * m],
            sb: vec![0.0; nn],
            dbar: self.output(),
            dcand: self.output(),
            ev: NodalEval {
                lanes: (0..rayon::current_num_threads().max(1))
                    .map(|_| EvalLane {
                        ws: self.ocp.nodal.iter().map(|c| c.function.workspace()).collect(),
                        iws: self
                            .ocp
                            .interval_constraints
                            .iter()
                            .map(|c| c.function.workspace())
                            .collect(),
                        input: vec![0.0; n + m],
                    })
                    .collect(),
                values: vec![0.0; self.g_len.0],
                jac: vec![0.0; self.g_len.1],
                violation: vec![0.0; self.buffers.len() + self.peaks.len()],
                peak_vals: vec![0.0; self.peak_src.len()],
                peak_g: vec![0.0; self.peaks.len()],
                fgrid: vec![
                    0.0;
                    self.intervals.iter().map(|m| (m.last - m.first) * pts * m.nout).sum()
                ],
                fjac: vec![
                    0.0;
                    self.intervals.iter().map(|m| (m.last - m.first) * pts * m.nnz).sum()
                ],
                fjac_at: vec![false; self.intervals.iter().map(|m| (m.last - m.first) * pts).sum()],
                stencil_points: Vec::with_capacity(
                    self.intervals.iter().map(|m| (m.last - m.first) * pts).sum(),
                ),
                stencils: vec![(0, [0.0; 3]); self.peaks.len()],
                fgrid_reference: false,
                segment_peak: vec![0.0; self.intervals.iter().map(|m| m.last - m.first).sum()],
            },
            lam_vc: vec![0.0; n],
            lam_vb: vec![0.0; self.buffers.len() + self.peaks.len()],
            lam_tr: 0.0,
            jbar: 0.0,
            tf: 0.0,
            history: Vec::new(),
            hess: self.elements.iter().map(|e| vec![0.0; e.cols.len() * e.cols.len()]).collect(),
            hess_ready: vec![false; self.elements.len()],
            duals: vec![0.0; self.b.len()],
            nz_new: vec![0.0; self.a_rowval.len()],
            qn_s: vec![0.0; dmax],
            qn_g: vec![0.0; dmax],
            qn_hs: vec![0.0; dmax],
            qn_r: vec![0.0; dmax],
            status: None,
            timings: Timings::default(),
            q: vec![0.0; self.n_vars],
            zbar: vec![0.0; n_primal],
            zc: vec![0.0; n_primal],
            pvals: vec![0.0; self.p_rowval.len()],
            inv_s2,
            nz: vec![0.0; self.a_rowval.len()],
            b: self.b.clone(),
            cones,
            solver: None,
            ipm: None,
            ipm_unusable: false,
            sol_x: vec![0.0; self.n_vars],
            sol_z: vec![0.0; self.b.len()],
            p_scaled: vec![0.0; self.p_rowval.len()],
            q_scaled: vec![0.0; self.n_vars],
            scale_objective: false,
            linearized: false,
        }
    }

    /// The subproblem's constraint values at the reference: `A`'s values (`st.nz`) from the
    /// discretization, the nodal constraints' Jacobians and the peak rows, and the
    /// right-hand sides `st.b` in deviation form.
    fn linearize_constraints(&self, st: &mut Iterate) {
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

    fn step_in(&mut self, st: &mut Iterate) -> Result<Iteration, PtrError> {
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
    fn fill_p(&self, st: &mut Iterate, qn: bool) {
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

    /// Solve the assembled subproblem into `st.sol_x`/`st.sol_z`: the native interior point
    /// (warm-started; retried with the objective scaled when it fails) when chosen, Clarabel
    /// otherwise or when the native solves fail.
    fn solve_subproblem(
        &self,
        st: &mut Iterate,
        set: &SubproblemSettings,
        record: &mut Iteration,
    ) -> Result<(), PtrStatus> {
        let nv = self.n_vars;
        if set.solver == SubproblemSolver::InteriorPoint && st.ipm.is_none() && !st.ipm_unusable {
            st.ipm = self.interior_point().ok();
            st.ipm_unusable = st.ipm.is_none();
        }
        if let (SubproblemSolver::InteriorPoint, Some(ipm)) = (set.solver, st.ipm.as_mut()) {
            // The objective as given, unless a solve of this run already needed it scaled:
            // then divided by λ_tr (a safeguard for a KKT matrix a heavy trust-region weight
            // leaves badly scaled). The minimizer is the same; the duals scale back. A
            // failure at a lighter λ_tr goes to Clarabel as it is.
            let sigma = st.lam_tr.max(1.0);
            let mut scaled = st.scale_objective;
            loop {
                let s = if scaled { sigma } else { 1.0 };
                // The same accuracy in the original units: the gap tolerance scales too.
                ipm.set_objective_scale(s);
                let status = if scaled {
                    for (d, v) in st.p_scaled.iter_mut().zip(&st.pvals) {
                        *d = v / s;
                    }
                    for (d, v) in st.q_scaled.iter_mut().zip(&st.q) {
                        *d = v / s;
                    }
                    ipm.solve(&st.p_scaled, &st.q_scaled, &st.nz, &st.b)
                } else {
                    ipm.solve(&st.pvals, &st.q, &st.nz, &st.b)
                };
                record.subproblem_iterations += ipm.iterations();
                if status == IpmStatus::Solved {
                    record.subproblem_status = "Solved";
                    st.sol_x.copy_from_slice(ipm.x());
                    for (d, z) in st.sol_z.iter_mut().zip(ipm.z()) {
                        *d = z * s;
                    }
                    st.scale_objective |= scaled;
                    return Ok(());
                }
                if scaled || sigma <= HEAVY_TRUST_REGION {
                    break;
                }
                scaled = true;
                ipm.reset();
            }
        }
        // Clarabel: in-place update when the solver exists (same pattern); rebuild if that
        // fails.
        if let Some(sv) = st.solver.as_mut() {
            let updated = sv.update_P(&st.pvals).is_ok()
                && sv.update_q(&st.q).is_ok()
                && sv.update_A(&st.nz).is_ok()
                && sv.update_b(&st.b).is_ok();
            if !updated {
                st.solver = None;
            }
        }
        if st.solver.is_none() {
            let pm = CscMatrix::new(
                nv,
                nv,
                self.p_colptr.clone(),
                self.p_rowval.clone(),
                st.pvals.clone(),
            );
            let am = CscMatrix::new(
                st.b.len(),
                nv,
                self.a_colptr.clone(),
                self.a_rowval.clone(),
                st.nz.clone(),
            );
            st.solver = DefaultSolver::new(&pm, &st.q, &am, &st.b, &st.cones, set.clarabel()).ok();
        }
        let Some(sv) = st.solver.as_mut() else {
            return Err(PtrStatus::NumericalFailure);
        };
        sv.solve();
        record.subproblem_iterations += sv.solution.iterations;
        record.subproblem_status = status_name(sv.solution.status);
        match sv.solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                st.sol_x.copy_from_slice(&sv.solution.x);
                st.sol_z.copy_from_slice(&sv.solution.z);
                Ok(())
            }
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                Err(PtrStatus::SubproblemInfeasible)
            }
            _ => Err(PtrStatus::NumericalFailure),
        }
    }

    fn update_hessian(&self, st: &mut Iterate) {
        // The constraint Jacobians at the candidate (its merit needed their values only).
        let (u0, s0, _, _) = self.layout();
        self.eval_nodal(&st.zc[..u0], &st.zc[u0..s0], &mut st.ev, &st.lam_vb, true);
        self.fill_peaks(&st.dcand, &mut st.ev, GridAt::Other);
        fill_values(&self.sources, &st.dcand, &st.ev, &st.ev.peak_vals, &mut st.nz_new);
        for (e, el) in self.elements.iter().enumerate() {
            let d = el.cols.len();
            if d == 0 {
                continue;
            }
            let (sv, gv) = (&mut st.qn_s[..d], &mut st.qn_g[..d]);
            for (a, &c) in el.cols.iter().enumerate() {
                sv[a] = st.zc[c] - st.zbar[c];
                gv[a] = (self.a_colptr[c]..self.a_colptr[c + 1])
                    .filter(|&p| self.row_elem[self.a_rowval[p]] == e)
                    .map(|p| (st.nz_new[p] - st.nz[p]) * st.duals[self.a_rowval[p]])
                    .sum();
            }
            let ss: f64 = sv.iter().zip(&el.cols).map(|(x, &c)| x * x * st.inv_s2[c]).sum();
            let sy: f64 = sv.iter().zip(gv.iter()).map(|(a, b)| a * b).sum();
            if ss < 1e-20 {
                continue;
            }
            let h = &mut st.hess[e];
            if !st.hess_ready[e] {
                // Initial scaled identity γ·S⁻² with γ = ‖ŷ‖²/ŷᵀŝ (Nocedal–Wright 6.20) in the
                // trust-region scaling.
                let yy: f64 = gv.iter().zip(&el.cols).map(|(g, &c)| g * g / st.inv_s2[c]).sum();
                if sy <= 1e-12 * (yy * ss).sqrt() {
                    continue;
                }
                let gamma = QN_INITIAL_SCALE * yy / sy;
                h.fill(0.0);
                for (a, &c) in el.cols.iter().enumerate() {
                    h[a * d + a] = gamma * st.inv_s2[c];
                }
                st.hess_ready[e] = true;
            }
            damped_bfgs(h, sv, gv, &mut st.qn_hs[..d], &mut st.qn_r[..d]);
        }
    }

    /// Records the final iteration with its status.
    fn finish(&self, st: &mut Iterate, mut record: Iteration, status: PtrStatus) -> Iteration {
        record.status = Some(status);
        st.status = Some(status);
        st.history.push(record.clone());
        record
    }
}

/// Sizes of the convex subproblem `min ½zᵀPz + qᵀz s.t. Az + s = b, s ∈ K`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct SubproblemDimensions {
    /// Unknowns (states, controls, dilations, virtual controls and buffers).
    pub variables: usize,
    /// Rows of the zero cone (linearized dynamics, boundary conditions).
    pub equality_rows: usize,
    /// Rows of the nonnegative cone (bounds, CTCS increments, linearized nodal constraints).
    pub inequality_rows: usize,
    /// Number of second-order cones (balls).
    pub second_order_cones: usize,
    /// Rows in second-order cones.
    pub cone_rows: usize,
    /// Structural nonzeros of `A`.
    pub nonzeros: usize,
    /// Structural nonzeros of the upper triangle of `P`: the trust-region diagonal plus,
    /// with [`PtrSettings::quasi_newton`], the Hessian blocks.
    pub hessian_nonzeros: usize,
    /// Nonzeros of the native interior point's reduced KKT matrix (upper triangle) and of
    /// its LDLᵀ factor (after the fill-reducing ordering): what each of its iterations
    /// factors. `None` if the pattern cannot be analysed (Clarabel then solves everything).
    pub reduced_kkt_nonzeros: Option<(usize, usize)>,
}

/// The Lagrangian merit's shift of the ℓ1 merit for the defects `d` (state rows cycle with
/// period `lam_vc.len()`): per row `(σ − 1)·λ·|d| − ŷ·d`, with the dual `y` clipped to
/// `ŷ ∈ [−σλ, σλ]`. The row's merit term `λ|d| + shift` then lies in `[0, 2σλ|d|]`: never
/// negative, so the merit stays bounded below. With the raw dual it is
/// `σλ|d| − y·d`, which decreases without bound along `sign(y)` wherever `|y| > σλ` — on the
/// seed's collision CTCS row (dual ≈ 2000, price ≈ 2500, σ = 0.5) steps that grew that
/// row's defect were accepted as improvements until the trust region hit its cap, and the
/// run ended at the iteration cap, infeasible.
fn lagrangian_shift(d: &[f64], duals: &[f64], lam_vc: &[f64], sigma: f64) -> f64 {
    let n = lam_vc.len();
    d.iter()
        .zip(duals)
        .enumerate()
        .map(|(i, (di, yi))| {
            let l = lam_vc[i % n];
            (sigma - 1.0) * l * di.abs() - yi.clamp(-sigma * l, sigma * l) * di
        })
        .sum()
}

/// Powell's damped BFGS update of the symmetric positive-definite `h` (`d×d`, row-major)
/// with the step `s` and the gradient difference `y`: `y` is replaced by
/// `r = θy + (1 − θ)Hs` with θ < 1 only when `sᵀy < 0.2·sᵀHs`, so `sᵀr ≥ 0.2·sᵀHs > 0` and
/// `H⁺ = H − HssᵀH/sᵀHs + rrᵀ/sᵀr` stays positive definite and satisfies `H⁺s = r` (the
/// secant equation when undamped). `hs` and `r` are scratch of length `d`. Returns false
/// (and leaves `h`) when `sᵀHs` is zero.
fn damped_bfgs(h: &mut [f64], s: &[f64], y: &[f64], hs: &mut [f64], r: &mut [f64]) -> bool {
    let d = s.len();
    for a in 0..d {
        hs[a] = (0..d).map(|b| h[a * d + b] * s[b]).sum();
    }
    let shs: f64 = s.iter().zip(hs.iter()).map(|(a, b)| a * b).sum();
    if shs <= 1e-300 {
        return false;
    }
    let sy: f64 = s.iter().zip(y).map(|(a, b)| a * b).sum();
    let theta = if sy >= 0.2 * shs { 1.0 } else { 0.8 * shs / (shs - sy) };
    for a in 0..d {
        r[a] = theta * y[a] + (1.0 - theta) * hs[a];
    }
    let sr: f64 = s.iter().zip(r.iter()).map(|(a, b)| a * b).sum();
    for a in 0..d {
        for b in 0..d {
            h[a * d + b] += r[a] * r[b] / sr - hs[a] * hs[b] / shs;
        }
    }
    true
}

/// A trajectory's merit `J`, final time, largest defect and largest nodal violation.
type MeritValues = (f64, f64, f64, f64);

/// Runs `f(lane, jobs, vals, jacs)` over the jobs `0..count` split into contiguous chunks of
/// about equal total `weight`, one per lane: the first on the calling thread, the others
/// spawned on the rayon pool (one small allocation each, as the discretization's lanes).
/// Job `j`'s outputs start at `offsets(j)` in `vals` and in `jacs`, non-decreasing in `j`
/// (`offsets(count)`: where the last job's end); each chunk gets the parts of both buffers
/// from its first job's offsets up to the next chunk's.
fn for_lanes<F>(
    lanes: &mut [EvalLane],
    count: usize,
    weight: impl Fn(usize) -> usize,
    offsets: impl Fn(usize) -> (usize, usize),
    vals: &mut [f64],
    jacs: &mut [f64],
    f: F,
) where
    F: Fn(&mut EvalLane, std::ops::Range<usize>, &mut [f64], &mut [f64]) + Sync,
{
    let (v0, j0) = offsets(0);
    let (mut vals, mut jacs) = (&mut vals[v0..], &mut jacs[j0..]);
    let lanes_used = lanes.len().min(count).max(1);
    if lanes_used == 1 {
        f(&mut lanes[0], 0..count, vals, jacs);
        return;
    }
    let (mut at, mut start) = ((v0, j0), 0);
    let total: usize = (0..count).map(&weight).sum();
    let (mut done, f) = (0, &f);
    rayon::in_place_scope(|scope| {
        let mut first = None;
        for (i, lane) in lanes[..lanes_used].iter_mut().enumerate() {
            let mut end = start;
            let target = total * (i + 1) / lanes_used;
            while end < count && (done < target || i + 1 == lanes_used) {
                done += weight(end);
                end += 1;
            }
            let next = offsets(end);
            let (mine_v, rest_v) = std::mem::take(&mut vals).split_at_mut(next.0 - at.0);
            let (mine_j, rest_j) = std::mem::take(&mut jacs).split_at_mut(next.1 - at.1);
            (vals, jacs, at) = (rest_v, rest_j, next);
            let range = start..end;
            start = end;
            if i == 0 {
                first = Some((lane, range, mine_v, mine_j));
            } else {
                scope.spawn(move |_| f(lane, range, mine_v, mine_j));
            }
        }
        if let Some((lane, range, v, j)) = first {
            f(lane, range, v, j);
        }
    });
}

/// The constraint matrix's values from their sources at one linearization.
fn fill_values(
    sources: &[Source],
    d: &Discretization,
    ev: &NodalEval,
    peak_vals: &[f64],
    out: &mut [f64],
) {
    for (v, src) in out.iter_mut().zip(sources) {
        *v = match *src {
            Source::Const(c) => c,
            Source::A(i) => d.a[i],
            Source::Bm(i) => d.b_minus[i],
            Source::Bp(i) => d.b_plus[i],
            Source::G(i) => ev.jac[i],
            Source::NegG(i) => -ev.jac[i],
            Source::Peak(i) => peak_vals[i],
        };
    }
}

/// The peak of `g` over the grid points `0..pts`: `(ĝ, first grid point of the stencil, its
/// Lagrange weights)`. The discrete maximum is refined by the parabola through it and its
/// neighbours (the vertex, when the parabola is concave and the vertex lies between them);
/// `ĝ = Σ w_i g_i` (the weights sum to 1).
fn peak_of(pts: usize, g: impl Fn(usize) -> f64) -> (f64, usize, [f64; 3]) {
    let best = (1..pts).fold(0, |b, j| if g(j) > g(b) { j } else { b });
    if pts < 3 {
        return (g(best), best, [1.0, 0.0, 0.0]);
    }
    let c = best.clamp(1, pts - 2);
    let (gm, g0, gp) = (g(c - 1), g(c), g(c + 1));
    let curv = gm - 2.0 * g0 + gp;
    let theta =
        if curv < 0.0 { (0.5 * (gm - gp) / curv).clamp(-1.0, 1.0) } else { best as f64 - c as f64 };
    let w = [0.5 * theta * (theta - 1.0), 1.0 - theta * theta, 0.5 * theta * (theta + 1.0)];
    (w[0] * gm + w[1] * g0 + w[2] * gp, c - 1, w)
}

/// Clarabel's status as a static name (no allocation per iteration).
fn status_name(s: SolverStatus) -> &'static str {
    match s {
        SolverStatus::Solved => "Solved",
        SolverStatus::AlmostSolved => "AlmostSolved",
        SolverStatus::PrimalInfeasible => "PrimalInfeasible",
        SolverStatus::AlmostPrimalInfeasible => "AlmostPrimalInfeasible",
        SolverStatus::DualInfeasible => "DualInfeasible",
        SolverStatus::AlmostDualInfeasible => "AlmostDualInfeasible",
        SolverStatus::MaxIterations => "MaxIterations",
        SolverStatus::MaxTime => "MaxTime",
        SolverStatus::NumericalError => "NumericalError",
        SolverStatus::InsufficientProgress => "InsufficientProgress",
        _ => "Other",
    }
}

/// The reference trajectory of a running solve (borrowed from the solver).
#[derive(Debug, Clone, Copy)]
pub struct Trajectory<'a> {
    /// Number of nodes N.
    pub nodes: usize,
    /// States, N×n row-major.
    pub x: &'a [f64],
    /// Controls, N×m row-major.
    pub u: &'a [f64],
    /// Dilations, N.
    pub s: &'a [f64],
    /// Final time `Δτ·Σ_{k<N−1} s_k`.
    pub final_time: f64,
}

/// Errors of [`Ptr`]: bad input, never solver outcomes (those are [`PtrStatus`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PtrError {
    /// An unusable setting.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// A guess of the wrong length.
    #[error("initial guess `{what}` has {got} entries, expected {expected}")]
    GuessSize {
        /// `x`, `u` or `s`.
        what: &'static str,
        /// N·n, N·m or N.
        expected: usize,
        /// What was given.
        got: usize,
    },
    /// A guess entry that is NaN or infinite.
    #[error("initial guess `{what}` entry {index} is not finite")]
    GuessNotFinite {
        /// `x`, `u` or `s`.
        what: &'static str,
        /// Flat index of the entry.
        index: usize,
    },
    /// The dynamics could not be discretized.
    #[error(transparent)]
    Discretization(#[from] DiscretizationError),
    /// No function of the problem reads this parameter.
    #[error("no function of the problem reads a parameter named `{0}`")]
    UnknownParameter(String),
    /// A parameter value the function rejects (wrong length, not finite).
    #[error("parameter: {0}")]
    Parameter(armature_symbolic::SymbolicError),
    /// [`Ocp::interval_bounds`] names a state row the problem does not have.
    #[error("interval bound on state row {row}, but the problem has {states} state rows")]
    IntervalBoundRow {
        /// The row.
        row: usize,
        /// The number of state rows.
        states: usize,
    },
    /// A [`NodalConstraint`] the solver cannot use.
    #[error("nodal constraint `{name}`: {reason}")]
    NodalConstraint {
        /// Its name.
        name: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// An [`IntervalConstraint`] the solver cannot use.
    #[error("interval constraint `{name}`: {reason}")]
    IntervalConstraint {
        /// Its name.
        name: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// [`Ptr::step`] before [`Ptr::start`] or after the final iteration.
    #[error("no solve is running: call start() first (a finished solve takes no more steps)")]
    NotRunning,
}

/// The largest violation of one constraint at a trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Violation {
    /// The constraint's name (`dynamics of angle[2]`, a nodal constraint's name).
    pub constraint: String,
    /// Its largest violation (≥ 0; a dynamics defect in the state's units).
    pub value: f64,
    /// The node (for dynamics: the segment's first node) where it is largest.
    pub node: Option<usize>,
}

/// Wall-clock totals of a solve (ms).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timings {
    /// All discretizations (the guess's and every candidate's).
    pub discretization_ms: f64,
    /// All convex subproblems (update or setup, and solve).
    pub subproblem_ms: f64,
}

/// The SCvx iteration table (one header, one row per [`Iteration`]), to any writer.
///
/// ```
/// use armature_scvx::IterationTable;
/// let mut out = Vec::new();
/// IterationTable::header(&mut out).unwrap();
/// assert!(String::from_utf8(out).unwrap().contains("J_vc"));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct IterationTable;

impl IterationTable {
    /// Writes the column headers.
    ///
    /// # Errors
    /// The writer's.
    pub fn header(w: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(
            w,
            "{:>4} {:>3} {:>8} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>8} {:>4}  subproblem",
            "iter",
            "acc",
            "disc ms",
            "solve ms",
            "cost",
            "J_tr",
            "J_vb",
            "J_vc",
            "defect",
            "violation",
            "TR grad",
            "λ_tr",
            "ipm"
        )
    }

    /// Writes one iteration's row (and its final status, if any, on the next line).
    ///
    /// # Errors
    /// The writer's.
    pub fn row(w: &mut impl std::io::Write, it: &Iteration) -> std::io::Result<()> {
        writeln!(
            w,
            "{:>4} {:>3} {:>8.2} {:>8.2} {:>10.6} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>8.1e} {:>4}  {}",
            it.iteration,
            if it.accepted { "yes" } else { "no" },
            it.discretization_ms,
            it.subproblem_ms,
            it.cost,
            it.j_tr,
            it.j_vb,
            it.j_vc,
            it.max_defect,
            it.max_violation,
            it.tr_gradient,
            it.lam_tr,
            it.subproblem_iterations,
            it.subproblem_status
        )?;
        if let Some(status) = it.status {
            writeln!(w, "stopped: {status:?}")?;
        }
        Ok(())
    }
}

/// The state of a running solve: the reference, the weights and the subproblem's data and
/// solver (kept between solves of the same [`Ptr`]).
struct Iterate {
    xb: Vec<f64>,
    ub: Vec<f64>,
    sb: Vec<f64>,
    dbar: Discretization,
    dcand: Discretization,
    ev: NodalEval,
    lam_vc: Vec<f64>,
    lam_vb: Vec<f64>,
    lam_tr: f64,
    jbar: f64,
    tf: f64,
    history: Vec<Iteration>,
    /// Per element: its Hessian approximation (`d×d`, row-major) and whether it has one.
    hess: Vec<Vec<f64>>,
    hess_ready: Vec<bool>,
    /// Duals of the last subproblem.
    duals: Vec<f64>,
    /// Constraint coefficients at the candidate.
    nz_new: Vec<f64>,
    /// Element scratch: step, gradient difference, H·step, damped difference.
    qn_s: Vec<f64>,
    qn_g: Vec<f64>,
    qn_hs: Vec<f64>,
    qn_r: Vec<f64>,
    status: Option<PtrStatus>,
    timings: Timings,
    q: Vec<f64>,
    zbar: Vec<f64>,
    zc: Vec<f64>,
    pvals: Vec<f64>,
    inv_s2: Vec<f64>,
    nz: Vec<f64>,
    b: Vec<f64>,
    cones: Vec<SupportedConeT<f64>>,
    solver: Option<DefaultSolver<f64>>,
    ipm: Option<InteriorPoint>,
    /// The native solver could not take this pattern (Clarabel is used throughout).
    ipm_unusable: bool,
    /// The objective divided by λ_tr for the native solver, once a solve needed it
    /// (`scale_objective`).
    p_scaled: Vec<f64>,
    q_scaled: Vec<f64>,
    scale_objective: bool,

    sol_x: Vec<f64>,
    sol_z: Vec<f64>,
    /// `nz` and `b` hold the linearization of the current reference (false once it moves):
    /// after a rejected step the next subproblem reuses them.
    linearized: bool,
}

impl std::fmt::Debug for Iterate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Iterate")
            .field("iteration", &self.history.len())
            .field("status", &self.status)
            .field("final_time", &self.tf)
            .field("lam_tr", &self.lam_tr)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::{damped_bfgs, lagrangian_shift};
    use crate::Dynamics;
    use armature_symbolic::{Expr, Function};
    use proptest::prelude::*;

    /// A double integrator p' = v, v' = a (|a| ≤ 1, |p| ≤ 10, |v| ≤ `v_max`) from rest at 0
    /// to `x_final` on `nodes` nodes, in minimum time, with an interval constraint `g(p, v)`
    /// on every segment and interval bounds on the listed state rows.
    fn double_integrator(
        nodes: usize,
        v_max: f64,
        x_final: [Option<f64>; 2],
        g: impl FnOnce(&Expr, &Expr) -> Expr,
        interval_bounds: Vec<usize>,
    ) -> super::Ocp {
        let (p, v, a) = (Expr::variable("p", 1), Expr::variable("v", 1), Expr::variable("a", 1));
        let function =
            Function::compile(&[g(&p, &v)], &[&[p.clone(), v.clone()], &[a.clone()]]).unwrap();
        let dynamics = Dynamics::new(&[p, v.clone()], &[a.clone()], &[v, a], &[true]).unwrap();
        super::Ocp {
            dynamics,
            nodes,
            x_min: vec![-10.0, -v_max],
            x_max: vec![10.0, v_max],
            u_min: vec![-1.0],
            u_max: vec![1.0],
            x_initial: vec![Some(0.0), Some(0.0)],
            x_final: x_final.to_vec(),
            s_min: 0.1,
            s_max: 10.0,
            final_time: (0.0, f64::INFINITY),
            time_weight: 1.0,
            final_cost: vec![],
            increments: vec![],
            nodal: vec![],
            interval_bounds,
            interval_constraints: vec![super::IntervalConstraint {
                name: "g".into(),
                function,
                first: 0,
                last: nodes - 1,
                activation: None,
            }],
        }
    }

    /// The interval values kept for the reference (`NodalEval::fgrid_reference`) are, bit
    /// for bit, what evaluating them at the reference gives: after every step of a solve of
    /// a double integrator with a nonlinear interval constraint, accepted or rejected.
    #[test]
    fn interval_values_kept_for_the_reference_are_its_own() {
        use super::{GridAt, Ptr, PtrSettings};
        // v² + 0.3·sin(p) ≤ 0.25 between the nodes of every segment, 0 → 1 m at rest.
        let nodes = 11;
        let g = |p: &Expr, v: &Expr| &(v * v) + &(&p.sin() * 0.3) - 0.25;
        let ocp = double_integrator(nodes, 10.0, [Some(1.0), Some(0.0)], g, vec![]);
        let mut ptr = Ptr::new(ocp, PtrSettings { max_iterations: 40, ..PtrSettings::default() });
        let x: Vec<f64> = (0..nodes).flat_map(|k| [k as f64 / (nodes - 1) as f64, 0.0]).collect();
        ptr.start(&x, &vec![0.0; nodes], &vec![3.0; nodes]).unwrap();
        let (mut kept, mut rejected) = (0, 0);
        loop {
            let it = ptr.step().unwrap();
            rejected += usize::from(!it.accepted);
            let st = ptr.state.as_ref().unwrap();
            if st.ev.fgrid_reference {
                let mut fresh = ptr.iterate().ev;
                ptr.eval_interval(&st.dbar, &mut fresh, GridAt::Other);
                assert_eq!(st.ev.fgrid, fresh.fgrid, "iteration {}", it.iteration);
                kept += 1;
            }
            if it.status.is_some() {
                break;
            }
        }
        // Both paths: accepted steps hand their values on, rejected ones must not.
        assert!(kept > 3 && rejected > 0, "kept at {kept} references, {rejected} rejections");
    }

    /// The interval rows' coefficients are the derivatives of their peaks: central
    /// differences of the peak value in every column of the row (the envelope theorem holds
    /// the vertex's weights), on a double integrator whose velocity peaks inside segments —
    /// for the velocity's bounds and for a nonlinear interval constraint of both states.
    #[test]
    fn peak_row_coefficients_are_derivatives_of_the_peak() {
        use super::{PeakOf, Ptr, PtrSettings, Source};
        use crate::DiscretizationSettings;
        // g = [v² + 0.3·p − 0.2, −v·(1 + sin²p)] ≤ 0 on segments 0..3.
        let g = |p: &Expr, v: &Expr| {
            Expr::concat(&[&(v * v) + &(p * 0.3) - 0.2, -(v * &(&(&p.sin() * &p.sin()) + 1.0))])
        };
        let ocp = double_integrator(4, 0.5, [None, None], g, vec![1]);
        let ptr = Ptr::new(ocp, PtrSettings::default());
        let settings = DiscretizationSettings::default();
        // z = [x (4×2) | u (4) | s (4)]: alternating accelerations make the velocity peak
        // (up) or dip (down) inside every segment.
        let mut z = vec![0.0, 0.2, 0.3, 0.1, 0.5, -0.3, 0.6, 0.2];
        z.extend([1.0, -0.6, 0.8, -0.9]);
        z.extend([1.2, 0.9, 1.5, 1.5]);
        let disc = |z: &[f64]| {
            let mut ws = ptr.ocp.dynamics.workspace();
            let mut d = ptr.output();
            ptr.ocp
                .dynamics
                .discretize(&z[..8], &z[8..12], &z[12..], &settings, &mut ws, &mut d)
                .unwrap();
            d
        };
        let peak = |z: &[f64], pk| {
            let d = disc(z);
            let mut ev = ptr.iterate().ev;
            ptr.eval_interval(&d, &mut ev, super::GridAt::Other);
            ptr.peak(&d, &ev, pk)
        };
        let d = disc(&z);
        let mut ev = ptr.iterate().ev;
        ptr.fill_peaks(&d, &mut ev, super::GridAt::Other);
        let h = 1e-6;
        let (mut checked, mut checked_g) = (0, 0);
        assert_eq!(ptr.peaks.len(), 3 * 2 + 3 * 2, "±v and g's 2 outputs on 3 segments");
        for pk in &ptr.peaks {
            let (_, _, w) = peak(&z, pk);
            let interior = w.iter().filter(|&&w| w != 0.0).count() == 3;
            for q in pk.src.clone() {
                let col = (0..12 + 4)
                    .find(|&c| {
                        (ptr.a_colptr[c]..ptr.a_colptr[c + 1])
                            .any(|i| matches!(ptr.sources[i], Source::Peak(k) if k == q))
                    })
                    .unwrap();
                let (mut zp, mut zm) = (z.clone(), z.clone());
                zp[col] += h;
                zm[col] -= h;
                let fd = (peak(&zp, pk).0 - peak(&zm, pk).0) / (2.0 * h);
                let an = ev.peak_vals[q];
                assert!(
                    (fd - an).abs() < 1e-6 * (1.0 + an.abs()),
                    "segment {} {:?} sign {} w {w:?} col {col}: {an} vs {fd}",
                    pk.seg,
                    pk.of,
                    pk.sign
                );
                if matches!(pk.of, PeakOf::Function { .. }) {
                    checked_g += usize::from(interior);
                } else {
                    checked += usize::from(interior);
                }
            }
        }
        assert!(checked >= 8, "{checked} coefficients of refined (interior) peaks checked");
        assert!(checked_g >= 8, "{checked_g} coefficients of refined function peaks checked");
    }

    /// `h` (d×d) times `v`.
    fn mul(h: &[f64], v: &[f64]) -> Vec<f64> {
        let d = v.len();
        (0..d).map(|a| (0..d).map(|b| h[a * d + b] * v[b]).sum()).collect()
    }

    /// Positive definite by Cholesky.
    fn positive_definite(h: &[f64], d: usize) -> bool {
        let mut l = vec![0.0; d * d];
        for i in 0..d {
            for j in 0..=i {
                let s: f64 = (0..j).map(|k| l[i * d + k] * l[j * d + k]).sum();
                if i == j {
                    let v = h[i * d + i] - s;
                    if v <= 0.0 {
                        return false;
                    }
                    l[i * d + i] = v.sqrt();
                } else {
                    l[i * d + j] = (h[i * d + j] - s) / l[j * d + j];
                }
            }
        }
        true
    }

    proptest! {
        /// Each row's Lagrangian-merit term `λ|d| + shift` lies in `[0, 2σλ|d|]` whatever the
        /// dual (a dual beyond σλ is clipped), and where `|y| ≤ σλ` the shift is the unclipped
        /// `(σ − 1)λ|d| − y·d`.
        #[test]
        fn the_lagrangian_merit_prices_every_defect_nonnegatively(
            rows in prop::collection::vec((-1.0f64..1.0, -5.0f64..5.0, 0.1f64..4.0), 1..12),
            sigma in 0.0f64..=1.0,
        ) {
            for &(d, y, lam) in &rows {
                let shift = lagrangian_shift(&[d], &[y], &[lam], sigma);
                let term = lam * d.abs() + shift;
                let tol = 1e-12 * (1.0 + lam * d.abs());
                prop_assert!(term >= -tol && term <= 2.0 * sigma * lam * d.abs() + tol, "{term}");
                if y.abs() <= sigma * lam {
                    let raw = (sigma - 1.0) * lam * d.abs() - y * d;
                    prop_assert!((shift - raw).abs() <= tol);
                }
            }
            // Rows cycle through the per-state prices.
            let (d, y): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r.0, r.1)).unzip();
            let lam: Vec<f64> = rows.iter().map(|r| r.2).collect();
            let twice: Vec<f64> = d.iter().chain(&d).copied().collect();
            let yy: Vec<f64> = y.iter().chain(&y).copied().collect();
            let one = lagrangian_shift(&d, &y, &lam, sigma);
            prop_assert!((lagrangian_shift(&twice, &yy, &lam, sigma) - 2.0 * one).abs() <= 1e-9);
        }

        /// Undamped (positive curvature) the update satisfies the secant equation H⁺s = y;
        /// with any pair it stays symmetric positive definite.
        #[test]
        fn damped_bfgs_keeps_the_secant_equation_and_positive_definiteness(
            diag in prop::collection::vec(0.1f64..10.0, 4),
            s in prop::collection::vec(-1.0f64..1.0, 4),
            y in prop::collection::vec(-1.0f64..1.0, 4),
        ) {
            let d = 4;
            prop_assume!(s.iter().map(|v| v * v).sum::<f64>() > 1e-3);
            let mut h = vec![0.0; d * d];
            for (a, v) in diag.iter().enumerate() {
                h[a * d + a] = *v;
            }
            let hs0 = mul(&h, &s);
            let shs: f64 = s.iter().zip(&hs0).map(|(a, b)| a * b).sum();
            let sy: f64 = s.iter().zip(&y).map(|(a, b)| a * b).sum();
            let (mut hs, mut r) = (vec![0.0; d], vec![0.0; d]);
            prop_assert!(damped_bfgs(&mut h, &s, &y, &mut hs, &mut r));
            for a in 0..d {
                for b in 0..d {
                    prop_assert!((h[a * d + b] - h[b * d + a]).abs() < 1e-9);
                }
            }
            prop_assert!(positive_definite(&h, d), "{h:?}");
            // H⁺s = r always; r = y when sᵀy ≥ 0.2·sᵀHs.
            let hs1 = mul(&h, &s);
            for a in 0..d {
                prop_assert!((hs1[a] - r[a]).abs() < 1e-8 * (1.0 + r[a].abs()));
                if sy >= 0.2 * shs {
                    prop_assert!((hs1[a] - y[a]).abs() < 1e-8 * (1.0 + y[a].abs()));
                }
            }
        }
    }

    #[test]
    fn damped_bfgs_refuses_a_zero_step() {
        let mut h = vec![1.0, 0.0, 0.0, 1.0];
        let (mut hs, mut r) = (vec![0.0; 2], vec![0.0; 2]);
        assert!(!damped_bfgs(&mut h, &[0.0, 0.0], &[1.0, 1.0], &mut hs, &mut r));
        assert_eq!(h, vec![1.0, 0.0, 0.0, 1.0]);
    }
}
