//! What a solve reports: statuses, per-iteration records, results, violations, timings,
//! errors and the printed iteration table.

use super::*;

/// How a solve ended (in JSON and on screen as a snake-case word: `converged`, …).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PtrStatus {
    /// Both criteria met.
    Converged,
    /// The iteration cap was reached.
    MaxIterations,
    /// λ_tr hit its cap without an acceptable step.
    Stalled,
    /// A constraint stayed violated without progress for
    /// [`infeasible_window`](crate::PtrSettings::infeasible_window) iterations: a local
    /// infeasibility (the exact penalty is stationary there; the violations name the
    /// constraint). Another initial guess may converge.
    LocallyInfeasible,
    /// Clarabel reported the subproblem infeasible.
    SubproblemInfeasible,
    /// Clarabel failed numerically.
    NumericalFailure,
    /// The loop converged at the nodes, but a constraint held in continuous time is violated
    /// on the dense trajectory, or a node's own condition (a nodal constraint, a final value)
    /// on the re-integrated motion, by more than
    /// [`dense_tolerance`](crate::PtrSettings::dense_tolerance) (set by the named layer's
    /// check after the solve; the violations name it).
    ViolatedBetweenNodes,
}

impl PtrStatus {
    /// The status as a stable snake-case word (`converged`, `max_iterations`, `stalled`,
    /// `locally_infeasible`,
    /// `subproblem_infeasible`, `numerical_failure`, `violated_between_nodes`).
    pub fn as_str(self) -> &'static str {
        match self {
            PtrStatus::Converged => "converged",
            PtrStatus::MaxIterations => "max_iterations",
            PtrStatus::Stalled => "stalled",
            PtrStatus::LocallyInfeasible => "locally_infeasible",
            PtrStatus::SubproblemInfeasible => "subproblem_infeasible",
            PtrStatus::NumericalFailure => "numerical_failure",
            PtrStatus::ViolatedBetweenNodes => "violated_between_nodes",
        }
    }
}

impl std::fmt::Display for PtrStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
    }
}

/// How the convex subproblem of one iteration ended (Clarabel's words; the native interior
/// point reports `Solved` or hands over to Clarabel).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum SubproblemStatus {
    /// No solver ran (its setup failed).
    SetupFailed,
    /// Solved to the tolerances.
    Solved,
    /// Solved to the reduced tolerances.
    AlmostSolved,
    /// Certified primal infeasible.
    PrimalInfeasible,
    /// Primal infeasible to the reduced tolerances.
    AlmostPrimalInfeasible,
    /// Certified dual infeasible (unbounded).
    DualInfeasible,
    /// Dual infeasible to the reduced tolerances.
    AlmostDualInfeasible,
    /// The solver's iteration cap.
    MaxIterations,
    /// The solver's time limit.
    MaxTime,
    /// A numerical error in the solver.
    NumericalError,
    /// The solver stopped making progress.
    InsufficientProgress,
    /// Any other outcome.
    Other,
}

impl SubproblemStatus {
    /// The status's name (`Solved`, `AlmostSolved`, …).
    pub fn as_str(self) -> &'static str {
        match self {
            SubproblemStatus::SetupFailed => "SetupFailed",
            SubproblemStatus::Solved => "Solved",
            SubproblemStatus::AlmostSolved => "AlmostSolved",
            SubproblemStatus::PrimalInfeasible => "PrimalInfeasible",
            SubproblemStatus::AlmostPrimalInfeasible => "AlmostPrimalInfeasible",
            SubproblemStatus::DualInfeasible => "DualInfeasible",
            SubproblemStatus::AlmostDualInfeasible => "AlmostDualInfeasible",
            SubproblemStatus::MaxIterations => "MaxIterations",
            SubproblemStatus::MaxTime => "MaxTime",
            SubproblemStatus::NumericalError => "NumericalError",
            SubproblemStatus::InsufficientProgress => "InsufficientProgress",
            SubproblemStatus::Other => "Other",
        }
    }
}

impl std::fmt::Display for SubproblemStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.as_str())
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
    /// The merit reduction the subproblem's model predicted for the step (before any
    /// second-order correction or backtracking).
    pub predicted: f64,
    /// Whether the candidate is the step's second-order correction
    /// ([`PtrSettings::second_order_correction`]).
    pub corrected: bool,
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
    /// Interior-point iterations of the subproblem (with those of its second-order
    /// correction's re-solve, when one was made).
    pub subproblem_iterations: u32,
    /// How the subproblem ended.
    pub subproblem_status: SubproblemStatus,
    /// Set on the final iteration: how the solve ended.
    pub status: Option<PtrStatus>,
    /// Whether the iteration only restored feasibility: its subproblem had no cost (dropped
    /// by [`Ptr::restore_feasibility_only`]).
    pub feasibility: bool,
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
    /// The exact-penalty prices and the trust-region weight it ended with (not serialized).
    #[serde(skip)]
    pub prices: Prices,
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
    /// An [`Ocp`](crate::Ocp) whose parts do not fit together.
    #[error("problem: {field} {reason}")]
    Ocp {
        /// The field (`x_min`, `increments[2]`).
        field: String,
        /// What is wrong.
        reason: String,
    },
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
    /// The constraint it belongs to (serialized as its [`Display`](std::fmt::Display) text,
    /// `dynamics of angle[2]`, a nodal constraint's name, `table (dense)`).
    pub constraint: ConstraintRef,
    /// Its largest violation (≥ 0; a dynamics defect in the state's units).
    pub value: f64,
    /// The node (for dynamics and the dense trajectory: the segment's first node) where it
    /// is largest.
    pub node: Option<usize>,
    /// For a check on the dense trajectory: the instant where it is largest (s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
}

/// Which constraint a [`Violation`] belongs to. `Display` gives the words of the reports and
/// the JSON (`dynamics of angle[2]`, `waypoint 5`, `bounds of v between nodes`, `table
/// (dense)`).
///
/// # Example
/// ```
/// use armature_scvx::ConstraintRef;
///
/// let c = ConstraintRef::Dense { name: "table".into() };
/// assert_eq!(c.to_string(), "table (dense)");
/// assert_eq!(c.name(), "table");
/// assert_eq!(serde_json::to_string(&c).unwrap(), "\"table (dense)\"");
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum ConstraintRef {
    /// The dynamics defect of state row `state` (named `name`) at the nodes.
    Dynamics {
        /// The state row.
        state: usize,
        /// Its name (`angle[2]`).
        name: String,
    },
    /// A nodal constraint (or the entries of one that share `name`) at its nodes.
    Nodal {
        /// Index into [`Ocp::nodal`](crate::Ocp::nodal).
        constraint: usize,
        /// Its (entry's) name.
        name: String,
    },
    /// The bounds of state row `state` at its peaks between the nodes
    /// ([`Ocp::interval_bounds`](crate::Ocp::interval_bounds)).
    StateBoundsBetweenNodes {
        /// The state row.
        state: usize,
        /// Its name.
        name: String,
    },
    /// An interval constraint at its peaks between the nodes
    /// ([`Ocp::interval_constraints`](crate::Ocp::interval_constraints)).
    BetweenNodes {
        /// Index into [`Ocp::interval_constraints`](crate::Ocp::interval_constraints).
        constraint: usize,
        /// Its name.
        name: String,
    },
    /// A continuous-time (CTCS) integral of the named layer: its defect at the nodes, which
    /// is the integrated violation of the constraints it carries.
    Continuous {
        /// The CTCS group (its integral is state row `n_named + group`).
        group: usize,
        /// What it carries (`continuous-time table (nodes 0..=10, ε = 1e-4)`).
        description: String,
    },
    /// A continuous-time constraint (or a state's bounds, `bounds of NAME`) evaluated on the
    /// dense trajectory after the solve.
    Dense {
        /// The constraint's name.
        name: String,
    },
}

impl ConstraintRef {
    /// The constraint's own name (the state's, for dynamics and bounds; the description,
    /// for a CTCS integral).
    pub fn name(&self) -> &str {
        match self {
            ConstraintRef::Dynamics { name, .. }
            | ConstraintRef::Nodal { name, .. }
            | ConstraintRef::StateBoundsBetweenNodes { name, .. }
            | ConstraintRef::BetweenNodes { name, .. }
            | ConstraintRef::Dense { name } => name,
            ConstraintRef::Continuous { description, .. } => description,
        }
    }
}

impl std::fmt::Display for ConstraintRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConstraintRef::Dynamics { name, .. } => write!(f, "dynamics of {name}"),
            ConstraintRef::Nodal { name, .. } => f.write_str(name),
            ConstraintRef::StateBoundsBetweenNodes { name, .. } => {
                write!(f, "bounds of {name} between nodes")
            }
            ConstraintRef::BetweenNodes { name, .. } => write!(f, "{name} between nodes"),
            ConstraintRef::Continuous { description, .. } => f.write_str(description),
            ConstraintRef::Dense { name } => write!(f, "{name} (dense)"),
        }
    }
}

impl Serialize for ConstraintRef {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl PartialEq<str> for ConstraintRef {
    /// Whether its report text is `other` (compared as it is written, without allocating).
    fn eq(&self, other: &str) -> bool {
        /// Consumes `rest` while what is written matches it.
        struct Matches<'a> {
            rest: &'a str,
            ok: bool,
        }
        impl std::fmt::Write for Matches<'_> {
            fn write_str(&mut self, s: &str) -> std::fmt::Result {
                match self.rest.strip_prefix(s) {
                    Some(rest) if self.ok => self.rest = rest,
                    _ => self.ok = false,
                }
                Ok(())
            }
        }
        let mut m = Matches { rest: other, ok: true };
        std::fmt::write(&mut m, format_args!("{self}")).is_ok() && m.ok && m.rest.is_empty()
    }
}

impl PartialEq<&str> for ConstraintRef {
    fn eq(&self, other: &&str) -> bool {
        *self == **other
    }
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
/// Columns: the iteration; whether its step was accepted (`yes`, `no`, or `cor` when the
/// accepted candidate is the step's second-order correction); `ρ`, the merit's actual over
/// predicted decrease (the trust region's signal: near 1 where the subproblem's model holds,
/// small where second-order defects eat the step's gain); the discretization's and the
/// subproblem's wall times; then the record's cost, penalties, defect, violation, trust-region
/// gradient, λ_tr, interior-point iterations and the subproblem's status. An iteration that
/// only restored feasibility (its cost dropped) shows `feasible` for its cost.
///
/// ```
/// use armature_scvx::{Iteration, IterationTable, SubproblemStatus};
/// let mut out = Vec::new();
/// IterationTable::header(&mut out).unwrap();
/// let it = Iteration {
///     iteration: 7, accepted: true, cost: 1.25, j_tr: 0.01, j_vc: 0.0, j_vb: 0.0,
///     max_defect: 1e-3, max_violation: 2e-3, final_time: 1.25, rho: 0.42, predicted: 4e-3,
///     corrected: true, lam_tr: 0.03, tr_gradient: 1e-3, discretization_ms: 1.0,
///     subproblem_ms: 13.0, subproblem_iterations: 21, subproblem_status: SubproblemStatus::Solved,
///     status: None, feasibility: false,
/// };
/// IterationTable::row(&mut out, &it).unwrap();
/// let text = String::from_utf8(out).unwrap();
/// let (header, row) = text.split_once('\n').unwrap();
/// assert!(header.contains("J_vc") && header.contains('ρ'));
/// assert!(row.trim_start().starts_with("7 cor   0.420"), "{row}");
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
            "{:>4} {:>3} {:>7} {:>8} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>8} {:>4}  subproblem",
            "iter",
            "acc",
            "ρ",
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
            "{:>4} {:>3} {:>7.3} {:>8.2} {:>8.2} {:>10} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>9.2e} {:>8.1e} {:>4}  {}",
            it.iteration,
            match (it.accepted, it.corrected) {
                (false, _) => "no",
                (true, false) => "yes",
                (true, true) => "cor",
            },
            it.rho,
            it.discretization_ms,
            it.subproblem_ms,
            if it.feasibility { "feasible".to_string() } else { format!("{:.6}", it.cost) },
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
            writeln!(w, "SCvx loop stopped: {status}")?;
        }
        Ok(())
    }
}
