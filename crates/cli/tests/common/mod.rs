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
