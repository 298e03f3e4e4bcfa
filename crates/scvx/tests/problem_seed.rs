//! The seed pick-and-place written with the named problem layer (as the tutorial writes it
//! with OpenSCvx): converges like the hand-assembled fixture, with named nodal and dense
//! trajectories, algebraic outputs and a JSON result with the stable top-level keys.

mod seed;

use armature_lie::SO3;
use armature_scvx::{
    Ball, Control, CtcsOptions, Penalty, Problem, ProblemConstraint, ProblemError, PtrSettings,
    State, Time,
};
use armature_symbolic::{Expr, Shape};

fn seed_problem(s: &seed::Seed) -> Problem {
    let nn = seed::NODES;
    let n = s.ocp.dynamics.n_x();
    let (qlo, qhi) = s.arm.position_limits();
    let q0: Vec<f64> = s.x[..7].to_vec();
    let angle = State::new("angle", 7).bounds(&qlo, &qhi).initial_value(&q0);
    let velocity = State::new("velocity", 7)
        .bounds(&[-seed::VELOCITY; 7], &[seed::VELOCITY; 7])
        .initial_value(&[0.0; 7])
        .final_value(&[0.0; 7]);
    let torque = Control::new("torque", 7)
        .bounds(&seed::TORQUE.map(|t| -t), &seed::TORQUE)
        .guess(s.u.clone());
    let (a, v, tau) = (angle.expr(), velocity.expr(), torque.expr());
    let angle = angle.guess((0..nn).flat_map(|k| s.x[k * n..k * n + 7].to_vec()).collect());
    let velocity =
        velocity.guess((0..nn).flat_map(|k| s.x[k * n + 7..k * n + 14].to_vec()).collect());
    let fk = s.arm.symbolic_fk(&a).unwrap();
    let p_ee = fk.ee_position();
    let down = SO3::from_quaternion_wxyz(seed::Q_DOWN).unwrap();
    let log = Expr::from_matrix(&down.matrix().transpose()).matmul(&fk.ee_rotation()).so3_log();
    let ori = log.norm2();
    let limits = CtcsOptions { penalty: Penalty::Relu, eps: 1e-6, group: 0 };
    let mut constraints: Vec<ProblemConstraint> = vec![ProblemConstraint {
        constraint: (-p_ee.at(2)).le(0.0).ctcs().named("table"),
        ctcs: limits,
    }];
    for (deg, first, last) in [(5.0, 2, 10), (0.1, 2, 6), (0.1, 8, 10)] {
        constraints.push(
            (&ori - f64::to_radians(deg))
                .le(0.0)
                .ctcs()
                .over(first, last)
                .named(format!("orientation {deg}° over {first}..={last}"))
                .into(),
        );
    }
    let mut balls: Vec<Ball> = seed::WAYPOINTS
        .iter()
        .enumerate()
        .map(|(w, (p, _))| Ball {
            name: format!("waypoint {w}"),
            g: &p_ee - Expr::parameter(&seed::waypoint_parameter(w), Shape::Vector(3), p),
            radius: 0.01,
            nodes: vec![2 * w],
        })
        .collect();
    for (deg, nodes) in seed::orientation_ranges() {
        balls.push(Ball {
            name: format!("orientation {deg}°"),
            g: log.clone(),
            radius: deg.to_radians(),
            nodes,
        });
    }
    let i_inv = Expr::constant_vector(&seed::INERTIA.map(|i| 1.0 / i));
    Problem {
        dynamics: vec![v.clone(), &i_inv * &tau],
        states: vec![angle, velocity],
        controls: vec![torque],
        time: Time::Free {
            min: 0.0,
            max: 4.0,
            guess: s.s[..nn - 1].iter().sum::<f64>() / (nn - 1) as f64,
            minimize: true,
        },
        constraints,
        balls,
        outputs: vec![
            ("ee_position".into(), p_ee),
            ("T_ee".into(), fk.frame("ee").unwrap().clone()),
        ],
        state_bounds_ctcs: Some(limits),
        ..Problem::new(nn)
    }
}

#[test]
fn seed_through_the_problem_layer_converges_with_named_outputs() {
    let s = seed::build();
    let mut compiled = seed_problem(&s).compile(PtrSettings::default()).unwrap();
    compiled.set_dilation_guess(&s.s).unwrap();
    let sol = compiled.solve().unwrap();
    eprintln!("{} after {} iterations, T = {:.4} s", sol.status, sol.iterations, sol.final_time);
    solved(&sol);
    assert!(sol.final_time <= 4.0 + 1e-9);
    // Named series, at the nodes and dense.
    for key in ["time", "angle", "velocity", "torque", "ee_position", "T_ee"] {
        assert_eq!(sol.nodes[key].len(), seed::NODES, "{key}");
        assert!(sol.trajectory[key].len() > 100, "{key}");
    }
    assert!(!sol.nodes.keys().any(|k| k.starts_with('_')), "internal states are not exposed");
    assert_eq!(sol.nodes["T_ee"][0].len(), 16);
    assert!((sol.nodes["time"][seed::NODES - 1][0] - sol.final_time).abs() < 1e-12);
    // Waypoints from the ee_position output, table and limits on the dense trajectory.
    for (w, (p, _)) in seed::WAYPOINTS.iter().enumerate() {
        let e = &sol.nodes["ee_position"][2 * w];
        let d = ((e[0] - p[0]).powi(2) + (e[1] - p[1]).powi(2) + (e[2] - p[2]).powi(2)).sqrt();
        assert!(d <= 0.01 + 1e-6, "waypoint {w}: {d} m");
    }
    let (qlo, qhi) = s.arm.position_limits();
    let worst = |key: &str, f: &dyn Fn(usize, f64) -> f64| {
        sol.trajectory[key]
            .iter()
            .flat_map(|r| r.iter().enumerate().map(|(i, &v)| f(i, v)))
            .fold(0.0, f64::max)
    };
    assert!(worst("ee_position", &|i, z| if i == 2 { -z } else { 0.0 }) <= 1e-4);
    assert!(worst("angle", &|i, q| (q - qhi[i]).max(qlo[i] - q)) <= 1e-4);
    assert!(worst("velocity", &|_, v| v.abs() - seed::VELOCITY) <= 1e-4);
    // Every constraint reported by name; nothing left violated at the nodes (the dense
    // checks carry their instants).
    assert!(sol.violations.iter().any(|v| v.constraint == "waypoint 5"));
    assert!(sol.violations.iter().any(|v| v.constraint == "dynamics of angle[3]"));
    assert!(sol.violations.iter().any(|v| v.constraint == "table (dense)" && v.time.is_some()));
    let nodal = sol.violations.iter().filter(|v| v.time.is_none());
    assert!(nodal.clone().all(|v| v.value < 1e-6), "{:?}", nodal.collect::<Vec<_>>());
    // The JSON keys scripts depend on.
    let json = serde_json::to_value(&sol).unwrap();
    for key in [
        "status",
        "final_time",
        "iterations",
        "nodes",
        "trajectory",
        "history",
        "timings",
        "violations",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
    // Moving a waypoint: a parameter, no recompilation; warm start from the solution.
    let first = compiled.last_result().unwrap();
    compiled.warm_start(&first).unwrap();
    assert!(
        compiled.set_parameter(&seed::waypoint_parameter(5), &[0.30, 0.28, 0.05]).unwrap() >= 1
    );
    let again = compiled.solve().unwrap();
    solved(&again);
    let e = &again.nodes["ee_position"][10];
    let d = ((e[0] - 0.30).powi(2) + (e[1] - 0.28).powi(2) + (e[2] - 0.05).powi(2)).sqrt();
    assert!(d <= 0.01 + 1e-6, "moved waypoint: {d} m");
}

#[test]
fn bad_problems_say_what_is_wrong() {
    let s = seed::build();
    let base = seed_problem(&s);
    let expect = |p: Problem, what: &str| match p.compile(PtrSettings::default()) {
        Err(ProblemError::Bad { what: w, reason }) => {
            assert!(w.contains(what), "{w}: {reason}")
        }
        Err(e) => panic!("{what}: {e}"),
        Ok(_) => panic!("{what}: compiled"),
    };
    let mut p = base.clone();
    p.states[1].min[0] = 5.0;
    expect(p, "state \"velocity\"");
    let mut p = base.clone();
    p.dynamics.pop();
    expect(p, "dynamics");
    let mut p = base.clone();
    p.balls[0].nodes = vec![99];
    expect(p, "ball \"waypoint 0\"");
    let mut p = base.clone();
    p.time = Time::Free { min: 0.0, max: f64::NAN, guess: 1.0, minimize: true };
    expect(p, "time");
    let mut p = base.clone();
    p.controls[0].name = "angle".into();
    expect(p, "control \"angle\"");
    let mut p = base.clone();
    p.states[0].guess = Some(vec![0.0; 3]);
    expect(p, "state \"angle\"");
    // A constraint over nodes beyond the last: the symbolic crate's message, named.
    let mut p = base.clone();
    p.constraints[1].constraint = p.constraints[1].constraint.clone().over(2, 40);
    assert!(matches!(p.compile(PtrSettings::default()), Err(ProblemError::Symbolic { .. })));
    // A dynamics expression over an unknown variable.
    let mut p = base;
    p.dynamics[0] = Expr::variable("nope", 7);
    let err = p.compile(PtrSettings::default()).unwrap_err();
    assert!(err.to_string().contains("nope"), "{err}");
}

/// Converged — or converged at the nodes with a constraint broken on the dense trajectory,
/// named with its instant (the seed's squared-ReLU orientation ranges, ε = 1e-4, hold at the
/// nodes but not between them).
fn solved(sol: &armature_scvx::Solution) {
    use armature_scvx::PtrStatus;
    match sol.status {
        PtrStatus::Converged => {}
        PtrStatus::ViolatedBetweenNodes => {
            let v = sol.max_violation.as_ref().unwrap();
            assert!(
                matches!(v.constraint, armature_scvx::ConstraintRef::Dense { .. })
                    && v.time.is_some()
                    && v.value > 1e-4,
                "{v:?}"
            );
        }
        other => panic!("{other}: {:?}", sol.max_violation),
    }
}
