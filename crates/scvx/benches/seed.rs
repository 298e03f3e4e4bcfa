//! The seed pick-and-place: one full solve (after problem construction), the same with the
//! quasi-Newton model and the Lagrangian merit, the same with Clarabel (instead of the
//! default native interior point) for every subproblem, the collision variant with either
//! solver (and without the clearances' peak rows, for comparison), the plain and collision
//! variants with interval bounds (the velocity limits also enforced between the nodes), and
//! one discretization of the guess; also problem construction alone and with the interior
//! point's KKT analysis.

#[path = "../tests/seed/mod.rs"]
mod seed;

use armature_scvx::{Merit, Ptr, PtrSettings, SubproblemSolver};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let s = seed::build();
    let mut g = c.benchmark_group("seed_pick_and_place");
    g.sample_size(10);
    // Problem construction (the subproblem's pattern), and with it the interior point's KKT
    // analysis (orderings and symbolic factorization), which a solve does once per `Ptr`
    // (at its first subproblem; `solve` below reuses it).
    g.bench_function("construct", |b| {
        b.iter(|| black_box(Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap()))
    });
    g.bench_function("construct_and_analyse_kkt", |b| {
        b.iter(|| {
            let ptr = Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap();
            black_box(ptr.dimensions().reduced_kkt_nonzeros)
        })
    });
    let mut ptr = Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap();
    g.bench_function("solve", |b| {
        b.iter(|| black_box(ptr.solve(&s.x, &s.u, &s.s).unwrap().final_time))
    });
    let qn = {
        let mut s = PtrSettings::default();
        s.quasi_newton = true;
        s.merit = Merit::Lagrangian { sigma: 0.5 };
        s
    };
    let mut ptr_qn = Ptr::new(s.ocp.clone(), qn).unwrap();
    g.bench_function("solve_quasi_newton", |b| {
        b.iter(|| black_box(ptr_qn.solve(&s.x, &s.u, &s.s).unwrap().final_time))
    });
    let clarabel = {
        let mut s = PtrSettings::default();
        s.subproblem.solver = SubproblemSolver::Clarabel;
        s
    };
    let mut ptr_n = Ptr::new(s.ocp.clone(), clarabel.clone()).unwrap();
    g.bench_function("solve_clarabel", |b| {
        b.iter(|| black_box(ptr_n.solve(&s.x, &s.u, &s.s).unwrap().final_time))
    });
    let sc = seed::build_collision();
    let mut ptr_c = Ptr::new(sc.ocp.clone(), PtrSettings::default()).unwrap();
    g.bench_function("solve_collision", |b| {
        b.iter(|| black_box(ptr_c.solve(&sc.x, &sc.u, &sc.s).unwrap().final_time))
    });
    let sn = seed::build_with(seed::Variant {
        collision: true,
        without_clearance_peaks: true,
        ..seed::Variant::default()
    });
    let mut ptr_np = Ptr::new(sn.ocp.clone(), PtrSettings::default()).unwrap();
    g.bench_function("solve_collision_without_peaks", |b| {
        b.iter(|| black_box(ptr_np.solve(&sn.x, &sn.u, &sn.s).unwrap().final_time))
    });
    let mut ptr_cn = Ptr::new(sc.ocp.clone(), clarabel).unwrap();
    g.bench_function("solve_collision_clarabel", |b| {
        b.iter(|| black_box(ptr_cn.solve(&sc.x, &sc.u, &sc.s).unwrap().final_time))
    });
    for (name, collision) in
        [("solve_interval_bounds", false), ("solve_collision_interval_bounds", true)]
    {
        let si = seed::build_with(seed::Variant {
            collision,
            interval_bounds: true,
            ..seed::Variant::default()
        });
        let mut ptr_i = Ptr::new(si.ocp.clone(), PtrSettings::default()).unwrap();
        g.bench_function(name, |b| {
            b.iter(|| black_box(ptr_i.solve(&si.x, &si.u, &si.s).unwrap().final_time))
        });
    }
    let d = &s.ocp.dynamics;
    let mut ws = d.workspace();
    let mut out = d.output(seed::NODES);
    g.bench_function("discretize", |b| {
        b.iter(|| d.discretize(&s.x, &s.u, &s.s, &Default::default(), &mut ws, &mut out).unwrap())
    });
    // The same with the integration grid recorded (what interval bounds need).
    let substeps = armature_scvx::DiscretizationSettings::default().substeps;
    let mut out_g = d.output_with_grid(seed::NODES, substeps);
    g.bench_function("discretize_with_grid", |b| {
        b.iter(|| d.discretize(&s.x, &s.u, &s.s, &Default::default(), &mut ws, &mut out_g).unwrap())
    });
    g.bench_function("defects", |b| {
        b.iter(|| d.defects(&s.x, &s.u, &s.s, &Default::default(), &mut ws, &mut out).unwrap())
    });
    // The collision variant's dynamics: its clearance penalties are inactive almost everywhere.
    let sc = seed::build_collision();
    let dc = &sc.ocp.dynamics;
    let (mut wsc, mut outc) = (dc.workspace(), dc.output(seed::NODES));
    g.bench_function("discretize_collision", |b| {
        b.iter(|| {
            dc.discretize(&sc.x, &sc.u, &sc.s, &Default::default(), &mut wsc, &mut outc).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
