//! The arm trajectory task as plain data.

use armature_collision::CollisionModel;
use armature_ik::Mode;
use armature_kinematics::Chain;
use armature_scvx::PtrSettings;
use serde::Serialize;

/// Which dynamics the arm obeys.
#[derive(Debug, Clone, PartialEq)]
pub enum DynamicsModel {
    /// `q̈ = τ / I` per joint, with these inertias (the seed tutorial's model; no gravity, no
    /// coupling).
    DecoupledInertia(Vec<f64>),
    /// `M(q)q̈ + C(q, q̇)q̇ + g(q) = τ` from the chain's mass properties (every joint needs its
    /// [`Inertial`](armature_kinematics::Inertial)), under `gravity` (m/s², base frame).
    RigidBody {
        /// Gravity (m/s²).
        gravity: [f64; 3],
    },
}

/// RK4 steps per segment for [`DynamicsModel::RigidBody`] by default. The decoupled model is
/// linear, so RK4 integrates it exactly at any step count; the coupled arm is not: on the
/// suite's UR5e tasks at the generic 10 steps the trajectory re-integrated at 1 ms ends with
/// joints still moving at 1–6e-3 rad/s where the task asks for rest, at 30 within 1e-4
/// (BENCHMARKS.md).
pub const RIGID_BODY_SUBSTEPS: usize = 30;

/// RK4 steps per waypoint segment for [`DynamicsModel::DecoupledInertia`] by default, shared
/// by its nodes ([`DynamicsModel::default_substeps`]): the integration grid on which the
/// velocity rows and the clearances are held between the nodes.
pub const DECOUPLED_STEPS_PER_WAYPOINT_SEGMENT: usize = 20;

impl DynamicsModel {
    /// The solver settings a task with this model starts from: the defaults, with
    /// [`default_substeps`](Self::default_substeps) at the model's nodes per waypoint segment
    /// and [`default_trust_region_weight`](Self::default_trust_region_weight).
    ///
    /// # Example
    /// ```
    /// use armature_arm::{DynamicsModel, RIGID_BODY_SUBSTEPS};
    ///
    /// let rigid = DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] }.default_settings();
    /// assert_eq!(rigid.discretization.substeps, RIGID_BODY_SUBSTEPS);
    /// let decoupled = DynamicsModel::DecoupledInertia(vec![1.0]).default_settings();
    /// assert_eq!(decoupled.discretization.substeps, 7);
    /// ```
    pub fn default_settings(&self) -> PtrSettings {
        let mut settings = PtrSettings::default();
        settings.discretization.substeps = self.default_substeps(self.default_per_segment());
        settings.lam_tr = self.default_trust_region_weight();
        settings
    }

    /// The initial trust-region weight ([`PtrSettings::lam_tr`]) by default: 0.25 for the
    /// decoupled model, 1 (the solver's own default) for the rigid-body one. The decoupled
    /// model's subproblems, linear in its time-scaled torques, predict its first steps well
    /// (ratios of 0.6–1), and a solve that starts with a trust region four times wider
    /// spends fewer iterations widening it: over the benchmark suite's decoupled tasks 18
    /// instead of 19 iterations at the median, 27 instead of 30 at the 90th percentile, and
    /// T / T_ref 1.021 instead of 1.022. The rigid-body model's do not (0.5 and 0.25 each
    /// leave one or two of its tasks over a velocity limit between the nodes; BENCHMARKS.md,
    /// 2026-12-07, "the initial trust region").
    ///
    /// # Example
    /// ```
    /// use armature_arm::DynamicsModel;
    ///
    /// assert_eq!(DynamicsModel::DecoupledInertia(vec![1.0]).default_trust_region_weight(), 0.25);
    /// let rigid = DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] };
    /// assert_eq!(rigid.default_trust_region_weight(), rigid.default_settings().lam_tr);
    /// assert_eq!(rigid.default_trust_region_weight(), armature_scvx::PtrSettings::default().lam_tr);
    /// ```
    pub fn default_trust_region_weight(&self) -> f64 {
        match self {
            DynamicsModel::DecoupledInertia(_) => 0.25,
            DynamicsModel::RigidBody { .. } => PtrSettings::default().lam_tr,
        }
    }

    /// The node intervals between two consecutive waypoints by default: 3 for the decoupled
    /// model, 2 for the rigid-body one. With time-scaled torques the decoupled tasks of the
    /// benchmark suite end at a median 1.022 × T_ref with 3 (1.087 with 2) in about as many
    /// iterations; the rigid-body tasks gain nothing from a third piece without velocity rows
    /// at every grid point, and take twice as long (BENCHMARKS.md, 2026-12-07,
    /// "time-scaled torques").
    ///
    /// # Example
    /// ```
    /// use armature_arm::DynamicsModel;
    ///
    /// assert_eq!(DynamicsModel::DecoupledInertia(vec![1.0]).default_per_segment(), 3);
    /// assert_eq!(DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] }.default_per_segment(), 2);
    /// ```
    pub fn default_per_segment(&self) -> usize {
        match self {
            DynamicsModel::DecoupledInertia(_) => 3,
            DynamicsModel::RigidBody { .. } => 2,
        }
    }

    /// The factor of the mesh refinement by default ([`ArmTask::refined`]): 2 for the
    /// decoupled model, 1 (one stage) for the rigid-body one. A solve on the model's nodes
    /// finds the basin; solved again from it on a grid twice as fine
    /// ([`crate::set_refined_guess`], starting from its prices), the decoupled tasks of the
    /// benchmark suite end at a median 1.005 × T_ref instead of 1.022 (the seed 1.049 s
    /// instead of 1.075) for about 1.7 times the solve time; the rigid-body model's refined
    /// stage costs seven times its first solve for a 7 % gain (BENCHMARKS.md, 2026-12-07,
    /// "refinement by default").
    ///
    /// # Example
    /// ```
    /// use armature_arm::DynamicsModel;
    ///
    /// assert_eq!(DynamicsModel::DecoupledInertia(vec![1.0]).default_refine(), 2);
    /// assert_eq!(DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] }.default_refine(), 1);
    /// ```
    pub fn default_refine(&self) -> usize {
        match self {
            DynamicsModel::DecoupledInertia(_) => 2,
            DynamicsModel::RigidBody { .. } => 1,
        }
    }

    /// RK4 steps per node interval by default for `per_segment` intervals between two
    /// waypoints: [`DECOUPLED_STEPS_PER_WAYPOINT_SEGMENT`] shared by them for the decoupled
    /// model (10 with 2 intervals, 7 with 3), [`RIGID_BODY_SUBSTEPS`] per interval for the
    /// rigid-body model, whose accuracy needs the short step.
    ///
    /// # Example
    /// ```
    /// use armature_arm::{DynamicsModel, RIGID_BODY_SUBSTEPS};
    ///
    /// let decoupled = DynamicsModel::DecoupledInertia(vec![1.0]);
    /// assert_eq!((decoupled.default_substeps(2), decoupled.default_substeps(3)), (10, 7));
    /// let rigid = DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] };
    /// assert_eq!(rigid.default_substeps(3), RIGID_BODY_SUBSTEPS);
    /// ```
    pub fn default_substeps(&self, per_segment: usize) -> usize {
        match self {
            DynamicsModel::DecoupledInertia(_) => {
                DECOUPLED_STEPS_PER_WAYPOINT_SEGMENT.div_ceil(per_segment.max(1)).max(1)
            }
            DynamicsModel::RigidBody { .. } => RIGID_BODY_SUBSTEPS,
        }
    }

    /// RK4 steps per node interval once `from` intervals of `steps` each become `to`
    /// (`from, to ≥ 1`): the grid's step length kept for the decoupled model (`⌈steps·from /
    /// to⌉`; it is linear, and RK4 integrates it exactly at any step), never fewer than
    /// `steps` for the rigid-body model, whose accuracy needs the short step.
    pub(crate) fn steps_when_split(&self, steps: usize, from: usize, to: usize) -> usize {
        let kept_length = (steps * from).div_ceil(to).max(1);
        match self {
            DynamicsModel::RigidBody { .. } => kept_length.max(steps),
            DynamicsModel::DecoupledInertia(_) => kept_length,
        }
    }

    /// Whether a task with this model bounds its velocities at every integration grid
    /// point by default ([`ArmTask::velocity_limit_peaks`]): yes for the decoupled model,
    /// whose velocity rows each read one joint; no for the rigid-body model, whose rows each
    /// read every joint of the segment (a subproblem 20 times slower on the UR5e) and whose
    /// faster optimum then outruns the integration's accuracy (BENCHMARKS.md, 2026-12-05).
    ///
    /// # Example
    /// ```
    /// use armature_arm::DynamicsModel;
    ///
    /// assert!(DynamicsModel::DecoupledInertia(vec![1.0]).default_velocity_limit_peaks());
    /// assert!(!DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] }.default_velocity_limit_peaks());
    /// ```
    pub fn default_velocity_limit_peaks(&self) -> bool {
        matches!(self, DynamicsModel::DecoupledInertia(_))
    }

    /// Whether a task with this model time-scales its torques by default
    /// ([`ArmTask::time_scaled_torque`]): yes for the decoupled model, whose accelerations
    /// are then linear in the solver's variables; no for the rigid-body model, whose solves
    /// then ride the velocity limits between the nodes more closely than the integration
    /// holds them (BENCHMARKS.md, 2026-12-07, "time-scaled torques").
    ///
    /// # Example
    /// ```
    /// use armature_arm::DynamicsModel;
    ///
    /// assert!(DynamicsModel::DecoupledInertia(vec![1.0]).default_time_scaled_torque());
    /// assert!(!DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] }.default_time_scaled_torque());
    /// ```
    pub fn default_time_scaled_torque(&self) -> bool {
        matches!(self, DynamicsModel::DecoupledInertia(_))
    }
}

/// A waypoint: the end effector passes within `tolerance` of `position` at node `node`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Waypoint {
    /// Its name.
    pub name: String,
    /// Its node.
    pub node: usize,
    /// Position (m).
    pub position: [f64; 3],
    /// Radius of its ball (m).
    pub tolerance: f64,
    /// The orientation `[w, x, y, z]` the initial guess's IK aims for (none: free).
    #[serde(skip)]
    pub orientation: Option<[f64; 4]>,
}

/// An orientation range: the end-effector rotation stays within `tolerance_deg` of
/// `quaternion_wxyz` from node `first` to node `last`, in continuous time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OrientationRange {
    /// A name for reports (`from..to`).
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

/// Capsule links and obstacles, kept apart by `margin`.
#[derive(Debug, Clone, PartialEq)]
pub struct Clearance {
    /// The collision model (its keypoint names must be the chain's).
    pub model: CollisionModel,
    /// The clearance every pair keeps (m).
    pub margin: f64,
    /// Also bound each segment's peak between the nodes, in the subproblem while some pair
    /// comes within this distance of its margin (m); `None`: only the integral and the
    /// nodes.
    pub between_nodes_activation: Option<f64>,
}

/// The final time: free in `[min, max]`, minimized or not.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeWindow {
    /// Lower bound (s).
    pub min: f64,
    /// Upper bound (s).
    pub max: f64,
    /// Minimize the final time.
    pub minimize: bool,
}

/// How the initial guess is made: IK through the waypoints (interpolated in task space).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Initialization {
    /// Branch search (default), sequential (each node from the previous) or parallel IK.
    pub mode: Mode,
    /// Random restarts of a node whose IK fails; for [`Mode::Branches`], the random
    /// configurations solved from at each waypoint.
    pub restarts: usize,
    /// Starts of the solve ([`ArmTask::solve`](crate::ArmTask::solve)): start `i` searches
    /// the IK path with [`start_ik_samples`](crate::start_ik_samples)`(restarts, i)` random
    /// configurations per waypoint ([`ArmTask::start`](crate::ArmTask::start)), the starts
    /// solved in parallel, the best kept. Default 2: over the benchmark suite the second
    /// start's path is faster on a tenth of the tasks (by up to 10 %), for about 13 % more
    /// solve time on two cores (BENCHMARKS.md, 2026-12-08).
    pub starts: usize,
    /// The seed of the branch search's random configurations ([`Mode::Branches`]): another
    /// seed draws other samples at the waypoints, and so possibly another IK path. Default 0.
    pub seed: u64,
    /// Fallback starts: when the solve does not converge, up to this many more are solved one
    /// after another, each from another IK path and timing ([`fallback_task`](crate::fallback_task)),
    /// until one converges ([`solve_fallbacks`](crate::solve_fallbacks)). Default 2.
    pub fallbacks: usize,
}

impl Default for Initialization {
    fn default() -> Self {
        Initialization { mode: Mode::Branches, restarts: 8, starts: 2, seed: 0, fallbacks: 2 }
    }
}

/// A robot-arm trajectory task: the robot and its dynamics, where to go and how, limits,
/// obstacles, time, nodes and solver settings. [`ArmTask::plan`] checks it and builds the
/// SCvx problem and its initial guess.
///
/// The states are the joint angles (`angle`) and velocities (`velocity`), the control the
/// joint torques (`torque`, first-order hold). The arm starts at rest at the first waypoint
/// (or at `start`) and ends at rest at the last. The end-effector is the chain's home frame.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmTask {
    /// The robot.
    pub chain: Chain,
    /// Its dynamics.
    pub dynamics: DynamicsModel,
    /// Joint velocity limits (one per joint, > 0).
    pub velocity_limit: Vec<f64>,
    /// Joint torque limits (one per joint, > 0).
    pub torque_limit: Vec<f64>,
    /// Also bound the velocities at every integration grid point between the nodes (rows
    /// with their exact sensitivities), besides their continuous-time integral, whose
    /// linearization has no gradient where the motion rides a limit. Default: the model's
    /// ([`DynamicsModel::default_velocity_limit_peaks`]).
    pub velocity_limit_peaks: bool,
    /// Also bound the joint angles at every integration grid point (rows with their exact
    /// sensitivities), besides the limits' continuous-time integral. Default false: the
    /// integral holds them on the tasks' own grids; [`refined`](Self::refined) turns the rows
    /// on, as shorter segments loosen the integral.
    pub angle_limit_peaks: bool,
    /// Solve for the time-scaled torques `w = s·τ` (the torque times its segment's
    /// dilation, [`Control::time_scaled`](armature_scvx::Control#structfield.time_scaled)):
    /// with `q̈ = τ / I` the velocities' dynamics are then linear in the solver's variables,
    /// so a step that shortens a segment and changes its torques is predicted exactly
    /// there, and the walk takes longer steps. The torque is then linear on each segment and
    /// jumps at a node where the segments' durations differ (the solution's `control_ends`).
    /// Default: the model's ([`DynamicsModel::default_time_scaled_torque`]).
    pub time_scaled_torque: bool,
    /// The joint angles at the start (default: IK of the first waypoint).
    pub start: Option<Vec<f64>>,
    /// The final time.
    pub time: TimeWindow,
    /// Node count N.
    pub nodes: usize,
    /// Waypoints, the first at node 0 and the last at node N − 1.
    pub waypoints: Vec<Waypoint>,
    /// Orientation ranges.
    pub orientation: Vec<OrientationRange>,
    /// The end effector stays above this height (m).
    pub table_height: Option<f64>,
    /// Collision avoidance.
    pub collision: Option<Clearance>,
    /// The initial guess.
    pub initialization: Initialization,
    /// Solver settings.
    pub settings: PtrSettings,
    /// For a result that will be retimed ([`retime`](Self::retime)): stop minimizing the
    /// solve's own final time once its path retimed stalls
    /// ([`RetimeStall`](crate::RetimeStall)). Default `None`: the solve minimizes its own
    /// time to the end (the CLI sets the default rule with a retimed result).
    pub retime_stall: Option<crate::RetimeStall>,
}

impl ArmTask {
    /// The same task on a grid `factor` times finer: every segment between two nodes split
    /// into `factor` (nodes `(N − 1)·factor + 1`), the waypoints and orientation ranges on
    /// the same instants (node `k` becomes node `k·factor`).
    ///
    /// # Example
    /// ```
    /// let seed = armature_arm::fixtures::pick_and_place();
    /// let fine = seed.subdivided(2);
    /// assert_eq!(fine.nodes, 2 * (seed.nodes - 1) + 1);
    /// assert_eq!(fine.waypoints[1].node, 2 * seed.waypoints[1].node);
    /// ```
    pub fn subdivided(&self, factor: usize) -> ArmTask {
        let factor = factor.max(1);
        let mut t = self.clone();
        t.nodes = (self.nodes.max(1) - 1) * factor + 1;
        for w in &mut t.waypoints {
            w.node *= factor;
        }
        for o in &mut t.orientation {
            (o.first, o.last) = (o.first * factor, o.last * factor);
        }
        t
    }

    /// The second stage of a mesh refinement: the task [`subdivided`](Self::subdivided) by
    /// `factor`, with its velocities and angles bounded at every integration grid point
    /// ([`velocity_limit_peaks`](Self::velocity_limit_peaks),
    /// [`angle_limit_peaks`](Self::angle_limit_peaks)) whatever the model's default.
    /// Solved from the first stage's solution ([`set_refined_guess`](crate::set_refined_guess)),
    /// its faster motion rides the velocity limits along whole segments, where the limits'
    /// continuous-time integral alone lets the rigid-body model's velocities exceed them by
    /// 1e-4 to 8e-4 rad/s between the nodes (11 of the suite's 20 UR5e rigid-body tasks,
    /// BENCHMARKS.md); with refine 3 the integral let one arm7 task's joint pass its angle
    /// limit by 2.65e-4 rad.
    ///
    /// The integration grid keeps its step length for the decoupled model (RK4 steps per
    /// interval `⌈substeps / factor⌉`, as [`resegmented`](Self::resegmented) keeps them: that
    /// model is linear, RK4 integrates it exactly at any step, and the grid-point rows then
    /// sit as densely as on the coarse grid); a rigid-body task keeps its steps per interval,
    /// which its accuracy needs.
    ///
    /// # Example
    /// ```
    /// let ur5e = armature_arm::fixtures::ur5e_rigid_body();
    /// assert!(!ur5e.velocity_limit_peaks);
    /// let fine = ur5e.refined(2);
    /// assert!(fine.velocity_limit_peaks && fine.angle_limit_peaks);
    /// assert!(!ur5e.angle_limit_peaks);
    /// assert_eq!(fine.nodes, ur5e.subdivided(2).nodes);
    /// let steps = |t: &armature_arm::ArmTask| t.settings.discretization.substeps;
    /// assert_eq!(steps(&fine), steps(&ur5e));
    ///
    /// let seed = armature_arm::fixtures::pick_and_place();
    /// assert_eq!(steps(&seed), 7);
    /// assert_eq!(steps(&seed.refined(2)), 4); // ⌈7 / 2⌉
    /// ```
    pub fn refined(&self, factor: usize) -> ArmTask {
        let mut t = ArmTask {
            velocity_limit_peaks: true,
            angle_limit_peaks: true,
            ..self.subdivided(factor)
        };
        let steps = &mut t.settings.discretization.substeps;
        *steps = self.dynamics.steps_when_split(*steps, 1, factor.max(1));
        t
    }
}
