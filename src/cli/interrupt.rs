//! Ctrl-C: stop at once, but leave no temporary file behind.
//!
//! Outputs are written to `.NAME.XXXXXX.tmp` beside their target and renamed into place, so an
//! interrupted job never damages an earlier export; this handler removes the temporaries being
//! written at that moment, says which outputs jobs that already finished in this run (`scenebake
//! run`) replaced, then exits with status 130.

use std::path::PathBuf;
use std::sync::Mutex;

/// Files written by the jobs of this run that finished.
static REPLACED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Records files a finished job wrote (for the message on Ctrl-C).
pub fn record_written(files: impl IntoIterator<Item = PathBuf>) {
    if let Ok(mut list) = REPLACED.lock() {
        list.extend(files);
    }
}

/// What Ctrl-C leaves: the outputs this run already replaced, or none.
fn message() -> String {
    let list = REPLACED.lock().map(|l| l.clone()).unwrap_or_default();
    match list.len() {
        0 => "interrupted: nothing was written; earlier exports are untouched".into(),
        n => format!(
            "interrupted: the job being baked wrote nothing, but finished jobs of this run replaced {n} file{}: {}",
            if n == 1 { "" } else { "s" },
            list.iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Installs the handler (once, at start-up).
pub fn install() {
    // Failing to install (e.g. a handler already set) only loses the clean-up, not data.
    let _ = ctrlc::set_handler(|| {
        scenebake::export::atomic::remove_live_temporaries();
        eprintln!("\n{}", message());
        std::process::exit(130);
    });
}
