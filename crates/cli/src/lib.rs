#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

use clap::Parser;

/// Command-line arguments of the `armature` binary.
#[derive(Debug, Parser)]
#[command(name = "armature", version, about, long_about = None)]
pub struct Cli {}

/// Runs the binary with already-parsed arguments and returns the process exit code.
pub fn run(_cli: Cli) -> i32 {
    println!(
        "armature {}: no subcommands yet; see README.md for what works today.",
        env!("CARGO_PKG_VERSION")
    );
    0
}
