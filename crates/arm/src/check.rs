//! The checks a task passes before it becomes a problem, each naming the part of the task.

use armature_lie::SO3;

use crate::{ArmError, ArmTask, TaskItem};

/// Checks everything [`ArmTask::plan`] relies on.
///
/// # Errors
/// The first problem found.
pub(crate) fn check(task: &ArmTask) -> Result<(), ArmError> {
    check_limits(task)?;
    check_time_and_nodes(task)?;
    check_waypoints(task)?;
    check_orientation(task)?;
    if let Some(h) = task.table_height
        && !h.is_finite()
    {
        return Err(ArmError::new(TaskItem::Table, "table_height must be finite"));
    }
    if let Some(c) = &task.collision {
        let bad = |m: String| Err(ArmError::new(TaskItem::Collision, m));
        if !(0.0..=MAX_MARGIN).contains(&c.margin) {
            return bad(format!("margin {:e} m must be in [0, {MAX_MARGIN}] m", c.margin));
        }
        if let Some(a) = c.between_nodes_activation
            && (a.is_nan() || a <= 0.0)
        {
            return bad(format!("activation {a} must be > 0"));
        }
    }
    check_start(task)
}

/// Largest collision margin (m): a clearance wider than an arm's reach is a mistake, and a
/// margin that large makes the fixed links' clearances constraints that never hold.
const MAX_MARGIN: f64 = 1.0;

fn check_limits(task: &ArmTask) -> Result<(), ArmError> {
    let n = task.chain.dof();
    for (item, what, values) in [
        (TaskItem::VelocityLimit, "velocity_limit", &task.velocity_limit),
        (TaskItem::TorqueLimit, "torque_limit", &task.torque_limit),
    ] {
        if values.len() != n {
            return Err(ArmError::new(
                item,
                format!("{what}: {} values for {n} joints", values.len()),
            ));
        }
        if let Some(i) = values.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(ArmError::new(
                item,
                format!("{what} {} of joint {i} must be > 0", values[i]),
            ));
        }
    }
    Ok(())
}

fn check_time_and_nodes(task: &ArmTask) -> Result<(), ArmError> {
    let t = task.time;
    if !(t.max.is_finite() && t.max > 0.0) {
        return Err(ArmError::new(
            TaskItem::Time,
            format!("max {} must be a positive number", t.max),
        ));
    }
    if !(t.min.is_finite() && (0.0..t.max).contains(&t.min)) {
        return Err(ArmError::new(TaskItem::Time, format!("min {} must be in [0, max)", t.min)));
    }
    if !(2..=armature_scvx::MAX_NODES).contains(&task.nodes) {
        let max = armature_scvx::MAX_NODES;
        return Err(ArmError::new(
            TaskItem::Nodes,
            format!("{} nodes: give 2 to {max}", task.nodes),
        ));
    }
    Ok(())
}

fn check_waypoints(task: &ArmTask) -> Result<(), ArmError> {
    let w = &task.waypoints;
    if w.len() < 2 {
        let m = format!("need at least 2 waypoints (start and goal), got {}", w.len());
        return Err(ArmError::new(TaskItem::Waypoint(0), m));
    }
    for (i, p) in w.iter().enumerate() {
        let bad = |m: String| Err(ArmError::new(TaskItem::Waypoint(i), m));
        if p.name.is_empty() || w[..i].iter().any(|o| o.name == p.name) {
            return bad(format!("waypoint name '{}' is empty or used twice", p.name));
        }
        if p.position.iter().any(|v| !v.is_finite()) {
            return bad("position must be finite".into());
        }
        if !(p.tolerance.is_finite() && p.tolerance > 0.0) {
            return bad(format!("tolerance {} must be > 0", p.tolerance));
        }
        if let Some(q) = p.orientation {
            SO3::from_quaternion_wxyz(q)
                .map_err(|e| ArmError::new(TaskItem::Waypoint(i), e.to_string()))?;
        }
        let expected = match i {
            0 => Some(0),
            _ if i == w.len() - 1 => Some(task.nodes - 1),
            _ => None,
        };
        if expected.is_some_and(|e| e != p.node) || p.node >= task.nodes {
            return bad(format!(
                "node {}: the first waypoint is at node 0, the last at node {}, the others between",
                p.node,
                task.nodes - 1
            ));
        }
        if i > 0 && p.node <= w[i - 1].node {
            return bad(format!(
                "node {} does not come after '{}' (node {})",
                p.node,
                w[i - 1].name,
                w[i - 1].node
            ));
        }
    }
    Ok(())
}

fn check_orientation(task: &ArmTask) -> Result<(), ArmError> {
    for (i, o) in task.orientation.iter().enumerate() {
        let bad = |m: String| Err(ArmError::new(TaskItem::Orientation(i), m));
        if let Err(e) = SO3::from_quaternion_wxyz(o.quaternion_wxyz) {
            return bad(e.to_string());
        }
        let deg = o.tolerance_deg;
        if !(deg.is_finite() && deg > 0.0 && deg < 180.0) {
            return bad(format!("tolerance_deg {deg:e} must be in (0, 180)"));
        }
        if o.first >= o.last || o.last >= task.nodes {
            return bad(format!(
                "nodes {}..{} must be increasing and within the {} nodes",
                o.first, o.last, task.nodes
            ));
        }
    }
    Ok(())
}

/// The start: one finite angle per joint within its limits, putting the end effector within
/// the first waypoint's tolerance.
fn check_start(task: &ArmTask) -> Result<(), ArmError> {
    let Some(q) = &task.start else { return Ok(()) };
    let bad = |m: String| Err(ArmError::new(TaskItem::Start, m));
    let chain = &task.chain;
    if let Err(e) = chain.check_q(q) {
        return bad(format!("start: {e}"));
    }
    let (lo, hi) = chain.position_limits();
    if let Some(j) = (0..q.len()).find(|&j| q[j] < lo[j] || q[j] > hi[j]) {
        let name = &chain.joints()[j].name;
        return bad(format!(
            "start: joint {j} ('{name}') at {} is outside its limits [{}, {}]",
            q[j], lo[j], hi[j]
        ));
    }
    let mut ws = chain.fk_workspace();
    if let Err(e) = chain.forward(q, &mut ws) {
        return bad(format!("start: {e}"));
    }
    let first = &task.waypoints[0];
    let gap = (ws.ee().translation() - nalgebra::Vector3::from(first.position)).norm();
    if gap > first.tolerance {
        return bad(format!(
            "start puts the end effector {gap:.4} m from the first waypoint '{}' (tolerance {} m)",
            first.name, first.tolerance
        ));
    }
    Ok(())
}
