//! `scenebake ik`: options → [`IkJob`].

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use scenebake::glam::DVec3;
use scenebake::ik::bake::IkJob;

/// Bake an inverse-kinematics animation: a joint chain whose tip follows a curve, text or drawing.
#[derive(Debug, Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:\n  scenebake ik --preset lab-arm --curve circle --solver fabrik -o exports/circle.glb\n  scenebake ik --preset lab-arm --text \"hello\" --font script -o exports/hello.glb --report hello.json\n  scenebake ik --rig meshes/Fox.glb --chain b_Spine01_02..b_Head_05 --curve heart -o exports/fox.glb"
)]
pub struct IkArgs {
    /// A generated reference chain: the labs' 5-joint arm.
    #[arg(long, value_enum)]
    pub preset: Option<IkPreset>,
    /// A straight generated chain of N joints (the last is the end effector).
    #[arg(long, value_name = "N")]
    pub joints: Option<usize>,
    /// Total length of the --joints chain [default: 2.6].
    #[arg(long, value_name = "L")]
    pub length: Option<f64>,
    /// A skinned glTF whose chain to animate (with --chain); the output is this document plus one
    /// new animation.
    #[arg(long, value_name = "FILE.glb|.gltf")]
    pub rig: Option<PathBuf>,
    /// The chain in --rig, ROOT..TIP: joint names, #N for node N (quote it: a shell drops
    /// everything after an unquoted #, so write --chain '#13..#15'), or Node_N as Blender names
    /// unnamed nodes. `scenebake inspect FILE` lists the nodes with their #N.
    #[arg(long, value_name = "ROOT..TIP")]
    pub chain: Option<String>,
    /// IK solver.
    #[arg(long, value_enum, default_value_t = IkSolverArg::Fabrik)]
    pub solver: IkSolverArg,
    /// Iteration cap per frame.
    #[arg(long, default_value_t = 100, value_name = "N")]
    pub max_iterations: usize,
    /// Distance from the target that counts as reached, in scene units.
    #[arg(long, default_value_t = 1e-4, value_name = "D")]
    pub tolerance: f64,
    /// Largest rotation of any joint from one frame to the next, in degrees (clamps sudden flips).
    #[arg(long, value_name = "DEG")]
    pub max_angle: Option<f64>,
    /// Keep the chain's bend facing this world point (like Blender's IK pole): an elbow points
    /// towards it.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub pole: Option<DVec3>,
    /// Limit a joint, from its rest rotation, in degrees: JOINT:hinge:MIN..MAX (one axis: with
    /// --pole, positive bends the joint out towards the pole; or give the axis as a world
    /// direction, JOINT:hinge:MIN..MAX:X,Y,Z) or JOINT:cone:DEG (the bone stays within DEG of
    /// its rest direction). Repeat for several joints.
    #[arg(long, value_name = "JOINT:KIND:RANGE", allow_hyphen_values = true)]
    pub limit: Vec<String>,
    /// Frames per second of the animation.
    #[arg(long, default_value_t = 30.0, value_name = "F")]
    pub fps: f64,
    /// Follow a closed curve.
    #[arg(long, value_enum)]
    pub curve: Option<CurveArg>,
    /// Write text (lines split at \n) in --font.
    #[arg(long, value_name = "TEXT")]
    pub text: Option<String>,
    /// Font for --text: a Hershey single-stroke font (simplex, duplex, triplex, script,
    /// script-complex, cursive, sans, greek), the old capitals-only `grid`, or a TrueType/OpenType
    /// file (letters drawn as outlines) [default: simplex].
    #[arg(long, value_name = "NAME|FILE.ttf")]
    pub font: Option<String>,
    /// Draw every path of an SVG file (lines, Béziers and arcs, flattened).
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// Follow points from a CSV file: `x,y[,z]` per line, a blank line lifts the pen.
    #[arg(long, value_name = "FILE.csv")]
    pub points: Option<PathBuf>,
    /// Curve radius in scene units [lab arm: 0.6; rigs: sized to the chain's reach].
    #[arg(long, value_name = "R")]
    pub radius: Option<f64>,
    /// Centre of the drawing [lab arm: the origin; rigs: in front of the chain].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub center: Option<DVec3>,
    /// Direction the drawing board faces (its normal); the drawing reads correctly from the
    /// chain root's side [default: facing the chain root along its rest direction].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub normal: Option<DVec3>,
    /// Letter height (--text) or drawing height (--svg) in scene units [default: fit the reach].
    #[arg(long, value_name = "H")]
    pub size: Option<f64>,
    /// How far the pen lifts between strokes, in scene units [default: 4% of the reach].
    #[arg(long, value_name = "D")]
    pub lift: Option<f64>,
    /// Even spacing of the targets along the path, in scene units [default: an even tip speed at
    /// the chosen fps; the lab circle keeps its 150 targets].
    #[arg(long, value_name = "D")]
    pub spacing: Option<f64>,
    /// Pen speed in scene units per second: one target per frame, every stroke and every lift
    /// starting and ending at rest (instead of --spacing).
    #[arg(long, value_name = "V")]
    pub pen_speed: Option<f64>,
    /// Seconds for the pen to reach --pen-speed from rest, and to stop [default: 0.15].
    #[arg(long, value_name = "S")]
    pub ease: Option<f64>,
    /// Output file: .glb, or .gltf with a .bin beside it.
    #[arg(short = 'o', long, value_name = "FILE")]
    pub output: PathBuf,
    /// Write a JSON report of the bake.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Name for the job in summaries.
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
}

/// Generated chains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum IkPreset {
    /// The labs' 5-joint arm (root at 1.7 m, reach 2.6 m).
    LabArm,
}

/// `--solver` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum IkSolverArg {
    /// Forward and backward reaching (positions, then rotations rebuilt in parent frames).
    Fabrik,
    /// Cyclic coordinate descent (rotations applied in each joint's parent frame).
    Ccd,
}

/// `--curve` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CurveArg {
    /// A circle.
    Circle,
    /// A square.
    Square,
    /// A heart, r = R(1 − sin θ).
    Heart,
    /// An equilateral triangle.
    Triangle,
    /// A five-pointed star.
    Star,
}

fn parse_vec3(s: &str) -> Result<DVec3, String> {
    scenebake::spec::parse_vec3("", s)
        .map_err(|e| e.to_string().replace("invalid value for : ", ""))
}

impl IkArgs {
    /// The library job these options describe.
    ///
    /// # Errors
    /// Never in practice: every value enum maps onto the library's names.
    pub fn job(&self) -> anyhow::Result<IkJob> {
        let name = |v: &dyn ValueEnumName| v.name();
        Ok(IkJob {
            preset: self.preset.map(|p| name(&p)),
            joints: self.joints,
            length: self.length,
            rig: self.rig.clone(),
            chain: self.chain.clone(),
            solver: name(&self.solver).parse()?,
            max_iterations: self.max_iterations,
            tolerance: self.tolerance,
            max_angle: self.max_angle,
            pole: self.pole,
            limit: self.limit.clone(),
            fps: self.fps,
            curve: self.curve.map(|c| name(&c).parse()).transpose()?,
            text: self.text.clone(),
            font: self.font.clone(),
            svg: self.svg.clone(),
            points: self.points.clone(),
            radius: self.radius,
            center: self.center,
            normal: self.normal,
            size: self.size,
            lift: self.lift,
            spacing: self.spacing,
            pen_speed: self.pen_speed,
            ease: self.ease,
            output: self.output.clone(),
            report: self.report.clone(),
        })
    }
}

/// The spelling of a value enum on the command line.
trait ValueEnumName {
    fn name(&self) -> String;
}

impl<T: ValueEnum> ValueEnumName for T {
    fn name(&self) -> String {
        self.to_possible_value()
            .map(|v| v.get_name().to_owned())
            .unwrap_or_default()
    }
}
