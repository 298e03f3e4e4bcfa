//! Criterion benchmarks: the seed's FK and dynamics through the tape.

use std::hint::black_box;

use armature_symbolic::{Expr, Function, Shape};
use criterion::{Criterion, criterion_group, criterion_main};

const D1: f64 = 0.340;
const A2: f64 = 0.300;
const A3: f64 = 0.250;
const A4: f64 = 0.150;

fn seed_fk_function() -> Function {
    let s = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, -A2, 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, A2, 0.0, 1.0, 0.0],
        [0.0, -(A2 + A3), 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, A2 + A3, 0.0, 1.0, 0.0],
        [0.0, -(A2 + A3 + A4), 0.0, 0.0, 0.0, 1.0],
    ];
    let angle = Expr::variable("angle", 7);
    let mut chain = Expr::identity(4);
    let mut outs = Vec::new();
    let mut j = 0;
    for after in [0, 1, 2, 4, 7] {
        while j < after {
            chain = chain.matmul(&(Expr::constant_vector(&s[j]) * angle.at(j)).se3_exp());
            j += 1;
        }
        outs.push(chain.clone());
    }
    let home = Expr::constant_matrix(&[
        [1.0, 0.0, 0.0, A2 + A3 + A4],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, D1],
        [0.0, 0.0, 0.0, 1.0],
    ]);
    outs.push(chain.matmul(&home));
    Function::compile(&outs, &[&[angle]]).unwrap()
}

/// The seed's dynamics with its CTCS penalty integrands: angle' = velocity,
/// velocity' = τ/I, and Σ squared-ReLU of the box constraints on angle and velocity.
fn seed_dynamics_function() -> Function {
    let angle = Expr::variable("angle", 7);
    let velocity = Expr::variable("velocity", 7);
    let torque = Expr::variable("torque", 7);
    let inertia = [0.08, 0.06, 0.05, 0.04, 0.02, 0.01, 0.005];
    let i_inv = Expr::constant_vector(&inertia.map(|i| 1.0 / i));
    let qmax =
        Expr::constant_vector(&[170f64, 120., 170., 120., 170., 120., 175.].map(f64::to_radians));
    let vmax = Expr::constant(Shape::Vector(7), &[3.0; 7]);
    let penalty = (&angle - &qmax).squared_pos().sum()
        + (-&qmax - &angle).squared_pos().sum()
        + (&velocity - &vmax).squared_pos().sum()
        + (-&vmax - &velocity).squared_pos().sum();
    Function::compile(
        &[velocity.clone(), &i_inv * &torque, penalty],
        &[&[angle, velocity], &[torque]],
    )
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("symbolic");
    let fk = seed_fk_function();
    let mut ws = fk.workspace();
    let mut v = vec![0.0; fk.n_outputs()];
    let mut jac = vec![0.0; fk.jacobian_pattern().nnz()];
    let q = [0.1, 0.6, -0.2, -1.2, 0.3, 2.17, 0.4];
    g.bench_function("seed_fk_values_jacobian", |b| {
        b.iter(|| fk.eval(black_box(&q), &mut ws, &mut v, Some(&mut jac)).unwrap())
    });
    g.bench_function("seed_fk_values", |b| {
        b.iter(|| fk.eval(black_box(&q), &mut ws, &mut v, None).unwrap())
    });

    let dyn_f = seed_dynamics_function();
    let mut ws = dyn_f.workspace();
    let mut v = vec![0.0; dyn_f.n_outputs()];
    let mut jac = vec![0.0; dyn_f.jacobian_pattern().nnz()];
    let x: Vec<f64> = (0..21).map(|i| (i as f64 * 0.37).sin() * 3.5).collect();
    g.bench_function("seed_dynamics_values_jacobian", |b| {
        b.iter(|| dyn_f.eval(black_box(&x), &mut ws, &mut v, Some(&mut jac)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
