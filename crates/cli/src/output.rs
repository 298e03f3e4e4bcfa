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

/// The reports of the starts and stages, as the library's pipeline makes them
/// ([`armature_arm::ArmTask::solve`]).
pub use armature_arm::{KeptStage, RefinementReport, StageSummary, StartsReport};

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
