//! `armature schema`: JSON Schema of the task and problem file formats (for editor
//! completion and validation), generated from the same types the loaders use.

use clap::{Args, ValueEnum};

use crate::{CliError, exit};

/// Which format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Task files (robot, waypoints, obstacles).
    Task,
    /// Problem files (states, controls, expressions).
    Problem,
}

/// Arguments of `armature schema`.
#[derive(Debug, Clone, Args)]
pub struct SchemaArgs {
    /// The format.
    #[arg(value_enum, default_value_t = Format::Task)]
    pub format: Format,
}

/// The JSON Schema of a format.
pub fn schema(format: Format) -> serde_json::Value {
    let s = match format {
        Format::Task => schemars::schema_for!(crate::task::TaskFile),
        Format::Problem => schemars::schema_for!(crate::problem_file::ProblemFile),
    };
    s.to_value()
}

/// Runs `armature schema`.
///
/// # Errors
/// Output failures.
pub fn run(args: &SchemaArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let text = serde_json::to_string_pretty(&schema(args.format))
        .map_err(|e| CliError { message: e.to_string(), code: exit::IO })?;
    writeln!(out, "{text}").map_err(|e| CliError { message: e.to_string(), code: exit::IO })
}
