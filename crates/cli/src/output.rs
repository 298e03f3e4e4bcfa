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

/// Writes what was asked for: the JSON result (`-` = standard output) and the CSV tables.
///
/// # Errors
/// Serialization or writing failures ([`exit::IO`]).
pub fn write_solution(
    solution: &Solution,
    json: Option<&Path>,
    csv_dir: Option<&Path>,
    out: &mut dyn Write,
) -> Result<Vec<PathBuf>, CliError> {
    let mut written = Vec::new();
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(solution)
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
