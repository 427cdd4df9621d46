//! `scenebake run SCENE.toml`: scene files whose jobs use the command line's own vocabulary.
//!
//! Each `[[cloth]]` or `[[ik]]` table is turned into the arguments of `scenebake cloth` / `ik`
//! (key `frames = 120` → `--frames 120`, arrays repeat the option, `input` is the positional
//! argument, `true` switches a flag on) and parsed by the same clap parser, so an option cannot
//! exist in one place only. Paths are relative to the scene file.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context};
use clap::{Args, CommandFactory, Parser};

use super::{
    print_warnings, progress, run_cloth, run_ik, summary_line, write_report, Cli, Command, Outcome,
};

/// Run the jobs of a scene file.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Scene file (TOML) with [[cloth]] and [[ik]] jobs.
    #[arg(value_name = "SCENE.toml")]
    pub scene: PathBuf,
    /// Run only the job with this `name`.
    #[arg(long, value_name = "NAME")]
    pub only: Option<String>,
    /// Write the run's summary (and each job's report) as JSON.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
}

/// Keys whose values are file paths, resolved against the scene file's folder.
const PATH_KEYS: &[&str] = &["input", "output", "report", "rig", "svg", "points", "vat"];
/// Job kinds a scene file may hold.
const KINDS: &[&str] = &["cloth", "ik"];

/// A job read from a scene file, parsed by the command-line parser.
struct SceneJob {
    kind: String,
    name: String,
    command: Command,
}

/// Loads, checks and runs a scene.
pub fn run(args: &RunArgs, quiet: bool) -> anyhow::Result<()> {
    let jobs = load_scene(&args.scene)?;
    let selected: Vec<&SceneJob> = match &args.only {
        Some(only) => {
            let hit: Vec<&SceneJob> = jobs.iter().filter(|j| &j.name == only).collect();
            if hit.is_empty() {
                let names: Vec<&str> = jobs.iter().map(|j| j.name.as_str()).collect();
                bail!(
                    "{}: no job named `{only}` (jobs: {})",
                    args.scene.display(),
                    names.join(", ")
                );
            }
            hit
        }
        None => jobs.iter().collect(),
    };
    let start = std::time::Instant::now();
    let mut outcomes = Vec::new();
    for (i, job) in selected.iter().enumerate() {
        let label = format!("[{}/{}] {} {}", i + 1, selected.len(), job.kind, job.name);
        let outcome = match &job.command {
            Command::Cloth(a) => run_cloth(a, &label, quiet),
            Command::Ik(a) => run_ik(a, &label, quiet),
            Command::Run(_) | Command::Inspect(_) | Command::Open(_) => {
                unreachable!("scene jobs are cloth or ik")
            }
        }
        .with_context(|| {
            format!(
                "{}: job `{}` ({})",
                args.scene.display(),
                job.name,
                job.kind
            )
        })?;
        if !quiet {
            eprintln!(
                "[{}/{}] {}",
                i + 1,
                selected.len(),
                summary_line(&Outcome {
                    name: job.name.clone(),
                    ..outcome.clone()
                })
            );
        }
        print_warnings(&Outcome {
            name: job.name.clone(),
            ..outcome.clone()
        });
        super::interrupt::record_written(outcome.files.iter().map(|(f, _)| f.clone()));
        outcomes.push(Outcome {
            name: job.name.clone(),
            ..outcome
        });
    }
    if !quiet {
        println!("{}", table(&outcomes));
        println!(
            "{} jobs in {:.2} s",
            outcomes.len(),
            start.elapsed().as_secs_f64()
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

/// Reads a scene file and parses every job with the command-line parser.
fn load_scene(path: &Path) -> anyhow::Result<Vec<SceneJob>> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let doc: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        anyhow!("{}: {}", path.display(), e.to_string().trim_end())
    })?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut jobs = Vec::new();
    for (kind, value) in &doc {
        if !KINDS.contains(&kind.as_str()) {
            let hint = did_you_mean(kind, KINDS.iter().copied())
                .map(|k| format!("did you mean [[{k}]]? "))
                .unwrap_or_default();
            bail!(
                "{}: unknown table `{kind}` ({hint}jobs are [[{}]])",
                path.display(),
                KINDS.join("]], [[")
            );
        }
        let tables = value.as_array().ok_or_else(|| {
            anyhow!(
                "{}: `{kind}` must be an array of tables: write [[{kind}]]",
                path.display()
            )
        })?;
        for (i, table) in tables.iter().enumerate() {
            let table = table.as_table().ok_or_else(|| {
                anyhow!(
                    "{}: [[{kind}]] entry {} is not a table",
                    path.display(),
                    i + 1
                )
            })?;
            let name = match table.get("name") {
                Some(toml::Value::String(s)) => s.clone(),
                _ => format!("{kind}{}", i + 1),
            };
            let place = format!("{}: [[{kind}]] job {} (`{name}`)", path.display(), i + 1);
            let argv = job_arguments(kind, table, &dir).map_err(|e| anyhow!("{place}: {e}"))?;
            let cli =
                Cli::try_parse_from(argv).map_err(|e| anyhow!("{place}: {}", clap_message(&e)))?;
            jobs.push(SceneJob {
                kind: kind.clone(),
                name,
                command: cli.command,
            });
        }
    }
    if jobs.is_empty() {
        bail!(
            "{}: no jobs: a scene lists [[cloth]] and [[ik]] tables (see scenes/demo.toml)",
            path.display()
        );
    }
    let mut names: Vec<&str> = jobs.iter().map(|j| j.name.as_str()).collect();
    names.sort_unstable();
    if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
        bail!(
            "{}: two jobs are named `{}`; names must be unique for --only",
            path.display(),
            w[0]
        );
    }
    Ok(jobs)
}

/// The argument vector `scenebake KIND --key value ...` for one job table.
fn job_arguments(kind: &str, table: &toml::Table, dir: &Path) -> anyhow::Result<Vec<OsString>> {
    let command = Cli::command();
    let sub = command
        .find_subcommand(kind)
        .ok_or_else(|| anyhow!("unknown job kind `{kind}`"))?;
    let mut argv: Vec<OsString> = vec!["scenebake".into(), kind.into()];
    let mut positional = Vec::new();
    for (raw_key, value) in table {
        let key = raw_key.replace('_', "-");
        let arg = sub
            .get_arguments()
            .find(|a| {
                a.get_long() == Some(key.as_str())
                    || (a.is_positional() && a.get_id().as_str() == key)
            })
            .ok_or_else(|| {
                let mut known: Vec<String> = sub
                    .get_arguments()
                    .filter_map(|a| {
                        a.get_long()
                            .map(str::to_owned)
                            .or_else(|| a.is_positional().then(|| a.get_id().to_string()))
                    })
                    .filter(|k| k != "help" && k != "version" && k != "quiet")
                    .collect();
                known.sort();
                let hint = did_you_mean(&key, known.iter().map(String::as_str))
                    .map(|k| format!("did you mean `{k}`? "))
                    .unwrap_or_default();
                anyhow!("unknown key `{raw_key}` ({hint}keys: {})", known.join(", "))
            })?;
        let takes_value = arg.get_num_args().is_none_or(|n| n.takes_values());
        let values: Vec<&toml::Value> = match value {
            toml::Value::Array(items) => items.iter().collect(),
            v => vec![v],
        };
        for v in values {
            let text = match v {
                toml::Value::String(s) if PATH_KEYS.contains(&key.as_str()) => lexically_normal(&dir.join(s)).into_os_string(),
                // A font file (not a built-in font name) is relative to the scene too.
                toml::Value::String(s)
                    if key == "font" && (s.contains('/') || s.contains('.')) =>
                {
                    lexically_normal(&dir.join(s)).into_os_string()
                }
                // A mesh collider's file is relative to the scene too.
                toml::Value::String(s) if key == "collider" && s.starts_with("mesh:") => {
                    let mut spec = OsString::from("mesh:");
                    spec.push(lexically_normal(&dir.join(s["mesh:".len()..].trim())));
                    spec
                }
                toml::Value::String(s) => s.into(),
                toml::Value::Integer(i) => i.to_string().into(),
                toml::Value::Float(f) => f.to_string().into(),
                toml::Value::Boolean(b) if !takes_value => {
                    if *b {
                        argv.push(format!("--{key}").into());
                    }
                    continue;
                }
                toml::Value::Boolean(b) => b.to_string().into(),
                other => bail!("key `{raw_key}`: expected a string, number, boolean or array of them, found {}", other.type_str()),
            };
            if arg.is_positional() {
                positional.push(text);
            } else {
                argv.push(format!("--{key}").into());
                argv.push(text);
            }
        }
    }
    if !positional.is_empty() {
        argv.push("--".into());
        argv.extend(positional);
    }
    Ok(argv)
}

/// `a/b/../c` → `a/c`, without touching the file system (the output may not exist yet).
fn lexically_normal(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            other => out.push(other),
        }
    }
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    out
}

/// The known word closest to `word` (edit distance at most 2, or a third of its length), if
/// any: the likely intended spelling of a typo.
fn did_you_mean<'a>(word: &str, known: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (word.chars().count() / 3).max(2);
    known
        .map(|k| (edit_distance(word, k), k))
        .filter(|&(d, _)| d <= limit)
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k)
}

/// Levenshtein distance between two strings, in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

/// clap's message without its `error:` prefix and usage footer, on one line.
fn clap_message(e: &clap::Error) -> String {
    let text = e.render().to_string();
    text.lines()
        .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
        .map(|l| l.trim().trim_start_matches("error: "))
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}
