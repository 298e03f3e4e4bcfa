//! Acceptance: the seed tutorial's 7-DOF pick-and-place converges, hits every waypoint within
//! 1 cm, keeps the gripper orientation within 5° / 0.1° at every node of its ranges, meets
//! the joint, velocity and table limits on the dense trajectory (dt = 0.01) within 1e-4, and
//! finishes in at most 4 s.

mod seed;

use armature_scvx::{Ptr, PtrSettings, PtrStatus};

#[test]
fn seed_pick_and_place_converges_and_meets_the_task() {
    let s = seed::build();
    let mut ptr = Ptr::new(s.ocp.clone(), PtrSettings::default());
    let r = ptr.solve(&s.x, &s.u, &s.s).unwrap();
    let c = seed::check(&s, &r);
    eprintln!(
        "{:?} after {} iterations, T = {:.4} s; {c:?}",
        r.status,
        r.history.len(),
        r.final_time
    );
    assert_eq!(r.status, PtrStatus::Converged);
    assert!(r.final_time <= 4.0 + 1e-9, "T = {}", r.final_time);
    assert!((c.dense_final_time - r.final_time).abs() < 1e-9);
    assert!(c.waypoint_error <= 0.01 + 1e-6, "waypoint error {} m", c.waypoint_error);
    assert!(c.orientation_error[0] <= 5f64.to_radians() + 1e-6, "{:?}", c.orientation_error);
    assert!(c.orientation_error[1] <= 0.1f64.to_radians() + 1e-6, "{:?}", c.orientation_error);
    assert!(c.joint_violation <= 1e-4, "joint limits violated by {}", c.joint_violation);
    assert!(c.velocity_violation <= 1e-4, "velocity violated by {}", c.velocity_violation);
    assert!(c.table_violation <= 1e-4, "table violated by {}", c.table_violation);
    // Dynamically consistent: the nodes are where the dynamics take them.
    assert!(r.history.last().unwrap().max_defect < 1e-6);
}
