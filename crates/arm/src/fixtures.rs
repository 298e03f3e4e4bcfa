//! Example tasks shared by the CLI's demos, tests, benches and examples: the seed tutorial's
//! pick-and-place, its collision variant, and a UR5e pick-and-place with rigid-body dynamics.
//! Each equals the task file of the same name in the repository's `examples/` as the CLI
//! builds it (a test of the CLI checks it): their results are retimed by default, so their
//! solves stop minimizing once the path retimed stalls ([`ArmTask::retime_stall`]).

use std::f64::consts::FRAC_1_SQRT_2;

use armature_collision::{LinkSpec, ObstacleSpec, Scene, SphereSpec};
use armature_kinematics::robots;

use crate::{
    ArmTask, Clearance, DynamicsModel, Initialization, OrientationRange, RetimeStall, TimeWindow,
    Waypoint,
};

/// Gripper down for arm7: Ry(90°).
pub const ARM7_DOWN: [f64; 4] = [FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2, 0.0];

/// Tool down for the UR5e in its base frame.
pub const UR5E_DOWN: [f64; 4] = [0.0, FRAC_1_SQRT_2, FRAC_1_SQRT_2, 0.0];

/// A waypoint's name, position and guess orientation.
type Spot<'a> = (&'a str, [f64; 3], Option<[f64; 4]>);

fn waypoints(list: &[Spot<'_>], per_segment: usize) -> Vec<Waypoint> {
    list.iter()
        .enumerate()
        .map(|(i, &(name, position, orientation))| Waypoint {
            name: name.into(),
            node: i * per_segment,
            position,
            tolerance: 0.01,
            orientation,
        })
        .collect()
}

fn range(from: (&str, usize), to: (&str, usize), q: [f64; 4], deg: f64) -> OrientationRange {
    OrientationRange {
        name: format!("{}..{}", from.0, to.0),
        quaternion_wxyz: q,
        tolerance_deg: deg,
        first: from.1,
        last: to.1,
    }
}

/// The seed tutorial's 7-DOF pick-and-place (`examples/pick-and-place.toml`): home →
/// pre_grasp → grasp → lift → pre_place → place within 1 cm, gripper down within 5° from
/// pre_grasp to place and 0.1° around the grasp and the place, above the table, `q̈ = τ / I`,
/// free final time ≤ 4 s, the model's default 3 node intervals between waypoints
/// ([`DynamicsModel::default_per_segment`]; the tutorial has 2) and time-scaled torques.
pub fn pick_and_place() -> ArmTask {
    let dynamics = DynamicsModel::DecoupledInertia(vec![0.08, 0.06, 0.05, 0.04, 0.02, 0.01, 0.005]);
    let p = dynamics.default_per_segment();
    let d = Some(ARM7_DOWN);
    let waypoints = waypoints(
        &[
            ("home", [0.69, 0.0, 0.34], Some([1.0, 0.0, 0.0, 0.0])),
            ("pre_grasp", [0.35, -0.25, 0.2], d),
            ("grasp", [0.35, -0.25, 0.05], d),
            ("lift", [0.35, -0.25, 0.2], d),
            ("pre_place", [0.35, 0.25, 0.2], d),
            ("place", [0.35, 0.25, 0.05], d),
        ],
        p,
    );
    let orientation = vec![
        range(("pre_grasp", p), ("place", 5 * p), ARM7_DOWN, 5.0),
        range(("pre_grasp", p), ("lift", 3 * p), ARM7_DOWN, 0.1),
        range(("pre_place", 4 * p), ("place", 5 * p), ARM7_DOWN, 0.1),
    ];
    ArmTask {
        chain: robots::arm7(),
        settings: dynamics.default_settings(),
        dynamics,
        velocity_limit: vec![3.0; 7],
        torque_limit: vec![8.0, 8.0, 4.0, 4.0, 2.0, 1.0, 0.5],
        velocity_limit_peaks: true,
        time_scaled_torque: true,
        angle_limit_peaks: false,
        start: None,
        time: TimeWindow { min: 0.0, max: 4.0, minimize: true },
        nodes: 5 * p + 1,
        waypoints,
        orientation,
        table_height: Some(0.0),
        collision: None,
        initialization: Initialization::default(),
        retime_stall: Some(RetimeStall::default()),
    }
}

/// [`pick_and_place`] with capsule links base–shoulder 0.06, shoulder–elbow 0.05,
/// elbow–wrist 0.04, wrist–ee 0.035, non-adjacent self-collision and a ball of radius 0.06 at
/// (0.35, 0, 0.25), 2 mm of clearance kept (`examples/pick-and-place-collision.toml`).
pub fn pick_and_place_collision() -> ArmTask {
    let mut task = pick_and_place();
    with_seed_ball(&mut task, [0.35, 0.0, 0.25], 0.06);
    task
}

/// Gives an arm7 task the seed's collision model with a ball at `centre` of `radius`: the
/// capsules of [`pick_and_place_collision`], non-adjacent self-collision, 2 mm of clearance
/// kept (also between the nodes, active within 2 cm), and 200 iterations at most.
///
/// # Panics
/// If the task's robot lacks arm7's keypoints (base, shoulder, elbow, wrist, ee).
pub fn with_seed_ball(task: &mut ArmTask, centre: [f64; 3], radius: f64) {
    let link =
        |start: &str, end: &str, radius| LinkSpec { start: start.into(), end: end.into(), radius };
    let scene = Scene {
        self_collision: true,
        allowed: Vec::new(),
        extra: Vec::new(),
        links: vec![
            link("base", "shoulder", 0.06),
            link("shoulder", "elbow", 0.05),
            link("elbow", "wrist", 0.04),
            link("wrist", "ee", 0.035),
        ],
        obstacles: vec![ObstacleSpec {
            name: "ball".into(),
            sphere: Some(SphereSpec { center: centre, radius }),
            cuboid: None,
            capsule: None,
            halfspace: None,
        }],
    };
    let model = scene.model(&task.chain).expect("the seed's capsules fit arm7");
    task.collision = Some(Clearance { model, margin: 0.002, between_nodes_activation: Some(0.02) });
    task.settings.max_iterations = 200;
}

/// A pick-and-place of a 3 kg part (5 cm out from the flange) on the UR5e with its
/// rigid-body dynamics under gravity (`examples/ur5e-rigid-body.toml`): from UR's upright home
/// pose (tool down) to a pick, a lift and a place, tool down within 5° from the pick to the
/// place, the robot's own limits, free final time ≤ 6 s.
pub fn ur5e_rigid_body() -> ArmTask {
    use std::f64::consts::FRAC_PI_2;
    let part = armature_kinematics::Inertial::point(3.0, [0.0, 0.0, 0.05]);
    let chain = robots::ur5e().with_payload(&part).expect("a point mass is a payload");
    let limit = |f: &dyn Fn(&armature_kinematics::Limits) -> Option<f64>| -> Vec<f64> {
        chain.joints().iter().map(|j| f(&j.limits).expect("the built-in ur5e has limits")).collect()
    };
    let (velocity_limit, torque_limit) = (limit(&|l| l.velocity), limit(&|l| l.effort));
    let d = Some(UR5E_DOWN);
    let dynamics = DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] };
    let p = dynamics.default_per_segment();
    let waypoints = waypoints(
        &[
            ("home", [-0.4919, -0.1333, 0.4879], d),
            ("pick", [-0.45, -0.3, 0.1], d),
            ("lift", [-0.45, -0.3, 0.25], d),
            ("place", [-0.45, 0.3, 0.1], d),
        ],
        p,
    );
    ArmTask {
        chain,
        settings: dynamics.default_settings(),
        retime_stall: Some(RetimeStall::default()),
        dynamics,
        velocity_limit,
        torque_limit,
        velocity_limit_peaks: false,
        time_scaled_torque: false,
        angle_limit_peaks: false,
        start: Some(vec![0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0]),
        time: TimeWindow { min: 0.0, max: 6.0, minimize: true },
        nodes: 3 * p + 1,
        waypoints,
        orientation: vec![range(("pick", p), ("place", 3 * p), UR5E_DOWN, 5.0)],
        table_height: Some(0.0),
        collision: None,
        initialization: Initialization::default(),
    }
}
