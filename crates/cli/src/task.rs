//! Task files: what most users write — a robot, its simple dynamics, waypoints, orientation
//! constraints, a table, obstacles, time, nodes, initialization and algorithm settings.
//!
//! ```toml
//! table_height = 0.0             # the end effector stays above z = table_height (top-level
//!                                # keys come before the first [table])
//!
//! [robot]
//! name = "arm7"                  # built-in (arm7, ur5e), or a .toml screw table / .urdf path
//! inertia = [0.08, 0.06, 0.05, 0.04, 0.02, 0.01, 0.005]   # q̈ = τ / I
//! # dynamics = "rigid_body"      # M(q)q̈ + C(q,q̇)q̇ + g(q) = τ from the URDF's <inertial>s
//! # gravity = [0.0, 0.0, -9.81]  # m/s² (rigid_body only; default standard gravity along −z)
//! # start = [0, -1.57, 1.57, -1.57, -1.57, 0]   # joint angles at the start (default: IK)
//! # keypoints = ["base_link", "upper_arm_link", "forearm_link", "tool0"]  # URDF links
//! # tool = { position = [0.0, 0.0, 0.12] }      # tool centre point in the tip frame
//! # payload = { mass = 2.0, com = [0.0, 0.0, 0.05] }   # held by the tool (rigid_body)
//! velocity_limit = 3.0           # one value or one per joint (default: the robot's)
//! torque_limit = [8, 8, 4, 4, 2, 1, 0.5]
//! # time_scaled_torque = false   # solve for the plain torques (default: the torques times
//!                                # their intervals' durations, decoupled dynamics only)
//!
//! [time]
//! max = 4.0                      # free final time in [min, max], minimized by default
//! # retime = false               # keep the solve's own timing (default: the solved path is
//!                                # then followed time-optimally within the limits, TOPP-RA)
//! # retime_stall = false         # minimize the solve's own time to the end (default: with
//!                                # a retimed result, stop once the retimed time stalls)
//!
//! [nodes]
//! per_segment = 3                # waypoint k sits at node k·per_segment (or give `count`;
//!                                # default 3, 2 with dynamics = "rigid_body")
//! # refine = 1                   # one stage (default 2, 1 with dynamics = "rigid_body":
//!                                # then again from that solution, every segment split in 2)
//!
//! [[waypoints]]
//! name = "home"
//! position = [0.69, 0.0, 0.34]
//! orientation = [1.0, 0.0, 0.0, 0.0]   # [w, x, y, z] for the IK guess, or "free"
//! tolerance = 0.01                     # the end effector passes within this distance (m)
//!
//! [[waypoints]]
//! name = "pre_grasp"
//! position = [0.35, -0.25, 0.2]
//! orientation = [0.7071068, 0.0, 0.7071068, 0.0]
//!
//! [[waypoints]]
//! name = "place"
//! position = [0.35, 0.25, 0.05]
//! orientation = [0.7071068, 0.0, 0.7071068, 0.0]
//!
//! [[orientation]]                # gripper orientation held between two waypoints
//! quaternion_wxyz = [0.7071068, 0.0, 0.7071068, 0.0]
//! tolerance_deg = 5.0
//! from = "pre_grasp"
//! to = "place"
//!
//! [initialization]               # the IK guess through the waypoints
//! ik = "branches"                # least joint travel over IK branches (default), or
//!                                # "sequential" / "parallel" node by node
//! restarts = 8                   # random configurations solved from at each waypoint
//! starts = 2                     # solves from IK paths searched with 8, 64, 512 samples
//!                                # in parallel, the fastest kept (retimed)
//! seed = 0                       # of the random configurations at the waypoints
//! fallbacks = 2                  # a solve that does not converge is tried again from
//!                                # up to this many other guesses (other samples, timing)
//!
//! [settings]                     # armature_scvx::PtrSettings, every field optional
//! max_iterations = 200
//! merit = { lagrangian = { sigma = 0.5 } }   # or "exact_penalty" (default)
//!
//! [settings.subproblem]          # nested settings are sub-tables
//! solver = "interior_point"      # or "clarabel"
//! ```
//!
//! Unknown keys are rejected; every error names `file:line:col` and the reason.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

/// A parsed task file (values keep their positions in the file for error messages).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TaskFile {
    /// The robot and its dynamics.
    pub robot: RobotSpec,
    /// Final time.
    pub time: TimeSpec,
    /// Node count or nodes per waypoint segment.
    #[serde(default)]
    pub nodes: NodesSpec,
    /// Waypoints in order; the first is the start (the arm starts at rest there), the last
    /// the goal (the arm ends at rest).
    pub waypoints: Vec<WaypointSpec>,
    /// Orientation constraints over waypoint ranges.
    #[serde(default)]
    pub orientation: Vec<OrientationSpec>,
    /// The end effector stays above this height (m), in continuous time.
    #[serde(default)]
    #[schemars(with = "Option<f64>")]
    pub table_height: Option<Spanned<f64>>,
    /// Capsules, self-collision and obstacles.
    #[serde(default)]
    #[schemars(with = "Option<CollisionSpec>")]
    pub collision: Option<Spanned<CollisionSpec>>,
    /// Initial guess.
    #[serde(default)]
    pub initialization: InitSpec,
    /// Algorithm settings ([`armature_scvx::PtrSettings`]; every key optional).
    #[serde(default)]
    pub settings: armature_scvx::PtrSettings,
}

/// The robot: kinematics and its dynamics (`q̈ = τ / I`, or rigid-body).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    /// A built-in name, or a path (relative to the task file) to a `.toml` screw table or a
    /// `.urdf`.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// URDF base link.
    #[serde(default)]
    pub base: Option<String>,
    /// URDF tip link.
    #[serde(default)]
    pub tip: Option<String>,
    /// The dynamics model: `decoupled_inertia` (default; `q̈ = τ / I` with `inertia`) or
    /// `rigid_body` (`M(q)q̈ + C(q, q̇)q̇ + g(q) = τ` from the robot's mass properties).
    #[serde(default)]
    #[schemars(with = "Option<DynamicsKind>")]
    pub dynamics: Option<Spanned<DynamicsKind>>,
    /// Joint inertias (one per joint, > 0) of the decoupled model.
    #[serde(default)]
    #[schemars(with = "Option<Vec<f64>>")]
    pub inertia: Option<Spanned<Vec<f64>>>,
    /// Gravity (m/s², base frame) of the rigid-body model. Default `[0, 0, −9.80665]`.
    #[serde(default)]
    #[schemars(with = "Option<[f64; 3]>")]
    pub gravity: Option<Spanned<Vec<f64>>>,
    /// URDF links to put keypoints at, named after them (default: the base, the child link
    /// of every movable joint, and the tip). Capsules and frames name keypoints.
    #[serde(default)]
    #[schemars(with = "Option<Vec<String>>")]
    pub keypoints: Option<Spanned<Vec<String>>>,
    /// A tool centre point: the end effector moves by this offset in the tip's frame, and a
    /// keypoint `tool` marks it. Waypoints and orientations are then the tool's.
    #[serde(default)]
    #[schemars(with = "Option<ToolSpec>")]
    pub tool: Option<Spanned<ToolSpec>>,
    /// A payload held by the end effector (rigid-body dynamics only): its mass properties in
    /// the end-effector (tool) frame.
    #[serde(default)]
    #[schemars(with = "Option<PayloadSpec>")]
    pub payload: Option<Spanned<PayloadSpec>>,
    /// Joint angles at the start (rad or m; default: IK of the first waypoint). The end
    /// effector must then be within the first waypoint's tolerance.
    #[serde(default)]
    #[schemars(with = "Option<Vec<f64>>")]
    pub start: Option<Spanned<Vec<f64>>>,
    /// Velocity limit: one value or one per joint (default: the robot's).
    #[serde(default)]
    #[schemars(with = "Option<Limit>")]
    pub velocity_limit: Option<Spanned<Limit>>,
    /// Torque limit: one value or one per joint (default: the robot's).
    #[serde(default)]
    #[schemars(with = "Option<Limit>")]
    pub torque_limit: Option<Spanned<Limit>>,
    /// Also bound the velocities at every integration grid point between the nodes (one
    /// linearized row per joint, grid point and side; scvx's `Ocp::interval_bounds`),
    /// besides the continuous-time integral of the velocity limits, whose linearization has
    /// no gradient where the motion rides a limit. Default: true for the decoupled
    /// dynamics, false for `dynamics = "rigid_body"` (`DynamicsModel::default_velocity_limit_peaks`).
    #[serde(default)]
    pub velocity_limit_peaks: Option<bool>,
    /// Solve for the torques times their segments' durations (`ArmTask::time_scaled_torque`):
    /// the decoupled model's velocities are then linear in the solver's variables and the
    /// solve takes fewer iterations; the torque jumps at the nodes where the segments'
    /// durations change. Default: true for the decoupled dynamics, false for
    /// `dynamics = "rigid_body"` (`DynamicsModel::default_time_scaled_torque`).
    #[serde(default)]
    pub time_scaled_torque: Option<bool>,
}

/// A tool centre point's offset from the tip frame.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    /// Offset (m) in the tip frame.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub position: [f64; 3],
    /// Rotation `[w, x, y, z]` of the tool frame in the tip frame (default identity).
    #[serde(default, deserialize_with = "armature_kinematics::exact::optional")]
    pub quaternion_wxyz: Option<[f64; 4]>,
}

/// A payload's mass properties in the end-effector frame.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PayloadSpec {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass (m) in the end-effector frame. Default the frame's origin.
    #[serde(default, deserialize_with = "armature_kinematics::exact::optional")]
    pub com: Option<[f64; 3]>,
    /// Rotational inertia about the centre of mass, `[ixx, ixy, ixz, iyy, iyz, izz]`
    /// (kg·m²). Default zero (a point mass).
    #[serde(default, deserialize_with = "armature_kinematics::exact::optional")]
    pub inertia: Option<[f64; 6]>,
}

/// Which dynamics the robot obeys.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DynamicsKind {
    /// `q̈ = τ / I` per joint (the seed tutorial's model).
    DecoupledInertia,
    /// `M(q)q̈ + C(q, q̇)q̇ + g(q) = τ` (ABA), from the robot's link inertials.
    RigidBody,
}

/// One limit for all joints, or one per joint.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Limit {
    /// The same for every joint.
    All(f64),
    /// Per joint.
    Each(Vec<f64>),
}

/// Final time: free in `[min, max]`, minimized by default.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Upper bound (s).
    #[schemars(with = "f64")]
    pub max: Spanned<f64>,
    /// Lower bound (s). Default 0.
    #[serde(default)]
    #[schemars(with = "Option<f64>")]
    pub min: Option<Spanned<f64>>,
    /// Minimize the final time. Default true.
    #[serde(default = "yes")]
    pub minimize: bool,
    /// After converging, follow the solved path time-optimally within the velocity and
    /// torque limits (`ArmTask::retime`); the result then carries the retimed trajectory,
    /// which is what is streamed and shown. Default: `minimize`.
    #[serde(default)]
    #[schemars(with = "Option<bool>")]
    pub retime: Option<Spanned<bool>>,
    /// With a retimed result: stop minimizing the solve's own final time once its path,
    /// retimed, stops getting faster, and only restore feasibility from there
    /// (`armature_arm::RetimeStall`): over the benchmark suite about a quarter fewer
    /// iterations for a retimed time within 0.04 % at the median, 1.3 % at the 90th
    /// percentile, of the full minimization's (BENCHMARKS.md). Default: `retime`.
    #[serde(default)]
    #[schemars(with = "Option<bool>")]
    pub retime_stall: Option<Spanned<bool>>,
}

/// Nodes: a count, or nodes per segment between waypoints (default: the dynamics model's,
/// `DynamicsModel::default_per_segment`: 3 decoupled, 2 rigid-body).
#[derive(Debug, Clone, Default, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NodesSpec {
    /// Nodes per segment between consecutive waypoints.
    #[serde(default)]
    #[schemars(with = "Option<usize>")]
    pub per_segment: Option<Spanned<usize>>,
    /// Total node count (waypoints then need explicit `node`s).
    #[serde(default)]
    #[schemars(with = "Option<usize>")]
    pub count: Option<Spanned<usize>>,
    /// Mesh refinement: after converging on these nodes, solve again from that solution on
    /// a grid this many times finer (`ArmTask::refined`: every segment split, velocities and
    /// angles bounded at every integration grid point; default the dynamics model's,
    /// `DynamicsModel::default_refine`: 2 decoupled, 1 rigid-body; 1 is one stage).
    #[serde(default)]
    #[schemars(with = "Option<usize>")]
    pub refine: Option<Spanned<usize>>,
}

/// A waypoint.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WaypointSpec {
    /// Unique name.
    #[schemars(with = "String")]
    pub name: Spanned<String>,
    /// End-effector position (m).
    #[schemars(with = "[f64; 3]")]
    #[serde(deserialize_with = "spanned_array")]
    pub position: Spanned<[f64; 3]>,
    /// Orientation `[w, x, y, z]` used by the IK guess, or `"free"`.
    #[serde(default)]
    #[schemars(with = "Option<OrientationValue>")]
    pub orientation: Option<Spanned<OrientationValue>>,
    /// Radius of the ball the end effector must pass through (m). Default 0.01.
    #[serde(default)]
    #[schemars(with = "Option<f64>")]
    pub tolerance: Option<Spanned<f64>>,
    /// Node index (default: position in the list × nodes per segment).
    #[serde(default)]
    #[schemars(with = "Option<usize>")]
    pub node: Option<Spanned<usize>>,
}

/// A quaternion or `"free"`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum OrientationValue {
    /// `[w, x, y, z]`.
    Quaternion([f64; 4]),
    /// `"free"`.
    Word(String),
}

/// An orientation held (within a tolerance) from one waypoint to another, in continuous
/// time and at every node of the range.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OrientationSpec {
    /// The orientation `[w, x, y, z]`.
    #[schemars(with = "[f64; 4]")]
    #[serde(deserialize_with = "spanned_array")]
    pub quaternion_wxyz: Spanned<[f64; 4]>,
    /// Largest rotation away from it (degrees, > 0).
    #[schemars(with = "f64")]
    pub tolerance_deg: Spanned<f64>,
    /// First waypoint of the range.
    #[schemars(with = "String")]
    pub from: Spanned<String>,
    /// Last waypoint of the range.
    #[schemars(with = "String")]
    pub to: Spanned<String>,
}

/// Collision: capsule links between keypoints, obstacles, pair options, and the clearance
/// kept from every pair (the `armature-collision` scene format plus `margin` and
/// `between_nodes`).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CollisionSpec {
    /// Clearance kept (m). Default 0.002: the continuous-time integral lets a trajectory
    /// dip a fraction of a millimetre below its bound between nodes.
    #[serde(default = "default_margin")]
    pub margin: f64,
    /// Also keep the clearance at each segment's peak between the nodes (one buffered row
    /// per pair and segment, linearized through the integration grid), not only through the
    /// continuous-time integral and at the nodes. Default true: where the motion grazes an
    /// obstacle between two nodes the integral's linearization switches on and off, and the
    /// solve takes far more iterations without these rows.
    #[serde(default = "yes")]
    pub between_nodes: bool,
    /// With `between_nodes`: a segment's peak rows stay out of the subproblem while every
    /// pair there keeps more than `margin` plus this much clearance (m), which makes the
    /// subproblems smaller without changing the steps (rows that far from their bound are
    /// slack); the merit, the integral and the nodal rows keep watching the segment. Default
    /// 0.02.
    #[serde(default = "default_activation")]
    pub activation: f64,
    /// Check non-adjacent link pairs. Default true.
    #[serde(default = "yes")]
    pub self_collision: bool,
    /// Pairs to skip.
    #[serde(default)]
    pub allowed: Vec<(String, String)>,
    /// Link pairs to add.
    #[serde(default)]
    pub extra: Vec<(String, String)>,
    /// Capsule links.
    #[serde(default)]
    #[schemars(with = "Vec<LinkSchema>")]
    pub links: Vec<armature_collision::LinkSpec>,
    /// Obstacles.
    #[serde(default)]
    #[schemars(with = "Vec<ObstacleSchema>")]
    pub obstacles: Vec<armature_collision::ObstacleSpec>,
}

/// Schema of a capsule link (mirrors `armature_collision::LinkSpec`).
#[derive(Debug, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct LinkSchema {
    /// Start keypoint.
    start: String,
    /// End keypoint.
    end: String,
    /// Radius (m, ≥ 0).
    radius: f64,
}

/// Schema of an obstacle: a name and exactly one shape (mirrors
/// `armature_collision::ObstacleSpec`).
#[derive(Debug, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct ObstacleSchema {
    /// Name.
    name: String,
    /// A ball: `{ center = [x, y, z], radius = r }`.
    sphere: Option<SphereSchema>,
    /// A box: `{ center, quaternion_wxyz (default identity), half_extents }`.
    #[serde(rename = "box")]
    cuboid: Option<BoxSchema>,
    /// A capsule: `{ a, b, radius }`.
    capsule: Option<CapsuleSchema>,
    /// A half-space `normal·x ≥ offset`: `{ normal, offset }`.
    halfspace: Option<HalfSpaceSchema>,
}

#[derive(Debug, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct SphereSchema {
    center: [f64; 3],
    radius: f64,
}

#[derive(Debug, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct BoxSchema {
    center: [f64; 3],
    quaternion_wxyz: Option<[f64; 4]>,
    half_extents: [f64; 3],
}

#[derive(Debug, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct CapsuleSchema {
    a: [f64; 3],
    b: [f64; 3],
    radius: f64,
}

#[derive(Debug, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
struct HalfSpaceSchema {
    normal: [f64; 3],
    offset: f64,
}

fn default_margin() -> f64 {
    0.002
}

fn default_activation() -> f64 {
    0.02
}

fn yes() -> bool {
    true
}

/// How the initial guess is made.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InitSpec {
    /// `"branches"` (the path of least travel under the velocity limits over IK branches;
    /// default), `"sequential"` (each node seeded from the previous) or `"parallel"`.
    #[serde(default = "branches")]
    #[schemars(with = "String")]
    pub ik: Spanned<String>,
    /// IK random restarts per node whose warm start fails (`"branches"`: random
    /// configurations solved from at each waypoint); at most 1,000. Default 8.
    #[serde(default = "eight")]
    #[schemars(with = "usize")]
    pub restarts: Spanned<usize>,
    /// Starts of the solve, 1 to 16: start `i` searches the IK path through the waypoints
    /// with `restarts·8^i` random configurations per waypoint (at most 1,000: 8, 64, 512, …
    /// from the default), which finds other paths through the arm's redundant postures and
    /// with them other local optima; the starts are solved in parallel, the best converged
    /// solution kept (each start is reported in a line; the iteration table is the first
    /// start's). Default 2.
    #[serde(default = "two")]
    #[schemars(with = "usize")]
    pub starts: Spanned<usize>,
    /// The seed of the random configurations the branch search solves from at the waypoints.
    /// Default 0.
    #[serde(default)]
    pub seed: u64,
    /// Fallback starts, 0 to 16: when the solve does not converge, it is tried again from up
    /// to this many other guesses, one after another (the random configurations drawn from
    /// seeds `seed + 1`, …, the timing scaled by 0.7, 1.4, …), the first that converges kept
    /// (each tried is reported in a line). Default 2.
    #[serde(default = "two")]
    #[schemars(with = "usize")]
    pub fallbacks: Spanned<usize>,
}

impl Default for InitSpec {
    fn default() -> Self {
        InitSpec { ik: branches(), restarts: eight(), starts: two(), seed: 0, fallbacks: two() }
    }
}

fn two() -> Spanned<usize> {
    Spanned::new(0..0, 2)
}

fn branches() -> Spanned<String> {
    Spanned::new(0..0, "branches".into())
}

fn eight() -> Spanned<usize> {
    Spanned::new(0..0, 8)
}

/// A located array of exactly `N` values (a longer or shorter list is an error at the value,
/// not silently cut; see [`armature_kinematics::exact`]).
///
/// # Errors
/// The entries' own, or an invalid length naming `N`.
pub fn spanned_array<'de, D, T, const N: usize>(d: D) -> Result<Spanned<[T; N]>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    let s = Spanned::<Vec<T>>::deserialize(d)?;
    let span = s.span();
    Ok(Spanned::new(span, armature_kinematics::exact::exact(s.into_inner())?))
}

/// `Option<Spanned<[T; N]>>` of exactly `N` values (use with `#[serde(default)]`).
///
/// # Errors
/// As [`spanned_array`].
pub fn optional_spanned_array<'de, D, T, const N: usize>(
    d: D,
) -> Result<Option<Spanned<[T; N]>>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    let Some(s) = Option::<Spanned<Vec<T>>>::deserialize(d)? else { return Ok(None) };
    let span = s.span();
    Ok(Some(Spanned::new(span, armature_kinematics::exact::exact(s.into_inner())?)))
}

/// An error located in a file.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}:{column}: {message}")]
pub struct LocatedError {
    /// The file (as given).
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (characters).
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

/// 1-based line and column of byte `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// A source text and its name, to locate errors.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    /// The file name as the user gave it (or `<built-in name>`).
    pub name: &'a str,
    /// Its text.
    pub text: &'a str,
}

impl Source<'_> {
    /// An error at byte `offset`.
    pub fn error_at(&self, offset: usize, message: impl Into<String>) -> LocatedError {
        let (line, column) = line_col(self.text, offset);
        LocatedError { file: self.name.to_string(), line, column, message: message.into() }
    }

    /// An error at a spanned value.
    pub fn error<T>(&self, at: &Spanned<T>, message: impl Into<String>) -> LocatedError {
        self.error_at(at.span().start, message)
    }
}

/// Parses a task file.
///
/// # Errors
/// TOML syntax, unknown keys and wrong types, as `file:line:col: reason`.
pub fn parse(src: Source<'_>) -> Result<TaskFile, LocatedError> {
    toml::from_str(src.text).map_err(|e| {
        let at = e.span().map_or(0, |s| s.start);
        src.error_at(at, e.message().trim_end().to_string())
    })
}

/// Resolves a robot path relative to the task file's folder (built-in names pass through).
pub fn resolve_robot(name: &str, task_path: Option<&Path>) -> String {
    let p = Path::new(name);
    let is_file = matches!(
        p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(),
        Some("toml" | "urdf")
    );
    match (is_file, task_path.and_then(Path::parent)) {
        (true, Some(dir)) if p.is_relative() => dir.join(p).to_string_lossy().into_owned(),
        _ => name.to_string(),
    }
}
