//! Running the real `armature` binary from the integration tests.
#![allow(dead_code)]

use std::process::Command;

/// Runs `armature ARGS`: (exit code, stdout, stderr).
pub(crate) fn armature(args: &[&str]) -> (i32, String, String) {
    let out =
        Command::new(env!("CARGO_BIN_EXE_armature")).args(args).output().expect("the binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

/// A fresh temporary folder `armature-cli-TAG-…` for one test, removed with everything in it
/// when dropped.
pub(crate) fn scratch(tag: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("armature-cli-{tag}-")).tempdir().unwrap()
}

/// A file written to its own [`scratch`] folder, which lives as long as this value: it
/// dereferences to the file's path, and siblings (`with_file_name`) land in the same folder.
pub(crate) struct TempFile {
    _dir: tempfile::TempDir,
    path: std::path::PathBuf,
}

impl std::ops::Deref for TempFile {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.path
    }
}

/// Writes `text` to `name` in a fresh scratch folder tagged `tag`.
pub(crate) fn temp_file(tag: &str, name: &str, text: &str) -> TempFile {
    let dir = scratch(tag);
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    TempFile { _dir: dir, path }
}

/// A task solve that ended at a solution: converged (exit 0), or converged at the nodes with
/// a constraint broken on the dense trajectory (exit 3, status `violated_between_nodes`, the
/// largest violation a dense check with its time). The shipped examples converge; edited
/// tasks may end either way.
pub(crate) fn assert_solved(code: i32, result: &serde_json::Value, stderr: &str) {
    match result["status"].as_str() {
        Some("converged") => assert_eq!(code, 0, "{stderr}"),
        Some("violated_between_nodes") => {
            assert_eq!(code, 3, "{stderr}");
            let v = &result["max_violation"];
            assert!(
                v["constraint"].as_str().is_some_and(|c| c.ends_with("(dense)"))
                    && v["time"].is_number()
                    && v["value"].as_f64().is_some_and(|x| x > 1e-4),
                "{v}"
            );
            assert!(stderr.contains("converged at the nodes, but the dense trajectory violates"));
        }
        other => panic!("status {other:?}: {stderr}"),
    }
}
