//! The `armature` binary; all logic lives in the `armature_cli` library.

use clap::Parser;

fn main() {
    let cli = armature_cli::Cli::parse();
    armature_cli::output_set::install_interrupt_cleanup();
    let mut out = armature_cli::ReaderMayLeave::new(std::io::stdout().lock());
    let code = armature_cli::run(cli, &mut out);
    std::process::exit(code);
}
