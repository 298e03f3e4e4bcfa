#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod chain;
mod description;
mod dynamics;
mod error;
pub mod exact;
mod fk;
mod inertial;
mod input;
pub mod robots;
mod symbolic_fk;
mod urdf;

pub use chain::{AXIS_TOLERANCE, Chain, ChainData, Joint, JointKind, Keypoint, Limits, Pose};
pub use description::{LoadOptions, chain_from_toml_str, load_robot, load_robot_with};
pub use dynamics::{DynamicsPartials, DynamicsWorkspace, RigidBodyModel, STANDARD_GRAVITY};
pub use error::KinematicsError;
pub use fk::FkWorkspace;
pub use inertial::Inertial;
pub use input::{MAX_INPUT_BYTES, located_read_error, read_text_file};
pub use symbolic_fk::SymbolicFk;
pub use urdf::{chain_from_urdf_file, chain_from_urdf_str};
