//! A time-scaled control through the named problem layer: its bounds, guess and solution stay
//! in physical units, `Solution::control_ends` holds where each segment ends, and what would
//! read the solver's variable instead of the control is refused.

use armature_scvx::{Control, Problem, ProblemConstraint, PtrSettings, PtrStatus, State, Time};

/// 1 m from rest to rest with |a| ≤ 1 m/s² in minimum time (bang–bang, T* = 2 s), the
/// acceleration time-scaled.
fn double_integrator(nodes: usize) -> Problem {
    let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]).with_time_scaling();
    Problem {
        dynamics: vec![v.expr(), a.expr()],
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(nodes)
    }
}

#[test]
fn the_solution_holds_physical_controls_and_where_each_segment_ends() {
    let nodes = 21;
    let mut compiled = double_integrator(nodes).compile(PtrSettings::default()).unwrap();
    // A physical guess: 0.5 m/s² everywhere.
    compiled.set_guess("a", &[0.5; 21]).unwrap();
    let sol = compiled.solve().unwrap();
    assert_eq!(sol.status, PtrStatus::Converged, "{:?}", sol.max_violation);
    assert!(sol.final_time > 2.0 - 1e-6 && sol.final_time < 2.02, "{}", sol.final_time);
    let (starts, ends) = (&sol.nodes["a"], &sol.control_ends["a"]);
    assert_eq!((starts.len(), ends.len()), (nodes, nodes - 1));
    // Physical: within the bounds at both ends of every segment, riding them.
    let all = starts.iter().chain(ends).map(|r| r[0]);
    let largest = all.fold(0.0f64, |m, a| m.max(a.abs()));
    assert!(largest <= 1.0 + 1e-7 && largest > 1.0 - 1e-6, "{largest}");
    // The dense trajectory's controls are the same line on each segment: at a segment's
    // last sample, its end.
    let (t, a) = (&sol.trajectory["time"], &sol.trajectory["a"]);
    let node_t: Vec<f64> = sol.nodes["time"].iter().map(|r| r[0]).collect();
    for k in 0..nodes - 1 {
        let last = t.iter().rposition(|r| r[0] <= node_t[k + 1] + 1e-12).unwrap();
        assert!((a[last][0] - ends[k][0]).abs() < 1e-9, "segment {k}");
    }
    // A warm start from the result reproduces it (the guess is physical again).
    let r = compiled.last_result().unwrap();
    compiled.warm_start(&r).unwrap();
    assert_eq!(compiled.guess().1[0], starts[0][0]);
}

#[test]
fn a_nodal_constraint_on_a_time_scaled_control_is_refused_by_name() {
    let mut problem = double_integrator(11);
    let a = problem.controls[0].expr();
    problem.constraints.push(ProblemConstraint::from((a.clone() * a).le(0.5).named("gentle")));
    let e = problem.compile(PtrSettings::default()).unwrap_err().to_string();
    assert!(e.contains("gentle") && e.contains("time-scaled"), "{e}");
}
