//! The suite's own parts: its FK agrees with the chains' (two implementations that share no
//! code), its re-integration with closed forms, and the generator makes the tasks the issue
//! asks for, deterministically.

use armature_kinematics::robots;
use armature_suite::generate::suite;
use armature_suite::verify::{self, Robot};
use rand::{Rng, SeedableRng};

#[test]
fn the_verification_fk_agrees_with_the_chains() {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
    for (robot, chain) in [
        (Robot::Arm7, robots::arm7()),
        (Robot::Ur5e, robots::ur5e()),
        (Robot::Iiwa7, armature_suite::generate::iiwa7()),
    ] {
        let mut ws = chain.fk_workspace();
        for _ in 0..50 {
            let q: Vec<f64> = (0..chain.dof()).map(|_| rng.random_range(-3.0..3.0)).collect();
            chain.forward(&q, &mut ws).unwrap();
            let (r, p) = robot.ee(&q);
            let ee = ws.ee();
            assert!((p - ee.translation()).norm() < 1e-12, "{robot:?}");
            assert!(verify::angle_between(&r, &ee.rotation().matrix()) < 1e-7, "{robot:?}");
        }
    }
}

#[test]
fn reintegration_matches_constant_acceleration() {
    // q̈ = τ / I with τ ramping linearly from 0 to 2 over 1 s and I = 2: q̈ = t, q̇ = t² / 2,
    // q = t³ / 6 (RK4 is exact on these polynomials).
    let mut d = verify::Decoupled(vec![2.0]);
    let dense = verify::reintegrate(&mut d, &[0.0, 1.0], &[vec![0.0], vec![2.0]], &[0.0], &[0.0]);
    let last = dense.t.len() - 1;
    assert!((dense.t[last] - 1.0).abs() < 1e-12);
    assert!((dense.qd[last][0] - 0.5).abs() < 1e-12, "{}", dense.qd[last][0]);
    assert!((dense.q[last][0] - 1.0 / 6.0).abs() < 1e-12, "{}", dense.q[last][0]);
}

#[test]
fn the_generator_is_deterministic_and_complete() {
    let a = suite();
    let count = |g: &str| a.iter().filter(|t| t.group == g).count();
    assert_eq!((count("arm7"), count("arm7-ball")), (50, 50));
    assert!(count("ur5e-urdf") >= 20 && count("ur5e-rigid-body") >= 20 && count("iiwa7") >= 20);
    assert!(count("infeasible") >= 3 && count("seed") == 2);
    // Every ball task has a ball, every task plans.
    for t in &a {
        assert_eq!(t.group == "arm7-ball", t.group == "arm7-ball" && !t.balls.is_empty());
        if t.infeasible.is_none() {
            t.task.plan().unwrap_or_else(|e| panic!("{}: {e}", t.name));
        }
    }
    let b = suite();
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.task, y.task, "{}", x.name);
    }
}
