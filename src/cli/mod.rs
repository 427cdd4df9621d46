//! The command-line front end: argument parsing, progress, summaries. All computation is in the
//! library.

pub mod cloth;
pub mod ik;
pub mod inspect;
pub mod interrupt;
pub mod open;
pub mod progress;
pub mod scene;
pub mod view;

use std::path::{Path, PathBuf};

use anyhow::{anyhow, Context};
use clap::{Parser, Subcommand};
use indicatif::ProgressBar;
use scenebake::scene::{Job, Report};
use scenebake::Param;

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
    /// Play a bake in the browser (glTF, or a VAT's .json): serves the built-in viewer locally.
    View(view::ViewArgs),
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
    /// Frames written.
    pub frames: usize,
    /// Frames simulated: more than written for a bake on a character (blend-in and warm-up).
    pub frames_simulated: usize,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Bytes written (report excluded).
    pub bytes: u64,
    /// Every file written (report excluded) with its size in bytes.
    pub files: Vec<(PathBuf, u64)>,
    /// The job's own report.
    pub report: Report,
}

/// How the command line names a parameter: `--max-iterations`, or `INPUT` for the positional
/// input file.
pub fn flag(param: Param) -> String {
    match param {
        Param::Input => "INPUT".into(),
        p => format!("--{}", p.key().replace('_', "-")),
    }
}

/// A library error in the command line's words.
pub fn cli_error(e: scenebake::Error) -> anyhow::Error {
    anyhow!(e.render(&flag))
}

/// Runs one parsed command.
pub fn execute(cli: &Cli) -> anyhow::Result<()> {
    match &cli.command {
        Command::Cloth(args) => run_single(Job::Cloth(Box::new(args.job.clone())), cli.quiet),
        Command::Ik(args) => run_single(Job::Ik(Box::new(args.job.clone())), cli.quiet),
        Command::Run(args) => scene::run(args, cli.quiet),
        Command::Inspect(args) => inspect::run(args),
        Command::Open(args) => open::run(args),
        Command::View(args) => view::run(args),
    }
}

/// `scenebake cloth` / `scenebake ik`: one job, errors and warnings in `--flag` words.
fn run_single(job: Job, quiet: bool) -> anyhow::Result<()> {
    let name = match &job {
        Job::Cloth(j) => j.display_name(),
        Job::Ik(j) => j.display_name(),
    };
    let bar = progress::bar(job.kind(), job.frames_hint().unwrap_or(1) as u64, quiet);
    let outcome = run_job(&job, &name, &bar, &flag).map_err(|e| match e {
        JobError::Bake(e) => cli_error(e),
        JobError::Other(e) => e,
    })?;
    if !quiet {
        eprintln!("{}", summary_line(&outcome));
    }
    print_warnings(&outcome, &flag);
    Ok(())
}

/// Why a job failed: the bake (a library error, to be worded by the caller) or writing its
/// report.
pub enum JobError {
    /// The library's error.
    Bake(scenebake::Error),
    /// Anything else.
    Other(anyhow::Error),
}

/// Bakes one job, moving `bar`; writes its report when asked. A cloth bake whose output will be
/// large says so before it starts (parameters named by `vocabulary`), not only when it is done.
pub fn run_job(
    job: &Job,
    name: &str,
    bar: &ProgressBar,
    vocabulary: scenebake::param::Vocabulary<'_>,
) -> Result<Outcome, JobError> {
    let start = std::time::Instant::now();
    // Every file the job writes (its report too) is checked before the bake, not after it.
    job.check_outputs().map_err(JobError::Bake)?;
    if let Job::Cloth(cloth) = job {
        if let Ok(Some(w)) = scenebake::bake::cloth::output_size_warning(cloth) {
            bar.suspend(|| eprintln!("warning: {name}: {}", w.render(vocabulary)));
        }
    }
    let report = job.run(&mut |done, total| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    });
    bar.finish_and_clear();
    let report = report.map_err(JobError::Bake)?;
    if let Some(path) = job.report_path() {
        write_report(path, &report).map_err(JobError::Other)?;
    }
    let written = match &report {
        Report::Cloth(r) => r.output.clone(),
        Report::Ik(r) => r.files.clone(),
    };
    let files = sizes(&written);
    Ok(Outcome {
        kind: job.kind(),
        name: name.to_owned(),
        output: job.output().to_path_buf(),
        frames: report.frames_written(),
        frames_simulated: report.frames(),
        seconds: start.elapsed().as_secs_f64(),
        bytes: files.iter().map(|(_, b)| b).sum(),
        files,
        report,
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
pub fn write_report(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    let bytes = serde_json::to_vec_pretty(value)?;
    scenebake::export::atomic::write_atomically(path, bytes)
        .map_err(cli_error)
        .context("cannot write the report")
}

/// Prints a job's warnings, parameters named by `vocabulary` (also with `--quiet`: a step above
/// its tolerance or a repaired input is never silent).
pub fn print_warnings(o: &Outcome, vocabulary: scenebake::param::Vocabulary<'_>) {
    for w in o.report.warnings() {
        eprintln!("warning: {}: {}", o.name, w.render(vocabulary));
    }
}

/// The one-line summary printed after a job.
pub fn summary_line(o: &Outcome) -> String {
    let extra = match &o.report {
        Report::Cloth(r) => {
            // A bake on a character simulates frames it does not write: say which.
            let simulated = match &r.character {
                _ if o.frames_simulated == o.frames => String::new(),
                Some(c) => format!(
                    "{} simulated: {} blending in, {} warming up, {} written; ",
                    o.frames_simulated,
                    c.blend_frames,
                    c.first_written_frame.saturating_sub(c.blend_frames),
                    o.frames
                ),
                None => format!("{} simulated, {} written; ", o.frames_simulated, o.frames),
            };
            let stretch = match r.membrane_triangles {
                0 => format!("{} springs", r.springs),
                t => format!("{t} membrane triangles, {} springs", r.springs),
            };
            let mut extra = format!(
                " ({simulated}{} particles, {stretch}, {} pinned; {:.2} ms/frame; {} of {} frames within \
                 tolerance {})",
                r.particles,
                r.pinned,
                r.ms_per_frame,
                r.frames - r.unconverged_frames.len().min(r.frames),
                r.frames,
                r.tolerance
            );
            if let Some(b) = &r.cache.basis {
                extra += &format!(
                    "; basis {} targets, max error {:.3} mm, positions {}",
                    b.targets,
                    1e3 * b.max_error,
                    b.quantization.positions
                );
            }
            extra
        }
        Report::Ik(r) => format!(
            " ({} joints, {} solver, {} of {} targets reached, {} unreachable, {:.1} \
             iterations/frame)",
            r.joints, r.solver, r.reached, r.frames, r.unreachable, r.mean_iterations
        ),
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
