//! Checks that name what makes a task infeasible before it is solved: a waypoint the arm
//! cannot reach, a start configuration inside an obstacle. Each is an [`ArmError`] naming the
//! part of the task.

use armature_ik::{IkSettings, IkTrajectory, IkWorkspace, Target, solve};
use armature_lie::SO3;
use nalgebra::Vector3;

use crate::{ArmError, ArmTask, TaskItem};

/// Every waypoint the IK guess missed is retried alone (position only, and then under the
/// orientation of a range that holds at its node); one that stays out of reach is an error.
///
/// # Errors
/// [`TaskItem::Waypoint`] with the closest distance (or angle) the IK reached.
pub(crate) fn waypoints_reachable(task: &ArmTask, ik: &IkTrajectory) -> Result<(), ArmError> {
    let chain = &task.chain;
    let mut ws = IkWorkspace::new(chain);
    let settings = IkSettings { restarts: 16, ..IkSettings::default() };
    for (i, w) in task.waypoints.iter().enumerate() {
        let r = &ik.nodes[w.node];
        let range = task.orientation.iter().find(|o| (o.first..=o.last).contains(&w.node));
        let position_ok = r.position_error <= w.tolerance;
        let orientation_ok = range.is_none() || w.orientation.is_some() && r.converged;
        if position_ok && orientation_ok {
            continue;
        }
        let p = Vector3::from(w.position);
        let alone = solve(chain, &Target::position(p), &ik.q[w.node], &settings, &mut ws)
            .map_err(|e| ArmError::new(TaskItem::Initialization, e.to_string()))?;
        if alone.position_error > w.tolerance {
            return Err(ArmError::new(
                TaskItem::Waypoint(i),
                format!(
                    "waypoint '{}' is out of reach: the closest the arm comes within its joint limits is {:.3} m away (tolerance {} m)",
                    w.name, alone.position_error, w.tolerance
                ),
            ));
        }
        let Some(o) = range else { continue };
        let rot = SO3::from_quaternion_wxyz(o.quaternion_wxyz)
            .map_err(|e| ArmError::new(TaskItem::Orientation(0), e.to_string()))?;
        let target = Target { position: p, orientation: Some(rot) };
        let posed = solve(chain, &target, &alone.q, &settings, &mut ws)
            .map_err(|e| ArmError::new(TaskItem::Initialization, e.to_string()))?;
        let tol = o.tolerance_deg.to_radians();
        if posed.position_error > w.tolerance || posed.orientation_error > tol {
            return Err(ArmError::new(
                TaskItem::Waypoint(i),
                format!(
                    "waypoint '{}' is out of reach with the orientation of range '{}': the closest pose is {:.3} m and {:.2}° away (tolerances {} m, {}°)",
                    w.name,
                    o.name,
                    posed.position_error,
                    posed.orientation_error.to_degrees(),
                    w.tolerance,
                    o.tolerance_deg
                ),
            ));
        }
    }
    Ok(())
}

/// The start configuration keeps every collision pair clear.
///
/// # Errors
/// [`TaskItem::Start`] naming the pair and its depth.
pub(crate) fn start_clear(task: &ArmTask, q0: &[f64]) -> Result<(), ArmError> {
    let Some(c) = &task.collision else { return Ok(()) };
    let mut ws = c.model.workspace(&task.chain);
    let results = c
        .model
        .evaluate(&task.chain, q0, &mut ws, false)
        .map_err(|e| ArmError::new(TaskItem::Start, e.to_string()))?;
    let worst =
        results.iter().zip(c.model.pairs()).min_by(|a, b| a.0.distance.total_cmp(&b.0.distance));
    if let Some((r, pair)) = worst
        && r.distance < 0.0
    {
        let depth = -r.distance;
        let depth = if depth < 1e3 { format!("{depth:.3}") } else { format!("{depth:.3e}") };
        return Err(ArmError::new(
            TaskItem::Start,
            format!(
                "the start configuration is in collision: {} and {} overlap by {depth} m",
                pair.a, pair.b
            ),
        ));
    }
    Ok(())
}
