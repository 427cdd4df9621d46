//! `scenebake run SCENE.toml`: the jobs of a scene file (parsed by [`scenebake::scene`]), run on
//! several cores at once.
//!
//! Jobs are independent, so `--jobs N` runs N at a time (each writes its own files; the outputs
//! are the same bytes whatever N is) and `--shard I/N` runs every N-th job for farm job arrays.
//! Errors and warnings name parameters by their scene keys.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{anyhow, bail};
use clap::Args;
use indicatif::MultiProgress;
use scenebake::bake::outputs::{check_writable, OutputFile};
use scenebake::cores::CoreShare;
use scenebake::scene::{Job, Scene, SceneJob};
use scenebake::Param;

use super::{print_warnings, progress, run_job, summary_line, write_report, JobError, Outcome};

/// Run the jobs of a scene file.
#[derive(Debug, Args)]
#[command(
    after_help = "Farm job arrays: each task runs its share of the jobs, e.g. with Slurm\n  #SBATCH --array=1-4\n  scenebake run scenes/demo.toml --shard ${SLURM_ARRAY_TASK_ID}/4 --jobs 1"
)]
pub struct RunArgs {
    /// Scene file (TOML) with [[cloth]] and [[ik]] jobs.
    #[arg(value_name = "SCENE.toml")]
    pub scene: PathBuf,
    /// Run only the job with this `name`.
    #[arg(long, value_name = "NAME")]
    pub only: Option<String>,
    /// Jobs baked at the same time [default: the number of cores].
    #[arg(long, short = 'j', value_name = "N")]
    pub jobs: Option<usize>,
    /// Run only the I-th of N shares of the jobs (jobs I, I+N, I+2N... in file order, I from 1),
    /// for farm job arrays.
    #[arg(long, value_name = "I/N", value_parser = parse_shard)]
    pub shard: Option<(usize, usize)>,
    /// Write the run's summary (and each job's report) as JSON.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
}

/// A rough relative cost of a job, for the order jobs start in: cloth frames × input size ×
/// (1 + colliders); IK bakes are nearly free.
fn cost_hint(job: &Job) -> f64 {
    match job {
        Job::Cloth(c) => {
            let size = match &c.input {
                Some(p) => std::fs::metadata(p).map_or(1e5, |m| m.len() as f64),
                None => 50.0 * f64::from(c.resolution + 1).powi(2),
            };
            let frames = c.frames.unwrap_or(120) as f64 * c.substeps as f64;
            frames * size * (1 + c.collider.len()) as f64
        }
        Job::Ik(_) => 1.0,
    }
}

fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let (i, n) = s
        .split_once('/')
        .ok_or_else(|| format!("`{s}`: expected I/N, e.g. 1/4"))?;
    let (i, n) = (i.trim().parse::<usize>(), n.trim().parse::<usize>());
    match (i, n) {
        (Ok(i), Ok(n)) if n >= 1 && (1..=n).contains(&i) => Ok((i, n)),
        _ => Err(format!("`{s}`: expected I/N with 1 ≤ I ≤ N, e.g. 1/4")),
    }
}

/// Loads, checks and runs a scene.
pub fn run(args: &RunArgs, quiet: bool) -> anyhow::Result<()> {
    let scene = Scene::load(&args.scene).map_err(|e| anyhow!("{e}"))?;
    let mut selected: Vec<&SceneJob> = match &args.only {
        Some(only) => {
            let hit: Vec<&SceneJob> = scene.jobs.iter().filter(|j| &j.name == only).collect();
            if hit.is_empty() {
                let names: Vec<&str> = scene.jobs.iter().map(|j| j.name.as_str()).collect();
                bail!(
                    "{}: no job named `{only}` (jobs: {})",
                    args.scene.display(),
                    names.join(", ")
                );
            }
            hit
        }
        None => scene.jobs.iter().collect(),
    };
    if let Some((i, n)) = args.shard {
        selected = selected
            .into_iter()
            .enumerate()
            .filter(|(k, _)| k % n == i - 1)
            .map(|(_, j)| j)
            .collect();
    }
    // Every file of every job to run, and the run's own report, can be written: checked before
    // the first job starts rather than when a later one ends.
    for job in &selected {
        job.job.check_outputs().map_err(|e| {
            anyhow!("{e}").context(format!(
                "{}: job `{}` ({})",
                args.scene.display(),
                job.name,
                job.job.kind()
            ))
        })?;
    }
    if let Some(path) = &args.report {
        check_writable(&[OutputFile::new(Param::Report, path)]).map_err(super::cli_error)?;
    }
    let cores = scenebake::cores::available();
    let workers = match args.jobs {
        Some(0) => bail!("invalid value for --jobs: 0: must be at least 1"),
        Some(n) => n,
        None => cores,
    }
    .min(selected.len().max(1));
    // Jobs running at once share the cores, and a worker that finds no job left gives its
    // share to the jobs still running (a cloth job that names its `threads` keeps them).
    let share = CoreShare::new(cores, workers);
    let start = std::time::Instant::now();
    let total = selected.len();
    // Longest expected first, so a long job does not start last on an otherwise idle core; the
    // table and reports keep the file order.
    let costs: Vec<f64> = selected.iter().map(|j| cost_hint(&j.job)).collect();
    let mut order: Vec<usize> = (0..total).collect();
    order.sort_by(|&a, &b| costs[b].total_cmp(&costs[a]));
    let multi = MultiProgress::new();
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let results: Mutex<Vec<Option<anyhow::Result<Outcome>>>> =
        Mutex::new((0..total).map(|_| None).collect());
    std::thread::scope(|threads| {
        for _ in 0..workers {
            threads.spawn(|| loop {
                let slot = next.fetch_add(1, Ordering::SeqCst);
                if slot >= total || failed.load(Ordering::SeqCst) {
                    share.leave();
                    break;
                }
                let k = order[slot];
                let job = selected[k];
                let budgeted = job.job.with_core_share(&share);
                let label = format!("[{}/{total}] {} {}", k + 1, job.job.kind(), job.name);
                let bar = multi.add(progress::bar(
                    &label,
                    job.job.frames_hint().unwrap_or(1) as u64,
                    quiet,
                ));
                let result = run_job(&budgeted, &job.name, &bar, &scenebake::param::scene_key)
                    .map_err(|e| {
                        let e = match e {
                            JobError::Bake(e) => anyhow!("{e}"),
                            JobError::Other(e) => e,
                        };
                        e.context(format!(
                            "{}: job `{}` ({})",
                            args.scene.display(),
                            job.name,
                            job.job.kind()
                        ))
                    });
                multi.remove(&bar);
                match &result {
                    Ok(outcome) => {
                        if !quiet {
                            let line = format!("[{}/{total}] {}", k + 1, summary_line(outcome));
                            // Above the bars on a terminal; plain lines otherwise (a hidden
                            // display would swallow them).
                            if multi.is_hidden() {
                                eprintln!("{line}");
                            } else {
                                let _ = multi.println(line);
                            }
                        }
                        super::interrupt::record_written(
                            outcome.files.iter().map(|(f, _)| f.clone()),
                        );
                    }
                    Err(_) => failed.store(true, Ordering::SeqCst),
                }
                if let Ok(mut r) = results.lock() {
                    r[k] = Some(result);
                }
            });
        }
    });
    let mut outcomes = Vec::new();
    let mut first_error = None;
    for r in results
        .into_inner()
        .unwrap_or_default()
        .into_iter()
        .flatten()
    {
        match r {
            Ok(o) => outcomes.push(o),
            Err(e) => {
                first_error.get_or_insert(e);
            }
        }
    }
    for o in &outcomes {
        print_warnings(o, &scenebake::param::scene_key);
    }
    if let Some(e) = first_error {
        return Err(e);
    }
    if !quiet {
        println!("{}", table(&outcomes));
        println!(
            "{} jobs in {:.2} s ({} at a time)",
            outcomes.len(),
            start.elapsed().as_secs_f64(),
            workers
        );
    }
    if let Some(path) = &args.report {
        write_report(
            path,
            &serde_json::json!({ "scene": args.scene, "seconds_total": start.elapsed().as_secs_f64(), "jobs": outcomes }),
        )?;
    }
    Ok(())
}

fn table(outcomes: &[Outcome]) -> String {
    // One row per file written: the job's first row names it, the others (a .bin, VAT images)
    // only give the file and its own size.
    let rows: Vec<[String; 6]> = outcomes
        .iter()
        .flat_map(|o| {
            let files = if o.files.is_empty() {
                vec![(o.output.clone(), o.bytes)]
            } else {
                o.files.clone()
            };
            files
                .into_iter()
                .enumerate()
                .map(move |(i, (file, bytes))| {
                    let first = i == 0;
                    [
                        if first {
                            o.kind.to_string()
                        } else {
                            String::new()
                        },
                        if first { o.name.clone() } else { String::new() },
                        file.display().to_string(),
                        if first {
                            o.frames.to_string()
                        } else {
                            String::new()
                        },
                        if first {
                            format!("{:.2} s", o.seconds)
                        } else {
                            String::new()
                        },
                        progress::bytes(bytes),
                    ]
                })
        })
        .collect();
    let header = ["job", "name", "output", "frames", "time", "size"].map(String::from);
    let mut widths = header.clone().map(|h| h.len());
    for r in &rows {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    std::iter::once(&header)
        .chain(&rows)
        .map(|r| {
            r.iter()
                .zip(widths)
                .map(|(c, w)| format!("{c:<w$}"))
                .collect::<Vec<_>>()
                .join("  ")
                .trim_end()
                .to_owned()
        })
        .collect::<Vec<_>>()
        .join("\n")
}
