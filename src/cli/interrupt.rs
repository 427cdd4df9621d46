//! Ctrl-C: stop at once, but leave no temporary file behind.
//!
//! Outputs are written to `.NAME.XXXXXX.tmp` beside their target and renamed into place, so an
//! interrupted run never damages an earlier export; this handler removes the temporaries being
//! written at that moment, then exits with status 130.

/// Installs the handler (once, at start-up).
pub fn install() {
    // Failing to install (e.g. a handler already set) only loses the clean-up, not data.
    let _ = ctrlc::set_handler(|| {
        scenebake::export::atomic::remove_live_temporaries();
        eprintln!("\ninterrupted: earlier exports are untouched");
        std::process::exit(130);
    });
}
