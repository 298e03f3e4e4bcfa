#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod error;
mod group;
mod se3;
mod so3;
mod trig_coefficients;

pub use error::LieError;
pub use group::LieGroup;
pub use se3::SE3;
pub use so3::{ROTATION_TOLERANCE, SO3};
pub use trig_coefficients::{SMALL_ANGLE, SMALL_ANGLE_HIGH_ORDER};
