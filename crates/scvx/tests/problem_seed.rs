//! The seed pick-and-place through the named problem layer, as `armature_arm` builds it
//! (the tutorial's formulation, written once for the whole repo, with the task's defaults: 3
//! nodes per segment, time-scaled torques): converges with named nodal and dense
//! trajectories, algebraic outputs and a JSON result with the stable top-level keys; broken
//! problems say what is wrong.

mod seed;

use armature_arm::fixtures;
use armature_scvx::{Problem, ProblemError, PtrSettings, Time};
use armature_symbolic::Expr;

/// The seed task's node count.
const NODES: usize = 16;

/// The seed's problem and the guess of its segments' durations.
fn seed_problem() -> (Problem, Vec<f64>) {
    let plan = fixtures::pick_and_place().plan().unwrap();
    (plan.problem, plan.dilation_guess)
}

#[test]
fn seed_through_the_problem_layer_converges_with_named_outputs() {
    let (problem, dilation) = seed_problem();
    let mut compiled = problem.compile(PtrSettings::default()).unwrap();
    compiled.set_dilation_guess(&dilation).unwrap();
    let sol = compiled.solve().unwrap();
    eprintln!("{} after {} iterations, T = {:.4} s", sol.status, sol.iterations, sol.final_time);
    solved(&sol);
    assert!(sol.final_time <= 4.0 + 1e-9);
    // Named series, at the nodes and dense.
    for key in ["time", "angle", "velocity", "torque", "ee_position", "T_ee"] {
        assert_eq!(sol.nodes[key].len(), NODES, "{key}");
        assert!(sol.trajectory[key].len() > 100, "{key}");
    }
    assert!(!sol.nodes.keys().any(|k| k.starts_with('_')), "internal states are not exposed");
    assert_eq!(sol.nodes["T_ee"][0].len(), 16);
    assert!((sol.nodes["time"][NODES - 1][0] - sol.final_time).abs() < 1e-12);
    // The outputs evaluated from named states and controls alone (as for a retimed
    // trajectory) are the dense trajectory's; a missing or ill-shaped series is named.
    let times: Vec<f64> = sol.trajectory["time"].iter().map(|r| r[0]).collect();
    let again = compiled.layout().tables_named(&times, &sol.trajectory).unwrap();
    assert_eq!(again, sol.trajectory);
    let mut short = sol.trajectory.clone();
    short.remove("torque");
    let e = compiled.layout().tables_named(&times, &short).unwrap_err().to_string();
    assert!(e.contains("torque"), "{e}");
    short = sol.trajectory.clone();
    short.get_mut("angle").unwrap()[3].pop();
    let e = compiled.layout().tables_named(&times, &short).unwrap_err().to_string();
    assert!(e.contains("`angle` needs"), "{e}");
    // Waypoints from the ee_position output, table and limits on the dense trajectory.
    for (w, wp) in fixtures::pick_and_place().waypoints.iter().enumerate() {
        let (e, p) = (&sol.nodes["ee_position"][wp.node], wp.position);
        let d = ((e[0] - p[0]).powi(2) + (e[1] - p[1]).powi(2) + (e[2] - p[2]).powi(2)).sqrt();
        assert!(d <= 0.01 + 1e-6, "waypoint {w}: {d} m");
    }
    let (qlo, qhi) = fixtures::pick_and_place().chain.position_limits();
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
    assert!(sol.violations.iter().any(|v| v.constraint == "waypoint place"));
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
    let e = &again.nodes["ee_position"][NODES - 1];
    let d = ((e[0] - 0.30).powi(2) + (e[1] - 0.28).powi(2) + (e[2] - 0.05).powi(2)).sqrt();
    assert!(d <= 0.01 + 1e-6, "moved waypoint: {d} m");
}

#[test]
fn bad_problems_say_what_is_wrong() {
    let base = seed_problem().0;
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
    expect(p, "ball \"waypoint home\"");
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
    p.constraints[0].constraint = p.constraints[0].constraint.clone().over(2, 40);
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

#[test]
fn a_monitor_that_drops_the_cost_is_consulted_until_then_and_the_solve_ends_feasible() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use armature_scvx::{Monitor, Steer};
    let (problem, dilation) = seed_problem();
    let mut compiled = problem.compile(PtrSettings::default()).unwrap();
    compiled.set_dilation_guess(&dilation).unwrap();
    let calls = Arc::new(AtomicUsize::new(0));
    let seen = Arc::clone(&calls);
    let layout = compiled.layout().clone();
    compiled.set_monitor(Some(Monitor::new(move |it, trajectory| {
        seen.fetch_add(1, Ordering::Relaxed);
        assert_eq!(trajectory.nodes, NODES);
        // The iterate by name without its outputs: the same rows as with them.
        let (series, tables) =
            (layout.nodal_series(trajectory).unwrap(), layout.nodal_tables(trajectory).unwrap());
        assert!(!series.contains_key("ee_position") && tables.contains_key("ee_position"));
        assert!(series.iter().all(|(k, v)| tables[k] == *v), "{:?}", series.keys());
        if it.iteration >= 8 { Steer::RestoreFeasibilityOnly } else { Steer::Continue }
    })));
    let sol = compiled.solve().unwrap();
    solved(&sol);
    assert_eq!(calls.load(Ordering::Relaxed), 8, "consulted while the cost is on only");
    assert!(sol.history.iter().all(|h| h.feasibility == (h.iteration > 8)));
    assert!(sol.iterations > 8);
    // Without the monitor the next solve minimizes to the end, and further.
    compiled.set_monitor(None);
    let full = compiled.solve().unwrap();
    assert!(full.history.iter().all(|h| !h.feasibility));
    assert!(full.final_time < sol.final_time, "{} vs {}", full.final_time, sol.final_time);
}

#[test]
fn a_monitor_that_keeps_an_iterate_rewinds_to_it_when_it_drops_the_cost() {
    use armature_scvx::{Monitor, Steer};
    let (problem, dilation) = seed_problem();
    let mut compiled = problem.compile(PtrSettings::default()).unwrap();
    compiled.set_dilation_guess(&dilation).unwrap();
    let (keep, drop) = (4, 9);
    // The states of the reference after every iteration, as an observer sees them.
    let solve = |compiled: &mut armature_scvx::CompiledProblem| {
        let mut states: Vec<Vec<f64>> = Vec::new();
        let sol = compiled.solve_with(|_, t| states.push(t.x.to_vec())).unwrap();
        solved(&sol);
        (sol, states)
    };
    let distance = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>();
    compiled.set_monitor(Some(Monitor::new(move |it, _| match it.iteration {
        k if k == keep => Steer::Keep,
        k if k == drop => Steer::RestoreFeasibilityFromKept,
        _ => Steer::Continue,
    })));
    let (sol, states) = solve(&mut compiled);
    assert!(sol.history.iter().all(|h| h.feasibility == (h.iteration > drop)));
    // The first restoring step starts from iteration 4's reference, not from iteration 9's:
    // the reference after it lies nearer the kept one.
    let (kept, last, after) = (&states[keep - 1], &states[drop - 1], &states[drop]);
    assert!(distance(kept, last) > 1e-2, "the test needs the solve to move");
    assert!(distance(after, kept) < distance(after, last));
    // Without a kept iterate the same answer restores from the current reference.
    compiled.set_monitor(Some(Monitor::new(move |it, _| {
        if it.iteration == drop { Steer::RestoreFeasibilityFromKept } else { Steer::Continue }
    })));
    let (here, states) = solve(&mut compiled);
    assert!(here.history.iter().all(|h| h.feasibility == (h.iteration > drop)));
    let (last, after) = (&states[drop - 1], &states[drop]);
    assert!(distance(after, last) < distance(after, kept));
}
