//! The initial guess: IK through the waypoints (from the start configuration if given; by
//! default the branch path of least travel under the velocity limits, kept clear of the
//! obstacles where it can be), timed by a spline at the joint limits.

use armature_ik::{
    BranchSettings, IkSettings, IkTrajectory, IkWorkspace, JointSpline, Keyframe, Mode, Start,
    ik_branch_search, ik_interpolation, interpolate_targets, solve,
};

use crate::dynamics::Resolved;
use crate::{ArmError, ArmTask, TaskItem};

/// The initial guess.
#[derive(Debug, Clone)]
pub(crate) struct Guess {
    pub(crate) ik: IkTrajectory,
    pub(crate) spline: JointSpline,
    pub(crate) duration: f64,
    pub(crate) dilation: Vec<f64>,
}

/// IK through the waypoints, time-parameterized by a spline (zero end velocities) whose
/// duration the limits allow, clamped into the time window.
///
/// # Errors
/// The IK's or the spline's, as [`TaskItem::Initialization`] (the knots', which the
/// velocity limits set, as [`TaskItem::VelocityLimit`]).
pub(crate) fn initial_guess(task: &ArmTask, dynamics: &Resolved) -> Result<Guess, ArmError> {
    let n = task.chain.dof();
    let bad = |m: String| ArmError::new(TaskItem::Initialization, m);
    let keyframes: Vec<Keyframe> = task
        .waypoints
        .iter()
        .map(|w| Keyframe { node: w.node, position: w.position, quaternion_wxyz: w.orientation })
        .collect();
    let settings = IkSettings { restarts: task.initialization.restarts, ..IkSettings::default() };
    let seed = task.start.clone().unwrap_or_else(|| vec![0.0; n]);
    let mut ik = match task.initialization.mode {
        Mode::Branches => {
            // The task's start: the given one, or the IK of the first waypoint from zero.
            let first = match (&task.start, keyframes.first()) {
                (None, Some(first)) => first_waypoint_ik(task, first, &seed, &settings)?,
                _ => seed.clone(),
            };
            let start = Start::Fixed(&first);
            let weights: Vec<f64> = task.velocity_limit.iter().map(|v| 1.0 / v).collect();
            let search = BranchSettings {
                samples: task.initialization.restarts,
                ..BranchSettings::default()
            };
            // The samples' seed is the task's; the start configuration above is not drawn
            // again with it (a fallback start solves the same task).
            let sampling = IkSettings { rng_seed: task.initialization.seed, ..settings.clone() };
            ik_branch_search(
                &task.chain,
                &keyframes,
                start,
                &sampling,
                &search,
                &weights,
                &mut clearance_cost(task),
            )
        }
        mode => ik_interpolation(&task.chain, &keyframes, &seed, &settings, mode),
    }
    .map_err(|e| bad(format!("IK initialization: {e}")))?;
    if let Some(start) = &task.start {
        ik.q[0] = start.clone();
    }
    let knots = JointSpline::time_optimal_knots(&ik.q, &task.velocity_limit)
        .map_err(|e| ArmError::new(TaskItem::VelocityLimit, format!("initial guess: {e}")))?;
    let spline = JointSpline::through_timed(&ik.q, &knots)
        .map_err(|e| bad(format!("initial guess: {e}")))?;
    let (t_min, t_max) = (task.time.min, task.time.max);
    let duration = guess_duration(task, dynamics, &spline, &ik.q, (t_min.max(1e-3 * t_max), t_max));
    let nodes = task.nodes;
    let mut dilation: Vec<f64> = knots.iter().map(|h| h * duration * (nodes - 1) as f64).collect();
    dilation.push(dilation[nodes - 2]);
    Ok(Guess { ik, spline, duration, dilation })
}

/// The IK of the first waypoint from `seed` (with the settings' restarts): the start
/// configuration of a task that gives none.
fn first_waypoint_ik(
    task: &ArmTask,
    first: &Keyframe,
    seed: &[f64],
    settings: &IkSettings,
) -> Result<Vec<f64>, ArmError> {
    let bad =
        |m: String| ArmError::new(TaskItem::Initialization, format!("IK initialization: {m}"));
    let targets =
        interpolate_targets(std::slice::from_ref(first)).map_err(|e| bad(e.to_string()))?;
    let mut ws = IkWorkspace::new(&task.chain);
    Ok(solve(&task.chain, &targets[0], seed, settings, &mut ws).map_err(|e| bad(e.to_string()))?.q)
}

/// The guess's duration: the spline's shortest under the velocity limits and the
/// accelerations the torque limits allow at the start, then (rigid-body dynamics) stretched
/// until its torques at the nodes fit the limits; clamped into the window.
fn guess_duration(
    task: &ArmTask,
    dynamics: &Resolved,
    spline: &JointSpline,
    q: &[Vec<f64>],
    (lo, hi): (f64, f64),
) -> f64 {
    let amax = dynamics.accelerations_allowed(&q[0], &task.torque_limit);
    let mut duration = spline.min_duration(&task.velocity_limit, &amax).clamp(lo, hi);
    if let Resolved::RigidBody(_) = dynamics {
        for _ in 0..30 {
            let qd: Vec<Vec<f64>> = (0..task.nodes).map(|k| spline.velocity(k, duration)).collect();
            let qdd: Vec<Vec<f64>> =
                (0..task.nodes).map(|k| spline.acceleration(k, duration)).collect();
            let ratio = dynamics
                .torques(q, &qd, &qdd)
                .iter()
                .flat_map(|t| t.iter().zip(&task.torque_limit).map(|(t, l)| t.abs() / l))
                .fold(0.0f64, f64::max);
            if ratio <= 1.0 || duration >= hi {
                break;
            }
            duration = (duration * ratio.sqrt().clamp(1.05, 2.0)).min(hi);
        }
    }
    duration
}

/// What the branch search charges per metre by which a node's configuration comes closer to
/// an obstacle or another link than the task's margin, summed over the pairs, in the units
/// of its travel (seconds at the velocity limits): 1 cm costs as much as 30 ms of motion.
/// On the benchmark suite's tasks with a ball, a path clear of it from the start ends 1.3 %
/// faster on average than one the solver must push out (3, 10, 30 and 100 measured: 3
/// gains about as much as 10 without lengthening the longest walk; BENCHMARKS.md,
/// 2026-12-07, "the IK guess").
const CLEARANCE_DEFICIT_COST: f64 = 3.0;

/// The branch search's cost of a node's configuration: [`CLEARANCE_DEFICIT_COST`] times its
/// collision pairs' summed shortfall from the margin (nothing without collision, or where
/// the distances cannot be evaluated).
fn clearance_cost(task: &ArmTask) -> impl FnMut(usize, &[f64]) -> f64 + '_ {
    let mut ws = task.collision.as_ref().map(|c| c.model.workspace(&task.chain));
    move |_, q| {
        let (Some(c), Some(ws)) = (&task.collision, ws.as_mut()) else { return 0.0 };
        let Ok(results) = c.model.evaluate(&task.chain, q, ws, false) else { return 0.0 };
        let shortfall: f64 = results.iter().map(|r| (c.margin - r.distance).max(0.0)).sum();
        CLEARANCE_DEFICIT_COST * shortfall
    }
}
