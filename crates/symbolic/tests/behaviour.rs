//! Specific behaviour: Lie-node derivatives at the edges (θ → 0, θ → π), CSE, parameters,
//! shape errors, vmap, constraints and the parser.

mod common;

use std::f64::consts::PI;

use armature_symbolic::{
    DerivativeMode, Expr, Function, Nodes, Shape, SymbolTable, SymbolicError, Timing,
    parse_constraint, parse_expr,
};
use common::{check_against_fd, dense_jacobian};

fn both_modes(outs: &[Expr], groups: &[&[Expr]]) -> [Function; 2] {
    [DerivativeMode::Sparse, DerivativeMode::Dense]
        .map(|m| Function::compile_with(outs, groups, m).unwrap())
}

/// Every Lie node against central differences at generic, tiny and near-π arguments, through
/// the generic (variable twist) path and the constant-screw path.
#[test]
fn lie_nodes_derivatives_at_edges() {
    let w = Expr::variable("w", 3);
    let xi = Expr::variable("xi", 6);
    let axis = [0.48, -0.6, 0.64];
    let mut points: Vec<Vec<f64>> = Vec::new();
    for t in [0.0, 1e-9, 1e-5, 0.3, 2.0, PI - 1e-3, PI - 2e-3] {
        points.push(axis.iter().map(|a| a * t).collect());
    }
    for p in &points {
        // so3_exp, and so3_log(so3_exp(w)) whose Jacobian is the identity below π.
        for f in both_modes(&[w.so3_exp(), w.so3_exp().so3_log()], &[&[w.clone()]]) {
            let (err, covered) = check_against_fd(&f, p, 1e-7);
            assert!(err < 1e-6 && covered, "so3 at {p:?}: {err}");
            let (v, j) = dense_jacobian(&f, p);
            let log_part = &v[9..12];
            let jl = &j[9 * 3..12 * 3];
            for i in 0..3 {
                assert!((log_part[i] - p[i]).abs() < 1e-12, "log(exp(w)) = w");
                for c in 0..3 {
                    let id = if i == c { 1.0 } else { 0.0 };
                    assert!((jl[i * 3 + c] - id).abs() < 1e-8, "d log(exp w)/dw = I at {p:?}");
                }
            }
        }
        // se3_exp / se3_log through the generic path.
        let x6: Vec<f64> = [0.2, -0.4, 0.1].iter().chain(p.iter()).copied().collect();
        for f in both_modes(&[xi.se3_exp(), xi.se3_exp().se3_log()], &[&[xi.clone()]]) {
            let (err, covered) = check_against_fd(&f, &x6, 1e-7);
            assert!(err < 1e-6 && covered, "se3 at {x6:?}: {err}");
            let (v, _) = dense_jacobian(&f, &x6);
            for i in 0..6 {
                assert!((v[16 + i] - x6[i]).abs() < 1e-12);
            }
        }
    }
    // The log of a rotation exactly at π: finite, |ω| = π.
    let f = Function::compile(&[w.so3_exp().so3_log()], &[&[w.clone()]]).unwrap();
    let at_pi: Vec<f64> = axis.iter().map(|a| a * PI).collect();
    let (v, j) = dense_jacobian(&f, &at_pi);
    assert!(((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - PI).abs() < 1e-12);
    assert!(j.iter().all(|x| x.is_finite()));
    // Constant-screw path at θ → 0 and θ = π, revolute and prismatic.
    let th = Expr::variable("th", 1);
    for s in [
        [-0.34, 0.0, 0.3, 0.0, 1.0, 0.0],
        [0.1, 0.2, 0.0, 0.0, 0.0, 2.5],
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
    ] {
        for f in both_modes(&[(Expr::constant_vector(&s) * &th).se3_exp()], &[&[th.clone()]]) {
            for t in [0.0, 1e-9, 0.5, PI, -PI] {
                let (err, covered) = check_against_fd(&f, &[t], 1e-7);
                assert!(err < 1e-7 && covered, "screw {s:?} at {t}: {err}");
            }
        }
    }
}

#[test]
fn structurally_identical_subexpressions_are_evaluated_once() {
    let x = Expr::variable("x", 3);
    let y = Expr::variable("y", 1);
    // Built twice, separately: the same nodes.
    let a = (x.sin() * &y).sum() + x.at(0).cos();
    let b = (x.sin() * &y).sum() + x.at(0).cos();
    let single = Function::compile(&[a.clone()], &[&[x.clone(), y.clone()]]).unwrap();
    let double = Function::compile(&[a.clone() + b.clone()], &[&[x.clone(), y.clone()]]).unwrap();
    // a + b costs exactly one more instruction (the final add) than a alone.
    assert_eq!(double.instruction_count(), single.instruction_count() + 1);
    // The graph itself still has both copies; the tape merged them.
    assert!((a.clone() + b).node_count() > 2 * a.node_count() - 2);
    // Shared handles count once.
    let shared = a.clone() + a.clone();
    assert_eq!(shared.node_count(), a.node_count() + 1);
    let f = Function::compile(&[shared], &[&[x.clone(), y.clone()]]).unwrap();
    assert_eq!(f.instruction_count(), double.instruction_count());
}

#[test]
fn identity_block_for_angle_dot_equals_velocity() {
    let angle = Expr::variable("angle", 7);
    let velocity = Expr::variable("velocity", 7);
    let torque = Expr::variable("torque", 7);
    let inv = Expr::constant_vector(&[12.5, 16.0, 20.0, 25.0, 50.0, 100.0, 200.0]);
    let f =
        Function::compile(&[velocity.clone(), &inv * &torque], &[&[angle, velocity], &[torque]])
            .unwrap();
    let p = f.jacobian_pattern();
    assert_eq!(p.nnz(), 14);
    for i in 0..7 {
        assert!(p.contains(i, 7 + i), "d angle'_{i} / d velocity_{i}");
        assert!(p.contains(7 + i, 14 + i), "d velocity'_{i} / d torque_{i}");
    }
    assert_eq!(f.group_range(1), 14..21);
    let picture = p.to_string();
    assert_eq!(picture.lines().count(), 14);
    assert_eq!(picture.lines().next().unwrap(), ".......*.............");
}

#[test]
fn parameters_change_without_recompiling() {
    let p = Expr::variable("p", 3);
    let wp = Expr::parameter("waypoint", Shape::Vector(3), &[0.35, -0.25, 0.05]);
    let mut f = Function::compile(&[(&p - &wp).norm2()], &[&[p.clone()]]).unwrap();
    let mut ws = f.workspace();
    let mut v = [0.0];
    let x = [0.35, -0.25, 0.15];
    f.eval(&x, &mut ws, &mut v, None).unwrap();
    assert!((v[0] - 0.1).abs() < 1e-15);
    f.set_parameter("waypoint", &[0.35, 0.25, 0.15]).unwrap();
    f.eval(&x, &mut ws, &mut v, None).unwrap();
    assert!((v[0] - 0.5).abs() < 1e-15);
    assert_eq!(f.parameter("waypoint").unwrap(), &[0.35, 0.25, 0.15]);
    assert!(matches!(f.set_parameter("nope", &[0.0]), Err(SymbolicError::UnknownParameter { .. })));
    assert!(matches!(f.set_parameter("waypoint", &[0.0]), Err(SymbolicError::BufferLength { .. })));
    assert!(matches!(
        f.set_parameter("waypoint", &[0.0, f64::NAN, 0.0]),
        Err(SymbolicError::BadData { .. })
    ));
    assert_eq!(f.parameter_names().collect::<Vec<_>>(), vec!["waypoint"]);
}

/// Every shape-error path: the error names the operation and both shapes, and nothing panics.
#[test]
fn shape_errors_name_operation_and_shapes() {
    let v3 = Expr::variable("a", 3);
    let v2 = Expr::variable("b", 2);
    let m = Expr::variable_shaped("m", Shape::Matrix(2, 3));
    let cases: Vec<(Expr, &str)> = vec![
        (&v3 + &v2, "add: shapes vector(3) and vector(2)"),
        (&v3 - &v2, "sub: shapes vector(3) and vector(2)"),
        (&v3 * &v2, "mul: shapes vector(3) and vector(2)"),
        (&v3 / &v2, "div: shapes vector(3) and vector(2)"),
        (v3.max(v2.clone()), "max: shapes vector(3) and vector(2)"),
        (v3.min(v2.clone()), "min: shapes vector(3) and vector(2)"),
        (v2.matmul(&m.transpose()), "matmul: shapes vector(2) and matrix(3×2)"),
        (m.matmul(&v2), "matmul: shapes matrix(2×3) and vector(2)"),
        (v3.dot(&v2), "dot: shapes vector(3) and vector(2)"),
        (v3.cross(&v2), "cross: shapes vector(3) and vector(2)"),
        (m.norm2(), "norm: operand of shape matrix(2×3) is not a vector"),
        (v3.quat_to_matrix(), "quat_to_matrix: operand of shape vector(3) is not vector(4)"),
        (v2.so3_exp(), "so3_exp: operand of shape vector(2) is not vector(3)"),
        (v3.so3_log(), "so3_log: operand of shape vector(3) is not matrix(3×3)"),
        (v3.se3_exp(), "se3_exp: operand of shape vector(3) is not vector(6)"),
        (m.se3_log(), "se3_log: operand of shape matrix(2×3) is not matrix(4×4)"),
        (v3.at(3), "index: index [3] is out of bounds for shape vector(3)"),
        (v3.slice(2, 5), "slice: index [2:5] is out of bounds for shape vector(3)"),
        (m.block(0, 3, 0, 1), "block: index [0:3, 0:1] is out of bounds for shape matrix(2×3)"),
        (v3.block(0, 1, 0, 1), "block: index [0:1, 0:1] is out of bounds for shape vector(3)"),
        (
            Expr::concat(&[v3.clone(), m.clone()]),
            "concat: operand of shape matrix(2×3) is not a scalar or vector",
        ),
        (Expr::concat(&[]), "concat: needs at least one operand"),
        (Expr::stack(&[v3.clone(), v2.clone()]), "stack: shapes vector(3) and vector(2)"),
        (v3.reshape(Shape::Matrix(2, 2)), "reshape: shapes vector(3) and matrix(2×2)"),
        (Expr::constant(Shape::Vector(2), &[1.0]), "1 values for shape vector(2)"),
        (Expr::constant_vector(&[1.0, f64::NAN]), "entry 1 is NaN"),
        (Expr::parameter("w", Shape::Scalar, &[f64::INFINITY]), "parameter 'w': entry 0 is inf"),
        (Expr::vmap(&[1.0, 2.0, 3.0], 2, |r| r.sum()), "3 values do not form rows of 2"),
        (
            Expr::vmap(&[1.0, 2.0], 2, |r| r * 2.0),
            "vmap: operand of shape vector(2) is not a scalar body",
        ),
    ];
    for (e, msg) in cases {
        let err = e.shape().unwrap_err().to_string();
        assert!(err.contains(msg), "{err:?} should contain {msg:?}");
        // Errors propagate through further operations and surface at compile time.
        let further = (e.sum() + 1.0).sin();
        assert_eq!(further.shape().unwrap_err().to_string(), err);
        assert_eq!(Function::compile(&[further], &[&[v3.clone()]]).unwrap_err().to_string(), err);
    }
    // Compile-time errors.
    let x = Expr::variable("x", 2);
    let other = Expr::variable("x", 3);
    assert!(matches!(
        Function::compile(&[x.sum()], &[&[]]),
        Err(SymbolicError::UnknownVariable { .. })
    ));
    assert!(matches!(
        Function::compile(&[other.sum()], &[&[x.clone()]]),
        Err(SymbolicError::DuplicateName { .. })
    ));
    assert!(matches!(
        Function::compile(&[x.sum()], &[&[x.clone(), x.clone()]]),
        Err(SymbolicError::DuplicateName { .. })
    ));
    assert!(matches!(
        Function::compile(&[x.sum()], &[&[x.sum()]]),
        Err(SymbolicError::NotAVariable { group: 0, index: 0 })
    ));
    let f = Function::compile(&[x.sum()], &[&[x.clone()]]).unwrap();
    let mut ws = f.workspace();
    assert!(matches!(
        f.eval(&[1.0], &mut ws, &mut [0.0], None),
        Err(SymbolicError::BufferLength { what: "input", .. })
    ));
    assert!(matches!(
        f.eval(&[1.0, 2.0], &mut ws, &mut [], None),
        Err(SymbolicError::BufferLength { what: "values", .. })
    ));
    assert!(matches!(
        f.eval(&[1.0, 2.0], &mut ws, &mut [0.0], Some(&mut [])),
        Err(SymbolicError::BufferLength { what: "jacobian", .. })
    ));
}

/// The seed's sampled capsule distance: a vmap over a constant batch, one batched node.
#[test]
fn vmap_values_jacobian_and_single_node() {
    let q = Expr::variable("q", 2);
    let pa0 = Expr::concat(&[q.at(0).cos(), q.at(0).sin(), Expr::scalar(0.0)]);
    let pa1 = &pa0 * 2.0;
    let pb = Expr::concat(&[Expr::scalar(1.0), q.at(1), Expr::scalar(0.3)]);
    let make = |n: usize| {
        let ts: Vec<f64> = (0..n).map(|i| i as f64 / (n - 1) as f64).collect();
        Expr::vmap(&ts, 1, |t| (&pa0 * (1.0 - t) + &pa1 * t - &pb).norm2())
    };
    let d4 = make(4);
    let d16 = make(16);
    let f4 = Function::compile(&[d4.clone()], &[&[q.clone()]]).unwrap();
    let f16 = Function::compile(&[d16], &[&[q.clone()]]).unwrap();
    assert_eq!(f4.instruction_count(), f16.instruction_count(), "one batched node, not copies");
    assert_eq!(f16.n_outputs(), 16);
    let x = [0.4, -0.3];
    let (v, _) = dense_jacobian(&f4, &x);
    for (i, t) in [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0].iter().enumerate() {
        let p = [(1.0 + t) * x[0].cos() - 1.0, (1.0 + t) * x[0].sin() - x[1], -0.3];
        let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        assert!((v[i] - d).abs() < 1e-14);
    }
    let (err, covered) = check_against_fd(&f16, &x, 1e-7);
    assert!(err < 1e-7 && covered);
    // A vmap used inside a bigger expression, with a parameter captured in its body.
    let r = Expr::parameter("r", Shape::Scalar, &[0.05]);
    let ts = [0.0, 0.5, 1.0];
    let clearance = Expr::vmap(&ts, 1, |t| (&pa0 * (1.0 - t) + &pa1 * t - &pb).norm2() - &r);
    let mut f = Function::compile(&[clearance.sum() + q.at(0)], &[&[q.clone()]]).unwrap();
    let (err, covered) = check_against_fd(&f, &x, 1e-7);
    assert!(err < 1e-7 && covered);
    let (v0, _) = dense_jacobian(&f, &x);
    f.set_parameter("r", &[0.15]).unwrap();
    let (v1, _) = dense_jacobian(&f, &x);
    assert!((v0[0] - v1[0] - 0.3).abs() < 1e-12, "parameter inside the vmap body");
    // A body that does not use the row gives constant rows.
    let c = Expr::vmap(&ts, 1, |_| q.at(1) * 2.0);
    let f = Function::compile(&[c], &[&[q.clone()]]).unwrap();
    assert_eq!(dense_jacobian(&f, &x).0, vec![-0.6; 3]);
    // Nested vmaps are an error, not a panic.
    let nested = Expr::vmap(&ts, 1, |t| Expr::vmap(&ts, 1, |s| t * s + q.at(0)).sum());
    assert!(Function::compile(&[nested], &[&[q.clone()]]).is_err());
}

#[test]
fn constraints_canonicalise_and_validate() {
    let x = Expr::variable("x", 2);
    let c = x.at(0).le(0.5);
    assert_eq!(c.name(), "x[0] <= 0.5");
    assert!(!c.is_equality() && c.timing() == &Timing::Nodal(Nodes::All));
    let f = Function::compile(&[c.function().clone()], &[&[x.clone()]]).unwrap();
    let mut ws = f.workspace();
    let mut v = [0.0];
    f.eval(&[2.0, 0.0], &mut ws, &mut v, None).unwrap();
    assert_eq!(v[0], 1.5, "g = lhs − rhs");
    let g = x.at(1).ge(1.0);
    let f2 = Function::compile(&[g.function().clone()], &[&[x.clone()]]).unwrap();
    // A workspace is tied to its function: same sizes, different constants.
    assert!(matches!(
        f2.eval(&[0.0, 3.0], &mut ws, &mut v, None),
        Err(SymbolicError::ForeignWorkspace)
    ));
    let f = f2;
    let mut ws = f.workspace();
    f.eval(&[0.0, 3.0], &mut ws, &mut v, None).unwrap();
    assert_eq!(v[0], -2.0, "g = rhs − lhs");
    assert_eq!(x.at(1).ge(1.0).ctcs().over(2, 6).timing(), &Timing::Continuous(Some((2, 6))));
    assert_eq!(x.at(1).ge(1.0).over(2, 6).timing(), &Timing::Nodal(Nodes::Range(2, 6)));
    assert_eq!(Nodes::Range(2, 6).resolve(5), vec![2, 3, 4]);
    assert!(x.at(0).eq(1.0).is_equality());
    assert!(x.at(0).le(1.0).convex().is_convex());
    // Validation against an 11-node trajectory.
    assert!(x.at(0).le(1.0).at(&[10]).validate(11).is_ok());
    let err = x.at(0).le(1.0).at(&[11]).named("wp").validate(11).unwrap_err().to_string();
    assert_eq!(err, "constraint 'wp': node 11 is beyond the last node 10");
    assert!(
        x.at(0)
            .eq(1.0)
            .ctcs()
            .validate(11)
            .unwrap_err()
            .to_string()
            .contains("must be an inequality")
    );
    assert!(x.at(0).le(1.0).ctcs().over(6, 2).validate(11).is_err());
    assert!(x.at(0).le(1.0).at(&[]).validate(11).is_err());
    // Long expressions get a bounded derived name.
    let mut long = x.at(0);
    for _ in 0..50 {
        long = long.sin() + 1.0;
    }
    assert!(long.le(0.0).name().chars().count() < 80);
    assert!(format!("{}", x.at(0).le(1.0).ctcs().over(2, 6)).ends_with("(ctcs over nodes 2..=6)"));
}

#[test]
fn parser_builds_the_same_expressions() {
    let angle = Expr::variable("angle", 7);
    let p = Expr::variable("p", 3);
    let t = Expr::variable_shaped("T", Shape::Matrix(4, 4));
    let wp = Expr::parameter("wp", Shape::Vector(3), &[0.35, -0.25, 0.05]);
    let a = Expr::variable_shaped("A", Shape::Matrix(3, 3));
    let xi = Expr::constant_vector(&[-0.34, 0.0, 0.3, 0.0, 1.0, 0.0]);
    let mut s = SymbolTable::new();
    s.insert_leaf(&angle)
        .insert_leaf(&p)
        .insert_leaf(&t)
        .insert_leaf(&wp)
        .insert_leaf(&a)
        .insert("xi", xi.clone());
    let pairs: Vec<(&str, Expr)> = vec![
        ("norm(p - wp, 2)", (&p - &wp).norm2()),
        (
            "norm(p, 1) + norm(p, inf)",
            p.norm(armature_symbolic::Norm::L1) + p.norm(armature_symbolic::Norm::Inf),
        ),
        ("se3_exp(xi * angle[3])", (&xi * angle.at(3)).se3_exp()),
        ("T[0:3, 3]", t.block(0, 3, 3, 4)),
        ("T[:3, :3].T @ A", t.block(0, 3, 0, 3).transpose().matmul(&a)),
        ("A @ p", a.matmul(&p)),
        ("-p[0]**2 + 2.5e-1 * angle[-1]", -(p.at(0).square()) + 0.25 * angle.at(6)),
        ("p ** 3", &p.square() * &p),
        (
            "sqrt(max(p[1], 0)) / (1 + sqpos(p[2]))",
            p.at(1).max(0.0).sqrt() / (1.0 + p.at(2).squared_pos()),
        ),
        (
            "dot(p, [1, 2, 3]) + sum(cross(p, wp))",
            p.dot(&Expr::constant_vector(&[1.0, 2.0, 3.0])) + p.cross(&wp).sum(),
        ),
        (
            "so3_log(so3_exp(p)) - [p[0], p[1], -p[2]]",
            p.so3_exp().so3_log() - Expr::concat(&[p.at(0), p.at(1), -p.at(2)]),
        ),
        ("angle[2:5] * pi", angle.slice(2, 5) * PI),
    ];
    let x: Vec<f64> = (0..7 + 3 + 16 + 9).map(|i| (i as f64 * 0.7).sin()).collect();
    for (text, expected) in pairs {
        let parsed = parse_expr(text, &s).unwrap_or_else(|e| panic!("{text}: {e}"));
        assert_eq!(parsed.shape(), expected.shape(), "{text}");
        let groups: &[&[Expr]] = &[&[angle.clone(), p.clone(), t.clone(), a.clone()]];
        let f1 = Function::compile(&[parsed], groups).unwrap();
        let f2 = Function::compile(&[expected], groups).unwrap();
        assert_eq!(dense_jacobian(&f1, &x), dense_jacobian(&f2, &x), "{text}");
    }
    let c = parse_constraint("norm(p - wp) <= 0.01", &s).unwrap();
    assert_eq!(c.name(), "norm(p - wp) <= 0.01");
    assert!(parse_constraint("p[2] >= 0", &s).is_ok());
    assert!(parse_constraint("p[2] == 0", &s).unwrap().is_equality());
}

#[test]
fn parser_errors_point_at_the_column() {
    let mut s = SymbolTable::new();
    s.insert_leaf(&Expr::variable("angle", 7)).insert_leaf(&Expr::variable("p", 3));
    let cases = [
        ("norm(p - q)", 10, "unknown name 'q'"),
        ("angel[0]", 1, "unknown name 'angel' (did you mean 'angle'?)"),
        ("p + angle", 3, "add: shapes vector(3) and vector(7)"),
        ("p[3]", 2, "index: index [3] is out of bounds"),
        ("p[0, 1]", 4, "expected ']'"),
        ("sin(p", 6, "expected ',' or ')'"),
        ("sin(p))", 7, "expected an operator or the end"),
        ("p * $", 5, "unexpected character '$'"),
        ("p < 1", 3, "use '<='"),
        ("p[0] = 1", 6, "use '==' for equality"),
        ("norm(p, 3)", 9, "norm order must be 1, 2 or inf"),
        ("p ** p", 6, "the exponent must be a number"),
        ("p ** 1.5", 6, "unsupported exponent 1.5"),
        ("frob(p)", 1, "unknown function 'frob'"),
        ("sin(p, p)", 1, "sin() takes 1 argument, got 2"),
        ("", 1, "unexpected end of expression"),
        ("angle[-8]", 7, "index -8 is out of range for length 7"),
    ];
    for (text, col, msg) in cases {
        let err = parse_expr(text, &s).unwrap_err();
        match &err {
            SymbolicError::Parse { column, message, caret, .. } => {
                assert_eq!(*column, col, "{text}: {err}");
                assert!(message.contains(msg), "{text}: {message:?} should contain {msg:?}");
                assert_eq!(caret.len(), col, "{text}: caret under column {col}");
            }
            other => panic!("{text}: {other:?}"),
        }
    }
    assert!(
        parse_constraint("norm(p)", &s).unwrap_err().to_string().contains("expected a comparison")
    );
    assert!(
        parse_expr("p <= 1", &s)
            .unwrap_err()
            .to_string()
            .contains("a comparison is not allowed here")
    );
}

/// `f(a, b, c) = [a·b, sin(a) + c²]` with its exact Jacobian, as an external function.
#[derive(Debug)]
struct Demo;

impl armature_symbolic::ExternalFunction for Demo {
    fn name(&self) -> &str {
        "demo"
    }
    fn n_outputs(&self) -> usize {
        2
    }
    fn eval(&self, x: &[f64], v: &mut [f64], j: &mut [f64]) {
        v[0] = x[0] * x[1];
        v[1] = x[0].sin() + x[2] * x[2];
        j.copy_from_slice(&[x[1], x[0], 0.0, x[0].cos(), 0.0, 2.0 * x[2]]);
    }
}

#[test]
fn external_functions_compose_with_the_graph() {
    let f: std::sync::Arc<dyn armature_symbolic::ExternalFunction> = std::sync::Arc::new(Demo);
    let x = Expr::variable("x", 3);
    let e = Expr::external(f.clone(), &[x.at(0).square(), x.slice(1, 3).sin()]);
    assert_eq!(e.shape().unwrap(), Shape::Vector(2));
    assert_eq!(format!("{}", Expr::external(f.clone(), &[x.clone()])), "demo(x)");
    let out = &e * 2.0 + x.at(2);
    for fun in both_modes(&[out.clone()], &[&[x.clone()]]) {
        for p in [[0.3, -0.7, 1.1], [1.2, 0.4, -0.9]] {
            let (err, covered) = check_against_fd(&fun, &p, 1e-6);
            assert!(err < 1e-8 && covered, "{err}");
            let (v, _) = dense_jacobian(&fun, &p);
            let (a, b, c) = (p[0] * p[0], p[1].sin(), p[2].sin());
            assert!((v[0] - (2.0 * a * b + p[2])).abs() < 1e-14);
            assert!((v[1] - (2.0 * (a.sin() + c * c) + p[2])).abs() < 1e-14);
        }
    }
    // The same call twice is evaluated once; constant operands fold at compile time.
    let twice = Function::compile(
        &[e.sum() + Expr::external(f.clone(), &[x.at(0).square(), x.slice(1, 3).sin()]).sum()],
        &[&[x.clone()]],
    )
    .unwrap();
    let once = Function::compile(&[e.sum()], &[&[x.clone()]]).unwrap();
    assert_eq!(
        twice.instruction_count(),
        once.instruction_count() + 1,
        "only the final add is new"
    );
    let folded = Function::compile(
        &[Expr::external(f.clone(), &[Expr::constant_vector(&[1.0, 2.0, 3.0])]) + x.at(0)],
        &[&[x.clone()]],
    )
    .unwrap();
    let (v, _) = dense_jacobian(&folded, &[0.0, 0.0, 0.0]);
    assert_eq!(v, vec![2.0, 1f64.sin() + 9.0]);
    assert!(Expr::external(f, &[]).shape().is_err());
}
