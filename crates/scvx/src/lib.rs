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

pub use ctcs::{CtcsGroup, Penalty, ctcs_states};
pub use discretization::{
    DenseTrajectory, Discretization, DiscretizationError, DiscretizationSettings,
    DiscretizationWorkspace, Dynamics, Integrator, MAX_ADAPTIVE_STEPS,
};
pub use problem::{
    Ball, BetweenNodes, Boundary, CompiledProblem, Control, CtcsOptions, MAX_NODES, Problem,
    ProblemConstraint, ProblemError, Solution, SolutionLayout, SolutionTimings, State, Time,
};
pub use ptr::{
    ClarabelSettings, ConstraintRef, IntervalConstraint, Iteration, IterationTable, Merit,
    NodalConstraint, NodalKind, Ocp, Ptr, PtrError, PtrResult, PtrSettings, PtrStatus,
    SettingsError, SubproblemDimensions, SubproblemSettings, SubproblemSolver, SubproblemStatus,
    Timings, Trajectory, TrustRegionUpdate, Violation,
};
