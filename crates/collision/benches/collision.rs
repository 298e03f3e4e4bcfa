//! The seed's collision pairs (3 self + 4 link–sphere): exact distances and gradients per
//! configuration, against the seed's sampled formulation (4×4 samples per self pair, 4 per
//! obstacle pair, through vmap) compiled to the symbolic tape.

use std::hint::black_box;

use armature_collision::CollisionModel;
use armature_kinematics::robots;
use armature_symbolic::{Expr, Function};
use criterion::{Criterion, criterion_group, criterion_main};

fn sampled_formulation(angle: &Expr) -> Vec<Expr> {
    let arm = robots::arm7();
    let fk = arm.symbolic_fk(angle).unwrap();
    let kp = |n: &str| fk.position(n).unwrap().clone();
    let links = [
        ("base", "shoulder", 0.06),
        ("shoulder", "elbow", 0.05),
        ("elbow", "wrist", 0.04),
        ("wrist", "ee", 0.035),
    ];
    let ts: Vec<f64> = (0..4).map(|i| i as f64 / 3.0).collect();
    let tt: Vec<f64> = ts.iter().flat_map(|&a| ts.iter().flat_map(move |&b| [a, b])).collect();
    let mut outs = Vec::new();
    for i in 0..links.len() {
        for j in i + 2..links.len() {
            let (pa0, pa1, ra) = (kp(links[i].0), kp(links[i].1), links[i].2);
            let (pb0, pb1, rb) = (kp(links[j].0), kp(links[j].1), links[j].2);
            outs.push(Expr::vmap(&tt, 2, |t| {
                let (s, u) = (t.at(0), t.at(1));
                ((1.0 - &s) * &pa0 + &s * &pa1 - ((1.0 - &u) * &pb0 + &u * &pb1)).norm2()
                    - (ra + rb)
            }));
        }
    }
    let c = Expr::constant_vector(&[0.35, 0.0, 0.25]);
    for (a, b, r) in links {
        let (p0, p1) = (kp(a), kp(b));
        outs.push(Expr::vmap(&ts, 1, |t| ((1.0 - t) * &p0 + t * &p1 - &c).norm2() - (0.06 + r)));
    }
    outs
}

fn bench(c: &mut Criterion) {
    let arm = robots::arm7();
    let model = CollisionModel::seed_arm7(&arm).unwrap();
    let mut ws = model.workspace(&arm);
    let q = [0.1, 0.6, -0.2, -1.2, 0.3, 2.17, 0.4];
    let mut g = c.benchmark_group("collision");
    g.bench_function("seed_7_pairs_exact_distances_gradients", |b| {
        b.iter(|| {
            model.evaluate(&arm, black_box(&q), &mut ws, true).unwrap();
        })
    });
    let angle = Expr::variable("angle", 7);
    let f = Function::compile(&sampled_formulation(&angle), &[&[angle.clone()]]).unwrap();
    let mut fws = f.workspace();
    let mut v = vec![0.0; f.n_outputs()];
    let mut jac = vec![0.0; f.jacobian_pattern().nnz()];
    g.bench_function("seed_sampled_formulation_tape_values_jacobian", |b| {
        b.iter(|| f.eval(black_box(&q), &mut fws, &mut v, Some(&mut jac)).unwrap())
    });
    let fk = arm.symbolic_fk(&angle).unwrap();
    let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
    let exact: Vec<Expr> =
        model.symbolic_distances(&positions).into_iter().map(|(_, e)| e).collect();
    let fe = Function::compile(&exact, &[&[angle]]).unwrap();
    let mut ews = fe.workspace();
    let mut ev = vec![0.0; fe.n_outputs()];
    let mut ejac = vec![0.0; fe.jacobian_pattern().nnz()];
    g.bench_function("seed_exact_pair_nodes_tape_values_jacobian", |b| {
        b.iter(|| fe.eval(black_box(&q), &mut ews, &mut ev, Some(&mut ejac)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
