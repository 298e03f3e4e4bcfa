//! Publishing a solve over iceoryx2 (`--stream RUN`): every SCvx iterate's nodes and
//! progress, then the final dense trajectory.

use std::collections::BTreeMap;

use armature_bridge::{
    BridgeError, BridgeSettings, Progress, Status, TrajectoryMeta, TrajectoryPublisher,
};
use armature_scvx::{Iteration, PtrStatus};

/// A publisher plus the names of the table columns that make each block.
#[derive(Debug)]
pub struct Streamer {
    publisher: TrajectoryPublisher,
    /// Values one trajectory message holds.
    max_values: usize,
    /// Table names of the frames block, in keypoint order (`T_<keypoint>`).
    frames: Vec<String>,
}

type Tables = BTreeMap<String, Vec<Vec<f64>>>;

/// Longest wait `--timeout` and `--linger` accept (s; about 32 years): beyond it a duration
/// does not fit the clock.
pub const MAX_WAIT_SECONDS: f64 = 1e9;

/// The wire status of a solve that ended with `s`.
pub fn wire_status(s: PtrStatus) -> Status {
    match s {
        PtrStatus::Converged => Status::Converged,
        PtrStatus::MaxIterations => Status::MaxIterations,
        PtrStatus::Stalled => Status::Stalled,
        PtrStatus::SubproblemInfeasible => Status::SubproblemInfeasible,
        PtrStatus::NumericalFailure => Status::NumericalFailure,
        PtrStatus::ViolatedBetweenNodes => Status::ViolatedBetweenNodes,
        PtrStatus::LocallyInfeasible => Status::LocallyInfeasible,
    }
}

/// A bridge error as the CLI's: what the user asked for that cannot be (a bad run name, a
/// run another process streams) is bad input (exit 2); the machine's state (permissions on
/// iceoryx2's shared files, a run's listener slots full, other iceoryx2 failures) exit 4.
pub fn bridge_error(context: &str, e: BridgeError) -> crate::CliError {
    let code = match e {
        BridgeError::BadRunName(_) | BridgeError::RunBusy { .. } => crate::exit::BAD_INPUT,
        _ => crate::exit::IO,
    };
    crate::CliError { message: format!("{context}{e}"), code }
}

impl Streamer {
    /// A streamer for run `run`; `keypoints` are the chain's keypoint names.
    ///
    /// # Errors
    /// The bridge's (a bad run name, iceoryx2 failures).
    pub fn new(run: &str, keypoints: &[String]) -> Result<Self, BridgeError> {
        let settings = BridgeSettings::default();
        Ok(Streamer {
            max_values: settings.max_values,
            publisher: TrajectoryPublisher::new(run, &settings)?,
            frames: keypoints.iter().map(|k| format!("T_{k}")).collect(),
        })
    }

    /// Publishes named tables (`time`, `angle`, `velocity`, `torque`, `ee_position`,
    /// `T_<keypoint>`) as one trajectory message, written in place. A trajectory with more
    /// values than one message holds is sent decimated to fit: every `stride`-th row and the
    /// last (the stride is returned with the sequence number; 1 when nothing was dropped).
    ///
    /// # Errors
    /// The bridge's.
    pub fn publish(
        &mut self,
        t: &Tables,
        iteration: u64,
        status: Status,
        final_time: f64,
        dense: bool,
    ) -> Result<(u64, usize), BridgeError> {
        let empty: Vec<Vec<f64>> = Vec::new();
        let get = |name: &str| t.get(name).unwrap_or(&empty);
        // Columns of each block as (table, index within its rows).
        let mut cols: Vec<(&Vec<Vec<f64>>, usize)> = Vec::new();
        let mut widths = [0u32; 6];
        for (b, names) in [
            vec!["time".to_string()],
            vec!["angle".into()],
            vec!["velocity".into()],
            vec!["torque".into()],
            vec!["ee_position".into()],
            self.frames.clone(),
        ]
        .iter()
        .enumerate()
        {
            for name in names {
                let table = get(name);
                let w = table.first().map_or(0, Vec::len);
                cols.extend((0..w).map(|i| (table, i)));
                widths[b] += w as u32;
            }
        }
        let all = get("time").len();
        let width = (widths.iter().sum::<u32>() as usize).max(1);
        let fit = (self.max_values / width).max(2);
        // Rows kept: 0, stride, 2·stride, … and the last one.
        let stride = if all <= fit { 1 } else { (all - 1).div_ceil(fit - 1) };
        let rows = if all == 0 { 0 } else { (all - 1).div_ceil(stride) + 1 };
        let row = |r: usize| (r * stride).min(all.saturating_sub(1));
        let meta = TrajectoryMeta { iteration, status, final_time, dense, widths };
        let seq = self.publisher.publish_with(&meta, rows, |r, c| cols[c].0[row(r)][cols[c].1])?;
        Ok((seq, stride))
    }

    /// Publishes one iteration's progress.
    ///
    /// # Errors
    /// The bridge's.
    pub fn progress(&mut self, it: &Iteration) -> Result<u64, BridgeError> {
        let status = it.status.map_or(Status::Running, wire_status);
        self.publisher.publish_progress(Progress {
            status: status.code(),
            iteration: it.iteration as u64,
            accepted: u32::from(it.accepted),
            subproblem_iterations: it.subproblem_iterations,
            feasibility: u32::from(it.feasibility),
            cost: it.cost,
            j_tr: it.j_tr,
            j_vc: it.j_vc,
            j_vb: it.j_vb,
            max_defect: it.max_defect,
            max_violation: it.max_violation,
            final_time: it.final_time,
            lam_tr: it.lam_tr,
            discretization_ms: it.discretization_ms,
            subproblem_ms: it.subproblem_ms,
            ..Progress::default()
        })
    }

    /// Serves the latest trajectory to late subscribers for `seconds`.
    ///
    /// # Errors
    /// The bridge's.
    pub fn linger(&self, seconds: f64) -> Result<(), BridgeError> {
        if seconds > 0.0 {
            self.publisher.serve(std::time::Duration::from_secs_f64(seconds))?;
        }
        Ok(())
    }
}
