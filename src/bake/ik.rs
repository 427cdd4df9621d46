//! The IK bake: chain + target path + solver → a glTF animation and a report.
//!
//! [`IkJob`] holds every parameter of one IK bake, with its defaults (scene files deserialise
//! into it; the `scenebake ik` command line is derived from it); [`bake_ik`] runs it and returns
//! the [`IkReport`] for the caller to write or print.

use std::f64::consts::TAU;
use std::path::PathBuf;
use std::str::FromStr;
use std::time::Instant;

use glam::{DQuat, DVec2, DVec3};

use crate::data::animation::{Clip, Skeleton, Trs};
use crate::error::{Error, ForParam, Result};
use crate::export::skin::NodeFrames;
use crate::export::skin::{write_chain_gltf, write_rig_gltf, IkFrames, Trail};
use crate::ik::chain::{Chain, Joint, Pose, ROOT_HEIGHT_FRACTION};
use crate::ik::constraints::{Constraints, TipAxis};
use crate::ik::solver::{IkSolver, SolverConfig};
use crate::ik::{Ccd, Fabrik};
use crate::io::rig::RigDocument;
use crate::param::{Param, Text};
use crate::path::{self, CurveKind, PenTarget, Plane, Stroke, Timing};
use crate::spec::de;
use crate::text;

pub use crate::ik::SolverKind;

impl FromStr for SolverKind {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        match s.trim().to_ascii_lowercase().as_str() {
            "fabrik" => Ok(SolverKind::Fabrik),
            "ccd" => Ok(SolverKind::Ccd),
            _ => Err(Error::param_value(
                Param::Solver,
                format!("`{s}`: expected fabrik or ccd"),
            )),
        }
    }
}

/// Default tip speed as a fraction of the chain's reach per second: the lab circle (radius 0.6
/// on the 2.6-long arm) drawn in 5 s, so at the default 30 fps it keeps the lab's 150 targets.
pub const TIP_SPEED_PER_REACH: f64 = TAU * 0.6 / 2.6 / 5.0;

/// Default time for the pen to reach `--pen-speed` from rest (and to stop), seconds.
pub const DEFAULT_EASE: f64 = 0.15;

/// Generated chains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum IkPreset {
    /// The labs' 5-joint arm (root at 1.7 m, reach 2.6 m).
    LabArm,
}

/// Default values of an IK bake.
pub mod defaults {
    /// Iteration cap per frame.
    pub const MAX_ITERATIONS: usize = 100;
    /// Distance from the target that counts as reached, scene units.
    pub const TOLERANCE: f64 = 1e-4;
    /// Frames per second.
    pub const FPS: f64 = 30.0;
}

/// One IK bake. Lengths are scene units (metres for the generated chains), positions and
/// directions are in glTF's world frame (+Y up), angles in degrees.
///
/// Exactly one chain source (`preset`, `joints`, or `rig` + `chain`) and exactly one path source
/// (`curve`, `text`, `svg`, `points`) must be given. The drawing plane (the board) passes through
/// `center` and faces along `normal` (by default it is perpendicular to the chain's rest
/// direction, root → end effector). Drawings are laid out to read correctly for someone on the
/// chain root's side of the board, up towards world +Y, whichever way `normal` points; the pen
/// lifts towards that side. Defaults that depend on the chain: `radius` lab arm 0.6 (heart 0.5),
/// else reach·0.6/2.6; `center` lab arm the origin, with `normal` root − (1.7/2.6)·reach·normal,
/// else root + (1.7/2.6)·reach along the chain; `lift` 0.04·reach; `spacing` an even tip speed
/// of 0.29·reach/s.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "cli", command(allow_negative_numbers = true))]
pub struct IkJob {
    /// A generated reference chain: the labs' 5-joint arm.
    #[cfg_attr(feature = "cli", arg(long, value_enum))]
    pub preset: Option<IkPreset>,
    /// A straight generated chain of N joints (the last is the end effector).
    #[cfg_attr(feature = "cli", arg(long, value_name = "N"))]
    pub joints: Option<usize>,
    /// Total length of the --joints chain [default: 2.6].
    #[cfg_attr(feature = "cli", arg(long, value_name = "L"))]
    pub length: Option<f64>,
    /// A skinned glTF whose chain to animate (with --chain); the output is this document plus one
    /// new animation.
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.glb|.gltf"))]
    pub rig: Option<PathBuf>,
    /// The chain in --rig, ROOT..TIP: joint names, #N for node N (quote it: a shell drops
    /// everything after an unquoted #, so write --chain '#13..#15'), or Node_N as Blender names
    /// unnamed nodes. `scenebake inspect FILE` lists the nodes with their #N.
    #[cfg_attr(feature = "cli", arg(long, value_name = "ROOT..TIP"))]
    pub chain: Option<String>,
    /// IK solver.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = SolverKind::Fabrik))]
    pub solver: SolverKind,
    /// Iteration cap per frame.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::MAX_ITERATIONS, value_name = "N"))]
    #[serde(alias = "max-iterations")]
    pub max_iterations: usize,
    /// Distance from the target that counts as reached, in scene units.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::TOLERANCE, value_name = "D"))]
    pub tolerance: f64,
    /// Largest rotation of any joint from one frame to the next, in degrees (clamps sudden flips).
    #[cfg_attr(feature = "cli", arg(long, value_name = "DEG"))]
    #[serde(alias = "max-angle")]
    pub max_angle: Option<f64>,
    /// Keep the chain's bend facing this world point (like Blender's IK pole): an elbow points
    /// towards it.
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    pub pole: Option<DVec3>,
    /// Limit a joint, from its rest rotation, in degrees: JOINT:hinge:MIN..MAX (one axis: with
    /// --pole, positive bends the joint out towards the pole; or give the axis as a world
    /// direction, JOINT:hinge:MIN..MAX:X,Y,Z) or JOINT:cone:DEG (the bone stays within DEG of
    /// its rest direction). Repeat for several joints.
    #[serde(deserialize_with = "de::string_list")]
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "JOINT:KIND:RANGE", allow_hyphen_values = true)
    )]
    pub limit: Vec<String>,
    /// Hold the pen along this world direction (e.g. into the board, `--tip-axis 0,0,1` for a
    /// board facing -Z): after each frame's position solve, the end effector (whose rotation
    /// moves no joint, so the tip stays on its target) turns by the shortest arc that points its
    /// pen along the axis. The pen is the direction from the tip joint to its first child in a
    /// rig, else the last bone continued.
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    #[serde(alias = "tip-axis")]
    pub tip_axis: Option<DVec3>,
    /// Layer the bake on this animation of --rig (its name, or #N for the N-th): every node
    /// outside the chain keeps it (sampled at each output frame's time, looping when the bake is
    /// longer), the chain's root moves with its animated parents while the targets stay fixed in
    /// the world, the chain's translations and scales and the end effector's rotation (unless
    /// --tip-axis) follow it too, and the new animation keys the whole skeleton.
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME|#N"))]
    #[serde(alias = "base-animation")]
    pub base_animation: Option<String>,
    /// Frames per second of the animation.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::FPS, value_name = "F"))]
    pub fps: f64,
    /// Follow a closed curve.
    #[cfg_attr(feature = "cli", arg(long, value_enum))]
    pub curve: Option<CurveKind>,
    /// Write text (lines split at \n) in --font.
    #[cfg_attr(feature = "cli", arg(long, value_name = "TEXT"))]
    pub text: Option<String>,
    /// Font for --text: a Hershey single-stroke font (simplex, duplex, triplex, script,
    /// script-complex, cursive, sans, greek), the old capitals-only `grid`, or a TrueType/OpenType
    /// file (letters drawn as outlines) [default: simplex].
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME|FILE.ttf"))]
    pub font: Option<String>,
    /// Draw every path of an SVG file (lines, Béziers and arcs, flattened).
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.svg"))]
    pub svg: Option<PathBuf>,
    /// Follow points from a CSV file: `x,y[,z]` per line, a blank line lifts the pen.
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.csv"))]
    pub points: Option<PathBuf>,
    /// Curve radius in scene units [lab arm: 0.6; rigs: sized to the chain's reach].
    #[cfg_attr(feature = "cli", arg(long, value_name = "R"))]
    pub radius: Option<f64>,
    /// Centre of the drawing [lab arm: the origin; rigs: in front of the chain].
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    pub center: Option<DVec3>,
    /// Direction the drawing board faces (its normal); the drawing reads correctly from the
    /// chain root's side [default: facing the chain root along its rest direction].
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    pub normal: Option<DVec3>,
    /// Letter height (--text) or drawing height (--svg) in scene units [default: fit the reach].
    #[cfg_attr(feature = "cli", arg(long, value_name = "H"))]
    pub size: Option<f64>,
    /// How far the pen lifts between strokes, in scene units [default: 4% of the reach].
    #[cfg_attr(feature = "cli", arg(long, value_name = "D"))]
    pub lift: Option<f64>,
    /// Even spacing of the targets along the path, in scene units [default: an even tip speed at
    /// the chosen fps; the lab circle keeps its 150 targets].
    #[cfg_attr(feature = "cli", arg(long, value_name = "D"))]
    pub spacing: Option<f64>,
    /// Pen speed in scene units per second: one target per frame, every stroke and every lift
    /// starting and ending at rest (instead of --spacing).
    #[cfg_attr(feature = "cli", arg(long, value_name = "V"))]
    #[serde(alias = "pen-speed")]
    pub pen_speed: Option<f64>,
    /// Seconds for the pen to reach --pen-speed from rest, and to stop [default: 0.15].
    #[cfg_attr(feature = "cli", arg(long, value_name = "S"))]
    pub ease: Option<f64>,
    /// Radius of the drawn trail, written as tubes, in scene units [default: 0.5% of the
    /// drawing's size (the diagonal of the pen-down targets' bounding box)].
    #[cfg_attr(feature = "cli", arg(long, value_name = "M"))]
    #[serde(alias = "trail-radius")]
    pub trail_radius: Option<f64>,
    /// Output file: .glb, or .gltf with a .bin beside it.
    #[cfg_attr(feature = "cli", arg(short = 'o', long, value_name = "FILE"))]
    pub output: PathBuf,
    /// Write a JSON report of the bake (the library returns the report; the binary and scene
    /// runs write it here).
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.json"))]
    pub report: Option<PathBuf>,
    /// Name for the job in summaries.
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME"))]
    pub name: Option<String>,
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
            max_iterations: defaults::MAX_ITERATIONS,
            tolerance: defaults::TOLERANCE,
            max_angle: None,
            pole: None,
            limit: Vec::new(),
            tip_axis: None,
            base_animation: None,
            fps: defaults::FPS,
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
            trail_radius: None,
            output: PathBuf::new(),
            report: None,
            name: None,
        }
    }
}

impl IkJob {
    /// The name of the job: `name`, else the output's file stem.
    pub fn display_name(&self) -> String {
        self.name.clone().unwrap_or_else(|| {
            self.output
                .file_stem()
                .map_or_else(|| "ik".into(), |s| s.to_string_lossy().into())
        })
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
    /// Radius of the drawn trail's tubes (scene units).
    pub trail_radius: f64,
    /// Seconds spent solving.
    pub seconds_solve: f64,
    /// Seconds for the whole bake (loading, solving, writing).
    pub seconds_total: f64,
    /// Files written.
    pub files: Vec<PathBuf>,
    /// What the bake repaired or could not do as asked (printed on the terminal too).
    pub warnings: Vec<Text>,
}

/// A rig animation the bake is layered on (`--base-animation`).
struct BaseLayer {
    skeleton: Skeleton,
    clip: Clip,
    /// Nodes the clip animates.
    animated: Vec<bool>,
    /// The chain's nodes, root first.
    chain_nodes: Vec<usize>,
    /// The nodes the new animation keys, sorted: those the clip animates, those a skinning
    /// viewer poses with the chain, and the chain.
    keyed: Vec<usize>,
}

impl BaseLayer {
    fn new(doc: &RigDocument, chain_nodes: &[usize], spec: &str) -> Result<Self> {
        let skeleton = doc.skeleton()?;
        let clip = doc.clip(spec).for_param(Param::BaseAnimation)?;
        let animated = clip.animated_nodes(skeleton.len());
        let mut keyed = crate::export::skin::posed_nodes(&doc.root, chain_nodes);
        keyed.extend((0..animated.len()).filter(|&i| animated[i]));
        keyed.extend_from_slice(chain_nodes);
        keyed.sort_unstable();
        keyed.dedup();
        Ok(BaseLayer {
            skeleton,
            clip,
            animated,
            chain_nodes: chain_nodes.to_vec(),
            keyed,
        })
    }

    /// Every node's local transform at bake time `t` (seconds): the clip from its first key,
    /// looped over its duration.
    fn locals(&self, t: f64) -> Vec<Trs> {
        let d = self.clip.duration();
        let local_t = if d > 0.0 { t.rem_euclid(d) } else { 0.0 };
        self.skeleton
            .pose(Some(&self.clip), self.clip.start() + local_t)
    }

    /// The chain at one frame: its base is the animated world frame of the root's parent, its
    /// joints take the animated translations and scales (their rest rotations, against which
    /// limits are measured, stay).
    fn chain_at(&self, template: &Chain, locals: &[Trs]) -> Result<Chain> {
        let base = match self.skeleton.parents[self.chain_nodes[0]] {
            Some(p) => self.skeleton.world(locals, &self.animated)[p],
            None => glam::DAffine3::IDENTITY,
        };
        let joints = template
            .joints()
            .iter()
            .zip(&self.chain_nodes)
            .map(|(j, &node)| Joint {
                translation: locals[node].translation,
                scale: locals[node].scale,
                ..j.clone()
            })
            .collect();
        Chain::new(joints, base)
    }

    /// The chain's pose as the clip has it at one frame.
    fn chain_pose(&self, chain: &Chain, locals: &[Trs]) -> Pose {
        let mut pose = chain.rest_pose();
        for (r, &node) in pose.rotations.iter_mut().zip(&self.chain_nodes) {
            *r = locals[node].rotation;
        }
        chain.fk(&mut pose, 0);
        pose
    }
}

struct Setup {
    chain: Chain,
    rig: Option<(RigDocument, Vec<usize>)>,
    lab: bool,
}

fn positive_opt(option: Param, v: Option<f64>) -> Result<()> {
    if let Some(v) = v {
        crate::spec::positive(v).for_param(option)?;
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
        return Err(Error::param_value(
            Param::Preset,
            text!(
                "give exactly one chain: ",
                Param::Preset,
                " lab-arm, ",
                Param::Joints,
                " N [",
                Param::Length,
                " L], or ",
                Param::Rig,
                " FILE ",
                Param::Chain,
                " ROOT..TIP"
            ),
        ));
    }
    if job.length.is_some() && job.joints.is_none() {
        return Err(Error::param_value(
            Param::Length,
            text!("only applies with ", Param::Joints),
        ));
    }
    if job.chain.is_some() != job.rig.is_some() {
        return Err(Error::param_value(
            Param::Chain,
            text!(Param::Rig, " and ", Param::Chain, " go together"),
        ));
    }
    if let Some(IkPreset::LabArm) = job.preset {
        return Ok(Setup {
            chain: Chain::lab_arm(),
            rig: None,
            lab: true,
        });
    }
    if let Some(n) = job.joints {
        if n < 2 {
            return Err(Error::param_value(
                Param::Joints,
                format!("{n}: a chain needs at least 2 joints"),
            ));
        }
        let length = crate::spec::positive(job.length.unwrap_or(2.6)).for_param(Param::Length)?;
        return Ok(Setup {
            chain: Chain::straight(n, length)?,
            rig: None,
            lab: false,
        });
    }
    let path = job.rig.as_ref().expect("one source");
    let doc = RigDocument::load(path)?;
    let spec = job.chain.as_deref().expect("checked");
    let rc = doc
        .chain(spec)
        .map_err(|e| match e {
            // A degenerate chain, named with the option that picked it.
            Error::Chain(m) => Error::invalid(path, text!(Param::Chain, format!(" {spec}: {m}"))),
            e => e,
        })
        .for_param(Param::Chain)?;
    Ok(Setup {
        chain: rc.chain,
        rig: Some((doc, rc.nodes)),
        lab: false,
    })
}

/// The pen direction in a rig's tip node frame: towards its first child with a non-zero offset.
fn tip_pen(doc: &RigDocument, tip: usize) -> Option<DVec3> {
    doc.root.nodes[tip]
        .children
        .iter()
        .flatten()
        .map(|c| doc.local_transform(c.value()).translation)
        .find(|t| t.length() > 1e-12)
}

/// The board's centre and the viewing direction (unit, from the reader's side into the board):
/// see [`IkJob`] for the defaults.
fn board(job: &IkJob, lab: bool, root: DVec3, tip: DVec3, reach: f64) -> Result<(DVec3, DVec3)> {
    if let Some(c) = job.center {
        if !c.is_finite() {
            return Err(Error::param_value(Param::Center, "must be finite"));
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
        return Err(Error::param_value(
            Param::Normal,
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
        return Err(Error::param_value(
            Param::Curve,
            text!(
                "give exactly one target path: ",
                Param::Curve,
                ", ",
                Param::Text,
                ", ",
                Param::Svg,
                " or ",
                Param::Points
            ),
        ));
    }
    if job.font.is_some() && job.text.is_none() {
        return Err(Error::param_value(
            Param::Font,
            text!("only applies with ", Param::Text),
        ));
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
        let font =
            crate::io::drawing::load_font(job.font.as_deref().unwrap_or(path::font::DEFAULT))
                .for_param(Param::Font)?;
        let laid = path::font::layout(&font, text).for_param(Param::Text)?;
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
        let shapes = crate::io::drawing::read_svg(svg)?;
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
    let pts = crate::io::drawing::read_points(file)?;
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

/// The trail radius when none is given: 0.5% of the diagonal of the pen-down targets' bounding
/// box (0.2% of the reach for a drawing that is a single point).
fn default_trail_radius(targets: &[PenTarget], reach: f64) -> f64 {
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for t in targets.iter().filter(|t| t.stroke.is_some()) {
        lo = lo.min(t.position);
        hi = hi.max(t.position);
    }
    let size = (hi - lo).length();
    if size.is_finite() && size > 0.0 {
        0.005 * size
    } else {
        0.002 * reach
    }
}

/// Runs an IK bake: builds the chain and the pen path, solves one target per frame (warm start
/// from the previous frame), writes the glTF at `job.output` and, if asked, the report JSON.
/// `progress(done, total)` is called after each solved frame.
///
/// # Errors
/// [`Error::Param`] for inconsistent options; load errors for `--rig`, `--points`,
/// `--svg`; [`Error::UnknownJoint`] / [`Error::JointNotBelow`] for a bad `--chain`; write
/// errors, an output that cannot be written checked first ([`super::outputs::check_writable`]).
/// Frames that do not converge are reported, not errors.
pub fn bake_ik(job: &IkJob, progress: &mut dyn FnMut(usize, usize)) -> Result<IkReport> {
    let t0 = Instant::now();
    super::outputs::check_writable(&super::outputs::ik_outputs(job))?;
    crate::spec::positive(job.fps).for_param(Param::Fps)?;
    crate::spec::positive(job.tolerance).for_param(Param::Tolerance)?;
    if job.max_iterations == 0 {
        return Err(Error::param_value(
            Param::MaxIterations,
            "0: must be at least 1",
        ));
    }
    positive_opt(Param::MaxAngle, job.max_angle)?;
    positive_opt(Param::Radius, job.radius)?;
    positive_opt(Param::Size, job.size)?;
    positive_opt(Param::Spacing, job.spacing)?;
    positive_opt(Param::TrailRadius, job.trail_radius)?;
    if let Some(l) = job.lift {
        crate::spec::non_negative(l).for_param(Param::Lift)?;
    }
    let mut setup = setup_chain(job)?;
    let layer = match (&job.base_animation, &setup.rig) {
        (None, _) => None,
        (Some(spec), Some((doc, nodes))) => Some(BaseLayer::new(doc, nodes, spec)?),
        (Some(_), None) => {
            return Err(Error::param_value(
                Param::BaseAnimation,
                text!("only applies with ", Param::Rig),
            ))
        }
    };
    // With a base animation, the chain and its start pose are the clip's at time 0.
    let start = match &layer {
        Some(l) => {
            let locals = l.locals(0.0);
            setup.chain = l.chain_at(&setup.chain, &locals)?;
            Some(l.chain_pose(&setup.chain, &locals))
        }
        None => None,
    };
    let chain = &setup.chain;
    if job.pole.is_some_and(|p| !p.is_finite()) {
        return Err(Error::param_value(Param::Pole, "must be finite"));
    }
    let mut constraints = Constraints::from_specs(chain, job.pole, &job.limit)
        .map_err(|e| match e {
            Error::HingeAxis { spec, joint } => Error::param_value(
                Param::Limit,
                text!(
                    format!(
                        "`{spec}`: cannot tell the bend axis of `{joint}`: it is straight in the \
                         rest pose; give "
                    ),
                    Param::Pole,
                    " or the axis as JOINT:hinge:MIN..MAX:X,Y,Z"
                ),
            ),
            e => e,
        })
        .for_param(Param::Limit)?;
    if let Some(axis) = job.tip_axis {
        let pen = match &setup.rig {
            Some((doc, nodes)) => tip_pen(doc, nodes[nodes.len() - 1]),
            None => None,
        }
        .unwrap_or_else(|| TipAxis::continuing(chain));
        constraints.tip_axis = Some(TipAxis::new(axis, pen).for_param(Param::TipAxis)?);
    }
    let rest = start.unwrap_or_else(|| chain.rest_pose());
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
    positive_opt(Param::PenSpeed, job.pen_speed)?;
    if job.pen_speed.is_some() && job.spacing.is_some() {
        return Err(Error::param_value(
            Param::PenSpeed,
            text!(
                "give ",
                Param::PenSpeed,
                " or ",
                Param::Spacing,
                ", not both"
            ),
        ));
    }
    if let Some(e) = job.ease {
        if job.pen_speed.is_none() {
            return Err(Error::param_value(
                Param::Ease,
                text!("only applies with ", Param::PenSpeed),
            ));
        }
        crate::spec::non_negative(e).for_param(Param::Ease)?;
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
        return Err(Error::param_value(Param::Curve, "the path has no points"));
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
    let mut layered: Vec<Trs> = Vec::new();
    for (k, t) in targets.iter().enumerate() {
        let moved;
        let (frame_chain, locals) = match &layer {
            Some(l) => {
                // The base moves under the chain: refresh its frames, keep the solved rotations
                // (warm start), and let the end effector follow the clip.
                let locals = l.locals(k as f64 / job.fps);
                moved = l.chain_at(chain, &locals)?;
                let n = chain.len();
                pose.rotations[n - 1] = locals[l.chain_nodes[n - 1]].rotation;
                moved.fk(&mut pose, 0);
                (&moved, Some(locals))
            }
            None => (chain, None),
        };
        let r = solver.solve_with(frame_chain, &mut pose, t.position, &constraints)?;
        if let (Some(l), Some(mut locals)) = (&layer, locals) {
            for (q, &node) in pose.rotations.iter().zip(&l.chain_nodes) {
                locals[node].rotation = *q;
            }
            layered.extend(l.keyed.iter().map(|&node| locals[node]));
        }
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
    let trail = Trail {
        targets: &targets,
        tips: &tips,
        radius: job
            .trail_radius
            .unwrap_or_else(|| default_trail_radius(&targets, reach)),
    };
    let mut warnings = Vec::new();
    let written = match setup.rig {
        Some((doc, nodes)) => {
            warnings.extend(doc.warnings.iter().map(|w| Text::from(w.as_str())));
            let node_frames = layer.as_ref().map(|l| NodeFrames {
                nodes: &l.keyed,
                trs: &layered,
            });
            write_rig_gltf(
                &job.output,
                doc,
                chain,
                &nodes,
                &frames,
                node_frames.as_ref(),
                &trail,
            )?
        }
        None => write_chain_gltf(&job.output, chain, &rest, &frames, &trail)?,
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
        trail_radius: trail.radius,
        seconds_solve,
        seconds_total: 0.0,
        files: written.files,
        warnings,
    };
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
            preset: Some(IkPreset::LabArm),
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
        assert!(e.contains("`preset`"), "{e}");
        assert!(toml::from_str::<IkJob>("preset = \"robot\"")
            .unwrap_err()
            .to_string()
            .contains("robot"));
        let e = bake_ik(
            &IkJob {
                preset: Some(IkPreset::LabArm),
                ..Default::default()
            },
            &mut |_, _| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("`curve`"), "{e}");
        assert!("cdd"
            .parse::<SolverKind>()
            .unwrap_err()
            .to_string()
            .contains("`solver`"));
    }
}
