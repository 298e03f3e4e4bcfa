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
/// violation is within `violation_gate`.
///
/// The solve's own final time belongs to its control parametrization (first-order-hold
/// torques on the nodes); the retiming replaces it with the fastest timing along the path.
/// The path settles earlier than that timing: the last iterations of a minimizing solve
/// improve its own time far more than the retimed one. This trades a little of the retimed
/// time for iterations (measured on the benchmark suite, `BENCHMARKS.md`).
///
/// # Example
/// ```
/// use armature_arm::RetimeStall;
///
/// let mut seed = armature_arm::fixtures::pick_and_place();
/// seed.retime_stall = Some(RetimeStall::default());
/// let solution = seed.plan()?.compile()?.solve()?;
/// assert!(solution.converged());
/// // The last iterations only restored feasibility.
/// assert!(solution.history.last().unwrap().feasibility);
/// let retimed = seed.retime(&solution)?;
/// assert!(retimed.final_time < solution.final_time);
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
    /// Points of the coarse retiming grid (at least 4 per segment). Default 200.
    pub points: usize,
}

impl Default for RetimeStall {
    fn default() -> Self {
        RetimeStall { tolerance: 0.002, window: 4, violation_gate: 1e-2, points: 200 }
    }
}

impl RetimeStall {
    /// Whether the settings are usable: a tolerance in `[0, 1)`, a window of 1 or more, a
    /// positive gate, 10 points or more.
    pub fn is_valid(&self) -> bool {
        (0.0..1.0).contains(&self.tolerance)
            && self.window >= 1
            && self.violation_gate > 0.0
            && self.points >= 10
    }

    /// The monitor for a solve of `task` whose iterates `layout` names (what
    /// [`ArmPlan::compile`](crate::ArmPlan::compile) sets when the task asks for it, for a
    /// caller compiling the problem itself).
    pub fn monitor(self, task: ArmTask, layout: SolutionLayout) -> Monitor {
        let mut best: Vec<f64> = Vec::new();
        Monitor::new(move |it: &Iteration, t: &Trajectory<'_>| {
            // A NaN violation (no candidate evaluated) does not count either.
            let gated = it.max_violation <= self.violation_gate;
            if !it.accepted || !gated {
                return Steer::Continue;
            }
            let Ok(tables) = layout.nodal_tables(t) else { return Steer::Continue };
            let Ok(time) = task.retimed_final_time(&tables, self.points) else {
                return Steer::Continue;
            };
            let so_far = best.last().map_or(time, |b| b.min(time));
            best.push(so_far);
            if self.stalled(&best) { Steer::RestoreFeasibilityOnly } else { Steer::Continue }
        })
    }

    /// Whether the running best `best` improved by less than the tolerance over the window.
    fn stalled(&self, best: &[f64]) -> bool {
        best.len() > self.window
            && best[best.len() - 1] >= (1.0 - self.tolerance) * best[best.len() - 1 - self.window]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stall_is_a_window_without_enough_improvement() {
        let rule = RetimeStall { tolerance: 0.01, window: 2, ..RetimeStall::default() };
        assert!(!rule.stalled(&[1.0, 1.0]), "a window needs window + 1 values");
        assert!(rule.stalled(&[1.0, 1.0, 0.995]));
        assert!(!rule.stalled(&[1.0, 1.0, 0.985]));
        assert!(!rule.stalled(&[1.2, 1.0, 0.995]), "measured from window iterates back");
        assert!(RetimeStall::default().is_valid());
        for bad in [
            RetimeStall { tolerance: 1.0, ..RetimeStall::default() },
            RetimeStall { tolerance: f64::NAN, ..RetimeStall::default() },
            RetimeStall { window: 0, ..RetimeStall::default() },
            RetimeStall { violation_gate: 0.0, ..RetimeStall::default() },
            RetimeStall { points: 9, ..RetimeStall::default() },
        ] {
            assert!(!bad.is_valid(), "{bad:?}");
        }
    }
}
