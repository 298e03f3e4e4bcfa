//! `armature solve`: the full pipeline from a task file.

use std::path::{Path, PathBuf};
use std::time::Instant;

use armature_scvx::IterationTable;
use clap::Args;

use crate::pipeline::plan;
use crate::task::{Source, parse};
use crate::{CliError, exit, output};

/// Where the results go (shared by `solve` and `demo`).
#[derive(Debug, Clone, Default, Args)]
pub struct OutputArgs {
    /// Write the result as JSON to this file (`-` for standard output).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Write `nodes.csv` and `trajectory.csv` into this folder.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write plots (SVG and PNG) into this folder.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print nothing but errors (no iteration table, no summary).
    #[arg(short, long)]
    pub quiet: bool,
}

/// Arguments of `armature solve`.
#[derive(Debug, Clone, Args)]
pub struct SolveArgs {
    /// The task file (TOML).
    pub file: PathBuf,
    /// Outputs.
    #[command(flatten)]
    pub output: OutputArgs,
}

/// Runs `armature solve`.
///
/// # Errors
/// Bad input ([`exit::BAD_INPUT`], `file:line:col: reason`), output failures, or a solve
/// that did not converge ([`exit::NOT_CONVERGED`], after writing its result).
pub fn run(args: &SolveArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let text = std::fs::read_to_string(&args.file)
        .map_err(|e| CliError::bad_input(format!("{}: {e}", args.file.display())))?;
    let name = args.file.display().to_string();
    run_task(Source { name: &name, text: &text }, Some(&args.file), &args.output, out)
}

/// Plans, solves and writes the outputs of one task.
///
/// # Errors
/// As [`run`].
pub fn run_task(
    src: Source<'_>,
    path: Option<&Path>,
    o: &OutputArgs,
    out: &mut dyn std::io::Write,
) -> Result<(), CliError> {
    let t0 = Instant::now();
    let say = |line: &str| {
        if !o.quiet {
            eprintln!("{line}");
        }
    };
    let task = parse(src).map_err(CliError::bad_input)?;
    let plan = plan(&task, src, path).map_err(CliError::bad_input)?;
    let converged_ik = plan.ik.nodes.iter().filter(|r| r.converged).count();
    say(&format!(
        "{}: {} joints, {} nodes, {} waypoints{}; IK initialization: {converged_ik}/{} nodes converged, largest joint step {:.3} rad",
        src.name,
        plan.chain.dof(),
        plan.nodes,
        plan.waypoints.len(),
        plan.collision
            .as_ref()
            .map_or(String::new(), |m| format!(", {} collision pairs", m.pairs().len())),
        plan.nodes,
        plan.ik.max_joint_step
    ));
    let mut compiled = plan.compile().map_err(CliError::bad_input)?;
    let d = compiled.ptr().dimensions();
    say(&format!(
        "subproblem: {} variables, {} equality + {} inequality rows, {} cones ({} rows), {} nonzeros; ready in {:.1} ms",
        d.variables,
        d.equality_rows,
        d.inequality_rows,
        d.second_order_cones,
        d.cone_rows,
        d.nonzeros,
        t0.elapsed().as_secs_f64() * 1e3
    ));
    if !o.quiet {
        let _ = IterationTable::header(&mut std::io::stderr());
    }
    let quiet = o.quiet;
    let solution = compiled
        .solve_with(|it, _| {
            if !quiet {
                let _ = IterationTable::row(&mut std::io::stderr(), it);
            }
        })
        .map_err(CliError::bad_input)?;
    say(&format!(
        "{}: final time {:.4} s after {} iterations; solve {:.1} ms (discretization {:.1}, subproblems {:.1}), dense propagation {:.1} ms ({} samples); total {:.1} ms",
        solution.status,
        solution.final_time,
        solution.iterations,
        solution.timings.solve_ms,
        solution.timings.discretization_ms,
        solution.timings.subproblem_ms,
        solution.timings.post_processing_ms,
        solution.trajectory["time"].len(),
        t0.elapsed().as_secs_f64() * 1e3
    ));
    if let Some(v) = &solution.max_violation {
        say(&format!("largest violation: {} = {:.3e} at node {:?}", v.constraint, v.value, v.node));
    }
    let mut written =
        output::write_solution(&solution, o.output.as_deref(), o.csv.as_deref(), out)?;
    if let Some(dir) = &o.plot {
        written.extend(crate::plot::write_plots(&plan, &solution, dir)?);
    }
    for p in &written {
        say(&format!("wrote {}", p.display()));
    }
    if solution.converged() {
        Ok(())
    } else {
        Err(CliError {
            message: format!("the solve stopped without converging: {}", solution.status),
            code: exit::NOT_CONVERGED,
        })
    }
}
