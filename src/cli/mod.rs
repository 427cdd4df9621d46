//! The command-line front end: argument parsing, progress, summaries. All computation is in the
//! library.

pub mod cloth;
pub mod ik;
pub mod inspect;
pub mod interrupt;
pub mod open;
pub mod progress;
pub mod scene;

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::{Parser, Subcommand};

/// Bake cloth simulations and IK animations offline into glTF files for Blender and game engines.
#[derive(Debug, Parser)]
#[command(name = "scenebake", version, about, propagate_version = true)]
pub struct Cli {
    /// No progress bar and no summary (errors are still printed).
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a cloth or soft body and write it as a morph-target glTF.
    Cloth(Box<cloth::ClothArgs>),
    /// Bake an inverse-kinematics animation: a chain whose tip follows a curve, text or drawing.
    Ik(Box<ik::IkArgs>),
    /// Run the jobs of a scene file (TOML) in order.
    Run(scene::RunArgs),
    /// Describe a glTF/GLB file and check the invariants scenebake's exports promise.
    Inspect(inspect::InspectArgs),
    /// Open a bake in Blender, set up to play it (fps, frame range, smooth shading, the bake's
    /// action, a camera).
    Open(open::OpenArgs),
}

/// One finished job, for summaries.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Outcome {
    /// `cloth` or `ik`.
    pub kind: &'static str,
    /// The job's name.
    pub name: String,
    /// Main output file.
    pub output: PathBuf,
    /// Frames baked.
    pub frames: usize,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Bytes written.
    pub bytes: u64,
    /// Every file written (report excluded) with its size in bytes.
    pub files: Vec<(PathBuf, u64)>,
    /// The job's own report.
    pub report: serde_json::Value,
}

/// Runs one parsed command.
pub fn execute(cli: &Cli) -> anyhow::Result<()> {
    match &cli.command {
        Command::Cloth(args) => {
            let outcome = run_cloth(args, "cloth", cli.quiet)?;
            if !cli.quiet {
                eprintln!("{}", summary_line(&outcome));
            }
            print_warnings(&outcome);
            Ok(())
        }
        Command::Ik(args) => {
            let outcome = run_ik(args, "ik", cli.quiet)?;
            if !cli.quiet {
                eprintln!("{}", summary_line(&outcome));
            }
            print_warnings(&outcome);
            Ok(())
        }
        Command::Run(args) => scene::run(args, cli.quiet),
        Command::Inspect(args) => inspect::run(args),
        Command::Open(args) => open::run(args),
    }
}

/// Bakes one cloth job with a progress bar; writes its report when asked.
pub fn run_cloth(args: &cloth::ClothArgs, label: &str, quiet: bool) -> anyhow::Result<Outcome> {
    let job = args.job();
    let frames = job
        .frames
        .unwrap_or(scenebake::bake::cloth::defaults::FRAMES) as u64;
    let bar = progress::bar(label, frames, quiet);
    let start = std::time::Instant::now();
    let report = scenebake::bake::bake_cloth(&job, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    let report = report?;
    let json = serde_json::to_value(&report)?;
    if let Some(path) = &args.report {
        write_report(path, &json)?;
    }
    Ok(Outcome {
        kind: "cloth",
        name: args.name.clone().unwrap_or_else(|| report.input.clone()),
        output: job.output.clone(),
        frames: report.frames,
        seconds: start.elapsed().as_secs_f64(),
        bytes: report.output_bytes,
        files: sizes(&report.output),
        report: json,
    })
}

/// Bakes one IK job with a progress bar (the library writes its report when asked).
pub fn run_ik(args: &ik::IkArgs, label: &str, quiet: bool) -> anyhow::Result<Outcome> {
    let job = args.job()?;
    let bar = progress::bar(label, 1, quiet);
    let start = std::time::Instant::now();
    let report = scenebake::ik::bake::bake_ik(&job, &mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    let report = report?;
    let written: Vec<PathBuf> = report
        .files
        .iter()
        .filter(|f| Some(f.as_path()) != job.report.as_deref())
        .cloned()
        .collect();
    let files = sizes(&written);
    let bytes = files.iter().map(|(_, b)| b).sum();
    Ok(Outcome {
        kind: "ik",
        name: args
            .name
            .clone()
            .unwrap_or_else(|| job.output.display().to_string()),
        output: job.output.clone(),
        frames: report.frames,
        seconds: start.elapsed().as_secs_f64(),
        bytes,
        files,
        report: serde_json::to_value(&report)?,
    })
}

/// Each file with its size on disk (0 when it cannot be read).
fn sizes(files: &[PathBuf]) -> Vec<(PathBuf, u64)> {
    files
        .iter()
        .map(|f| (f.clone(), std::fs::metadata(f).map_or(0, |m| m.len())))
        .collect()
}

/// `a.glb (1.2 MB)`, or one such entry per file, comma-separated.
pub fn files_with_sizes(o: &Outcome) -> String {
    if o.files.is_empty() {
        return format!("{} ({})", o.output.display(), progress::bytes(o.bytes));
    }
    o.files
        .iter()
        .map(|(f, b)| format!("{} ({})", f.display(), progress::bytes(*b)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Writes a JSON report atomically.
pub fn write_report(path: &Path, value: &serde_json::Value) -> anyhow::Result<()> {
    let bytes = serde_json::to_vec_pretty(value)?;
    scenebake::export::atomic::write_atomically(path, bytes)
        .with_context(|| "cannot write the report".to_string())
}

/// Prints the report's `warnings` on standard error, one line each (also with `--quiet`: a
/// step above its tolerance or a repaired input is never silent).
pub fn print_warnings(o: &Outcome) {
    if let Some(list) = o.report["warnings"].as_array() {
        for w in list.iter().filter_map(|w| w.as_str()) {
            eprintln!("warning: {}: {w}", o.name);
        }
    }
}

/// The one-line summary printed after a job.
pub fn summary_line(o: &Outcome) -> String {
    let r = &o.report;
    let extra = match o.kind {
        "cloth" => format!(
            " ({} particles, {} springs, {} pinned; {:.2} ms/frame; {} of {} frames within \
             tolerance {})",
            r["particles"],
            r["springs"],
            r["pinned"],
            r["ms_per_frame"].as_f64().unwrap_or(0.0),
            o.frames
                - r["unconverged_frames"]
                    .as_array()
                    .map_or(0, |a| a.len())
                    .min(o.frames),
            o.frames,
            r["tolerance"]
        ),
        "ik" => format!(
            " ({} joints, {} solver, {} of {} targets reached, {} unreachable, {:.1} iterations/frame)",
            r["joints"], r["solver"].as_str().unwrap_or(""), r["reached"], o.frames, r["unreachable"], r["mean_iterations"].as_f64().unwrap_or(0.0)
        ),
        _ => String::new(),
    };
    let basis = &r["cache"]["basis"];
    let extra = if basis.is_object() {
        format!(
            "{extra}; basis {} targets, max error {:.3} mm, positions {}",
            basis["targets"],
            1e3 * basis["max_error"].as_f64().unwrap_or(0.0),
            basis["quantization"]["positions"].as_str().unwrap_or("")
        )
    } else {
        extra
    };
    format!(
        "{}: baked {} frames{} in {:.2} s; wrote {}",
        o.name,
        o.frames,
        extra,
        o.seconds,
        files_with_sizes(o)
    )
}
