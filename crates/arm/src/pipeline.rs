//! The whole solve of a task in one call, as the CLI runs it ([`ArmTask::solve`]): the starts,
//! the fallback starts, the mesh refinement and the retiming around the solver.

use armature_scvx::{MAX_NODES, ProblemError, PtrStatus, Solution};
use serde::{Deserialize, Serialize};

use crate::{
    ArmError, ArmTask, Fallbacks, KeptStage, Refinement, RefinementReport, Retimed, StageSummary,
    StartSummary, StartsReport, best_start_by, keep_refined, set_refined_guess, solve_fallbacks,
    solve_task_starts_with,
};

/// What [`ArmTask::solve`] runs around the solver (the task's own settings say how each
/// solve runs, how many starts and fallbacks it has: [`ArmTask::initialization`]).
///
/// # Example
/// ```
/// use armature_arm::Pipeline;
///
/// // The defaults: the dynamics model's refinement, the result retimed.
/// assert_eq!(Pipeline::default(), Pipeline { refine: None, retime: true });
/// let one_stage: Pipeline = serde_json::from_str(r#"{ "refine": 1 }"#).unwrap();
/// assert_eq!(one_stage, Pipeline { refine: Some(1), retime: true });
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Pipeline {
    /// The mesh refinement's factor (1: one stage; see [`ArmTask::refined`]). Default `None`:
    /// the dynamics model's ([`DynamicsModel::default_refine`](crate::DynamicsModel::default_refine)),
    /// or one stage where its refined grid would pass [`MAX_NODES`].
    pub refine: Option<usize>,
    /// Retime the converged result along its path within the limits ([`ArmTask::retime`]); with
    /// several starts, the kept start is then the one whose path retimes fastest. Default true.
    pub retime: bool,
}

impl Default for Pipeline {
    fn default() -> Self {
        Pipeline { refine: None, retime: true }
    }
}

/// Errors of [`ArmTask::solve`]: the task's and the problem layer's, never solver outcomes
/// (those are the [`Solved::solution`]'s status).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PipelineError {
    /// The task cannot become a problem (or is infeasible as checked before solving).
    #[error(transparent)]
    Task(#[from] ArmError),
    /// The problem could not be built or solved.
    #[error(transparent)]
    Problem(#[from] ProblemError),
    /// A refinement factor of 0, or one whose grid would pass [`MAX_NODES`].
    #[error("refine {factor}: need 1 or more, and at most {MAX_NODES} nodes once refined")]
    Refine {
        /// The factor asked for.
        factor: usize,
    },
}

/// What [`ArmTask::solve`] returns: the kept solution, the task whose grid it lies on, its
/// retiming, and how every start and stage ended.
#[derive(Debug, Clone)]
pub struct Solved {
    /// The kept solution (with a refinement that converged: both stages joined,
    /// [`join_stages`](crate::join_stages)).
    pub solution: Solution,
    /// The task whose nodes the solution has: the refined task when the refined stage is
    /// kept, the task itself otherwise.
    pub task: ArmTask,
    /// With [`Pipeline::retime`] and a converged solution: its retiming, or why it failed.
    pub retimed: Option<Result<Retimed, ArmError>>,
    /// With more than one start: which was kept and how each ended.
    pub starts: Option<StartsReport>,
    /// The fallback starts tried after the first stage did not converge (empty when it did),
    /// and which solve was kept (0: the first, `i`: fallback `i`).
    pub fallbacks: (Vec<StartSummary>, usize),
    /// With a refinement: how each stage ended and which one the solution is.
    pub refinement: Option<RefinementReport>,
    /// The iterations of every solve run: starts, fallbacks and stages, kept or not.
    pub total_iterations: usize,
}

impl ArmTask {
    /// Plans and solves this task as the CLI does: from [`Initialization::starts`](crate::Initialization::starts)
    /// timings in parallel (the best kept, [`best_start_by`]), from its fallback starts when that
    /// does not converge ([`solve_fallbacks`]), then, converged, again on a grid
    /// [`Pipeline::refine`] times finer from that solution (kept when it converges,
    /// [`keep_refined`]), and the result retimed along its path ([`ArmTask::retime`]).
    ///
    /// # Errors
    /// [`PipelineError`]: the task's (before solving, as [`ArmTask::plan`]), the problem
    /// layer's, or a refinement factor out of range.
    ///
    /// # Example
    /// ```
    /// use armature_arm::{KeptStage, Pipeline};
    ///
    /// let seed = armature_arm::fixtures::pick_and_place();
    /// let solved = seed.solve(Pipeline::default())?;
    /// assert!(solved.solution.converged());
    /// // Refined by the model's default: 16 nodes, then 31.
    /// let report = solved.refinement.as_ref().unwrap();
    /// assert_eq!((report.first_stage.nodes, solved.task.nodes), (16, 31));
    /// assert_eq!(report.kept, KeptStage::Refined);
    /// // Retimed along its path, no slower than the solve's own timing.
    /// let retimed = solved.retimed.unwrap()?;
    /// assert!(retimed.final_time <= solved.solution.final_time * (1.0 + 1e-9));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn solve(&self, pipeline: Pipeline) -> Result<Solved, PipelineError> {
        let factor = self.refinement_factor(pipeline.refine)?;
        let plan = self.plan()?;
        let (first, starts, chosen_retimed, iterations) =
            self.solve_first_stage(&plan, pipeline)?;
        let Fallbacks { solution, kept, tried } = solve_fallbacks(self, first);
        let total_iterations = iterations + tried.iter().map(|s| s.iterations).sum::<usize>();
        // The kept start's retiming serves while its solution is the result.
        let mut retimed = chosen_retimed.filter(|_| kept == 0);
        let mut solved = Solved {
            solution,
            task: self.clone(),
            retimed: None,
            starts,
            fallbacks: (tried, kept),
            refinement: None,
            total_iterations,
        };
        if factor > 1 {
            solved = self.refine_stage(factor, solved)?;
            if solved.refinement.as_ref().is_some_and(|r| r.kept == KeptStage::Refined) {
                retimed = None;
            }
        }
        if pipeline.retime && solved.solution.converged() {
            let again = || solved.task.retime(&solved.solution);
            solved.retimed = Some(retimed.map_or_else(again, Ok));
        }
        Ok(solved)
    }

    /// The mesh refinement's factor on this task's grid for [`Pipeline::refine`]: the given
    /// one, or the dynamics model's ([`DynamicsModel::default_refine`](crate::DynamicsModel::default_refine))
    /// where its refined grid, `(N − 1)·k + 1` nodes, stays within [`MAX_NODES`] (one stage
    /// otherwise).
    ///
    /// # Errors
    /// [`PipelineError::Refine`] for a given factor of 0 or one whose grid would pass
    /// [`MAX_NODES`].
    ///
    /// # Example
    /// ```
    /// let seed = armature_arm::fixtures::pick_and_place();
    /// assert_eq!(seed.refinement_factor(None), Ok(2));
    /// assert!(seed.refinement_factor(Some(0)).is_err());
    /// ```
    pub fn refinement_factor(&self, refine: Option<usize>) -> Result<usize, PipelineError> {
        let fits = |k: usize| self.nodes.saturating_sub(1).saturating_mul(k) < MAX_NODES;
        match refine {
            None => {
                let k = self.dynamics.default_refine();
                Ok(if fits(k) { k } else { 1 })
            }
            Some(factor) if factor >= 1 && fits(factor) => Ok(factor),
            Some(factor) => Err(PipelineError::Refine { factor }),
        }
    }

    /// The first stage: one start, or the best of several ([`ArmTask::start`]: other IK
    /// paths; by their retimed final times when retiming, each start's retiming kept for the
    /// chosen one); the starts' report and their iterations.
    fn solve_first_stage(
        &self,
        plan: &crate::ArmPlan,
        pipeline: Pipeline,
    ) -> Result<(Solution, Option<StartsReport>, Option<Retimed>, usize), PipelineError> {
        let starts = self.initialization.starts.max(1);
        if starts == 1 {
            let solution = plan.compile()?.solve()?;
            let iterations = solution.iterations;
            return Ok((solution, None, None, iterations));
        }
        // Each start plans its own IK path (start 0's is `plan`'s, planned again: a few ms).
        let (mut ends, each) = solve_task_starts_with(self, 0, starts, |_, c| c.solve());
        let total = each.iter().map(|s| s.iterations).sum();
        let mut retimed: Vec<Option<Retimed>> = match pipeline.retime {
            true => ends
                .iter()
                .map(|e| self.retime(e.as_ref().ok().filter(|s| s.converged())?).ok())
                .collect(),
            false => Vec::new(),
        };
        let retimed_time = |i: usize| retimed.get(i).and_then(Option::as_ref).map(|r| r.final_time);
        let time = |i: usize, s: &Solution| retimed_time(i).unwrap_or(s.final_time);
        let Some(kept) = best_start_by(&ends, time) else {
            return Err(ends.swap_remove(0).expect_err("every start failed").into());
        };
        let retimed_final_times = (0..ends.len()).map(retimed_time).collect();
        let report = StartsReport { kept, each, retimed_final_times };
        let chosen = retimed.get_mut(kept).and_then(Option::take);
        let best = ends.swap_remove(kept).expect("best_start_by picks a solution");
        Ok((best, Some(report), chosen, total))
    }

    /// The refined stage after `solved`'s first stage: solved from it when it converged,
    /// kept when it converges too ([`keep_refined`]); the report either way.
    fn refine_stage(&self, factor: usize, solved: Solved) -> Result<Solved, PipelineError> {
        let first_stage = StageSummary::of(&solved.solution);
        if solved.solution.status != PtrStatus::Converged {
            let kept = KeptStage::FirstStage;
            let report = RefinementReport { factor, kept, first_stage, refined_stage: None };
            return Ok(Solved { refinement: Some(report), ..solved });
        }
        let task = self.refined(factor);
        let mut fine = task.plan()?.compile()?;
        set_refined_guess(&mut fine, &solved.solution, factor)?;
        let fine = fine.solve()?;
        let total_iterations = solved.total_iterations + fine.iterations;
        let refined_stage = Some(StageSummary::of(&fine));
        let (solution, task, kept) = match keep_refined(solved.solution, fine) {
            Refinement::Refined(both) => (both, task, KeptStage::Refined),
            Refinement::KeptFirstStage { first, .. } => (first, solved.task, KeptStage::FirstStage),
        };
        let refinement = Some(RefinementReport { factor, kept, first_stage, refined_stage });
        Ok(Solved { solution, task, refinement, total_iterations, ..solved })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The model's factor unless given; one stage where the model's refined grid would pass
    /// the node limit; a given factor past it, or 0, an error.
    #[test]
    fn the_refinement_factor_fits_the_node_limit() {
        let mut task = crate::fixtures::pick_and_place();
        assert_eq!(task.refinement_factor(None), Ok(2));
        assert_eq!(task.refinement_factor(Some(3)), Ok(3));
        assert_eq!(task.refinement_factor(Some(0)), Err(PipelineError::Refine { factor: 0 }));
        // (N − 1)·k + 1 nodes: 1 000 intervals refined by 2 would be 2 001 nodes.
        task.nodes = 1_001;
        assert_eq!(task.refinement_factor(None), Ok(1));
        assert_eq!(task.refinement_factor(Some(2)), Err(PipelineError::Refine { factor: 2 }));
        task.nodes = 1_000;
        assert_eq!(task.refinement_factor(None), Ok(2));
        let rigid = crate::fixtures::ur5e_rigid_body();
        assert_eq!(rigid.refinement_factor(None), Ok(1));
    }
}
