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
//! contact and so is its linearization: the subproblem pushes through the bound, the merit
//! rejects or shrinks the step, and a first-order loop creeps along the bound.
//!
//! [`Ocp::interval_constraints`] do the same for nonlinear state constraints `g(x) ≤ 0`: per
//! segment and output, the peak of `g_o(x(t_j))` over the grid, refined the same way, and the
//! row `Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z · Δz − ν_b ≤ −ĝ_o` ([`IntervalConstraint`]). The
//! values are computed at every grid point, the Jacobians only at the stencils' points. Each
//! row couples a segment's states, controls and dilation, so the KKT factor grows. With
//! [`crate::Sampling::GridPoints`] every grid point has its row, bounding `g_o` over its half-step
//! cell (a node has one on each of its two segments, each reaching into its own): its parabola at its largest there plus `max|Δ³g|/15`, a bound on what a parabola
//! misses of a cubic (the third differences' weights join the stencil, so the row's gradient
//! is exact away from the margin's kinks). Without the margin the 0.1° orientation ranges
//! ended 1e-4–2.5e-4 rad out between grid points on 6 of the suite's tasks.
//!
//! With an activation distance ([`IntervalConstraint::activation`]) a segment's rows sit out
//! of the subproblem while all its peaks lie further than that below the bound: their
//! coefficients are zeroed, and the interior point, told which rows may be switched off,
//! factors K without them (one analysis per set of switched-off rows, cached). Rows that far
//! from their bound are slack, so the steps are nearly always the same; the merit still
//! prices every peak, and the CTCS integral and the nodal rows still hold the segment.
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
//! defect is below `ε_defect` and the largest nodal violation below `ε_vb` (the named layer
//! then checks the dense trajectory). An accepted, nearly feasible step whose predicted
//! decrease is below [`PtrSettings::eps_flat`] of the cost quadruples λ_tr: the steps that
//! follow repair defects rather than creep along a flat valley for smaller gains.
//!
//! A short step is not a stationary point: with a heavy λ_tr the step is short while the
//! Lagrangian's gradient (≈ 2λ_tr·S⁻²Δz at the subproblem's optimum) is not small.
//! [`PtrSettings::quasi_newton`] adds a damped BFGS model of the Lagrangian's Hessian per
//! segment (`P` gains one dense block per segment over the columns where the segment's rows
//! are nonlinear; the pairs are `s = z − z̄`, `y = (A(z) − A(z̄))ᵀλ` with the subproblem's
//! duals λ), and [`Merit::Lagrangian`] prices a defect by its dual instead of its full ℓ1
//! weight. The default, [`PtrSettings::exact_hessian`], puts the Lagrangian's exact curvature
//! there instead: the dynamics' by the second-order adjoint, the nodal rows' from the
//! symbolic graph, and each active peak row's curvature in the states through the grid's
//! sensitivities (`peak_curvature.rs`) plus that of its vertex moving between the grid
//! points (`peak_envelope.rs`).
//!
//! A rejected step (or one with a poor ratio) gets one second-order correction
//! ([`PtrSettings::second_order_correction`], `correction.rs`): the subproblem is re-solved
//! with its right-hand sides shifted by the linear model's error at the candidate,
//! `b′ = h(z̄ + Δz) + A·Δz`, and the corrected candidate is kept when its ratio is better —
//! the classical remedy when curved constraints (a 0.1° orientation range) make a good
//! step look bad to the merit. Only b changes, so by default the corrected step is first
//! the step's solution moved to `b′` on the interior point's last factorization (one Newton
//! solve, [`crate::ipm::InteriorPoint::moved_solution`]); the corrected subproblem is solved
//! again only when that fails and the step would be rejected ([`CorrectionSolve`]). What
//! each of these does, measured on the suite, is in BENCHMARKS.md.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT, SolverStatus,
    SupportedConeT, ZeroConeT,
};
use std::time::Instant;

use crate::ipm::{Cones, InteriorPoint, IpmSettings, IpmStatus};

use serde::Serialize;

use crate::{Discretization, DiscretizationError, DiscretizationSettings, DiscretizationWorkspace};

/// λ_tr above which a failed native solve is retried with the objective divided by λ_tr
/// (see `solve_subproblem`).
const HEAVY_TRUST_REGION: f64 = 1e3;

/// Scale of the initial quasi-Newton block, `γ·S⁻²` with `γ` this times Nocedal and
/// Wright's `‖y‖²/yᵀs` (in the trust-region scaling): their estimate sits near the largest
/// curvature, and a tenth of it let the seed arm take longer first steps.
const QN_INITIAL_SCALE: f64 = 0.1;

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
    /// Where the exact Hessians of the dynamics and the nodal constraints go (empty unless
    /// `exact_hessian`).
    exact: curvature::ExactHessian,
    /// The running (or last) solve.
    state: Option<Box<Iterate>>,
    /// Whether the running solve still minimizes its cost; `false` once
    /// [`restore_feasibility_only`](Self::restore_feasibility_only) dropped it.
    cost_on: bool,
    /// The prices a solve starts from besides the settings' ([`Ptr::set_starting_prices`]).
    starting: StartingPrices,
}

impl Ptr {
    pub(super) fn layout(&self) -> (usize, usize, usize, usize) {
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        (nn * n, nn * n + nn * m, nn * n + nn * m + nn, (nn - 1) * n)
    }

    /// The peak rows' buffers (the last columns; one per bound and segment, shared by its
    /// rows: `rows/peaks.rs`).
    pub(super) fn peak_buffers(&self) -> usize {
        self.n_vars - self.vb0 - self.buffers.len()
    }

    /// Sizes of the convex subproblem (fixed at construction). The reduced KKT matrix's
    /// come from the interior point of the running (or last) solve; before the first solve
    /// one is analysed for them.
    pub fn dimensions(&self) -> SubproblemDimensions {
        let running =
            self.state.as_ref().and_then(|st| st.native.as_ref()).map(|n| n.ipm.kkt_nonzeros());
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
}

mod acceptance;
mod backend;
mod build;
mod correction;
mod curvature;
mod evaluate;
mod iterate;
mod merit;
mod peak_curvature;
mod peak_envelope;
mod prices;
mod psd;
mod quasi_newton;
mod report;
mod rows;
mod run;
mod settings;
mod step;
mod subproblem;
#[cfg(test)]
mod tests;
mod violations;

pub use crate::ocp::*;
use backend::*;
use evaluate::*;
use iterate::*;
use merit::*;
use prices::StartingPrices;
pub use prices::{PeakBound, PricedRow, Prices};
pub use report::*;
use rows::*;
pub use settings::*;
