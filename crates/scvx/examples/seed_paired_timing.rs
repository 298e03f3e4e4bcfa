//! Paired timing of the seed's variants: the plain solve, the collision variant (with and
//! without the clearances' peak rows) and both with interval bounds, alternated in one
//! process so that every variant sees the same phases of a machine whose speed drifts, then
//! the median of each, its ratio to the plain solve and the medians of its discretization
//! and subproblem times. Criterion's benches
//! (`cargo bench -p armature-scvx --bench seed`) measure the variants one after another, so
//! their ratios move with the machine's phase; these do not.
//!
//! Run: `cargo run --release -p armature-scvx --example seed_paired_timing [-- ROUNDS [VARIANT…]]`
//! (default 15 rounds, all five variants; name some — `plain`, `collision`,
//! `collision-without-peak-rows`, `interval-bounds`, `collision-interval-bounds` — to
//! alternate only those; the ratios are then to the first of them).

#[path = "../tests/seed/mod.rs"]
mod seed;

use armature_scvx::{Ptr, PtrSettings};
use seed::Variant;

fn main() {
    let rounds: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(15).max(1);
    let variants = [
        ("plain", Variant::default()),
        ("collision", Variant { collision: true, ..Variant::default() }),
        (
            "collision without peak rows",
            Variant { collision: true, without_clearance_peaks: true, ..Variant::default() },
        ),
        ("interval bounds", Variant { interval_bounds: true, ..Variant::default() }),
        (
            "collision + interval bounds",
            Variant { collision: true, interval_bounds: true, ..Variant::default() },
        ),
    ];
    // Named variants only (`plain`, `collision`, …: a prefix of the name), else all five.
    let only: Vec<String> = std::env::args().skip(2).collect();
    let variants: Vec<_> = variants
        .into_iter()
        .filter(|(name, _)| {
            let slug = name.replace(" + ", " ").replace(' ', "-");
            only.is_empty() || only.contains(&slug)
        })
        .collect();
    let seeds: Vec<seed::Seed> = variants.iter().map(|(_, v)| seed::build_with(*v)).collect();
    let mut solvers: Vec<Ptr> =
        seeds.iter().map(|s| Ptr::new(s.ocp.clone(), PtrSettings::default()).unwrap()).collect();
    let mut times = vec![Vec::with_capacity(rounds); seeds.len()];
    let mut outcome = vec![(0, 0.0); seeds.len()];
    let mut parts = vec![(Vec::new(), Vec::new()); seeds.len()];
    for _ in 0..rounds {
        for (i, s) in seeds.iter().enumerate() {
            let t = std::time::Instant::now();
            let r = solvers[i].solve(&s.x, &s.u, &s.s).expect("the seed's sizes match");
            times[i].push(t.elapsed().as_secs_f64() * 1e3);
            outcome[i] = (r.history.len(), r.final_time);
            parts[i].0.push(r.timings.discretization_ms);
            parts[i].1.push(r.timings.subproblem_ms);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let medians: Vec<f64> = times.iter_mut().map(median).collect();
    println!(
        "variant                       its        T   median ms   ratio   discr. ms   subpr. ms"
    );
    for (i, (name, _)) in variants.iter().enumerate() {
        let (d, s) = &mut parts[i];
        println!(
            "{name:28} {:4} {:8.4} {:11.1} {:7.2} {:11.1} {:11.1}",
            outcome[i].0,
            outcome[i].1,
            medians[i],
            medians[i] / medians[0],
            median(d),
            median(s)
        );
    }
    println!(
        "({rounds} rounds, medians; the ratio of each to the first; the discretizations' and the \
         subproblems' shares of each solve)"
    );
}
