//! Multi-start: a task solved from three IK paths through its waypoints side by side on
//! rayon's threads ([`ArmTask::start`](armature_arm::ArmTask::start): the branch search with
//! 8, 64 and 512 random configurations per waypoint finds other postures of the redundant
//! arm), the start whose path retimes fastest kept ([`ArmTask::solve`](armature_arm::ArmTask::solve)
//! with `Initialization::starts = 3`). Each start can end at another local optimum: on this
//! task of the benchmark suite's kind the first start's basin is 10 % slower than the
//! second's. In a task file: `[initialization] starts = 3`.
//!
//! `cargo run --release -p armature-arm --example multi_start`

use armature_arm::{Pipeline, StartOutcome, fixtures};
use armature_scvx::PtrStatus;

/// Runs the example (its asserts are its test: `tests/gallery.rs`).
pub(crate) fn main() {
    let mut task = fixtures::pick_and_place();
    // The benchmark suite's arm7-03: the pick at (0.329, −0.275, 0.075), the place at
    // (0.302, 0.131, 0.057), lifts of 12.2 cm.
    let (pick, place, lift) =
        ([0.329235, -0.275445, 0.075101], [0.301894, 0.130708, 0.057237], 0.121535);
    let above = |p: [f64; 3]| [p[0], p[1], p[2] + lift];
    for (w, p) in
        task.waypoints.iter_mut().skip(1).zip([above(pick), pick, above(pick), above(place), place])
    {
        w.position = p;
    }
    task.initialization.starts = 3;
    let solved = task.solve(Pipeline { refine: Some(1), retime: true }).unwrap();
    let report = solved.starts.as_ref().unwrap();
    for (i, s) in report.each.iter().enumerate() {
        let kept = if i == report.kept { "  (kept)" } else { "" };
        let retimed =
            report.retimed_final_times[i].map_or(String::new(), |t| format!(", retimed {t:.4} s"));
        println!(
            "start {} ({} IK samples per waypoint): {}, T = {:.4} s{retimed}, {} iterations{kept}",
            i + 1,
            s.ik_samples.unwrap(),
            s.outcome,
            s.final_time,
            s.iterations
        );
    }
    assert_eq!(solved.solution.status, PtrStatus::Converged);
    let converged = StartOutcome::Solved(PtrStatus::Converged);
    let best = solved.retimed.unwrap().unwrap().final_time;
    for (s, t) in report.each.iter().zip(&report.retimed_final_times) {
        if s.outcome == converged {
            assert!(best <= t.unwrap());
        }
    }
    // Another path than the first start's is kept, and faster by more than 5 %.
    assert_ne!(report.kept, 0);
    assert!(best < 0.95 * report.retimed_final_times[0].unwrap());
}
