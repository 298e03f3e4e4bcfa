//! `armature listen`: prints what a `--stream RUN` solve publishes.

use std::io::Write;
use std::time::{Duration, Instant};

use armature_bridge::{BridgeSettings, Status, TrajectorySubscriber};
use clap::Args;
use serde_json::json;

use crate::{CliError, exit};

/// Arguments of `armature listen`.
#[derive(Debug, Clone, Args)]
pub struct ListenArgs {
    /// The run name given to `--stream`.
    pub run: String,
    /// Exit after the first trajectory.
    #[arg(long)]
    pub once: bool,
    /// One JSON object per line per trajectory: `{"run_id", "sequence", "iteration", "status",
    /// "final_time", "dense", "columns", "rows"}` (progress is not printed).
    #[arg(long)]
    pub json: bool,
    /// Keep listening after the final trajectory of a solve (until --timeout or Ctrl-C).
    #[arg(long)]
    pub follow: bool,
    /// Give up after this many seconds without a message (default: wait forever).
    #[arg(long, value_name = "SECONDS")]
    pub timeout: Option<f64>,
}

fn io(e: std::io::Error) -> CliError {
    CliError { message: format!("writing: {e}"), code: exit::IO }
}

/// Runs `armature listen`. Exit code 0 once it received what it waited for (the final
/// trajectory, or any with `--once`); 3 on `--timeout` without it.
///
/// # Errors
/// A bad run name; bridge failures (e.g. a publisher of another format version).
pub fn run(args: &ListenArgs, out: &mut dyn Write) -> Result<(), CliError> {
    if let Some(t) = args.timeout
        && !(t.is_finite() && t > 0.0 && t <= crate::streaming::MAX_WAIT_SECONDS)
    {
        return Err(CliError::bad_input(format!(
            "--timeout {t}: give seconds > 0 and at most {:e}",
            crate::streaming::MAX_WAIT_SECONDS
        )));
    }
    let sub = TrajectorySubscriber::new(&args.run, &BridgeSettings::default())
        .map_err(|e| crate::streaming::bridge_error("", e))?;
    let _ = writeln!(
        std::io::stderr(),
        "listening on armature/{0}/trajectory and armature/{0}/progress",
        args.run
    );
    let idle = args.timeout.map(Duration::from_secs_f64);
    let mut last = Instant::now();
    // With --follow: a final trajectory has arrived, so an idle timeout ends a complete
    // session (exit 0), not a missing one.
    let mut got_final = false;
    loop {
        let slice = Duration::from_millis(200);
        let (progress, trajectory) =
            sub.receive_any_timeout(slice).map_err(|e| crate::streaming::bridge_error("", e))?;
        if let Some(p) = progress {
            last = Instant::now();
            if !args.json {
                writeln!(
                    out,
                    "progress   iteration {:>3} {} cost {} J_tr {:.2e} J_vc {:.2e} J_vb {:.2e} defect {:.2e} violation {:.2e} ({:.2} + {:.2} ms)",
                    p.iteration,
                    if p.accepted == 1 { "accepted" } else { "rejected" },
                    if p.feasibility == 1 { "feasible".to_string() } else { format!("{:.6}", p.cost) },
                    p.j_tr,
                    p.j_vc,
                    p.j_vb,
                    p.max_defect,
                    p.max_violation,
                    p.discretization_ms,
                    p.subproblem_ms
                )
                .map_err(io)?;
                out.flush().map_err(io)?;
            }
        }
        if let Some(t) = trajectory {
            last = Instant::now();
            let h = *t.header();
            let status = h.status().map_or("unknown", Status::word);
            if args.json {
                let rows: Vec<&[f64]> = t.iter_rows().collect();
                let line = json!({
                    "run_id": h.run_id,
                    "sequence": h.sequence,
                    "iteration": h.iteration,
                    "status": status,
                    "final_time": h.final_time,
                    "dense": h.dense == 1,
                    "columns": h.columns(),
                    "rows": rows,
                });
                writeln!(out, "{line}").map_err(io)?;
            } else {
                writeln!(
                    out,
                    "trajectory sequence {} iteration {} {status}: {} {} rows × {} values, final time {:.4} s",
                    h.sequence,
                    h.iteration,
                    if h.dense == 1 { "dense" } else { "nodal" },
                    h.samples,
                    h.row_width(),
                    h.final_time
                )
                .map_err(io)?;
            }
            out.flush().map_err(io)?;
            let is_final = h.dense == 1 && h.status() != Some(Status::Running);
            if args.once || (is_final && !args.follow) {
                return Ok(());
            }
            got_final |= is_final;
        }
        if let Some(idle) = idle
            && last.elapsed() >= idle
        {
            if got_final {
                return Ok(());
            }
            return Err(CliError {
                message: format!("no message on run '{}' for {} s", args.run, idle.as_secs_f64()),
                code: exit::NOT_CONVERGED,
            });
        }
    }
}
