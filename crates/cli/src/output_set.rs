//! The outputs of one run as one set: every file is first written to a temporary file beside
//! its destination, and only when all of them are written are they renamed into place, in
//! one go, with each destination folder locked (so two runs on the same paths do not mix
//! their files). A failure before that removes the temporaries: the old files
//! stay as they were and nothing half-written is left.
//!
//! An interrupt (SIGINT, SIGTERM, SIGHUP; [`install_interrupt_cleanup`]) removes the
//! temporaries of every uncommitted set and exits with [`exit::INTERRUPTED`]; a commit in
//! progress finishes first, so a set is in place whole or not at all.
//!
//! Destinations are checked before the solve ([`check_destinations`]): an existing
//! destination must be a regular file (not a device, folder or pipe) and not one of the
//! run's inputs. A destination that is a symlink is written through: the file it points to is
//! replaced and the link kept.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::{CliError, exit};

/// Numbers the temporary files of this process.
static COUNTER: AtomicUsize = AtomicUsize::new(0);

/// The temporaries of every staged, uncommitted output of this process.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn forget(tmps: &mut Vec<PathBuf>, staged: &[Staged]) {
    tmps.retain(|p| !staged.iter().any(|s| &s.tmp == p));
}

/// Installs (once per process) the interrupt handler: on SIGINT, SIGTERM or SIGHUP it
/// removes every pending temporary, says so on standard error and exits with
/// [`exit::INTERRUPTED`].
pub fn install_interrupt_cleanup() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // Without a handler (another one installed by an embedding program), the default
        // action still ends the process; only the cleanup is lost.
        let _ = ctrlc::set_handler(|| {
            let tmps = pending();
            for p in tmps.iter() {
                let _ = std::fs::remove_file(p);
            }
            eprintln!("error: interrupted; no output of this run was written");
            std::process::exit(exit::INTERRUPTED);
        });
    });
}

fn io_error(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError { message: format!("{}: {e}", path.display()), code: exit::IO }
}

/// Where a destination is written: itself, or the file a symlink at it points to.
fn resolve(dest: &Path) -> Result<PathBuf, CliError> {
    match std::fs::symlink_metadata(dest) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(dest).map_err(|e| {
            CliError::bad_input(format!("{}: a symlink to nowhere ({e})", dest.display()))
        }),
        _ => Ok(dest.to_path_buf()),
    }
}

/// The path an existing or future file has, for comparing destinations with inputs.
fn identity(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    Some(std::fs::canonicalize(parent).ok()?.join(path.file_name()?))
}

/// Checks the destinations of a run before it starts.
///
/// # Errors
/// A bad-input [`CliError`] naming a destination that is not a regular file (or a folder
/// where files go, for `dirs`), or that is one of `inputs`.
pub fn check_destinations(
    files: &[&Path],
    dirs: &[&Path],
    inputs: &[&Path],
) -> Result<(), CliError> {
    let inputs: Vec<PathBuf> = inputs.iter().filter_map(|p| identity(p)).collect();
    for dest in files {
        let target = resolve(dest)?;
        if let Ok(m) = std::fs::metadata(&target)
            && !m.is_file()
        {
            return Err(CliError::bad_input(format!(
                "{}: not a regular file; outputs are written as regular files only",
                dest.display()
            )));
        }
        if identity(&target).is_some_and(|t| inputs.contains(&t)) {
            return Err(CliError::bad_input(format!(
                "{}: is an input of this run; give another output path",
                dest.display()
            )));
        }
    }
    for dir in dirs {
        if let Ok(m) = std::fs::metadata(dir)
            && !m.is_dir()
        {
            return Err(CliError::bad_input(format!("{}: not a folder", dir.display())));
        }
    }
    Ok(())
}

/// One staged file: its destination and its temporary beside it.
#[derive(Debug)]
struct Staged {
    dest: PathBuf,
    tmp: PathBuf,
}

/// The files of one run, staged, then renamed into place together by [`commit`](Self::commit).
/// Dropped uncommitted, it removes its temporaries.
#[derive(Debug, Default)]
pub struct OutputSet {
    staged: Vec<Staged>,
    /// Files of the set's kind that this run does not write: removed on commit, so a folder
    /// of outputs holds this run's files only (e.g. `retimed.csv` of an earlier run).
    retired: Vec<PathBuf>,
}

impl OutputSet {
    /// A temporary path beside `dest` (created folders included) to write it through, e.g. by
    /// a renderer that writes files itself; [`commit`](Self::commit) renames it to `dest`.
    ///
    /// # Errors
    /// Creating the destination's folder, or a symlink at `dest` that points nowhere.
    pub fn stage_path(&mut self, dest: &Path) -> Result<PathBuf, CliError> {
        let dest = resolve(dest)?;
        let dir = dest.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(|e| io_error(dir, e))?;
        let ext = dest.extension().and_then(|e| e.to_str()).unwrap_or("tmp");
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".armature-{}-{n}.{ext}", std::process::id()));
        pending().push(tmp.clone());
        self.staged.push(Staged { dest, tmp: tmp.clone() });
        Ok(tmp)
    }

    /// Stages `bytes` for `dest`.
    ///
    /// # Errors
    /// An [`exit::IO`] error naming the destination.
    pub fn stage(&mut self, dest: &Path, bytes: &[u8]) -> Result<(), CliError> {
        use std::io::Write;
        let tmp = self.stage_path(dest)?;
        let written = std::fs::File::create(&tmp).and_then(|mut f| {
            f.write_all(bytes)?;
            f.sync_all()
        });
        written.map_err(|e| io_error(dest, e))
    }

    /// Marks `dest` as a file this run does not write: if it exists when the set is
    /// committed (every rename done), it is removed — an earlier run's output must not pass
    /// for this run's. Nothing happens to it if the set is dropped uncommitted.
    pub fn retire(&mut self, dest: &Path) {
        self.retired.push(dest.to_path_buf());
    }

    /// Renames every staged file into place, each destination folder locked meanwhile, then
    /// removes the retired files ([`retire`](Self::retire)); returns the destinations as
    /// given to the stage calls (symlinks resolved).
    ///
    /// # Errors
    /// An [`exit::IO`] error naming the destination a rename failed for (the ones before it
    /// are in place).
    pub fn commit(mut self) -> Result<Vec<PathBuf>, CliError> {
        let mut dirs: Vec<PathBuf> = self
            .staged
            .iter()
            .map(|s| s.tmp.parent().unwrap_or(Path::new(".")).to_path_buf())
            .collect();
        dirs.sort();
        dirs.dedup();
        // Locks in a fixed order (no deadlock between runs); released when dropped.
        let _locks: Vec<std::fs::File> = dirs
            .iter()
            .filter_map(|d| std::fs::File::open(d).ok())
            .filter(|f| f.lock().is_ok())
            .collect();
        let staged = std::mem::take(&mut self.staged);
        // Held through the renames: an interrupt waits for the whole set to be in place.
        let mut tmps = pending();
        let mut done = Vec::new();
        let mut failure = None;
        for s in &staged {
            match (&failure, std::fs::rename(&s.tmp, &s.dest)) {
                (None, Ok(())) => done.push(s.dest.clone()),
                (None, Err(e)) => failure = Some(io_error(&s.dest, e)),
                (Some(_), _) => {}
            }
        }
        // After a failed rename, the temporaries not renamed are removed.
        for s in &staged {
            let _ = std::fs::remove_file(&s.tmp);
        }
        forget(&mut tmps, &staged);
        if let Some(e) = failure {
            return Err(e);
        }
        for r in &self.retired {
            match std::fs::remove_file(r) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(io_error(r, e)),
                _ => {}
            }
        }
        Ok(done)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let mut tmps = pending();
        for s in &self.staged {
            let _ = std::fs::remove_file(&s.tmp);
        }
        forget(&mut tmps, &self.staged);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("armature-set-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn listing(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn retired_files_go_on_commit_only() {
        let d = scratch("retire");
        std::fs::write(d.join("stale.csv"), "old").unwrap();
        let set = || {
            let mut set = OutputSet::default();
            set.stage(&d.join("a.csv"), b"new").unwrap();
            set.retire(&d.join("stale.csv"));
            set.retire(&d.join("never-there.csv"));
            set
        };
        drop(set());
        assert_eq!(listing(&d), ["stale.csv"], "dropped: nothing removed");
        assert_eq!(set().commit().unwrap(), [d.join("a.csv")]);
        assert_eq!(listing(&d), ["a.csv"]);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_set_dropped_before_commit_leaves_the_old_files_and_no_litter() {
        let d = scratch("drop");
        std::fs::write(d.join("a.json"), "old").unwrap();
        let mut set = OutputSet::default();
        set.stage(&d.join("a.json"), b"new").unwrap();
        set.stage(&d.join("b.csv"), b"new").unwrap();
        drop(set);
        assert_eq!(listing(&d), ["a.json"]);
        assert_eq!(std::fs::read_to_string(d.join("a.json")).unwrap(), "old");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_committed_set_replaces_every_file_and_writes_through_symlinks() {
        let d = scratch("commit");
        std::fs::write(d.join("target.json"), "old").unwrap();
        std::os::unix::fs::symlink(d.join("target.json"), d.join("link.json")).unwrap();
        let long = "x".repeat(250) + ".json";
        let mut set = OutputSet::default();
        set.stage(&d.join("link.json"), b"new").unwrap();
        set.stage(&d.join(&long), b"long").unwrap();
        set.commit().unwrap();
        assert!(std::fs::symlink_metadata(d.join("link.json")).unwrap().file_type().is_symlink());
        assert_eq!(std::fs::read_to_string(d.join("target.json")).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(d.join(&long)).unwrap(), "long");
        assert_eq!(listing(&d).len(), 3, "{:?}", listing(&d));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn devices_folders_and_inputs_are_refused_as_destinations() {
        let d = scratch("check");
        let input = d.join("task.toml");
        std::fs::write(&input, "").unwrap();
        let dev = Path::new("/dev/null");
        assert!(check_destinations(&[dev], &[], &[]).unwrap_err().message.contains("regular"));
        assert!(check_destinations(&[&d], &[], &[]).is_err(), "a folder");
        let e = check_destinations(&[&input], &[], &[&input]).unwrap_err();
        assert!(e.message.contains("is an input"), "{}", e.message);
        let relative_twin = d.join(".").join("task.toml");
        assert!(check_destinations(&[&relative_twin], &[], &[&input]).is_err());
        assert!(check_destinations(&[], &[&input], &[]).is_err(), "a file where a folder goes");
        assert!(check_destinations(&[&d.join("new.json")], &[&d.join("plots")], &[&input]).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
