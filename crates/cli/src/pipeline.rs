//! The main job's front half: task file → checked [`ArmTask`] (every error at its place in
//! the file) → [`armature_arm`]'s problem and guess.

use std::path::Path;

use armature_arm::{
    ArmError, ArmTask, Clearance, Initialization, RetimeStall, TaskItem, TimeWindow,
};
use armature_collision::{CollisionModel, Scene};
use armature_ik::{IkTrajectory, Mode};
use armature_kinematics::{Chain, Inertial, KinematicsError, LoadOptions, Pose};
use armature_lie::SO3;
use armature_scvx::{CompiledProblem, Problem, PtrSettings};

use crate::robot_dynamics::dynamics_model;
use crate::task::{
    DynamicsKind, Limit, LocatedError, OrientationValue, Source, TaskFile, resolve_robot,
};

/// A waypoint as planned: where and when.
pub type PlannedWaypoint = armature_arm::Waypoint;

/// An orientation range as planned: the end-effector rotation stays within
/// `tolerance_deg` of `quaternion_wxyz` from node `first` to node `last`.
pub type PlannedOrientation = armature_arm::OrientationRange;

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
    /// `[time] retime_stall`'s rule with the task it retimes.
    pub retime_stall: Option<Stall>,
}

/// A [`RetimeStall`] rule with the task whose path it retimes.
pub type Stall = (RetimeStall, Box<ArmTask>);

pub use armature_arm::waypoint_parameter;

/// The task file as an [`ArmTask`], with every check that needs the file's positions.
///
/// # Errors
/// The first problem found, as `file:line:col: reason`.
pub fn arm_task(
    task: &TaskFile,
    src: Source<'_>,
    path: Option<&Path>,
) -> Result<ArmTask, LocatedError> {
    let robot = &task.robot;
    let chain = robot_chain(task, src, path)?;
    let (velocity_limit, torque_limit) = joint_limits(task, &chain, src)?;
    let dynamics = dynamics_model(task, src)?;
    let (t_min, t_max) = time_window(task, src)?;
    let (nodes, per_segment) = node_count(task, dynamics.default_per_segment(), src)?;
    let mut waypoints = planned_waypoints(task, nodes, per_segment, src)?;
    for (w, q) in waypoints.iter_mut().zip(guess_orientations(task, src)?) {
        w.orientation = q;
    }
    let orientation = orientation_ranges(task, &waypoints, src)?;
    let table_height = match &task.table_height {
        Some(h) if !h.get_ref().is_finite() => {
            return Err(src.error(h, "table_height must be finite"));
        }
        h => h.as_ref().map(|h| *h.get_ref()),
    };
    let collision = collision(task, &chain, src)?;
    let mut settings = crate::settings::checked(&task.settings, src)?;
    if !crate::settings::has_key(src.text, &["settings", "discretization", "substeps"]) {
        let per = per_segment.unwrap_or_else(|| dynamics.default_per_segment());
        settings.discretization.substeps = dynamics.default_substeps(per);
    }
    if !crate::settings::has_key(src.text, &["settings", "lam_tr"]) {
        settings.lam_tr = dynamics.default_trust_region_weight();
    }
    let velocity_limit_peaks =
        robot.velocity_limit_peaks.unwrap_or_else(|| dynamics.default_velocity_limit_peaks());
    let time_scaled_torque =
        robot.time_scaled_torque.unwrap_or_else(|| dynamics.default_time_scaled_torque());
    let arm_task = ArmTask {
        chain,
        dynamics,
        velocity_limit,
        torque_limit,
        velocity_limit_peaks,
        time_scaled_torque,
        // Angles are held by the limits' integral on the task's own grid (a refined stage,
        // `ArmTask::refined`, adds their rows).
        angle_limit_peaks: false,
        start: robot.start.as_ref().map(|s| s.get_ref().clone()),
        time: TimeWindow { min: t_min, max: t_max, minimize: task.time.minimize },
        nodes,
        waypoints,
        orientation,
        table_height,
        collision,
        initialization: initialization(task, src)?,
        settings,
        retime_stall: retime_stall(task, src)?,
    };
    Ok(arm_task)
}

/// Checks an [`ArmTask`] built from `task` ([`arm_task`], or refined from one) against its
/// robot and builds the problem and its guess, errors located in `task`.
///
/// # Errors
/// The first problem found, as `file:line:col: reason`.
pub fn plan_arm(task: &TaskFile, src: Source<'_>, arm_task: ArmTask) -> Result<Plan, LocatedError> {
    let arm = arm_task.plan().map_err(|e| locate(task, src, &e))?;
    let nodes = arm_task.nodes;
    let table_height = arm_task.table_height;
    let ArmTask { chain, waypoints, orientation, velocity_limit, torque_limit, collision, .. } =
        arm_task;
    Ok(Plan {
        chain,
        nodes,
        waypoints,
        velocity_limit,
        torque_limit,
        table_height,
        margin: collision.as_ref().map_or(0.0, |c| c.margin),
        collision: collision.map(|c| c.model),
        orientation,
        problem: arm.problem,
        dilation_guess: arm.dilation_guess,
        ik: arm.ik,
        settings: arm.settings,
        retime_stall: arm.retime_stall,
    })
}

/// `[robot]`'s chain: loaded (URDF base, tip and keypoint links as given), with its tool
/// centre point.
fn robot_chain(
    task: &TaskFile,
    src: Source<'_>,
    path: Option<&Path>,
) -> Result<Chain, LocatedError> {
    let robot = &task.robot;
    let spec = resolve_robot(robot.name.get_ref(), path);
    let links: Option<Vec<&str>> =
        robot.keypoints.as_ref().map(|k| k.get_ref().iter().map(String::as_str).collect());
    let options = LoadOptions {
        base: robot.base.as_deref(),
        tip: robot.tip.as_deref(),
        keypoint_links: links.as_deref(),
    };
    let chain = armature_kinematics::load_robot_with(&spec, &options).map_err(|e| {
        let hint = match e {
            KinematicsError::NoRootLink => ": give `base = \"LINK\"` in [robot]",
            KinematicsError::AmbiguousTip { .. } => ": give `tip = \"LINK\"` in [robot]",
            _ => "",
        };
        let message = format!("{e}{hint}");
        match &robot.keypoints {
            Some(k) if message.contains("keypoint") => src.error(k, message),
            _ => src.error(&robot.name, message),
        }
    })?;
    let chain = match &robot.tool {
        None => chain,
        Some(t) => {
            let spec = t.get_ref();
            let pose = Pose {
                position: spec.position,
                quaternion_wxyz: spec.quaternion_wxyz.unwrap_or([1.0, 0.0, 0.0, 0.0]),
            };
            chain.with_tool(&pose).map_err(|e| src.error(t, e.to_string()))?
        }
    };
    match &robot.payload {
        None => Ok(chain),
        Some(p) => {
            if robot.dynamics.as_ref().map(|d| *d.get_ref()) != Some(DynamicsKind::RigidBody) {
                return Err(src.error(p, "a payload applies to dynamics = \"rigid_body\" only"));
            }
            let spec = p.get_ref();
            let payload = Inertial {
                mass: spec.mass,
                com: spec.com.unwrap_or([0.0; 3]),
                inertia: spec.inertia.unwrap_or([0.0; 6]),
            };
            chain.with_payload(&payload).map_err(|e| src.error(p, e.to_string()))
        }
    }
}

/// Where in the file the part of the task an [`ArmError`] names was written.
fn locate(task: &TaskFile, src: Source<'_>, e: &ArmError) -> LocatedError {
    let robot = &task.robot;
    let name_at = robot.name.span().start;
    let at = match e.item {
        TaskItem::Robot => name_at,
        TaskItem::Dynamics => robot
            .dynamics
            .as_ref()
            .map(|d| d.span().start)
            .or(robot.inertia.as_ref().map(|i| i.span().start))
            .unwrap_or(name_at),
        TaskItem::VelocityLimit => {
            robot.velocity_limit.as_ref().map_or(name_at, |l| l.span().start)
        }
        TaskItem::TorqueLimit => robot.torque_limit.as_ref().map_or(name_at, |l| l.span().start),
        TaskItem::Start => robot.start.as_ref().map_or(name_at, |s| s.span().start),
        TaskItem::Time => task.time.max.span().start,
        TaskItem::Waypoint(i) => task.waypoints.get(i).map_or(0, |w| w.position.span().start),
        TaskItem::Orientation(i) => {
            task.orientation.get(i).map_or(0, |o| o.quaternion_wxyz.span().start)
        }
        TaskItem::Table => task.table_height.as_ref().map_or(0, |t| t.span().start),
        TaskItem::Collision => task.collision.as_ref().map_or(0, |c| c.span().start),
        TaskItem::Nodes | TaskItem::Initialization | TaskItem::Solution => 0,
    };
    src.error_at(at, e.message.clone())
}

/// Most starts of a solve (`[initialization] starts`).
pub const MAX_STARTS: usize = 16;

/// `[initialization]`: the IK mode, restarts, starts, seed and fallbacks.
fn initialization(task: &TaskFile, src: Source<'_>) -> Result<Initialization, LocatedError> {
    let mode = match task.initialization.ik.get_ref().as_str() {
        "sequential" => Mode::Sequential,
        "parallel" => Mode::Parallel,
        "branches" => Mode::Branches,
        other => {
            return Err(src.error(
                &task.initialization.ik,
                format!("ik '{other}': give \"branches\", \"sequential\" or \"parallel\""),
            ));
        }
    };
    let restarts = &task.initialization.restarts;
    if *restarts.get_ref() > armature_ik::MAX_RESTARTS {
        let max = armature_ik::MAX_RESTARTS;
        return Err(src.error(restarts, format!("restarts {}: at most {max}", restarts.get_ref())));
    }
    let starts = &task.initialization.starts;
    if !(1..=MAX_STARTS).contains(starts.get_ref()) {
        let message = format!("starts {}: give 1 to {MAX_STARTS}", starts.get_ref());
        return Err(src.error(starts, message));
    }
    let fallbacks = &task.initialization.fallbacks;
    if *fallbacks.get_ref() > MAX_STARTS {
        let message = format!("fallbacks {}: give 0 to {MAX_STARTS}", fallbacks.get_ref());
        return Err(src.error(fallbacks, message));
    }
    Ok(Initialization {
        mode,
        restarts: *restarts.get_ref(),
        starts: *starts.get_ref(),
        seed: task.initialization.seed,
        fallbacks: *fallbacks.get_ref(),
    })
}

/// `[robot]`'s velocity and torque limits (the robot's own where not given).
fn joint_limits(
    task: &TaskFile,
    chain: &Chain,
    src: Source<'_>,
) -> Result<(Vec<f64>, Vec<f64>), LocatedError> {
    let robot = &task.robot;
    let n = chain.dof();
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
    Ok((velocity, torque))
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

/// `[time] retime`: whether to retime the solved path (default: when the time is
/// minimized).
///
/// # Errors
/// `retime = true` on a task whose time is not minimized.
pub fn retiming(task: &TaskFile, src: Source<'_>) -> Result<bool, LocatedError> {
    match &task.time.retime {
        Some(r) if *r.get_ref() && !task.time.minimize => Err(src.error(
            r,
            "retime = true follows the path as fast as the limits allow: it needs minimize = true",
        )),
        Some(r) => Ok(*r.get_ref()),
        None => Ok(task.time.minimize),
    }
}

/// `[time] retime_stall`: the rule that stops the solve's minimization once its path
/// retimed stalls (default: when the result is retimed), or `None`.
///
/// # Errors
/// `retime_stall = true` on a task that is not retimed.
fn retime_stall(task: &TaskFile, src: Source<'_>) -> Result<Option<RetimeStall>, LocatedError> {
    let retimed = retiming(task, src)?;
    let on = match &task.time.retime_stall {
        Some(r) if *r.get_ref() && !retimed => return Err(src.error(
            r,
            "retime_stall = true judges the solve by its path retimed: it needs the result retimed (retime and minimize true)",
        )),
        Some(r) => *r.get_ref(),
        None => retimed,
    };
    Ok(on.then(RetimeStall::default))
}

/// `[nodes] refine`: the factor of the mesh refinement of `arm` (the task built from `task`),
/// by the library's rule ([`ArmTask::refinement_factor`]): when not given, the dynamics
/// model's (`DynamicsModel::default_refine`: 2 decoupled, 1 rigid-body), or 1 where that grid
/// would pass the node limit.
///
/// # Errors
/// A factor below 1 or above 16, or a refined grid beyond the node limit.
pub fn refinement(task: &TaskFile, src: Source<'_>, arm: &ArmTask) -> Result<usize, LocatedError> {
    let Some(r) = &task.nodes.refine else {
        return Ok(arm.refinement_factor(None).unwrap_or(1));
    };
    let k = *r.get_ref();
    match arm.refinement_factor(Some(k)) {
        Ok(k) if k <= 16 => Ok(k),
        _ => {
            let max = armature_scvx::MAX_NODES;
            let why =
                format!("refine {k}: need 1 to 16, and at most {max} nodes in all once refined");
            Err(src.error(r, why))
        }
    }
}

/// `[nodes]`: the node count, and the nodes per segment when given that way.
fn node_count(
    task: &TaskFile,
    default_per_segment: usize,
    src: Source<'_>,
) -> Result<(usize, Option<usize>), LocatedError> {
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
            let p = per.as_ref().map_or(default_per_segment, |p| *p.get_ref());
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
        waypoints.push(PlannedWaypoint {
            name: name.clone(),
            node,
            position,
            tolerance,
            orientation: None,
        });
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

/// Each waypoint's orientation for the IK guess (`None`: free).
fn guess_orientations(
    task: &TaskFile,
    src: Source<'_>,
) -> Result<Vec<Option<[f64; 4]>>, LocatedError> {
    let mut out = Vec::new();
    for wp in &task.waypoints {
        out.push(match wp.orientation.as_ref().map(|o| (o, o.get_ref())) {
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
        });
    }
    Ok(out)
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
                src.error(&o.tolerance_deg, format!("tolerance_deg {deg:e} must be in (0, 180)"))
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

/// `[collision]`: the model for the robot, its margin and activation.
fn collision(
    task: &TaskFile,
    chain: &Chain,
    src: Source<'_>,
) -> Result<Option<Clearance>, LocatedError> {
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
            Some(Clearance {
                model,
                margin: spec.margin,
                between_nodes_activation: spec.between_nodes.then_some(spec.activation),
            })
        }
    })
}

/// `problem` compiled with `settings`, the dilation guess set, and `stall`'s monitor.
fn compile_guess(
    problem: &Problem,
    settings: &armature_scvx::PtrSettings,
    dilation_guess: &[f64],
    stall: Option<&Stall>,
) -> Result<CompiledProblem, armature_scvx::ProblemError> {
    let mut c = problem.compile(settings.clone())?;
    c.set_dilation_guess(dilation_guess)?;
    armature_arm::set_retime_stall(&mut c, stall);
    Ok(c)
}

impl Plan {
    /// Compiles the problem and sets the guess.
    ///
    /// # Errors
    /// The problem layer's (a bug here rather than bad input: the plan was checked).
    pub fn compile(&self) -> Result<CompiledProblem, armature_scvx::ProblemError> {
        let stall = self.retime_stall.as_ref();
        compile_guess(&self.problem, &self.settings, &self.dilation_guess, stall)
    }
}
