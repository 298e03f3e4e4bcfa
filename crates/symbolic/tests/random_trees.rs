//! Random expression trees over random shapes: tape values equal an independent direct
//! evaluation, tape Jacobians equal central finite differences, the sparsity pattern covers
//! every numerically nonzero entry, and the sparse and dense derivative modes agree.

mod common;

use armature_lie::{SE3, SO3};
use armature_symbolic::{DerivativeMode, Expr, Function, Shape};
use common::tree::{B, M3, M4, T, U, V3, V4, V6, build, grow};
use common::{Rng, dense_jacobian, fd_jacobian};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector6};
use proptest::prelude::*;

/// Direct evaluation: row-major values and the shape.
fn eval(t: &T, x: &[f64], y: f64) -> (Vec<f64>, Shape) {
    let ev = |t: &T| eval(t, x, y);
    let un = |u: &U, v: f64| match u {
        U::Neg => -v,
        U::Sin => v.sin(),
        U::Cos => v.cos(),
        U::Tanh => v.tanh(),
        U::Square => v * v,
        U::ExpTanh => v.tanh().exp(),
        U::SqrtOnePlusSq => (v * v + 1.0).sqrt(),
        U::LogOnePlusSq => (v * v + 1.0).ln(),
    };
    let m3 = |v: &[f64]| Matrix3::from_row_slice(v);
    let m4 = |v: &[f64]| Matrix4::from_row_slice(v);
    let rows3 = |m: Matrix3<f64>| (0..9).map(|e| m[(e / 3, e % 3)]).collect::<Vec<_>>();
    let rows4 = |m: Matrix4<f64>| (0..16).map(|e| m[(e / 4, e % 4)]).collect::<Vec<_>>();
    match t {
        T::X => (x.to_vec(), V4),
        T::Y => (vec![y], Shape::Scalar),
        T::Const(s, d) => (d.clone(), *s),
        T::Un(u, a) => {
            let (v, s) = ev(a);
            (v.iter().map(|&q| un(u, q)).collect(), s)
        }
        T::Bin(op, a, b) => {
            let ((va, sa), (vb, _)) = (ev(a), ev(b));
            let out = (0..va.len())
                .map(|k| {
                    let (p, q) = (va[k], if vb.len() == 1 { vb[0] } else { vb[k] });
                    match op {
                        B::Add => p + q,
                        B::Sub => p - q,
                        B::Mul => p * q,
                        B::DivOnePlusSq => p / (q * q + 1.0),
                    }
                })
                .collect();
            (out, sa)
        }
        T::MatMul(a, b) => {
            let ((va, sa), (vb, sb)) = (ev(a), ev(b));
            let (r, k) = if let Shape::Vector(n) = sa { (1, n) } else { (sa.rows(), sa.cols()) };
            let c = if let Shape::Vector(_) = sb { 1 } else { sb.cols() };
            let mut out = vec![0.0; r * c];
            for i in 0..r {
                for j in 0..c {
                    out[i * c + j] = (0..k).map(|l| va[i * k + l] * vb[l * c + j]).sum();
                }
            }
            let shape = match (sa, sb) {
                (Shape::Vector(_), Shape::Vector(_)) => Shape::Scalar,
                (Shape::Matrix(..), Shape::Vector(_)) => Shape::Vector(r),
                _ => Shape::Matrix(r, c),
            };
            (out, shape)
        }
        T::Sum(a) => (vec![ev(a).0.iter().sum()], Shape::Scalar),
        T::Norm2(a) => {
            (vec![ev(a).0.iter().map(|v| (v + 2.0).powi(2)).sum::<f64>().sqrt()], Shape::Scalar)
        }
        T::Dot(a, b) => {
            (vec![ev(a).0.iter().zip(ev(b).0).map(|(p, q)| p * q).sum()], Shape::Scalar)
        }
        T::Cross(a, b) => {
            let (p, q) =
                (Vector3::from_column_slice(&ev(a).0), Vector3::from_column_slice(&ev(b).0));
            (p.cross(&q).iter().copied().collect(), V3)
        }
        T::Index(a, i) => (vec![ev(a).0[*i]], Shape::Scalar),
        T::Slice3(a) => (ev(a).0[..3].to_vec(), V3),
        T::Concat(v) => {
            let d: Vec<f64> = v.iter().flat_map(|t| ev(t).0).collect();
            let n = d.len();
            (d, Shape::Vector(n))
        }
        T::Transpose(a) => {
            let (v, s) = ev(a);
            let (r, c) = (s.rows(), s.cols());
            ((0..r * c).map(|e| v[(e % r) * c + e / r]).collect(), Shape::Matrix(c, r))
        }
        T::Block(a) => {
            let v = ev(a).0;
            ((0..9).map(|e| v[(e / 3) * 4 + e % 3]).collect(), M3)
        }
        T::Column(a) => {
            let v = ev(a).0;
            (vec![v[3], v[7], v[11]], V3)
        }
        T::Quat(a) => {
            let q = ev(a).0;
            let uq = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                q[0] + 2.0,
                q[1],
                q[2],
                q[3],
            ));
            (rows3(uq.to_rotation_matrix().into_inner()), M3)
        }
        T::So3Exp(a) => (rows3(SO3::exp(&Vector3::from_column_slice(&ev(a).0)).matrix()), M3),
        T::So3LogExp(a) => {
            let w = Vector3::from_column_slice(&ev(a).0).map(f64::tanh);
            (
                SO3::from_matrix_unchecked(&m3(&rows3(SO3::exp(&w).matrix())))
                    .log()
                    .iter()
                    .copied()
                    .collect(),
                V3,
            )
        }
        T::Se3Exp(a) => (rows4(SE3::exp(&Vector6::from_column_slice(&ev(a).0)).matrix()), M4),
        T::Se3LogExp(a) => {
            let xi = Vector6::from_column_slice(&ev(a).0).map(f64::tanh);
            (
                SE3::from_matrix(&m4(&rows4(SE3::exp(&xi).matrix())))
                    .unwrap()
                    .log()
                    .iter()
                    .copied()
                    .collect(),
                V6,
            )
        }
        T::Screw(s, a) => {
            let th = ev(a).0[0];
            (rows4(SE3::exp(&(Vector6::from_column_slice(s) * th)).matrix()), M4)
        }
    }
}

fn check_tree(seed: u64, inputs: &[f64]) -> Result<(), TestCaseError> {
    let mut r = Rng(seed);
    let shape = [Shape::Scalar, V3, V4, V6, M3, M4][r.below(6)];
    let t = grow(&mut r, shape, 4);
    let x = Expr::variable("x", 4);
    let y = Expr::variable("y", 1);
    let e = build(&t, &x, &y);
    prop_assert_eq!(e.shape().unwrap(), shape, "{:?}", t);
    let (reference, _) = eval(&t, &inputs[..4], inputs[4]);
    let scale = reference.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    for mode in [DerivativeMode::Sparse, DerivativeMode::Dense] {
        let f = Function::compile_with(std::slice::from_ref(&e), &[&[x.clone(), y.clone()]], mode)
            .unwrap();
        let (vals, jac) = dense_jacobian(&f, inputs);
        for (k, (a, b)) in vals.iter().zip(&reference).enumerate() {
            prop_assert!(
                (a - b).abs() <= 1e-10 * scale,
                "value {k}: tape {a} vs direct {b}; tree {t:?}"
            );
        }
        let fd = fd_jacobian(&f, inputs, 1e-6);
        let jscale = jac.iter().fold(scale, |m, v| m.max(v.abs()));
        for (k, (a, d)) in jac.iter().zip(&fd).enumerate() {
            prop_assert!(
                (a - d).abs() <= 1e-6 * jscale,
                "jac entry {k}: {a} vs FD {d}; tree {t:?}"
            );
            if d.abs() > 1e-7 * jscale {
                prop_assert!(
                    f.jacobian_pattern().contains(k / 5, k % 5),
                    "FD nonzero outside pattern at {k}"
                );
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    #[test]
    fn random_trees_match_direct_evaluation_and_finite_differences(
        seed in any::<u64>(),
        inputs in prop::collection::vec(-1.5f64..1.5, 5),
    ) {
        check_tree(seed, &inputs)?;
    }
}
