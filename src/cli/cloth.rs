//! `scenebake cloth`: options → [`ClothJob`].

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use scenebake::bake::cloth::{ClothJob, ClothSource};
use scenebake::cloth::collide::{ColliderSpec, DEFAULT_FRICTION};
use scenebake::cloth::material::MaterialPreset;
use scenebake::cloth::pins::PinSpec;
use scenebake::cloth::SolverKind;
use scenebake::export::Interpolation;
use scenebake::export::{BasisSize, QuantizeMode, SparseMode, VatMode};
use scenebake::glam::DVec3;

/// Simulate a cloth or soft body and write it as a morph-target glTF.
#[derive(Debug, Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:\n  scenebake cloth meshes/plane_30x30.obj -o exports/plane.glb --frames 120 --pin box:-1,-1,-1,1,1,-0.49\n  scenebake cloth --preset lab-cloth -o exports/lab_cloth.glb"
)]
pub struct ClothArgs {
    /// Mesh to simulate: .obj, .gltf/.glb (surface) or .tet (volume).
    #[arg(
        required_unless_present = "preset",
        conflicts_with = "preset",
        value_name = "INPUT"
    )]
    pub input: Option<PathBuf>,
    /// A generated reference scene instead of a file.
    #[arg(long, value_enum)]
    pub preset: Option<ClothPreset>,
    /// Cells per side of the lab-cloth grid ((N+1)² particles over the same 2×2 m).
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub resolution: u32,
    /// Output file: .glb, or .gltf with a .bin beside it.
    #[arg(short = 'o', long, value_name = "FILE")]
    pub output: PathBuf,
    /// Frames to bake after the initial state [default: 120; lab-cloth 120].
    #[arg(long, value_name = "N")]
    pub frames: Option<usize>,
    /// Frames per second; the time step is 1/fps/substeps [default: 30; lab-cloth 60].
    #[arg(long, value_name = "F")]
    pub fps: Option<f64>,
    /// Solver steps per frame.
    #[arg(long, default_value_t = 1, value_name = "S")]
    pub substeps: usize,
    /// Time integrator: newton (converged implicit Euler, the default) or fast (local/global).
    #[arg(long, value_enum)]
    pub solver: Option<SolverArg>,
    /// Every solver stops a step when ρ = ‖∇g‖/‖M·g‖ (unbalanced force relative to the weight)
    /// falls below R; steps that end above it are flagged [default: 0.1].
    #[arg(long, value_name = "R")]
    pub tolerance: Option<f64>,
    /// Iterations per step at most, for whichever solver runs [default: newton 50, fast 500].
    #[arg(long, value_name = "N")]
    pub max_iterations: Option<usize>,
    /// Local/global iterations per step at most (fast solver; alias of --max-iterations).
    #[arg(long, value_name = "K")]
    pub iterations: Option<usize>,
    /// Newton iterations per step at most (alias of --max-iterations for Newton).
    #[arg(long, value_name = "N")]
    pub max_newton: Option<usize>,
    /// The fabric of a surface mesh, mapped onto its edges by rest length and area [default:
    /// cotton].
    #[arg(long, value_enum)]
    pub material: Option<MaterialArg>,
    /// The fabric's stretch modulus in N/m (force per unit width per unit strain).
    #[arg(long, value_name = "N/M")]
    pub stretch: Option<f64>,
    /// The fabric's bending rigidity in N·m.
    #[arg(long, value_name = "N·M")]
    pub bend: Option<f64>,
    /// The fabric's compression stiffness as a fraction of its stretch stiffness (0..1).
    #[arg(long, value_name = "FRACTION")]
    pub compression: Option<f64>,
    /// Every spring's stiffness in N/m, symmetric in tension and compression: the labs' model
    /// instead of a material [lab-cloth 100; .tet 1000].
    #[arg(long, value_name = "K")]
    pub stiffness: Option<f64>,
    /// Bending-spring stiffness in N/m, 0 for none (the labs' model) [default with --stiffness:
    /// 2; lab-cloth = --stiffness].
    #[arg(long, value_name = "K")]
    pub bend_stiffness: Option<f64>,
    /// Mass-proportional damping in 1/s, 0 for plain implicit Euler [default: 0.5; lab-cloth 0.2].
    #[arg(long, value_name = "C")]
    pub damping: Option<f64>,
    /// Mass per particle in kg (instead of --density) [lab-cloth: 1].
    #[arg(long, value_name = "KG")]
    pub mass: Option<f64>,
    /// Density: kg/m² for surfaces [default: the material's], kg/m³ for .tet volumes [default 50].
    #[arg(long, value_name = "D")]
    pub density: Option<f64>,
    /// Gravity in m/s² [default: 0,-9.81,0; lab-cloth 0,-0.3,0].
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub gravity: Option<DVec3>,
    /// Hold particles fixed (repeatable): index:I,J,... (zero-based, file order),
    /// box:X0,Y0,Z0,X1,Y1,Z1, or group:NAME (an OBJ group or object).
    #[arg(long = "pin", value_name = "SPEC", value_parser = parse_pin, allow_hyphen_values = true)]
    pub pins: Vec<PinSpec>,
    /// Only this object or group of an OBJ (default: all, merged into one body).
    #[arg(long, value_name = "NAME")]
    pub object: Option<String>,
    /// Which mesh of a glTF input (default: the first).
    #[arg(long, value_name = "NAME")]
    pub mesh: Option<String>,
    /// Weight interpolation between frames.
    #[arg(long, value_enum, default_value_t = InterpolationArg::Linear)]
    pub interpolation: InterpolationArg,
    /// Write NORMAL deltas in the morph targets.
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub normals: OnOff,
    /// Name of the glTF mesh, node and animation (default: the input's file stem).
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
    /// Write a JSON report of the bake.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Also write a vertex-animation texture: FILE.exr (32-bit float RGB positions, one row per
    /// frame from frame 0 at the top, one column per glTF vertex), FILE.normals.exr (unit normals,
    /// same layout; not with --normals off) and FILE.json (layout, bounds, fps, glTF name).
    #[arg(long, value_name = "FILE.exr")]
    pub vat: Option<PathBuf>,
    /// What the VAT's RGB stores: object-space positions, or offsets from the base mesh (frame 0).
    #[arg(long, value_enum, default_value_t = VatModeArg::Absolute)]
    pub vat_mode: VatModeArg,
    /// Most pixels per VAT row; meshes with more vertices wrap into several rows per frame
    /// (frame f, vertex v → row f*rows_per_frame + v/width, column v%width).
    #[arg(long, default_value_t = 8192, value_name = "PIXELS")]
    pub vat_max_width: usize,
    /// Keep only the frames needed for linear playback to reproduce every baked frame within T
    /// (scene units, largest vertex distance); first and last frames are always kept
    /// [default: off, one morph target per frame].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    pub keyframe_tolerance: Option<f64>,
    /// Store morph-target deltas as sparse accessors (changed vertices only) where smaller.
    #[arg(long, value_enum, default_value_t = SparseArg::Auto)]
    pub sparse: SparseArg,
    /// Write the motion as a base shape plus K basis shapes (morph targets) with per-frame
    /// weights, from a truncated SVD of the frame deltas, instead of one target per frame;
    /// `auto` picks the fewest targets that keep every baked frame within --basis-tolerance
    /// (measured as a player computes it).
    #[arg(long, value_name = "K|auto", value_parser = parse_basis)]
    pub basis: Option<BasisSize>,
    /// Largest vertex distance (scene units) allowed between a played frame and the bake, for
    /// --basis auto and --quantize auto [default: --keyframe-tolerance, else 0.001].
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub basis_tolerance: Option<f64>,
    /// Most morph targets written (for engines that cap them); an error if the tolerance
    /// cannot be met within N.
    #[arg(long, value_name = "N")]
    pub max_targets: Option<usize>,
    /// KHR_mesh_quantization for a --basis cache: int16 positions and deltas, int8 normals,
    /// dequantised by the node's scale and translation; auto quantises when the measured error
    /// stays within --basis-tolerance [default: auto with --basis].
    #[arg(long, value_enum, value_name = "MODE")]
    pub quantize: Option<QuantizeArg>,
    /// Scale the input file about its origin by S (before --translate; not for presets).
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub scale: f64,
    /// Move the input file by this offset in metres, after --scale; pins and colliders are given
    /// in the placed coordinates.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub translate: Option<DVec3>,
    /// The input file's up axis: z turns a Z-up file (Blender, many OBJ exporters) to glTF's
    /// Y-up, (x, y, z) → (x, z, −y), before --scale and --translate; pins, colliders and
    /// --gravity are in the turned (Y-up) coordinates.
    #[arg(long, value_enum, default_value_t = UpArg::Y)]
    pub up: UpArg,
    /// A static collider (repeatable): plane:NX,NY,NZ,D (the half-space n·x ≤ D is solid, e.g.
    /// plane:0,1,0,0 is the ground y = 0), sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1, or
    /// mesh:FILE.obj (closed meshes are solid, open ones two-sided). Written into the glTF as
    /// static meshes.
    #[arg(long = "collider", value_name = "SPEC", value_parser = parse_collider, allow_hyphen_values = true)]
    pub colliders: Vec<ColliderSpec>,
    /// How far particles stay from collider surfaces, in metres [default: a quarter of the
    /// mean edge length].
    #[arg(long, value_name = "M")]
    pub thickness: Option<f64>,
    /// Coulomb friction coefficient against colliders (0 = ice).
    #[arg(long, default_value_t = DEFAULT_FRICTION, value_name = "MU")]
    pub friction: f64,
    /// Mean wind velocity in m/s; turns on aerodynamic drag and lift on every triangle.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub wind: Option<DVec3>,
    /// Drag coefficient of the triangles (pressure along the normal) [default with wind: 1.0].
    #[arg(long, value_name = "CD")]
    pub drag: Option<f64>,
    /// Lift coefficient of the triangles (force across the flow) [default with wind: 0.3].
    #[arg(long, value_name = "CL")]
    pub lift: Option<f64>,
    /// Gusts: RMS gust speed as a fraction of the wind speed (0 = steady wind).
    #[arg(long, default_value_t = 0.0, value_name = "T")]
    pub turbulence: f64,
    /// Seed of the gusts (the same seed gives the same bake).
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub seed: u64,
}

/// `--up` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum UpArg {
    /// Y up (glTF's convention; kept as it is).
    Y,
    /// Z up (turned to Y up).
    Z,
}

/// `--vat-mode` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum VatModeArg {
    /// Object-space positions.
    Absolute,
    /// Offsets from the base mesh (frame 0).
    Offset,
}

/// `--quantize` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum QuantizeArg {
    /// Where the measured error stays within the tolerance.
    Auto,
    /// Always.
    On,
    /// Never.
    Off,
}

/// `--sparse` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SparseArg {
    /// Sparse where smaller than dense.
    Auto,
    /// Always dense.
    Off,
}

/// Generated cloth scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClothPreset {
    /// The labs' 2×2 m grid pinned at two corners.
    LabCloth,
}

/// `--material` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MaterialArg {
    /// Light woven cotton: 1000 N/m, 5e-6 N·m, 0.15 kg/m².
    Cotton,
    /// Silk: 300 N/m, 1e-6 N·m, 0.081 kg/m².
    Silk,
    /// 11 oz denim: 3000 N/m, 5e-5 N·m, 0.373 kg/m².
    Denim,
    /// Garment leather: 8000 N/m, 5e-4 N·m, 0.9 kg/m².
    Leather,
    /// 1 mm rubber sheet: 2000 N/m, 1.7e-4 N·m, 1.1 kg/m², resists compression fully.
    Rubber,
}

/// `--solver` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SolverArg {
    /// Local/global fast mass-spring (Liu et al. 2013), prefactored.
    Fast,
    /// Implicit Euler solved exactly by Newton's method (sparse Hessian, line search).
    Newton,
}

/// `--interpolation` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum InterpolationArg {
    /// Linear blend between frames.
    Linear,
    /// Hold each frame.
    Step,
}

/// On/off switches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OnOff {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

fn parse_vec3(s: &str) -> Result<DVec3, String> {
    scenebake::spec::parse_vec3("", s)
        .map_err(|e| e.to_string().replace("invalid value for : ", ""))
}

fn parse_basis(s: &str) -> Result<BasisSize, String> {
    s.parse::<BasisSize>()
        .map_err(|e| e.to_string().replace("invalid value for --basis: ", ""))
}

fn parse_collider(s: &str) -> Result<ColliderSpec, String> {
    s.parse::<ColliderSpec>()
        .map_err(|e| e.to_string().replace("invalid value for --collider: ", ""))
}

fn parse_pin(s: &str) -> Result<PinSpec, String> {
    s.parse::<PinSpec>()
        .map_err(|e| e.to_string().replace("invalid value for --pin: ", ""))
}

impl ClothArgs {
    /// The library job these options describe.
    pub fn job(&self) -> ClothJob {
        let source = match (self.preset, &self.input) {
            (Some(ClothPreset::LabCloth), _) => ClothSource::LabCloth {
                resolution: self.resolution,
            },
            (None, Some(path)) => ClothSource::File(path.clone()),
            (None, None) => unreachable!("clap requires INPUT or --preset"),
        };
        let mut job = ClothJob::new(source, self.output.clone());
        job.object = self.object.clone();
        job.mesh = self.mesh.clone();
        job.frames = self.frames;
        job.fps = self.fps;
        job.substeps = self.substeps;
        if let Some(solver) = self.solver {
            job.solver = match solver {
                SolverArg::Fast => SolverKind::Fast,
                SolverArg::Newton => SolverKind::Newton,
            };
        }
        if let Some(k) = self.iterations {
            job.iterations = k;
        }
        if let Some(r) = self.tolerance {
            job.tolerance = r;
        }
        if let Some(n) = self.max_newton {
            job.max_newton = n;
        }
        job.max_iterations = self.max_iterations;
        job.material = self.material.map(|m| match m {
            MaterialArg::Cotton => MaterialPreset::Cotton,
            MaterialArg::Silk => MaterialPreset::Silk,
            MaterialArg::Denim => MaterialPreset::Denim,
            MaterialArg::Leather => MaterialPreset::Leather,
            MaterialArg::Rubber => MaterialPreset::Rubber,
        });
        job.stretch = self.stretch;
        job.bend = self.bend;
        job.compression = self.compression;
        job.stiffness = self.stiffness;
        job.bend_stiffness = self.bend_stiffness;
        job.damping = self.damping;
        job.mass = self.mass;
        job.density = self.density;
        job.gravity = self.gravity;
        job.pins = self.pins.clone();
        job.interpolation = match self.interpolation {
            InterpolationArg::Linear => Interpolation::Linear,
            InterpolationArg::Step => Interpolation::Step,
        };
        job.normals = self.normals == OnOff::On;
        job.name = self.name.clone();
        job.vat = self.vat.clone();
        job.vat_mode = match self.vat_mode {
            VatModeArg::Absolute => VatMode::Absolute,
            VatModeArg::Offset => VatMode::Offset,
        };
        job.vat_max_width = self.vat_max_width;
        job.keyframe_tolerance = self.keyframe_tolerance;
        job.sparse = match self.sparse {
            SparseArg::Auto => SparseMode::Auto,
            SparseArg::Off => SparseMode::Off,
        };
        job.basis = self.basis;
        job.basis_tolerance = self.basis_tolerance;
        job.max_targets = self.max_targets;
        job.quantize = self.quantize.map(|q| match q {
            QuantizeArg::Auto => QuantizeMode::Auto,
            QuantizeArg::On => QuantizeMode::On,
            QuantizeArg::Off => QuantizeMode::Off,
        });
        job.scale = self.scale;
        job.translate = self.translate.unwrap_or(DVec3::ZERO);
        job.up_z = self.up == UpArg::Z;
        job.colliders = self.colliders.clone();
        job.thickness = self.thickness;
        job.friction = self.friction;
        job.wind = self.wind;
        job.drag = self.drag;
        job.lift = self.lift;
        job.turbulence = self.turbulence;
        job.seed = self.seed;
        job
    }
}
