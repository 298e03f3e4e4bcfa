//! The seed tutorial's forward kinematics through the tape: values against armature-lie,
//! Jacobian against central differences, and the cost of the PoE fast path.

mod common;

use armature_lie::SE3;
use armature_symbolic::{DerivativeMode, Expr, Function};
use common::*;
use nalgebra::{Vector3, Vector6};

fn numeric_fk(q: &[f64]) -> (Vec<SE3>, SE3) {
    let s = screws();
    let mut chain = SE3::identity();
    let mut frames = Vec::new();
    let mut j = 0;
    for after in [0, 1, 2, 4, 7] {
        while j < after {
            chain = chain * SE3::exp(&(Vector6::from_column_slice(&s[j]) * q[j]));
            j += 1;
        }
        frames.push(chain);
    }
    let ee = chain * SE3::from_translation(Vector3::new(A2 + A3 + A4, 0.0, D1));
    (frames, ee)
}

fn compiled_with(mode: DerivativeMode) -> Function {
    let angle = Expr::variable("angle", 7);
    let (frames, t_ee) = seed_fk(&angle);
    let mut outs = frames;
    outs.push(t_ee);
    Function::compile_with(&outs, &[&[angle]], mode).unwrap()
}

fn compiled() -> Function {
    compiled_with(DerivativeMode::Auto)
}

#[test]
fn values_match_numeric_fk() {
    let f = compiled();
    let mut ws = f.workspace();
    let mut v = vec![0.0; f.n_outputs()];
    for k in 0..50 {
        let q: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.7351).sin() * 2.5).collect();
        f.eval(&q, &mut ws, &mut v, None).unwrap();
        let (frames, ee) = numeric_fk(&q);
        for (fi, t) in frames.iter().chain([&ee]).enumerate() {
            let m = t.matrix();
            for e in 0..16 {
                let got = v[fi * 16 + e];
                assert!((got - m[(e / 4, e % 4)]).abs() < 1e-12, "frame {fi} entry {e}: {got}");
            }
        }
    }
}

#[test]
fn jacobian_matches_finite_differences_and_pattern_is_tight() {
    let f = compiled();
    assert!(f.is_dense(), "7 inputs compile to dense rows under Auto");
    let sparse = compiled_with(DerivativeMode::Sparse);
    assert!(!sparse.is_dense());
    for k in 0..20 {
        let q: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.513).sin() * 2.0).collect();
        let (v1, j1) = dense_jacobian(&f, &q);
        let (v2, j2) = dense_jacobian(&sparse, &q);
        for (a, b) in v1.iter().zip(&v2).chain(j1.iter().zip(&j2)) {
            assert!((a - b).abs() < 1e-14, "modes disagree");
        }
    }
    for f in [&f, &sparse] {
        for k in 0..20 {
            let q: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 1.913).cos() * 2.0).collect();
            let (err, covered) = check_against_fd(f, &q, 1e-6);
            assert!(err < 1e-7, "rel err {err}");
            assert!(covered);
        }
    }
    let p = f.jacobian_pattern();
    // The base frame is constant; the shoulder frame depends on joint 1 only; the bottom
    // rows of every frame are constant.
    for c in 0..7 {
        for e in 0..16 {
            assert!(!p.contains(e, c), "base frame entry {e} depends on joint {c}");
        }
        for fr in 0..6 {
            for e in 12..16 {
                assert!(!p.contains(fr * 16 + e, c));
            }
        }
    }
    for e in 0..16 {
        for c in 1..7 {
            assert!(!p.contains(16 + e, c), "shoulder depends only on joint 1");
        }
    }
    // Frame after joint 2 (elbow) never depends on joints 3..7.
    for e in 0..16 {
        for c in 2..7 {
            assert!(!p.contains(32 + e, c));
        }
    }
}

#[test]
fn poe_fast_path_folds_constants() {
    let f = compiled();
    // Seven joint exponentials and five products of 4×4 matrices would be thousands of
    // scalar operations without folding; with it the tape stays small.
    assert!(f.instruction_count() < 400, "{} instructions", f.instruction_count());
}
