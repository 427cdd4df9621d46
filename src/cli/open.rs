//! `scenebake open FILE`: opens a bake in Blender through `scripts/blender/scenebake_import.py`
//! (embedded in the binary, written to a temporary file for Blender to run), which sets the
//! scene's fps and frame range from the bake, shades it smooth, makes the bake's action active
//! and adds a camera.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{anyhow, bail, Context};
use clap::Args;

/// The helper script Blender runs.
const HELPER: &str = include_str!("../../scripts/blender/scenebake_import.py");

/// Open a bake in Blender with the bake's fps, frame range, smooth shading, active action and a
/// camera (Blender 3.4 or later).
#[derive(Debug, Args)]
#[command(
    after_help = "Examples:\n  scenebake open exports/lab_cloth.glb\n  scenebake open exports/fox.glb --blender ~/blender-4.2/blender\n\nThe same without scenebake: blender --python scripts/blender/scenebake_import.py -- FILE"
)]
pub struct OpenArgs {
    /// The .glb or .gltf file.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// The Blender executable [default: `blender` on PATH].
    #[arg(long, value_name = "PATH")]
    pub blender: Option<PathBuf>,
    /// Run Blender without its window (-b): import, set up, print a summary and quit.
    #[arg(long)]
    pub background: bool,
}

/// Finds `name` in the directories of PATH.
fn on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// The Blender executable to run.
fn blender(args: &OpenArgs) -> anyhow::Result<PathBuf> {
    match &args.blender {
        Some(p) if p.is_file() => Ok(p.clone()),
        Some(p) => bail!(
            "invalid value for --blender: {}: no such file (give the path of the Blender executable)",
            p.display()
        ),
        None => on_path("blender").ok_or_else(|| {
            anyhow!(
                "blender is not on PATH: install Blender 3.4 or later (https://www.blender.org/download/, or `apt install blender`), or give its executable with --blender PATH"
            )
        }),
    }
}

/// Launches Blender on the file; returns when Blender exits.
pub fn run(args: &OpenArgs) -> anyhow::Result<()> {
    let ext = args
        .file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("glb") | Some("gltf")) {
        bail!(
            "{}: expected a .glb or .gltf file (a scenebake export)",
            args.file.display()
        );
    }
    if !args.file.is_file() {
        bail!("{}: no such file", args.file.display());
    }
    let exe = blender(args)?;
    let dir = tempfile::tempdir().context("cannot create a temporary folder for the helper")?;
    let script = dir.path().join("scenebake_import.py");
    std::fs::write(&script, HELPER)
        .with_context(|| format!("cannot write {}", script.display()))?;
    let file = std::path::absolute(&args.file).unwrap_or_else(|_| args.file.clone());
    let mut argv: Vec<OsString> = Vec::new();
    if args.background {
        argv.push("-b".into());
    }
    argv.extend([
        OsString::from("--python-exit-code"),
        "1".into(),
        "--python".into(),
        script.into_os_string(),
        "--".into(),
        file.into_os_string(),
    ]);
    let status = Command::new(&exe)
        .args(&argv)
        // A Python environment of the caller's (pyenv, a venv) must not leak into Blender's.
        .env_remove("PYTHONPATH")
        .env_remove("PYTHONHOME")
        .status()
        .with_context(|| format!("cannot run {}", exe.display()))?;
    if !status.success() {
        bail!(
            "{} exited with {status} while opening {}",
            display(&exe),
            args.file.display()
        );
    }
    Ok(())
}

fn display(p: &Path) -> String {
    p.display().to_string()
}
