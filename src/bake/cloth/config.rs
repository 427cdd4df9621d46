//! The cloth job's configuration: every parameter of a cloth bake, with its default, defined
//! once. Scene files deserialise into [`ClothJob`] (keys are its field names, see
//! [`crate::param::Param`]); the `scenebake cloth` command line is derived from it (feature
//! `cli`), so both take exactly the same parameters and spellings.

use std::path::PathBuf;
use std::sync::Arc;

use glam::DVec3;

use crate::cloth::collide::{ColliderSpec, ContactModel, DEFAULT_FRICTION};
use crate::cloth::material::{BendRest, MaterialPreset};
use crate::cloth::membrane::MembraneModel;
use crate::cloth::pins::PinSpec;
use crate::cloth::{LinearSolver, SolverKind};
use crate::cores::CoreShare;
use crate::error::{Error, Result};
use crate::export::vat::DEFAULT_MAX_WIDTH;
use crate::export::{BasisSize, Compression, Interpolation, QuantizeMode, SparseMode, VatMode};
use crate::param::Param;
use crate::spec::de;

/// Where the body comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ClothSource {
    /// An `.obj`, `.gltf`/`.glb` or `.tet` file.
    File(PathBuf),
    /// The labs' grid with `resolution` cells per side.
    LabCloth {
        /// Cells per side (N); the grid has (N+1)² particles.
        resolution: u32,
    },
}

/// Generated cloth scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum ClothPreset {
    /// The labs' 2×2 m grid pinned at two corners.
    LabCloth,
}

/// The up axis of an input file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum UpAxis {
    /// Y up (glTF's convention; kept as it is).
    #[default]
    Y,
    /// Z up (turned to Y up).
    Z,
}

/// An on/off switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Switch {
    /// Enabled.
    #[default]
    On,
    /// Disabled.
    Off,
}

/// Default values for meshes loaded from files (the lab-cloth preset brings its own, see
/// [`crate::cloth::preset::defaults`]).
pub mod defaults {
    /// Frames baked after the initial state.
    pub const FRAMES: usize = 120;
    /// Frames per second.
    pub const FPS: f64 = 30.0;
    /// The labs' spring stiffness, N/m per spring.
    pub const STIFFNESS: f64 = 1000.0;
    /// The labs' bending-spring stiffness, N/m per spring.
    pub const BEND_STIFFNESS: f64 = 2.0;
    /// Mass-proportional damping, 1/s.
    pub const DAMPING: f64 = 0.5;
    /// Areal density of surfaces with the labs' springs, kg/m² (a light cotton).
    pub const AREAL_DENSITY: f64 = 0.2;
    /// Density of `.tet` volumes, kg/m³ (a soft foam).
    pub const VOLUME_DENSITY: f64 = 50.0;
    /// Gravity, m/s².
    pub const GRAVITY: [f64; 3] = [0.0, -9.81, 0.0];
    /// The fast solver's cap on local/global iterations per step.
    pub const ITERATIONS: usize = 500;
    /// Every solver stops a step when ρ = ‖∇g‖ / ‖M·g‖ falls below this (the RMS unbalanced
    /// force per particle relative to its weight, roughly). 0.1 is visually converged on
    /// garments: hem heights within 0.5 mm of a 1e-3 solve (docs/performance.md).
    pub const TOLERANCE: f64 = 0.1;
    /// Edge stretch (l / l₀ − 1) above which a written frame is flagged as torn.
    pub const STRAIN_LIMIT: f64 = 0.2;
    /// The solver when none is named.
    pub const SOLVER: crate::cloth::SolverKind = crate::cloth::SolverKind::Newton;
    /// Cells per side of the lab-cloth grid.
    pub const RESOLUTION: u32 = 10;
    /// Solver steps per frame.
    pub const SUBSTEPS: usize = 1;
    /// Times over a step may be halved ([`crate::cloth::BakeParams::splits`]).
    pub const SPLITS: usize = 3;
    /// Loops of a driving animation written.
    pub const CYCLES: usize = 1;
    /// Loops of a driving animation simulated and discarded before those written.
    pub const WARMUP_CYCLES: usize = 1;
    /// Seconds of blending from a rig's rest pose into its animation.
    pub const BLEND_IN: f64 = 0.5;
    /// `--pin-smooth`, metres: on a cape pinned across CesiumMan's back at shoulder height it
    /// brings the worst edge between two pins from 222 % to 15 % stretch over the walk, where
    /// the body's own skin near them stretches 74 % (docs/characters.md).
    pub const PIN_SMOOTH: f64 = 0.1;
}

/// One cloth bake. `None` means "the default": the preset's value for presets, else
/// [`defaults`]. Lengths are metres, masses kilograms, times seconds, in the glTF frame (+Y up)
/// after `up`, `scale` and `translate` place the input.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[cfg_attr(feature = "cli", command(allow_negative_numbers = true))]
pub struct ClothJob {
    /// Mesh to simulate: .obj, .gltf/.glb (surface) or .tet (volume).
    #[cfg_attr(
        feature = "cli",
        arg(
            required_unless_present = "preset",
            conflicts_with = "preset",
            value_name = "INPUT"
        )
    )]
    pub input: Option<PathBuf>,
    /// A generated reference scene instead of a file.
    #[cfg_attr(feature = "cli", arg(long, value_enum))]
    pub preset: Option<ClothPreset>,
    /// Cells per side of the lab-cloth grid ((N+1)² particles over the same 2×2 m).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::RESOLUTION, value_name = "N"))]
    pub resolution: u32,
    /// Output file: .glb, or .gltf with a .bin beside it.
    #[cfg_attr(feature = "cli", arg(short = 'o', long, value_name = "FILE"))]
    pub output: PathBuf,
    /// Write a JSON report of the bake (the library returns the report; the binary and scene
    /// runs write it here).
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.json"))]
    pub report: Option<PathBuf>,
    /// Name of the glTF mesh, node and animation, and of the job in summaries (default: the
    /// input's file stem).
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME"))]
    pub name: Option<String>,
    /// Frames to bake after the initial state [default: 120; lab-cloth 120].
    #[cfg_attr(feature = "cli", arg(long, value_name = "N"))]
    pub frames: Option<usize>,
    /// Frames per second; the time step is 1/fps/substeps [default: 30; lab-cloth 60].
    #[cfg_attr(feature = "cli", arg(long, value_name = "F"))]
    pub fps: Option<f64>,
    /// Solver steps per frame.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::SUBSTEPS, value_name = "S"))]
    pub substeps: usize,
    /// Newton: a step that ends above the tolerance, stalls far from it, or fails (a non-finite
    /// state, a Hessian that no longer factors) is taken again from its start as two steps of
    /// half its length, each split again as needed, up to N times over (down to 1/2ᴺ of the
    /// step); 0 never splits
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::SPLITS, value_name = "N"))]
    pub splits: usize,
    /// Time integrator: newton (converged implicit Euler, the default) or fast (local/global).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = defaults::SOLVER))]
    pub solver: SolverKind,
    /// Every solver stops a step when ρ = ‖∇g‖/‖M·g‖ (unbalanced force relative to the weight)
    /// falls below R; steps that end above it are flagged.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::TOLERANCE, value_name = "R"))]
    pub tolerance: f64,
    /// Written frames with an edge stretched more than this (l / l₀ − 1, a fraction: 0.2 is
    /// 20 %) are flagged in the report and on the terminal.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::STRAIN_LIMIT, value_name = "S"))]
    pub strain_limit: f64,
    /// Iterations per step at most, for whichever solver runs [default: newton 200, fast 500].
    #[cfg_attr(feature = "cli", arg(long, value_name = "N"))]
    #[serde(alias = "max-iterations")]
    pub max_iterations: Option<usize>,
    /// Local/global iterations per step at most (fast solver; alias of --max-iterations).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::ITERATIONS, value_name = "K"))]
    pub iterations: usize,
    /// Newton iterations per step at most (alias of --max-iterations for Newton).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = crate::cloth::newton::DEFAULT_MAX_ITERATIONS, value_name = "N"))]
    #[serde(alias = "max-newton")]
    pub max_newton: usize,
    /// Newton: Gauss–Seidel sweeps (one local Newton step per particle) after each iteration;
    /// 0 turns them off. They shorten Newton on stiff cloth without changing the tolerance a
    /// step is solved to [default: 10; 0 with --self-contact on, whose pairs the sweeps do not
    /// see]
    #[cfg_attr(feature = "cli", arg(long, value_name = "N"))]
    pub sweeps: Option<usize>,
    /// Threads the bake may use: with two, Newton's Gauss–Seidel sweeps move the two halves of a
    /// large mesh at once, and its factor's two halves are factored and solved at once, with the
    /// same result as on one [default: every core; in a scene, the cores shared among the jobs
    /// running at once, growing as they end].
    #[cfg_attr(feature = "cli", arg(long, value_name = "N"))]
    pub threads: Option<usize>,
    /// Where `threads` is not given: a share of the cores among the jobs of a scene running at
    /// once, which grows as they end (set by `scenebake run`, not read from a file).
    #[serde(skip)]
    #[cfg_attr(feature = "cli", arg(skip))]
    pub share: Option<Arc<CoreShare>>,
    /// How Newton solves for each iteration's direction: `direct` (a sparse Cholesky factor,
    /// whose cost grows faster than the mesh), `multigrid` (conjugate gradients preconditioned
    /// by algebraic multigrid, each gradient's cost linear in the mesh), or `auto` (multigrid
    /// from 100,000 free particles).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = LinearSolver::Auto, value_name = "SOLVER"))]
    #[serde(alias = "linear-solver")]
    pub linear_solver: LinearSolver,
    /// The fabric of a surface mesh, mapped onto its edges by rest length and area [default:
    /// cotton].
    #[cfg_attr(feature = "cli", arg(long, value_enum))]
    pub material: Option<MaterialPreset>,
    /// The fabric's stretch modulus in N/m (force per unit width per unit strain).
    #[cfg_attr(feature = "cli", arg(long, value_name = "N/M"))]
    pub stretch: Option<f64>,
    /// The fabric's bending rigidity in N·m.
    #[cfg_attr(feature = "cli", arg(long, value_name = "N·M"))]
    pub bend: Option<f64>,
    /// The fabric's compression stiffness as a fraction of its stretch stiffness (0..1).
    #[cfg_attr(feature = "cli", arg(long, value_name = "FRACTION"))]
    pub compression: Option<f64>,
    /// The fabric's jamming strain J: around this compression (a fraction of an edge's rest
    /// length, between 0 and 1) an edge resists with its full stretch stiffness again, added
    /// along a ramp from J/2 to 3J/2 [default: 0.06].
    #[cfg_attr(feature = "cli", arg(long, value_name = "STRAIN"))]
    #[serde(alias = "jam-strain")]
    pub jam_strain: Option<f64>,
    /// The shape the fabric's bending returns to: `mesh`, the input's own curvature (a garment
    /// modelled draped keeps its folds, as in Blender's cloth), or `flat` [default: mesh].
    #[cfg_attr(feature = "cli", arg(long, value_enum, value_name = "REST"))]
    #[serde(alias = "bend-rest")]
    pub bend_rest: Option<BendRest>,
    /// How the fabric resists stretch: `springs` on the mesh's edges, or `triangles`, a
    /// membrane whose response does not depend on the triangulation (irregular and scanned
    /// meshes; Newton only) [default: springs].
    #[cfg_attr(feature = "cli", arg(long, value_enum, value_name = "MODEL"))]
    pub membrane: Option<MembraneModel>,
    /// Every spring's stiffness in N/m, symmetric in tension and compression: the labs' model
    /// instead of a material [lab-cloth 100; .tet 1000].
    #[cfg_attr(feature = "cli", arg(long, value_name = "K"))]
    pub stiffness: Option<f64>,
    /// Bending-spring stiffness in N/m, 0 for none (the labs' model) [default with --stiffness:
    /// 2; lab-cloth = --stiffness].
    #[cfg_attr(feature = "cli", arg(long, value_name = "K"))]
    #[serde(alias = "bend-stiffness")]
    pub bend_stiffness: Option<f64>,
    /// Mass-proportional damping in 1/s, 0 for plain implicit Euler [default: 0.5; lab-cloth 0.2].
    #[cfg_attr(feature = "cli", arg(long, value_name = "C"))]
    pub damping: Option<f64>,
    /// Mass per particle in kg (instead of --density) [lab-cloth: 1].
    #[cfg_attr(feature = "cli", arg(long, value_name = "KG"))]
    pub mass: Option<f64>,
    /// Density: kg/m² for surfaces [default: the material's], kg/m³ for .tet volumes [default 50].
    #[cfg_attr(feature = "cli", arg(long, value_name = "D"))]
    pub density: Option<f64>,
    /// Gravity in m/s² [default: 0,-9.81,0; lab-cloth 0,-0.3,0].
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    pub gravity: Option<DVec3>,
    /// Hold particles fixed (repeatable): index:I,J,... (zero-based, file order),
    /// box:X0,Y0,Z0,X1,Y1,Z1, or group:NAME (an OBJ group or object).
    #[serde(deserialize_with = "de::spec_list")]
    #[cfg_attr(feature = "cli", arg(long = "pin", value_name = "SPEC", value_parser = crate::spec::parsed_value::<PinSpec>, allow_hyphen_values = true))]
    pub pin: Vec<PinSpec>,
    /// Only this object or group of an OBJ (default: all, merged into one body).
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME"))]
    pub object: Option<String>,
    /// Which mesh of a glTF input (default: the first).
    #[cfg_attr(feature = "cli", arg(long, value_name = "NAME"))]
    pub mesh: Option<String>,
    /// Weight interpolation between frames.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Interpolation::Linear))]
    pub interpolation: Interpolation,
    /// Write NORMAL deltas in the morph targets.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Switch::On))]
    pub normals: Switch,
    /// Also write a vertex-animation texture: FILE.exr (32-bit float RGB positions, one row per
    /// frame from frame 0 at the top, one column per glTF vertex), FILE.normals.exr (unit normals,
    /// same layout; not with --normals off) and FILE.json (layout, bounds, fps, start time, glTF
    /// name).
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.exr"))]
    pub vat: Option<PathBuf>,
    /// What the VAT's RGB stores: object-space positions, or offsets from the base mesh (frame 0).
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = VatMode::Absolute))]
    #[serde(alias = "vat-mode")]
    pub vat_mode: VatMode,
    /// Most pixels per VAT row; meshes with more vertices wrap into several rows per frame
    /// (frame f, vertex v → row f*rows_per_frame + v/width, column v%width).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_MAX_WIDTH, value_name = "PIXELS"))]
    #[serde(alias = "vat-max-width")]
    pub vat_max_width: usize,
    /// Also write a PC2 point cache (little-endian, for Blender's Mesh Cache modifier): every
    /// frame's positions from frame 0, one sample per frame, one point per simulated position in
    /// the input's order (an OBJ's `v` lines that faces use, as Blender's OBJ import keeps them),
    /// in the bake's placed coordinates (as the glTF).
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.pc2"))]
    pub pc2: Option<PathBuf>,
    /// Also write an MDD point cache (big-endian, LightWave's; Blender's Mesh Cache modifier reads
    /// it too): the same frames and points as --pc2, with each frame's time in seconds.
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.mdd"))]
    pub mdd: Option<PathBuf>,
    /// Also write a USD layer (text .usda; for Blender's USD import, Houdini, usdview): the cloth
    /// as a mesh with time-sampled points and normals (the --pc2 points: every frame from frame 0,
    /// frame k at time code k, the bake's fps), the colliders as static meshes, and a --body
    /// sequence or a --rig character's skinned meshes with time-sampled points, in metres, +Y up.
    #[cfg_attr(feature = "cli", arg(long, value_name = "FILE.usda"))]
    pub usd: Option<PathBuf>,
    /// Keep only the frames needed for linear playback to reproduce every baked frame within T
    /// (scene units, largest vertex distance); first and last frames are always kept
    /// [default: off, one morph target per frame].
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "T", allow_negative_numbers = true)
    )]
    #[serde(alias = "keyframe-tolerance")]
    pub keyframe_tolerance: Option<f64>,
    /// Store morph-target deltas as sparse accessors (changed vertices only) where smaller.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = SparseMode::Auto))]
    pub sparse: SparseMode,
    /// Write the motion as a base shape plus K basis shapes (morph targets) with per-frame
    /// weights, from a truncated SVD of the frame deltas, instead of one target per frame;
    /// `auto` picks the fewest targets that keep every baked frame within --basis-tolerance
    /// (measured as a player computes it).
    #[cfg_attr(feature = "cli", arg(long, value_name = "K|auto", value_parser = crate::spec::parsed_value::<BasisSize>))]
    pub basis: Option<BasisSize>,
    /// Largest vertex distance (scene units) allowed between a played frame and the bake, for
    /// --basis auto and --quantize auto [default: --keyframe-tolerance, else 0.001].
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "M", allow_negative_numbers = true)
    )]
    #[serde(alias = "basis-tolerance")]
    pub basis_tolerance: Option<f64>,
    /// Most morph targets written, a basis cache's normal targets included (for engines that
    /// cap them); an error if the tolerance cannot be met within N. Without it a basis cache
    /// adds normal targets only while it keeps 64 targets in all.
    #[cfg_attr(feature = "cli", arg(long, value_name = "N"))]
    #[serde(alias = "max-targets")]
    pub max_targets: Option<usize>,
    /// KHR_mesh_quantization for a --basis cache: int16/int8 positions and deltas, int16/int8
    /// normals and normal deltas, u16 texture coordinates, dequantised by the node's scale and
    /// translation; auto quantises when the measured error
    /// stays within --basis-tolerance [default: auto with --basis].
    #[cfg_attr(feature = "cli", arg(long, value_enum, value_name = "MODE"))]
    pub quantize: Option<QuantizeMode>,
    /// Engine-side compression: meshopt writes EXT_meshopt_compression (smaller files for
    /// three.js, Babylon.js and engines with a meshopt decoder; Blender's importer cannot read
    /// it, so keep `none` for Blender).
    #[cfg_attr(feature = "cli", arg(long, value_enum, value_name = "METHOD", default_value_t = Compression::None))]
    pub compress: Compression,
    /// Scale the input file about its origin by S (before --translate; not for presets).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 1.0, value_name = "S"))]
    pub scale: f64,
    /// Move the input file by this offset in metres, after --scale; pins and colliders are given
    /// in the placed coordinates.
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    pub translate: Option<DVec3>,
    /// The input file's up axis: z turns a Z-up file (Blender, many OBJ exporters) to glTF's
    /// Y-up, (x, y, z) → (x, z, −y), before --scale and --translate; mesh collider files are
    /// turned the same way; pins, the other colliders and --gravity are in the turned (Y-up)
    /// coordinates.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = UpAxis::Y))]
    pub up: UpAxis,
    /// A static collider (repeatable): plane:NX,NY,NZ,D (the half-space n·x ≤ D is solid, e.g.
    /// plane:0,1,0,0 is the ground y = 0), sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1, or
    /// mesh:FILE[#NAME] (an .obj, .gltf or .glb; #NAME keeps one OBJ object or group, or one
    /// glTF mesh node or mesh; closed meshes are solid, open ones two-sided). Written into the
    /// glTF as static meshes.
    #[serde(deserialize_with = "de::spec_list")]
    #[cfg_attr(feature = "cli", arg(long = "collider", value_name = "SPEC", value_parser = crate::spec::parsed_value::<ColliderSpec>, allow_hyphen_values = true))]
    pub collider: Vec<ColliderSpec>,
    /// How far particles stay from collider surfaces, in metres (with Newton's barrier, more
    /// than half of it, resting about that far) [default: a quarter of the mean edge length].
    #[cfg_attr(feature = "cli", arg(long, value_name = "M"))]
    pub thickness: Option<f64>,
    /// Coulomb friction coefficient against colliders (0 = ice).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = DEFAULT_FRICTION, value_name = "MU"))]
    pub friction: f64,
    /// How Newton keeps the cloth out of the colliders: `barrier` (a smooth barrier energy:
    /// particles stay more than half the thickness off and rest about a thickness off) or
    /// `constraint` (an active set: particles stay at least the thickness off) [default:
    /// barrier].
    #[cfg_attr(feature = "cli", arg(long, value_enum, value_name = "MODEL"))]
    pub contact: Option<ContactModel>,
    /// Whether the cloth collides with itself (Newton): vertex–triangle and edge–edge pairs are
    /// kept apart by a barrier and no step lets the cloth pass through itself (continuous
    /// collision detection). Costs several times a bake without it where the cloth folds.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Switch::Off))]
    pub self_contact: Switch,
    /// The cloth's layer against itself, in metres: pairs stay more than half of it apart and
    /// rest about that far [default: --thickness].
    #[cfg_attr(feature = "cli", arg(long, value_name = "M"))]
    pub self_thickness: Option<f64>,
    /// Mean wind velocity in m/s; turns on aerodynamic drag and lift on every triangle.
    #[serde(deserialize_with = "de::opt_vec3")]
    #[cfg_attr(feature = "cli", arg(long, value_name = "X,Y,Z", value_parser = crate::spec::vec3_value, allow_hyphen_values = true))]
    pub wind: Option<DVec3>,
    /// Drag coefficient of the triangles (pressure along the normal) [default with wind: 1.0].
    #[cfg_attr(feature = "cli", arg(long, value_name = "CD"))]
    pub drag: Option<f64>,
    /// Lift coefficient of the triangles (force across the flow) [default with wind: 0.3].
    #[cfg_attr(feature = "cli", arg(long, value_name = "CL"))]
    pub lift: Option<f64>,
    /// Gusts: RMS gust speed as a fraction of the wind speed (0 = steady wind).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.0, value_name = "T"))]
    pub turbulence: f64,
    /// Seed of the gusts (the same seed gives the same bake).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0, value_name = "N"))]
    pub seed: u64,
    /// An animated character (skinned .glb/.gltf) that drives the bake: the garment is given in
    /// its rest pose; --pin selections ride its skinned surface, its body is a moving collider,
    /// and the output is the character's document with the garment added (Newton solver only).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "FILE.glb|.gltf", help_heading = "Character")
    )]
    pub rig: Option<PathBuf>,
    /// The rig's animation that drives the bake: its name or #N [default: the first].
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            value_name = "NAME|#N",
            requires = "rig",
            help_heading = "Character"
        )
    )]
    pub animation: Option<String>,
    /// Loops of the animation written (frames follow its keys at --fps; --frames is not used).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::CYCLES, value_name = "N", help_heading = "Character"))]
    pub cycles: usize,
    /// Loops simulated and discarded before those written, so the written loop starts in
    /// motion and joins up (the report measures the seam).
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::WARMUP_CYCLES, value_name = "W", help_heading = "Character"))]
    pub warmup_cycles: usize,
    /// Seconds of blending from the rig's rest pose (where the garment is given) into the
    /// animation's first pose, simulated and discarded first.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::BLEND_IN, value_name = "S", help_heading = "Character"))]
    pub blend_in: f64,
    /// Seconds at the end of the written loops over which the solver steers the cloth onto its
    /// path one written span earlier (the last warm-up loop's), so the output loops without a
    /// jump where the motion itself does not settle into a loop; 0 writes the loops as they
    /// fall. Each steered step is solved to the tolerance like any other and measured; with
    /// --self-contact on the cloth is steered only as far as it can go without passing through
    /// itself. [default: a quarter of the written loops, as far as the warm-up loops reach]
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "S", requires = "rig", help_heading = "Character")
    )]
    pub loop_blend: Option<f64>,
    /// Bind every pin rigidly to this joint (name, #N or Node_N) instead of the skinned surface
    /// under it.
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            value_name = "JOINT",
            requires = "rig",
            help_heading = "Character"
        )
    )]
    pub pin_to: Option<String>,
    /// Pins ride the skinned surface with the skin weights averaged over the pins within this
    /// many metres (a Gaussian), so neighbouring pins move alike where the weights under them
    /// change abruptly (a band across the torso and an arm); 0 keeps each pin's own.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = defaults::PIN_SMOOTH, value_name = "M", requires = "rig", help_heading = "Character"))]
    pub pin_smooth: f64,
    /// Whether the character's skinned meshes are a (moving) collider.
    #[cfg_attr(feature = "cli", arg(long, value_enum, default_value_t = Switch::On, help_heading = "Character"))]
    pub body_collider: Switch,
    /// Body meshes the garment ignores (repeatable; node or mesh names, or `#N` node indices):
    /// they neither collide with it nor carry its pins, e.g. hands that hang through a skirt. A
    /// joint of the skin leaves out the part of the body it and the joints below it move (every
    /// triangle with a corner more than half theirs), e.g. the forearms of a character made as
    /// one mesh.
    #[serde(deserialize_with = "de::string_list")]
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            value_name = "NAME",
            value_delimiter = ',',
            requires = "rig",
            help_heading = "Character"
        )
    )]
    pub body_exclude: Vec<String>,
    /// Write only the garment (its morph animation keyed on the animation's times), not the
    /// character.
    #[cfg_attr(feature = "cli", arg(long, help_heading = "Character"))]
    pub garment_only: bool,
    /// Metres per unit of the rig (Fox.glb is in centimetres: 0.01). The garment is placed (by
    /// --scale/--translate/--up) in metres in the rig's frame scaled by this.
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            default_value_t = 1.0,
            value_name = "M",
            help_heading = "Character"
        )
    )]
    pub rig_scale: f64,
    /// A moving body as an OBJ sequence: a file pattern with a printf-style frame number
    /// (`kick/shell%d.obj`, `frame_%04d.obj`), frames numbered from the first file that exists
    /// up to the last, every one with the first's vertices and faces. The body collides as it
    /// moves (linearly between its frames), the bake lasts as long as the sequence (--frames
    /// can shorten it), and the output holds the body with its animation. The sequence is used
    /// as it is: --translate, --scale and --up place the garment only (Newton solver only).
    /// Or a glTF animated by morph targets, `FILE.glb[#NAME]`: the mesh (node or mesh NAME, else
    /// the first) whose weights an animation drives, sampled at --body-fps (default: the rate
    /// the file records, else its keys' spacing).
    #[cfg_attr(
        feature = "cli",
        arg(long, value_name = "PATTERN", help_heading = "Body sequence")
    )]
    pub body: Option<PathBuf>,
    /// Frames per second of the --body sequence (required with it); the bake's --fps defaults
    /// to it.
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            value_name = "F",
            requires = "body",
            help_heading = "Body sequence"
        )
    )]
    pub body_fps: Option<f64>,
    /// The --body sequence's first frame number [default: the lowest of the files that exist].
    #[cfg_attr(
        feature = "cli",
        arg(
            long,
            value_name = "N",
            requires = "body",
            help_heading = "Body sequence"
        )
    )]
    pub body_start: Option<u64>,
}

impl Default for ClothJob {
    fn default() -> Self {
        ClothJob {
            input: None,
            preset: None,
            resolution: defaults::RESOLUTION,
            output: PathBuf::new(),
            report: None,
            name: None,
            frames: None,
            fps: None,
            substeps: defaults::SUBSTEPS,
            splits: defaults::SPLITS,
            solver: defaults::SOLVER,
            tolerance: defaults::TOLERANCE,
            strain_limit: defaults::STRAIN_LIMIT,
            max_iterations: None,
            iterations: defaults::ITERATIONS,
            max_newton: crate::cloth::newton::DEFAULT_MAX_ITERATIONS,
            sweeps: None,
            threads: None,
            share: None,
            material: None,
            stretch: None,
            bend: None,
            compression: None,
            jam_strain: None,
            bend_rest: None,
            membrane: None,
            stiffness: None,
            bend_stiffness: None,
            damping: None,
            mass: None,
            density: None,
            gravity: None,
            pin: Vec::new(),
            object: None,
            mesh: None,
            interpolation: Interpolation::Linear,
            normals: Switch::On,
            vat: None,
            vat_mode: VatMode::Absolute,
            vat_max_width: DEFAULT_MAX_WIDTH,
            pc2: None,
            mdd: None,
            usd: None,
            keyframe_tolerance: None,
            sparse: SparseMode::Auto,
            basis: None,
            basis_tolerance: None,
            max_targets: None,
            quantize: None,
            compress: Compression::None,
            scale: 1.0,
            translate: None,
            up: UpAxis::Y,
            collider: Vec::new(),
            thickness: None,
            friction: DEFAULT_FRICTION,
            contact: None,
            wind: None,
            drag: None,
            lift: None,
            turbulence: 0.0,
            seed: 0,
            rig: None,
            animation: None,
            cycles: defaults::CYCLES,
            warmup_cycles: defaults::WARMUP_CYCLES,
            blend_in: defaults::BLEND_IN,
            loop_blend: None,
            pin_to: None,
            pin_smooth: defaults::PIN_SMOOTH,
            body_collider: Switch::On,
            self_contact: Switch::Off,
            linear_solver: LinearSolver::Auto,
            self_thickness: None,
            body_exclude: Vec::new(),
            garment_only: false,
            rig_scale: 1.0,
            body: None,
            body_fps: None,
            body_start: None,
        }
    }
}

impl ClothJob {
    /// A job with every other parameter at its default.
    pub fn new(source: ClothSource, output: PathBuf) -> Self {
        let mut job = ClothJob {
            output,
            ..ClothJob::default()
        };
        match source {
            ClothSource::File(path) => job.input = Some(path),
            ClothSource::LabCloth { resolution } => {
                job.preset = Some(ClothPreset::LabCloth);
                job.resolution = resolution;
            }
        }
        job
    }

    /// Where the body comes from: `input` or `preset`, exactly one.
    ///
    /// # Errors
    /// [`Error::Param`] naming `input` when neither or both are given.
    pub fn source(&self) -> Result<ClothSource> {
        match (&self.input, self.preset) {
            (Some(path), None) => Ok(ClothSource::File(path.clone())),
            (None, Some(ClothPreset::LabCloth)) => Ok(ClothSource::LabCloth {
                resolution: self.resolution,
            }),
            (Some(_), Some(_)) => Err(Error::param_value(
                Param::Input,
                crate::text!("give an input file or ", Param::Preset, ", not both"),
            )),
            (None, None) => Err(Error::param_value(
                Param::Input,
                crate::text!("a mesh file is required (or ", Param::Preset, " lab-cloth)"),
            )),
        }
    }

    /// Whether the input is turned from Z-up to Y-up.
    pub fn up_z(&self) -> bool {
        self.up == UpAxis::Z
    }

    /// The name of the job and of what it writes: `name`, else the input's file stem, else
    /// the preset's name.
    pub fn display_name(&self) -> String {
        if let Some(n) = &self.name {
            return n.clone();
        }
        match (&self.input, self.preset) {
            (Some(p), _) => p
                .file_stem()
                .map_or_else(|| p.display().to_string(), |s| s.to_string_lossy().into()),
            (None, Some(ClothPreset::LabCloth)) => "lab_cloth".into(),
            (None, None) => "cloth".into(),
        }
    }
}
