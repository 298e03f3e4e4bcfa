//! Fallback starts: a solve that does not converge is tried again from other initial
//! guesses, one after another, until one converges.
//!
//! Which local solution a solve reaches — and whether it reaches one — depends on its
//! initial guess: the IK path through the waypoints (a redundant arm has a family of
//! configurations at each) and the guess's timing. On the benchmark suite, drawing the branch
//! search's samples from other seeds left three ball tasks of 100 stuck 0.4 mm to 1 cm from a
//! waypoint until the iteration cap, and one iiwa7 task's solution rides an orientation range
//! that its integration grid does not resolve (BENCHMARKS.md); another guess converges on
//! each. The fallbacks cost nothing where the first solve converges.

use armature_scvx::Solution;

use crate::{ArmTask, StartOutcome, StartSummary, start_time_scale, summarize};

/// Fallback start `i` (from 1) of `task`: the same task, its branch search's samples drawn
/// from seed `task.initialization.seed + i` and, once planned, its guess's timing scaled by
/// [`start_time_scale`]`(i)` (0.7, 1.4, …; see [`solve_fallbacks`]). The start
/// configuration is the task's own (a task without one keeps the IK of its first waypoint,
/// which the seed does not change).
///
/// # Example
/// ```
/// let task = armature_arm::fixtures::pick_and_place();
/// let second = armature_arm::fallback_task(&task, 1);
/// assert_eq!(second.initialization.seed, task.initialization.seed + 1);
/// assert_eq!(second.initialization.fallbacks, 0);
/// ```
pub fn fallback_task(task: &ArmTask, i: usize) -> ArmTask {
    let mut t = task.clone();
    t.initialization.seed = task.initialization.seed.wrapping_add(i as u64);
    t.initialization.starts = 1;
    t.initialization.fallbacks = 0;
    t
}

/// The solution kept after the fallback starts, and how each of them ended.
#[derive(Debug, Clone)]
pub struct Fallbacks {
    /// The kept solution: the first converged one; without one, the one whose largest
    /// violation is least (the first solve's on a tie).
    pub solution: Solution,
    /// Which: 0 for the first solve, `i` for fallback start `i`.
    pub kept: usize,
    /// Each fallback start tried, in order (empty when the first solve converged).
    pub tried: Vec<StartSummary>,
}

impl Fallbacks {
    /// The iterations of every solve: the first's, and each fallback's.
    pub fn total_iterations(&self, first_iterations: usize) -> usize {
        first_iterations + self.tried.iter().map(|s| s.iterations).sum::<usize>()
    }
}

/// After `first` — the solve from `task`'s own guess — did not converge, solves fallback
/// starts `1..=task.initialization.fallbacks` ([`fallback_task`], each guess's timing scaled
/// by [`start_time_scale`]`(i)`) one after another, until one converges. A converged `first`
/// is returned as it is. A start that cannot be planned or solved is reported as
/// [`StartOutcome::Failed`] and the next is tried.
///
/// # Example
/// ```
/// let task = armature_arm::fixtures::pick_and_place();
/// let first = task.plan()?.compile()?.solve()?;
/// let kept = armature_arm::solve_fallbacks(&task, first);
/// assert_eq!(kept.kept, 0); // the seed converges: no fallback was needed
/// assert!(kept.tried.is_empty() && kept.solution.converged());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn solve_fallbacks(task: &ArmTask, first: Solution) -> Fallbacks {
    let mut out = Fallbacks { solution: first, kept: 0, tried: Vec::new() };
    for i in 1..=task.initialization.fallbacks {
        if out.solution.converged() {
            break;
        }
        let scale = start_time_scale(i);
        let end = fallback_task(task, i)
            .plan()
            .map_err(|e| e.to_string())
            .and_then(|p| p.time_scaled(scale).compile().map_err(|e| e.to_string()))
            .and_then(|mut c| c.solve().map_err(|e| e.to_string()));
        match end {
            Ok(solution) => {
                out.tried.push(summarize(scale, Ok(&solution)));
                if solution.converged() || largest(&solution) < largest(&out.solution) {
                    (out.solution, out.kept) = (solution, i);
                }
            }
            Err(e) => out.tried.push(StartSummary {
                time_scale: scale,
                ik_samples: None,
                outcome: StartOutcome::Failed(e),
                final_time: f64::NAN,
                iterations: 0,
            }),
        }
    }
    out
}

/// A solution's largest violation (0 when none is reported).
fn largest(s: &Solution) -> f64 {
    s.max_violation.as_ref().map_or(0.0, |v| v.value)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A solve cut short by its iteration cap does not converge; the fallback starts (with
    /// the cap lifted only for them, as another guess) are tried in order and the first that
    /// converges is kept, its summary naming its time scale.
    #[test]
    fn a_solve_that_does_not_converge_is_replaced_by_the_first_converged_fallback() {
        let mut task = crate::fixtures::pick_and_place();
        task.settings.max_iterations = 3;
        let first = task.plan().unwrap().compile().unwrap().solve().unwrap();
        assert!(!first.converged());
        // Fallbacks that cannot converge either: all tried, the least violation kept.
        let stuck = solve_fallbacks(&task, first.clone());
        assert_eq!(stuck.tried.len(), 2);
        assert!(!stuck.solution.converged());
        assert!(largest(&stuck.solution) <= largest(&first));
        assert_eq!(stuck.tried[0].time_scale, start_time_scale(1));
        assert_eq!(stuck.total_iterations(first.iterations), 9);
        // With the cap back for the fallbacks (the task they are drawn from), the first of
        // them converges and the second is not tried.
        let mut lifted = task.clone();
        lifted.settings.max_iterations = 200;
        let kept = solve_fallbacks(&lifted, first);
        assert_eq!((kept.kept, kept.tried.len()), (1, 1));
        assert!(kept.solution.converged());
        assert_eq!(
            kept.tried[0].outcome,
            StartOutcome::Solved(armature_scvx::PtrStatus::Converged)
        );
    }

    /// Fallback tasks draw other samples and leave the rest of the task alone.
    #[test]
    fn fallback_tasks_differ_only_in_their_seed_and_starts() {
        let mut task = crate::fixtures::pick_and_place();
        task.initialization.starts = 3;
        let f = fallback_task(&task, 2);
        assert_eq!(f.initialization.seed, 2);
        assert_eq!((f.initialization.starts, f.initialization.fallbacks), (1, 0));
        let mut back = f.clone();
        back.initialization = task.initialization;
        assert_eq!(back, task);
    }
}
