//! Result files: JSON, CSV per trajectory, the 3D view, staged in an [`OutputSet`] so a run's
//! files are renamed into place together and a failed run leaves none of its files.

use std::io::Write;
use std::path::Path;

use armature_scvx::Solution;

use crate::output_set::OutputSet;
use crate::{CliError, exit};

fn io_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError { message: format!("{}: {e}", path.display()), code: exit::IO }
}

/// One CSV table: `time` first, then every other series flattened as `name[i]`.
pub fn csv(table: &std::collections::BTreeMap<String, Vec<Vec<f64>>>) -> String {
    let mut names: Vec<&String> = table.keys().filter(|k| *k != "time").collect();
    names.sort();
    names.insert(0, table.keys().find(|k| *k == "time").expect("every table has a time"));
    let mut out = String::new();
    let mut header = Vec::new();
    for n in &names {
        let width = table[*n].first().map_or(0, Vec::len);
        if width == 1 {
            header.push((*n).clone());
        } else {
            header.extend((0..width).map(|i| format!("{n}[{i}]")));
        }
    }
    out.push_str(&header.join(","));
    out.push('\n');
    let rows = table[names[0]].len();
    for r in 0..rows {
        let mut line = Vec::with_capacity(header.len());
        for n in &names {
            line.extend(table[*n][r].iter().map(|v| format!("{v}")));
        }
        out.push_str(&line.join(","));
        out.push('\n');
    }
    out
}

/// A result file: the solver's [`Solution`] with, for a task, the scene the 3D view draws
/// and the iterates it can show.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct ResultFile<'a> {
    /// The solution (its keys at the top level).
    #[serde(flatten)]
    pub solution: &'a Solution,
    /// The solved path retimed (`[time] retime`): what is streamed and shown.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub retimed: Option<&'a crate::retimed::RetimedResult>,
    /// The task's geometry and limits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<&'a crate::view::Scene>,
    /// The guess and the SCvx iterates (end effector at the nodes).
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub iterates: &'a [crate::view::Iterate],
    /// With `[initialization] starts > 1`: how every start ended and which was kept.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub starts: Option<&'a StartsReport>,
    /// With a mesh refinement (`[nodes] refine`, by default the dynamics model's): how each
    /// stage ended and which one the result is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refinement: Option<&'a RefinementReport>,
}

/// The stages of a mesh refinement: which one the result is, and how each ended.
///
/// # Example
/// ```
/// use armature_cli::output::{KeptStage, RefinementReport, StageSummary};
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
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KeptStage {
    /// The refined stage converged: the result is its solution (its `iterations` count both
    /// stages').
    Refined,
    /// The first stage's solution: it did not converge, or the refined stage did not.
    FirstStage,
}

/// How one stage of a refinement ended: its grid, status, own iterations and final time.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StageSummary {
    /// Its nodes.
    pub nodes: usize,
    /// Its status.
    pub status: armature_scvx::PtrStatus,
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
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct StartsReport {
    /// The kept start's index in `each` (0: the guess's own timing).
    pub kept: usize,
    /// Every start, in order (`final_time` is null for a start that ended in an error).
    pub each: Vec<armature_arm::StartSummary>,
    /// With `[time] retime`: each start's final time once retimed along its path (null for
    /// a start that did not converge); the kept start is the least of these.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub retimed_final_times: Vec<Option<f64>>,
}

/// Stages what was asked for in `set`: the JSON result (`-` = standard output, written at
/// once) and the CSV tables (`retimed.csv` with a retimed trajectory; without one, a
/// `retimed.csv` already in the folder is removed on commit).
///
/// # Errors
/// Serialization or writing failures ([`exit::IO`]).
pub fn write_solution(
    result: &ResultFile<'_>,
    json: Option<&Path>,
    csv_dir: Option<&Path>,
    out: &mut dyn Write,
    set: &mut OutputSet,
) -> Result<(), CliError> {
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(result)
            .map_err(|e| CliError { message: e.to_string(), code: exit::IO })?;
        if path == Path::new("-") {
            writeln!(out, "{text}").map_err(|e| io_error(path, e))?;
        } else {
            set.stage(path, text.as_bytes())?;
        }
    }
    if let Some(dir) = csv_dir {
        let solution = result.solution;
        for (name, table) in
            [("nodes.csv", &solution.nodes), ("trajectory.csv", &solution.trajectory)]
        {
            set.stage(&dir.join(name), csv(table).as_bytes())?;
        }
        // Without a retimed trajectory, an earlier run's `retimed.csv` goes.
        match result.retimed {
            Some(r) => set.stage(&dir.join("retimed.csv"), csv(&r.trajectory).as_bytes())?,
            None => set.retire(&dir.join("retimed.csv")),
        }
    }
    Ok(())
}

/// Stages the 3D view of `data` for `path` in `set`.
///
/// # Errors
/// Serialization or writing failures ([`exit::IO`]).
pub fn write_html(
    data: &crate::view::ViewData,
    path: &Path,
    set: &mut OutputSet,
) -> Result<(), CliError> {
    let page = crate::view::html(data).map_err(|e| io_error(path, e))?;
    set.stage(path, page.as_bytes())
}
