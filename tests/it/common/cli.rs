//! Running the `scenebake` binary as a user does.

use std::ffi::OsStr;
use std::process::Command;

/// A command for the binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_scenebake"))
}

/// Runs scenebake; returns (exit code, stderr).
pub fn scenebake<I, S>(args: I) -> (i32, String)
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = bin().args(args).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Asserts a failure whose message has every one of `words` and no panic.
#[track_caller]
pub fn fails_with(args: &[&str], words: &[&str]) {
    let (code, err) = scenebake(args);
    assert_ne!(code, 0, "{args:?} should fail");
    assert!(
        !err.contains("panicked") && !err.contains("RUST_BACKTRACE"),
        "{args:?} panicked: {err}"
    );
    for w in words {
        assert!(err.contains(w), "{args:?}: message lacks `{w}`:\n{err}");
    }
}

/// Asserts that `scenebake cloth OBJ -o DIR/OUT EXTRA…` fails with every one of `words` and
/// leaves `dir` holding exactly `kept` (nothing written, not even a temporary).
#[track_caller]
pub fn cloth_refused(
    obj: &str,
    dir: &std::path::Path,
    out: &str,
    extra: &[&str],
    words: &[&str],
    kept: &[&str],
) {
    let out = dir.join(out).display().to_string();
    let mut args = vec!["cloth", obj, "-o", &out];
    args.extend_from_slice(extra);
    fails_with(&args, words);
    assert_eq!(super::names_in(dir), kept, "{extra:?} wrote nothing");
}

/// Sends signal `name` (`INT`, `STOP`, `CONT`...) to process `pid` with kill(1).
#[cfg(unix)]
#[track_caller]
pub fn signal(pid: u32, name: &str) {
    let status = Command::new("kill")
        .args([format!("-{name}"), pid.to_string()])
        .status()
        .unwrap();
    assert!(status.success(), "kill -{name} {pid}");
}
