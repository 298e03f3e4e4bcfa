//! Mesh refinement: a coarse solution as the guess of the task on a finer grid.

use armature_arm::{fixtures, set_refined_guess};
use armature_scvx::PtrStatus;

#[test]
fn a_refined_solve_starts_on_the_coarse_trajectory_and_ends_faster() {
    let seed = fixtures::pick_and_place();
    let coarse_plan = seed.plan().unwrap();
    let coarse = coarse_plan.compile().unwrap().solve().unwrap();
    assert_eq!(coarse.status, PtrStatus::Converged);
    let fine_task = seed.refined(2);
    assert_eq!(fine_task.nodes, 2 * seed.nodes - 1);
    // The refined stage bounds angles and velocities at every grid point; the task's own
    // grid holds its angles by the limits' integral alone.
    let bounded = |plan: &armature_arm::ArmPlan| {
        plan.problem.states.iter().map(|s| (s.name.clone(), s.interval_bounds)).collect::<Vec<_>>()
    };
    let (angle, velocity) = ("angle".to_string(), "velocity".to_string());
    assert_eq!(bounded(&coarse_plan), [(angle.clone(), false), (velocity.clone(), true)]);
    let fine_plan = fine_task.plan().unwrap();
    assert_eq!(bounded(&fine_plan), [(angle, true), (velocity, true)]);
    let mut fine = fine_plan.compile().unwrap();
    set_refined_guess(&mut fine, &coarse, 2).unwrap();
    let (x, u, s) = fine.guess();
    let (nf, dof) = (fine_task.nodes, seed.chain.dof());
    // The durations add up to the coarse final time, each coarse segment split in two.
    let total: f64 = s[..nf - 1].iter().map(|d| d / (nf - 1) as f64).sum();
    assert!((total - coarse.final_time).abs() < 1e-12, "{total} vs {}", coarse.final_time);
    // The torques: the coarse nodes', and between them the midpoint of each coarse
    // segment's line (to where it ends: a time-scaled torque jumps at the nodes).
    let m = u.len() / nf;
    for k in 0..seed.nodes - 1 {
        let (a, b) = (&coarse.nodes["torque"][k], &coarse.control_ends["torque"][k]);
        for c in 0..dof {
            assert_eq!(u[2 * k * m + c], a[c]);
            assert!((u[(2 * k + 1) * m + c] - 0.5 * (a[c] + b[c])).abs() < 1e-12);
        }
    }
    // The angles at the coarse nodes are the coarse nodes' (the states start with them).
    let n = x.len() / nf;
    for k in 0..seed.nodes {
        assert_eq!(&x[2 * k * n..2 * k * n + dof], &coarse.nodes["angle"][k][..]);
    }
    // Solved from there, the finer control reaches a faster motion, every constraint held
    // on the dense trajectory.
    let refined = fine.solve().unwrap();
    assert_eq!(refined.status, PtrStatus::Converged, "{:?}", refined.max_violation);
    assert!(
        refined.final_time < 0.99 * coarse.final_time,
        "{} vs {}",
        refined.final_time,
        coarse.final_time
    );
    // A guess that does not fit is an error, not a panic.
    assert!(set_refined_guess(&mut fine, &coarse, 0).is_err());
    assert!(set_refined_guess(&mut fine, &coarse, 3).is_err());
    let mut broken = coarse.clone();
    broken.nodes.remove("torque");
    let e = set_refined_guess(&mut fine, &broken, 2).unwrap_err();
    assert!(e.to_string().contains("torque"), "{e}");
    let mut short = coarse.clone();
    short.trajectory.get_mut("angle").unwrap().pop();
    assert!(set_refined_guess(&mut fine, &short, 2).is_err());
}

/// The refined stage starts from the coarse stage's exact-penalty prices (mapped to the
/// finer grid's rows): its first step buys a small fraction of the buffers it buys from the
/// settings' prices, and it converges in no more iterations to as fast a motion.
#[test]
fn the_refined_stage_starts_from_the_coarse_prices() {
    let seed = fixtures::pick_and_place();
    let coarse = seed.plan().unwrap().compile().unwrap().solve().unwrap();
    assert_eq!(coarse.status, PtrStatus::Converged);
    assert!(coarse.prices.rows.iter().any(|r| r.1 > seed.settings.lam_vb), "no raised price");
    let fine_task = seed.refined(2);
    let mut fine = fine_task.plan().unwrap().compile().unwrap();
    set_refined_guess(&mut fine, &coarse, 2).unwrap();
    let carried = fine.solve().unwrap();
    // The same stage from the settings' prices and trust region: a coarse solution without
    // prices (as one read back from a file) carries none.
    let mut unpriced = coarse.clone();
    unpriced.prices = Default::default();
    set_refined_guess(&mut fine, &unpriced, 2).unwrap();
    let fresh = fine.solve().unwrap();
    assert_eq!((carried.status, fresh.status), (PtrStatus::Converged, PtrStatus::Converged));
    let (bought, bought_fresh) = (carried.history[0].j_vb, fresh.history[0].j_vb);
    assert!(bought < 0.1 * bought_fresh, "first step's buffers {bought:e} vs {bought_fresh:e}");
    // On the seed: 9 iterations against 10, T 1.0495 s against 1.0526 s.
    assert!(
        carried.iterations <= fresh.iterations,
        "{} iterations from the coarse prices, {} from the settings'",
        carried.iterations,
        fresh.iterations
    );
    assert!(carried.final_time < 1.002 * fresh.final_time);
}
