//! Weighted Hessians of random expression trees (the Jacobian suite's generator): against
//! central differences of the exact Jacobian, symmetric, with a pattern that covers every
//! numerically nonzero entry, the same in sparse and dense modes, and Hessian-vector
//! products equal to `H·v`.

mod common;

use armature_symbolic::{DerivativeMode, Expr, Function, Shape};
use common::tree::{M3, M4, V3, V4, V6, build, grow};
use common::{Rng, dense_jacobian};
use proptest::prelude::*;

/// `Σᵢ wᵢ ∂Jᵢ/∂x` by central differences of the exact Jacobian (row-major n × n; column c
/// from the differences along x_c).
fn fd_weighted_hessian(f: &Function, x: &[f64], w: &[f64], h: f64) -> Vec<f64> {
    let (n, m) = (f.n_inputs(), f.n_outputs());
    let mut out = vec![0.0; n * n];
    let mut xp = x.to_vec();
    for c in 0..n {
        xp[c] = x[c] + h;
        let (_, jp) = dense_jacobian(f, &xp);
        xp[c] = x[c] - h;
        let (_, jm) = dense_jacobian(f, &xp);
        xp[c] = x[c];
        for r in 0..n {
            out[r * n + c] =
                (0..m).map(|i| w[i] * (jp[i * n + r] - jm[i * n + r])).sum::<f64>() / (2.0 * h);
        }
    }
    out
}

/// The exact weighted Hessian (dense, full) and the values.
pub(crate) fn dense_hessian(f: &Function, x: &[f64], w: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut hws = f.hessian_workspace();
    let mut v = vec![0.0; f.n_outputs()];
    let mut h = vec![0.0; f.hessian_pattern().nnz()];
    f.eval_hessian(x, w, &mut hws, &mut v, None, &mut h).unwrap();
    (v, f.hessian_pattern().to_dense(&h))
}

fn check_tree(seed: u64, inputs: &[f64], dir: &[f64]) -> Result<(), TestCaseError> {
    let mut r = Rng(seed);
    let shape = [Shape::Scalar, V3, V4, V6, M3, M4][r.below(6)];
    let t = grow(&mut r, shape, 4);
    let x = Expr::variable("x", 4);
    let y = Expr::variable("y", 1);
    let e = build(&t, &x, &y);
    let mut reference: Option<Vec<f64>> = None;
    for mode in [DerivativeMode::Sparse, DerivativeMode::Dense] {
        let f = Function::compile_with(std::slice::from_ref(&e), &[&[x.clone(), y.clone()]], mode)
            .unwrap();
        let w: Vec<f64> = (0..f.n_outputs()).map(|_| r.f()).collect();
        let (vals, h) = dense_hessian(&f, inputs, &w);
        let fd = fd_weighted_hessian(&f, inputs, &w, 1e-6);
        let scale = h.iter().chain(&vals).fold(1.0f64, |m, v| m.max(v.abs()));
        for k in 0..25 {
            let (i, j) = (k / 5, k % 5);
            prop_assert!(
                (h[k] - fd[k]).abs() <= 1e-6 * scale,
                "H[{i},{j}] {} vs FD {}; {mode:?} tree {t:?}",
                h[k],
                fd[k]
            );
            prop_assert!((fd[k] - fd[j * 5 + i]).abs() <= 2e-6 * scale, "FD asymmetric at {k}");
            if fd[k].abs() > 1e-7 * scale {
                let (rr, cc) = (i.max(j), i.min(j));
                prop_assert!(
                    f.hessian_pattern().lower().contains(rr, cc),
                    "FD nonzero outside pattern at ({i},{j}); tree {t:?}"
                );
            }
        }
        // H·v from the product sweep equals the matrix product.
        let mut hws = f.hessian_workspace();
        let (mut v2, mut hv) = (vec![0.0; f.n_outputs()], vec![0.0; 5]);
        f.hessian_vector_product(inputs, &w, dir, &mut hws, &mut v2, &mut hv).unwrap();
        for i in 0..5 {
            let want: f64 = (0..5).map(|j| h[i * 5 + j] * dir[j]).sum();
            prop_assert!(
                (hv[i] - want).abs() <= 1e-12 * scale * 5.0,
                "Hv[{i}] {} vs {want}",
                hv[i]
            );
        }
        // Both modes agree (the weights are redrawn per mode: compare with weights fixed).
        if let Some(prev) = &reference {
            let w0: Vec<f64> = (0..f.n_outputs()).map(|i| (i as f64 * 0.7).sin()).collect();
            let (_, hd) = dense_hessian(&f, inputs, &w0);
            for (a, b) in hd.iter().zip(prev) {
                prop_assert!((a - b).abs() <= 1e-12 * scale, "dense {a} vs sparse {b}");
            }
        } else {
            let w0: Vec<f64> = (0..f.n_outputs()).map(|i| (i as f64 * 0.7).sin()).collect();
            reference = Some(dense_hessian(&f, inputs, &w0).1);
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn random_tree_hessians_match_finite_differences_of_the_jacobian(
        seed in any::<u64>(),
        inputs in prop::collection::vec(-1.5f64..1.5, 5),
        dir in prop::collection::vec(-1.0f64..1.0, 5),
    ) {
        check_tree(seed, &inputs, &dir)?;
    }
}
