//! Several starts of one task: the guess's timing scaled per start, solved in parallel, the
//! fastest converged solution kept.

use armature_arm::{StartOutcome, best_start, best_start_by, fixtures, start_time_scale};
use armature_scvx::{ProblemError, PtrStatus, Solution, Time};

fn free_time(time: &Time) -> f64 {
    match time {
        Time::Free { guess, .. } => *guess,
        Time::Fixed(t) => *t,
    }
}

/// Each start is the solve of the plan with its guess's timing scaled (the same iterations
/// and final time as solving that plan alone), and the kept one is the fastest converged.
#[test]
fn several_starts_keep_the_fastest_converged_one() {
    let plan = fixtures::pick_and_place().plan().unwrap();
    let outcome = plan.solve_multi_start(2).unwrap();
    let scales: Vec<f64> = outcome.starts.iter().map(|s| s.time_scale).collect();
    assert_eq!(scales, [1.0, start_time_scale(1)]);
    let shorter = plan.time_scaled(0.7);
    assert!((free_time(&shorter.problem.time) - 0.7 * free_time(&plan.problem.time)).abs() < 1e-12);
    for (d, d0) in shorter.dilation_guess.iter().zip(&plan.dilation_guess) {
        assert!((d - 0.7 * d0).abs() < 1e-12);
    }
    let alone = shorter.compile().unwrap().solve().unwrap();
    let second = &outcome.starts[1];
    assert_eq!((second.final_time, second.iterations), (alone.final_time, alone.iterations));
    assert_eq!(second.outcome, StartOutcome::Solved(alone.status));
    let converged: Vec<f64> = outcome
        .starts
        .iter()
        .filter(|s| s.outcome == StartOutcome::Solved(PtrStatus::Converged))
        .map(|s| s.final_time)
        .collect();
    assert!(!converged.is_empty());
    let fastest = converged.iter().copied().fold(f64::INFINITY, f64::min);
    assert_eq!(outcome.best.status, PtrStatus::Converged);
    assert_eq!(outcome.best.final_time, fastest);
    assert_eq!(outcome.starts[outcome.chosen].final_time, fastest);
    assert!(plan.solve_multi_start(0).is_err());
}

/// The rule: a converged solution before any other, the least final time among them;
/// without one, the least largest violation; nothing when every start failed.
#[test]
fn best_start_prefers_converged_then_the_least_violation() {
    let mut plan = fixtures::pick_and_place().plan().unwrap();
    plan.settings.max_iterations = 2;
    let unfinished: Solution = plan.compile().unwrap().solve().unwrap();
    assert_eq!(unfinished.status, PtrStatus::MaxIterations);
    let violation = unfinished.max_violation.clone().expect("a violation after 2 iterations");
    let with = |status: PtrStatus, final_time: f64, value: f64| {
        let mut s = unfinished.clone();
        (s.status, s.final_time) = (status, final_time);
        s.max_violation = Some(armature_scvx::Violation { value, ..violation.clone() });
        Ok::<Solution, ProblemError>(s)
    };
    let failed = || Err(ProblemError::Bad { what: "start".into(), reason: "failed".into() });
    let converged = PtrStatus::Converged;
    let stalled = PtrStatus::Stalled;
    // Converged first, then the least final time among the converged.
    let ends = [with(stalled, 0.5, 0.0), with(converged, 1.3, 0.0), with(converged, 1.2, 0.0)];
    assert_eq!(best_start(&ends), Some(2));
    // Nothing converged: the least largest violation, whatever the final time.
    let ends = [failed(), with(stalled, 0.9, 1e-2), with(stalled, 1.5, 1e-4)];
    assert_eq!(best_start(&ends), Some(2));
    assert_eq!(best_start(&[failed(), failed()]), None);
    assert_eq!(best_start(&[]), None);
    // Ranked by another final time (a retiming's): the converged start it calls fastest.
    let ends = [with(converged, 1.2, 0.0), with(converged, 1.3, 0.0), with(stalled, 0.5, 0.0)];
    let retimed = [1.15, 1.1, 0.4];
    assert_eq!(best_start_by(&ends, |i, _| retimed[i]), Some(1));
    assert_eq!(best_start_by(&ends, |_, s| s.final_time), best_start(&ends));
}

/// `solve_starts_with` hands each start's compiled problem to the caller's solve: watching
/// it sees that start's own iterations, and the ends are those of `solve_starts`.
#[test]
fn starts_solved_by_the_caller_report_their_own_iterations() {
    let mut plan = fixtures::pick_and_place().plan().unwrap();
    plan.settings.max_iterations = 6;
    let compile = |s: f64| plan.time_scaled(s).compile();
    let seen: Vec<std::sync::Mutex<Vec<usize>>> = (0..3).map(|_| Default::default()).collect();
    let (ends, summaries) = armature_arm::solve_starts_with(1, 3, compile, |i, c| {
        let mut its = Vec::new();
        let end = c.solve_with(|it, _| its.push(it.iteration));
        *seen[i - 1].lock().unwrap() = its;
        end
    });
    let (plain, _) = armature_arm::solve_starts(1, 3, compile);
    for (j, (end, same)) in ends.iter().zip(&plain).enumerate() {
        let (end, same) = (end.as_ref().unwrap(), same.as_ref().unwrap());
        assert_eq!((end.final_time, end.iterations), (same.final_time, same.iterations));
        assert_eq!(summaries[j].time_scale, start_time_scale(j + 1));
        let its = seen[j].lock().unwrap().clone();
        assert_eq!(its, (1..=end.iterations).collect::<Vec<_>>(), "start {}", j + 1);
    }
}
