#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod stream;
pub mod wire;

pub use stream::{
    BridgeError, BridgeSettings, Received, TrajectoryLoan, TrajectoryMeta, TrajectoryPublisher,
    TrajectorySubscriber, cleanup_dead_nodes, service_names,
};
pub use wire::{Block, FORMAT_VERSION, Progress, Status, TrajectoryHeader};
