//! Stopping a solve's minimization once its path, retimed, stops getting faster
//! ([`RetimeStall`]): for a caller that retimes the result, the solve's own timing is not
//! what it delivers.

use armature_scvx::{Iteration, Monitor, SolutionLayout, Steer, Trajectory};
use serde::{Deserialize, Serialize};

use crate::ArmTask;

/// When a solve whose result is retimed ([`ArmTask::retime`]) stops minimizing its own final
/// time and only restores feasibility: once the final time of its iterates' paths retimed
/// (estimated on a coarse grid, [`ArmTask::retimed_final_time`]) has improved by less than
/// `tolerance` (relative) over the last `window` accepted iterates whose largest nodal
/// violation is within `violation_gate`, while the solve's own final time improved by less
/// than `solve_tolerance` over them. It then restores feasibility from the iterate whose path
/// retimed fastest among those whose largest nodal violation is within `rewind_gate`
/// (`rewind`), or from the current one if that is the fastest or none qualifies.
///
/// The solve's own final time belongs to its control parametrization (first-order-hold
/// torques on the nodes); the retiming replaces it with the fastest timing along the path.
/// The path settles earlier than that timing: the last iterations of a minimizing solve
/// improve its own time far more than the retimed one. The retimed time of the early
/// iterates is a noisy signal, though (they still violate the task's nodal constraints, and
/// a path that cuts a corner retimes faster), and a solve whose own time still falls fast
/// is still reshaping its path: `solve_tolerance` waits for that. This trades a little of
/// the retimed time for iterations (measured on the benchmark suite, `BENCHMARKS.md`).
///
/// Minimizing its own time, a solve may also walk its path away from the one that retimes
/// fastest (on some tasks the retimed time rises by several percent while the solve's own
/// falls): the rewind goes back to the best nearly feasible iterate. Its gate is tight because
/// an iterate that still leaves a waypoint or a range cuts a corner that the restoration must
/// put back, at a cost the retimed time does not show.
///
/// # Example
/// ```
/// use armature_arm::RetimeStall;
///
/// // The example tasks stop at the stall, as the CLI's do by default.
/// let mut ur5e = armature_arm::fixtures::ur5e_rigid_body();
/// assert_eq!(ur5e.retime_stall, Some(RetimeStall::default()));
/// let solution = ur5e.plan()?.compile()?.solve()?;
/// assert!(solution.converged());
/// // The last iterations only restored feasibility.
/// assert!(solution.history.last().unwrap().feasibility);
/// let retimed = ur5e.retime(&solution)?;
/// assert!(retimed.final_time < solution.final_time);
/// // The record starts again with each solve: the same problem stalls at the same point.
/// let mut compiled = ur5e.plan()?.compile()?;
/// let (first, again) = (compiled.solve()?, compiled.solve()?);
/// assert_eq!(first.iterations, solution.iterations);
/// assert_eq!(again.iterations, solution.iterations);
/// // It stopped minimizing before a solve minimizing to the end stops, within 1 % of its
/// // retimed time.
/// let minimizing = solution.history.iter().take_while(|it| !it.feasibility).count();
/// ur5e.retime_stall = None;
/// let full = ur5e.plan()?.compile()?.solve()?;
/// assert!(minimizing < full.iterations);
/// assert!(retimed.final_time < 1.01 * ur5e.retime(&full)?.final_time);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RetimeStall {
    /// Relative improvement of the best retimed final time below which the path has
    /// stalled. Default 0.002.
    pub tolerance: f64,
    /// Accepted, gated iterates over which the improvement is measured. Default 4.
    pub window: usize,
    /// Largest nodal violation of an iterate that counts (its path may still leave a
    /// waypoint or an orientation range by this much). Default 1e-2.
    pub violation_gate: f64,
    /// Relative improvement of the solve's own final time over the same window below which
    /// the solve is no longer reshaping its path fast (1 or more: not required). Default
    /// 0.02.
    pub solve_tolerance: f64,
    /// Points of the coarse retiming grid (at least 4 per segment). Default 200.
    pub points: usize,
    /// At the stall, restore feasibility from the counted iterate whose path retimed fastest
    /// ([`Steer::RestoreFeasibilityFromKept`]) rather than from the current one. Default true.
    pub rewind: bool,
    /// Largest nodal violation of an iterate that may be kept to rewind to. Default 1e-4.
    pub rewind_gate: f64,
}

impl Default for RetimeStall {
    fn default() -> Self {
        RetimeStall {
            tolerance: 0.002,
            window: 4,
            violation_gate: 1e-2,
            solve_tolerance: 0.02,
            points: 200,
            rewind: true,
            rewind_gate: 1e-4,
        }
    }
}

impl RetimeStall {
    /// Whether the settings are usable: a tolerance in `[0, 1)`, a window of 1 or more,
    /// positive gates, a solve tolerance of 0 or more, 10 points or more.
    pub fn is_valid(&self) -> bool {
        (0.0..1.0).contains(&self.tolerance)
            && self.solve_tolerance >= 0.0
            && self.window >= 1
            && self.violation_gate > 0.0
            && self.rewind_gate > 0.0
            && self.points >= 10
    }

    /// The monitor for a solve of `task` whose iterates `layout` names (what
    /// [`ArmPlan::compile`](crate::ArmPlan::compile) sets when the task asks for it, for a
    /// caller compiling the problem itself).
    pub fn monitor(self, task: ArmTask, layout: SolutionLayout) -> Monitor {
        // Per counted iterate: the best retimed time so far, and the solve's own.
        let mut seen: Vec<(f64, f64)> = Vec::new();
        let mut last_iteration = 0;
        // The retimed time of the iterate kept to rewind to.
        let mut kept: Option<f64> = None;
        Monitor::new(move |it: &Iteration, t: &Trajectory<'_>| {
            // A new solve of the same problem starts its own record.
            if it.iteration <= last_iteration {
                seen.clear();
                kept = None;
            }
            last_iteration = it.iteration;
            // A NaN violation (no candidate evaluated) does not count either.
            let gated = it.max_violation <= self.violation_gate;
            if !it.accepted || !gated {
                return Steer::Continue;
            }
            let Ok(tables) = layout.nodal_series(t) else { return Steer::Continue };
            let ends = layout.nodal_control_ends(t);
            let Ok(time) = task.retimed_final_time(&tables, Some(&ends), self.points) else {
                return Steer::Continue;
            };
            let keepable = self.rewind && it.max_violation <= self.rewind_gate;
            let new_best = keepable && kept.is_none_or(|k| time < k);
            if new_best {
                kept = Some(time);
            }
            let so_far = seen.last().map_or(time, |b| b.0.min(time));
            seen.push((so_far, t.final_time));
            Self::steer(self.stalled(&seen), new_best, kept.is_some_and(|k| k < time))
        })
    }

    /// The answer to a counted iterate: at a stall, restore feasibility — from the kept
    /// iterate if it retimes faster than this one (`kept_faster`), else from here; before it,
    /// keep this iterate if it is the fastest nearly feasible one so far (`new_best`).
    fn steer(stalled: bool, new_best: bool, kept_faster: bool) -> Steer {
        match (stalled, kept_faster, new_best) {
            (true, true, _) => Steer::RestoreFeasibilityFromKept,
            (true, false, _) => Steer::RestoreFeasibilityOnly,
            (false, _, true) => Steer::Keep,
            (false, _, false) => Steer::Continue,
        }
    }

    /// Whether, over the window, the best retimed time (first of each pair in `seen`)
    /// improved by less than `tolerance` and the solve's own (second) by less than
    /// `solve_tolerance`.
    fn stalled(&self, seen: &[(f64, f64)]) -> bool {
        let Some(back) = seen.len().checked_sub(self.window + 1) else { return false };
        let (now, then) = (seen[seen.len() - 1], seen[back]);
        now.0 >= (1.0 - self.tolerance) * then.0 && now.1 >= (1.0 - self.solve_tolerance) * then.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stall_is_a_window_without_enough_improvement() {
        let rule = RetimeStall {
            tolerance: 0.01,
            window: 2,
            solve_tolerance: 0.05,
            ..RetimeStall::default()
        };
        let own = |best: &[f64]| best.iter().map(|&b| (b, 1.3)).collect::<Vec<_>>();
        assert!(!rule.stalled(&own(&[1.0, 1.0])), "a window needs window + 1 values");
        assert!(rule.stalled(&own(&[1.0, 1.0, 0.995])));
        assert!(!rule.stalled(&own(&[1.0, 1.0, 0.985])));
        assert!(!rule.stalled(&own(&[1.2, 1.0, 0.995])), "measured from window iterates back");
        // The solve's own time still falling fast: its path is still changing.
        assert!(!rule.stalled(&[(1.0, 1.4), (1.0, 1.35), (0.995, 1.3)]));
        assert!(rule.stalled(&[(1.0, 1.34), (1.0, 1.32), (0.995, 1.3)]));
        assert!(RetimeStall::default().is_valid());
        // What it answers: rewind only to a kept iterate that retimes faster.
        assert_eq!(RetimeStall::steer(true, false, true), Steer::RestoreFeasibilityFromKept);
        assert_eq!(RetimeStall::steer(true, true, false), Steer::RestoreFeasibilityOnly);
        assert_eq!(RetimeStall::steer(true, false, false), Steer::RestoreFeasibilityOnly);
        assert_eq!(RetimeStall::steer(false, true, false), Steer::Keep);
        assert_eq!(RetimeStall::steer(false, false, true), Steer::Continue);
        for bad in [
            RetimeStall { tolerance: 1.0, ..RetimeStall::default() },
            RetimeStall { tolerance: f64::NAN, ..RetimeStall::default() },
            RetimeStall { window: 0, ..RetimeStall::default() },
            RetimeStall { violation_gate: 0.0, ..RetimeStall::default() },
            RetimeStall { points: 9, ..RetimeStall::default() },
            RetimeStall { solve_tolerance: -0.1, ..RetimeStall::default() },
            RetimeStall { rewind_gate: f64::NAN, ..RetimeStall::default() },
        ] {
            assert!(!bad.is_valid(), "{bad:?}");
        }
    }
}
