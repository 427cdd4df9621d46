//! Ctrl-C: stop at once, but leave no temporary file behind.
//!
//! Outputs are written to `.NAME.XXXXXX.tmp` beside their target and renamed into place, so an
//! interrupted run never damages an earlier export; this handler removes the temporaries of the
//! outputs the current job registered, then exits with status 130.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

static OUTPUTS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Installs the handler (once, at start-up).
pub fn install() {
    // Failing to install (e.g. a handler already set) only loses the clean-up, not data.
    let _ = ctrlc::set_handler(|| {
        if let Ok(outputs) = OUTPUTS.lock() {
            for path in outputs.iter() {
                remove_temporaries(path);
            }
        }
        eprintln!("\ninterrupted: earlier exports are untouched");
        std::process::exit(130);
    });
}

/// Declares the files the current job writes (replacing the previous job's).
pub fn register_outputs(paths: &[&Path]) {
    if let Ok(mut outputs) = OUTPUTS.lock() {
        outputs.clear();
        outputs.extend(paths.iter().map(|p| p.to_path_buf()));
        // A .gltf's .bin is written beside it.
        let bins: Vec<PathBuf> = outputs
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == "gltf"))
            .map(|p| p.with_extension("bin"))
            .collect();
        outputs.extend(bins);
    }
}

fn remove_temporaries(target: &Path) {
    let (Some(dir), Some(name)) = (target.parent(), target.file_name().and_then(|n| n.to_str()))
    else {
        return;
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!(".{name}.");
    if let Ok(entries) = std::fs::read_dir(dir) {
        for entry in entries.flatten() {
            let file = entry.file_name();
            let file = file.to_string_lossy();
            if file.starts_with(&prefix) && file.ends_with(".tmp") {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
}
