//! Reading an input file (a robot description, a task) from an untrusted path: regular files
//! only, at most [`MAX_INPUT_BYTES`], valid UTF-8 with the position of the first bad byte.

use std::io::Read;
use std::path::Path;

/// The largest input file read (64 MiB): far above any robot or task, far below what would
/// exhaust memory.
pub const MAX_INPUT_BYTES: u64 = 64 << 20;

/// Reads the text file at `path` (a symlink is followed to its target).
///
/// # Errors
/// An [`std::io::Error`] saying what is wrong: the OS's (missing, unreadable); `InvalidInput`
/// for something that is not a regular file (a directory, a device such as `/dev/zero`, a
/// pipe) or is larger than [`MAX_INPUT_BYTES`]; `InvalidData` for invalid UTF-8, with the
/// line and column of the first bad byte.
///
/// # Example
/// ```
/// let e = armature_kinematics::read_text_file(std::path::Path::new("/dev/zero")).unwrap_err();
/// assert!(e.to_string().contains("not a regular file"));
/// ```
pub fn read_text_file(path: &Path) -> std::io::Result<String> {
    use std::io::{Error, ErrorKind};
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(Error::new(ErrorKind::InvalidInput, "not a regular file"));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)?.take(MAX_INPUT_BYTES + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_INPUT_BYTES {
        let msg = format!("larger than {} MiB", MAX_INPUT_BYTES >> 20);
        return Err(Error::new(ErrorKind::InvalidInput, msg));
    }
    String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        let start = good.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let column = String::from_utf8_lossy(&good[start..]).chars().count() + 1;
        Error::new(ErrorKind::InvalidData, format!("{line}:{column}: invalid UTF-8"))
    })
}

/// `file:line:col` and the reason for an error of [`read_text_file`] on `file` (the
/// position only for invalid UTF-8).
pub fn located_read_error(file: &str, e: &std::io::Error) -> (String, String) {
    let text = e.to_string();
    match text.split_once(": invalid UTF-8") {
        Some((at, _)) if e.kind() == std::io::ErrorKind::InvalidData => {
            (format!("{file}:{at}"), "invalid UTF-8".to_string())
        }
        _ => (file.to_string(), text),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_utf8_is_located_and_devices_and_folders_are_refused() {
        let dir = std::env::temp_dir().join(format!("armature-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("bad.toml");
        std::fs::write(&f, b"[robot]\nname = \"\xc3\xa4x\xff\"\n").unwrap();
        let e = read_text_file(&f).unwrap_err();
        assert_eq!(e.to_string(), "2:11: invalid UTF-8");
        assert!(read_text_file(&dir).unwrap_err().to_string().contains("not a regular file"));
        std::fs::write(&f, "ok").unwrap();
        assert_eq!(read_text_file(&f).unwrap(), "ok");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
