//! The weighted Hessian of the seed's nodal constraint set at one node — waypoint
//! distance, gripper orientation error and the seed's seven capsule clearances (through the
//! collision node, which supplies first derivatives only) — next to its value + Jacobian
//! evaluation and the Hessian-vector product. 7 inputs, dense derivative rows.

use std::hint::black_box;

use armature_collision::CollisionModel;
use armature_kinematics::robots;
use armature_lie::SO3;
use armature_symbolic::{Expr, Function, Shape};
use criterion::{Criterion, criterion_group, criterion_main};

fn nodal_set() -> Function {
    let arm = robots::arm7();
    let angle = Expr::variable("angle", 7);
    let fk = arm.symbolic_fk(&angle).unwrap();
    let down = SO3::rot_y(std::f64::consts::FRAC_PI_2);
    let r_des_t = Expr::from_matrix(&down.matrix().transpose());
    let ori = r_des_t.matmul(&fk.ee_rotation()).so3_log().norm2();
    let wp = Expr::parameter("wp", Shape::Vector(3), &[0.4, 0.1, 0.3]);
    let dist = (fk.ee_position() - wp).norm2();
    let model = CollisionModel::seed_arm7(&arm).unwrap();
    let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
    let mut outs = vec![dist, ori];
    outs.extend(model.symbolic_distances(&positions).into_iter().map(|(_, d)| d));
    Function::compile(&outs, &[&[angle]]).unwrap()
}

fn bench(c: &mut Criterion) {
    let f = nodal_set();
    let q = [0.1, 0.6, -0.2, -1.2, 0.3, 2.17, 0.4];
    let w: Vec<f64> = (0..f.n_outputs()).map(|i| 1.0 + 0.1 * i as f64).collect();
    let mut ws = f.workspace();
    let mut hws = f.hessian_workspace();
    let mut v = vec![0.0; f.n_outputs()];
    let mut jac = vec![0.0; f.jacobian_pattern().nnz()];
    let mut h = vec![0.0; f.hessian_pattern().nnz()];
    let mut hv = vec![0.0; 7];
    let dir = [0.3, -0.1, 0.2, 0.5, -0.4, 0.1, 0.2];
    let mut g = c.benchmark_group("nodal_hessian");
    g.bench_function("seed_nodal_set_values_jacobian", |b| {
        b.iter(|| f.eval(black_box(&q), &mut ws, &mut v, Some(&mut jac)).unwrap())
    });
    g.bench_function("seed_nodal_set_values_jacobian_hessian", |b| {
        b.iter(|| {
            f.eval_hessian(black_box(&q), &w, &mut hws, &mut v, Some(&mut jac), &mut h).unwrap()
        })
    });
    g.bench_function("seed_nodal_set_hessian_vector_product", |b| {
        b.iter(|| {
            f.hessian_vector_product(black_box(&q), &w, &dir, &mut hws, &mut v, &mut hv).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
