#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

pub mod discretization;

pub use discretization::{
    Discretization, DiscretizationError, DiscretizationSettings, DiscretizationWorkspace, Dynamics,
};
