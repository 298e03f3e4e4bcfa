#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod branches;
mod error;
mod interpolation;
mod solver;
mod spline;

pub use branches::{BranchSettings, Start, ik_branch_search};
pub use error::IkError;
pub use interpolation::{
    IkTrajectory, Keyframe, MAX_KEYFRAME_NODE, Mode, ik_interpolation, interpolate_targets,
};
pub use solver::{
    IkResult, IkSettings, IkWorkspace, LOCAL_RESTART_STEP, LOCAL_RESTARTS, MAX_IK_ITERATIONS,
    MAX_RESTARTS, Nullspace, Target, solve,
};
pub use spline::JointSpline;
