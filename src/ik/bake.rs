//! The IK bake: chain + target path + solver → a glTF animation and a report.
//!
//! [`IkJob`] is a plain description of one `scenebake ik` run, one field per command-line
//! option; [`bake_ik`] runs it.

use std::f64::consts::TAU;
use std::path::PathBuf;
use std::str::FromStr;
use std::time::Instant;

use glam::{DQuat, DVec2, DVec3};

use super::chain::{Chain, ROOT_HEIGHT_FRACTION};
use super::constraints::Constraints;
use super::rig::RigDocument;
use super::solver::{IkSolver, SolverConfig};
use super::{Ccd, Fabrik};
use crate::error::{Error, Result};
use crate::export::skin::{write_chain_gltf, write_rig_gltf, IkFrames};
use crate::path::font::Font;
use crate::path::{self, CurveKind, PenTarget, Plane, Stroke, Timing};

/// Which solver runs (`--solver`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// FABRIK (the default).
    #[default]
    Fabrik,
    /// Cyclic coordinate descent.
    Ccd,
}

impl SolverKind {
    /// The option value (`fabrik`, `ccd`).
    pub fn as_str(self) -> &'static str {
        match self {
            SolverKind::Fabrik => "fabrik",
            SolverKind::Ccd => "ccd",
        }
    }
}

impl FromStr for SolverKind {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "fabrik" => Ok(SolverKind::Fabrik),
            "ccd" => Ok(SolverKind::Ccd),
            _ => Err(Error::option(
                "--solver",
                format!("`{s}`: expected fabrik or ccd"),
            )),
        }
    }
}

/// The name of the lab arm preset (`--preset lab-arm`).
pub const LAB_ARM: &str = "lab-arm";

/// Default tip speed as a fraction of the chain's reach per second: the lab circle (radius 0.6
/// on the 2.6-long arm) drawn in 5 s, so at the default 30 fps it keeps the lab's 150 targets.
pub const TIP_SPEED_PER_REACH: f64 = TAU * 0.6 / 2.6 / 5.0;

/// Default time for the pen to reach `--pen-speed` from rest (and to stop), seconds.
pub const DEFAULT_EASE: f64 = 0.15;

/// One `scenebake ik` run. Each field is one command-line option:
///
/// | field | option | default |
/// | --- | --- | --- |
/// | `preset` | `--preset NAME` (only `lab-arm`) | — |
/// | `joints` | `--joints N` (straight generated chain of N joints) | — |
/// | `length` | `--length L` (total length of that chain) | 2.6 |
/// | `rig` | `--rig FILE.glb\|.gltf` | — |
/// | `chain` | `--chain ROOT..TIP` (names or `#N`; with `--rig`) | — |
/// | `solver` | `--solver fabrik\|ccd` ([`SolverKind::from_str`]) | fabrik |
/// | `max_iterations` | `--max-iterations N` | 100 |
/// | `tolerance` | `--tolerance D` (scene units) | 1e-4 |
/// | `max_angle` | `--max-angle DEG` (per joint per frame) | unlimited |
/// | `pole` | `--pole X,Y,Z` (the chain bends towards this world point) | none |
/// | `limit` | `--limit JOINT:hinge:MIN..MAX[:X,Y,Z]`, `--limit JOINT:cone:DEG` (repeatable; [`Constraints::from_specs`]) | none |
/// | `fps` | `--fps F` | 30 |
/// | `curve` | `--curve circle\|square\|heart\|triangle\|star` ([`CurveKind::from_str`]) | — |
/// | `text` | `--text "..."` | — |
/// | `font` | `--font NAME\|FILE.ttf` (with `--text`; [`crate::path::font`]) | simplex |
/// | `svg` | `--svg FILE` | — |
/// | `points` | `--points FILE.csv` | — |
/// | `radius` | `--radius R` (curve size) | lab arm: 0.6 (heart 0.5); else reach·0.6/2.6 (heart reach·0.5/2.6) |
/// | `center` | `--center X,Y,Z` ([`crate::spec::parse_vec3`]) | lab arm: origin; with `normal`: root − (1.7/2.6)·reach·normal; else root + (1.7/2.6)·reach along the chain |
/// | `normal` | `--normal X,Y,Z` (the board faces along it) | the chain's rest direction, reversed |
/// | `size` | `--size H` (letter height for `--text`, drawing height for `--svg`) | fit to reach |
/// | `lift` | `--lift D` (pen lift between strokes) | 0.04·reach |
/// | `spacing` | `--spacing D` (target spacing along the path) | tip speed (0.29·reach/s) / fps |
/// | `pen_speed` | `--pen-speed V` (scene units/s; strokes and lifts start and end at rest) | none: even spacing |
/// | `ease` | `--ease S` (seconds to reach the pen speed; with `pen_speed`) | 0.15 |
/// | `output` | `-o FILE.glb\|.gltf` | `exports/ik.glb` |
/// | `report` | `--report FILE.json` | none |
///
/// Exactly one chain source (`preset`, `joints`, or `rig` + `chain`) and exactly one path source
/// (`curve`, `text`, `svg`, `points`) must be given. The drawing plane (the board) passes through
/// `center` and faces along `normal` (by default it is perpendicular to the chain's rest
/// direction, root → end effector). Drawings are laid out to read correctly for someone on the
/// chain root's side of the board, up towards world +Y, whichever way `normal` points; the pen
/// lifts towards that side.
///
/// The struct also (de)serialises with serde under the option names (`max-iterations`,
/// `max-angle`...), every key optional, unknown keys rejected, so scene files can hold a job.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, rename_all = "kebab-case", deny_unknown_fields)]
pub struct IkJob {
    /// `--preset`.
    pub preset: Option<String>,
    /// `--joints`.
    pub joints: Option<usize>,
    /// `--length`.
    pub length: Option<f64>,
    /// `--rig`.
    pub rig: Option<PathBuf>,
    /// `--chain`.
    pub chain: Option<String>,
    /// `--solver`.
    pub solver: SolverKind,
    /// `--max-iterations`.
    pub max_iterations: usize,
    /// `--tolerance` (scene units).
    pub tolerance: f64,
    /// `--max-angle` (degrees).
    pub max_angle: Option<f64>,
    /// `--pole` (world point).
    pub pole: Option<DVec3>,
    /// `--limit` specifications, one per limited joint.
    pub limit: Vec<String>,
    /// `--fps`.
    pub fps: f64,
    /// `--curve`.
    pub curve: Option<CurveKind>,
    /// `--text`.
    pub text: Option<String>,
    /// `--font` (built-in name or font file).
    pub font: Option<String>,
    /// `--svg`.
    pub svg: Option<PathBuf>,
    /// `--points`.
    pub points: Option<PathBuf>,
    /// `--radius` (scene units).
    pub radius: Option<f64>,
    /// `--center` (world position).
    pub center: Option<DVec3>,
    /// `--normal` (world direction the board faces).
    pub normal: Option<DVec3>,
    /// `--size` (scene units).
    pub size: Option<f64>,
    /// `--lift` (scene units).
    pub lift: Option<f64>,
    /// `--spacing` (scene units).
    pub spacing: Option<f64>,
    /// `--pen-speed` (scene units per second).
    pub pen_speed: Option<f64>,
    /// `--ease` (seconds).
    pub ease: Option<f64>,
    /// `-o`.
    pub output: PathBuf,
    /// `--report`.
    pub report: Option<PathBuf>,
}

impl Default for IkJob {
    fn default() -> Self {
        IkJob {
            preset: None,
            joints: None,
            length: None,
            rig: None,
            chain: None,
            solver: SolverKind::Fabrik,
            max_iterations: 100,
            tolerance: 1e-4,
            max_angle: None,
            pole: None,
            limit: Vec::new(),
            fps: 30.0,
            curve: None,
            text: None,
            font: None,
            svg: None,
            points: None,
            radius: None,
            center: None,
            normal: None,
            size: None,
            lift: None,
            spacing: None,
            pen_speed: None,
            ease: None,
            output: PathBuf::from("exports/ik.glb"),
            report: None,
        }
    }
}

/// What a bake did (serialised as the `--report` JSON).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct IkReport {
    /// Number of joints in the chain (end effector included).
    pub joints: usize,
    /// Joint names, root first.
    pub joint_names: Vec<String>,
    /// Number of frames (one target per frame).
    pub frames: usize,
    /// Frames per second.
    pub fps: f64,
    /// `"fabrik"` or `"ccd"`.
    pub solver: String,
    /// Target world position per frame.
    pub targets: Vec<[f64; 3]>,
    /// Whether the pen is down (drawing) at each frame.
    pub pen_down: Vec<bool>,
    /// Solver iterations per frame.
    pub iterations: Vec<usize>,
    /// Distance from end effector to target per frame (scene units).
    pub error: Vec<f64>,
    /// Frames whose error is within the tolerance.
    pub reached: usize,
    /// Frames whose target lies beyond the chain's reach (chain stretched towards it).
    pub unreachable: usize,
    /// Indices of the unreachable frames.
    pub unreachable_frames: Vec<usize>,
    /// Mean iterations per frame.
    pub mean_iterations: f64,
    /// Largest per-frame error.
    pub max_error: f64,
    /// The chain's reach (scene units).
    pub reach: f64,
    /// Seconds spent solving.
    pub seconds_solve: f64,
    /// Seconds for the whole bake (loading, solving, writing).
    pub seconds_total: f64,
    /// Files written.
    pub files: Vec<PathBuf>,
    /// What the bake repaired or could not do as asked (printed on the terminal too).
    pub warnings: Vec<String>,
}

struct Setup {
    chain: Chain,
    rig: Option<(RigDocument, Vec<usize>)>,
    lab: bool,
}

fn positive_opt(option: &str, v: Option<f64>) -> Result<()> {
    if let Some(v) = v {
        crate::spec::positive(option, v)?;
    }
    Ok(())
}

fn setup_chain(job: &IkJob) -> Result<Setup> {
    let sources = [
        job.preset.is_some(),
        job.joints.is_some(),
        job.rig.is_some(),
    ]
    .iter()
    .filter(|&&b| b)
    .count();
    if sources != 1 {
        return Err(Error::option("--preset/--joints/--rig", "give exactly one chain: --preset lab-arm, --joints N [--length L], or --rig FILE --chain ROOT..TIP"));
    }
    if job.length.is_some() && job.joints.is_none() {
        return Err(Error::option("--length", "only applies with --joints"));
    }
    if job.chain.is_some() != job.rig.is_some() {
        return Err(Error::option("--chain", "--rig and --chain go together"));
    }
    if let Some(p) = &job.preset {
        if p != LAB_ARM {
            return Err(Error::option(
                "--preset",
                format!("`{p}`: expected {LAB_ARM}"),
            ));
        }
        return Ok(Setup {
            chain: Chain::lab_arm(),
            rig: None,
            lab: true,
        });
    }
    if let Some(n) = job.joints {
        return Ok(Setup {
            chain: Chain::straight(n, job.length.unwrap_or(2.6))?,
            rig: None,
            lab: false,
        });
    }
    let path = job.rig.as_ref().expect("one source");
    let doc = RigDocument::load(path)?;
    let rc = doc.chain(job.chain.as_deref().expect("checked"))?;
    Ok(Setup {
        chain: rc.chain,
        rig: Some((doc, rc.nodes)),
        lab: false,
    })
}

/// The board's centre and the viewing direction (unit, from the reader's side into the board):
/// see [`IkJob`] for the defaults.
fn board(job: &IkJob, lab: bool, root: DVec3, tip: DVec3, reach: f64) -> Result<(DVec3, DVec3)> {
    if let Some(c) = job.center {
        if !c.is_finite() {
            return Err(Error::option("--center", "must be finite"));
        }
    }
    let Some(n) = job.normal else {
        let view = (tip - root).normalize_or(DVec3::NEG_Y);
        let center = job.center.unwrap_or(if lab {
            DVec3::ZERO
        } else {
            root + view * (reach * ROOT_HEIGHT_FRACTION)
        });
        return Ok((center, view));
    };
    if !n.is_finite() || n.length() < 1e-12 {
        return Err(Error::option(
            "--normal",
            format!("{n}: must be a finite, non-zero direction"),
        ));
    }
    let n = n.normalize();
    let center = job.center.unwrap_or(if lab {
        DVec3::ZERO
    } else {
        root - n * (reach * ROOT_HEIGHT_FRACTION)
    });
    // The reader stands on the root's side of the board.
    let view = if (root - center).dot(n) < 0.0 { n } else { -n };
    Ok((center, view))
}

/// Places 2-D strokes (centred drawing units) on the plane, scaled to `scale`.
fn place(plane: &Plane, strokes: &[Vec<DVec2>], scale: f64, closed: bool) -> Vec<Stroke> {
    strokes
        .iter()
        .map(|s| Stroke {
            points: s.iter().map(|p| plane.to_world(*p * scale)).collect(),
            closed,
        })
        .collect()
}

/// Scale that fits a drawing of `extent` (width, height) in the reachable disc of the plane,
/// capped so its height is at most `max_height`.
fn fit_scale(extent: DVec2, disc: f64, max_height: f64) -> f64 {
    let diag = extent.length().max(1e-12);
    let by_disc = if disc > 0.0 {
        2.0 * disc * 0.85 / diag
    } else {
        f64::INFINITY
    };
    let by_height = if extent.y > 0.0 {
        max_height / extent.y
    } else {
        f64::INFINITY
    };
    let s = by_disc.min(by_height);
    if s.is_finite() {
        s
    } else {
        1.0
    }
}

fn build_strokes(
    job: &IkJob,
    plane: &Plane,
    reach: f64,
    lab: bool,
    disc: f64,
    spacing: f64,
) -> Result<Vec<Stroke>> {
    let sources = [
        job.curve.is_some(),
        job.text.is_some(),
        job.svg.is_some(),
        job.points.is_some(),
    ]
    .iter()
    .filter(|&&b| b)
    .count();
    if sources != 1 {
        return Err(Error::option(
            "--curve/--text/--svg/--points",
            "give exactly one target path",
        ));
    }
    if job.font.is_some() && job.text.is_none() {
        return Err(Error::option("--font", "only applies with --text"));
    }
    let default_radius = |heart: bool| {
        let base = if heart { 0.5 } else { 0.6 };
        if lab {
            base
        } else {
            reach * base / 2.6
        }
    };
    if let Some(curve) = job.curve {
        let r = job
            .radius
            .unwrap_or_else(|| default_radius(curve == CurveKind::Heart));
        let samples = match curve {
            // Evenly spaced in θ is evenly spaced in arc length: one sample per target.
            CurveKind::Circle => ((TAU * r / spacing).round() as usize).max(3),
            _ => 1440,
        };
        return Ok(place(plane, &[curve.polyline(r, samples)], 1.0, true));
    }
    let max_height = 2.0 * default_radius(false);
    if let Some(text) = &job.text {
        let font = Font::load(job.font.as_deref().unwrap_or(path::font::DEFAULT))?;
        let laid = path::font::layout(&font, text)?;
        let scale = match job.size {
            Some(h) => h / font.cap_height(),
            None => fit_scale(laid.extent, disc, max_height),
        };
        return Ok(laid
            .strokes
            .iter()
            .map(|(s, closed)| Stroke {
                points: s.iter().map(|p| plane.to_world(*p * scale)).collect(),
                closed: *closed,
            })
            .collect());
    }
    if let Some(svg) = &job.svg {
        let shapes = path::svg::read_svg(svg)?;
        let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
        for p in shapes.iter().flat_map(|(s, _)| s) {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let mid = (lo + hi) / 2.0;
        let extent = hi - lo;
        let scale = match job.size {
            Some(h) => h / extent.y.max(1e-12),
            None => fit_scale(extent, disc, max_height),
        };
        // SVG y points down: flip it.
        return Ok(shapes
            .iter()
            .map(|(s, closed)| Stroke {
                points: s
                    .iter()
                    .map(|p| plane.to_world(DVec2::new(p.x - mid.x, mid.y - p.y) * scale))
                    .collect(),
                closed: *closed,
            })
            .collect());
    }
    let file = job.points.as_ref().expect("one source");
    let pts = path::points::read_points(file)?;
    Ok(pts
        .strokes
        .iter()
        .map(|s| Stroke {
            points: s
                .iter()
                .map(|p| {
                    if pts.world {
                        *p
                    } else {
                        plane.to_world(p.truncate())
                    }
                })
                .collect(),
            closed: false,
        })
        .collect())
}

/// Runs an IK bake: builds the chain and the pen path, solves one target per frame (warm start
/// from the previous frame), writes the glTF at `job.output` and, if asked, the report JSON.
/// `progress(done, total)` is called after each solved frame.
///
/// # Errors
/// [`Error::InvalidOption`] for inconsistent options; load errors for `--rig`, `--points`,
/// `--svg`; [`Error::UnknownJoint`] / [`Error::JointNotBelow`] for a bad `--chain`; write
/// errors. Frames that do not converge are reported, not errors.
pub fn bake_ik(job: &IkJob, progress: &mut dyn FnMut(usize, usize)) -> Result<IkReport> {
    let t0 = Instant::now();
    crate::spec::positive("--fps", job.fps)?;
    crate::spec::positive("--tolerance", job.tolerance)?;
    if job.max_iterations == 0 {
        return Err(Error::option("--max-iterations", "0: must be at least 1"));
    }
    positive_opt("--max-angle", job.max_angle)?;
    positive_opt("--radius", job.radius)?;
    positive_opt("--size", job.size)?;
    positive_opt("--spacing", job.spacing)?;
    if let Some(l) = job.lift {
        crate::spec::non_negative("--lift", l)?;
    }
    let setup = setup_chain(job)?;
    let chain = &setup.chain;
    let constraints = Constraints::from_specs(chain, job.pole, &job.limit)?;
    let rest = chain.rest_pose();
    let reach = chain.reach(&rest);
    let root = rest.position(0);
    let (center, view) = board(job, setup.lab, root, rest.tip(), reach)?;
    let plane = if job.normal.is_some() {
        Plane::facing_from(center, view, root)
    } else {
        Plane::facing(center, view)
    };
    let h = (center - root).dot(view);
    let disc = (reach * reach - h * h).max(0.0).sqrt();
    positive_opt("--pen-speed", job.pen_speed)?;
    if job.pen_speed.is_some() && job.spacing.is_some() {
        return Err(Error::option(
            "--pen-speed",
            "give --pen-speed or --spacing, not both",
        ));
    }
    if let Some(e) = job.ease {
        if job.pen_speed.is_none() {
            return Err(Error::option("--ease", "only applies with --pen-speed"));
        }
        crate::spec::non_negative("--ease", e)?;
    }
    let spacing = match job.pen_speed {
        Some(v) => v / job.fps,
        None => job.spacing.unwrap_or(reach * TIP_SPEED_PER_REACH / job.fps),
    };
    let timing = match job.pen_speed {
        Some(_) => Timing::Eased {
            step: spacing,
            ease_frames: job.ease.unwrap_or(DEFAULT_EASE) * job.fps,
        },
        None => Timing::Even(spacing),
    };
    let lift = job.lift.unwrap_or(0.04 * reach);
    let strokes = build_strokes(job, &plane, reach, setup.lab, disc, spacing)?;
    let targets: Vec<PenTarget> = path::pen_path_timed(&strokes, timing, -view * lift);
    if targets.is_empty() {
        return Err(Error::option(
            "--curve/--text/--svg/--points",
            "the path has no points",
        ));
    }

    let config = SolverConfig {
        max_iterations: job.max_iterations,
        tolerance: job.tolerance,
        max_angle: job.max_angle.map(f64::to_radians),
    };
    let solver: Box<dyn IkSolver> = match job.solver {
        SolverKind::Fabrik => Box::new(Fabrik { config }),
        SolverKind::Ccd => Box::new(Ccd { config }),
    };
    let t_solve = Instant::now();
    let mut pose = rest.clone();
    let total = targets.len();
    let mut rotations: Vec<DQuat> = Vec::with_capacity(total * chain.len());
    let mut tips = Vec::with_capacity(total);
    let (mut iterations, mut error, mut unreachable_frames) = (
        Vec::with_capacity(total),
        Vec::with_capacity(total),
        Vec::new(),
    );
    let mut reached = 0;
    for (k, t) in targets.iter().enumerate() {
        let r = solver.solve_with(chain, &mut pose, t.position, &constraints)?;
        rotations.extend_from_slice(&pose.rotations);
        tips.push(pose.tip());
        iterations.push(r.iterations);
        error.push(r.error);
        reached += usize::from(r.reached);
        if r.unreachable {
            unreachable_frames.push(k);
        }
        progress(k + 1, total);
    }
    let seconds_solve = t_solve.elapsed().as_secs_f64();

    let frames = IkFrames {
        fps: job.fps,
        joints: chain.len(),
        rotations: &rotations,
        name: "ik",
    };
    let mut warnings = Vec::new();
    let written = match setup.rig {
        Some((doc, nodes)) => {
            warnings.extend(doc.warnings.iter().cloned());
            write_rig_gltf(&job.output, doc, chain, &nodes, &frames)?
        }
        None => write_chain_gltf(&job.output, chain, &rest, &frames, &targets, &tips)?,
    };
    let mut report = IkReport {
        joints: chain.len(),
        joint_names: chain.joints().iter().map(|j| j.name.clone()).collect(),
        frames: total,
        fps: job.fps,
        solver: solver.name().into(),
        targets: targets.iter().map(|t| t.position.to_array()).collect(),
        pen_down: targets.iter().map(|t| t.stroke.is_some()).collect(),
        mean_iterations: iterations.iter().sum::<usize>() as f64 / total as f64,
        max_error: error.iter().cloned().fold(0.0, f64::max),
        iterations,
        error,
        reached,
        unreachable: unreachable_frames.len(),
        unreachable_frames,
        reach,
        seconds_solve,
        seconds_total: 0.0,
        files: written.files,
        warnings,
    };
    if let Some(path) = &job.report {
        report.seconds_total = t0.elapsed().as_secs_f64();
        report.files.push(path.clone());
        let bytes = serde_json::to_vec_pretty(&report).map_err(|error| Error::Json {
            path: path.clone(),
            error,
        })?;
        crate::export::atomic::write_atomically(path, bytes)?;
    }
    report.seconds_total = t0.elapsed().as_secs_f64();
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_circle_defaults_to_150_targets() {
        let dir = tempfile::tempdir().unwrap();
        let job = IkJob {
            preset: Some(LAB_ARM.into()),
            curve: Some(CurveKind::Circle),
            output: dir.path().join("c.glb"),
            ..Default::default()
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert_eq!(r.frames, 150);
        assert!(
            r.targets
                .iter()
                .all(|t| t[1].abs() < 1e-12
                    && ((t[0] * t[0] + t[2] * t[2]).sqrt() - 0.6).abs() < 1e-9)
        );
    }

    #[test]
    fn jobs_deserialise_under_the_option_names() {
        let job: IkJob = toml::from_str("preset = \"lab-arm\"\ncurve = \"heart\"\nsolver = \"ccd\"\nmax-iterations = 50\ncenter = [0.0, 0.1, 0.0]\noutput = \"h.glb\"\n").unwrap();
        assert_eq!(job.curve, Some(CurveKind::Heart));
        assert_eq!(job.solver, SolverKind::Ccd);
        assert_eq!(job.max_iterations, 50);
        assert_eq!(job.tolerance, 1e-4);
        assert_eq!(job.center, Some(DVec3::new(0.0, 0.1, 0.0)));
        assert!(toml::from_str::<IkJob>("max_iter = 3").is_err());
    }

    #[test]
    fn option_conflicts_are_named() {
        let e = bake_ik(
            &IkJob {
                curve: Some(CurveKind::Circle),
                ..Default::default()
            },
            &mut |_, _| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--preset"), "{e}");
        let e = bake_ik(
            &IkJob {
                preset: Some("robot".into()),
                curve: Some(CurveKind::Circle),
                ..Default::default()
            },
            &mut |_, _| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--preset") && e.contains("robot"), "{e}");
        let e = bake_ik(
            &IkJob {
                preset: Some(LAB_ARM.into()),
                ..Default::default()
            },
            &mut |_, _| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--curve"), "{e}");
        assert!("cdd"
            .parse::<SolverKind>()
            .unwrap_err()
            .to_string()
            .contains("--solver"));
    }
}
