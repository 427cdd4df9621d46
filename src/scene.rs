//! Scene files: several jobs in one TOML file, run together.
//!
//! A scene lists `[[cloth]]` and `[[ik]]` tables; each deserialises straight into a
//! [`ClothJob`] or an [`IkJob`], its keys the config's fields (the parameters' [`Param::key`]s:
//! `frames = 120`, `pin = ["box:..."]`, `gravity = "0,-9.81,0"` or `[0, -9.81, 0]`). Relative
//! paths (inputs, outputs, reports, rigs, body sequences, drawings, font files, mesh colliders) are relative to
//! the scene file. Jobs are independent: [`Scene::jobs`] may run in any order or in parallel.
//!
//! ```no_run
//! let scene = scenebake::scene::Scene::load("scenes/demo.toml".as_ref())?;
//! for job in &scene.jobs {
//!     let report = job.job.run(&mut |_done, _total| {})?;
//!     println!("{}: {} frames", job.name, report.frames());
//! }
//! # Ok::<(), scenebake::Error>(())
//! ```
//!
//! [`Param::key`]: crate::param::Param::key

use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

use serde::de::{self, Deserialize, Visitor};

use crate::bake::outputs::{check_writable, cloth_outputs, ik_outputs, OutputFile};
use crate::bake::{bake_cloth, bake_ik, ClothJob, ClothReport, IkJob, IkReport};
use crate::cloth::collide::ColliderSpec;
use crate::cores::CoreShare;
use crate::error::{Error, Result};

/// A loaded scene.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The scene file.
    pub path: PathBuf,
    /// Its jobs: every `[[cloth]]` table in file order, then every `[[ik]]` table.
    pub jobs: Vec<SceneJob>,
}

/// One job of a scene.
#[derive(Debug, Clone)]
pub struct SceneJob {
    /// The job's `name`, or `cloth1`, `ik2`... by kind and position.
    pub name: String,
    /// The job, paths resolved against the scene file's folder.
    pub job: Job,
}

/// A job of either kind.
#[derive(Debug, Clone, PartialEq)]
pub enum Job {
    /// A cloth bake.
    Cloth(Box<ClothJob>),
    /// An IK bake.
    Ik(Box<IkJob>),
}

/// What a job returns.
#[derive(Debug, Clone, serde::Serialize)]
#[serde(untagged)]
pub enum Report {
    /// A cloth bake's report.
    Cloth(Box<ClothReport>),
    /// An IK bake's report.
    Ik(Box<IkReport>),
}

impl Report {
    /// Frames simulated or solved (after the initial state).
    pub fn frames(&self) -> usize {
        match self {
            Report::Cloth(r) => r.frames,
            Report::Ik(r) => r.frames,
        }
    }

    /// Frames written: those simulated less, for a bake on a character, the blend-in and
    /// warm-up frames simulated first and cut.
    pub fn frames_written(&self) -> usize {
        match self {
            Report::Cloth(r) => r
                .character
                .as_ref()
                .map_or(r.frames, |c| r.frames.saturating_sub(c.first_written_frame)),
            Report::Ik(r) => r.frames,
        }
    }

    /// The report's warnings.
    pub fn warnings(&self) -> &[crate::param::Text] {
        match self {
            Report::Cloth(r) => &r.warnings,
            Report::Ik(r) => &r.warnings,
        }
    }
}

impl Job {
    /// `cloth` or `ik`: the job's table name in scene files.
    pub fn kind(&self) -> &'static str {
        match self {
            Job::Cloth(_) => "cloth",
            Job::Ik(_) => "ik",
        }
    }

    /// The main output file.
    pub fn output(&self) -> &Path {
        match self {
            Job::Cloth(j) => &j.output,
            Job::Ik(j) => &j.output,
        }
    }

    /// Where the caller should write the job's report, when asked.
    pub fn report_path(&self) -> Option<&Path> {
        match self {
            Job::Cloth(j) => j.report.as_deref(),
            Job::Ik(j) => j.report.as_deref(),
        }
    }

    /// Every file the job writes (its report included), with the parameter naming each.
    pub fn outputs(&self) -> Vec<OutputFile> {
        match self {
            Job::Cloth(j) => cloth_outputs(j),
            Job::Ik(j) => ik_outputs(j),
        }
    }

    /// Checks that every file the job writes can be written, before it runs.
    ///
    /// # Errors
    /// As [`check_writable`].
    pub fn check_outputs(&self) -> Result<()> {
        check_writable(&self.outputs())
    }

    /// Frames the job will bake, when known before it runs (for progress displays).
    pub fn frames_hint(&self) -> Option<usize> {
        match self {
            Job::Cloth(j) => Some(j.frames.unwrap_or(crate::bake::cloth::defaults::FRAMES)),
            Job::Ik(_) => None,
        }
    }

    /// The job taking its threads from `share` where it does not name its own (`threads` in a
    /// cloth job): a scene running several jobs at once shares the cores among them.
    pub fn with_core_share(&self, share: &Arc<CoreShare>) -> Job {
        match self {
            Job::Cloth(j) if j.threads.is_none() => Job::Cloth(Box::new(ClothJob {
                share: Some(Arc::clone(share)),
                ..(**j).clone()
            })),
            job => job.clone(),
        }
    }

    /// Runs the job; `progress(done, total)` is called as frames are baked.
    ///
    /// # Errors
    /// The job's own errors ([`bake_cloth`], [`bake_ik`]).
    pub fn run(&self, progress: &mut dyn FnMut(usize, usize)) -> Result<Report> {
        Ok(match self {
            Job::Cloth(j) => Report::Cloth(Box::new(bake_cloth(j, progress)?)),
            Job::Ik(j) => Report::Ik(Box::new(bake_ik(j, progress)?)),
        })
    }
}

/// The tables a scene may hold.
const KINDS: &[&str] = &["cloth", "ik"];

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    cloth: Vec<ClothJob>,
    #[serde(default)]
    ik: Vec<IkJob>,
}

impl Scene {
    /// Reads and checks a scene file.
    ///
    /// # Errors
    /// [`Error::Io`] when unreadable; [`Error::Scene`] naming the job and key for an unknown
    /// table or key (with the likely intended spelling), a value of the wrong type or form
    /// (with its line), no jobs, or two jobs with one name.
    pub fn load(path: &Path) -> Result<Scene> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Scene::parse(&text, path)
    }

    /// Parses a scene's text; `path` is where it came from (for messages and relative paths).
    ///
    /// # Errors
    /// As [`Scene::load`].
    pub fn parse(text: &str, path: &Path) -> Result<Scene> {
        let fail = |job: Option<String>, message: String| Error::Scene {
            path: path.to_path_buf(),
            job,
            message,
        };
        let table: toml::Table =
            toml::from_str(text).map_err(|e| fail(None, e.to_string().trim_end().to_owned()))?;
        check_keys(&table).map_err(|(job, m)| fail(job, m))?;
        let file: SceneFile = toml::from_str(text).map_err(|e| {
            let job = e.span().and_then(|span| job_at(text, &table, span.start));
            // A value of the wrong form: its line and key in one plain sentence.
            let message = match e.span().and_then(|span| key_at(text, span.start)) {
                Some((line, key)) => format!("line {line}: `{key}`: {}", e.message()),
                None => e.to_string().trim_end().to_owned(),
            };
            fail(job, message)
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        let mut jobs = Vec::new();
        for (i, mut job) in file.cloth.into_iter().enumerate() {
            let name = job
                .name
                .clone()
                .unwrap_or_else(|| format!("cloth{}", i + 1));
            if job.output.as_os_str().is_empty() {
                return Err(fail(
                    Some(format!("[[cloth]] job {} (`{name}`)", i + 1)),
                    "`output` is required".into(),
                ));
            }
            resolve_cloth(&mut job, dir);
            jobs.push(SceneJob {
                name,
                job: Job::Cloth(Box::new(job)),
            });
        }
        for (i, mut job) in file.ik.into_iter().enumerate() {
            let name = job.name.clone().unwrap_or_else(|| format!("ik{}", i + 1));
            if job.output.as_os_str().is_empty() {
                return Err(fail(
                    Some(format!("[[ik]] job {} (`{name}`)", i + 1)),
                    "`output` is required".into(),
                ));
            }
            resolve_ik(&mut job, dir);
            jobs.push(SceneJob {
                name,
                job: Job::Ik(Box::new(job)),
            });
        }
        if jobs.is_empty() {
            return Err(fail(
                None,
                "no jobs: a scene lists [[cloth]] and [[ik]] tables (see scenes/demo.toml)".into(),
            ));
        }
        let mut names: Vec<&str> = jobs.iter().map(|j| j.name.as_str()).collect();
        names.sort_unstable();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            return Err(fail(
                None,
                format!("two jobs are named `{}`; names must be unique", w[0]),
            ));
        }
        shared_outputs(&jobs).map_err(|m| fail(None, m))?;
        Ok(Scene {
            path: path.to_path_buf(),
            jobs,
        })
    }
}

/// Two jobs that write one file (their outputs, `.bin`s, VAT files or reports), or one job that
/// writes a file twice: whichever is written last would silently replace the other.
fn shared_outputs(jobs: &[SceneJob]) -> std::result::Result<(), String> {
    let mut seen: std::collections::HashMap<PathBuf, (&str, crate::param::Param)> =
        std::collections::HashMap::new();
    for job in jobs {
        for OutputFile { param, path } in job.job.outputs() {
            if let Some((first, first_param)) =
                seen.insert(path.clone(), (job.name.as_str(), param))
            {
                return Err(if first == job.name {
                    format!(
                        "job `{first}` writes {} twice (as its {first_param} and its {param}); \
                         give each its own file",
                        path.display()
                    )
                } else {
                    format!(
                        "jobs `{first}` and `{}` both write {} (as their {first_param} and \
                         {param}); give each job its own files",
                        job.name,
                        path.display()
                    )
                });
            }
        }
    }
    Ok(())
}

/// The one-based line and the key of the `key = value` whose value starts at byte `offset` of
/// the scene's text.
fn key_at(text: &str, offset: usize) -> Option<(usize, String)> {
    let before = text.get(..offset)?;
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    let (key, rest) = before[start..].split_once('=')?;
    let key = key.trim().trim_matches('"');
    let plain = !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    (plain && rest.trim().is_empty()).then(|| (line, key.to_owned()))
}

/// "[[cloth]] job 2 (`name`)" for the job whose table holds byte `offset` of the scene's text.
fn job_at(text: &str, table: &toml::Table, offset: usize) -> Option<String> {
    let mut current: Option<(String, usize)> = None;
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        if at > offset {
            break;
        }
        let header = line.trim();
        if let Some(kind) = header.strip_prefix("[[").and_then(|h| h.strip_suffix("]]")) {
            let n = counts.entry(kind.trim().to_owned()).or_insert(0);
            *n += 1;
            current = Some((kind.trim().to_owned(), *n));
        } else if header.starts_with('[') {
            current = None;
        }
        at += line.len();
    }
    let (kind, n) = current?;
    let name = table
        .get(&kind)
        .and_then(|v| v.as_array())
        .and_then(|a| a.get(n - 1))
        .and_then(|t| t.get("name"))
        .and_then(|v| v.as_str())
        .map_or_else(|| format!("{kind}{n}"), str::to_owned);
    Some(format!("[[{kind}]] job {n} (`{name}`)"))
}

/// Unknown tables and keys, with the likely intended spelling.
fn check_keys(table: &toml::Table) -> std::result::Result<(), (Option<String>, String)> {
    for (kind, value) in table {
        let fields = match kind.as_str() {
            "cloth" => fields_of::<ClothJob>(),
            "ik" => fields_of::<IkJob>(),
            _ => {
                let hint = did_you_mean(kind, KINDS.iter().copied())
                    .map(|k| format!("did you mean [[{k}]]? "))
                    .unwrap_or_default();
                return Err((
                    None,
                    format!(
                        "unknown table `{kind}` ({hint}jobs are [[{}]])",
                        KINDS.join("]], [[")
                    ),
                ));
            }
        };
        let Some(tables) = value.as_array() else {
            return Err((
                None,
                format!("`{kind}` must be an array of tables: write [[{kind}]]"),
            ));
        };
        for (i, t) in tables.iter().enumerate() {
            let Some(t) = t.as_table() else {
                return Err((None, format!("[[{kind}]] entry {} is not a table", i + 1)));
            };
            let name = match t.get("name") {
                Some(toml::Value::String(s)) => s.clone(),
                _ => format!("{kind}{}", i + 1),
            };
            for key in t.keys() {
                // Multi-word keys may also be spelt with dashes, as the options are.
                if !fields.contains(&key.replace('-', "_").as_str()) {
                    let hint = did_you_mean(key, fields.iter().copied())
                        .map(|k| format!("did you mean `{k}`? "))
                        .unwrap_or_default();
                    let mut known: Vec<&str> = fields
                        .iter()
                        .copied()
                        .filter(|f| !f.contains('-'))
                        .collect();
                    known.sort_unstable();
                    return Err((
                        Some(format!("[[{kind}]] job {} (`{name}`)", i + 1)),
                        format!("unknown key `{key}` ({hint}keys: {})", known.join(", ")),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The field names serde expects for `T` (a struct), read off its `Deserialize` impl.
pub fn fields_of<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    struct Probe<'a>(&'a mut &'static [&'static str]);
    impl<'de> de::Deserializer<'de> for Probe<'_> {
        type Error = de::value::Error;
        fn deserialize_any<V: Visitor<'de>>(
            self,
            _: V,
        ) -> std::result::Result<V::Value, Self::Error> {
            Err(de::Error::custom("probe"))
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> std::result::Result<V::Value, Self::Error> {
            *self.0 = fields;
            Err(de::Error::custom("probe"))
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
            option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
            ignored_any
        }
    }
    let mut fields: &'static [&'static str] = &[];
    let _ = T::deserialize(Probe(&mut fields));
    fields
}

fn resolve_cloth(job: &mut ClothJob, dir: &Path) {
    let at = |p: &Path| lexically_normal(&dir.join(p));
    job.input = job.input.as_deref().map(at);
    job.rig = job.rig.as_deref().map(at);
    job.body = job.body.as_deref().map(at);
    job.output = at(&job.output);
    job.report = job.report.as_deref().map(at);
    job.vat = job.vat.as_deref().map(at);
    job.pc2 = job.pc2.as_deref().map(at);
    job.mdd = job.mdd.as_deref().map(at);
    job.usd = job.usd.as_deref().map(at);
    for c in &mut job.collider {
        if let ColliderSpec::Mesh { path, .. } = c {
            *path = at(path);
        }
    }
}

fn resolve_ik(job: &mut IkJob, dir: &Path) {
    let at = |p: &Path| lexically_normal(&dir.join(p));
    job.rig = job.rig.as_deref().map(at);
    job.svg = job.svg.as_deref().map(at);
    job.points = job.points.as_deref().map(at);
    job.output = at(&job.output);
    job.report = job.report.as_deref().map(at);
    // A font file (not a built-in font name) is relative to the scene too.
    if let Some(f) = &mut job.font {
        if f.contains('/') || f.contains('.') {
            *f = at(Path::new(f.as_str())).display().to_string();
        }
    }
}

/// `a/b/../c` → `a/c`, without touching the file system (the output may not exist yet).
fn lexically_normal(path: &Path) -> PathBuf {
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
pub fn did_you_mean<'a>(word: &str, known: impl Iterator<Item = &'a str>) -> Option<&'a str> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::param::Param;

    #[test]
    fn every_config_field_is_a_param_and_back() {
        let mut fields: Vec<&str> = fields_of::<ClothJob>().to_vec();
        fields.extend(fields_of::<IkJob>());
        assert!(fields.len() > 60, "{fields:?}");
        // serde lists the dashed aliases too (`max-iterations`).
        fields.retain(|f| !f.contains('-'));
        for f in &fields {
            assert!(
                Param::ALL.iter().any(|p| p.key() == *f),
                "config field `{f}` has no Param"
            );
        }
        for p in Param::ALL {
            assert!(fields.contains(&p.key()), "{p:?} is no config field");
        }
    }

    #[test]
    fn scenes_deserialise_into_configs_with_paths_beside_the_scene() {
        let text = r#"
            [[cloth]]
            name = "a"
            input = "../meshes/plane.obj"
            output = "out/a.glb"
            frames = 3
            stiffness = 200
            gravity = [0, -1, 0]
            pin = "box:-1,-1,-1,1,1,1"
            collider = ["mesh:table.obj", "plane:0,1,0,0"]
            [[ik]]
            preset = "lab-arm"
            curve = "circle"
            output = "ik.glb"
        "#;
        let scene = Scene::parse(text, Path::new("scenes/x.toml")).unwrap();
        assert_eq!(scene.jobs.len(), 2);
        let Job::Cloth(c) = &scene.jobs[0].job else {
            panic!()
        };
        assert_eq!(c.input.as_deref(), Some(Path::new("meshes/plane.obj")));
        assert_eq!(c.output, Path::new("scenes/out/a.glb"));
        assert_eq!(c.stiffness, Some(200.0));
        assert_eq!(c.gravity, Some(glam::DVec3::new(0.0, -1.0, 0.0)));
        assert_eq!(c.pin.len(), 1);
        assert_eq!(
            c.collider[0],
            ColliderSpec::Mesh {
                path: PathBuf::from("scenes/table.obj"),
                part: None
            }
        );
        assert_eq!(scene.jobs[1].name, "ik1");
    }

    #[test]
    fn scene_mistakes_name_the_job_and_key() {
        let e = Scene::parse(
            "[[cloth]]\nname = \"a\"\nframe = 3\noutput = \"a.glb\"\n",
            Path::new("s.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("job 1 (`a`)")
                && e.contains("unknown key `frame`")
                && e.contains("did you mean `frames`"),
            "{e}"
        );
        let e = Scene::parse(
            "[[cloth]]\nframes = \"ten\"\noutput = \"a.glb\"\n",
            Path::new("s.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("job 1 (`cloth1`)") && e.contains("line 2") && e.contains("ten"),
            "{e}"
        );
        let e = Scene::parse("", Path::new("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no jobs"), "{e}");
        let e = Scene::parse("[[clth]]\n", Path::new("s.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("did you mean [[cloth]]"), "{e}");
    }
}
