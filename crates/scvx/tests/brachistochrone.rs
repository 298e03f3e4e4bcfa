//! Analytic reference: the brachistochrone. A bead released at rest at the origin reaches
//! (x_f, y_f) (y downward) fastest along a cycloid x = R(φ − sin φ), y = R(1 − cos φ), in
//! T = φ_f·√(R/g), with φ_f solving (φ − sin φ)/(1 − cos φ) = x_f/y_f.

use armature_scvx::{
    CorrectionSolve, Dynamics, Merit, Ocp, Ptr, PtrSettings, PtrStatus, SubproblemSolver,
};
use armature_symbolic::Expr;

const G: f64 = 9.81;

fn analytic(xf: f64, yf: f64) -> f64 {
    let f = |p: f64| (p - p.sin()) / (1.0 - p.cos()) - xf / yf;
    let (mut lo, mut hi) = (1e-6, 2.0 * std::f64::consts::PI - 1e-6);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let phi = 0.5 * (lo + hi);
    let r = yf / (1.0 - phi.cos());
    phi * (r / G).sqrt()
}

#[test]
fn brachistochrone_matches_the_cycloid() {
    check(|_| {});
}

/// The same with the quasi-Newton model and the Lagrangian merit.
#[test]
fn brachistochrone_matches_the_cycloid_with_quasi_newton() {
    check(|s| {
        s.quasi_newton = true;
        s.merit = Merit::Lagrangian { sigma: 0.5 };
    });
}

/// The same with the exact Hessian of the Lagrangian (the dynamics' second-order adjoint)
/// and the Lagrangian merit.
#[test]
fn brachistochrone_matches_the_cycloid_with_the_exact_hessian() {
    check(|s| {
        s.exact_hessian = true;
        s.merit = Merit::Lagrangian { sigma: 0.5 };
    });
}

/// The same with the second-order correction of the steps the exact Hessian's model
/// predicts well but whose defects spoil the ratio (exact-penalty merit).
/// Each way to the corrected step: a second solve, the step's factorization alone, and the
/// factorization with a second solve where it fails (the default).
#[test]
fn brachistochrone_matches_the_cycloid_with_second_order_corrections() {
    for how in
        [CorrectionSolve::Resolve, CorrectionSolve::Factorization, CorrectionSolve::default()]
    {
        let corrected = check(|s| {
            s.exact_hessian = true;
            s.second_order_correction = true;
            s.correction_solve = how;
        });
        assert!(corrected > 0, "{how:?}: no step was corrected: the test would not test it");
    }
}

/// The same with every subproblem solved by Clarabel (whose solver object a second solve
/// must not reuse as it was left: updated in place it does not reproduce its results).
#[test]
fn brachistochrone_matches_the_cycloid_with_clarabel() {
    check(|s| s.subproblem.solver = SubproblemSolver::Clarabel);
}

/// Solves with the default settings (200 iterations at most) as `change` leaves them; how
/// many steps the second-order correction replaced.
fn check(change: impl FnOnce(&mut PtrSettings)) -> usize {
    let mut settings = PtrSettings::default();
    settings.max_iterations = 200;
    change(&mut settings);
    let (xf, yf) = (1.0, 0.6);
    let nodes = 31;
    let pos = Expr::variable("pos", 2);
    let v = Expr::variable("v", 1);
    let th = Expr::variable("theta", 1);
    // θ is the direction of motion from the downward vertical.
    let rhs = Expr::concat(&[&v * th.sin(), &v * th.cos()]);
    let vdot = th.cos() * G;
    let dynamics = Dynamics::new(&[pos, v], &[th], &[rhs, vdot], &[true]).unwrap();
    let ocp = Ocp {
        dynamics,
        nodes,
        x_min: vec![-1.0, -1.0, 0.0],
        x_max: vec![2.0, 2.0, 10.0],
        u_min: vec![0.0],
        u_max: vec![std::f64::consts::PI],
        x_initial: vec![Some(0.0), Some(0.0), Some(0.0)],
        x_final: vec![Some(xf), Some(yf), None],
        s_min: 0.05,
        s_max: 5.0,
        s_scale: None,
        final_time: (0.0, f64::INFINITY),
        time_weight: 1.0,
        final_cost: vec![],
        increments: vec![],
        nodal: vec![],
        interval_bounds: vec![],
        interval_bounds_sampling: armature_scvx::Sampling::Peak,
        interval_constraints: Vec::new(),
    };
    let mut ptr = Ptr::new(ocp, settings).unwrap();
    // Guess: straight line at 45°, speed growing, 1 s.
    let x: Vec<f64> = (0..nodes)
        .flat_map(|k| {
            let t = k as f64 / (nodes - 1) as f64;
            [xf * t, yf * t, (2.0 * G * yf * t).sqrt()]
        })
        .collect();
    let r = ptr.solve(&x, &vec![1.0; nodes], &vec![1.0; nodes]).unwrap();
    // A second solve of the same problem by the same solver is the same, to the last bit.
    let again = ptr.solve(&x, &vec![1.0; nodes], &vec![1.0; nodes]).unwrap();
    assert_eq!((again.history.len(), again.x.clone()), (r.history.len(), r.x.clone()));
    let expected = analytic(xf, yf);
    eprintln!(
        "status {:?}, iterations {}, T = {} (cycloid {expected})",
        r.status,
        r.history.len(),
        r.final_time
    );
    assert_eq!(r.status, PtrStatus::Converged);
    assert!(
        (r.final_time - expected).abs() < 0.01 * expected,
        "T = {} vs {expected}",
        r.final_time
    );
    // Energy: v = √(2 g y) along the way (no friction), a check of the dynamics integration.
    for k in 0..nodes {
        let (y, v) = (r.x[k * 3 + 1], r.x[k * 3 + 2]);
        assert!((v - (2.0 * G * y.max(0.0)).sqrt()).abs() < 1e-3, "node {k}: v = {v}, y = {y}");
    }
    r.history.iter().filter(|it| it.corrected).count()
}
