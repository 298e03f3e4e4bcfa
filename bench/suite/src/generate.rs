//! The suite's tasks, generated from a fixed seed: pick-and-place tasks of the seed's kind on
//! arm7 (half with a ball between pick and place), on the UR5e loaded from URDF, on the
//! built-in UR5e with rigid-body dynamics and on a KUKA LBR iiwa 7 from its DH table; the
//! seed and its collision variant; and a few infeasible tasks that must come back as such. Every feasible task is checked before it
//! enters: each waypoint reachable within the joint limits under its orientation (the true
//! rotation angle, by the verification's own FK), the start and waypoint configurations clear
//! of the ball.

use armature_arm::{ArmTask, DynamicsModel, OrientationRange, Waypoint, fixtures};
use armature_ik::{IkSettings, IkWorkspace, Target, solve};
use armature_lie::SO3;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use crate::verify::{Robot, angle_between, point_segment};

/// The generator's seed.
pub const SEED: u64 = 20_261_203;

/// Ball obstacles: centre and radius.
pub type Balls = Vec<(Vector3<f64>, f64)>;

/// One task of the suite.
#[derive(Debug, Clone)]
pub struct SuiteTask {
    /// Group (`seed`, `arm7`, `arm7-ball`, `ur5e-urdf`, `ur5e-rigid-body`, `iiwa7`,
    /// `infeasible`).
    pub group: &'static str,
    /// Name within the suite.
    pub name: String,
    /// The task.
    pub task: ArmTask,
    /// Which FK the verification uses.
    pub robot: Robot,
    /// Ball obstacles (centre, radius), for the verification.
    pub balls: Balls,
    /// Built to be infeasible, and why.
    pub infeasible: Option<&'static str>,
    /// Mesh refinement: solved on `task`'s grid, then on the grid `refine` times finer
    /// (`ArmTask::refined`) from that solution (1: once, on `task`'s grid). By default its
    /// dynamics model's (`DynamicsModel::default_refine`), as the CLI's.
    pub refine: usize,
    /// Retime the converged solution along its path (`ArmTask::retime`) and report, and
    /// verify, the retimed trajectory.
    pub retime: bool,
}

fn lerp(rng: &mut Pcg64Mcg, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.random::<f64>()
}

fn wp(name: &str, node: usize, p: Vector3<f64>, q: Option<[f64; 4]>) -> Waypoint {
    Waypoint { name: name.into(), node, position: p.into(), tolerance: 0.01, orientation: q }
}

/// IK of each waypoint (pose where an orientation is given), from the previous solution: the
/// configurations, or `None` if one is out of reach within the limits, or its orientation
/// is off by more than `max_angle` (true rotation angle by the verification's FK).
fn reachable(task: &ArmTask, robot: Robot, max_angle: f64) -> Option<Vec<Vec<f64>>> {
    let chain = &task.chain;
    let mut ws = IkWorkspace::new(chain);
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    let mut seed = task.start.clone().unwrap_or_else(|| vec![0.0; chain.dof()]);
    let mut out = Vec::new();
    for w in &task.waypoints {
        let orientation = w.orientation.map(|q| SO3::from_quaternion_wxyz(q).expect("unit"));
        let target = Target { position: Vector3::from(w.position), orientation };
        let r = solve(chain, &target, &seed, &settings, &mut ws).ok()?;
        let (rot, p) = robot.ee(&r.q);
        if !r.converged || (p - Vector3::from(w.position)).norm() > 1e-3 {
            return None;
        }
        if let Some(o) = orientation
            && angle_between(&rot, &o.matrix()) > max_angle
        {
            return None;
        }
        seed = r.q.clone();
        out.push(r.q);
    }
    Some(out)
}

/// The seed's capsules and a ball, as the task's clearance (2 mm kept).
fn with_ball(task: &mut ArmTask, centre: Vector3<f64>, radius: f64) {
    fixtures::with_seed_ball(task, centre.into(), radius);
}

/// The smallest clearance of the arm7 capsules from the ball over configurations `qs`.
fn ball_clearance(qs: &[Vec<f64>], centre: &Vector3<f64>, radius: f64) -> f64 {
    qs.iter()
        .flat_map(|q| Robot::Arm7.capsules(q))
        .map(|(a, b, r)| point_segment(centre, &a, &b) - r - radius)
        .fold(f64::INFINITY, f64::min)
}

/// An arm7 pick-and-place like the seed's, at random picks, places and lifts.
fn arm7_task(rng: &mut Pcg64Mcg, ball: bool) -> Option<(ArmTask, Balls)> {
    let mut task = fixtures::pick_and_place();
    let down = Some(fixtures::ARM7_DOWN);
    let pick = Vector3::new(lerp(rng, 0.30, 0.50), lerp(rng, -0.35, -0.10), lerp(rng, 0.03, 0.08));
    let place = Vector3::new(lerp(rng, 0.30, 0.50), lerp(rng, 0.10, 0.35), lerp(rng, 0.03, 0.08));
    let lift = Vector3::new(0.0, 0.0, lerp(rng, 0.10, 0.20));
    // The fixture's nodes per segment (its orientation ranges sit on them).
    let p = task.dynamics.default_per_segment();
    task.waypoints = vec![
        wp("home", 0, Vector3::new(0.69, 0.0, 0.34), Some([1.0, 0.0, 0.0, 0.0])),
        wp("pre_grasp", p, pick + lift, down),
        wp("grasp", 2 * p, pick, down),
        wp("lift", 3 * p, pick + lift, down),
        wp("pre_place", 4 * p, place + lift, down),
        wp("place", 5 * p, place, down),
    ];
    let qs = reachable(&task, Robot::Arm7, 0.05f64.to_radians())?;
    if !ball {
        return Some((task, Vec::new()));
    }
    let mid = (pick + place) / 2.0 + lift;
    let centre = Vector3::new(mid.x + lerp(rng, -0.05, 0.05), mid.y, mid.z - lerp(rng, 0.0, 0.06));
    let radius = lerp(rng, 0.04, 0.06);
    if ball_clearance(&qs, &centre, radius) < 0.02 {
        return None;
    }
    with_ball(&mut task, centre, radius);
    Some((task, vec![(centre, radius)]))
}

/// A UR5e pick-and-place like the rigid-body demo's, at random picks, places and lifts.
fn ur5e_task(rng: &mut Pcg64Mcg, base: &ArmTask) -> Option<ArmTask> {
    let mut task = base.clone();
    let down = Some(fixtures::UR5E_DOWN);
    let pick =
        Vector3::new(lerp(rng, -0.55, -0.35), lerp(rng, -0.40, -0.15), lerp(rng, 0.05, 0.12));
    let place = Vector3::new(lerp(rng, -0.55, -0.35), lerp(rng, 0.15, 0.40), lerp(rng, 0.05, 0.12));
    let lift = Vector3::new(0.0, 0.0, lerp(rng, 0.10, 0.20));
    let home = Vector3::from(base.waypoints[0].position);
    // The base's nodes per segment.
    let p = base.waypoints[1].node;
    task.waypoints = vec![
        wp("home", 0, home, down),
        wp("pick", p, pick, down),
        wp("lift", 2 * p, pick + lift, down),
        wp("place", 3 * p, place, down),
    ];
    task.orientation = vec![OrientationRange {
        name: "pick..place".into(),
        quaternion_wxyz: fixtures::UR5E_DOWN,
        tolerance_deg: 5.0,
        first: p,
        last: 3 * p,
    }];
    reachable(&task, Robot::Ur5e, 1.0f64.to_radians()).map(|_| task)
}

/// The KUKA LBR iiwa 7 R800 from its DH table ([`crate::verify::IIWA7_DH`]) and KUKA's
/// published limits: ±[170, 120, 170, 120, 170, 120, 175]°,
/// [98, 98, 100, 130, 140, 180, 180]°/s, [176, 176, 110, 110, 110, 40, 40] N·m.
pub fn iiwa7() -> armature_kinematics::Chain {
    use armature_kinematics::{JointKind, Limits, robots::DhRow};
    const NAMES: [&str; 7] = ["a1", "a2", "a3", "a4", "a5", "a6", "a7"];
    let qmax = [170.0f64, 120.0, 170.0, 120.0, 170.0, 120.0, 175.0];
    let vmax = [98.0f64, 98.0, 100.0, 130.0, 140.0, 180.0, 180.0];
    let tmax = [176.0, 176.0, 110.0, 110.0, 110.0, 40.0, 40.0];
    let rows: Vec<DhRow> = (0..7)
        .map(|i| {
            let (d, a, alpha) = crate::verify::IIWA7_DH[i];
            DhRow {
                name: NAMES[i],
                kind: JointKind::Revolute,
                d,
                theta_offset: 0.0,
                a,
                alpha,
                limits: Limits::symmetric(qmax[i].to_radians(), vmax[i].to_radians(), tmax[i]),
            }
        })
        .collect();
    let keypoints = [("base", 0), ("shoulder", 2), ("elbow", 4), ("wrist", 6), ("ee", 7)];
    armature_kinematics::robots::from_dh("iiwa7", &rows, &keypoints)
        .expect("the iiwa table is valid")
}

/// Tool down for the iiwa (its flange points up at q = 0): Ry(180°).
const IIWA_DOWN: [f64; 4] = [0.0, 0.0, 1.0, 0.0];

/// An iiwa pick-and-place: from above the table in front of it to a pick, a lift and a
/// place, tool down within 5° from the pick to the place, decoupled dynamics.
fn iiwa_task(rng: &mut Pcg64Mcg) -> Option<ArmTask> {
    let mut task = fixtures::ur5e_rigid_body();
    task.chain = iiwa7();
    let limit = |f: &dyn Fn(&armature_kinematics::Limits) -> Option<f64>| -> Vec<f64> {
        task.chain.joints().iter().map(|j| f(&j.limits).expect("limits")).collect()
    };
    (task.velocity_limit, task.torque_limit) = (limit(&|l| l.velocity), limit(&|l| l.effort));
    task.dynamics = DynamicsModel::DecoupledInertia(vec![1.0, 1.0, 0.6, 0.6, 0.3, 0.1, 0.05]);
    task.velocity_limit_peaks = task.dynamics.default_velocity_limit_peaks();
    task.time_scaled_torque = task.dynamics.default_time_scaled_torque();
    task.start = None;
    let down = Some(IIWA_DOWN);
    let pick = Vector3::new(lerp(rng, 0.45, 0.65), lerp(rng, -0.35, -0.15), lerp(rng, 0.05, 0.12));
    let place = Vector3::new(lerp(rng, 0.45, 0.65), lerp(rng, 0.15, 0.35), lerp(rng, 0.05, 0.12));
    let lift = Vector3::new(0.0, 0.0, lerp(rng, 0.10, 0.20));
    task.waypoints = vec![
        wp("home", 0, Vector3::new(0.5, 0.0, 0.5), down),
        wp("pick", 2, pick, down),
        wp("lift", 4, pick + lift, down),
        wp("place", 6, place, down),
    ];
    task.orientation[0].quaternion_wxyz = IIWA_DOWN;
    // The model's nodes per segment and integration steps.
    let mut task = task.resegmented(task.dynamics.default_per_segment()).expect("even waypoints");
    task.settings = task.dynamics.default_settings();
    reachable(&task, Robot::Iiwa7, 1.0f64.to_radians()).map(|_| task)
}

/// Every task of the suite, in a fixed order.
pub fn suite() -> Vec<SuiteTask> {
    let mut rng = Pcg64Mcg::seed_from_u64(SEED);
    let mut out = Vec::new();
    let entry = |group, name: String, task: ArmTask, robot, balls| SuiteTask {
        group,
        name,
        refine: task.dynamics.default_refine(),
        task,
        robot,
        balls,
        infeasible: None,
        retime: false,
    };
    out.push(entry("seed", "seed".into(), fixtures::pick_and_place(), Robot::Arm7, vec![]));
    out.push(entry(
        "seed",
        "seed-collision".into(),
        fixtures::pick_and_place_collision(),
        Robot::Arm7,
        vec![(Vector3::new(0.35, 0.0, 0.25), 0.06)],
    ));
    for (group, ball, count) in [("arm7", false, 50), ("arm7-ball", true, 50)] {
        let mut made = 0;
        while made < count {
            if let Some((task, balls)) = arm7_task(&mut rng, ball) {
                out.push(entry(group, format!("{group}-{made:02}"), task, Robot::Arm7, balls));
                made += 1;
            }
        }
    }
    let rigid = fixtures::ur5e_rigid_body();
    let mut urdf = rigid.clone();
    let xml = include_str!("../../../crates/kinematics/tests/fixtures/dynamics/ur5e.urdf");
    urdf.chain = armature_kinematics::chain_from_urdf_str(xml, "base_link", "tool0", None)
        .expect("the fixture URDF loads");
    urdf.dynamics = DynamicsModel::DecoupledInertia(vec![2.0, 2.0, 1.0, 0.1, 0.1, 0.05]);
    let mut urdf = urdf.resegmented(urdf.dynamics.default_per_segment()).expect("even waypoints");
    urdf.settings = urdf.dynamics.default_settings();
    urdf.velocity_limit_peaks = urdf.dynamics.default_velocity_limit_peaks();
    urdf.time_scaled_torque = urdf.dynamics.default_time_scaled_torque();
    for (group, base) in [("ur5e-urdf", &urdf), ("ur5e-rigid-body", &rigid)] {
        let mut made = 0;
        while made < 20 {
            if let Some(task) = ur5e_task(&mut rng, base) {
                out.push(entry(group, format!("{group}-{made:02}"), task, Robot::Ur5e, vec![]));
                made += 1;
            }
        }
    }
    let mut made = 0;
    while made < 20 {
        if let Some(task) = iiwa_task(&mut rng) {
            out.push(entry("iiwa7", format!("iiwa7-{made:02}"), task, Robot::Iiwa7, vec![]));
            made += 1;
        }
    }
    out.extend(infeasible());
    out
}

/// Tasks built to be infeasible.
fn infeasible() -> Vec<SuiteTask> {
    let mut start_in_ball = fixtures::pick_and_place();
    let home = Vector3::new(0.69, 0.0, 0.34);
    with_ball(&mut start_in_ball, home - Vector3::new(0.05, 0.0, 0.0), 0.05);
    let mut out_of_reach = fixtures::pick_and_place();
    out_of_reach.waypoints[5].position = [1.5, 0.25, 0.05];
    let mut ur_out_of_reach = fixtures::ur5e_rigid_body();
    ur_out_of_reach.waypoints[3].position = [-1.2, 0.3, 0.1];
    let entry = |name: &str, task: ArmTask, robot, balls, why| SuiteTask {
        group: "infeasible",
        name: name.into(),
        refine: task.dynamics.default_refine(),
        task,
        robot,
        balls,
        infeasible: Some(why),
        retime: false,
    };
    vec![
        entry(
            "start-inside-ball",
            start_in_ball,
            Robot::Arm7,
            vec![(home - Vector3::new(0.05, 0.0, 0.0), 0.05)],
            "the start configuration is inside the ball",
        ),
        entry(
            "place-out-of-reach",
            out_of_reach,
            Robot::Arm7,
            vec![],
            "the place is 1.5 m out, beyond arm7's 0.7 m reach",
        ),
        entry(
            "ur5e-place-out-of-reach",
            ur_out_of_reach,
            Robot::Ur5e,
            vec![],
            "the place is 1.24 m out, beyond the UR5e's reach",
        ),
    ]
}
