//! Result files: JSON, CSV per trajectory, written atomically (a temporary file in the
//! same folder, then a rename), so a failed run never leaves a half-written file.

use std::io::Write;
use std::path::{Path, PathBuf};

use armature_scvx::Solution;

use crate::{CliError, exit};

fn io_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError { message: format!("{}: {e}", path.display()), code: exit::IO }
}

/// Writes `bytes` to `path` atomically.
///
/// # Errors
/// An [`exit::IO`] error naming the path.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().ok_or_else(|| io_error(path, "not a file path"))?;
    let tmp = dir.join(format!(".{}.tmp-{}", name.to_string_lossy(), std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(io_error(path, e));
    }
    Ok(())
}

/// Creates `dir` (and parents).
///
/// # Errors
/// An [`exit::IO`] error naming it.
pub fn ensure_dir(dir: &Path) -> Result<(), CliError> {
    std::fs::create_dir_all(dir).map_err(|e| io_error(dir, e))
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
    /// The task's geometry and limits.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<&'a crate::view::Scene>,
    /// The guess and the SCvx iterates (end effector at the nodes).
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    pub iterates: &'a [crate::view::Iterate],
}

/// Writes what was asked for: the JSON result (`-` = standard output) and the CSV tables.
///
/// # Errors
/// Serialization or writing failures ([`exit::IO`]).
pub fn write_solution(
    result: &ResultFile<'_>,
    json: Option<&Path>,
    csv_dir: Option<&Path>,
    out: &mut dyn Write,
) -> Result<Vec<PathBuf>, CliError> {
    let mut written = Vec::new();
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(result)
            .map_err(|e| CliError { message: e.to_string(), code: exit::IO })?;
        if path == Path::new("-") {
            writeln!(out, "{text}").map_err(|e| io_error(path, e))?;
        } else {
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                ensure_dir(dir)?;
            }
            write_atomic(path, text.as_bytes())?;
            written.push(path.to_path_buf());
        }
    }
    if let Some(dir) = csv_dir {
        let solution = result.solution;
        ensure_dir(dir)?;
        for (name, table) in
            [("nodes.csv", &solution.nodes), ("trajectory.csv", &solution.trajectory)]
        {
            let path = dir.join(name);
            write_atomic(&path, csv(table).as_bytes())?;
            written.push(path);
        }
    }
    Ok(written)
}

/// Writes the 3D view of `data` to `path`.
///
/// # Errors
/// Serialization or writing failures ([`exit::IO`]).
pub fn write_html(data: &crate::view::ViewData, path: &Path) -> Result<PathBuf, CliError> {
    let page = crate::view::html(data).map_err(|e| io_error(path, e))?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        ensure_dir(dir)?;
    }
    write_atomic(path, page.as_bytes())?;
    Ok(path.to_path_buf())
}
