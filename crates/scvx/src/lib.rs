#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod ctcs;
mod dense_check;
pub mod discretization;
pub mod ipm;
pub mod ocp;
pub mod problem;
pub mod ptr;
mod sparse;

// Modeling: a problem by name, its variables and constraints.
pub use problem::{
    Ball, BetweenNodes, Boundary, Control, CtcsOptions, DENSE_CHECK_DT, MAX_DENSE_SAMPLES,
    MAX_NODES, Problem, ProblemConstraint, State, Time,
};

// Solving: compilation, the solver-level problem, the loop and its settings.
pub use ctcs::{CtcsGroup, Penalty, ctcs_states};
pub use discretization::{
    ControlHolds, ControlProfile, DenseTrajectory, Discretization, DiscretizationError,
    DiscretizationSettings, DiscretizationWorkspace, Dynamics, Integrator, MAX_ADAPTIVE_STEPS,
    MAX_GRID_STEPS, MAX_SUBSTEPS, SegmentHessianWorkspace,
};
pub use ipm::IpmSettings;
pub use problem::{CompiledProblem, Monitor, Steer};
pub use ptr::{
    ClarabelSettings, CorrectionSolve, Increment, IntervalConstraint, Merit, NodalConstraint,
    NodalKind, Ocp, PeakBound, PricedRow, Prices, Ptr, PtrSettings, Sampling, SettingsError,
    SubproblemDimensions, SubproblemSettings, SubproblemSolver, TrustRegionUpdate,
};

// Results: statuses, records, violations, solutions and errors.
pub use problem::{ProblemError, Solution, SolutionLayout, SolutionTimings};
pub use ptr::{
    ConstraintRef, Iteration, IterationTable, PtrError, PtrResult, PtrStatus, SubproblemStatus,
    Timings, Trajectory, Violation,
};
