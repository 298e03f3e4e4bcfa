//! The independent optimal-control reference (`T_ref`): the tasks written out for
//! `bench/reference/t_ref.py` (CasADi + IPOPT, direct transcription on a fine grid), and its
//! stored solutions read back and verified here, by [`crate::verify`], like armature's own.
//!
//! A reference counts for a task only when its trajectory passes the same verification as
//! armature's: the torques at its grid times, first-order hold, re-integrated from its start at
//! rest; for the rigid-body tasks, whose reference is parametrized by its accelerations, those
//! (first-order hold) integrated exactly and the torques that the suite's own rigid-body model
//! asks along the way.

use std::collections::BTreeMap;

use armature_arm::DynamicsModel;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::generate::SuiteTask;
use crate::run::{self, Outcome};
use crate::verify::{self, Worst};

/// The committed reference solutions, relative to the workspace root.
pub const STORED: &str = "bench/reference/t_ref.json";

/// One task's reference solution, as `t_ref.py` stores it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ReferenceSolution {
    /// IPOPT's outcome of the best start (`Solve_Succeeded`, …), or why there is none.
    pub status: String,
    /// The final time of the best verified start (s); `None`: no start converged.
    pub final_time: Option<f64>,
    /// The final time each start reached (`None`: it failed).
    pub starts: Vec<Option<f64>>,
    /// Grid times (s).
    pub times: Vec<f64>,
    /// Torques at the grid times (first-order hold between them).
    pub torques: Vec<Vec<f64>>,
    /// The start configuration (at rest).
    pub q0: Vec<f64>,
    /// How far (rad) the orientation tolerances were tightened in the transcription so that
    /// the trajectory holds them between its grid points too (0: not at all).
    #[serde(default)]
    pub backoff: f64,
    /// Rigid-body tasks: the fraction of each torque limit the transcription kept in reserve
    /// at its samples, so that the torque between them holds the limit too.
    #[serde(default)]
    pub torque_margin: f64,
    /// Rigid-body tasks: the accelerations at the grid times (first-order hold between them),
    /// the reference's own control; empty for the others.
    #[serde(default)]
    pub accelerations: Vec<Vec<f64>>,
}

/// The stored references by task name.
pub type References = BTreeMap<String, ReferenceSolution>;

/// Reads [`STORED`] (or another file).
///
/// # Errors
/// The file cannot be read or is not the reference's JSON.
pub fn load(path: &std::path::Path) -> Result<References, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Verifies a reference solution against its task: the largest violation on its dense
/// re-integration.
pub fn verify_reference(t: &SuiteTask, r: &ReferenceSolution) -> Worst {
    if r.times.len() < 2 || r.torques.len() != r.times.len() {
        return Worst { value: f64::INFINITY, what: "no trajectory".into() };
    }
    let dense = if r.accelerations.is_empty() {
        let mut acc = run::accelerations(t);
        let zeros = vec![0.0; r.q0.len()];
        verify::reintegrate(acc.as_mut(), &r.times, (&r.torques, None), &r.q0, &zeros)
    } else {
        match acceleration_path(t, r) {
            Ok(dense) => dense,
            Err(what) => return Worst { value: f64::INFINITY, what },
        }
    };
    // The reference's grid is finer than the task's nodes; its waypoints and orientation
    // ranges fall on the grid times of the task's node instants.
    let node_times = reference_node_times(t, r);
    let worst = verify::check(&run::checks(t), &dense, &node_times);
    // It starts where the task starts (the plan's start configuration).
    let start = t.task.plan().map(|p| p.ik.q[0].clone()).unwrap_or_default();
    let off = if start.len() == r.q0.len() {
        start.iter().zip(&r.q0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
    } else {
        f64::INFINITY
    };
    if off > worst.value {
        return Worst { value: off, what: "start configuration".into() };
    }
    worst
}

/// A rigid-body reference's trajectory: its accelerations (first-order hold between its grid
/// times) integrated exactly from its start at rest, sampled every [`verify::DT`] or finer,
/// with the torques the task's rigid-body model (RNEA) needs for that motion at each sample.
///
/// # Errors
/// A task without a rigid-body model, or accelerations that do not fit the grid.
fn acceleration_path(t: &SuiteTask, r: &ReferenceSolution) -> Result<verify::Dense, String> {
    let DynamicsModel::RigidBody { gravity } = &t.task.dynamics else {
        return Err("accelerations stored for a task without rigid-body dynamics".into());
    };
    let n = r.q0.len();
    let fits =
        r.accelerations.len() == r.times.len() && r.accelerations.iter().all(|a| a.len() == n);
    let model = armature_kinematics::RigidBodyModel::new(&t.task.chain, *gravity)
        .map_err(|e| e.to_string())?;
    if !fits || model.dof() != n {
        return Err("accelerations that do not fit the grid".into());
    }
    let mut ws = model.workspace();
    let (mut q, mut qd) = (r.q0.clone(), vec![0.0; n]);
    let mut dense = verify::Dense::default();
    let mut tau = vec![0.0; n];
    for k in 0..r.times.len() - 1 {
        let (t0, h) = (r.times[k], r.times[k + 1] - r.times[k]);
        let (a0, a1) = (&r.accelerations[k], &r.accelerations[k + 1]);
        let steps = (h / verify::DT).ceil().max(1.0) as usize;
        // The last interval's end is sampled too.
        let last = if k + 2 == r.times.len() { steps } else { steps - 1 };
        for i in 0..=last {
            let s = h * i as f64 / steps as f64;
            // q″ = a linear over the interval: v quadratic, q cubic in s.
            let (mut qs, mut vs, mut acc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            for j in 0..n {
                let jerk = (a1[j] - a0[j]) / h;
                acc[j] = a0[j] + jerk * s;
                vs[j] = qd[j] + a0[j] * s + jerk * s * s / 2.0;
                qs[j] = q[j] + qd[j] * s + a0[j] * s * s / 2.0 + jerk * s.powi(3) / 6.0;
            }
            model.rnea(&mut ws, &qs, &vs, &acc, &mut tau).map_err(|e| e.to_string())?;
            dense.t.push(t0 + s);
            dense.q.push(qs);
            dense.qd.push(vs);
            dense.tau.push(tau.clone());
        }
        for j in 0..n {
            let jerk = (a1[j] - a0[j]) / h;
            q[j] += qd[j] * h + a0[j] * h * h / 2.0 + jerk * h.powi(3) / 6.0;
            qd[j] += a0[j] * h + jerk * h * h / 2.0;
        }
    }
    Ok(dense)
}

/// The instants of the task's nodes on the reference's grid: the grid is uniform within each
/// phase between the task's event nodes (waypoints, orientation range ends), so node `k` of
/// phase `[a, b]` sits at the fraction `(k − a)/(b − a)` of it.
fn reference_node_times(t: &SuiteTask, r: &ReferenceSolution) -> Vec<f64> {
    let events = event_nodes(t);
    let phases = events.len() - 1;
    let per_phase = (r.times.len() - 1) / phases.max(1);
    let mut out = Vec::with_capacity(t.task.nodes);
    for k in 0..t.task.nodes {
        let p = events.windows(2).position(|w| k >= w[0] && k <= w[1]).unwrap_or(phases - 1);
        let (a, b) = (events[p], events[p + 1]);
        let (t0, t1) = (r.times[p * per_phase], r.times[(p + 1) * per_phase]);
        out.push(t0 + (t1 - t0) * (k - a) as f64 / (b - a).max(1) as f64);
    }
    out
}

/// Nodes where the reference starts a phase: the first and last, each waypoint's and each
/// orientation range's ends.
pub fn event_nodes(t: &SuiteTask) -> Vec<usize> {
    let task = &t.task;
    let mut e = vec![0, task.nodes - 1];
    e.extend(task.waypoints.iter().map(|w| w.node));
    e.extend(task.orientation.iter().flat_map(|o| [o.first, o.last]));
    e.sort_unstable();
    e.dedup();
    e
}

/// The task as `t_ref.py` reads it, with armature's guess and (when it converged) its
/// solution as starts. A solution on a refined grid (more nodes than the task) is exported
/// with the refined task (`ArmTask::refined`), whose nodes and events index its times.
pub fn export(t: &SuiteTask, outcome: Option<&Outcome>) -> Value {
    let solved_on = solution_task(t, outcome);
    let t = solved_on.as_ref().unwrap_or(t);
    let task = &t.task;
    let checks = run::checks(t);
    let (inertia, gravity) = match &task.dynamics {
        DynamicsModel::DecoupledInertia(i) => (i.clone(), None),
        DynamicsModel::RigidBody { gravity } => (Vec::new(), Some(*gravity)),
    };
    // The robot's mass properties (each joint's body, in the base frame at q = 0): task
    // data the reference's own rigid-body dynamics reads.
    let links: Vec<Value> = task
        .chain
        .joints()
        .iter()
        .filter_map(|j| j.inertial.as_ref())
        .map(|i| json!({ "mass": i.mass, "com": i.com, "inertia": i.inertia }))
        .collect();
    let plan = task.plan().ok();
    let guess = plan.as_ref().map(|p| json!({ "angles": p.ik.q, "durations": p.dilation_guess }));
    let solution = outcome
        .and_then(|o| o.solution.as_ref())
        .map(|s| json!({ "times": s.times, "angles": s.angles, "torques": s.torques }));
    json!({
        "name": t.name,
        "group": t.group,
        "robot": run::robot_name(t.robot),
        "infeasible": t.infeasible,
        "rigid_body": gravity.is_some(),
        "inertia": inertia,
        "gravity": gravity,
        "links": if gravity.is_some() { links } else { Vec::new() },
        "q_lo": checks.q_lo,
        "q_hi": checks.q_hi,
        "qd_max": checks.qd_max,
        "tau_max": checks.tau_max,
        "nodes": task.nodes,
        "events": event_nodes(t),
        "t_max": task.time.max,
        "waypoints": task.waypoints.iter().map(|w| json!({
            "node": w.node, "position": w.position, "tolerance": w.tolerance })).collect::<Vec<_>>(),
        "orientation": task.orientation.iter().map(|o| json!({
            "quaternion_wxyz": o.quaternion_wxyz, "tolerance_deg": o.tolerance_deg,
            "first": o.first, "last": o.last })).collect::<Vec<_>>(),
        "table": task.table_height,
        "balls": t.balls.iter().map(|(c, r)| json!({ "centre": [c.x, c.y, c.z], "radius": r }))
            .collect::<Vec<_>>(),
        "margin": task.collision.as_ref().map_or(0.0, |c| c.margin),
        "q0": plan.as_ref().map(|p| p.ik.q[0].clone()),
        "guess": guess,
        "armature": solution,
    })
}

/// The refined task a solution on more nodes than `t`'s lives on (its nodes `f·k` for the
/// task's `k`), or none when it is on the task's own grid.
fn solution_task(t: &SuiteTask, outcome: Option<&Outcome>) -> Option<SuiteTask> {
    let nodes = outcome?.solution.as_ref()?.times.len();
    let intervals = t.task.nodes.checked_sub(1).filter(|&n| n > 0)?;
    let factor = (nodes.checked_sub(1)? / intervals).max(1);
    (factor > 1 && factor * intervals + 1 == nodes)
        .then(|| SuiteTask { task: t.task.refined(factor), ..t.clone() })
}
