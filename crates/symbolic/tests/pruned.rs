//! `Function::eval_pruned`: random trees with ReLUs, `max`/`min` and exact zeros give the
//! same values and, on the needed rows, the same Jacobian as `eval` (zero on the others);
//! and the pruning is real: an inactive penalty's operands are not differentiated.

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use armature_symbolic::{DerivativeMode, Expr, ExternalFunction, Function};
use common::Rng;
use proptest::prelude::*;

/// Inputs: enough for sparse mode to be the automatic choice as well.
const N: usize = 20;

/// A random scalar expression over `x` mixing smooth and pruning operations: ReLUs of
/// shifted subtrees (active or not depending on the point), `max`/`min`, products with an
/// exact zero, norms and a rotation (a reduction and a Lie node).
fn tree(r: &mut Rng, x: &Expr, depth: usize) -> Expr {
    if depth == 0 || r.below(5) == 0 {
        return match r.below(4) {
            0 => Expr::scalar([0.0, 0.5, -1.25][r.below(3)]),
            _ => x.at(r.below(N)),
        };
    }
    let sub = |r: &mut Rng| tree(r, x, depth - 1);
    match r.below(12) {
        0 => sub(r).sin(),
        1 => sub(r).square(),
        2 => (sub(r) - 0.3).pos(),
        3 => (sub(r) + 0.2).squared_pos(),
        4 => sub(r).tanh(),
        5 => sub(r) + sub(r),
        6 => sub(r) - sub(r),
        7 => sub(r) * sub(r),
        8 => sub(r).max(sub(r)),
        9 => sub(r).min(sub(r)),
        10 => Expr::concat(&[sub(r), sub(r), sub(r)]).norm2(),
        _ => Expr::concat(&[sub(r), sub(r), sub(r)]).so3_exp().get(r.below(3), r.below(3)),
    }
}

fn check(seed: u64, point: &[f64], mask: &[bool]) -> Result<(), TestCaseError> {
    let mut r = Rng(seed);
    let x = Expr::variable("x", N);
    let outputs: Vec<Expr> = (0..mask.len()).map(|_| tree(&mut r, &x, 5)).collect();
    for mode in [DerivativeMode::Sparse, DerivativeMode::Dense, DerivativeMode::Auto] {
        let f = Function::compile_with(&outputs, &[std::slice::from_ref(&x)], mode).unwrap();
        let nnz = f.jacobian_pattern().nnz();
        let (mut ws, mut ws2) = (f.workspace(), f.workspace());
        let (mut v, mut j) = (vec![0.0; mask.len()], vec![0.0; nnz]);
        let (mut vp, mut jp) = (vec![0.0; mask.len()], vec![f64::NAN; nnz]);
        f.eval(point, &mut ws, &mut v, Some(&mut j)).unwrap();
        // Twice on one workspace: stale derivatives from the first run must not leak.
        for needed in [None, Some(mask)] {
            f.eval_pruned(point, &mut ws2, &mut vp, &mut jp, needed).unwrap();
            prop_assert_eq!(&vp, &v);
            let p = f.jacobian_pattern();
            for c in 0..p.ncols() {
                for k in p.col_ptr()[c]..p.col_ptr()[c + 1] {
                    let row = p.row_idx()[k];
                    let want = if needed.is_none_or(|m| m[row]) { j[k] } else { 0.0 };
                    prop_assert!(
                        jp[k] == want,
                        "{mode:?} row {row} col {c}: pruned {} vs {want}",
                        jp[k]
                    );
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn pruned_jacobians_equal_full_ones_on_needed_rows(
        seed in any::<u64>(),
        point in prop::collection::vec(-1.5f64..1.5, N),
        mask in prop::collection::vec(any::<bool>(), 1..5),
    ) {
        check(seed, &point, &mask)?;
    }
}

/// `Σ xᵢ²` that counts its calls (values and local Jacobian in one call).
#[derive(Debug, Default)]
struct CountingSquares(AtomicUsize);

impl ExternalFunction for CountingSquares {
    fn name(&self) -> &str {
        "squares"
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn eval(&self, inputs: &[f64], values: &mut [f64], jacobian: &mut [f64]) {
        self.0.fetch_add(1, Ordering::Relaxed);
        values[0] = inputs.iter().map(|v| v * v).sum();
        for (j, v) in jacobian.iter_mut().zip(inputs) {
            *j = 2.0 * v;
        }
    }
}

/// A penalty `pos(‖x‖² − 1)` of an external function, next to a smooth output: while the
/// penalty is inactive, the pruned evaluation calls the external function once (its value)
/// and not again for its derivative; once active, it is differentiated (a second call) and
/// its row equals `eval`'s. The row mask skips a needed-looking path too.
#[test]
fn an_inactive_penalty_is_not_differentiated() {
    let squares = Arc::new(CountingSquares::default());
    let x = Expr::variable("x", N);
    let xs: Vec<Expr> = (0..N).map(|i| x.at(i)).collect();
    let penalty = (Expr::external(squares.clone(), &xs) - 1.0).pos();
    let f = Function::compile(&[penalty, x.at(0) * 3.0], &[std::slice::from_ref(&x)]).unwrap();
    assert!(!f.is_dense());
    let calls = || squares.0.load(Ordering::Relaxed);
    let mut ws = f.workspace();
    let (mut v, mut j) = ([0.0; 2], vec![0.0; f.jacobian_pattern().nnz()]);
    let inside = vec![0.1; N];
    f.eval_pruned(&inside, &mut ws, &mut v, &mut j, None).unwrap();
    assert_eq!(calls(), 1, "inactive: value only");
    assert_eq!(v[0], 0.0);
    assert!((v[1] - 0.3).abs() < 1e-15);
    assert_eq!(j.iter().filter(|&&e| e != 0.0).count(), 1, "only the smooth row: {j:?}");
    let outside = vec![0.5; N];
    f.eval_pruned(&outside, &mut ws, &mut v, &mut j, None).unwrap();
    assert_eq!(calls(), 3, "active: value and derivative");
    let (mut v2, mut j2) = ([0.0; 2], vec![0.0; j.len()]);
    f.eval(&outside, &mut f.workspace(), &mut v2, Some(&mut j2)).unwrap();
    assert_eq!((v, &j), (v2, &j2));
    assert_eq!(calls(), 4, "eval: one call");
    f.eval_pruned(&outside, &mut ws, &mut v, &mut j, Some(&[false, true])).unwrap();
    assert_eq!(calls(), 5, "masked row: value only");
    assert_eq!(j.iter().filter(|&&e| e != 0.0).count(), 1, "only the smooth row: {j:?}");
    let bad = f.eval_pruned(&outside, &mut ws, &mut v, &mut j, Some(&[true]));
    assert!(bad.is_err(), "a mask of the wrong length is an error");
}
