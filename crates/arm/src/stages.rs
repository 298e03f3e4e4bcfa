//! How the solves of one task ended: the starts of a multi-start solve and the stages of a
//! mesh refinement, as the pipeline ([`ArmTask::solve`](crate::ArmTask::solve)) and the CLI's
//! result file report them.

use armature_scvx::{PtrStatus, Solution};
use serde::Serialize;

use crate::StartSummary;

/// The stages of a mesh refinement: which one the result is, and how each ended.
///
/// # Example
/// ```
/// use armature_arm::{KeptStage, RefinementReport, StageSummary};
/// use armature_scvx::PtrStatus;
///
/// let stage = |nodes, iterations, final_time| StageSummary {
///     nodes,
///     status: PtrStatus::Converged,
///     iterations,
///     final_time,
/// };
/// let report = RefinementReport {
///     factor: 2,
///     kept: KeptStage::Refined,
///     first_stage: stage(16, 20, 1.089),
///     refined_stage: Some(stage(31, 9, 1.0495)),
/// };
/// let json = serde_json::to_value(&report).unwrap();
/// assert_eq!(json["kept"], "refined");
/// assert_eq!(json["first_stage"]["status"], "converged");
/// assert_eq!(json["refined_stage"]["nodes"], 31);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinementReport {
    /// The factor: every node interval of the first stage split in this many.
    pub factor: usize,
    /// Which stage's solution the result is.
    pub kept: KeptStage,
    /// The first stage, on the task's nodes.
    pub first_stage: StageSummary,
    /// The refined stage, from the first stage's solution (none when the first stage did not
    /// converge: it is then the result, not refined).
    pub refined_stage: Option<StageSummary>,
}

/// Which stage of a mesh refinement the result is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KeptStage {
    /// The refined stage converged: the result is its solution (its `iterations` count both
    /// stages').
    Refined,
    /// The first stage's solution: it did not converge, or the refined stage did not.
    FirstStage,
}

/// How one stage of a refinement ended: its grid, status, own iterations and final time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageSummary {
    /// Its nodes.
    pub nodes: usize,
    /// Its status.
    pub status: PtrStatus,
    /// Its own iterations.
    pub iterations: usize,
    /// Its final time (s).
    pub final_time: f64,
}

impl StageSummary {
    /// The summary of a stage's `solution`.
    pub fn of(solution: &Solution) -> StageSummary {
        StageSummary {
            nodes: solution.nodes.get("time").map_or(0, Vec::len),
            status: solution.status,
            iterations: solution.iterations,
            final_time: solution.final_time,
        }
    }
}

/// The starts of a multi-start solve: which one the result is, and how each ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StartsReport {
    /// The kept start's index in `each` (0: the guess's own timing).
    pub kept: usize,
    /// Every start, in order (`final_time` is null for a start that ended in an error).
    pub each: Vec<StartSummary>,
    /// When the result is retimed: each start's final time once retimed along its path (null
    /// for a start that did not converge); the kept start is the least of these.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub retimed_final_times: Vec<Option<f64>>,
}
