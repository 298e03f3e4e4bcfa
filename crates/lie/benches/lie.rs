//! Criterion benchmarks of the hot Lie-group operations.

use std::hint::black_box;

use armature_lie::{SE3, SO3};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Vector3, Vector6};

fn bench(c: &mut Criterion) {
    let xi = Vector6::new(0.1, -0.2, 0.3, 0.4, -0.5, 0.6);
    let w = Vector3::new(0.4, -0.5, 0.6);
    let r = SO3::exp(&w);
    let t = SE3::exp(&xi);
    let mut g = c.benchmark_group("lie");
    g.bench_function("so3_exp", |b| b.iter(|| SO3::exp(black_box(&w))));
    g.bench_function("so3_log", |b| b.iter(|| black_box(&r).log()));
    g.bench_function("so3_matrix", |b| b.iter(|| black_box(&r).matrix()));
    g.bench_function("se3_exp", |b| b.iter(|| SE3::exp(black_box(&xi))));
    g.bench_function("se3_log", |b| b.iter(|| black_box(&t).log()));
    g.bench_function("se3_jr", |b| b.iter(|| SE3::jr(black_box(&xi))));
    g.bench_function("se3_jr_inv", |b| b.iter(|| SE3::jr_inv(black_box(&xi))));
    g.bench_function("se3_compose", |b| b.iter(|| black_box(&t).compose(black_box(&t))));
    g.bench_function("se3_act", |b| b.iter(|| black_box(&t).act(black_box(&w))));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
