//! The benchmark suite: a seeded generator of pick-and-place tasks on several robots
//! ([`generate`]), a verification that shares no code with the solver ([`verify`]: its own
//! forward kinematics, a dense re-integration of the solution's torques, every constraint
//! checked to 1e-4), and the run and its table ([`run`]). `cargo run --release -p
//! armature-suite` runs it all.

#![warn(missing_docs)]

pub mod generate;
pub mod reference;
pub mod retimed;
pub mod run;
pub mod study;
pub mod verify;
