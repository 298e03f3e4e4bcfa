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
    let dense =
        verify::reintegrate(&mut d, &[0.0, 1.0], (&[vec![0.0], vec![2.0]], None), &[0.0], &[0.0]);
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

#[test]
fn segment_distance_agrees_with_dense_sampling() {
    // Random segments (some nearly parallel, some crossing, some degenerate) against the least
    // distance over a 400 × 400 grid of their points, which overestimates by at most the grid's
    // spacing times the segments' lengths.
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
    let point = |rng: &mut rand_pcg::Pcg64Mcg| {
        nalgebra::Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
    };
    for case in 0..200 {
        let (a0, b0) = (point(&mut rng), point(&mut rng));
        let mut a1 = point(&mut rng);
        let mut b1 = point(&mut rng);
        match case % 4 {
            1 => b1 = b0 + (a1 - a0) * 0.7 + nalgebra::Vector3::new(1e-9, 0.0, 0.0),
            2 => a1 = a0,
            3 => b1 = b0 + (a1 - a0).cross(&(b0 - a0)) * 0.5,
            _ => {}
        }
        let d = verify::segment_segment(&a0, &a1, &b0, &b1);
        let n = 400;
        let sampled = (0..=n)
            .flat_map(|i| (0..=n).map(move |j| (i as f64 / n as f64, j as f64 / n as f64)))
            .map(|(s, t)| ((a0 + s * (a1 - a0)) - (b0 + t * (b1 - b0))).norm())
            .fold(f64::INFINITY, f64::min);
        let slack = ((a1 - a0).norm() + (b1 - b0).norm()) / n as f64;
        assert!(d <= sampled + 1e-12, "case {case}: {d} above the sampled {sampled}");
        assert!(d >= sampled - slack, "case {case}: {d} below the sampled {sampled} − {slack}");
    }
    // Crossing segments touch; parallel ones at distance 1 are 1 apart.
    let v = |x: f64, y: f64, z: f64| nalgebra::Vector3::new(x, y, z);
    assert!(
        verify::segment_segment(&v(-1., 0., 0.), &v(1., 0., 0.), &v(0., -1., 0.), &v(0., 1., 0.))
            < 1e-15
    );
    let parallel =
        verify::segment_segment(&v(0., 0., 0.), &v(1., 0., 0.), &v(0.5, 1., 0.), &v(2., 1., 0.));
    assert!((parallel - 1.0).abs() < 1e-15);
}

#[test]
fn self_collision_is_checked_on_the_tasks_own_link_pairs() {
    // The arm7 ball tasks keep their non-adjacent capsules apart: the verification knows
    // those pairs, its capsules have the model's radii, and a configuration folded onto
    // itself is reported.
    let tasks = suite();
    let t = tasks.iter().find(|t| t.group == "arm7-ball").expect("a ball task");
    let checks = armature_suite::run::checks(t);
    assert_eq!(checks.link_pairs, vec![(0, 2), (0, 3), (1, 3)]);
    let model = &t.task.collision.as_ref().unwrap().model;
    let q0 = vec![0.0; 7];
    for (link, (_, _, r)) in model.links().iter().zip(Robot::Arm7.capsules(&q0)) {
        assert_eq!(link.radius, r, "{}", link.name);
    }
    for u in &tasks {
        let c = armature_suite::run::checks(u);
        let n = u.robot.capsules(&vec![0.0; u.task.chain.dof()]).len();
        assert!(c.link_pairs.iter().all(|&(i, j)| i < n && j < n), "{}", u.name);
    }
    // Only the configuration's own constraints: no waypoints, ranges or table at t = 0.
    let checks = verify::Checks {
        waypoints: Vec::new(),
        orientation: Vec::new(),
        table: None,
        balls: Vec::new(),
        ..checks
    };
    let still = |q: Vec<f64>| verify::Dense {
        t: vec![0.0],
        q: vec![q],
        qd: vec![vec![0.0; 7]],
        tau: vec![vec![0.0; 7]],
        segment_starts: Vec::new(),
    };
    let ok = verify::check(&checks, &still(vec![0.0, 0.3, 0.0, -1.2, 0.0, 0.9, 0.0]), &[0.0]);
    assert!(!ok.what.starts_with("capsules"), "{ok:?}");
    // A configuration within the joint limits whose wrist reaches back into the upper arm's
    // or the base's capsule (found by a seeded search).
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(3);
    let folded = (0..100_000)
        .map(|_| {
            (0..7).map(|j| rng.random_range(checks.q_lo[j]..checks.q_hi[j])).collect::<Vec<f64>>()
        })
        .find(|q| {
            let c = Robot::Arm7.capsules(q);
            [(0, 2), (0, 3), (1, 3)].iter().any(|&(i, j)| {
                let d = verify::segment_segment(&c[i].0, &c[i].1, &c[j].0, &c[j].1);
                d < c[i].2 + c[j].2 - 0.01
            })
        })
        .expect("a folded configuration");
    let bad = verify::check(&checks, &still(folded), &[0.0]);
    assert!(bad.value > 0.0 && bad.what.starts_with("capsules"), "{bad:?}");
}

#[test]
fn an_outcome_keeps_the_solvers_iteration_records() {
    let tasks = suite();
    let task = tasks.iter().find(|t| t.name == "ur5e-urdf-00").expect("the task");
    let outcome = armature_suite::run::run_one(task);
    assert!(outcome.verified, "{} {}", outcome.status, outcome.worst_what);
    assert_eq!(outcome.history.len(), outcome.iterations);
    let last = outcome.history.last().expect("a record per iteration");
    assert_eq!(last.status, Some(armature_scvx::PtrStatus::Converged));
    assert!((last.final_time - outcome.final_time).abs() < 1e-12);
    // What `--history` prints: a header and a row per record.
    let mut table = Vec::new();
    armature_scvx::IterationTable::header(&mut table).unwrap();
    for it in &outcome.history {
        armature_scvx::IterationTable::row(&mut table, it).unwrap();
    }
    // The task refines by default: each stage's last record says how its loop stopped.
    let ends = outcome.history.iter().filter(|it| it.status.is_some()).count();
    assert_eq!((task.refine, ends), (2, 2));
    let text = String::from_utf8(table).unwrap();
    assert_eq!(text.lines().count(), 1 + outcome.iterations + ends, "{text}");
    // Exported for the reference, the refined solution comes with the refined task: its
    // events index the solution's node times (a waypoint at node k of the task at 2k).
    let exported = armature_suite::reference::export(task, Some(&outcome));
    let nodes = outcome.solution.as_ref().expect("a solution").times.len();
    assert_eq!((exported["nodes"].as_u64(), nodes), (Some(2 * task.task.nodes as u64 - 1), nodes));
    let events: Vec<u64> = serde_json::from_value(exported["events"].clone()).unwrap();
    let own = armature_suite::reference::event_nodes(task);
    assert_eq!(events, own.iter().map(|&k| 2 * k as u64).collect::<Vec<_>>());
    assert_eq!(
        exported["waypoints"][1]["node"].as_u64(),
        Some(2 * task.task.waypoints[1].node as u64)
    );
}
