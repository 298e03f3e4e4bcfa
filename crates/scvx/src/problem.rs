//! The named problem layer: states, controls, time, dynamics, constraints and algebraic
//! outputs by name — the seed tutorial's modeling API in Rust — compiled once into an
//! [`Ocp`] and solved by [`Ptr`], with post-processing into a named, serializable
//! [`Solution`].
//!
//! # What compiling does
//! - Continuous-time constraints (`Constraint::ctcs()`, optionally `.over(a, b)`) are grouped
//!   by node interval and [`CtcsOptions`] into augmented integral states (as OpenSCvx groups
//!   them), gated to their interval, with the nodal condition `y_{k+1} − y_k ≤ ε`.
//! - State bounds hold at the nodes (subproblem box constraints) and, with
//!   [`Problem::state_bounds_ctcs`], also between them (one more CTCS group).
//! - Nodal constraints (`.at(&[k])`, `.over(a, b)`, all nodes by default) are linearized
//!   with virtual buffers; equalities become two inequalities. [`Ball`]s `‖g‖ ≤ r` stay
//!   second-order cones (waypoint tolerances, orientation cones).
//! - Free final time `≤ max` (and `≥ min`) is a linear constraint on the dilations; minimizing
//!   it puts weight 1 on it. `Minimize`/`Maximize` final conditions add ±1 × that component.
//! - The initial guess is each state's guess or the straight line between its fixed
//!   initial and final values, the controls' guesses or zero (clamped into their bounds), and
//!   uniform dilations for the time guess; the CTCS integrals are integrated along it.
//!
//! # Example: minimum-time double integrator
//! ```
//! use armature_scvx::{Boundary, Control, Problem, PtrSettings, State, Time};
//! let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
//! let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
//! let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
//! let problem = Problem {
//!     dynamics: vec![v.expr(), a.expr()],
//!     states: vec![p, v],
//!     controls: vec![a],
//!     time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
//!     ..Problem::new(21)
//! };
//! let mut settings = PtrSettings::default();
//! settings.trust_region = armature_scvx::TrustRegionUpdate::Constant;
//! settings.lam_vc = 1e2;
//! settings.eps_tr = 1e-4;
//! let mut compiled = problem.compile(settings).unwrap();
//! let solution = compiled.solve().unwrap();
//! assert_eq!(solution.status, armature_scvx::PtrStatus::Converged);
//! assert!((solution.final_time - 2.0).abs() < 0.02); // bang–bang: 2 s
//! // The dense single-shooting trajectory ends where the nodes do (to the defect tolerance).
//! assert!((solution.trajectory["p"].last().unwrap()[0] - 1.0).abs() < 1e-5);
//! assert_eq!(solution.nodes["time"].len(), 21);
//! ```

use std::collections::BTreeMap;
use std::time::Instant;

use armature_symbolic::{Constraint, Expr, Function, SymbolicError, Timing};
use serde::Serialize;

mod checks;
mod compile;
mod monitor;
mod solution;
mod variables;

pub use monitor::{Monitor, Steer};
pub use solution::{Solution, SolutionLayout, SolutionTimings};
pub use variables::{Boundary, Control, State, Time};

use crate::dense_check::{BoundCheck, DenseChecks, PathCheck, nodes_on_dense};
use crate::{
    ConstraintRef, ControlHolds, CtcsGroup, DiscretizationError, Dynamics, IntervalConstraint,
    Iteration, NodalConstraint, NodalKind, Ocp, Penalty, Ptr, PtrError, PtrResult, PtrSettings,
    PtrStatus, Trajectory, Violation, ctcs_states,
};

/// Largest node count a [`Problem`] accepts. Memory and time per iteration grow linearly
/// with the nodes (the crate's BENCHMARKS.md has the measurements: about 25 kB per node for
/// a two-state problem, 1.3 MB per node for the seed arm with its collision rows); this
/// bound keeps an input from asking for more than a workstation has.
pub const MAX_NODES: usize = 2_000;

/// Largest number of samples of the dense trajectory (the longest final time allowed over
/// `dense_dt`): the result files and the dense checks grow with it.
pub const MAX_DENSE_SAMPLES: usize = 200_000;

/// The dense checks sample the trajectory at most this far apart (s), however coarse the
/// result's own sampling (`PtrSettings::dense_dt`): a velocity that rides its limit can
/// exceed it for a few milliseconds between 10 ms samples (and an RK4 step of 10 ms misses
/// the rigid-body arm's motion by as much). Longer final times sample at most
/// [`MAX_DENSE_SAMPLES`] points.
pub const DENSE_CHECK_DT: f64 = 1e-3;

/// How a continuous-time constraint is integrated (CTCS).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CtcsOptions {
    /// The penalty integrated. Default squared ReLU (OpenSCvx's).
    pub penalty: Penalty,
    /// Allowed increment of the integral per segment. Default 1e-4.
    pub eps: f64,
    /// Group label (OpenSCvx's `idx`): constraints with the same node interval, penalty, ε
    /// and group share one integral state. Default 0.
    pub group: usize,
}

impl Default for CtcsOptions {
    fn default() -> Self {
        CtcsOptions { penalty: Penalty::SquaredRelu, eps: 1e-4, group: 0 }
    }
}

/// A constraint of the problem with its CTCS options (used when it is continuous-time).
#[derive(Debug, Clone)]
pub struct ProblemConstraint {
    /// `g ≤ 0` or `g = 0` with its timing (see `armature_symbolic::Constraint`).
    pub constraint: Constraint,
    /// Integration options if it is continuous-time.
    pub ctcs: CtcsOptions,
}

impl From<Constraint> for ProblemConstraint {
    fn from(constraint: Constraint) -> Self {
        ProblemConstraint { constraint, ctcs: CtcsOptions::default() }
    }
}

/// A nodal second-order-cone constraint `‖g‖₂ ≤ radius` (kept exact in the subproblem).
#[derive(Debug, Clone)]
pub struct Ball {
    /// Name for diagnostics.
    pub name: String,
    /// The vector `g` (e.g. `p_ee − waypoint`).
    pub g: Expr,
    /// The radius (> 0).
    pub radius: f64,
    /// Nodes where it holds.
    pub nodes: Vec<usize>,
}

/// A state constraint `g ≤ 0` (entrywise) also enforced between the nodes of segments
/// `first..last`, at each segment's peak on the integration grid (see
/// [`IntervalConstraint`]): for clearances and other limits the
/// motion grazes between the nodes, where a CTCS integral's linearization is blind.
///
/// It adds the peak rows only; give the constraint at the nodes too (a nodal
/// [`ProblemConstraint`], and a CTCS one for continuous-time guarantees beyond the grid), as
/// the collision tasks do. [`Problem::compile`] rejects an expression that reads a control
/// and segments outside `0..N − 1`.
///
/// # Example: a point mass around a disc
/// ```
/// use armature_scvx::{BetweenNodes, Control, Problem, ProblemConstraint, PtrSettings, State, Time};
/// use armature_symbolic::Expr;
/// let p = State::new("p", 2).initial_value(&[0.0, 0.0]).final_value(&[2.0, 0.0]);
/// let v = State::new("v", 2).initial_value(&[0.0, 0.0]).final_value(&[0.0, 0.0]);
/// let a = Control::new("a", 2).bounds(&[-1.0, -1.0], &[1.0, 1.0]);
/// // Outside the disc of radius 0.3 around (1, −0.1): 0.09 − |p − c|² ≤ 0.
/// let d = p.expr() - Expr::constant_vector(&[1.0, -0.1]);
/// let g = -(d.clone() * d).sum() + 0.09;
/// let problem = Problem {
///     dynamics: vec![v.expr(), a.expr()],
///     constraints: vec![ProblemConstraint::from(g.le(0.0).named("outside"))],
///     between_nodes: vec![BetweenNodes {
///         name: "outside".into(),
///         g,
///         first: 0,
///         last: 5,
///         activation: None,
///         sampling: armature_scvx::Sampling::Peak,
///     }],
///     states: vec![p, v],
///     controls: vec![a],
///     time: Time::Free { min: 0.0, max: 10.0, guess: 4.0, minimize: true },
///     ..Problem::new(6)
/// };
/// let solution = problem.compile(PtrSettings::default()).unwrap().solve().unwrap();
/// assert_eq!(solution.status, armature_scvx::PtrStatus::Converged);
/// // No sample of the dense trajectory lies inside the disc.
/// let inside = |q: &Vec<f64>| (q[0] - 1.0).powi(2) + (q[1] + 0.1).powi(2) < 0.09 - 1e-6;
/// assert!(!solution.trajectory["p"].iter().any(inside));
/// ```
#[derive(Debug, Clone)]
pub struct BetweenNodes {
    /// Name for diagnostics.
    pub name: String,
    /// `g`, an expression of the states only (any shape; each entry is one constraint).
    pub g: Expr,
    /// First segment (= its first node).
    pub first: usize,
    /// One past the last segment (= the last node); `first < last ≤ N − 1`.
    pub last: usize,
    /// Activation distance in `g`'s units: a segment's rows are left out of the subproblem
    /// while all its peaks lie further than this below the bound (see
    /// [`IntervalConstraint::activation`]); `None` keeps every row.
    pub activation: Option<f64>,
    /// Rows at each segment's peak or at every grid point (see [`crate::Sampling`]).
    pub sampling: crate::Sampling,
}

/// A trajectory optimization problem by name. Build with struct-update syntax from
/// [`Problem::new`] (see the module example).
#[derive(Debug, Clone)]
pub struct Problem {
    /// Number of nodes N (≥ 2).
    pub nodes: usize,
    /// States, in order.
    pub states: Vec<State>,
    /// Controls, in order.
    pub controls: Vec<Control>,
    /// One right-hand side per state (`d state / dt`), in the order of `states`.
    pub dynamics: Vec<Expr>,
    /// Final time.
    pub time: Time,
    /// Constraints.
    pub constraints: Vec<ProblemConstraint>,
    /// Nodal second-order-cone constraints.
    pub balls: Vec<Ball>,
    /// State constraints also enforced at each segment's peak between the nodes.
    pub between_nodes: Vec<BetweenNodes>,
    /// Named algebraic outputs evaluated along the solution (e.g. `ee_position`).
    pub outputs: Vec<(String, Expr)>,
    /// Also enforce the state bounds between nodes (a CTCS group) with these options.
    /// Default `Some(ReLU, ε = 1e-6)`; `None` keeps them nodal only. A state
    /// [`with_interval_bounds`](State::with_interval_bounds) under
    /// [`Sampling::GridPoints`](crate::Sampling::GridPoints) stays out of the integral: its rows
    /// at every grid point hold it between the nodes, and the integral's kink where the motion
    /// rides the bound would only slow the solve. The dense checks hold every bound either way.
    pub state_bounds_ctcs: Option<CtcsOptions>,
    /// Where the bounds of states [`with_interval_bounds`](State::with_interval_bounds) are
    /// held between the nodes: at each segment's peak (the default) or at every grid point
    /// (see [`crate::Sampling`]).
    pub interval_bounds_sampling: crate::Sampling,
    /// Bounds of the per-segment dilation `s` (segment duration `s/(N − 1)`); `None`:
    /// `[H/40, 5·T_max]` with `H = min(T_max, 4·guess)` for a free time (`T` when fixed),
    /// the trust region measuring `s` in units of `2.5·H`.
    pub dilation: Option<(f64, f64)>,
}

impl Problem {
    /// An empty problem with `nodes` nodes and free final time in [0, 10] s.
    pub fn new(nodes: usize) -> Problem {
        Problem {
            nodes,
            states: Vec::new(),
            controls: Vec::new(),
            dynamics: Vec::new(),
            time: Time::Free { min: 0.0, max: 10.0, guess: 5.0, minimize: true },
            constraints: Vec::new(),
            balls: Vec::new(),
            between_nodes: Vec::new(),
            outputs: Vec::new(),
            state_bounds_ctcs: Some(CtcsOptions { penalty: Penalty::Relu, eps: 1e-6, group: 0 }),
            interval_bounds_sampling: crate::Sampling::Peak,
            dilation: None,
        }
    }
}

/// Errors of building or solving a [`Problem`]: bad input, never solver outcomes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProblemError {
    /// Something in the problem that cannot be used, saying what and why.
    #[error("problem: {what}: {reason}")]
    Bad {
        /// The item (`state "angle"`, `constraint "…"`, `time`).
        what: String,
        /// Why.
        reason: String,
    },
    /// An expression that does not compile (shape mismatch, unknown variable, …).
    #[error("{what}: {source}")]
    Symbolic {
        /// Where.
        what: String,
        /// The symbolic error.
        source: SymbolicError,
    },
    /// The solver's input errors.
    #[error(transparent)]
    Ptr(#[from] PtrError),
}

fn bad(what: impl Into<String>, reason: impl Into<String>) -> ProblemError {
    ProblemError::Bad { what: what.into(), reason: reason.into() }
}

fn sym(what: impl Into<String>) -> impl FnOnce(SymbolicError) -> ProblemError {
    let what = what.into();
    move |source| ProblemError::Symbolic { what, source }
}

/// A guess `(x, u, s)`: N×n states (with the CTCS integrals), N×m controls, N dilations.
type Guess = (Vec<f64>, Vec<f64>, Vec<f64>);

/// Where a named block lives in the flat state/control/output vectors.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct Block {
    name: String,
    offset: usize,
    size: usize,
}

/// A compiled [`Problem`]: the solver, the guess and the name layout.
#[derive(Debug)]
pub struct CompiledProblem {
    ptr: Ptr,
    /// `(integral's state name, what it carries)` per CTCS group; group i's integral is state
    /// row `ctcs_row0 + i`.
    ctcs_names: Vec<(String, String)>,
    ctcs_row0: usize,
    /// The continuous-time constraints checked on the dense trajectory.
    dense_checks: DenseChecks,
    settings: PtrSettings,
    layout: SolutionLayout,
    guess: Guess,
    /// Consulted after every iteration while the cost is on ([`set_monitor`](Self::set_monitor)).
    monitor: Option<Monitor>,
}

impl CompiledProblem {
    /// The continuous-time (CTCS) integrals: `(the integral's state name, what it carries)`.
    pub fn ctcs_groups(&self) -> &[(String, String)] {
        &self.ctcs_names
    }

    /// How trajectories map to names (clone it to name iterates while solving).
    pub fn layout(&self) -> &SolutionLayout {
        &self.layout
    }

    /// The underlying solver (its [`Ocp`], step API and parameters).
    pub fn ptr(&mut self) -> &mut Ptr {
        &mut self.ptr
    }

    /// The prepared guess `(x, u, s)` (N×n with the CTCS integrals, N×m, N).
    pub fn guess(&self) -> (&[f64], &[f64], &[f64]) {
        (&self.guess.0, &self.guess.1, &self.guess.2)
    }

    /// Replaces the guess of state or control `name` (N × size, row-major); the CTCS
    /// integrals keep their values.
    ///
    /// # Errors
    /// An unknown name or a guess of the wrong length.
    pub fn set_guess(&mut self, name: &str, values: &[f64]) -> Result<(), ProblemError> {
        let nn = self.ptr.ocp().nodes;
        let (n, m) = (self.ptr.ocp().dynamics.n_x(), self.ptr.ocp().dynamics.n_u());
        let (block, target, width) =
            if let Some(b) = self.layout.states.iter().find(|b| b.name == name) {
                (b, &mut self.guess.0, n)
            } else if let Some(b) = self.layout.controls.iter().find(|b| b.name == name) {
                (b, &mut self.guess.1, m)
            } else {
                return Err(bad(format!("guess \"{name}\""), "no state or control has this name"));
            };
        if values.len() != nn * block.size {
            return Err(bad(
                format!("guess \"{name}\""),
                format!("{} entries, expected {}", values.len(), nn * block.size),
            ));
        }
        for k in 0..nn {
            target[k * width + block.offset..k * width + block.offset + block.size]
                .copy_from_slice(&values[k * block.size..(k + 1) * block.size]);
        }
        Ok(())
    }

    /// Replaces the dilation guess (N values; segment k lasts `s_k/(N − 1)`).
    ///
    /// # Errors
    /// A wrong length or non-positive values.
    pub fn set_dilation_guess(&mut self, s: &[f64]) -> Result<(), ProblemError> {
        if s.len() != self.guess.2.len() || s.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(bad(
                "dilation guess",
                format!("need {} positive values", self.guess.2.len()),
            ));
        }
        self.guess.2.copy_from_slice(s);
        Ok(())
    }

    /// Sets a parameter everywhere it is read (dynamics, constraints, outputs); nothing
    /// recompiles.
    ///
    /// # Errors
    /// An unknown parameter or an unusable value.
    pub fn set_parameter(&mut self, name: &str, value: &[f64]) -> Result<usize, ProblemError> {
        let mut count = match self.ptr.set_parameter(name, value) {
            Ok(c) => c,
            Err(PtrError::UnknownParameter(_)) => 0,
            Err(e) => return Err(e.into()),
        };
        if let Some(f) = self.layout.output_fn.as_mut()
            && f.parameter_names().any(|p| p == name)
        {
            f.set_parameter(name, value).map_err(sym(format!("parameter \"{name}\"")))?;
            count += 1;
        }
        // The dense checks read the same parameters (not counted: they mirror the solver's).
        for c in &mut self.dense_checks.paths {
            if c.function.parameter_names().any(|p| p == name) {
                c.function
                    .set_parameter(name, value)
                    .map_err(sym(format!("parameter \"{name}\"")))?;
            }
        }
        if count == 0 {
            return Err(PtrError::UnknownParameter(name.to_string()).into());
        }
        Ok(count)
    }

    /// Solves from the prepared guess.
    ///
    /// # Errors
    /// Input errors only; solver outcomes are the solution's `status`.
    pub fn solve(&mut self) -> Result<Solution, ProblemError> {
        self.solve_with(|_, _| {})
    }

    /// Solves from the prepared guess, calling `observer` after every iteration (see
    /// [`Ptr::solve_with`]).
    ///
    /// # Errors
    /// As [`solve`](Self::solve).
    pub fn solve_with(
        &mut self,
        observer: impl FnMut(&Iteration, &Trajectory<'_>),
    ) -> Result<Solution, ProblemError> {
        let t0 = Instant::now();
        let (x, mut u, s) = (self.guess.0.clone(), self.guess.1.clone(), self.guess.2.clone());
        self.layout.holds.to_solver(&mut u, &s);
        let r = self.run((&x, &u, &s), observer)?;
        let solve_ms = t0.elapsed().as_secs_f64() * 1e3;
        self.solution(&r, solve_ms)
    }

    /// Uses a solution's nodal trajectory as the next guess (warm start after a parameter
    /// change).
    ///
    /// # Errors
    /// A solution of another problem.
    pub fn warm_start(&mut self, r: &PtrResult) -> Result<(), ProblemError> {
        if r.x.len() != self.guess.0.len()
            || r.u.len() != self.guess.1.len()
            || r.s.len() != self.guess.2.len()
        {
            return Err(bad("warm start", "the result belongs to another problem"));
        }
        self.guess.0.copy_from_slice(&r.x);
        // The guess holds the physical controls: a time-scaled entry's value where each
        // segment starts.
        self.guess.1.copy_from_slice(&self.layout.holds.profile(&r.u, &r.s).starts);
        self.guess.2.copy_from_slice(&r.s);
        Ok(())
    }

    /// The solver's last result (for [`warm_start`](Self::warm_start)).
    pub fn last_result(&mut self) -> Option<PtrResult> {
        self.ptr.result()
    }

    /// Post-processing: named nodal and dense trajectories with the algebraic outputs.
    fn solution(&mut self, r: &PtrResult, solve_ms: f64) -> Result<Solution, ProblemError> {
        let t0 = Instant::now();
        let ocp = self.ptr.ocp();
        let (n, nn) = (ocp.dynamics.n_x(), ocp.nodes);
        let dtau = 1.0 / (nn - 1) as f64;
        let mut node_times = vec![0.0; nn];
        for k in 1..nn {
            node_times[k] = node_times[k - 1] + r.s[k - 1] * dtau;
        }
        let dense = ocp
            .dynamics
            .propagate_dense(&r.x[..n], &r.u, &r.s, self.settings.dense_dt)
            .map_err(PtrError::from)?;
        let profile = self.layout.holds.profile(&r.u, &r.s);
        let nodes = self.layout.tables(&node_times, &r.x, &profile.starts)?;
        let control_ends = self.layout.control_series(&profile.ends);
        // The defects of the CTCS integrals are the violations of what they carry.
        let rename = |v: &Violation| {
            let mut v = v.clone();
            if let ConstraintRef::Dynamics { state, .. } = v.constraint
                && let Some(group) = state.checked_sub(self.ctcs_row0)
                && let Some((_, description)) = self.ctcs_names.get(group)
            {
                v.constraint =
                    ConstraintRef::Continuous { group, description: description.clone() };
            }
            v
        };
        let trajectory = self.layout.tables(&dense.time, &dense.x, &dense.u)?;
        let m = ocp.dynamics.n_u();
        let check_dt = DENSE_CHECK_DT.max(r.final_time / MAX_DENSE_SAMPLES as f64);
        let fine = if check_dt < self.settings.dense_dt {
            let fine = ocp.dynamics.propagate_dense(&r.x[..n], &r.u, &r.s, check_dt);
            Some(fine.map_err(PtrError::from)?)
        } else {
            None
        };
        let checked = fine.as_ref().unwrap_or(&dense);
        let mut dense_violations = self.dense_checks.violations(checked, (n, m), &node_times)?;
        dense_violations.extend(nodes_on_dense(ocp, checked, &r.u)?);
        let worst_dense = dense_violations.iter().map(|v| v.value).fold(0.0, f64::max);
        let status =
            if r.status == PtrStatus::Converged && worst_dense > self.settings.dense_tolerance {
                PtrStatus::ViolatedBetweenNodes
            } else {
                r.status
            };
        let mut violations: Vec<Violation> = r.violations.iter().map(rename).collect();
        violations.extend(dense_violations);
        let max_violation = violations
            .iter()
            .filter(|v| v.value > 0.0)
            .max_by(|a, b| a.value.total_cmp(&b.value))
            .cloned();
        Ok(Solution {
            status,
            final_time: r.final_time,
            iterations: r.history.len(),
            nodes,
            control_ends,
            trajectory,
            history: r.history.clone(),
            timings: SolutionTimings {
                discretization_ms: r.timings.discretization_ms,
                subproblem_ms: r.timings.subproblem_ms,
                solve_ms,
                post_processing_ms: t0.elapsed().as_secs_f64() * 1e3,
            },
            violations,
            max_violation,
            prices: r.prices.clone(),
        })
    }
}
