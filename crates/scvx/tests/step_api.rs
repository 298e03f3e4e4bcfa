//! The step API, the observer hook, the iteration table and outcomes as data, on the
//! minimum-time double integrator.

mod double_integrator;

use armature_scvx::{
    ConstraintRef, IterationTable, Merit, NodalConstraint, NodalKind, Ocp, Ptr, PtrError,
    PtrSettings, PtrStatus, TrustRegionUpdate,
};

/// The published PTR (constant trust region, heavy virtual-control price), as in
/// `min_time.rs`: the defaults are tuned on the seed arm.
fn settings() -> PtrSettings {
    let mut s = PtrSettings::default();
    s.trust_region = TrustRegionUpdate::Constant;
    s.lam_vc = 1e2;
    s.eps_tr = 1e-4;
    s
}
use armature_symbolic::{Expr, Function};
use double_integrator::poor_guess;

/// The double integrator with its mid-course nodal constraint.
fn problem(nodes: usize) -> Ocp {
    double_integrator::problem(nodes, |p, v, a| {
        // At the middle node, position at least 0.6 (nonconvex only in form: `0.6 − p ≤ 0`).
        let args = [vec![p.clone(), v.clone()], vec![a.clone()]];
        let g = Function::compile(&[Expr::scalar(0.6) - p], &[&args[0], &args[1]]).unwrap();
        vec![NodalConstraint {
            name: "past 0.6 at mid-course".into(),
            function: g,
            nodes: vec![nodes / 2],
            kind: NodalKind::Inequality,
            output_names: Vec::new(),
        }]
    })
}

#[test]
fn stepping_by_hand_equals_solve_and_the_observer_sees_every_iteration() {
    let nodes = 21;
    let (x, u, s) = poor_guess(nodes);
    let mut ptr = Ptr::new(problem(nodes), settings()).unwrap();
    let mut seen = Vec::new();
    let mut table = Vec::new();
    IterationTable::header(&mut table).unwrap();
    let solved = ptr
        .solve_with(&x, &u, &s, |it, traj| {
            assert_eq!(traj.x.len(), nodes * 2);
            seen.push(it.iteration);
            IterationTable::row(&mut table, it).unwrap();
        })
        .unwrap();
    assert_eq!(solved.status, PtrStatus::Converged);
    assert_eq!(seen, (1..=solved.history.len()).collect::<Vec<_>>());
    let table = String::from_utf8(table).unwrap();
    assert_eq!(table.lines().count(), 1 + solved.history.len() + 1, "{table}");
    assert!(table.ends_with("SCvx loop stopped: converged\n"), "{table}");
    // The same by hand, reusing the solver.
    ptr.start(&x, &u, &s).unwrap();
    let mut last = None;
    while last.is_none() {
        last = ptr.step().unwrap().status;
    }
    assert_eq!(last, Some(PtrStatus::Converged));
    let by_hand = ptr.result().unwrap();
    assert_eq!(by_hand.x, solved.x);
    assert_eq!(by_hand.final_time, solved.final_time);
    assert_eq!(by_hand.history.len(), solved.history.len());
    // A finished solve takes no more steps.
    assert_eq!(ptr.step(), Err(PtrError::NotRunning));
    // Timings are measured and add up.
    let sum: f64 = by_hand.history.iter().map(|h| h.subproblem_ms).sum();
    assert!((sum - by_hand.timings.subproblem_ms).abs() < 1e-9 && sum > 0.0);
    assert!(by_hand.history.iter().all(|h| h.subproblem_iterations > 0));
    // The nodal constraint is met and reported with its name.
    let v = by_hand.violations.iter().find(|v| v.constraint == "past 0.6 at mid-course").unwrap();
    assert!(v.value <= 1e-6 && v.node == Some(nodes / 2));
}

#[test]
fn an_unfinished_solve_reports_what_it_still_violates() {
    let nodes = 21;
    let (x, u, s) = poor_guess(nodes);
    let r = Ptr::new(problem(nodes), {
        let mut s = settings();
        s.max_iterations = 1;
        s
    })
    .unwrap()
    .solve(&x, &u, &s)
    .unwrap();
    assert_eq!(r.status, PtrStatus::MaxIterations);
    assert_eq!(r.history.len(), 1);
    assert_eq!(r.history[0].status, Some(PtrStatus::MaxIterations));
    // The guess (no step accepted yet, or one step) is still infeasible somewhere; the worst
    // violation names a constraint that exists and is the maximum of the list.
    let worst = r.max_violation.expect("something is still violated");
    assert!(worst.value > 1e-6);
    let largest = r.violations.iter().map(|v| v.value).fold(0.0, f64::max);
    assert_eq!(worst.value, largest);
    assert!(
        matches!(worst.constraint, ConstraintRef::Dynamics { .. })
            || worst.constraint == "past 0.6 at mid-course",
        "{}",
        worst.constraint
    );
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let nodes = 11;
    let (x, u, s) = poor_guess(nodes);
    let mut ptr = Ptr::new(problem(nodes), PtrSettings::default()).unwrap();
    assert_eq!(ptr.step(), Err(PtrError::NotRunning));
    assert!(ptr.result().is_none());
    assert_eq!(
        ptr.start(&x[1..], &u, &s),
        Err(PtrError::GuessSize { what: "x", expected: 22, got: 21 })
    );
    let mut bad = u.clone();
    bad[3] = f64::NAN;
    assert_eq!(ptr.start(&x, &bad, &s), Err(PtrError::GuessNotFinite { what: "u", index: 3 }));
    for (settings, field) in [
        (
            {
                let mut s = PtrSettings::default();
                s.lam_tr = -1.0;
                s
            },
            "lam_tr",
        ),
        (
            {
                let mut s = PtrSettings::default();
                s.max_iterations = 0;
                s
            },
            "max_iterations",
        ),
        (
            {
                let mut s = PtrSettings::default();
                s.eps_tr = f64::NAN;
                s
            },
            "eps_tr",
        ),
        (
            {
                let mut s = PtrSettings::default();
                s.eps_flat = -1e-3;
                s
            },
            "eps_flat",
        ),
        (
            {
                let mut s = PtrSettings::default();
                s.merit = Merit::Lagrangian { sigma: 1.5 };
                s
            },
            "merit.lagrangian.sigma",
        ),
        (
            {
                let mut s = PtrSettings::default();
                s.subproblem.interior_point.max_iterations = 0;
                s
            },
            "subproblem.interior_point.max_iterations",
        ),
    ] {
        assert!(settings.validate().is_err());
        let err = Ptr::new(problem(nodes), settings).unwrap_err();
        match err {
            PtrError::Settings(e) => assert_eq!(e.field, field),
            other => panic!("{other:?}"),
        }
    }
    assert!(PtrSettings::default().validate().is_ok());
}

/// A problem whose parts do not fit together is refused by `Ptr::new`, naming the part,
/// before any pattern is built.
#[test]
fn a_problem_whose_parts_do_not_fit_is_refused_at_construction() {
    let nodes = 11;
    let field = |e: PtrError| match e {
        PtrError::Ocp { field, .. } => field,
        other => panic!("{other}"),
    };
    let mut ocp = problem(nodes);
    ocp.x_min.pop();
    assert_eq!(field(Ptr::new(ocp, settings()).unwrap_err()), "x_min");
    let mut ocp = problem(nodes);
    ocp.u_min[0] = 2.0;
    assert_eq!(field(Ptr::new(ocp, settings()).unwrap_err()), "u_min");
    let mut ocp = problem(nodes);
    ocp.increments.push(armature_scvx::Increment { state: 9, eps: 1e-6, first: 0, last: 4 });
    assert_eq!(field(Ptr::new(ocp, settings()).unwrap_err()), "increments[0]");
    let mut ocp = problem(nodes);
    ocp.final_cost.push((0, f64::NAN));
    assert_eq!(field(Ptr::new(ocp, settings()).unwrap_err()), "final_cost");
    let mut ocp = problem(nodes);
    ocp.nodal[0].nodes = vec![nodes];
    let e = Ptr::new(ocp, settings()).unwrap_err();
    assert!(matches!(&e, PtrError::NodalConstraint { .. }) && e.to_string().contains("beyond"));
    let mut ocp = problem(nodes);
    ocp.nodes = 1;
    assert_eq!(field(Ptr::new(ocp, settings()).unwrap_err()), "nodes");
}

#[test]
fn dropping_the_cost_ends_with_a_feasible_trajectory_and_marks_the_iterations() {
    let nodes = 21;
    let (x, u, s) = poor_guess(nodes);
    let mut ptr = Ptr::new(problem(nodes), settings()).unwrap();
    assert!(matches!(ptr.restore_feasibility_only(), Err(PtrError::NotRunning)));
    let full = ptr.solve(&x, &u, &s).unwrap();
    assert_eq!(full.status, PtrStatus::Converged);
    assert!(full.history.iter().all(|h| !h.feasibility));
    ptr.start(&x, &u, &s).unwrap();
    assert!(ptr.cost_on());
    let switch = 3;
    for _ in 0..switch {
        assert!(ptr.step().unwrap().status.is_none());
    }
    ptr.restore_feasibility_only().unwrap();
    assert!(!ptr.cost_on());
    let mut last = None;
    while last.is_none() {
        last = ptr.step().unwrap().status;
    }
    let r = ptr.result().unwrap();
    assert_eq!(r.status, PtrStatus::Converged, "{:?}", r.history.last());
    for h in &r.history {
        assert_eq!(h.feasibility, h.iteration > switch, "{h:?}");
        if h.feasibility {
            assert_eq!(h.cost, 0.0, "{h:?}");
        }
    }
    // Feasible: the dynamics close and the mid-course constraint holds.
    assert!(r.history.last().unwrap().max_defect < 1e-6);
    assert!(r.x[(nodes / 2) * 2] >= 0.6 - 1e-6);
    let end = &r.x[(nodes - 1) * 2..];
    assert!((end[0] - 1.0).abs() < 1e-6 && end[1].abs() < 1e-6, "{end:?}");
    // Minimizing stopped early: no faster than the full solve.
    assert!(r.final_time >= full.final_time - 1e-6, "{} vs {}", r.final_time, full.final_time);
    assert!(matches!(ptr.restore_feasibility_only(), Err(PtrError::NotRunning)));
    // A new start minimizes again.
    let again = ptr.solve(&x, &u, &s).unwrap();
    assert!(ptr.cost_on() && again.history.iter().all(|h| !h.feasibility));
    assert_eq!(again.final_time, full.final_time);
}

#[test]
fn restoring_feasibility_from_an_earlier_iterate_ends_near_it() {
    let nodes = 21;
    let (x, u, s) = poor_guess(nodes);
    let mut ptr = Ptr::new(problem(nodes), settings()).unwrap();
    let (xk, uk, sk) = (x.clone(), u.clone(), s.clone());
    assert!(matches!(ptr.restore_feasibility_from(&xk, &uk, &sk), Err(PtrError::NotRunning)));
    ptr.start(&x, &u, &s).unwrap();
    for _ in 0..2 {
        ptr.step().unwrap();
    }
    let t = ptr.trajectory().unwrap();
    let (xk, uk, sk, tk) = (t.x.to_vec(), t.u.to_vec(), t.s.to_vec(), t.final_time);
    for _ in 0..3 {
        assert!(ptr.step().unwrap().status.is_none());
    }
    assert_ne!(ptr.trajectory().unwrap().x, &xk[..], "the solve moved on");
    // A trajectory that does not fit is refused and the solve goes on as it was.
    let short = &xk[1..];
    assert!(matches!(
        ptr.restore_feasibility_from(short, &uk, &sk),
        Err(PtrError::GuessSize { what: "x", .. })
    ));
    let mut bad = uk.clone();
    bad[3] = f64::NAN;
    assert!(matches!(
        ptr.restore_feasibility_from(&xk, &bad, &sk),
        Err(PtrError::GuessNotFinite { what: "u", index: 3 })
    ));
    assert!(ptr.cost_on());
    ptr.restore_feasibility_from(&xk, &uk, &sk).unwrap();
    assert!(!ptr.cost_on());
    let back = ptr.trajectory().unwrap();
    assert_eq!((back.x, back.u, back.s), (&xk[..], &uk[..], &sk[..]));
    assert_eq!(back.final_time, tk);
    let mut last = None;
    while last.is_none() {
        last = ptr.step().unwrap().status;
    }
    let r = ptr.result().unwrap();
    assert_eq!(r.status, PtrStatus::Converged, "{:?}", r.history.last());
    assert!(r.history.iter().all(|h| h.feasibility == (h.iteration > 5)));
    // Feasible, as from the current reference.
    assert!(r.history.last().unwrap().max_defect < 1e-6);
    assert!(r.x[(nodes / 2) * 2] >= 0.6 - 1e-6);
    let end = &r.x[(nodes - 1) * 2..];
    assert!((end[0] - 1.0).abs() < 1e-6 && end[1].abs() < 1e-6, "{end:?}");
    // The first restoring step starts from the kept trajectory, not the last one.
    let first = r.history.iter().find(|h| h.feasibility).unwrap();
    let fifth = r.history[4].final_time;
    assert!((first.final_time - tk).abs() < (first.final_time - fifth).abs());
    assert!(matches!(ptr.restore_feasibility_from(&xk, &uk, &sk), Err(PtrError::NotRunning)));
}
