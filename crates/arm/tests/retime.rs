//! `ArmTask::retime` on the seed: faster along the same path, every limit held at the
//! samples, consistent with the dynamics; bad solutions are named, not panicked on.

use armature_arm::{TaskItem, fixtures};
use armature_scvx::Solution;

fn seed_solution() -> (armature_arm::ArmTask, Solution) {
    let seed = fixtures::pick_and_place();
    let solution = seed.plan().unwrap().compile().unwrap().solve().unwrap();
    (seed, solution)
}

#[test]
fn the_seed_retimed_is_faster_on_the_same_path_within_its_limits() {
    let (seed, solution) = seed_solution();
    let r = seed.retime(&solution).unwrap();
    assert!(
        r.final_time < 0.995 * solution.final_time,
        "{} vs {}",
        r.final_time,
        solution.final_time
    );
    assert_eq!(r.time.len(), r.angle.len());
    assert!(r.time.windows(2).all(|w| w[1] > w[0]));
    let inertia = match &seed.dynamics {
        armature_arm::DynamicsModel::DecoupledInertia(i) => i.clone(),
        armature_arm::DynamicsModel::RigidBody { .. } => unreachable!("the seed is decoupled"),
    };
    for i in 0..r.time.len() {
        for j in 0..inertia.len() {
            assert!(r.velocity[i][j].abs() <= seed.velocity_limit[j] + 1e-9);
            assert!(r.torque[i][j].abs() <= seed.torque_limit[j] + 1e-9);
            // q̈ = τ / I, sample by sample.
            assert!((r.torque[i][j] - inertia[j] * r.acceleration[i][j]).abs() < 1e-9);
        }
    }
    let still = |v: &[f64]| v.iter().all(|x| x.abs() < 1e-9);
    assert!(still(&r.velocity[0]) && still(&r.velocity[r.time.len() - 1]));
    // The path passes the solution's nodes, at the retimed node times.
    let nodes = &solution.nodes["angle"];
    assert_eq!(r.node_times.len(), nodes.len());
    for (k, t) in r.node_times.iter().enumerate() {
        let i = r.time.iter().position(|s| s == t).unwrap();
        for (a, b) in r.angle[i].iter().zip(&nodes[k]) {
            assert!((a - b).abs() < 1e-4, "node {k}: {a} vs {b}");
        }
    }
    // The velocities integrate to the angles (trapezoidal rule), within 1e-4 rad.
    let mut q = r.angle[0].clone();
    for i in 0..r.time.len() - 1 {
        let dt = r.time[i + 1] - r.time[i];
        for j in 0..q.len() {
            q[j] += 0.5 * dt * (r.velocity[i][j] + r.velocity[i + 1][j]);
            assert!((q[j] - r.angle[i + 1][j]).abs() < 1e-4);
        }
    }
}

#[test]
fn a_bad_solution_is_named_not_panicked_on() {
    let (seed, solution) = seed_solution();
    let mut missing = solution.clone();
    missing.nodes.remove("torque");
    let e = seed.retime(&missing).unwrap_err();
    assert_eq!(e.item, TaskItem::Solution);
    assert!(e.message.contains("torque"), "{}", e.message);

    let mut moving = solution.clone();
    let last = moving.nodes.get_mut("velocity").unwrap().last_mut().unwrap();
    last[0] = 0.5;
    let e = seed.retime(&moving).unwrap_err();
    assert!(e.message.contains("rest"), "{}", e.message);

    let mut nan = solution.clone();
    nan.nodes.get_mut("angle").unwrap()[3][2] = f64::NAN;
    assert_eq!(seed.retime(&nan).unwrap_err().item, TaskItem::Solution);

    let mut short = solution;
    for table in short.nodes.values_mut() {
        table.truncate(1);
    }
    assert_eq!(seed.retime(&short).unwrap_err().item, TaskItem::Solution);
}

#[test]
fn limits_that_do_not_fit_the_arm_are_named() {
    let (mut seed, solution) = seed_solution();
    seed.torque_limit.pop();
    assert_eq!(seed.retime(&solution).unwrap_err().item, TaskItem::TorqueLimit);
}

#[test]
fn the_coarse_estimate_of_the_retimed_time_is_close_and_converges_to_it() {
    let (seed, solution) = seed_solution();
    let fine = seed.retime(&solution).unwrap().final_time;
    assert_eq!(
        seed.retimed_final_time(&solution.nodes, Some(&solution.control_ends), 2000).unwrap(),
        fine
    );
    let coarse =
        seed.retimed_final_time(&solution.nodes, Some(&solution.control_ends), 200).unwrap();
    let finer =
        seed.retimed_final_time(&solution.nodes, Some(&solution.control_ends), 800).unwrap();
    // Coarser grids relax the rows between samples a little less tightly (within 1 %).
    assert!((coarse / fine - 1.0).abs() < 1e-2, "{coarse} vs {fine}");
    assert!((finer - fine).abs() <= (coarse - fine).abs(), "{finer} {coarse} {fine}");
    let mut moving = solution.nodes.clone();
    moving.get_mut("velocity").unwrap()[0][1] = 0.3;
    let e = seed.retimed_final_time(&moving, None, 200).unwrap_err();
    assert_eq!(e.item, TaskItem::Solution);
}
