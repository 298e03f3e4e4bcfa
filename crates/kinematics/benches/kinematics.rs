//! Numeric FK of arm7 (all keypoints, end effector, space Jacobian) against the symbolic
//! tape of the same chain (keypoint frames, positions and T_ee with their Jacobian).

use std::hint::black_box;

use armature_kinematics::robots;
use armature_symbolic::{Expr, Function};
use criterion::{Criterion, criterion_group, criterion_main};

fn bench(c: &mut Criterion) {
    let arm = robots::arm7();
    let q = [0.1, 0.6, -0.2, -1.2, 0.3, 2.17, 0.4];
    let mut g = c.benchmark_group("kinematics");
    let mut ws = arm.fk_workspace();
    g.bench_function("arm7_numeric_fk_keypoints_ee_space_jacobian", |b| {
        b.iter(|| arm.forward(black_box(&q), &mut ws).unwrap())
    });
    let angle = Expr::variable("angle", 7);
    let fk = arm.symbolic_fk(&angle).unwrap();
    let mut outs: Vec<Expr> = fk.frames.iter().map(|(_, e)| e.clone()).collect();
    outs.extend(fk.positions.iter().map(|(_, e)| e.clone()));
    outs.push(fk.t_ee.clone());
    let f = Function::compile(&outs, &[&[angle]]).unwrap();
    let mut fws = f.workspace();
    let mut v = vec![0.0; f.n_outputs()];
    let mut jac = vec![0.0; f.jacobian_pattern().nnz()];
    g.bench_function("arm7_symbolic_tape_frames_positions_ee_jacobian", |b| {
        b.iter(|| f.eval(black_box(&q), &mut fws, &mut v, Some(&mut jac)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
