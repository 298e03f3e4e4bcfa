//! Several starts of one task, solved in parallel (rayon), the best kept: time-optimal
//! trajectories have local optima, and which one a solve reaches depends on its start.
//!
//! A task's starts ([`ArmTask::start`], [`solve_task_starts_with`]) differ in the IK path
//! of their guess: start `i` draws [`start_ik_samples`] random configurations per waypoint
//! for the branch search (8, 64, 512 from the default 8), which then finds other paths
//! through the waypoints' redundant postures, and with them other basins. On the benchmark
//! suite the basin is what keeps a solve above the reference (17 of the 18 decoupled tasks
//! above 1.02 × T_ref sit within 0.8 % of their own basin's optimum), and the best of the
//! first two starts leaves 6 of them (BENCHMARKS.md, 2026-12-08). A plan's starts
//! ([`ArmPlan::solve_multi_start`]) can only scale its guess's timing
//! ([`start_time_scale`]: 1, 0.7, 1.4, 0.49, …), which on today's solver reaches the same
//! basins.

use armature_scvx::{CompiledProblem, ProblemError, PtrStatus, Solution, Time};
use rayon::prelude::*;
use serde::Serialize;

use crate::{ArmPlan, ArmTask};

/// The time scale of start `i`: 1 for the first, then alternately shorter and longer
/// (`0.7^k`, `1.4^k`).
///
/// # Example
/// ```
/// use armature_arm::start_time_scale;
/// assert_eq!(start_time_scale(0), 1.0);
/// assert_eq!(start_time_scale(1), 0.7);
/// assert_eq!(start_time_scale(2), 1.4);
/// assert!((start_time_scale(3) - 0.49).abs() < 1e-12);
/// ```
pub fn start_time_scale(i: usize) -> f64 {
    let k = i.div_ceil(2) as i32;
    if i == 0 {
        1.0
    } else if i % 2 == 1 {
        0.7f64.powi(k)
    } else {
        1.4f64.powi(k)
    }
}

/// The most random configurations per waypoint a start's branch search draws
/// ([`start_ik_samples`]); the CLI's cap on `[initialization] restarts`.
pub const MAX_START_SAMPLES: usize = 1000;

/// The IK branch search's random configurations per waypoint of a task's start `i`, the
/// task's own being `restarts`: eight times more per start (`restarts·8^i`), at most
/// [`MAX_START_SAMPLES`].
///
/// # Example
/// ```
/// use armature_arm::start_ik_samples;
/// assert_eq!((0..4).map(|i| start_ik_samples(8, i)).collect::<Vec<_>>(), [8, 64, 512, 1000]);
/// assert_eq!(start_ik_samples(0, 0), 1);
/// ```
pub fn start_ik_samples(restarts: usize, i: usize) -> usize {
    let factor = 8usize.saturating_pow(u32::try_from(i).unwrap_or(u32::MAX));
    restarts.max(1).saturating_mul(factor).min(MAX_START_SAMPLES.max(restarts))
}

impl ArmTask {
    /// Start `i` of this task's multi-start solve: the same task, its IK branch search
    /// drawing [`start_ik_samples`]`(restarts, i)` random configurations per waypoint (start
    /// 0 is the task itself), one start of its own.
    ///
    /// # Example
    /// ```
    /// let mut task = armature_arm::fixtures::pick_and_place();
    /// task.initialization.starts = 2;
    /// let second = task.start(1);
    /// assert_eq!(second.initialization.restarts, 64);
    /// assert_eq!(second.initialization.starts, 1);
    /// assert_eq!(task.start(0).initialization.restarts, task.initialization.restarts);
    /// ```
    pub fn start(&self, i: usize) -> ArmTask {
        let mut t = self.clone();
        t.initialization.restarts = start_ik_samples(self.initialization.restarts, i);
        t.initialization.starts = 1;
        t
    }
}

/// Solves the starts `first..first + count` of `task` ([`ArmTask::start`]) in parallel, each
/// planned, compiled and solved by `solve(i, compiled)` (through
/// [`CompiledProblem::solve_with`] to watch its iterations): each start's end, in start
/// order, and its summary. A start that cannot be planned ends in [`ProblemError::Bad`].
pub fn solve_task_starts_with<S>(
    task: &ArmTask,
    first: usize,
    count: usize,
    solve: S,
) -> (Vec<Result<Solution, ProblemError>>, Vec<StartSummary>)
where
    S: Fn(usize, &mut CompiledProblem) -> Result<Solution, ProblemError> + Sync,
{
    let planned = |i: usize| {
        let what = format!("start {}", i + 1);
        let plan =
            task.start(i).plan().map_err(|e| ProblemError::Bad { what, reason: e.message })?;
        solve(i, &mut plan.compile()?)
    };
    let ends: Vec<Result<Solution, ProblemError>> =
        (first..first + count).into_par_iter().map(planned).collect();
    let summaries = ends
        .iter()
        .enumerate()
        .map(|(j, end)| summarize_start(task, first + j, end.as_ref()))
        .collect();
    (ends, summaries)
}

/// The summary of `task`'s start `i` ([`ArmTask::start`]): its IK samples per waypoint, and
/// how it ended.
pub fn summarize_start(
    task: &ArmTask,
    i: usize,
    end: Result<&Solution, &ProblemError>,
) -> StartSummary {
    let ik_samples = Some(start_ik_samples(task.initialization.restarts, i));
    StartSummary { ik_samples, ..summarize(1.0, end) }
}

/// How one start ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StartSummary {
    /// The start's time scale ([`start_time_scale`]; 1 for a task's starts).
    pub time_scale: f64,
    /// A task's start ([`ArmTask::start`]): its IK branch search's random configurations per
    /// waypoint ([`start_ik_samples`]); `None` for a plan's starts, which share its IK path.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ik_samples: Option<usize>,
    /// Its outcome: the solver's status, or the error that ended it.
    pub outcome: StartOutcome,
    /// Final time (s; NaN after an error).
    pub final_time: f64,
    /// SCvx iterations (0 after an error).
    pub iterations: usize,
}

/// A start's end: the solver's status, or the problem layer's error.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StartOutcome {
    /// The solver ran: its status.
    Solved(PtrStatus),
    /// The start could not be compiled or solved.
    Failed(String),
}

/// The status word (`converged`, …), or `failed: REASON`.
impl std::fmt::Display for StartOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StartOutcome::Solved(status) => write!(f, "{status}"),
            StartOutcome::Failed(e) => write!(f, "failed: {e}"),
        }
    }
}

/// The best of several starts: its solution and which start it was, and every start's
/// summary.
#[derive(Debug, Clone)]
pub struct MultiStart {
    /// The kept solution: the converged one of least final time; without one, the start
    /// whose largest violation is least.
    pub best: Solution,
    /// The kept start's index in `starts`.
    pub chosen: usize,
    /// Every start, in order.
    pub starts: Vec<StartSummary>,
}

/// Solves `compile(start_time_scale(i))` for the starts `first..first + count` in
/// parallel: each start's end, in start order, and its summary.
pub fn solve_starts<F>(
    first: usize,
    count: usize,
    compile: F,
) -> (Vec<Result<Solution, ProblemError>>, Vec<StartSummary>)
where
    F: Fn(f64) -> Result<CompiledProblem, ProblemError> + Sync,
{
    solve_starts_with(first, count, compile, |_, c| c.solve())
}

/// As [`solve_starts`], each start solved by `solve(i, compiled)`: through
/// [`CompiledProblem::solve_with`] to watch its iterations (start `i`'s own).
pub fn solve_starts_with<F, S>(
    first: usize,
    count: usize,
    compile: F,
    solve: S,
) -> (Vec<Result<Solution, ProblemError>>, Vec<StartSummary>)
where
    F: Fn(f64) -> Result<CompiledProblem, ProblemError> + Sync,
    S: Fn(usize, &mut CompiledProblem) -> Result<Solution, ProblemError> + Sync,
{
    let ends: Vec<Result<Solution, ProblemError>> = (first..first + count)
        .into_par_iter()
        .map(|i| compile(start_time_scale(i)).and_then(|mut c| solve(i, &mut c)))
        .collect();
    let summaries = ends
        .iter()
        .enumerate()
        .map(|(j, end)| summarize(start_time_scale(first + j), end.as_ref()))
        .collect();
    (ends, summaries)
}

/// A start's summary.
pub fn summarize(time_scale: f64, end: Result<&Solution, &ProblemError>) -> StartSummary {
    match end {
        Ok(s) => StartSummary {
            time_scale,
            ik_samples: None,
            outcome: StartOutcome::Solved(s.status),
            final_time: s.final_time,
            iterations: s.iterations,
        },
        Err(e) => StartSummary {
            time_scale,
            ik_samples: None,
            outcome: StartOutcome::Failed(e.to_string()),
            final_time: f64::NAN,
            iterations: 0,
        },
    }
}

/// Which of the starts' ends to keep (`None` when every start failed): the converged
/// solution of least final time; without one, the solution whose largest violation is least.
pub fn best_start(ends: &[Result<Solution, ProblemError>]) -> Option<usize> {
    best_start_by(ends, |_, s| s.final_time)
}

/// As [`best_start`], the converged solutions ranked by `final_time(i, solution)` instead of
/// their own final time: e.g. the final time of start `i`'s path retimed
/// ([`crate::ArmTask::retime`]), which is what a retiming caller delivers.
pub fn best_start_by(
    ends: &[Result<Solution, ProblemError>],
    final_time: impl Fn(usize, &Solution) -> f64,
) -> Option<usize> {
    let rank = |i: usize, s: &Solution| {
        let violation = s.max_violation.as_ref().map_or(0.0, |v| v.value);
        if s.status == PtrStatus::Converged { (0, final_time(i, s)) } else { (1, violation) }
    };
    ends.iter()
        .enumerate()
        .filter_map(|(i, s)| s.as_ref().ok().map(|s| (i, rank(i, s))))
        .min_by(|a, b| a.1.0.cmp(&b.1.0).then(a.1.1.total_cmp(&b.1.1)))
        .map(|(i, _)| i)
}

/// Scales a guess's timing by `scale`: each segment's duration (`dilation_guess`) and a free
/// final time's guess, clamped into its window (the durations follow the clamped ratio). A
/// fixed final time, or a scale that is not a positive number, leaves the timing as it is.
///
/// # Example
/// ```
/// use armature_arm::scale_timing;
/// use armature_scvx::Time;
///
/// let mut time = Time::Free { min: 0.5, max: 4.0, guess: 2.0, minimize: true };
/// let mut dilation = vec![1.0, 1.0, 2.0];
/// scale_timing(&mut time, &mut dilation, 3.0); // 6 s, clamped to 4 s: the ratio is 2
/// assert_eq!(time, Time::Free { min: 0.5, max: 4.0, guess: 4.0, minimize: true });
/// assert_eq!(dilation, [2.0, 2.0, 4.0]);
/// ```
pub fn scale_timing(time: &mut Time, dilation_guess: &mut [f64], scale: f64) {
    let Time::Free { min, max, guess, .. } = time else { return };
    if !(scale > 0.0 && scale.is_finite() && *guess > 0.0) {
        return;
    }
    let scaled = (*guess * scale).clamp(*min, *max);
    let ratio = scaled / *guess;
    *guess = scaled;
    dilation_guess.iter_mut().for_each(|d| *d *= ratio);
}

impl ArmPlan {
    /// This plan with the guess's timing scaled by `scale` ([`scale_timing`]).
    pub fn time_scaled(&self, scale: f64) -> ArmPlan {
        let mut plan = self.clone();
        scale_timing(&mut plan.problem.time, &mut plan.dilation_guess, scale);
        plan
    }

    /// Solves this plan from `starts` time scalings of its guess ([`start_time_scale`]) in
    /// parallel and keeps the best (see [`MultiStart::best`]).
    ///
    /// # Errors
    /// The first start's error when no start could be solved; `starts` of 0.
    ///
    /// # Example
    /// ```
    /// use armature_arm::StartOutcome;
    /// use armature_scvx::PtrStatus;
    ///
    /// let plan = armature_arm::fixtures::pick_and_place().plan()?;
    /// let outcome = plan.solve_multi_start(2)?;
    /// assert_eq!(outcome.starts.len(), 2);
    /// assert_eq!(outcome.best.status, PtrStatus::Converged);
    /// // The kept solution is the fastest of the converged starts.
    /// let converged = StartOutcome::Solved(PtrStatus::Converged);
    /// let mut times = outcome.starts.iter().filter(|s| s.outcome == converged);
    /// assert!(times.all(|s| outcome.best.final_time <= s.final_time));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn solve_multi_start(&self, starts: usize) -> Result<MultiStart, ProblemError> {
        if starts == 0 {
            let (what, reason) = ("multi-start".to_string(), "0 starts".to_string());
            return Err(ProblemError::Bad { what, reason });
        }
        let (mut ends, starts) = solve_starts(0, starts, |s| self.time_scaled(s).compile());
        match best_start(&ends) {
            Some(chosen) => {
                let best = ends.swap_remove(chosen).expect("best_start picks a solution");
                Ok(MultiStart { best, chosen, starts })
            }
            None => Err(ends.swap_remove(0).expect_err("every start failed")),
        }
    }
}
