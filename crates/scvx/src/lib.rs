#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod discretization;
pub mod ptr;

pub use discretization::{
    Discretization, DiscretizationError, DiscretizationSettings, DiscretizationWorkspace, Dynamics,
};
pub use ptr::{Iteration, Ocp, Ptr, PtrResult, PtrSettings, PtrStatus};
