//! Random minimum-time double integrators (rest to rest over d ∈ [0.2, 5] m, |a| ≤ 1 m/s²,
//! so T* = 2√d; an odd number of nodes from 5 to 21, so the switch can fall on a node; a
//! straight-line guess of 0.5–10 s; λ_tr ∈ {0.3, 1, 3}), solved with the chosen settings.
//! Prints every run that does not converge within 1 % of T*, and the iteration medians.
//!
//! Run: `cargo run --release -p armature-scvx --example double_integrator_sweep [-- published|lagrangian|qn] [N]`
//! (`published`: constant trust region, λ_vc = 100, ε_tr = 1e-4, as the published PTR;
//! `lagrangian`: the Lagrangian merit with σ = 0.5; `qn`: that and the quasi-Newton model;
//! N runs, default 300).

#[path = "../tests/double_integrator/mod.rs"]
#[allow(dead_code)] // the tests' poor guess
mod double_integrator;

use armature_scvx::{Merit, Ptr, PtrSettings, PtrStatus, TrustRegionUpdate};

/// SplitMix64: a reproducible sequence without a dependency.
struct SplitMix(u64);

impl SplitMix {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.iter().find(|a| a.parse::<usize>().is_err()).cloned().unwrap_or_default();
    let runs = args.iter().find_map(|a| a.parse::<usize>().ok()).unwrap_or(300);
    let mut rng = SplitMix(5);
    let (mut good, mut its) = (0, Vec::new());
    for _ in 0..runs {
        let nodes = 2 * (2 + (rng.unit() * 9.0) as usize) + 1;
        let d = rng.range(0.2, 5.0);
        let guess_time = rng.range(0.5, 10.0);
        let lam_tr = [0.3, 1.0, 3.0][(rng.unit() * 3.0) as usize];
        let mut ocp = double_integrator::problem(nodes, |_, _, _| vec![]);
        ocp.x_final = vec![Some(d), Some(0.0)];
        let x: Vec<f64> =
            (0..nodes).flat_map(|k| [d * k as f64 / (nodes - 1) as f64, 0.0]).collect();
        let mut settings = {
            let mut s = PtrSettings::default();
            s.lam_tr = lam_tr;
            s
        };
        match mode.as_str() {
            "published" => {
                settings.trust_region = TrustRegionUpdate::Constant;
                settings.lam_vc = 1e2;
                settings.eps_tr = 1e-4;
            }
            "lagrangian" => settings.merit = Merit::Lagrangian { sigma: 0.5 },
            "qn" => {
                settings.merit = Merit::Lagrangian { sigma: 0.5 };
                settings.quasi_newton = true;
            }
            _ => {}
        }
        let r = Ptr::new(ocp, settings)
            .unwrap()
            .solve(&x, &vec![0.0; nodes], &vec![guess_time; nodes])
            .expect("sizes match");
        let best = 2.0 * d.sqrt();
        its.push(r.history.len());
        if r.status == PtrStatus::Converged
            && r.final_time >= best - 1e-6
            && r.final_time < 1.01 * best
        {
            good += 1;
        } else {
            println!(
                "{nodes:>2} nodes, d = {d:.3} m, guess {guess_time:.2} s, λ_tr = {lam_tr}: {:?} after {} iterations, T = {:.4} s (T* = {best:.4} s)",
                r.status,
                r.history.len(),
                r.final_time
            );
        }
    }
    its.sort_unstable();
    println!(
        "{good} of {runs} converge within 1 % of T*; iterations: median {}, largest {}",
        its[its.len() / 2],
        its[its.len() - 1]
    );
}
