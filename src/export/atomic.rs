//! Writing outputs so that a failed or interrupted run never leaves a partial file nor destroys an
//! earlier export: each file goes to a temporary in its target folder and is renamed into place
//! only when every file of the set has been written completely. The temporaries being written
//! are listed process-wide, so that an interrupt handler can remove them
//! ([`remove_live_temporaries`]) before the process exits without running destructors.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::{Error, Result};

/// Writes every (path, bytes) pair; all temporaries are complete before the first rename. On
/// failure no target is touched and the temporaries are removed.
///
/// # Errors
/// [`Error::Io`] naming the file that could not be written.
pub fn write_all_atomically(files: &[(PathBuf, Vec<u8>)]) -> Result<()> {
    let mut live = LiveTemporaries(Vec::with_capacity(files.len()));
    let mut staged = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        let dir = parent_dir(path);
        if dir.is_dir() {
            if path.is_dir() {
                return Err(Error::io(path, std::io::Error::other("is a directory")));
            }
        } else {
            std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        }
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or("output");
        let mut builder = tempfile::Builder::new();
        let prefix = format!(".{name}.");
        builder.prefix(&prefix).suffix(".tmp");
        // Temporaries are private (0600) by default; an export is an ordinary file.
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
        let mut tmp = builder.tempfile_in(&dir).map_err(|e| Error::io(path, e))?;
        live.add(tmp.path());
        tmp.write_all(bytes)
            .and_then(|_| tmp.as_file().sync_data())
            .map_err(|e| Error::io(path, e))?;
        staged.push((tmp, path));
    }
    for (tmp, path) in staged {
        tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    }
    Ok(())
}

/// Temporaries currently being written by this process.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Removes every temporary this process is writing right now. For an interrupt handler that is
/// about to exit: the targets themselves are never touched (they are only ever renamed onto).
pub fn remove_live_temporaries() {
    if let Ok(live) = LIVE.lock() {
        for path in live.iter() {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The temporaries of one write, listed in [`LIVE`] until the write ends either way.
struct LiveTemporaries(Vec<PathBuf>);

impl LiveTemporaries {
    fn add(&mut self, path: &Path) {
        self.0.push(path.to_path_buf());
        if let Ok(mut live) = LIVE.lock() {
            live.push(path.to_path_buf());
        }
    }
}

impl Drop for LiveTemporaries {
    fn drop(&mut self) {
        if let Ok(mut live) = LIVE.lock() {
            live.retain(|p| !self.0.contains(p));
        }
    }
}

/// Writes one file atomically.
///
/// # Errors
/// As [`write_all_atomically`].
pub fn write_atomically(path: &Path, bytes: Vec<u8>) -> Result<()> {
    write_all_atomically(&[(path.to_path_buf(), bytes)])
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_set_leaves_earlier_file_and_no_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("a.gltf");
        std::fs::write(&good, b"old").unwrap();
        // The second target is a directory: the whole set must fail before any rename.
        let blocked = dir.path().join("b.bin");
        std::fs::create_dir(&blocked).unwrap();
        let err =
            write_all_atomically(&[(good.clone(), b"new".to_vec()), (blocked, b"x".to_vec())]);
        assert!(err.is_err());
        assert_eq!(std::fs::read(&good).unwrap(), b"old");
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}
