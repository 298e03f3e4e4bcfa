//! Honest reports: a solve is `converged` only when every constraint held in continuous time
//! also holds on the dense trajectory within `dense_tolerance`; otherwise the status is
//! `violated_between_nodes` and the violations name the constraint with its instant. Checked
//! on a minimum-time double integrator with a `.ctcs()` speed limit at the default settings,
//! against the speed measured here from the dense trajectory.

use armature_scvx::{
    Control, DENSE_CHECK_DT, Problem, PtrSettings, PtrStatus, Solution, State, Time,
};

const V_MAX: f64 = 0.7;

/// From rest at 0 to rest at 1, |a| ≤ 1, the speed limit |v| ≤ 0.7 in continuous time.
fn problem(nodes: usize) -> Problem {
    let p = State::new("p", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
    let speed = v.expr().abs() - V_MAX;
    Problem {
        dynamics: vec![v.expr(), a.expr()],
        constraints: vec![speed.le(0.0).ctcs().named("speed limit").into()],
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(nodes)
    }
}

fn fastest(s: &Solution) -> f64 {
    s.trajectory["v"].iter().map(|r| r[0].abs()).fold(0.0, f64::max)
}

/// The defaults, with the result sampled as finely as the dense checks.
fn fine() -> PtrSettings {
    let mut s = PtrSettings::default();
    s.dense_dt = DENSE_CHECK_DT;
    s
}

#[test]
fn the_speed_limit_holds_on_the_dense_trajectory_or_the_status_says_so() {
    for nodes in [6, 11, 41] {
        let s = problem(nodes).compile(fine()).unwrap().solve().unwrap();
        let vmax = fastest(&s);
        let dense = s.violations.iter().find(|v| v.constraint == "speed limit (dense)").unwrap();
        assert!((dense.value - (vmax - V_MAX).max(0.0)).abs() < 1e-12, "{dense:?} vs {vmax}");
        match s.status {
            PtrStatus::Converged => assert!(vmax <= V_MAX + 1e-4, "{nodes} nodes: {vmax}"),
            PtrStatus::ViolatedBetweenNodes => {
                assert!(vmax > V_MAX + 1e-4, "{nodes} nodes: {vmax}");
                let worst = s.max_violation.as_ref().unwrap();
                assert_eq!(worst, dense, "the largest violation is the speed limit's");
                // Its instant is a dense sample where the speed is the fastest.
                let t = worst.time.unwrap();
                let k = s.trajectory["time"].iter().position(|r| r[0] == t).unwrap();
                assert_eq!(s.trajectory["v"][k][0].abs(), vmax);
            }
            other => panic!("{nodes} nodes: {other}"),
        }
    }
}

/// The checks sample every `DENSE_CHECK_DT` whatever the result's own sampling: a coarse
/// `dense_dt` gives the same violation and status as a fine one, and the excess the coarse
/// samples show is at most what the checks report.
#[test]
fn the_dense_checks_do_not_depend_on_the_results_sampling() {
    for nodes in [6, 11] {
        let reference = problem(nodes).compile(fine()).unwrap().solve().unwrap();
        let speed = |s: &Solution| {
            s.violations.iter().find(|v| v.constraint == "speed limit (dense)").unwrap().clone()
        };
        for dense_dt in [0.01, 0.05] {
            let mut settings = PtrSettings::default();
            settings.dense_dt = dense_dt;
            let s = problem(nodes).compile(settings).unwrap().solve().unwrap();
            assert_eq!((s.status, speed(&s)), (reference.status, speed(&reference)));
            assert!(s.trajectory["time"].len() < reference.trajectory["time"].len() / 5);
            assert!(fastest(&s) - V_MAX <= speed(&s).value + 1e-12, "{nodes} nodes, {dense_dt}");
        }
    }
}

#[test]
fn the_tolerance_decides_and_a_loose_one_lets_the_same_solve_converge() {
    let strict = problem(6).compile(fine()).unwrap().solve().unwrap();
    let excess = fastest(&strict) - V_MAX;
    assert!(excess > 1e-4, "6 nodes keep the limit: the test needs an overshoot ({excess})");
    assert_eq!(strict.status, PtrStatus::ViolatedBetweenNodes);
    let mut loose = fine();
    loose.dense_tolerance = 2.0 * excess;
    let s = problem(6).compile(loose).unwrap().solve().unwrap();
    assert_eq!(s.status, PtrStatus::Converged);
    assert_eq!((s.final_time, s.iterations), (strict.final_time, strict.iterations));
    // Not a usable tolerance.
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let settings = {
            let mut s = PtrSettings::default();
            s.dense_tolerance = bad;
            s
        };
        assert!(problem(6).compile(settings).is_err(), "{bad}");
    }
}

/// A pendulum swung from rest at 0 to rest at 1 rad in least time, `θ̈ = a − sin θ`,
/// `|a| ≤ 2`, `θ ≤ 0.5` at node 2, on 4 (or 4k − 3) nodes and `substeps` RK4 steps per
/// segment.
fn pendulum(nodes: usize, substeps: usize) -> (Problem, PtrSettings) {
    let th =
        State::new("theta", 1).bounds(&[-5.0], &[5.0]).initial_value(&[0.0]).final_value(&[1.0]);
    let w =
        State::new("omega", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-2.0], &[2.0]);
    let middle = 2 * (nodes - 1) / 3;
    let problem = Problem {
        dynamics: vec![w.expr(), a.expr() - th.expr().sin()],
        constraints: vec![th.expr().le(0.5).at(&[middle]).named("theta at 2/3").into()],
        states: vec![th, w],
        controls: vec![a],
        time: Time::Free { min: 0.1, max: 10.0, guess: 2.0, minimize: true },
        ..Problem::new(nodes)
    };
    let mut settings = fine();
    settings.discretization.substeps = substeps;
    (problem, settings)
}

/// The pendulum's motion re-integrated here (RK4 at 0.1 ms through the first-order-hold
/// control at the solution's nodes): `[θ, ω]` at each node's time.
fn reintegrated(s: &Solution) -> Vec<[f64; 2]> {
    let times: Vec<f64> = s.nodes["time"].iter().map(|r| r[0]).collect();
    let a: Vec<f64> = s.nodes["a"].iter().map(|r| r[0]).collect();
    let f = |x: [f64; 2], u: f64| [x[1], u - x[0].sin()];
    let mut x = [0.0, 0.0];
    let mut out = vec![x];
    for k in 0..times.len() - 1 {
        let steps = ((times[k + 1] - times[k]) / 1e-4).ceil() as usize;
        let h = (times[k + 1] - times[k]) / steps as f64;
        let u = |b: f64| a[k] + b * (a[k + 1] - a[k]);
        for i in 0..steps {
            let (b0, b1) = (i as f64 / steps as f64, (i + 1) as f64 / steps as f64);
            let bh = 0.5 * (b0 + b1);
            let add = |x: [f64; 2], k: [f64; 2], c: f64| [x[0] + c * k[0], x[1] + c * k[1]];
            let k0 = f(x, u(b0));
            let k1 = f(add(x, k0, 0.5 * h), u(bh));
            let k2 = f(add(x, k1, 0.5 * h), u(bh));
            let k3 = f(add(x, k2, h), u(b1));
            x = [
                x[0] + h / 6.0 * (k0[0] + 2.0 * k1[0] + 2.0 * k2[0] + k3[0]),
                x[1] + h / 6.0 * (k0[1] + 2.0 * k1[1] + 2.0 * k2[1] + k3[1]),
            ];
        }
        out.push(x);
    }
    out
}

/// The solver holds its dynamics on its own RK4 grid, and the nodes' conditions at its node
/// values. With one step per long segment that grid is coarse: the motion re-integrated from
/// the start through the controls alone does not end at rest at 1 rad, the report says how
/// far for each final value and for the node constraint (against a re-integration written
/// here), and the status is not `converged`. With ten steps per segment on more nodes the
/// same conditions hold on the re-integrated motion and the task converges.
#[test]
fn the_nodes_conditions_are_checked_on_the_re_integrated_motion() {
    for (nodes, substeps) in [(4, 1), (13, 10)] {
        let (problem, settings) = pendulum(nodes, substeps);
        let s = problem.compile(settings).unwrap().solve().unwrap();
        let mine = reintegrated(&s);
        let report = |name: &str| {
            s.violations.iter().find(|v| v.constraint == name).unwrap_or_else(|| panic!("{name}"))
        };
        let last = mine[nodes - 1];
        let middle = 2 * (nodes - 1) / 3;
        for (name, want) in [
            ("final value of theta, re-integrated (dense)", (last[0] - 1.0).abs()),
            ("final value of omega, re-integrated (dense)", last[1].abs()),
            ("theta at 2/3, re-integrated (dense)", (mine[middle][0] - 0.5).max(0.0)),
        ] {
            let got = report(name).value;
            assert!((got - want).abs() < 1e-6 + 1e-3 * want, "{name}: {got} vs {want}");
        }
        let worst = s.violations.iter().map(|v| v.value).fold(0.0, f64::max);
        match (nodes, s.status) {
            (4, PtrStatus::ViolatedBetweenNodes) => {
                let v = s.max_violation.as_ref().unwrap();
                assert!(v.constraint.name().ends_with(", re-integrated"), "{v:?}");
                assert!(v.value > 1e-3, "{v:?}");
                assert_eq!(v.value, worst);
            }
            (13, PtrStatus::Converged) => assert!(worst < 1e-5, "{worst}"),
            other => panic!("{other:?}: {:?}", s.max_violation),
        }
    }
}
