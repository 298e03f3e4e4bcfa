//! Random expression trees over random shapes, shared by the Jacobian and Hessian
//! property suites: a test-side tree that builds an `Expr`.
#![allow(dead_code)]

use armature_symbolic::{Expr, Shape};

use super::Rng;

/// A test-side expression tree that can build an `Expr` and evaluate itself directly.
#[derive(Debug, Clone)]
pub(crate) enum T {
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
pub(crate) enum U {
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
pub(crate) enum B {
    Add,
    Sub,
    Mul,
    DivOnePlusSq, // a / (1 + b²)
}

pub(crate) const V3: Shape = Shape::Vector(3);
pub(crate) const V4: Shape = Shape::Vector(4);
pub(crate) const V6: Shape = Shape::Vector(6);
pub(crate) const M3: Shape = Shape::Matrix(3, 3);
pub(crate) const M4: Shape = Shape::Matrix(4, 4);

pub(crate) fn grow(r: &mut Rng, shape: Shape, depth: usize) -> T {
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

pub(crate) fn build(t: &T, x: &Expr, y: &Expr) -> Expr {
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
