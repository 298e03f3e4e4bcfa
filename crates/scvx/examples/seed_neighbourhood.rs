//! The seed solve over a neighbourhood of its settings: initial trust-region weight λ_tr ∈
//! {0.5, 1, 2} × RK4 substeps ∈ {8, 10, 12} (with `wide`: λ_tr ∈ {0.25, …, 4} × substeps ∈
//! {6, 8, 10, 12, 16}), for the four variants (plain or collision, with or without interval
//! bounds). Prints iterations, final time, solve time and outcome per run — converged and
//! meeting the acceptance test's task, or what it missed — and the medians. A first-order
//! PTR stop is a short step; where the merit keeps rejecting steps (the CTCS integral's
//! blind linearization) the count and the final time swing with any setting, and one lucky
//! run says little.
//!
//! Run: `cargo run --release -p armature-scvx --example seed_neighbourhood [-- wide] [lagrangian|qn] [nopeaks]`
//! (`lagrangian`: the Lagrangian merit with σ = 0.5; `qn`: that and the quasi-Newton model;
//! `nopeaks`: the collision variants without the clearances' peak rows between the nodes).

#[path = "../tests/seed/mod.rs"]
mod seed;

use armature_scvx::{Merit, Ptr, PtrSettings, PtrStatus};

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let has = |flag: &str| std::env::args().any(|a| a == flag);
    let (weights, substeps): (&[f64], &[usize]) = if has("wide") {
        (&[0.25, 0.5, 1.0, 2.0, 4.0], &[6, 8, 10, 12, 16])
    } else {
        (&[0.5, 1.0, 2.0], &[8, 10, 12])
    };
    // Every setting runs the four variants back to back, so that each collision/plain time
    // ratio compares runs that saw the same phase of a machine whose speed drifts.
    let variants: Vec<(bool, bool)> =
        [false, true].into_iter().flat_map(|i| [(false, i), (true, i)]).collect();
    let seeds: Vec<seed::Seed> = variants
        .iter()
        .map(|&(collision, interval_bounds)| {
            seed::build_with(seed::Variant {
                collision,
                interval_bounds,
                without_clearance_peaks: has("nopeaks"),
                ..seed::Variant::default()
            })
        })
        .collect();
    // Per variant: one line per setting, and (iterations, final time, ms, meets the task).
    let mut lines = vec![Vec::new(); variants.len()];
    let mut runs: Vec<Vec<(f64, f64, f64, bool)>> = vec![Vec::new(); variants.len()];
    for &lam_tr in weights {
        for &substeps in substeps {
            for (v, (&(collision, _), s)) in variants.iter().zip(&seeds).enumerate() {
                let mut settings = {
                    let mut s = PtrSettings::default();
                    s.lam_tr = lam_tr;
                    s.discretization.substeps = substeps;
                    s
                };
                if has("lagrangian") || has("qn") {
                    settings.merit = Merit::Lagrangian { sigma: 0.5 };
                }
                settings.quasi_newton = has("qn");
                let mut ptr = Ptr::new(s.ocp.clone(), settings).unwrap();
                let t0 = std::time::Instant::now();
                let r = ptr.solve(&s.x, &s.u, &s.s).expect("sizes match");
                let elapsed = t0.elapsed().as_secs_f64() * 1e3;
                let (good, outcome) = match (r.status, seed::check(s, &r).missed(collision)) {
                    (PtrStatus::Converged, None) => (true, "meets the task".to_string()),
                    (PtrStatus::Converged, Some(miss)) => (false, format!("Converged, but {miss}")),
                    (status, _) => (false, format!("{status:?}")),
                };
                lines[v].push(format!(
                    "{:<28} {lam_tr:>4} {substeps:>8} {:>4} {:>8.4} {elapsed:>10.1}  {outcome}",
                    name(variants[v]),
                    r.history.len(),
                    r.final_time,
                ));
                runs[v].push((r.history.len() as f64, r.final_time, elapsed, good));
            }
        }
    }
    println!("variant                      λ_tr substeps  its        T    solve ms  outcome");
    for (v, &variant) in variants.iter().enumerate() {
        for line in &lines[v] {
            println!("{line}");
        }
        let column =
            |f: fn(&(f64, f64, f64, bool)) -> f64| -> Vec<f64> { runs[v].iter().map(f).collect() };
        println!(
            "{:<28} median        {:>4} {:>8.4} {:>10.1}  {} of {} meet the task\n",
            name(variant),
            median(&mut column(|r| r.0)),
            median(&mut column(|r| r.1)),
            median(&mut column(|r| r.2)),
            runs[v].iter().filter(|r| r.3).count(),
            runs[v].len()
        );
    }
    // Collision / plain solve time at each setting (variants 1 / 0 and 3 / 2).
    for (c, p) in [(1, 0), (3, 2)] {
        let mut ratios: Vec<f64> =
            runs[c].iter().zip(&runs[p]).map(|(rc, rp)| rc.2 / rp.2).collect();
        let (lo, hi) =
            ratios.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &r| (a.min(r), b.max(r)));
        println!(
            "{} / {}: solve time ratio per setting, median {:.2} (range {lo:.2}–{hi:.2})",
            name(variants[c]),
            name(variants[p]),
            median(&mut ratios)
        );
    }
}

/// A variant's name from (collision, interval bounds).
fn name((collision, interval_bounds): (bool, bool)) -> String {
    format!(
        "{}{}",
        if collision { "collision" } else { "plain" },
        if interval_bounds { " + interval bounds" } else { "" }
    )
}
