//! A model that cannot be solved is refused at compile time, naming the part: dynamics that
//! evaluate to NaN or ∞ at the guess, a constraint that reads no variable and never holds.

use armature_scvx::{Control, Problem, ProblemError, PtrSettings, State, Time};
use armature_symbolic::Expr;

fn problem(dv: impl Fn(&Expr, &Expr) -> Expr) -> Problem {
    let p = State::new("p", 1).initial_value(&[0.0]).final_value(&[1.0]);
    let v = State::new("v", 1).bounds(&[-10.0], &[10.0]).initial_value(&[0.0]).final_value(&[0.0]);
    let a = Control::new("a", 1).bounds(&[-1.0], &[1.0]);
    Problem {
        dynamics: vec![v.expr(), dv(&v.expr(), &a.expr())],
        states: vec![p, v],
        controls: vec![a],
        time: Time::Free { min: 0.0, max: 10.0, guess: 3.0, minimize: true },
        ..Problem::new(11)
    }
}

fn refused(p: Problem) -> String {
    match p.compile(PtrSettings::default()) {
        Err(e @ ProblemError::Bad { .. }) => e.to_string(),
        Err(other) => panic!("another error: {other}"),
        Ok(_) => panic!("compiled"),
    }
}

#[test]
fn dynamics_that_are_not_finite_at_the_guess_are_named() {
    let e = refused(problem(|_, a| a / &Expr::scalar(0.0)));
    assert!(e.contains("dynamics of v") && e.contains("node 0"), "{e}");
    let e = refused(problem(|v, a| &(v - 1.0).sqrt() + a));
    assert!(e.contains("dynamics of v") && e.contains("NaN"), "{e}");
    // Finite dynamics compile.
    assert!(problem(|_, a| a.clone()).compile(PtrSettings::default()).is_ok());
}

#[test]
fn a_constraint_on_no_variable_that_never_holds_is_refused() {
    let mut p = problem(|_, a| a.clone());
    p.constraints.push(Expr::scalar(2.0).le(1.0).at(&[3]).named("two below one").into());
    let e = refused(p);
    assert!(e.contains("two below one") && e.contains("never holds"), "{e}");
    let mut p = problem(|_, a| a.clone());
    p.constraints.push(Expr::scalar(2.0).le(1.0).ctcs().named("always broken").into());
    assert!(refused(p).contains("always broken"));
    // A constant constraint that holds is harmless.
    let mut p = problem(|_, a| a.clone());
    p.constraints.push(Expr::scalar(0.0).le(1.0).at(&[3]).named("holds").into());
    assert!(p.compile(PtrSettings::default()).is_ok());
}

#[test]
fn what_sizes_memory_is_capped_with_the_setting_named() {
    let mut p = problem(|_, a| a.clone());
    p.time = Time::Free { min: 0.0, max: 1e9, guess: 3.0, minimize: true };
    let e = refused(p);
    assert!(e.contains("dense_dt") && e.contains("200000"), "{e}");
    let mut settings = PtrSettings::default();
    settings.dense_dt = 1e-9;
    let e = problem(|_, a| a.clone()).compile(settings).err().unwrap().to_string();
    assert!(e.contains("dense_dt"), "{e}");
    let p = Problem { nodes: armature_scvx::MAX_NODES + 1, ..problem(|_, a| a.clone()) };
    assert!(refused(p).contains("nodes"));
    // A maximum so long that 5·max overflows: the samples it would take, not a NaN bound.
    let mut p = problem(|_, a| a.clone());
    p.time = Time::Free { min: 0.0, max: 1e308, guess: 3.0, minimize: true };
    let e = refused(p);
    assert!(e.contains("time") && e.contains("samples"), "{e}");
    // Integration steps: per segment, and over the whole horizon.
    let mut settings = PtrSettings::default();
    settings.discretization.substeps = armature_scvx::MAX_SUBSTEPS + 1;
    let e = problem(|_, a| a.clone()).compile(settings).err().unwrap().to_string();
    assert!(e.contains("substeps"), "{e}");
    let mut settings = PtrSettings::default();
    settings.discretization.substeps = armature_scvx::MAX_SUBSTEPS;
    let p = Problem { nodes: armature_scvx::MAX_NODES, ..problem(|_, a| a.clone()) };
    let e = p.compile(settings).err().unwrap().to_string();
    assert!(e.contains("substeps") && e.contains("200000"), "{e}");
}

/// The subproblem's KKT factor grows linearly with the nodes: the final-time bounds, a row
/// over every segment's dilation, keep rows of their own instead of joining every dilation
/// into one clique (quadratic in the nodes, which took 240 MB and 9 s for one iteration at
/// 1,000 nodes).
#[test]
fn the_kkt_factor_grows_linearly_with_the_nodes() {
    let factor = |nodes: usize| {
        let p = Problem { nodes, ..problem(|_, a| a.clone()) };
        let mut compiled = p.compile(PtrSettings::default()).expect("compiles");
        compiled.ptr().dimensions().reduced_kkt_nonzeros.expect("interior point").1
    };
    let (small, large) = (factor(200), factor(armature_scvx::MAX_NODES));
    let ratio = large as f64 / small as f64;
    let nodes = armature_scvx::MAX_NODES as f64 / 200.0;
    assert!(ratio < 1.2 * nodes, "factor nonzeros {small} → {large}: ×{ratio:.1} for ×{nodes}");
}
