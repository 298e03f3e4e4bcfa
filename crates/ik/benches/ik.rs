//! IK benchmarks: one pose solve from the zero seed to a random reachable target, and the
//! seed's 11-node pick-and-place initialization.

use std::f64::consts::{FRAC_1_SQRT_2, PI};
use std::hint::black_box;

use armature_ik::{IkSettings, IkWorkspace, Keyframe, Mode, Target, ik_interpolation, solve};
use armature_kinematics::robots;
use criterion::{Criterion, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

fn bench(c: &mut Criterion) {
    let arm = robots::arm7();
    let (lo, hi) = arm.position_limits();
    let mut rng = Pcg64Mcg::seed_from_u64(5);
    let mut fk = arm.fk_workspace();
    let targets: Vec<Target> = (0..64)
        .map(|_| {
            let q: Vec<f64> =
                (0..7).map(|i| rng.random_range(lo[i].max(-PI)..=hi[i].min(PI))).collect();
            arm.forward(&q, &mut fk).unwrap();
            Target { position: fk.ee().translation(), orientation: Some(fk.ee().rotation()) }
        })
        .collect();
    // Restart-driven settings: short attempts that give up early at local minima (the best
    // of a sweep over iteration caps and give-up damping on 1000 targets; all converge).
    let settings =
        IkSettings { restarts: 30, max_iterations: 20, max_damping: 1e-2, ..IkSettings::default() };
    let mut ws = IkWorkspace::new(&arm);
    let mut g = c.benchmark_group("ik");
    let mut k = 0;
    g.bench_function("arm7_pose_solve_zero_seed_random_target", |b| {
        b.iter(|| {
            k = (k + 1) % targets.len();
            solve(&arm, black_box(&targets[k]), &[0.0; 7], &settings, &mut ws).unwrap()
        })
    });
    let q_down = [FRAC_1_SQRT_2, 0.0, FRAC_1_SQRT_2, 0.0];
    let kf =
        |node, p: [f64; 3], q: [f64; 4]| Keyframe { node, position: p, quaternion_wxyz: Some(q) };
    let keyframes = vec![
        kf(0, [0.69, 0.0, 0.34], [1.0, 0.0, 0.0, 0.0]),
        kf(2, [0.35, -0.25, 0.2], q_down),
        kf(4, [0.35, -0.25, 0.05], q_down),
        kf(6, [0.35, -0.25, 0.2], q_down),
        kf(8, [0.35, 0.25, 0.2], q_down),
        kf(10, [0.35, 0.25, 0.05], q_down),
    ];
    let settings = IkSettings { restarts: 8, ..IkSettings::default() };
    for (name, mode) in
        [("seed_11_nodes_sequential", Mode::Sequential), ("seed_11_nodes_parallel", Mode::Parallel)]
    {
        g.bench_function(name, |b| {
            b.iter(|| {
                ik_interpolation(&arm, black_box(&keyframes), &[0.0; 7], &settings, mode).unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
