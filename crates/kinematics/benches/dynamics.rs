//! Rigid-body dynamics of the seed arm with inertials (the Pinocchio fixture `arm7.urdf`):
//! RNEA, CRBA, ABA and the derivatives of RNEA and ABA, at one random state. Compare with
//! Pinocchio's C++ on the same URDF: `bench/dynamics/pinocchio_bench.sh`.

use std::hint::black_box;

use armature_kinematics::{DynamicsPartials, RigidBodyModel, chain_from_urdf_str};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::DMatrix;

fn bench(c: &mut Criterion) {
    let xml = include_str!("../tests/fixtures/dynamics/arm7.urdf");
    let chain = chain_from_urdf_str(xml, "base", "ee", None).unwrap();
    let model = RigidBodyModel::new(&chain, [0.0, 0.0, -9.81]).unwrap();
    let mut ws = model.workspace();
    let q = [0.1, 0.6, -0.2, -1.2, 0.3, 1.17, 0.4];
    let qd = [0.5, -0.3, 0.8, 0.1, -0.6, 0.9, -0.2];
    let qdd = [1.0, -2.0, 0.5, 1.5, -0.7, 0.3, 2.0];
    let mut out = [0.0; 7];
    let mut m = DMatrix::zeros(7, 7);
    let mut d = DynamicsPartials::new(7);
    let mut g = c.benchmark_group("dynamics_arm7");
    g.bench_function("rnea", |b| {
        b.iter(|| model.rnea(&mut ws, black_box(&q), &qd, &qdd, &mut out).unwrap())
    });
    g.bench_function("crba", |b| b.iter(|| model.crba(&mut ws, black_box(&q), &mut m).unwrap()));
    g.bench_function("aba", |b| {
        b.iter(|| model.aba(&mut ws, black_box(&q), &qd, &qdd, &mut out).unwrap())
    });
    g.bench_function("rnea_derivatives", |b| {
        b.iter(|| {
            model.rnea_derivatives(&mut ws, black_box(&q), &qd, &qdd, &mut out, &mut d).unwrap()
        })
    });
    g.bench_function("aba_derivatives", |b| {
        b.iter(|| {
            model.aba_derivatives(&mut ws, black_box(&q), &qd, &qdd, &mut out, &mut d).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
