//! The main job: task file → robot chain → symbolic FK → task constraints → IK guess →
//! SCvx problem → solution.

use std::path::Path;

use armature_collision::{CollisionModel, Scene};
use armature_ik::{IkSettings, IkTrajectory, JointSpline, Keyframe, Mode, ik_interpolation};
use armature_kinematics::Chain;
use armature_lie::SO3;
use armature_scvx::{
    Ball, BetweenNodes, CompiledProblem, Control, CtcsOptions, Penalty, Problem, ProblemConstraint,
    PtrSettings, State, Time,
};
use armature_symbolic::{Expr, Shape};
use serde::Serialize;

use crate::robot_dynamics::RobotDynamics;
use crate::task::{Limit, LocatedError, OrientationValue, Source, TaskFile, resolve_robot};

/// A waypoint as planned: where and when.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedWaypoint {
    /// Its name.
    pub name: String,
    /// Its node.
    pub node: usize,
    /// Position (m).
    pub position: [f64; 3],
    /// Radius of its ball (m).
    pub tolerance: f64,
}

/// An orientation range as planned: the end-effector rotation stays within
/// `tolerance_deg` of `quaternion_wxyz` from node `first` to node `last`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlannedOrientation {
    /// `from..to` (the waypoint names).
    pub name: String,
    /// The desired rotation.
    pub quaternion_wxyz: [f64; 4],
    /// The largest rotation angle away from it (degrees).
    pub tolerance_deg: f64,
    /// First node.
    pub first: usize,
    /// Last node.
    pub last: usize,
}

/// Everything the task defines, checked, with the compiled problem's inputs.
#[derive(Debug)]
pub struct Plan {
    /// The robot.
    pub chain: Chain,
    /// Node count N.
    pub nodes: usize,
    /// Waypoints with their nodes.
    pub waypoints: Vec<PlannedWaypoint>,
    /// Velocity limits (rad/s).
    pub velocity_limit: Vec<f64>,
    /// Torque limits (N·m).
    pub torque_limit: Vec<f64>,
    /// Table height, if any.
    pub table_height: Option<f64>,
    /// The collision model, if any.
    pub collision: Option<CollisionModel>,
    /// The clearance every collision pair keeps (m).
    pub margin: f64,
    /// Orientation ranges.
    pub orientation: Vec<PlannedOrientation>,
    /// The SCvx problem.
    pub problem: Problem,
    /// Dilation guess (N values).
    pub dilation_guess: Vec<f64>,
    /// The IK initialization.
    pub ik: IkTrajectory,
    /// Solver settings.
    pub settings: PtrSettings,
}

/// Name of the parameter holding waypoint `name`'s position.
pub fn waypoint_parameter(name: &str) -> String {
    format!("waypoint.{name}")
}

/// Checks a task against its robot and builds the problem and its guess.
///
/// # Errors
/// The first problem found, as `file:line:col: reason`.
pub fn plan(task: &TaskFile, src: Source<'_>, path: Option<&Path>) -> Result<Plan, LocatedError> {
    let robot = &task.robot;
    let spec = resolve_robot(robot.name.get_ref(), path);
    let chain = armature_kinematics::load_robot(&spec, robot.base.as_deref(), robot.tip.as_deref())
        .map_err(|e| {
            let hint = match e {
                armature_kinematics::KinematicsError::NoRootLink => {
                    ": give `base = \"LINK\"` in [robot]"
                }
                armature_kinematics::KinematicsError::AmbiguousTip { .. } => {
                    ": give `tip = \"LINK\"` in [robot]"
                }
                _ => "",
            };
            src.error(&robot.name, format!("{e}{hint}"))
        })?;
    let limits = joint_limits(task, &chain, src)?;
    let (t_min, t_max) = time_window(task, src)?;
    let (nodes, per_segment) = node_count(task, src)?;
    let waypoints = planned_waypoints(task, nodes, per_segment, src)?;
    let keyframes = keyframes(task, &waypoints, src)?;
    let orientation = orientation_ranges(task, &waypoints, src)?;
    let table_height = match &task.table_height {
        Some(h) if !h.get_ref().is_finite() => {
            return Err(src.error(h, "table_height must be finite"));
        }
        h => h.as_ref().map(|h| *h.get_ref()),
    };
    let collision = collision(task, &chain, src)?;
    let settings = crate::settings::checked(&task.settings, src)?;
    let guess = initial_guess(task, &chain, &keyframes, &limits, (t_min, t_max), nodes, src)?;
    let mut problem = states_and_dynamics(task, &chain, &limits, &guess, nodes);
    problem.time =
        Time::Free { min: t_min, max: t_max, guess: guess.duration, minimize: task.time.minimize };
    let task_parts = TaskParts {
        waypoints: &waypoints,
        orientation: &orientation,
        table_height,
        collision: collision.as_ref(),
    };
    add_task_constraints(&mut problem, &chain, &task_parts, task.robot.velocity_limit_peaks)
        .map_err(|e| src.error(&robot.name, e))?;
    let JointLimits { velocity: velocity_limit, torque: torque_limit, .. } = limits;
    Ok(Plan {
        chain,
        nodes,
        waypoints,
        velocity_limit,
        torque_limit,
        table_height,
        margin: collision.as_ref().map_or(0.0, |(_, m, _)| *m),
        collision: collision.map(|(m, _, _)| m),
        orientation,
        problem,
        dilation_guess: guess.dilation,
        ik: guess.ik,
        settings,
    })
}

/// The robot's dynamics and limits, checked against its joints.
struct JointLimits {
    dynamics: RobotDynamics,
    velocity: Vec<f64>,
    torque: Vec<f64>,
}

/// `[robot]`'s dynamics, velocity and torque limits (the robot's own where not given).
fn joint_limits(
    task: &TaskFile,
    chain: &Chain,
    src: Source<'_>,
) -> Result<JointLimits, LocatedError> {
    let robot = &task.robot;
    let n = chain.dof();
    let dynamics = RobotDynamics::from_task(task, chain, src)?;
    let limit = |what: &str,
                 given: &Option<toml::Spanned<Limit>>,
                 robot_value: &dyn Fn(usize) -> Option<f64>| {
        let (values, at) = match given {
            Some(l) => (
                match l.get_ref() {
                    Limit::All(v) => vec![*v; n],
                    Limit::Each(v) => v.clone(),
                },
                l.span().start,
            ),
            None => {
                let v: Option<Vec<f64>> = (0..n).map(robot_value).collect();
                let v = v.ok_or_else(|| {
                    src.error(
                        &robot.name,
                        format!("the robot has no {what} for every joint: give {what} in [robot]"),
                    )
                })?;
                (v, robot.name.span().start)
            }
        };
        if values.len() != n {
            return Err(src.error_at(at, format!("{what}: {} values for {n} joints", values.len())));
        }
        if let Some(i) = values.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(src.error_at(at, format!("{what} {} of joint {i} must be > 0", values[i])));
        }
        Ok(values)
    };
    let velocity =
        limit("velocity_limit", &robot.velocity_limit, &|i| chain.joints()[i].limits.velocity)?;
    let torque = limit("torque_limit", &robot.torque_limit, &|i| chain.joints()[i].limits.effort)?;
    Ok(JointLimits { dynamics, velocity, torque })
}

/// `[time]`: the final time's window `[min, max]`.
fn time_window(task: &TaskFile, src: Source<'_>) -> Result<(f64, f64), LocatedError> {
    let t_max = *task.time.max.get_ref();
    if !(t_max.is_finite() && t_max > 0.0) {
        return Err(src.error(&task.time.max, format!("max {t_max} must be a positive number")));
    }
    let t_min = task.time.min.as_ref().map_or(0.0, |m| *m.get_ref());
    if !(t_min.is_finite() && (0.0..t_max).contains(&t_min)) {
        let at = task.time.min.as_ref().map_or(task.time.max.span().start, |m| m.span().start);
        return Err(src.error_at(at, format!("min {t_min} must be in [0, max)")));
    }
    Ok((t_min, t_max))
}

/// `[nodes]`: the node count, and the nodes per segment when given that way.
fn node_count(task: &TaskFile, src: Source<'_>) -> Result<(usize, Option<usize>), LocatedError> {
    let w = &task.waypoints;
    if w.len() < 2 {
        return Err(
            src.error_at(0, format!("need at least 2 waypoints (start and goal), got {}", w.len()))
        );
    }
    Ok(match (&task.nodes.count, &task.nodes.per_segment) {
        (Some(c), None) => {
            if !(2..=armature_scvx::MAX_NODES).contains(c.get_ref()) {
                let max = armature_scvx::MAX_NODES;
                return Err(src.error(c, format!("count must be 2 to {max}")));
            }
            (*c.get_ref(), None)
        }
        (None, per) => {
            let p = per.as_ref().map_or(2, |p| *p.get_ref());
            let n = p
                .checked_mul(w.len() - 1)
                .map(|n| n + 1)
                .filter(|n| *n <= armature_scvx::MAX_NODES);
            match (p, n) {
                (1.., Some(n)) => (n, Some(p)),
                _ => {
                    let at = per.as_ref().expect("the default fits");
                    let max = armature_scvx::MAX_NODES;
                    return Err(src.error(
                        at,
                        format!("per_segment {p}: need 1 or more, and at most {max} nodes in all"),
                    ));
                }
            }
        }
        (Some(c), Some(_)) => {
            return Err(src.error(c, "give either count or per_segment, not both"));
        }
    })
}

/// The waypoints with their nodes: distinct names, finite positions, increasing nodes from
/// the start (node 0) to the goal (the last node).
fn planned_waypoints(
    task: &TaskFile,
    nodes: usize,
    per_segment: Option<usize>,
    src: Source<'_>,
) -> Result<Vec<PlannedWaypoint>, LocatedError> {
    let w = &task.waypoints;
    let mut waypoints: Vec<PlannedWaypoint> = Vec::new();
    for (i, wp) in w.iter().enumerate() {
        let name = wp.name.get_ref();
        if name.is_empty() || waypoints.iter().any(|p| &p.name == name) {
            return Err(
                src.error(&wp.name, format!("waypoint name '{name}' is empty or used twice"))
            );
        }
        let position = *wp.position.get_ref();
        if position.iter().any(|v| !v.is_finite()) {
            return Err(src.error(&wp.position, "position must be finite"));
        }
        let tolerance = wp.tolerance.as_ref().map_or(0.01, |t| *t.get_ref());
        if !(tolerance.is_finite() && tolerance > 0.0) {
            let t = wp.tolerance.as_ref().expect("the default is positive");
            return Err(src.error(t, format!("tolerance {tolerance} must be > 0")));
        }
        let node = match (&wp.node, per_segment) {
            (Some(k), _) => *k.get_ref(),
            (None, Some(p)) => i * p,
            (None, None) => {
                return Err(src.error(&wp.name, "with nodes.count every waypoint needs a node"));
            }
        };
        let at = wp.node.as_ref().map_or(wp.name.span().start, |k| k.span().start);
        if node >= nodes {
            return Err(
                src.error_at(at, format!("node {node} is beyond the last node {}", nodes - 1))
            );
        }
        if let Some(prev) = waypoints.last()
            && node <= prev.node
        {
            return Err(src.error_at(
                at,
                format!("node {node} does not come after '{}' (node {})", prev.name, prev.node),
            ));
        }
        if i == 0 && node != 0 {
            return Err(src.error_at(at, "the first waypoint is the start: it must be at node 0"));
        }
        if i == w.len() - 1 && node != nodes - 1 {
            return Err(src.error_at(
                at,
                format!("the last waypoint is the goal: it must be at node {}", nodes - 1),
            ));
        }
        waypoints.push(PlannedWaypoint { name: name.clone(), node, position, tolerance });
    }
    Ok(waypoints)
}

/// The node of the waypoint `name` names.
fn node_of(
    waypoints: &[PlannedWaypoint],
    name: &toml::Spanned<String>,
    src: Source<'_>,
) -> Result<usize, LocatedError> {
    waypoints
        .iter()
        .find(|p| &p.name == name.get_ref())
        .map(|p| p.node)
        .ok_or_else(|| src.error(name, format!("no waypoint is named '{}'", name.get_ref())))
}

/// The IK guess's keyframes: each waypoint's position and, unless free, its orientation.
fn keyframes(
    task: &TaskFile,
    waypoints: &[PlannedWaypoint],
    src: Source<'_>,
) -> Result<Vec<Keyframe>, LocatedError> {
    let w = &task.waypoints;
    let mut keyframes = Vec::new();
    for (wp, p) in w.iter().zip(waypoints) {
        let quaternion_wxyz = match wp.orientation.as_ref().map(|o| (o, o.get_ref())) {
            None => None,
            Some((_, OrientationValue::Word(s))) if s == "free" => None,
            Some((o, OrientationValue::Word(s))) => {
                return Err(
                    src.error(o, format!("orientation '{s}': give [w, x, y, z] or \"free\""))
                );
            }
            Some((o, OrientationValue::Quaternion(q))) => {
                SO3::from_quaternion_wxyz(*q).map_err(|e| src.error(o, e.to_string()))?;
                Some(*q)
            }
        };
        keyframes.push(Keyframe { node: p.node, position: p.position, quaternion_wxyz });
    }
    Ok(keyframes)
}

/// `[[orientation]]`: the ranges, checked.
fn orientation_ranges(
    task: &TaskFile,
    waypoints: &[PlannedWaypoint],
    src: Source<'_>,
) -> Result<Vec<PlannedOrientation>, LocatedError> {
    let mut orientation = Vec::new();
    for o in &task.orientation {
        SO3::from_quaternion_wxyz(*o.quaternion_wxyz.get_ref())
            .map_err(|e| src.error(&o.quaternion_wxyz, e.to_string()))?;
        let deg = *o.tolerance_deg.get_ref();
        if !(deg.is_finite() && deg > 0.0 && deg < 180.0) {
            return Err(
                src.error(&o.tolerance_deg, format!("tolerance_deg {deg} must be in (0, 180)"))
            );
        }
        let (a, b) = (node_of(waypoints, &o.from, src)?, node_of(waypoints, &o.to, src)?);
        if a >= b {
            return Err(src.error(
                &o.to,
                format!(
                    "'{}' (node {b}) must come after '{}' (node {a})",
                    o.to.get_ref(),
                    o.from.get_ref()
                ),
            ));
        }
        orientation.push(PlannedOrientation {
            name: format!("{}..{}", o.from.get_ref(), o.to.get_ref()),
            quaternion_wxyz: *o.quaternion_wxyz.get_ref(),
            tolerance_deg: deg,
            first: a,
            last: b,
        });
    }
    Ok(orientation)
}

/// A collision model with its margin and, when held between the nodes, its activation.
type PlannedCollision = (CollisionModel, f64, Option<f64>);

/// `[collision]`: the model for the robot, its margin and activation.
fn collision(
    task: &TaskFile,
    chain: &Chain,
    src: Source<'_>,
) -> Result<Option<PlannedCollision>, LocatedError> {
    Ok(match &task.collision {
        None => None,
        Some(c) => {
            let spec = c.get_ref();
            if !(spec.margin.is_finite() && spec.margin >= 0.0) {
                return Err(src.error(c, format!("margin {} must be ≥ 0", spec.margin)));
            }
            if spec.activation.is_nan() || spec.activation <= 0.0 {
                return Err(src.error(c, format!("activation {} must be > 0", spec.activation)));
            }
            let scene = Scene {
                self_collision: spec.self_collision,
                allowed: spec.allowed.clone(),
                extra: spec.extra.clone(),
                links: spec.links.clone(),
                obstacles: spec.obstacles.clone(),
            };
            let model = scene.model(chain).map_err(|e| src.error(c, e.to_string()))?;
            Some((model, spec.margin, spec.between_nodes.then_some(spec.activation)))
        }
    })
}

/// The initial guess: IK through the keyframes, timed by a spline at the joint limits.
struct Guess {
    ik: IkTrajectory,
    spline: JointSpline,
    duration: f64,
    dilation: Vec<f64>,
}

/// IK through the keyframes (from `[robot] start` if given), time-parameterized by a spline
/// (zero end velocities) whose duration the limits allow, clamped into the time window.
fn initial_guess(
    task: &TaskFile,
    chain: &Chain,
    keyframes: &[Keyframe],
    limits: &JointLimits,
    (t_min, t_max): (f64, f64),
    nodes: usize,
    src: Source<'_>,
) -> Result<Guess, LocatedError> {
    let n = chain.dof();
    let mode = match task.initialization.ik.get_ref().as_str() {
        "sequential" => Mode::Sequential,
        "parallel" => Mode::Parallel,
        other => {
            return Err(src.error(
                &task.initialization.ik,
                format!("ik '{other}': give \"sequential\" or \"parallel\""),
            ));
        }
    };
    let start = start_configuration(task, chain, keyframes, src)?;
    let mut ik = ik_interpolation(
        chain,
        keyframes,
        start.as_deref().unwrap_or(&vec![0.0; n]),
        &IkSettings { restarts: task.initialization.restarts, ..IkSettings::default() },
        mode,
    )
    .map_err(|e| src.error_at(0, format!("IK initialization: {e}")))?;
    if let Some(start) = start {
        ik.q[0] = start;
    }
    let knots = JointSpline::time_optimal_knots(&ik.q, &limits.velocity)
        .map_err(|e| src.error_at(0, format!("initial guess: {e}")))?;
    let spline = JointSpline::through_timed(&ik.q, &knots)
        .map_err(|e| src.error_at(0, format!("initial guess: {e}")))?;
    let window = (t_min.max(1e-3 * t_max), t_max);
    let duration = guess_duration(&spline, &ik.q, limits, nodes, window);
    let mut dilation: Vec<f64> = knots.iter().map(|h| h * duration * (nodes - 1) as f64).collect();
    dilation.push(dilation[nodes - 2]);
    Ok(Guess { ik, spline, duration, dilation })
}

/// `[robot] start`, checked: one finite angle per joint within its limits, putting the end
/// effector within the first waypoint's tolerance.
fn start_configuration(
    task: &TaskFile,
    chain: &Chain,
    keyframes: &[Keyframe],
    src: Source<'_>,
) -> Result<Option<Vec<f64>>, LocatedError> {
    let Some(start) = &task.robot.start else { return Ok(None) };
    let q = start.get_ref();
    chain.check_q(q).map_err(|e| src.error(start, format!("start: {e}")))?;
    let (lo, hi) = chain.position_limits();
    if let Some(j) = (0..q.len()).find(|&j| q[j] < lo[j] || q[j] > hi[j]) {
        let name = &chain.joints()[j].name;
        return Err(src.error(
            start,
            format!(
                "start: joint {j} ('{name}') at {} is outside its limits [{}, {}]",
                q[j], lo[j], hi[j]
            ),
        ));
    }
    let mut ws = chain.fk_workspace();
    chain.forward(q, &mut ws).map_err(|e| src.error(start, format!("start: {e}")))?;
    let (first, wp) = (&keyframes[0], &task.waypoints[0]);
    let tolerance = wp.tolerance.as_ref().map_or(0.01, |t| *t.get_ref());
    let gap = (ws.ee().translation() - nalgebra::Vector3::from(first.position)).norm();
    if gap > tolerance {
        return Err(src.error(
            start,
            format!(
                "start puts the end effector {gap:.4} m from the first waypoint '{}' (tolerance {tolerance} m)",
                wp.name.get_ref()
            ),
        ));
    }
    Ok(Some(q.clone()))
}

/// The guess's duration: the spline's shortest under the velocity limits and the
/// accelerations the torque limits allow at the start, then (rigid-body dynamics) stretched
/// until its torques at the nodes fit the limits; clamped into the window.
fn guess_duration(
    spline: &JointSpline,
    q: &[Vec<f64>],
    limits: &JointLimits,
    nodes: usize,
    (lo, hi): (f64, f64),
) -> f64 {
    let n = limits.torque.len();
    let amax: Vec<f64> = match &limits.dynamics {
        RobotDynamics::Decoupled(inertia) => {
            (0..n).map(|j| limits.torque[j] / inertia[j]).collect()
        }
        RobotDynamics::RigidBody(model) => {
            let (mut ws, mut m) = (model.workspace(), nalgebra::DMatrix::zeros(n, n));
            match model.crba(&mut ws, &q[0], &mut m) {
                Ok(()) => (0..n).map(|j| limits.torque[j] / m[(j, j)]).collect(),
                Err(_) => limits.torque.clone(),
            }
        }
    };
    let mut duration = spline.min_duration(&limits.velocity, &amax).clamp(lo, hi);
    if let RobotDynamics::RigidBody(_) = &limits.dynamics {
        for _ in 0..30 {
            let qd: Vec<Vec<f64>> = (0..nodes).map(|k| spline.velocity(k, duration)).collect();
            let qdd: Vec<Vec<f64>> = (0..nodes).map(|k| spline.acceleration(k, duration)).collect();
            let tau = limits.dynamics.torques(q, &qd, &qdd);
            let ratio = tau
                .iter()
                .flat_map(|t| t.iter().zip(&limits.torque).map(|(t, l)| t.abs() / l))
                .fold(0.0f64, f64::max);
            if ratio <= 1.0 || duration >= hi {
                break;
            }
            duration = (duration * ratio.sqrt().clamp(1.05, 2.0)).min(hi);
        }
    }
    duration
}

/// The states (angles, velocities), the torques and the dynamics `q̈ = τ / I`, with their
/// bounds, boundary values and guesses.
fn states_and_dynamics(
    task: &TaskFile,
    chain: &Chain,
    limits: &JointLimits,
    guess: &Guess,
    nodes: usize,
) -> Problem {
    let n = chain.dof();
    let robot = &task.robot;
    let (ik, spline, duration) = (&guess.ik, &guess.spline, guess.duration);
    let (velocity_limit, torque_limit) = (&limits.velocity, &limits.torque);
    let (qlo, qhi) = chain.position_limits();
    let angle = State::new("angle", n)
        .bounds(&qlo, &qhi)
        .initial_value(&ik.q[0])
        .guess(ik.q.iter().flatten().copied().collect());
    let velocity = State::new("velocity", n)
        .bounds(&velocity_limit.iter().map(|v| -v).collect::<Vec<_>>(), velocity_limit)
        .initial_value(&vec![0.0; n])
        .final_value(&vec![0.0; n])
        .guess((0..nodes).flat_map(|k| spline.velocity(k, duration)).collect());
    let velocity =
        if robot.velocity_limit_peaks { velocity.with_interval_bounds() } else { velocity };
    let qd: Vec<Vec<f64>> = (0..nodes).map(|k| spline.velocity(k, duration)).collect();
    let qdd: Vec<Vec<f64>> = (0..nodes).map(|k| spline.acceleration(k, duration)).collect();
    let tau_guess = limits.dynamics.torques(&ik.q, &qd, &qdd);
    let torque = Control::new("torque", n)
        .bounds(&torque_limit.iter().map(|t| -t).collect::<Vec<_>>(), torque_limit)
        .guess(
            tau_guess
                .iter()
                .flat_map(|t| t.iter().zip(torque_limit).map(|(t, l)| t.clamp(-l, *l)))
                .collect(),
        );
    let qdd_expr = limits.dynamics.acceleration(&angle.expr(), &velocity.expr(), &torque.expr());
    Problem {
        dynamics: vec![velocity.expr(), qdd_expr],
        states: vec![angle, velocity],
        controls: vec![torque],
        ..Problem::new(nodes)
    }
}

/// What the task asks of the end effector and the links.
struct TaskParts<'a> {
    waypoints: &'a [PlannedWaypoint],
    orientation: &'a [PlannedOrientation],
    table_height: Option<f64>,
    collision: Option<&'a PlannedCollision>,
}

/// The task's constraints on the forward kinematics of `problem`'s angles: waypoint balls,
/// orientation ranges, the table, clearances; and the outputs (end-effector pose, frames,
/// clearances).
///
/// # Errors
/// The symbolic forward kinematics' (for the robot).
fn add_task_constraints(
    problem: &mut Problem,
    chain: &Chain,
    t: &TaskParts<'_>,
    velocity_limit_peaks: bool,
) -> Result<(), String> {
    let nodes = problem.nodes;
    let fk = chain.symbolic_fk(&problem.states[0].expr()).map_err(|e| e.to_string())?;
    let p_ee = fk.ee_position();
    // With the velocity peaks bounded, the limits' integral only has to catch what lies
    // between the integration grid's points: a budget of 1e-5 (1e-6 slows the solve).
    let eps = if velocity_limit_peaks { 1e-5 } else { 1e-6 };
    let limits = CtcsOptions { penalty: Penalty::Relu, eps, group: 0 };
    let mut constraints: Vec<ProblemConstraint> = Vec::new();
    if let Some(h) = t.table_height {
        constraints.push(ProblemConstraint {
            constraint: (Expr::scalar(h) - p_ee.at(2)).le(0.0).ctcs().named("table"),
            ctcs: limits,
        });
    }
    let mut balls: Vec<Ball> = t
        .waypoints
        .iter()
        .map(|p| Ball {
            name: format!("waypoint {}", p.name),
            g: &p_ee - Expr::parameter(&waypoint_parameter(&p.name), Shape::Vector(3), &p.position),
            radius: p.tolerance,
            nodes: vec![p.node],
        })
        .collect();
    for o in t.orientation {
        let r = SO3::from_quaternion_wxyz(o.quaternion_wxyz).map_err(|e| e.to_string())?;
        let (deg, first, last, name) = (o.tolerance_deg, o.first, o.last, &o.name);
        let log = Expr::from_matrix(&r.matrix().transpose()).matmul(&fk.ee_rotation()).so3_log();
        constraints.push(
            (log.norm2() - deg.to_radians())
                .le(0.0)
                .ctcs()
                .over(first, last)
                .named(format!("orientation {name} within {deg}°"))
                .into(),
        );
        balls.push(Ball {
            name: format!("orientation {name} within {deg}° at the nodes"),
            g: log,
            radius: deg.to_radians(),
            nodes: (first..=last).collect(),
        });
    }
    let mut between_nodes = Vec::new();
    let mut outputs =
        vec![("ee_position".to_string(), p_ee.clone()), ("ee_pose".to_string(), fk.t_ee.clone())];
    for (name, frame) in &fk.frames {
        outputs.push((format!("T_{name}"), frame.clone()));
    }
    if let Some((model, margin, activation)) = t.collision {
        let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
        let distances = model.symbolic_distances(&positions);
        if !distances.is_empty() {
            // Every pair's signed distance, in the model's pair order (the 3D view's readout).
            let all: Vec<Expr> = distances.iter().map(|(_, d)| d.clone()).collect();
            outputs.push(("clearance".to_string(), Expr::concat(&all)));
        }
        if let (Some(activation), false) = (activation, distances.is_empty()) {
            between_nodes.push(BetweenNodes {
                name: "clearance".into(),
                g: Expr::concat(&distances.iter().map(|(_, d)| *margin - d).collect::<Vec<_>>()),
                first: 0,
                last: nodes - 1,
                activation: Some(*activation),
            });
        }
        for (pair, d) in distances {
            constraints.push(ProblemConstraint {
                constraint: (*margin - &d).le(0.0).ctcs().named(format!("clearance {pair}")),
                // An integral of its own: summed into the limits' integral, the clearance
                // violations of single pairs are drowned and the solve stalls.
                ctcs: CtcsOptions { group: 1, ..limits },
            });
            constraints.push(
                (*margin - &d).le(0.0).named(format!("clearance {pair} at the nodes")).into(),
            );
        }
    }
    problem.constraints = constraints;
    problem.balls = balls;
    problem.between_nodes = between_nodes;
    problem.outputs = outputs;
    problem.state_bounds_ctcs = Some(limits);
    Ok(())
}

impl Plan {
    /// Compiles the problem and sets the guess.
    ///
    /// # Errors
    /// The problem layer's (a bug here rather than bad input: the plan was checked).
    pub fn compile(&self) -> Result<CompiledProblem, armature_scvx::ProblemError> {
        let mut c = self.problem.compile(self.settings.clone())?;
        c.set_dilation_guess(&self.dilation_guess)?;
        Ok(c)
    }
}
