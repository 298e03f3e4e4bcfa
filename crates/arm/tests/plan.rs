//! `ArmTask::plan`: the fixtures plan, and every check names the part of the task at fault.

use armature_arm::{DynamicsModel, TaskItem, fixtures};

fn item_of(mut change: impl FnMut(&mut armature_arm::ArmTask)) -> (TaskItem, String) {
    let mut task = fixtures::pick_and_place();
    change(&mut task);
    let e = task.plan().unwrap_err();
    (e.item, e.message)
}

#[test]
fn the_fixtures_plan_with_their_states_controls_and_guess() {
    for task in [
        fixtures::pick_and_place(),
        fixtures::pick_and_place_collision(),
        fixtures::ur5e_rigid_body(),
    ] {
        let plan = task.plan().unwrap();
        let n = task.chain.dof();
        assert_eq!(plan.problem.nodes, task.nodes);
        assert_eq!(plan.problem.states.len(), 2);
        assert_eq!(plan.dilation_guess.len(), task.nodes);
        assert!(plan.dilation_guess.iter().all(|d| d.is_finite() && *d > 0.0));
        assert_eq!(plan.ik.q.len(), task.nodes);
        assert!(plan.ik.q.iter().all(|q| q.len() == n));
        plan.compile().unwrap();
    }
    // The start is where the guess begins.
    let ur = fixtures::ur5e_rigid_body();
    assert_eq!(&ur.plan().unwrap().ik.q[0], ur.start.as_ref().unwrap());
}

#[test]
fn every_check_names_its_item() {
    assert_eq!(
        item_of(|t| t.velocity_limit.pop().map(drop).unwrap_or(())).0,
        TaskItem::VelocityLimit
    );
    assert_eq!(item_of(|t| t.torque_limit[3] = -1.0).0, TaskItem::TorqueLimit);
    assert_eq!(item_of(|t| t.time.max = f64::NAN).0, TaskItem::Time);
    assert_eq!(item_of(|t| t.nodes = 1).0, TaskItem::Nodes);
    assert_eq!(item_of(|t| t.waypoints[2].position[1] = f64::INFINITY).0, TaskItem::Waypoint(2));
    assert_eq!(item_of(|t| t.waypoints[3].name = "grasp".into()).0, TaskItem::Waypoint(3));
    assert_eq!(item_of(|t| t.waypoints[5].node = 9).0, TaskItem::Waypoint(5));
    assert_eq!(item_of(|t| t.orientation[1].tolerance_deg = 180.0).0, TaskItem::Orientation(1));
    assert_eq!(item_of(|t| t.orientation[2].last = 11).0, TaskItem::Orientation(2));
    assert_eq!(item_of(|t| t.table_height = Some(f64::NAN)).0, TaskItem::Table);
    let (item, message) = item_of(|t| t.dynamics = DynamicsModel::DecoupledInertia(vec![1.0; 6]));
    assert_eq!((item, message.as_str()), (TaskItem::Dynamics, "6 inertias for 7 joints"));
    // The seed arm has no mass properties: rigid-body dynamics names the first joint.
    let (item, message) =
        item_of(|t| t.dynamics = DynamicsModel::RigidBody { gravity: [0.0, 0.0, -9.81] });
    assert_eq!(item, TaskItem::Dynamics);
    assert!(message.contains("joint 'j1'"), "{message}");
    let (item, message) = item_of(|t| t.start = Some(vec![0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]));
    assert_eq!(item, TaskItem::Start);
    assert!(message.contains("from the first waypoint 'home'"), "{message}");
    // arm7 at zero puts the end effector 1 cm from home: within a 2 cm tolerance it plans.
    let mut task = fixtures::pick_and_place();
    task.waypoints[0].tolerance = 0.02;
    task.start = Some(vec![0.0; 7]);
    assert_eq!(task.plan().unwrap().ik.q[0], vec![0.0; 7]);
}

#[test]
fn rigid_body_dynamics_is_the_aba_of_the_chain() {
    use armature_kinematics::RigidBodyModel;
    let task = fixtures::ur5e_rigid_body();
    let plan = task.plan().unwrap();
    let compiled = plan.compile().unwrap();
    // The dynamics at the guess's first node, evaluated through the compiled problem, against
    // a direct ABA call.
    let model = RigidBodyModel::new(&task.chain, [0.0, 0.0, -9.81]).unwrap();
    let (q, qd, tau) = (
        [0.1, -1.2, 1.3, -1.0, -1.5, 0.2],
        [0.3, -0.2, 0.1, 0.4, 0.0, -0.1],
        [5.0, -40.0, 10.0, 2.0, 1.0, 0.1],
    );
    let mut direct = [0.0; 6];
    model.aba(&mut model.workspace(), &q, &qd, &tau, &mut direct).unwrap();
    let f = armature_symbolic::Function::compile(
        &[plan.problem.dynamics[1].clone()],
        &[
            &[plan.problem.states[0].expr(), plan.problem.states[1].expr()],
            &[plan.problem.controls[0].expr()],
        ],
    )
    .unwrap();
    let x: Vec<f64> = q.iter().chain(&qd).chain(&tau).copied().collect();
    let mut out = [0.0; 6];
    f.eval(&x, &mut f.workspace(), &mut out, None).unwrap();
    assert_eq!(out, direct);
    drop(compiled);
}

#[test]
fn infeasible_tasks_are_named_before_solving() {
    // A place 1.5 m out, beyond arm7's reach.
    let mut task = fixtures::pick_and_place();
    task.waypoints[5].position = [1.5, 0.25, 0.05];
    let e = task.plan().unwrap_err();
    assert_eq!(e.item, TaskItem::Waypoint(5));
    assert!(
        e.message.contains("'place' is out of reach") && e.message.contains("0.8"),
        "{}",
        e.message
    );
    // A ball where the arm starts.
    let mut task = fixtures::pick_and_place_collision();
    let c = task.collision.as_mut().unwrap();
    let scene = armature_collision::Scene {
        self_collision: true,
        allowed: vec![],
        extra: vec![],
        links: vec![armature_collision::LinkSpec {
            start: "wrist".into(),
            end: "ee".into(),
            radius: 0.035,
        }],
        obstacles: vec![armature_collision::ObstacleSpec {
            name: "ball".into(),
            sphere: Some(armature_collision::SphereSpec {
                center: [0.64, 0.0, 0.34],
                radius: 0.05,
            }),
            cuboid: None,
            capsule: None,
            halfspace: None,
        }],
    };
    c.model = scene.model(&task.chain).unwrap();
    let e = task.plan().unwrap_err();
    assert_eq!(e.item, TaskItem::Start);
    assert!(e.message.contains("wrist-ee and ball overlap"), "{}", e.message);
    // The fixtures themselves pass these checks (they plan: see above).
}
