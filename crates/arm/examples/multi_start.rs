//! Multi-start: the seed's collision variant solved from three timings of its guess (× 1,
//! 0.7 and 1.4) side by side on rayon's threads, the fastest converged solution kept
//! ([`ArmPlan::solve_multi_start`](armature_arm::ArmPlan::solve_multi_start)). Each start can
//! end at another local optimum. In a task file: `[initialization] starts = 3`.
//!
//! `cargo run --release -p armature-arm --example multi_start`

use armature_arm::{StartOutcome, fixtures};
use armature_scvx::PtrStatus;

/// Runs the example (its asserts are its test: `tests/gallery.rs`).
pub(crate) fn main() {
    let plan = fixtures::pick_and_place_collision().plan().unwrap();
    let outcome = plan.solve_multi_start(3).unwrap();
    for (i, s) in outcome.starts.iter().enumerate() {
        let kept = if i == outcome.chosen { "  (kept)" } else { "" };
        println!(
            "start {} (guess timing × {:.2}): {:?}, T = {:.4} s, {} iterations{kept}",
            i + 1,
            s.time_scale,
            s.outcome,
            s.final_time,
            s.iterations
        );
    }
    assert_eq!(outcome.best.status, PtrStatus::Converged);
    let converged = StartOutcome::Solved(PtrStatus::Converged);
    for s in outcome.starts.iter().filter(|s| s.outcome == converged) {
        assert!(outcome.best.final_time <= s.final_time);
    }
}
