//! `armature demo`: the main job on a built-in example, with nothing but the binary.

use clap::{Args, ValueEnum};

use super::solve::{OutputArgs, run_task};
use crate::CliError;
use crate::task::Source;

/// The built-in examples (the task files in the repository's `examples/`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Example {
    /// The seed tutorial's 7-DOF pick-and-place.
    PickAndPlace,
    /// The same with capsule links, self-collision and a ball obstacle.
    PickAndPlaceCollision,
    /// A pick-and-place on the UR5e with its rigid-body dynamics under gravity.
    Ur5eRigidBody,
}

impl Example {
    /// The task file's name and text.
    pub fn task(self) -> (&'static str, &'static str) {
        match self {
            Example::PickAndPlace => (
                "<built-in pick-and-place>",
                include_str!("../../../../examples/pick-and-place.toml"),
            ),
            Example::PickAndPlaceCollision => (
                "<built-in pick-and-place-collision>",
                include_str!("../../../../examples/pick-and-place-collision.toml"),
            ),
            Example::Ur5eRigidBody => (
                "<built-in ur5e-rigid-body>",
                include_str!("../../../../examples/ur5e-rigid-body.toml"),
            ),
        }
    }
}

/// Arguments of `armature demo`.
#[derive(Debug, Clone, Args)]
pub struct DemoArgs {
    /// Which example.
    #[arg(value_enum, default_value_t = Example::PickAndPlace)]
    pub example: Example,
    /// Print the example's task file instead of solving it.
    #[arg(long)]
    pub print_task: bool,
    /// Outputs.
    #[command(flatten)]
    pub output: OutputArgs,
}

/// Runs `armature demo`.
///
/// # Errors
/// As `armature solve`.
pub fn run(args: &DemoArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let (name, text) = args.example.task();
    if args.print_task {
        return write!(out, "{text}")
            .map_err(|e| CliError { message: e.to_string(), code: crate::exit::IO });
    }
    run_task(Source { name, text }, None, &args.output, out)
}
