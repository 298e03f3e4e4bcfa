//! Evaluation allocates nothing after compilation: a counting global allocator watches
//! repeated evaluations (values and Jacobians, sparse and dense modes, Lie nodes, norms,
//! vmap) and weighted Hessians and Hessian-vector products on this thread.

mod common;

use armature_symbolic::{DerivativeMode, Expr, Function, Norm, Shape};
use armature_testing::{Counting, allocations_during};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn evaluation_is_allocation_free() {
    let angle = Expr::variable("angle", 7);
    let extra = Expr::variable("w", 6);
    let (frames, t_ee) = common::seed_fk(&angle);
    let wp = Expr::parameter("wp", Shape::Vector(3), &[0.4, 0.1, 0.3]);
    let p_ee = t_ee.block(0, 3, 3, 4);
    let r_ee = t_ee.block(0, 3, 0, 3);
    let ts = [0.0, 0.25, 0.5, 0.75, 1.0];
    let kp = frames[3].block(0, 3, 3, 4);
    let outputs = vec![
        t_ee.clone(),
        (&p_ee - &wp).norm2(),
        (&p_ee - &wp).norm(Norm::Inf),
        (&p_ee - &wp).norm(Norm::L1),
        r_ee.so3_log(),
        t_ee.se3_log(),
        extra.se3_exp(),
        extra.slice(0, 3).so3_exp(),
        Expr::vmap(&ts, 1, |t| (&kp * (1.0 - t) + &p_ee * t - &wp).norm2()),
        angle.squared_pos().sum() + extra.pos().sum() + angle.at(0).max(extra.at(1)),
    ];
    let mut fns = Vec::new();
    for mode in [DerivativeMode::Sparse, DerivativeMode::Dense, DerivativeMode::Auto] {
        // Without the vmap (dense mode needs none), and with everything.
        fns.push(
            Function::compile_with(&outputs[..8], &[&[angle.clone(), extra.clone()]], mode)
                .unwrap(),
        );
        fns.push(
            Function::compile_with(&outputs, &[&[angle.clone(), extra.clone()]], mode).unwrap(),
        );
    }
    assert!(fns.iter().any(|f| f.is_dense()) && fns.iter().any(|f| !f.is_dense()));
    for f in &mut fns {
        let mut ws = f.workspace();
        let mut v = vec![0.0; f.n_outputs()];
        let mut jac = vec![0.0; f.jacobian_pattern().nnz()];
        let mut x: Vec<f64> = (0..13).map(|i| (i as f64 * 0.61).sin()).collect();
        let n = allocations_during(|| {
            for k in 0..100 {
                x[k % 13] += 0.01;
                f.eval(&x, &mut ws, &mut v, Some(&mut jac)).unwrap();
                f.eval(&x, &mut ws, &mut v, None).unwrap();
            }
            f.set_parameter("wp", &[0.3, 0.2, 0.1]).unwrap();
            f.eval(&x, &mut ws, &mut v, Some(&mut jac)).unwrap();
        });
        assert_eq!(n, 0, "evaluation allocated {n} times (dense = {})", f.is_dense());
        assert!(v.iter().chain(&jac).all(|x| x.is_finite()));
    }
    // Weighted Hessians and Hessian-vector products, every node kind, both modes.
    for f in &fns {
        let mut hws = f.hessian_workspace();
        let mut v = vec![0.0; f.n_outputs()];
        let mut jac = vec![0.0; f.jacobian_pattern().nnz()];
        let mut h = vec![0.0; f.hessian_pattern().nnz()];
        let mut hv = vec![0.0; f.n_inputs()];
        let w: Vec<f64> = (0..f.n_outputs()).map(|i| (i as f64 * 0.37).cos()).collect();
        let dir: Vec<f64> = (0..13).map(|i| (i as f64 * 0.23).sin()).collect();
        let mut x: Vec<f64> = (0..13).map(|i| (i as f64 * 0.61).sin()).collect();
        let n = allocations_during(|| {
            for k in 0..50 {
                x[k % 13] += 0.01;
                f.eval_hessian(&x, &w, &mut hws, &mut v, Some(&mut jac), &mut h).unwrap();
                f.eval_hessian(&x, &w, &mut hws, &mut v, None, &mut h).unwrap();
                f.hessian_vector_product(&x, &w, &dir, &mut hws, &mut v, &mut hv).unwrap();
            }
        });
        assert_eq!(n, 0, "Hessian evaluation allocated {n} times (dense = {})", f.is_dense());
        assert!(h.iter().chain(&hv).all(|x| x.is_finite()));
        assert!(h.iter().any(|x| *x != 0.0));
    }
    // The counter does see allocations (the test can fail).
    assert!(allocations_during(|| drop(std::hint::black_box(vec![1u8; 64]))) > 0);
}
