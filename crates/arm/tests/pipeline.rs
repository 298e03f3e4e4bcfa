//! The whole solve of a task in one call (`ArmTask::solve`): each step is the one its own
//! function takes, composed as the CLI composes them.

use armature_arm::{
    KeptStage, Pipeline, PipelineError, StartOutcome, TaskItem, fixtures, keep_refined,
    set_refined_guess,
};
use armature_scvx::{PtrStatus, Solution};

/// The refined stage of the pipeline is the one `set_refined_guess` and `keep_refined` make
/// from the first stage's solution; the report says so, the task is the refined one and the
/// retiming is that solution's (one start: the starts are the test below's).
#[test]
fn the_default_pipeline_refines_and_retimes_the_seed() {
    let mut seed = fixtures::pick_and_place();
    seed.initialization.starts = 1;
    let solved = seed.solve(Pipeline::default()).unwrap();
    let coarse = seed.plan().unwrap().compile().unwrap().solve().unwrap();
    let mut fine = seed.refined(2).plan().unwrap().compile().unwrap();
    set_refined_guess(&mut fine, &coarse, 2).unwrap();
    let fine = fine.solve().unwrap();
    let (coarse_iterations, fine_iterations) = (coarse.iterations, fine.iterations);
    let both = keep_refined(coarse, fine).into_solution();
    assert_eq!(solved.solution.final_time, both.final_time);
    assert_eq!(solved.solution.iterations, both.iterations);
    assert_eq!(solved.total_iterations, coarse_iterations + fine_iterations);
    assert_eq!(solved.task, seed.refined(2));
    let report = solved.refinement.as_ref().unwrap();
    assert_eq!((report.factor, report.kept), (2, KeptStage::Refined));
    assert_eq!(report.first_stage.iterations, coarse_iterations);
    let fine_report = report.refined_stage.as_ref().unwrap();
    assert_eq!((fine_report.nodes, fine_report.iterations), (31, fine_iterations));
    let retimed = solved.retimed.unwrap().unwrap();
    let again = solved.task.retime(&solved.solution).unwrap();
    assert_eq!(retimed.final_time, again.final_time);
    assert!(solved.starts.is_none());
    assert_eq!(solved.fallbacks, (vec![], 0));
}

/// `refine: Some(1)` solves once on the task's own grid; `retime: false` leaves the result
/// unretimed.
#[test]
fn one_stage_without_retiming() {
    let mut seed = fixtures::pick_and_place();
    seed.initialization.starts = 1;
    let solved = seed.solve(Pipeline { refine: Some(1), retime: false }).unwrap();
    let alone = seed.plan().unwrap().compile().unwrap().solve().unwrap();
    assert_eq!(
        (solved.solution.final_time, solved.solution.iterations),
        (alone.final_time, alone.iterations)
    );
    assert_eq!(solved.total_iterations, alone.iterations);
    assert!(solved.refinement.is_none() && solved.retimed.is_none());
    assert_eq!(solved.task, seed);
}

/// With two starts (the default) — the task's own IK path and the one its branch search
/// finds with eight times the samples (`ArmTask::start`) — the kept one is the start whose
/// path retimes fastest, each start's retimed final time reported; every start's iterations
/// are counted, and each start is the solve of its own task.
#[test]
fn several_starts_keep_the_fastest_retimed_path() {
    let seed = fixtures::pick_and_place();
    assert_eq!(seed.initialization.starts, 2);
    let solved = seed.solve(Pipeline { refine: Some(1), retime: true }).unwrap();
    let starts = solved.starts.as_ref().unwrap();
    let samples: Vec<Option<usize>> = starts.each.iter().map(|s| s.ik_samples).collect();
    assert_eq!(samples, [Some(8), Some(64)]);
    assert!(starts.each.iter().all(|s| s.time_scale == 1.0));
    let second = seed.start(1).plan().unwrap().compile().unwrap().solve().unwrap();
    assert_eq!(
        (starts.each[1].final_time, starts.each[1].iterations),
        (second.final_time, second.iterations)
    );
    let retimed: Vec<f64> = starts.retimed_final_times.iter().map(|t| t.unwrap()).collect();
    let fastest = retimed.iter().copied().fold(f64::INFINITY, f64::min);
    assert_eq!(retimed[starts.kept], fastest);
    assert_eq!(solved.retimed.unwrap().unwrap().final_time, fastest);
    let kept = &starts.each[starts.kept];
    assert_eq!(kept.outcome, StartOutcome::Solved(PtrStatus::Converged));
    assert_eq!(
        (kept.final_time, kept.iterations),
        (solved.solution.final_time, solved.solution.iterations)
    );
    let all: usize = starts.each.iter().map(|s| s.iterations).sum();
    assert_eq!(solved.total_iterations, all);
}

/// A first stage that does not converge, nor do its fallbacks (each capped as the task is):
/// it is the result, not refined nor retimed, the report naming it; every solve's iterations
/// counted.
#[test]
fn a_first_stage_that_does_not_converge_is_the_result() {
    let mut seed = fixtures::pick_and_place();
    seed.settings.max_iterations = 3;
    let solved = seed.solve(Pipeline::default()).unwrap();
    assert_eq!(solved.solution.status, PtrStatus::MaxIterations);
    let (tried, kept) = &solved.fallbacks;
    assert_eq!(tried.len(), seed.initialization.fallbacks);
    assert!(*kept <= tried.len());
    let starts = seed.initialization.starts;
    assert_eq!(solved.starts.as_ref().map(|r| r.each.len()), Some(starts));
    assert_eq!(solved.total_iterations, 3 * (starts + tried.len()));
    let report = solved.refinement.unwrap();
    assert_eq!((report.kept, report.refined_stage), (KeptStage::FirstStage, None));
    assert_eq!(report.first_stage.status, PtrStatus::MaxIterations);
    assert!(solved.retimed.is_none());
    assert_eq!(solved.task, seed);
}

/// Bad refinements and infeasible tasks are errors before any solve; a task whose refined
/// grid would pass the node limit is solved once by default.
#[test]
fn errors_come_before_solving() {
    let seed = fixtures::pick_and_place();
    for factor in [0, 200] {
        let e = seed.solve(Pipeline { refine: Some(factor), retime: true }).unwrap_err();
        assert_eq!(e, PipelineError::Refine { factor });
        assert!(e.to_string().contains(&format!("refine {factor}")), "{e}");
    }
    let mut far = seed.clone();
    far.waypoints[5].position = [1.5, 0.25, 0.05];
    match far.solve(Pipeline::default()) {
        Err(PipelineError::Task(e)) => assert_eq!(e.item, TaskItem::Waypoint(5)),
        other => panic!("{:?}", other.map(|s| s.solution.status)),
    }
}

/// The solution's own grid: a refined result has the refined task's nodes.
#[test]
fn the_task_returned_is_the_grid_of_the_solution() {
    let seed = fixtures::pick_and_place();
    let solved = seed.solve(Pipeline::default()).unwrap();
    let nodes = |s: &Solution| s.nodes["time"].len();
    assert_eq!(nodes(&solved.solution), solved.task.nodes);
}
