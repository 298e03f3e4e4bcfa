//! The `armature` binary; all logic lives in the `armature_cli` library.

use clap::Parser;

fn main() {
    let cli = armature_cli::Cli::parse();
    let code = armature_cli::run(cli, &mut std::io::stdout().lock());
    std::process::exit(code);
}
