//! The seed solve over a neighbourhood of its settings: initial trust-region weight λ_tr ∈
//! {0.5, 1, 2} × RK4 substeps ∈ {8, 10, 12}, for the four variants (plain or collision, with
//! or without interval bounds). Prints iterations, final time and solve time per run, and the
//! medians. A first-order PTR stop is a short step; where the merit keeps rejecting steps
//! (the CTCS integral's blind linearization) the count and the final time swing with any
//! setting, and one lucky run says little.
//!
//! Run: `cargo run --release -p armature-scvx --example seed_neighbourhood`

#[path = "../tests/seed/mod.rs"]
mod seed;

use armature_scvx::{DiscretizationSettings, Ptr, PtrSettings};

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    println!("variant                      λ_tr substeps  its        T    solve ms");
    for interval_bounds in [false, true] {
        for collision in [false, true] {
            let s = seed::build_with(seed::Variant { collision, interval_bounds });
            let name = format!(
                "{}{}",
                if collision { "collision" } else { "plain" },
                if interval_bounds { " + interval bounds" } else { "" }
            );
            let (mut its, mut tf, mut ms) = (Vec::new(), Vec::new(), Vec::new());
            for lam_tr in [0.5, 1.0, 2.0] {
                for substeps in [8, 10, 12] {
                    let settings = PtrSettings {
                        lam_tr,
                        discretization: DiscretizationSettings { substeps, ..Default::default() },
                        ..PtrSettings::default()
                    };
                    let mut ptr = Ptr::new(s.ocp.clone(), settings);
                    let t0 = std::time::Instant::now();
                    let r = ptr.solve(&s.x, &s.u, &s.s).expect("sizes match");
                    let elapsed = t0.elapsed().as_secs_f64() * 1e3;
                    println!(
                        "{name:<28} {lam_tr:>4} {substeps:>8} {:>4} {:>8.4} {elapsed:>10.1}  {:?}",
                        r.history.len(),
                        r.final_time,
                        r.status
                    );
                    its.push(r.history.len() as f64);
                    tf.push(r.final_time);
                    ms.push(elapsed);
                }
            }
            println!(
                "{name:<28} median        {:>4} {:>8.4} {:>10.1}\n",
                median(&mut its),
                median(&mut tf),
                median(&mut ms)
            );
        }
    }
}
