//! IK acceptance: random reachable targets, unreachable targets, the seed's keyframes, bad
//! input, nullspace objective, reproducibility.

use std::f64::consts::{FRAC_1_SQRT_2, PI};

use armature_ik::{
    IkError, IkSettings, IkWorkspace, Keyframe, Mode, Nullspace, Target, ik_interpolation,
    interpolate_targets, solve,
};
use armature_kinematics::{Chain, robots};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn random_in_limits(chain: &Chain, rng: &mut Pcg64Mcg) -> Vec<f64> {
    let (lo, hi) = chain.position_limits();
    (0..chain.dof()).map(|i| rng.random_range(lo[i].max(-PI)..=hi[i].min(PI))).collect()
}

fn fk_target(chain: &Chain, q: &[f64]) -> Target {
    let mut ws = chain.fk_workspace();
    chain.forward(q, &mut ws).unwrap();
    let ee = ws.ee();
    Target { position: ee.translation(), orientation: Some(ee.rotation()) }
}

#[test]
fn thousand_random_reachable_pose_targets() {
    let arm = robots::arm7();
    let (lo, hi) = arm.position_limits();
    let mut rng = Pcg64Mcg::seed_from_u64(2026);
    let settings = IkSettings { restarts: 30, ..IkSettings::default() };
    let mut ws = IkWorkspace::new(&arm);
    let (mut ok, mut iters, mut attempts) = (0, 0, 0);
    for _ in 0..1000 {
        let q_true = random_in_limits(&arm, &mut rng);
        let target = fk_target(&arm, &q_true);
        let r = solve(&arm, &target, &[0.0; 7], &settings, &mut ws).unwrap();
        for i in 0..7 {
            assert!(r.q[i] >= lo[i] && r.q[i] <= hi[i], "joint {i} = {} outside limits", r.q[i]);
        }
        assert!(r.position_error.is_finite() && r.orientation_error.is_finite());
        if r.converged {
            ok += 1;
            assert!(r.position_error < 1e-6 && r.orientation_error < 1e-6);
            // The reported errors are the true errors of the returned configuration.
            let got = fk_target(&arm, &r.q);
            assert!((got.position - target.position).norm() < 1e-6);
        }
        iters += r.iterations;
        attempts += r.attempts;
    }
    eprintln!(
        "converged {ok}/1000, mean iterations {:.1}, mean attempts {:.2}",
        iters as f64 / 1000.0,
        attempts as f64 / 1000.0
    );
    assert!(ok >= 990, "only {ok}/1000 converged");
}

#[test]
fn position_only_targets_and_ur5e() {
    let mut rng = Pcg64Mcg::seed_from_u64(7);
    for chain in [robots::arm7(), robots::ur5e()] {
        let mut ws = IkWorkspace::new(&chain);
        let settings = IkSettings { restarts: 30, ..IkSettings::default() };
        let mut ok = 0;
        for _ in 0..200 {
            let q = random_in_limits(&chain, &mut rng);
            let full = fk_target(&chain, &q);
            let pos = Target::position(full.position);
            let seed = vec![0.1; chain.dof()];
            let a = solve(&chain, &pos, &seed, &settings, &mut ws).unwrap();
            let b = solve(&chain, &full, &seed, &settings, &mut ws).unwrap();
            assert_eq!(a.orientation_error, 0.0);
            ok += usize::from(a.converged) + usize::from(b.converged);
        }
        assert!(ok >= 396, "{}: {ok}/400", chain.name());
    }
}

#[test]
fn unreachable_targets_report_best_effort() {
    let arm = robots::arm7();
    let mut ws = IkWorkspace::new(&arm);
    let settings = IkSettings { restarts: 3, ..IkSettings::default() };
    // Beyond the 0.7 m reach from the shoulder at (0, 0, 0.34).
    for p in [Vector3::new(2.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 1.5), Vector3::new(0.0, 0.0, 1.2)]
    {
        let r = solve(&arm, &Target::position(p), &[0.0; 7], &settings, &mut ws).unwrap();
        assert!(!r.converged, "{p:?}");
        assert!(r.position_error.is_finite() && r.position_error > 1e-3);
        assert_eq!(r.attempts, 4);
    }
    // Far away, the best effort points the outstretched arm at the target: error = distance − reach.
    let r =
        solve(&arm, &Target::position(Vector3::new(2.0, 0.0, 0.34)), &[0.0; 7], &settings, &mut ws)
            .unwrap();
    assert!((r.position_error - (2.0 - 0.7)).abs() < 1e-6, "{}", r.position_error);
}

fn seed_keyframes() -> Vec<Keyframe> {
    let q_down = [FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2, 0.0];
    let kf =
        |node, p: [f64; 3], q: [f64; 4]| Keyframe { node, position: p, quaternion_wxyz: Some(q) };
    vec![
        kf(0, [0.69, 0.0, 0.34], [1.0, 0.0, 0.0, 0.0]),
        kf(2, [0.35, -0.25, 0.2], q_down),
        kf(4, [0.35, -0.25, 0.05], q_down),
        kf(6, [0.35, -0.25, 0.2], q_down),
        kf(8, [0.35, 0.25, 0.2], q_down),
        kf(10, [0.35, 0.25, 0.05], q_down),
    ]
}

#[test]
fn seed_pick_and_place_keyframes_both_modes() {
    let arm = robots::arm7();
    let targets = interpolate_targets(&seed_keyframes()).unwrap();
    assert_eq!(targets.len(), 11);
    assert!((targets[1].position - Vector3::new(0.52, -0.125, 0.27)).norm() < 1e-15);
    // Node 1 lies halfway between identity and gripper-down: a 45° rotation about y.
    assert!((targets[1].orientation.unwrap().angle() - PI / 4.0).abs() < 1e-12);
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    for mode in [Mode::Sequential, Mode::Parallel] {
        let t = ik_interpolation(&arm, &seed_keyframes(), &[0.0; 7], &settings, mode).unwrap();
        assert_eq!(t.q.len(), 11);
        assert!(
            t.all_converged(),
            "{mode:?}: {:?}",
            t.nodes.iter().map(|r| r.converged).collect::<Vec<_>>()
        );
        for (k, q) in t.q.iter().enumerate() {
            let got = fk_target(&arm, q);
            assert!((got.position - targets[k].position).norm() < 1e-6, "{mode:?} node {k}");
        }
        eprintln!("{mode:?}: max joint step {:.3} rad", t.max_joint_step);
        if mode == Mode::Sequential {
            // Warm starts give a continuous path: no joint jumps by more than 1.5 rad between nodes.
            assert!(t.max_joint_step < 1.5, "max joint step {}", t.max_joint_step);
        }
    }
}

#[test]
fn bad_input_is_an_error_naming_the_problem() {
    let arm = robots::arm7();
    let mut ws = IkWorkspace::new(&arm);
    let s = IkSettings::default();
    let t = Target::position(Vector3::new(0.4, 0.0, 0.3));
    let nan = Target::position(Vector3::new(f64::NAN, 0.0, 0.3));
    assert!(matches!(solve(&arm, &nan, &[0.0; 7], &s, &mut ws), Err(IkError::BadTarget(_))));
    let e = solve(&arm, &t, &[0.0; 6], &s, &mut ws).unwrap_err().to_string();
    assert!(e.contains("expected 7 joint values, got 6"), "{e}");
    assert!(solve(&arm, &t, &[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0], &s, &mut ws).is_err());
    assert!(
        Target::pose(Vector3::zeros(), [1.0, 1.0, 0.0, 0.0])
            .unwrap_err()
            .to_string()
            .contains("norm")
    );
    let bad = IkSettings { damping: -1.0, ..IkSettings::default() };
    assert_eq!(
        solve(&arm, &t, &[0.0; 7], &bad, &mut ws).unwrap_err().to_string(),
        "IK settings: damping must be a positive finite number"
    );
    assert!(IkSettings { max_iterations: 0, ..IkSettings::default() }.validate().is_err());
    assert!(IkSettings { nullspace_gain: 2.0, ..IkSettings::default() }.validate().is_err());
    let mut kfs = seed_keyframes();
    kfs[2].node = 1;
    assert!(
        interpolate_targets(&kfs)
            .unwrap_err()
            .to_string()
            .contains("keyframe 2: node 1 does not come after node 2")
    );
    assert!(interpolate_targets(&[]).is_err());
    let mut other = IkWorkspace::new(&robots::ur5e());
    assert!(solve(&arm, &t, &[0.0; 7], &s, &mut other).is_err(), "workspace of another chain");
}

#[test]
fn nullspace_objective_and_reproducible_restarts() {
    let arm = robots::arm7();
    let mut ws = IkWorkspace::new(&arm);
    let mut rng = Pcg64Mcg::seed_from_u64(11);
    let (mut plain_dist, mut null_dist) = (0.0, 0.0);
    for _ in 0..50 {
        let target = Target::position(fk_target(&arm, &random_in_limits(&arm, &mut rng)).position);
        let seed = random_in_limits(&arm, &mut rng);
        let plain = solve(&arm, &target, &seed, &IkSettings::default(), &mut ws).unwrap();
        let near =
            IkSettings { nullspace: Nullspace::Seed, nullspace_gain: 0.2, ..IkSettings::default() };
        let held = solve(&arm, &target, &seed, &near, &mut ws).unwrap();
        let d = |q: &[f64]| q.iter().zip(&seed).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        if plain.converged && held.converged {
            plain_dist += d(&plain.q);
            null_dist += d(&held.q);
        }
    }
    assert!(
        null_dist < plain_dist,
        "the nullspace term keeps solutions nearer the seed: {null_dist} vs {plain_dist}"
    );
    // Mid-range objective converges too.
    let mid = IkSettings { nullspace: Nullspace::MidRange, restarts: 5, ..IkSettings::default() };
    let t = fk_target(&arm, &[0.3, 0.5, -0.4, -1.0, 0.2, 1.2, 0.1]);
    assert!(solve(&arm, &t, &[0.0; 7], &mid, &mut ws).unwrap().converged);
    // Same seed, same answer; restarts draw from the seeded generator.
    let s = IkSettings { restarts: 6, rng_seed: 99, max_iterations: 5, ..IkSettings::default() };
    let far = Target::position(Vector3::new(0.1, 0.5, 0.1));
    let a = solve(&arm, &far, &[0.0; 7], &s, &mut ws).unwrap();
    let b = solve(&arm, &far, &[0.0; 7], &s, &mut IkWorkspace::new(&arm)).unwrap();
    assert_eq!(a, b);
}

/// Targets so far away that the squared error overflows are not reached (issue 25, class 5:
/// `ik --pos 1e300,0,0` reported converged with zero errors), and the errors say how far.
#[test]
fn astronomically_far_targets_are_not_converged() {
    let arm = robots::arm7();
    let mut ws = IkWorkspace::new(&arm);
    for x in [1e300, -1e308, 1e155, 1e20] {
        let target = Target { position: Vector3::new(x, 0.0, 0.0), orientation: None };
        let r = solve(&arm, &target, &[0.0; 7], &IkSettings::default(), &mut ws).unwrap();
        assert!(!r.converged, "{x}");
        let rel = (r.position_error - x.abs()) / x.abs();
        assert!(rel.abs() < 1e-6, "{x}: error {} m", r.position_error);
    }
}

/// A keyframe at an absurd node is an error naming the limit, not hours of IK.
#[test]
fn a_keyframe_beyond_the_largest_node_is_an_error() {
    let k = |node| armature_ik::Keyframe { node, position: [0.5, 0.0, 0.4], quaternion_wxyz: None };
    let e = armature_ik::interpolate_targets(&[k(0), k(100_000_000)]).unwrap_err();
    assert!(e.to_string().contains("beyond the largest node 100000"), "{e}");
    assert!(armature_ik::interpolate_targets(&[k(0), k(10)]).is_ok());
}
