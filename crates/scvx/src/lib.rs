#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod ctcs;
pub mod discretization;
pub mod ptr;

pub use ctcs::{CtcsGroup, Penalty, ctcs_states};
pub use discretization::{
    Discretization, DiscretizationError, DiscretizationSettings, DiscretizationWorkspace, Dynamics,
};
pub use ptr::{
    Iteration, IterationTable, NodalConstraint, NodalKind, Ocp, Ptr, PtrError, PtrResult,
    PtrSettings, PtrStatus, SettingsError, SubproblemSettings, Timings, Trajectory,
    TrustRegionUpdate, Violation,
};
