//! What a cloth bake did: the report it returns (the binary writes it as JSON).

use std::path::PathBuf;

use crate::cloth::collide::ContactModel;
use crate::cloth::material::{Material, MaterialPreset};
use crate::cloth::{LinearSolver, SolverKind};
use crate::export::pointcache::PointCacheFormat;
use crate::export::vat::VatManifest;
use crate::export::{BasisStats, CacheStats};
use crate::param::Text;

/// What a cloth bake did, as written by `--report`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ClothReport {
    /// The input file or preset.
    pub input: String,
    /// Particles simulated (pinned included).
    pub particles: usize,
    /// Springs in the model.
    pub springs: usize,
    /// Springs by kind.
    pub springs_by_kind: SpringCounts,
    /// Triangles of the membrane (`--membrane triangles`; 0 with edge springs).
    pub membrane_triangles: usize,
    /// Pinned particles.
    pub pinned: usize,
    /// Triangles exported.
    pub triangles: usize,
    /// Frames baked after the initial state.
    pub frames: usize,
    /// Frames per second.
    pub fps: f64,
    /// Steps per frame.
    pub substeps: usize,
    /// How many times over a step that ends above the tolerance may be halved (`--splits`).
    pub splits: usize,
    /// The solver.
    pub solver: SolverKind,
    /// Time step h, seconds.
    pub time_step: f64,
    /// The stopping tolerance on ρ = ‖∇g‖ / ‖M·g‖ every step was solved to.
    pub tolerance: f64,
    /// The iteration cap per step.
    pub max_iterations: usize,
    /// Gauss–Seidel sweeps after each Newton iteration (0 for the fast solver).
    pub sweeps: usize,
    /// The most threads the bake could be given (`--threads`, or every core of a scene's share:
    /// [`crate::cores::Threads::most`]).
    pub threads: usize,
    /// How Newton solved for its directions: `direct` or `multigrid` (`--linear-solver`; `None`
    /// for the fast solver).
    pub linear_solver: Option<LinearSolver>,
    /// The fabric, when the body uses the material model (`None`: the labs' springs).
    pub material: Option<MaterialReport>,
    /// Spring stiffness used, N/m (the labs' model; the largest spring's for a material).
    pub stiffness: f64,
    /// Bending stiffness used, N/m (bending springs of the labs' model; 0 for a material).
    pub bend_stiffness: f64,
    /// Damping used, 1/s.
    pub damping: f64,
    /// Gravity used, m/s².
    pub gravity: [f64; 3],
    /// Total mass, kg.
    pub total_mass: f64,
    /// Solver iterations per frame (summed over substeps).
    pub iterations: Vec<usize>,
    /// Solver steps per frame: the substeps, and more where a step was split.
    pub steps: Vec<usize>,
    /// Relative residual ρ = ‖∇g‖/‖M·g‖ at the end of each frame (worst substep).
    pub residuals: Vec<f64>,
    /// Frames with a step that ended above the tolerance.
    pub unconverged_frames: Vec<usize>,
    /// Every written frame's largest edge strain and crossing triangles, and the frames past
    /// their limits.
    pub quality: QualityReport,
    /// Seconds spent simulating.
    pub seconds_simulate: f64,
    /// Milliseconds per frame.
    pub ms_per_frame: f64,
    /// Milliseconds per solver iteration.
    pub ms_per_iteration: f64,
    /// Seconds spent writing the output.
    pub seconds_export: f64,
    /// The output file(s).
    pub output: Vec<PathBuf>,
    /// Bytes written (every output file, VAT and point caches included).
    pub output_bytes: u64,
    /// The morph cache: targets, kept frames, sparse accessors, sizes.
    pub cache: CacheReport,
    /// The vertex-animation texture, when `--vat` was given.
    pub vat: Option<VatReport>,
    /// The point caches `--pc2` and `--mdd` wrote (none without them).
    pub point_caches: Vec<PointCacheReport>,
    /// The USD layer `--usd` wrote, when given.
    pub usd: Option<UsdReport>,
    /// Colliders, contacts and wind, when any.
    pub environment: Option<EnvironmentReport>,
    /// The cloth's contact with itself, when on (`--self-contact`).
    pub self_contact: Option<SelfContactReport>,
    /// The character that drove the bake, with `--rig`.
    pub character: Option<CharacterReport>,
    /// The mesh sequence that moved as a body, with `--body`.
    pub body: Option<BodyReport>,
    /// Non-fatal quirks of the input.
    pub warnings: Vec<Text>,
}

/// What an exact reader finds in every written frame (frame 0 of the output first): edge
/// strain against the input's edge lengths, and triangle pairs that cross, measured on the
/// positions as written (single precision) with exact orientation tests
/// ([`crate::measure::crossing`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct QualityReport {
    /// Frames with an edge stretched past this (l / l₀ − 1) are flagged.
    pub strain_limit: f64,
    /// Largest edge stretch of each written frame (l / l₀ − 1).
    pub max_strain: Vec<f64>,
    /// Largest edge compression of each written frame (l / l₀ − 1, ≤ 0).
    pub min_strain: Vec<f64>,
    /// Pairs of the cloth's triangles (sharing no vertex) that cross, each written frame.
    pub self_crossings: Vec<usize>,
    /// Pairs (cloth triangle, body or mesh-collider triangle) that cross, each written frame.
    pub body_crossings: Vec<usize>,
    /// Simulated written frames with an edge past the strain limit.
    pub overstrained_frames: Vec<usize>,
    /// Simulated written frames with any crossing pair (cloth–cloth or cloth–body).
    pub intersecting_frames: Vec<usize>,
    /// Seconds spent measuring (not counted in `seconds_simulate`).
    pub seconds: f64,
}

/// A bake driven by an animated character (`--rig`). The report's per-frame arrays
/// (`iterations`, `residuals`, `unconverged_frames`) count every simulated frame, the blend-in
/// and warm-up included; the output holds frames `first_written_frame..=frames`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CharacterReport {
    /// The rig file.
    pub rig: PathBuf,
    /// The driving animation.
    pub animation: String,
    /// Its duration (one loop), seconds.
    pub cycle_seconds: f64,
    /// Frames per loop (the bake's fps is frames_per_cycle / cycle_seconds).
    pub frames_per_cycle: usize,
    /// Frames blending from the rest pose into the animation.
    pub blend_frames: usize,
    /// Loops simulated and discarded.
    pub warmup_cycles: usize,
    /// Loops written.
    pub cycles: usize,
    /// The first simulated frame written (it is frame 0 of the output).
    pub first_written_frame: usize,
    /// Pins bound to the skinned surface, and to one joint.
    pub pins_on_surface: usize,
    /// Pins bound to the `--pin-to` joint.
    pub pins_on_joint: usize,
    /// Triangles of the body collider (0 when off).
    pub body_triangles: usize,
    /// Largest distance between a particle's position in the first and the last written frame
    /// (the loop's seam), metres.
    pub loop_seam: f64,
    /// The steering that joins the written loop up (`--loop-blend`); absent without it.
    pub loop_blend: Option<LoopBlend>,
    /// The edge between two pins stretched most over the written frames (`--pin-smooth`);
    /// absent without one.
    pub pin_strain: Option<PinStrain>,
}

/// The written loops joined up by the solver (`--loop-blend`): their last `frames` frames
/// steered onto the frames one written span earlier (see [`crate::cloth::LoopClosure`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LoopBlend {
    /// The written frames steered (the last ones).
    pub frames: usize,
    /// How far apart the loops were where the steering began: the largest distance between a
    /// particle's position in the frame before the steered ones and in the frame one span
    /// earlier, metres.
    pub gap: f64,
}

/// How far the pins' motion alone stretches the cloth: the worst edge between two pins.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PinStrain {
    /// Its length over its rest length, less 1 (negative where every such edge is shorter than
    /// at rest).
    pub strain: f64,
    /// The written frame (0 is the output's first).
    pub frame: usize,
    /// The two particles.
    pub particles: [u32; 2],
}

/// A bake on a body given as a mesh sequence (`--body`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct BodyReport {
    /// The file pattern.
    pub pattern: PathBuf,
    /// The first file read.
    pub first_file: PathBuf,
    /// The last file read.
    pub last_file: PathBuf,
    /// Frames in the sequence (every one was read and checked).
    pub frames: usize,
    /// The sequence's frames per second.
    pub fps: f64,
    /// Its duration, seconds (the bake's length unless `--frames` shortens it).
    pub duration_seconds: f64,
    /// Vertices of the body.
    pub vertices: usize,
    /// Triangles of the body.
    pub triangles: usize,
    /// Whether it collides with the cloth (`--body-collider`).
    pub collides: bool,
    /// The name of its mesh and node in the output.
    pub node: String,
}

/// The fabric of a material-model bake.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MaterialReport {
    /// The preset named (or the default), before `--stretch`/`--bend`/`--density` overrides.
    pub preset: MaterialPreset,
    /// The figures used.
    #[serde(flatten)]
    pub material: Material,
}

/// The morph cache as written.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CacheReport {
    /// `--keyframe-tolerance`, scene units (`None`: every frame kept).
    pub keyframe_tolerance: Option<f64>,
    /// Bytes of the glTF file(s) (`.glb`, or `.gltf` plus `.bin`).
    pub gltf_bytes: u64,
    /// Targets, kept frames, largest interpolation error against the full bake, accessors.
    #[serde(flatten)]
    pub stats: CacheStats,
    /// The morph basis, when `--basis` was given: K, measured error, quantisation, bytes per
    /// part.
    pub basis: Option<BasisStats>,
}

/// The vertex-animation texture as written.
#[derive(Debug, Clone, serde::Serialize)]
pub struct VatReport {
    /// The images and the JSON.
    pub files: Vec<PathBuf>,
    /// Their total size.
    pub bytes: u64,
    /// What the JSON says (layout, bounds, mode).
    pub manifest: VatManifest,
}

/// A point cache as written (`--pc2`, `--mdd`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct PointCacheReport {
    /// `pc2` or `mdd`.
    pub format: PointCacheFormat,
    /// The file.
    pub file: PathBuf,
    /// Its size.
    pub bytes: u64,
    /// Points per frame: the simulated positions, in the input's order.
    pub points: usize,
    /// Frames, frame 0 (the initial state) included; one sample per frame.
    pub frames: usize,
    /// Frames per second.
    pub fps: f64,
}

/// A USD layer as written (`--usd`).
#[derive(Debug, Clone, serde::Serialize)]
pub struct UsdReport {
    /// The file.
    pub file: PathBuf,
    /// Its size.
    pub bytes: u64,
    /// Its meshes' prim paths: the cloth's first, then the colliders', then a body's.
    pub prims: Vec<String>,
    /// Frames, frame 0 (the initial state) included: the animated meshes' time samples.
    pub frames: usize,
    /// The first and last frames' time codes.
    pub time_codes: [f64; 2],
    /// Time codes (frames) per second.
    pub fps: f64,
}

/// The environment of a bake, as used.
#[derive(Debug, Clone, serde::Serialize)]
pub struct EnvironmentReport {
    /// Each collider, described.
    pub colliders: Vec<String>,
    /// Collision thickness used, m.
    pub thickness: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Newton's contact model (`constraint` or `barrier`).
    pub contact: ContactModel,
    /// Particles touching a collider at the end of each frame.
    pub contacts: Vec<usize>,
    /// Particles a moving body pinched behind its surface in each frame (summed over its
    /// steps): released from it until they came out, where the cloth went through the body.
    pub pinched: Vec<usize>,
    /// Self-contact pairs of a body's vertex or edge with the cloth released as pinched in each
    /// frame (summed over its steps): where the body closed on the cloth and was let through it.
    pub pinched_pairs: Vec<usize>,
    /// The wind, when any.
    pub wind: Option<WindReport>,
}

/// The cloth's contact with itself (vertex–triangle and edge–edge pairs).
#[derive(Debug, Clone, serde::Serialize)]
pub struct SelfContactReport {
    /// The layer pairs are kept apart by, m (pairs that start closer keep their distance).
    pub thickness: f64,
    /// Pairs inside their layer at the end of each frame (the most over its substeps).
    pub pairs: Vec<usize>,
}

/// The wind of a bake, as used.
#[derive(Debug, Clone, serde::Serialize)]
pub struct WindReport {
    /// Mean wind velocity, m/s.
    pub velocity: [f64; 3],
    /// Drag coefficient.
    pub drag: f64,
    /// Lift coefficient.
    pub lift: f64,
    /// Gust strength relative to the wind speed.
    pub turbulence: f64,
    /// Gust seed.
    pub seed: u64,
}

/// Spring counts by kind.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct SpringCounts {
    /// Along edges.
    pub stretch: usize,
    /// Across grid cells.
    pub shear: usize,
    /// Bending.
    pub bend: usize,
}
