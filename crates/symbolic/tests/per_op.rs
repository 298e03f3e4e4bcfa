//! Every operation on its own: Jacobian against central differences (both derivative
//! modes), pattern covering every numerically nonzero entry. Non-smooth operations are
//! evaluated away from their kinks, and their documented choice at the kink is checked.

mod common;

use armature_symbolic::{DerivativeMode, Expr, Function, Norm, Shape};
use common::{check_against_fd, dense_jacobian};

#[test]
fn each_operation_matches_finite_differences() {
    let x = Expr::variable("x", 4);
    let m = Expr::variable_shaped("m", Shape::Matrix(2, 2));
    let a = x.slice(0, 3);
    let b = Expr::concat(&[x.at(3), x.at(0), m.get(1, 0)]);
    let ops: Vec<(&str, Expr)> = vec![
        ("neg", -&x),
        ("add", &x + &x.sin()),
        ("add scalar", &x + m.get(0, 1)),
        ("sub", &x - &x.square()),
        ("mul", &x * &x.cos()),
        ("div", &x / (x.square() + 1.0)),
        ("div scalar", 2.0 / (x.at(0).square() + 1.0)),
        ("sqrt", (x.square() + 0.5).sqrt()),
        ("square", x.square()),
        ("abs", x.abs()),
        ("sin", x.sin()),
        ("cos", x.cos()),
        ("tan", (&x * 0.5).tan()),
        ("exp", x.exp()),
        ("log", (x.square() + 0.1).log()),
        ("tanh", x.tanh()),
        ("pos", x.pos()),
        ("squared_pos", x.squared_pos()),
        ("max", x.max(m.get(1, 1))),
        ("min", x.min(m.get(1, 1))),
        ("matmul M@M", m.matmul(&m)),
        ("matmul M@v", m.matmul(&x.slice(0, 2))),
        ("matmul v@M", x.slice(2, 4).matmul(&m)),
        ("matmul v@v", a.matmul(&b)),
        ("transpose", m.transpose()),
        ("dot", a.dot(&b)),
        ("cross", a.cross(&b)),
        ("index", x.at(2)),
        ("slice", x.slice(1, 3)),
        ("block", m.block(0, 2, 1, 2)),
        ("concat", Expr::concat(&[x.at(1), m.get(0, 0), x.slice(2, 4)])),
        ("stack", Expr::stack(&[x.slice(0, 2), m.block(1, 2, 0, 2)])),
        ("reshape", x.reshape(Shape::Matrix(2, 2)).matmul(&m)),
        ("sum", (&x * &x).sum()),
        ("norm L1", x.norm(Norm::L1)),
        ("norm L2", x.norm2()),
        ("norm inf", x.norm(Norm::Inf)),
        ("quat_to_matrix", x.quat_to_matrix()),
        ("so3_exp", a.so3_exp()),
        ("so3_log", a.so3_exp().so3_log()),
        ("se3_exp", Expr::concat(&[a.clone(), b.clone()]).se3_exp()),
        ("se3_log", Expr::concat(&[b.clone(), a.clone()]).se3_exp().se3_log()),
        ("vmap", Expr::vmap(&[0.0, 1.0, 0.5, -2.0], 2, |r| (&x.slice(0, 2) - r).norm2())),
    ];
    // Generic points, away from every kink (no zero entries, no ties).
    let points = [
        [0.3, -0.7, 1.1, 0.45, -0.2, 0.9, 0.35, -1.3],
        [-1.2, 0.25, -0.6, 1.4, 0.8, -0.55, 1.05, 0.15],
    ];
    for (name, e) in ops {
        for mode in [DerivativeMode::Sparse, DerivativeMode::Dense] {
            let f =
                Function::compile_with(std::slice::from_ref(&e), &[&[x.clone(), m.clone()]], mode)
                    .unwrap();
            for p in &points {
                let (err, covered) = check_against_fd(&f, p, 1e-6);
                assert!(err < 1e-7, "{name} ({mode:?}): relative error {err}");
                assert!(covered, "{name}: FD nonzero outside the pattern");
                let (v, j) = dense_jacobian(&f, p);
                assert!(v.iter().chain(&j).all(|t| t.is_finite()), "{name}");
            }
        }
    }
}

/// The documented derivative choices where a function is not differentiable.
#[test]
fn kinks_have_documented_finite_derivatives() {
    let x = Expr::variable("x", 3);
    let cases: Vec<(&str, Expr, [f64; 3], Vec<f64>)> = vec![
        ("abs at 0", x.at(0).abs(), [0.0, 1.0, 1.0], vec![0.0, 0.0, 0.0]),
        ("pos at 0", x.at(0).pos(), [0.0, 1.0, 1.0], vec![0.0, 0.0, 0.0]),
        ("sqrt at 0", x.at(0).sqrt(), [0.0, 1.0, 1.0], vec![0.0, 0.0, 0.0]),
        ("norm2 at origin", x.norm2(), [0.0, 0.0, 0.0], vec![0.0, 0.0, 0.0]),
        ("max tie follows x", x.at(0).max(x.at(1)), [0.5, 0.5, 0.0], vec![1.0, 0.0, 0.0]),
        ("min tie follows x", x.at(0).min(x.at(1)), [0.5, 0.5, 0.0], vec![1.0, 0.0, 0.0]),
        ("inf norm picks first largest", x.norm(Norm::Inf), [-2.0, 2.0, 1.0], vec![-1.0, 0.0, 0.0]),
        ("squared_pos at 0 is smooth", x.at(0).squared_pos(), [0.0, 1.0, 1.0], vec![0.0, 0.0, 0.0]),
    ];
    for (name, e, p, expected) in cases {
        for mode in [DerivativeMode::Sparse, DerivativeMode::Dense] {
            let f =
                Function::compile_with(std::slice::from_ref(&e), &[&[x.clone()]], mode).unwrap();
            let (_, j) = dense_jacobian(&f, &p);
            assert_eq!(j, expected, "{name} ({mode:?})");
        }
    }
}
