//! Random expression trees over random shapes: tape values equal an independent direct
//! evaluation, tape Jacobians equal central finite differences, the sparsity pattern covers
//! every numerically nonzero entry, and the sparse and dense derivative modes agree.

mod common;

use armature_lie::{SE3, SO3};
use armature_symbolic::{DerivativeMode, Expr, Function, Shape};
use common::{Rng, dense_jacobian, fd_jacobian};
use nalgebra::{Matrix3, Matrix4, Vector3, Vector6};
use proptest::prelude::*;

/// A test-side expression tree that can build an `Expr` and evaluate itself directly.
#[derive(Debug, Clone)]
enum T {
    X, // vector(4) variable
    Y, // scalar variable
    Const(Shape, Vec<f64>),
    Un(U, Box<T>),
    Bin(B, Box<T>, Box<T>), // same shape, or scalar right operand
    MatMul(Box<T>, Box<T>),
    Sum(Box<T>),
    Norm2(Box<T>), // of (v + 2): away from the origin
    Dot(Box<T>, Box<T>),
    Cross(Box<T>, Box<T>),
    Index(Box<T>, usize),
    Slice3(Box<T>), // first three entries of a vector(4)
    Concat(Vec<T>),
    Transpose(Box<T>),
    Block(Box<T>),  // [0:3, 0:3] of a 4×4
    Column(Box<T>), // [0:3, 3] of a 4×4
    Quat(Box<T>),   // quat_to_matrix of a vector(4) + [2, 0, 0, 0]
    So3Exp(Box<T>),
    So3LogExp(Box<T>), // so3_log(so3_exp(tanh v)): |ω| < π
    Se3Exp(Box<T>),
    Se3LogExp(Box<T>),       // se3_log(se3_exp(tanh ξ))
    Screw([f64; 6], Box<T>), // se3_exp(const_screw * scalar): the PoE fast path
}

#[derive(Debug, Clone, Copy)]
enum U {
    Neg,
    Sin,
    Cos,
    Tanh,
    Square,
    ExpTanh,
    SqrtOnePlusSq,
    LogOnePlusSq,
}

#[derive(Debug, Clone, Copy)]
enum B {
    Add,
    Sub,
    Mul,
    DivOnePlusSq, // a / (1 + b²)
}

const V3: Shape = Shape::Vector(3);
const V4: Shape = Shape::Vector(4);
const V6: Shape = Shape::Vector(6);
const M3: Shape = Shape::Matrix(3, 3);
const M4: Shape = Shape::Matrix(4, 4);

fn grow(r: &mut Rng, shape: Shape, depth: usize) -> T {
    let leafy = depth == 0 || r.below(4) == 0;
    let b = |t: T| Box::new(t);
    match shape {
        Shape::Scalar => {
            if leafy {
                return match r.below(3) {
                    0 => T::Y,
                    1 => T::Index(b(T::X), r.below(4)),
                    _ => T::Const(Shape::Scalar, vec![r.f()]),
                };
            }
            match r.below(8) {
                0 => T::Sum(b(grow(r, V4, depth - 1))),
                1 => T::Norm2(b(grow(r, V3, depth - 1))),
                2 => T::Dot(b(grow(r, V3, depth - 1)), b(grow(r, V3, depth - 1))),
                3 => T::Index(b(grow(r, V6, depth - 1)), r.below(6)),
                4 => T::Un(unary(r), b(grow(r, Shape::Scalar, depth - 1))),
                5 => T::Bin(
                    binary(r),
                    b(grow(r, Shape::Scalar, depth - 1)),
                    b(grow(r, Shape::Scalar, depth - 1)),
                ),
                6 => T::MatMul(b(grow(r, V3, depth - 1)), b(grow(r, V3, depth - 1))),
                _ => T::Index(b(T::Column(b(grow(r, M4, depth - 1)))), r.below(3)),
            }
        }
        Shape::Vector(4) => {
            if leafy {
                return if r.below(3) == 0 {
                    T::Const(V4, (0..4).map(|_| r.f()).collect())
                } else {
                    T::X
                };
            }
            match r.below(4) {
                0 => T::Un(unary(r), b(grow(r, V4, depth - 1))),
                1 => {
                    let rs = if r.below(2) == 0 { V4 } else { Shape::Scalar };
                    T::Bin(binary(r), b(grow(r, V4, depth - 1)), b(grow(r, rs, depth - 1)))
                }
                2 => T::Concat(vec![grow(r, V3, depth - 1), grow(r, Shape::Scalar, depth - 1)]),
                _ => T::MatMul(b(grow(r, M4, depth - 1)), b(grow(r, V4, depth - 1))),
            }
        }
        Shape::Vector(3) => {
            if leafy {
                return T::Slice3(b(T::X));
            }
            match r.below(8) {
                0 => T::Cross(b(grow(r, V3, depth - 1)), b(grow(r, V3, depth - 1))),
                1 => T::MatMul(b(grow(r, M3, depth - 1)), b(grow(r, V3, depth - 1))),
                2 => T::Un(unary(r), b(grow(r, V3, depth - 1))),
                3 => {
                    let rs = if r.below(2) == 0 { V3 } else { Shape::Scalar };
                    T::Bin(binary(r), b(grow(r, V3, depth - 1)), b(grow(r, rs, depth - 1)))
                }
                4 => T::So3LogExp(b(grow(r, V3, depth - 1))),
                5 => T::Column(b(grow(r, M4, depth - 1))),
                6 => T::Slice3(b(grow(r, V4, depth - 1))),
                _ => T::Concat((0..3).map(|_| grow(r, Shape::Scalar, depth - 1)).collect()),
            }
        }
        Shape::Vector(6) => match if leafy { 0 } else { r.below(3) } {
            0 => T::Concat(vec![T::Slice3(b(T::X)), grow(r, V3, depth.saturating_sub(1))]),
            1 => T::Se3LogExp(b(grow(r, V6, depth - 1))),
            _ => T::Un(unary(r), b(grow(r, V6, depth - 1))),
        },
        Shape::Matrix(3, 3) => match if leafy { r.below(2) } else { r.below(6) } {
            0 => T::So3Exp(b(grow(r, V3, depth.saturating_sub(1)))),
            1 => T::Quat(b(if leafy { T::X } else { grow(r, V4, depth - 1) })),
            2 => T::MatMul(b(grow(r, M3, depth - 1)), b(grow(r, M3, depth - 1))),
            3 => T::Transpose(b(grow(r, M3, depth - 1))),
            4 => T::Block(b(grow(r, M4, depth - 1))),
            _ => T::Bin(binary(r), b(grow(r, M3, depth - 1)), b(grow(r, Shape::Scalar, depth - 1))),
        },
        Shape::Matrix(4, 4) => match if leafy { 0 } else { r.below(4) } {
            0 => {
                let mut s = [0.0; 6];
                // Revolute (unit or scaled axis) or prismatic screws, with structural zeros.
                match r.below(3) {
                    0 => s = [r.f(), 0.0, r.f(), 0.0, 1.0, 0.0],
                    1 => s = [0.0, r.f(), 0.0, 0.6, 0.0, 0.8 * (1.0 + r.f())],
                    _ => s[r.below(3)] = r.f(),
                }
                T::Screw(s, b(if leafy { T::Y } else { grow(r, Shape::Scalar, depth - 1) }))
            }
            1 => T::Se3Exp(b(grow(r, V6, depth - 1))),
            2 => T::MatMul(b(grow(r, M4, depth - 1)), b(grow(r, M4, depth - 1))),
            _ => T::Transpose(b(grow(r, M4, depth - 1))),
        },
        _ => unreachable!(),
    }
}

fn unary(r: &mut Rng) -> U {
    [U::Neg, U::Sin, U::Cos, U::Tanh, U::Square, U::ExpTanh, U::SqrtOnePlusSq, U::LogOnePlusSq]
        [r.below(8)]
}

fn binary(r: &mut Rng) -> B {
    [B::Add, B::Sub, B::Mul, B::DivOnePlusSq][r.below(4)]
}

fn build(t: &T, x: &Expr, y: &Expr) -> Expr {
    let bd = |t: &T| build(t, x, y);
    match t {
        T::X => x.clone(),
        T::Y => y.clone(),
        T::Const(s, d) => Expr::constant(*s, d),
        T::Un(u, a) => {
            let a = bd(a);
            match u {
                U::Neg => -a,
                U::Sin => a.sin(),
                U::Cos => a.cos(),
                U::Tanh => a.tanh(),
                U::Square => a.square(),
                U::ExpTanh => a.tanh().exp(),
                U::SqrtOnePlusSq => (a.square() + 1.0).sqrt(),
                U::LogOnePlusSq => (a.square() + 1.0).log(),
            }
        }
        T::Bin(op, a, b) => {
            let (a, b) = (bd(a), bd(b));
            match op {
                B::Add => a + b,
                B::Sub => a - b,
                B::Mul => a * b,
                B::DivOnePlusSq => a / (b.square() + 1.0),
            }
        }
        T::MatMul(a, b) => bd(a).matmul(&bd(b)),
        T::Sum(a) => bd(a).sum(),
        T::Norm2(a) => (bd(a) + 2.0).norm2(),
        T::Dot(a, b) => bd(a).dot(&bd(b)),
        T::Cross(a, b) => bd(a).cross(&bd(b)),
        T::Index(a, i) => bd(a).at(*i),
        T::Slice3(a) => bd(a).slice(0, 3),
        T::Concat(v) => Expr::concat(&v.iter().map(bd).collect::<Vec<_>>()),
        T::Transpose(a) => bd(a).transpose(),
        T::Block(a) => bd(a).block(0, 3, 0, 3),
        T::Column(a) => bd(a).block(0, 3, 3, 4),
        T::Quat(a) => (bd(a) + Expr::constant_vector(&[2.0, 0.0, 0.0, 0.0])).quat_to_matrix(),
        T::So3Exp(a) => bd(a).so3_exp(),
        T::So3LogExp(a) => bd(a).tanh().so3_exp().so3_log(),
        T::Se3Exp(a) => bd(a).se3_exp(),
        T::Se3LogExp(a) => bd(a).tanh().se3_exp().se3_log(),
        T::Screw(s, a) => (Expr::constant_vector(s) * bd(a)).se3_exp(),
    }
}

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
