//! The retimed trajectory of a task's result (`[time] retime`, on by default where the time is
//! minimized): the solved path followed time-optimally within the velocity and torque
//! limits ([`armature_arm::ArmTask::retime`]), with the task's outputs (end effector,
//! keypoint frames, clearances) evaluated on its samples.

use std::collections::BTreeMap;

use armature_arm::ArmTask;
use armature_scvx::{Solution, SolutionLayout};
use serde::Serialize;

/// Named series, one row per sample.
pub type Tables = BTreeMap<String, Vec<Vec<f64>>>;

/// A solved path retimed: what the result file carries under `retimed`.
///
/// `trajectory` holds `time`, `angle`, `velocity`, `acceleration` and `torque` (at each
/// sample, see [`armature_arm::Retimed`]) and every output of the task, as the solver's dense
/// trajectory does.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RetimedResult {
    /// The final time (s).
    pub final_time: f64,
    /// When the retimed path passes each node of the solution (s).
    pub node_times: Vec<f64>,
    /// The samples.
    pub trajectory: Tables,
}

/// `solution` of `task` retimed, its outputs evaluated with `layout`.
///
/// # Errors
/// The retiming's (a solution that does not start and end at rest, a path that cannot be
/// followed within the limits) or the outputs' evaluation, as text.
pub fn retime(
    task: &ArmTask,
    layout: &SolutionLayout,
    solution: &Solution,
) -> Result<RetimedResult, String> {
    with_outputs(layout, task.retime(solution).map_err(|e| e.to_string())?)
}

/// The retiming `r` with the task's outputs evaluated on its samples by `layout`.
///
/// # Errors
/// The outputs' evaluation, as text.
pub fn with_outputs(
    layout: &SolutionLayout,
    r: armature_arm::Retimed,
) -> Result<RetimedResult, String> {
    let mut named: Tables = BTreeMap::new();
    named.insert("angle".into(), r.angle);
    named.insert("velocity".into(), r.velocity);
    named.insert("torque".into(), r.torque);
    let mut trajectory = layout.tables_named(&r.time, &named).map_err(|e| e.to_string())?;
    trajectory.insert("acceleration".into(), r.acceleration);
    Ok(RetimedResult { final_time: r.final_time, node_times: r.node_times, trajectory })
}

impl RetimedResult {
    /// `solution` as the retimed trajectory shows it (what the plots draw and the stream
    /// sends last): the retimed samples as its dense trajectory, its final time, and at the
    /// nodes the retimed samples nearest the node times; status, iterations, history and
    /// violations are the solve's.
    pub fn shown(&self, solution: &Solution) -> Solution {
        let times = &self.trajectory["time"];
        let nearest = |t: f64| {
            let i = times.partition_point(|r| r[0] < t);
            match i {
                0 => 0,
                i if i >= times.len() => times.len() - 1,
                i if (times[i][0] - t).abs() <= (t - times[i - 1][0]).abs() => i,
                i => i - 1,
            }
        };
        let at: Vec<usize> = self.node_times.iter().map(|&t| nearest(t)).collect();
        let nodes = self
            .trajectory
            .iter()
            .map(|(name, rows)| (name.clone(), at.iter().map(|&i| rows[i].clone()).collect()))
            .collect();
        // The retimed torques are sampled, not held between the nodes: each segment ends
        // at the next node's sample.
        let control_ends = solution
            .control_ends
            .keys()
            .filter_map(|name| {
                let rows = self.trajectory.get(name)?;
                Some((name.clone(), at[1..].iter().map(|&i| rows[i].clone()).collect()))
            })
            .collect();
        // Field by field: the solve's own node and dense tables are not copied to be dropped.
        Solution {
            status: solution.status,
            final_time: self.final_time,
            iterations: solution.iterations,
            nodes,
            control_ends,
            trajectory: self.trajectory.clone(),
            history: solution.history.clone(),
            timings: solution.timings,
            violations: solution.violations.clone(),
            max_violation: solution.max_violation.clone(),
            prices: solution.prices.clone(),
        }
    }
}
