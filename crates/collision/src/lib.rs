#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod error;
pub mod geometry;
mod model;
mod scene;
mod symbolic_distance;

pub use error::CollisionError;
pub use geometry::Closest;
pub use model::{
    CollisionModel, CollisionWorkspace, Link, Obstacle, ObstacleShape, Pair, PairKind, PairOptions,
    PairResult,
};
pub use scene::{
    BoxSpec, CapsuleSpec, HalfSpaceSpec, LinkSpec, ObstacleSpec, Scene, SphereSpec,
    scene_from_toml_str,
};
pub use symbolic_distance::PairDistance;
