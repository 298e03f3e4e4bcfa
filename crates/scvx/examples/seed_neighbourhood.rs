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

use armature_scvx::{DiscretizationSettings, Merit, Ptr, PtrSettings, PtrStatus};

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
    println!("variant                      λ_tr substeps  its        T    solve ms  outcome");
    for interval_bounds in [false, true] {
        for collision in [false, true] {
            let s = seed::build_with(seed::Variant {
                collision,
                interval_bounds,
                without_clearance_peaks: has("nopeaks"),
            });
            let name = format!(
                "{}{}",
                if collision { "collision" } else { "plain" },
                if interval_bounds { " + interval bounds" } else { "" }
            );
            let (mut its, mut tf, mut ms, mut good) = (Vec::new(), Vec::new(), Vec::new(), 0);
            for &lam_tr in weights {
                for &substeps in substeps {
                    let mut settings = PtrSettings {
                        lam_tr,
                        discretization: DiscretizationSettings { substeps, ..Default::default() },
                        ..PtrSettings::default()
                    };
                    if has("lagrangian") || has("qn") {
                        settings.merit = Merit::Lagrangian { sigma: 0.5 };
                    }
                    settings.quasi_newton = has("qn");
                    let mut ptr = Ptr::new(s.ocp.clone(), settings);
                    let t0 = std::time::Instant::now();
                    let r = ptr.solve(&s.x, &s.u, &s.s).expect("sizes match");
                    let elapsed = t0.elapsed().as_secs_f64() * 1e3;
                    let outcome = match (r.status, seed::check(&s, &r).missed(collision)) {
                        (PtrStatus::Converged, None) => {
                            good += 1;
                            "meets the task".to_string()
                        }
                        (PtrStatus::Converged, Some(miss)) => format!("Converged, but {miss}"),
                        (status, _) => format!("{status:?}"),
                    };
                    println!(
                        "{name:<28} {lam_tr:>4} {substeps:>8} {:>4} {:>8.4} {elapsed:>10.1}  {outcome}",
                        r.history.len(),
                        r.final_time,
                    );
                    its.push(r.history.len() as f64);
                    tf.push(r.final_time);
                    ms.push(elapsed);
                }
            }
            println!(
                "{name:<28} median        {:>4} {:>8.4} {:>10.1}  {good} of {} meet the task\n",
                median(&mut its),
                median(&mut tf),
                median(&mut ms),
                its.len()
            );
        }
    }
}
