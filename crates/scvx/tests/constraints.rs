//! CTCS and nodal constraints in the PTR loop, on problems with known answers.

mod double_integrator;

use armature_scvx::{
    ConstraintRef, CtcsGroup, Dynamics, NodalConstraint, NodalKind, Ocp, Ptr, PtrSettings,
    PtrStatus, TrustRegionUpdate, ctcs_states,
};
use armature_symbolic::{Expr, Function};

/// The published PTR (constant trust region, heavy virtual-control price): these small
/// problems converge with it; the defaults are tuned on the seed arm problem.
fn published_ptr(max_iterations: usize) -> PtrSettings {
    let mut s = PtrSettings::default();
    s.max_iterations = max_iterations;
    s.trust_region = TrustRegionUpdate::Constant;
    s.lam_vc = 1e2;
    s.lam_vb = 1e2;
    s.eps_tr = 1e-4;
    s
}

/// Minimum time 0 → 1 m at rest with |a| ≤ 1 and the path constraint |v| ≤ 0.7 enforced in
/// continuous time: accelerate 0.7 s, cruise 0.51/0.7 s, brake 0.7 s: T* = 1.4 + 0.51/0.7.
#[test]
fn ctcs_velocity_limit_matches_the_analytic_minimum_time() {
    let nodes = 41;
    let p = Expr::variable("p", 1);
    let v = Expr::variable("v", 1);
    let a = Expr::variable("a", 1);
    let groups = [CtcsGroup {
        constraints: vec![&v - 0.7, -&v - 0.7],
        first: 0,
        last: nodes - 1,
        penalty: Default::default(),
    }];
    let aug = ctcs_states(&groups);
    let (y, ydot) = aug[0].clone();
    let dynamics = Dynamics::new(&[p, v.clone(), y], &[a.clone()], &[v, a, ydot], &[true])
        .unwrap()
        .gate(2, 0, nodes - 1)
        .unwrap();
    let ocp = Ocp {
        dynamics,
        nodes,
        x_min: vec![-10.0, -10.0, 0.0],
        x_max: vec![10.0, 10.0, 10.0],
        u_min: vec![-1.0],
        u_max: vec![1.0],
        x_initial: vec![Some(0.0), Some(0.0), Some(0.0)],
        x_final: vec![Some(1.0), Some(0.0), None],
        s_min: 0.1,
        s_max: 10.0,
        s_scale: None,
        final_time: (0.0, f64::INFINITY),
        time_weight: 1.0,
        final_cost: vec![],
        increments: vec![armature_scvx::Increment {
            state: 2,
            eps: 1e-6,
            first: 0,
            last: nodes - 1,
        }],
        nodal: vec![],
        interval_bounds: vec![],
        interval_bounds_sampling: armature_scvx::Sampling::Peak,
        interval_constraints: Vec::new(),
    };
    let mut ptr = Ptr::new(ocp.clone(), published_ptr(150)).unwrap();
    let x: Vec<f64> = (0..nodes).flat_map(|k| [k as f64 / (nodes - 1) as f64, 0.3, 0.0]).collect();
    let r = ptr.solve(&x, &vec![0.0; nodes], &vec![3.0; nodes]).unwrap();
    let expected = 1.4 + 0.51 / 0.7;
    eprintln!(
        "status {:?}, iterations {}, T = {} (analytic {expected})",
        r.status,
        r.history.len(),
        r.final_time
    );
    assert_eq!(r.status, PtrStatus::Converged);
    assert!((r.final_time - expected).abs() < 0.01 * expected, "T = {}", r.final_time);
    // Between nodes too: propagate each segment finely and check the speed.
    let fine = ocp.dynamics.clone();
    let mut ws = fine.workspace();
    let sub = 40;
    for k in 0..nodes - 1 {
        for j in 1..=sub {
            // Integrate segment k up to fraction j/sub with the FOH control, via a 2-node
            // discretization of the partial segment.
            let t = j as f64 / sub as f64;
            let uk = r.u[k];
            let ue = uk + t * (r.u[k + 1] - uk);
            let xs = [r.x[3 * k], r.x[3 * k + 1], r.x[3 * k + 2], 0.0, 0.0, 0.0];
            let mut out = fine.output(2);
            let settings = {
                let mut s = armature_scvx::DiscretizationSettings::default();
                s.substeps = 4;
                s
            };
            fine.discretize(
                &xs,
                &[uk, ue],
                &[r.s[k] * t / (nodes - 1) as f64, 0.0],
                &settings,
                &mut ws,
                &mut out,
            )
            .unwrap();
            // CTCS bounds the violation integral by ε = 1e-6 per segment of duration Δt: a
            // triangular violation peak of height δ has integral δ²Δt/3, so δ ≤ √(3ε/Δt).
            let dt = r.s[k] / (nodes - 1) as f64;
            let bound = (3.0 * 1e-6 / dt).sqrt();
            assert!(
                out.x_prop[1].abs() < 0.7 + bound,
                "speed {} inside segment {k} (bound {bound})",
                out.x_prop[1]
            );
        }
    }
}

/// A nodal constraint p ≤ 0.3 at the middle node holds at convergence, and costs time.
#[test]
fn nodal_constraint_holds_at_convergence() {
    let nodes = 31;
    let ocp = double_integrator::problem(nodes, |p, v, a| {
        let g = Function::compile(
            &[(p - 0.3) * (1.0 + v.square() * 0.0)],
            &[&[p.clone(), v.clone()], &[a.clone()]],
        )
        .unwrap();
        vec![NodalConstraint {
            name: "slow start".into(),
            function: g,
            nodes: vec![15],
            kind: NodalKind::Inequality,
            output_names: Vec::new(),
        }]
    });
    let mut ptr = Ptr::new(ocp, published_ptr(100)).unwrap();
    let (x, u, s) = double_integrator::poor_guess(nodes);
    let r = ptr.solve(&x, &u, &s).unwrap();
    eprintln!("status {:?}, iterations {}, T = {}", r.status, r.history.len(), r.final_time);
    assert_eq!(r.status, PtrStatus::Converged);
    assert!(r.x[15 * 2] <= 0.3 + 1e-6, "p at node 15 = {}", r.x[15 * 2]);
    assert!(r.final_time > 2.0, "the constraint costs time: {}", r.final_time);
    assert!(r.history.last().unwrap().max_violation < 1e-6);
}

/// The entries of a vector nodal constraint are reported under their names, entries that
/// share a name together; names that do not fit the constraint are refused.
#[test]
fn named_entries_of_a_nodal_constraint_are_reported_apart() {
    let nodes = 31;
    let names = ["position", "speed", "position"].map(String::from).to_vec();
    let build = |names: Vec<String>, kind: NodalKind| {
        double_integrator::problem(nodes, |p, v, a| {
            let g = Function::compile(
                &[Expr::concat(&[p - 0.3, 0.02 - v, p - 0.35])],
                &[&[p.clone(), v.clone()], &[a.clone()]],
            )
            .unwrap();
            vec![NodalConstraint {
                name: "slow middle".into(),
                function: g,
                nodes: (10..=20).collect(),
                kind,
                output_names: names,
            }]
        })
    };
    // At the straight-line guess (at rest) the middle nodes violate the position entries,
    // and the speed entry is violated by its constant −0.02 (checked at 0.02 − v).
    let mut ptr = Ptr::new(build(names, NodalKind::Inequality), published_ptr(1)).unwrap();
    let (x, u, s) = double_integrator::poor_guess(nodes);
    ptr.start(&x, &u, &s).unwrap();
    let r = ptr.result().unwrap();
    let reported: Vec<_> = r
        .violations
        .iter()
        .filter(|v| !matches!(v.constraint, ConstraintRef::Dynamics { .. }))
        .collect();
    assert_eq!(reported.len(), 2, "{reported:?}");
    assert_eq!(
        (&reported[0].constraint, &reported[1].constraint),
        (
            &ConstraintRef::Nodal { constraint: 0, name: "position".into() },
            &ConstraintRef::Nodal { constraint: 0, name: "speed".into() }
        )
    );
    // Each report is the worst of its entries over the nodes, at the trajectory returned.
    let worst = |f: &dyn Fn(f64, f64) -> f64| {
        (10..=20)
            .map(|k| (f(r.x[2 * k], r.x[2 * k + 1]).max(0.0), k))
            .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a })
    };
    let position = worst(&|p, _| (p - 0.3).max(p - 0.35));
    let speed = worst(&|_, v| 0.02 - v);
    assert!(position.0 > 0.0 && speed.0 > 0.0, "the guess violates both");
    for (report, (value, node)) in reported.iter().zip([position, speed]) {
        assert!((report.value - value).abs() < 1e-12, "{report:?} against {value}");
        assert_eq!(report.node, Some(node));
    }
    // Names for some entries only, or for a ball's entries: refused before solving.
    let short = build(vec!["position".into()], NodalKind::Inequality);
    let ball = build(["a", "b", "c"].map(String::from).to_vec(), NodalKind::Ball { radius: 0.1 });
    for ocp in [short, ball] {
        let err = Ptr::new(ocp, published_ptr(1)).unwrap_err();
        assert!(matches!(err, armature_scvx::PtrError::NodalConstraint { .. }), "{err}");
    }
}

/// Constraints that contradict each other at a node (p ≤ 0.3 and p ≥ 0.5): no step can
/// repair them, the exact penalty settles where both are violated, and the solve stops as
/// locally infeasible once the violation has stayed pinned for `infeasible_window`
/// iterations — long before the cap, the violation naming the constraint. With the test off
/// it runs to the cap.
#[test]
fn contradicting_constraints_end_locally_infeasible_before_the_cap() {
    let nodes = 31;
    let build = || {
        double_integrator::problem(nodes, |p, v, a| {
            let g =
                Function::compile(&[p - 0.3, 0.5 - p], &[&[p.clone(), v.clone()], &[a.clone()]])
                    .unwrap();
            vec![NodalConstraint {
                name: "contradiction".into(),
                function: g,
                nodes: vec![15],
                kind: NodalKind::Inequality,
                output_names: Vec::new(),
            }]
        })
    };
    let (x, u, s) = double_integrator::poor_guess(nodes);
    let settings = published_ptr(200);
    let window = settings.infeasible_window;
    let r = Ptr::new(build(), settings.clone()).unwrap().solve(&x, &u, &s).unwrap();
    eprintln!("status {:?}, iterations {}", r.status, r.history.len());
    assert_eq!(r.status, PtrStatus::LocallyInfeasible);
    assert!(r.history.len() >= window && r.history.len() < 100, "{} iterations", r.history.len());
    let worst = r.max_violation.expect("a violation is reported");
    assert!(worst.constraint.name().contains("contradiction"), "{}", worst.constraint.name());
    assert!(worst.value > 0.05, "the gap of 0.2 is shared: {}", worst.value);
    assert_eq!(r.history.last().unwrap().status, Some(PtrStatus::LocallyInfeasible));
    let mut off = settings;
    off.infeasible_window = 0;
    let r = Ptr::new(build(), off).unwrap().solve(&x, &u, &s).unwrap();
    eprintln!("without the test: status {:?}, iterations {}", r.status, r.history.len());
    assert_ne!(r.status, PtrStatus::LocallyInfeasible);
    assert_ne!(r.status, PtrStatus::Converged);
}
