#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

use std::io::Write as _;

use clap::{Parser, Subcommand};

pub mod commands;
pub mod exit;
pub mod output;
pub mod output_set;
pub mod pipeline;
pub mod plot;
pub mod problem_file;
pub mod retimed;
pub mod robot_dynamics;
pub mod settings;
pub mod streaming;
pub mod task;
pub mod toml_string;
pub mod view;

/// Command-line arguments of the `armature` binary.
#[derive(Debug, Parser)]
#[command(name = "armature", version, about = "Time-optimal arm trajectories: kinematics, IK, collision, SCvx", long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Forward kinematics: keypoint frames and the end-effector pose as JSON.
    Fk(commands::fk::FkArgs),
    /// Inverse kinematics for a target pose, or every node of a keyframe file.
    Ik(commands::ik::IkArgs),
    /// Signed distances, witness points and gradients of capsule links and obstacles.
    Collide(commands::collide::CollideArgs),
    /// Solve a task file: IK initialization, SCvx, dense trajectory; JSON, CSV, plots.
    Solve(commands::solve::SolveArgs),
    /// Solve a built-in example (the seed pick-and-place, with or without collision).
    Demo(commands::demo::DemoArgs),
    /// What a task compiles to, without solving: constraints, sparsity, subproblem sizes.
    Inspect(commands::inspect::InspectArgs),
    /// Write the interactive 3D view of a result file (one self-contained HTML page).
    View(commands::view::ViewArgs),
    /// JSON Schema of the task or problem file format.
    Schema(commands::schema::SchemaArgs),
    /// Print the trajectories and progress a `--stream RUN` solve publishes.
    Listen(commands::listen::ListenArgs),
}

/// An error a command reports to the user (printed as `error: …`), with its exit code.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct CliError {
    /// What went wrong, for the user.
    pub message: String,
    /// The process exit code (see [`exit`]).
    pub code: i32,
}

impl CliError {
    /// A bad-input error (exit code [`exit::BAD_INPUT`]).
    pub fn bad_input(message: impl std::fmt::Display) -> Self {
        CliError { message: message.to_string(), code: exit::BAD_INPUT }
    }
}

/// Standard output for a reader that may stop reading (`armature demo -o - | head -1`): once
/// the pipe is closed, further output is dropped instead of failing the run, whose exit code
/// then says how the run itself went.
#[derive(Debug)]
pub struct ReaderMayLeave<W> {
    inner: W,
    closed: bool,
}

impl<W: std::io::Write> ReaderMayLeave<W> {
    /// Wraps `inner`.
    pub fn new(inner: W) -> Self {
        ReaderMayLeave { inner, closed: false }
    }
}

impl<W: std::io::Write> std::io::Write for ReaderMayLeave<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.closed {
            return Ok(buf.len());
        }
        match self.inner.write(buf) {
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                self.closed = true;
                Ok(buf.len())
            }
            other => other,
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self.inner.flush() {
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                self.closed = true;
                Ok(())
            }
            other => other,
        }
    }
}

/// Reads an input file: regular files only, bounded in size, UTF-8 (a bad byte located at
/// `file:line:col`), see [`armature_kinematics::read_text_file`].
///
/// # Errors
/// A bad-input [`CliError`] naming the file.
pub fn read_input(path: &std::path::Path) -> Result<String, CliError> {
    armature_kinematics::read_text_file(path).map_err(|e| {
        let (at, reason) = armature_kinematics::located_read_error(&path.display().to_string(), &e);
        CliError::bad_input(format!("{at}: {reason}"))
    })
}

/// Runs the binary with already-parsed arguments, writing results to `out`; returns the
/// process exit code (errors are printed to standard error).
pub fn run(cli: Cli, out: &mut dyn std::io::Write) -> i32 {
    let result = match cli.command {
        Command::Fk(args) => commands::fk::run(&args, out),
        Command::Ik(args) => commands::ik::run(&args, out),
        Command::Collide(args) => commands::collide::run(&args, out),
        Command::Solve(args) => commands::solve::run(&args, out),
        Command::Demo(args) => commands::demo::run(&args, out),
        Command::Listen(args) => commands::listen::run(&args, out),
        Command::Inspect(args) => commands::inspect::run(&args, out),
        Command::View(args) => commands::view::run(&args, out),
        Command::Schema(args) => commands::schema::run(&args, out),
    };
    match result {
        Ok(()) => exit::SUCCESS,
        Err(e) => {
            // Best effort: the exit code carries the outcome even if standard error is closed.
            let _ = writeln!(std::io::stderr(), "error: {}", e.message);
            e.code
        }
    }
}
