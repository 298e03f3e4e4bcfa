//! The `armature` binary; all logic lives in the `armature_cli` library.

use clap::Parser;

fn main() {
    std::process::exit(armature_cli::run(armature_cli::Cli::parse()));
}
