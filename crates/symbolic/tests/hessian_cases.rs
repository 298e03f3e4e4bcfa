//! Named cases of the weighted Hessian: the Lie nodes at θ = 0, 1e-9, near π and at π, the
//! seed's orientation error and waypoint distance, the documented choices at kinks, and
//! external functions with and without second derivatives.

mod common;

use std::sync::Arc;

use armature_lie::SO3;
use armature_symbolic::{Expr, ExternalFunction, Function, Shape};
use common::{dense_jacobian, seed_fk};
use nalgebra::Vector3;

fn hessian(f: &Function, x: &[f64], w: &[f64]) -> Vec<f64> {
    let mut hws = f.hessian_workspace();
    let mut v = vec![0.0; f.n_outputs()];
    let mut h = vec![0.0; f.hessian_pattern().nnz()];
    f.eval_hessian(x, w, &mut hws, &mut v, None, &mut h).unwrap();
    f.hessian_pattern().to_dense(&h)
}

/// Central differences of the exact Jacobian, weighted.
fn fd(f: &Function, x: &[f64], w: &[f64], h: f64) -> Vec<f64> {
    let n = f.n_inputs();
    let mut out = vec![0.0; n * n];
    let mut xp = x.to_vec();
    for c in 0..n {
        xp[c] = x[c] + h;
        let (_, jp) = dense_jacobian(f, &xp);
        xp[c] = x[c] - h;
        let (_, jm) = dense_jacobian(f, &xp);
        xp[c] = x[c];
        for r in 0..n {
            out[r * n + c] = w
                .iter()
                .enumerate()
                .map(|(i, wi)| wi * (jp[i * n + r] - jm[i * n + r]))
                .sum::<f64>()
                / (2.0 * h);
        }
    }
    out
}

/// Largest |a − b| relative to max(1, |a|∞).
fn rel(a: &[f64], b: &[f64]) -> f64 {
    let s = a.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max) / s
}

fn weights(m: usize) -> Vec<f64> {
    (0..m).map(|i| ((i as f64 + 1.0) * 1.37).sin()).collect()
}

fn axis() -> Vector3<f64> {
    Vector3::new(0.48, -0.6, 0.64)
}

const ANGLES: [f64; 6] = [0.0, 1e-9, 1e-3, 0.7, std::f64::consts::PI - 1e-4, 2.5];

#[test]
fn so3_exp_and_se3_exp_at_small_and_large_angles() {
    let x = Expr::variable("x", 6);
    let f = Function::compile(&[x.slice(0, 3).so3_exp(), x.se3_exp()], &[&[x]]).unwrap();
    let w = weights(f.n_outputs());
    for th in ANGLES {
        let a = axis() * th;
        let input = [0.3, -0.2, 0.5, a.x, a.y, a.z];
        let (h, d) = (hessian(&f, &input, &w), fd(&f, &input, &w, 1e-5));
        assert!(rel(&h, &d) < 1e-7, "θ = {th}: {}", rel(&h, &d));
    }
}

/// `log(R₀ᵀ exp(ω))` puts the log's argument at angle θ from the identity when ω = θ·axis
/// and R₀ = I, and near π when R₀ is a half-turn about another axis.
#[test]
fn so3_log_at_small_angles_and_near_pi() {
    let w3 = Expr::variable("w", 3);
    for r0 in
        [SO3::identity(), SO3::exp(&(Vector3::new(0.0, 0.8, 0.6) * (std::f64::consts::PI - 1e-3)))]
    {
        let r0t = Expr::from_matrix(&r0.matrix().transpose());
        let f =
            Function::compile(&[r0t.matmul(&w3.so3_exp()).so3_log()], &[&[w3.clone()]]).unwrap();
        let w = weights(3);
        for th in [0.0, 1e-9, 1e-3, 0.4] {
            let a = axis() * th;
            let (h, d) = (hessian(&f, a.as_slice(), &w), fd(&f, a.as_slice(), &w, 1e-5));
            assert!(rel(&h, &d) < 1e-6, "θ = {th}: {} {h:?} {d:?}", rel(&h, &d));
        }
    }
}

/// `log(exp(ω)) = ω` for |ω| < π: its Hessian vanishes (up to round-off) from θ = 0 to
/// near π; at π exactly it is finite and equals the limit from inside.
#[test]
fn log_of_exp_has_zero_curvature_up_to_pi() {
    let x = Expr::variable("x", 6);
    let f = Function::compile(&[x.slice(3, 6).so3_exp().so3_log(), x.se3_exp().se3_log()], &[&[x]])
        .unwrap();
    let w = weights(f.n_outputs());
    for th in ANGLES {
        let a = axis() * th;
        let h = hessian(&f, &[0.3, -0.2, 0.5, a.x, a.y, a.z], &w);
        let worst = h.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst < 1e-6, "θ = {th}: {worst}");
    }
    let pi = axis() * std::f64::consts::PI;
    let h = hessian(&f, &[0.3, -0.2, 0.5, pi.x, pi.y, pi.z], &w);
    assert!(h.iter().all(|v| v.is_finite()));
    let inside = axis() * (std::f64::consts::PI - 1e-7);
    let hi = hessian(&f, &[0.3, -0.2, 0.5, inside.x, inside.y, inside.z], &w);
    assert!(rel(&h, &hi) < 1e-4, "{}", rel(&h, &hi));
}

#[test]
fn se3_log_of_a_moved_frame() {
    let x = Expr::variable("x", 6);
    let t0 = Expr::constant_matrix(&[
        [0.0, -1.0, 0.0, 0.2],
        [1.0, 0.0, 0.0, -0.1],
        [0.0, 0.0, 1.0, 0.4],
        [0.0, 0.0, 0.0, 1.0],
    ]);
    let f = Function::compile(&[t0.matmul(&x.se3_exp()).se3_log()], &[&[x]]).unwrap();
    let w = weights(6);
    for th in [0.0, 1e-9, 0.5, 1.2] {
        let a = axis() * th;
        let input = [0.3, -0.2, 0.5, a.x, a.y, a.z];
        let (h, d) = (hessian(&f, &input, &w), fd(&f, &input, &w, 1e-5));
        assert!(rel(&h, &d) < 1e-6, "θ = {th}: {}", rel(&h, &d));
    }
}

/// The seed's nodal constraints: ‖log(R_desᵀ R_ee(q))‖ (gripper down) and ‖p_ee(q) − wp‖.
#[test]
fn seed_orientation_error_and_waypoint_distance() {
    let q = Expr::variable("q", 7);
    let (_, t_ee) = seed_fk(&q);
    let down = SO3::rot_y(std::f64::consts::FRAC_PI_2);
    let r_des_t = Expr::from_matrix(&down.matrix().transpose());
    let ori = r_des_t.matmul(&t_ee.block(0, 3, 0, 3)).so3_log().norm2();
    let wp = Expr::parameter("wp", Shape::Vector(3), &[0.4, 0.1, 0.3]);
    let dist = (t_ee.block(0, 3, 3, 4) - wp).norm2();
    let f = Function::compile(&[ori, dist], &[&[q]]).unwrap();
    assert!(f.is_dense());
    for k in 0..20 {
        let qv: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.531).sin() * 2.0).collect();
        for w in [[1.0, 0.0], [0.0, 1.0], [0.7, -1.3]] {
            let (h, d) = (hessian(&f, &qv, &w), fd(&f, &qv, &w, 1e-6));
            assert!(rel(&h, &d) < 1e-6, "q {qv:?} w {w:?}: {}", rel(&h, &d));
        }
    }
}

/// At kinks the second derivative is the documented one-sided choice (0), and nothing is
/// NaN: `pos`, `squared_pos` at 0, `abs` at 0, `‖·‖₂` at the origin, `sqrt` at 0, `max` at a
/// tie; `squared_pos` just above 0 has 2.
#[test]
fn kinks_take_documented_one_sided_values() {
    let x = Expr::variable("x", 3);
    let outs = [
        x.at(0).pos(),
        x.at(0).squared_pos(),
        x.at(0).abs(),
        x.norm2(),
        x.at(0).sqrt(),
        x.at(0).max(x.at(1)),
        x.norm(armature_symbolic::Norm::Inf),
        x.norm(armature_symbolic::Norm::L1),
    ];
    for (k, o) in outs.iter().enumerate() {
        let f = Function::compile(std::slice::from_ref(o), &[&[x.clone()]]).unwrap();
        let h = hessian(&f, &[0.0, 0.0, 0.0], &[1.0]);
        assert!(h.iter().all(|v| *v == 0.0), "output {k}: {h:?}");
    }
    let f = Function::compile(&[x.at(0).squared_pos()], &[&[x.clone()]]).unwrap();
    assert_eq!(hessian(&f, &[1e-12, 0.0, 0.0], &[1.0])[0], 2.0);
    assert_eq!(hessian(&f, &[-1e-12, 0.0, 0.0], &[1.0])[0], 0.0);
}

/// `f(a, b) = (a²b, a + b)`, with or without its second derivatives.
#[derive(Debug)]
struct Cubic {
    exact: bool,
}

impl ExternalFunction for Cubic {
    fn name(&self) -> &str {
        if self.exact { "cubic" } else { "cubic_first_order" }
    }
    fn n_outputs(&self) -> usize {
        2
    }
    fn eval(&self, x: &[f64], v: &mut [f64], j: &mut [f64]) {
        v[0] = x[0] * x[0] * x[1];
        v[1] = x[0] + x[1];
        j.copy_from_slice(&[2.0 * x[0] * x[1], x[0] * x[0], 1.0, 1.0]);
    }
    fn has_hessian(&self) -> bool {
        self.exact
    }
    fn hessian(&self, x: &[f64], w: &[f64], h: &mut [f64]) {
        h[0] += w[0] * 2.0 * x[1];
        h[1] += w[0] * 2.0 * x[0];
        h[2] += w[0] * 2.0 * x[0];
    }
}

#[test]
fn external_functions_with_and_without_second_derivatives() {
    let x = Expr::variable("x", 2);
    let inner = Expr::concat(&[x.at(0).sin(), x.at(1)]);
    for exact in [true, false] {
        let e = Expr::external(Arc::new(Cubic { exact }), &[inner.clone()]);
        let f = Function::compile(&[e], &[&[x.clone()]]).unwrap();
        let p = f.hessian_pattern();
        assert_eq!(p.is_exact(), exact);
        let input = [0.4, -0.7];
        let w = [1.3, 0.6];
        let h = hessian(&f, &input, &w);
        if exact {
            assert!(rel(&h, &fd(&f, &input, &w, 1e-6)) < 1e-7);
        } else {
            assert_eq!(p.missing_second_derivatives(), ["cubic_first_order"]);
            // Only the chain rule's first-order part: Σ wᵢ ∂fᵢ/∂u · ∇²u, here through sin.
            let g0 = w[0] * 2.0 * input[0].sin() * input[1] + w[1];
            assert!((h[0] - g0 * -input[0].sin()).abs() < 1e-14, "{h:?}");
            assert_eq!(&h[1..], &[0.0, 0.0, 0.0]);
        }
    }
}

/// A `vmap` body's curvature (each row's second-order sweep, contracted once with the
/// captured operands' gradients) against differences of the Jacobian.
#[test]
fn vmap_rows() {
    let q = Expr::variable("q", 7);
    let (frames, t_ee) = seed_fk(&q);
    let (kp, p_ee) = (frames[3].block(0, 3, 3, 4), t_ee.block(0, 3, 3, 4));
    let wp = Expr::constant_vector(&[0.4, 0.1, 0.3]);
    let ts = [0.0, 0.3, 0.6, 1.0];
    let seg = Expr::vmap(&ts, 1, |t| (&kp * (1.0 - t) + &p_ee * t - &wp).norm2().sin());
    let f = Function::compile(&[seg], &[&[q]]).unwrap();
    assert!(!f.is_dense());
    let qv = [0.1, 0.6, -0.2, -1.2, 0.3, 2.17, 0.4];
    let w = weights(4);
    let (h, d) = (hessian(&f, &qv, &w), fd(&f, &qv, &w, 1e-6));
    assert!(rel(&h, &d) < 1e-6, "{}", rel(&h, &d));
}
