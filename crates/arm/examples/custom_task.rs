//! An arm task written from scratch in Rust: the UR5e moves a tool from its home pose to two
//! points on a table, tool down, as fast as the decoupled model allows; the plan is solved
//! and read back by name.
//!
//! `cargo run --release -p armature-arm --example custom_task`

use armature_arm::{
    ArmTask, DynamicsModel, Initialization, OrientationRange, TimeWindow, Waypoint, fixtures,
};
use armature_kinematics::robots;
use armature_scvx::{PtrSettings, PtrStatus};

/// Runs the example (its asserts are its test: `tests/gallery.rs`).
pub(crate) fn main() {
    let chain = robots::ur5e();
    let down = fixtures::UR5E_DOWN;
    let at = |name: &str, node, position| Waypoint {
        name: String::from(name),
        node,
        position,
        tolerance: 0.01,
        orientation: Some(down),
    };
    use std::f64::consts::FRAC_PI_2 as H;
    let task = ArmTask {
        dynamics: DynamicsModel::DecoupledInertia(vec![2.0, 2.0, 1.0, 0.1, 0.1, 0.05]),
        velocity_limit: vec![std::f64::consts::PI; 6],
        torque_limit: vec![150.0, 150.0, 150.0, 28.0, 28.0, 28.0],
        velocity_limit_peaks: true,
        time_scaled_torque: true,
        angle_limit_peaks: false,
        start: Some(vec![0.0, -H, H, -H, -H, 0.0]),
        time: TimeWindow { min: 0.0, max: 6.0, minimize: true },
        nodes: 5,
        waypoints: vec![
            at("home", 0, [-0.4919, -0.1333, 0.4879]),
            at("a", 2, [-0.5, -0.2, 0.15]),
            at("b", 4, [-0.5, 0.2, 0.15]),
        ],
        orientation: vec![OrientationRange {
            name: "a..b".into(),
            quaternion_wxyz: down,
            tolerance_deg: 10.0,
            first: 2,
            last: 4,
        }],
        table_height: Some(0.0),
        collision: None,
        initialization: Initialization::default(),
        settings: PtrSettings::default(),
        retime_stall: None,
        chain,
    };
    let solution = task.plan().expect("the task is consistent").compile().unwrap().solve().unwrap();
    println!(
        "{:?} after {} iterations: T = {:.3} s",
        solution.status, solution.iterations, solution.final_time
    );
    assert_eq!(solution.status, PtrStatus::Converged);
    // The trajectory by name: the tool ends at b, at rest.
    let last = solution.nodes["ee_position"].last().unwrap().clone();
    let gap = ((last[0] + 0.5).powi(2) + (last[1] - 0.2).powi(2) + (last[2] - 0.15).powi(2)).sqrt();
    assert!(gap <= 0.01 + 1e-6, "{gap}");
    assert!(solution.nodes["velocity"].last().unwrap().iter().all(|v| v.abs() < 1e-6));
}
