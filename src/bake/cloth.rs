//! A cloth bake from start to finish: load the body, build the model, simulate, export, report.
//!
//! [`ClothJob`] holds one field per `scenebake cloth` option; the command line and scene files
//! both fill it, so they share one vocabulary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;

use crate::cloth::collide::{
    Collider, ColliderSpec, Colliders, DEFAULT_FRICTION, DEFAULT_THICKNESS_FRACTION,
};
use crate::cloth::material::{fabric_model_terms, Material, MaterialPreset, DEFAULT_MATERIAL};
use crate::cloth::model::{masses_from_area, masses_from_volume};
use crate::cloth::pins::{pinned_flags, PinSpec};
use crate::cloth::preset::{self, lab_cloth};
use crate::cloth::springs::{surface_springs, volume_springs, SpringKind, SpringSet};
use crate::cloth::wind::{self, Wind};
use crate::cloth::{
    make_solver, simulate, BakeParams, ClothModel, Simulation, SolverKind, StepStats,
};
use crate::error::{Error, Result};
use crate::export::basis::encode_basis_gltf;
use crate::export::morph::{check_cache, encode_morph_gltf};
use crate::export::vat::{encode_vat, vat_paths, VatManifest, DEFAULT_MAX_WIDTH};
use crate::export::{BasisOptions, BasisSize, BasisStats, QuantizeMode};
use crate::export::{
    CacheStats, Interpolation, MorphOptions, RenderFrames, SparseMode, VatMode, VatOptions, Written,
};
use crate::io::{gltf_mesh::load_gltf_mesh, obj, tet::load_tet};
use crate::mesh::Mesh;
use crate::spec::{non_negative, positive};

/// Where the body comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ClothSource {
    /// An `.obj`, `.gltf`/`.glb` or `.tet` file (the `INPUT` argument).
    File(PathBuf),
    /// `--preset lab-cloth`: the labs' grid with `--resolution N` cells per side.
    LabCloth {
        /// Cells per side (N); the grid has (N+1)² particles.
        resolution: u32,
    },
}

/// Default values for meshes loaded from files (presets bring their own).
pub mod defaults {
    /// `--frames`.
    pub const FRAMES: usize = 120;
    /// `--fps`.
    pub const FPS: f64 = 30.0;
    /// `--stiffness`, N/m per spring.
    pub const STIFFNESS: f64 = 1000.0;
    /// `--bend-stiffness`, N/m per bending spring.
    pub const BEND_STIFFNESS: f64 = 2.0;
    /// `--damping`, 1/s.
    pub const DAMPING: f64 = 0.5;
    /// `--density` for surfaces, kg/m² (a light cotton).
    pub const AREAL_DENSITY: f64 = 0.2;
    /// `--density` for `.tet` volumes, kg/m³ (a soft foam).
    pub const VOLUME_DENSITY: f64 = 50.0;
    /// `--gravity`, m/s².
    pub const GRAVITY: [f64; 3] = [0.0, -9.81, 0.0];
    /// `--iterations`: the fast solver's cap on local/global iterations per step.
    pub const ITERATIONS: usize = 500;
    /// `--tolerance`: every solver stops a step when ρ = ‖∇g‖ / ‖M·g‖ falls below this (the
    /// RMS unbalanced force per particle relative to its weight, roughly). 0.1 is visually
    /// converged on garments: hem heights within 0.5 mm of a 1e-3 solve (docs/performance.md).
    pub const TOLERANCE: f64 = 0.1;
    /// The solver when none is named.
    pub const SOLVER: crate::cloth::SolverKind = crate::cloth::SolverKind::Newton;
}

/// One cloth bake. `None` means "the default": the preset's value for presets, else
/// [`defaults`].
#[derive(Debug, Clone, PartialEq)]
pub struct ClothJob {
    /// `INPUT` or `--preset`.
    pub source: ClothSource,
    /// `--object NAME`: one object or group of an OBJ.
    pub object: Option<String>,
    /// `--mesh NAME`: one mesh of a glTF.
    pub mesh: Option<String>,
    /// `-o FILE`: `.glb`, or `.gltf` with a `.bin` beside it.
    pub output: PathBuf,
    /// `--frames N`: frames after the initial state.
    pub frames: Option<usize>,
    /// `--fps F`.
    pub fps: Option<f64>,
    /// `--substeps S`: solver steps per frame.
    pub substeps: usize,
    /// `--solver`.
    pub solver: SolverKind,
    /// `--iterations K`: local/global iterations per step at most (fast solver).
    pub iterations: usize,
    /// `--tolerance`: every solver's stopping residual ρ = ‖∇g‖ / ‖M·g‖.
    pub tolerance: f64,
    /// `--max-newton`: Newton iterations per step at most.
    pub max_newton: usize,
    /// `--max-iterations`: the cap of whichever solver runs (overrides `iterations` and
    /// `max_newton`).
    pub max_iterations: Option<usize>,
    /// `--material`: the fabric of a surface mesh (default [`DEFAULT_MATERIAL`]).
    pub material: Option<MaterialPreset>,
    /// `--stretch` (N/m): the material's stretch modulus.
    pub stretch: Option<f64>,
    /// `--bend` (N·m): the material's bending rigidity.
    pub bend: Option<f64>,
    /// `--compression`: the material's compression stiffness as a fraction of its tension one.
    pub compression: Option<f64>,
    /// `--stiffness` (N/m): every spring's constant, symmetric (the labs' model).
    pub stiffness: Option<f64>,
    /// `--bend-stiffness` (N/m): bending springs' constant (the labs' model).
    pub bend_stiffness: Option<f64>,
    /// `--damping` (1/s).
    pub damping: Option<f64>,
    /// `--mass` (kg per particle); exclusive with `density`.
    pub mass: Option<f64>,
    /// `--density` (kg/m², or kg/m³ for `.tet`).
    pub density: Option<f64>,
    /// `--gravity X,Y,Z` (m/s²).
    pub gravity: Option<DVec3>,
    /// `--pin SPEC` (repeatable).
    pub pins: Vec<PinSpec>,
    /// `--interpolation`.
    pub interpolation: Interpolation,
    /// `--normals off` clears this.
    pub normals: bool,
    /// `--name`: the glTF mesh/node/animation name (default: the input's file stem).
    pub name: Option<String>,
    /// `--vat FILE.exr`: also write a vertex-animation texture (`FILE.exr`, `FILE.normals.exr`,
    /// `FILE.json`; see [`crate::export::vat`]).
    pub vat: Option<PathBuf>,
    /// `--vat-mode`: absolute positions or offsets from the base mesh.
    pub vat_mode: VatMode,
    /// `--vat-max-width`: most pixels per VAT row; wider meshes wrap into several rows per frame.
    pub vat_max_width: usize,
    /// `--keyframe-tolerance T` (scene units): keep only the frames needed to reproduce every
    /// baked frame within T; `None` keeps one target per frame.
    pub keyframe_tolerance: Option<f64>,
    /// `--sparse`: sparse morph-target accessors where smaller (`auto`) or never (`off`).
    pub sparse: SparseMode,
    /// `--basis K|auto`: write a base plus K basis targets with per-frame weights instead of one
    /// target per frame (see [`crate::export::basis`]).
    pub basis: Option<BasisSize>,
    /// `--basis-tolerance M` (scene units) [default: the keyframe tolerance, else 1 mm].
    pub basis_tolerance: Option<f64>,
    /// `--max-targets N`: most morph targets written.
    pub max_targets: Option<usize>,
    /// `--quantize`: KHR_mesh_quantization for the basis cache [default: auto with --basis].
    pub quantize: Option<QuantizeMode>,
    /// `--scale S`: the input file is scaled about its origin by S, then…
    pub scale: f64,
    /// `--translate X,Y,Z` (m): …moved by this offset, before anything else (pins and colliders
    /// are in the placed coordinates).
    pub translate: DVec3,
    /// `--up z`: the input file is Z-up (Blender's and many OBJ exporters' convention) and is
    /// turned to glTF's Y-up first, (x, y, z) → (x, z, −y), before `--scale` and `--translate`.
    pub up_z: bool,
    /// `--collider SPEC` (repeatable); mesh paths as given (relative to the working directory).
    pub colliders: Vec<ColliderSpec>,
    /// `--thickness` (m): how far particles stay from colliders; default a quarter of the mean
    /// edge length.
    pub thickness: Option<f64>,
    /// `--friction`: Coulomb coefficient against colliders.
    pub friction: f64,
    /// `--wind X,Y,Z` (m/s).
    pub wind: Option<DVec3>,
    /// `--drag`: drag coefficient (turns aerodynamics on even without wind).
    pub drag: Option<f64>,
    /// `--lift`: lift coefficient (turns aerodynamics on even without wind).
    pub lift: Option<f64>,
    /// `--turbulence`: gust strength relative to the wind speed.
    pub turbulence: f64,
    /// `--seed`: the gusts' random seed.
    pub seed: u64,
}

impl ClothJob {
    /// A job with every option at its default.
    pub fn new(source: ClothSource, output: PathBuf) -> Self {
        ClothJob {
            source,
            object: None,
            mesh: None,
            output,
            frames: None,
            fps: None,
            substeps: 1,
            solver: defaults::SOLVER,
            iterations: defaults::ITERATIONS,
            tolerance: defaults::TOLERANCE,
            max_newton: crate::cloth::newton::DEFAULT_MAX_ITERATIONS,
            max_iterations: None,
            material: None,
            stretch: None,
            bend: None,
            compression: None,
            stiffness: None,
            bend_stiffness: None,
            damping: None,
            mass: None,
            density: None,
            gravity: None,
            pins: Vec::new(),
            interpolation: Interpolation::Linear,
            normals: true,
            name: None,
            vat: None,
            vat_mode: VatMode::Absolute,
            vat_max_width: DEFAULT_MAX_WIDTH,
            keyframe_tolerance: None,
            sparse: SparseMode::Auto,
            basis: None,
            basis_tolerance: None,
            max_targets: None,
            quantize: None,
            scale: 1.0,
            translate: DVec3::ZERO,
            up_z: false,
            colliders: Vec::new(),
            thickness: None,
            friction: DEFAULT_FRICTION,
            wind: None,
            drag: None,
            lift: None,
            turbulence: 0.0,
            seed: 0,
        }
    }
}

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
    /// The solver.
    pub solver: SolverKind,
    /// Time step h, seconds.
    pub time_step: f64,
    /// The stopping tolerance on ρ = ‖∇g‖ / ‖M·g‖ every step was solved to.
    pub tolerance: f64,
    /// The iteration cap per step.
    pub max_iterations: usize,
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
    /// Relative residual ρ = ‖∇g‖/‖M·g‖ at the end of each frame (worst substep).
    pub residuals: Vec<f64>,
    /// Frames with a step that ended above the tolerance.
    pub unconverged_frames: Vec<usize>,
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
    /// Bytes written (every output file, VAT included).
    pub output_bytes: u64,
    /// The morph cache: targets, kept frames, sparse accessors, sizes.
    pub cache: CacheReport,
    /// The vertex-animation texture, when `--vat` was given.
    pub vat: Option<VatReport>,
    /// Colliders, contacts and wind, when any.
    pub environment: Option<EnvironmentReport>,
    /// Non-fatal quirks of the input.
    pub warnings: Vec<String>,
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

/// The environment of a bake, as used.
#[derive(Debug, Clone, serde::Serialize)]
pub struct EnvironmentReport {
    /// Each collider, described.
    pub colliders: Vec<String>,
    /// Collision thickness used, m.
    pub thickness: f64,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Particles touching a collider at the end of each frame.
    pub contacts: Vec<usize>,
    /// The wind, when any.
    pub wind: Option<WindReport>,
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

/// A model ready to bake, with the parameters resolved from the job and the preset.
#[derive(Debug, Clone)]
pub struct PreparedCloth {
    /// The model.
    pub model: ClothModel,
    /// The bake settings.
    pub params: BakeParams,
    /// Stiffness used, N/m.
    pub stiffness: f64,
    /// Bending stiffness used, N/m.
    pub bend_stiffness: f64,
    /// The fabric, for material-model bodies.
    pub material: Option<MaterialReport>,
    /// Spring counts.
    pub counts: SpringCounts,
}

/// Loads the body and resolves every parameter of `job`, checking them.
///
/// # Errors
/// Input errors (naming the file and element) and option errors (naming the option).
pub fn prepare_cloth(job: &ClothJob) -> Result<PreparedCloth> {
    let frames = job.frames.unwrap_or(defaults::FRAMES);
    if frames == 0 {
        return Err(Error::option("--frames", "0: must be at least 1"));
    }
    if job.substeps == 0 {
        return Err(Error::option("--substeps", "0: must be at least 1"));
    }
    if job.iterations == 0 {
        return Err(Error::option("--iterations", "0: must be at least 1"));
    }
    if job.max_newton == 0 {
        return Err(Error::option("--max-newton", "0: must be at least 1"));
    }
    if job.max_iterations == Some(0) {
        return Err(Error::option("--max-iterations", "0: must be at least 1"));
    }
    if job.mass.is_some() && job.density.is_some() {
        return Err(Error::option(
            "--mass",
            "give either --mass (kg per particle) or --density, not both",
        ));
    }
    let is_preset = matches!(job.source, ClothSource::LabCloth { .. });
    let springs_option = [
        ("--stiffness", job.stiffness.is_some()),
        ("--bend-stiffness", job.bend_stiffness.is_some()),
    ]
    .into_iter()
    .find_map(|(name, given)| given.then_some(name));
    let material_option = [
        ("--material", job.material.is_some()),
        ("--stretch", job.stretch.is_some()),
        ("--bend", job.bend.is_some()),
        ("--compression", job.compression.is_some()),
    ]
    .into_iter()
    .find_map(|(name, given)| given.then_some(name));
    if let (Some(springs), Some(material)) = (springs_option, material_option) {
        return Err(Error::option(
            material,
            format!(
                "{springs} sets the labs' symmetric springs (N/m per spring); {material} sets a \
                 fabric mapped onto the mesh: give one or the other"
            ),
        ));
    }
    if is_preset {
        if let Some(material) = material_option {
            return Err(Error::option(
                material,
                "the lab-cloth preset uses the labs' springs; use --stiffness and --bend-stiffness",
            ));
        }
    }
    // The labs' spring model: the preset, `--stiffness`/`--bend-stiffness`, and volumes.
    let stiffness = positive(
        "--stiffness",
        job.stiffness.unwrap_or(if is_preset {
            preset::defaults::STIFFNESS
        } else {
            defaults::STIFFNESS
        }),
    )?;
    let bend_stiffness = non_negative(
        "--bend-stiffness",
        job.bend_stiffness.unwrap_or(if is_preset {
            stiffness
        } else {
            defaults::BEND_STIFFNESS
        }),
    )?;
    let material = resolve_material(job)?;
    let damping = non_negative(
        "--damping",
        job.damping.unwrap_or(if is_preset {
            preset::defaults::DAMPING
        } else {
            defaults::DAMPING
        }),
    )?;
    let fps = positive(
        "--fps",
        job.fps.unwrap_or(if is_preset {
            preset::defaults::FPS
        } else {
            defaults::FPS
        }),
    )?;
    let gravity = job.gravity.unwrap_or(DVec3::from_array(if is_preset {
        preset::defaults::GRAVITY
    } else {
        defaults::GRAVITY
    }));
    if let Some(m) = job.mass {
        positive("--mass", m)?;
    }
    if let Some(d) = job.density {
        positive("--density", d)?;
    }
    check_export_options(job)?;

    // Set where the body takes the fabric model (a surface file without --stiffness).
    let (mut bending, mut uses_material) = (Vec::new(), false);
    let (mesh, springs, mut pinned): (Mesh, SpringSet, Vec<bool>) = match &job.source {
        ClothSource::LabCloth { resolution } => {
            if let Some(option) = [
                ("--object", job.object.is_some()),
                ("--mesh", job.mesh.is_some()),
            ]
            .into_iter()
            .find_map(|(o, given)| given.then_some(o))
            {
                return Err(Error::option(
                    option,
                    "picks part of an input file; the lab-cloth preset has none",
                ));
            }
            if job.scale != 1.0 || job.translate != DVec3::ZERO || job.up_z {
                let option = if job.scale != 1.0 {
                    "--scale"
                } else if job.up_z {
                    "--up"
                } else {
                    "--translate"
                };
                return Err(Error::option(
                    option,
                    "places an input file; the lab-cloth preset keeps the labs' coordinates",
                ));
            }
            if *resolution == 0 || *resolution > 2000 {
                return Err(Error::option(
                    "--resolution",
                    format!("{resolution}: must be between 1 and 2000"),
                ));
            }
            let mut lab = lab_cloth(*resolution, stiffness);
            // The lab's springs share one stiffness; --bend-stiffness overrides the bending ones.
            for s in lab
                .springs
                .springs
                .iter_mut()
                .filter(|s| s.kind == SpringKind::Bend)
            {
                s.stiffness = bend_stiffness;
            }
            lab.springs.springs.retain(|s| s.stiffness > 0.0);
            let pinned = if job.pins.is_empty() {
                lab.pinned_flags()
            } else {
                vec![false; lab.mesh.particle_count()]
            };
            (lab.mesh, lab.springs, pinned)
        }
        ClothSource::File(path) => {
            let mut mesh = load_body(path, job)?;
            place(&mut mesh, job)?;
            if !mesh.tets.is_empty() {
                if let Some(option) = material_option {
                    return Err(Error::option(
                        option,
                        "fabric materials apply to surfaces; a .tet volume uses --stiffness",
                    ));
                }
            }
            let springs = if !mesh.tets.is_empty() {
                volume_springs(&mesh, stiffness)
            } else if springs_option.is_some() {
                surface_springs(&mesh, stiffness, bend_stiffness)
            } else {
                let terms = fabric_model_terms(&mesh, &material.material);
                bending = terms.bending;
                uses_material = true;
                terms.springs
            };
            let n = mesh.particle_count();
            (mesh, springs, vec![false; n])
        }
    };
    let material = uses_material.then_some(material);
    let size_warning =
        crate::export::estimate::check_frames(frames, mesh.render_vertices.len(), job.normals)?;
    for (flag, extra) in pinned.iter_mut().zip(pinned_flags(&mesh, &job.pins)?) {
        *flag |= extra;
    }
    let mass = match (job.mass, job.density, is_preset) {
        (Some(m), _, _) => vec![m; mesh.particle_count()],
        (None, None, true) => vec![preset::defaults::MASS; mesh.particle_count()],
        (None, density, _) if !mesh.tets.is_empty() => {
            masses_from_volume(&mesh, density.unwrap_or(defaults::VOLUME_DENSITY))
        }
        (None, _, _) if material.is_some() => {
            masses_from_area(&mesh, material.as_ref().expect("some").material.density)
        }
        (None, density, _) => masses_from_area(&mesh, density.unwrap_or(defaults::AREAL_DENSITY)),
    };
    let counts = SpringCounts {
        stretch: springs.count(SpringKind::Stretch),
        shear: springs.count(SpringKind::Shear),
        bend: springs.count(SpringKind::Bend),
    };
    let mut model = ClothModel::new(mesh, springs, mass, pinned)?.with_bending(bending)?;
    model.warnings.extend(size_warning);
    let colliders = prepare_colliders(job, &model)?;
    let wind = prepare_wind(job)?;
    let params = BakeParams {
        frames,
        fps,
        substeps: job.substeps,
        damping,
        gravity,
        solver: job.solver,
        iterations: job.max_iterations.unwrap_or(job.iterations),
        tolerance: non_negative("--tolerance", job.tolerance)?,
        max_newton: job.max_iterations.unwrap_or(job.max_newton),
        colliders,
        wind,
    };
    let (stiffness, bend_stiffness) = if material.is_some() {
        let k: Vec<f64> = model.springs.iter().map(|s| s.stiffness).collect();
        (k.iter().sum::<f64>() / k.len().max(1) as f64, 0.0)
    } else {
        (stiffness, bend_stiffness)
    };
    Ok(PreparedCloth {
        model,
        params,
        stiffness,
        bend_stiffness,
        material,
        counts,
    })
}

/// `--material` with the `--stretch`, `--bend`, `--compression` and `--density` overrides.
fn resolve_material(job: &ClothJob) -> Result<MaterialReport> {
    let preset = job.material.unwrap_or(DEFAULT_MATERIAL);
    let mut m = preset.material();
    if let Some(v) = job.stretch {
        m.stretch = positive("--stretch", v)?;
    }
    if let Some(v) = job.bend {
        m.bend = non_negative("--bend", v)?;
    }
    if let Some(v) = job.compression {
        if !(0.0..=1.0).contains(&v) {
            return Err(Error::option(
                "--compression",
                format!("{v}: must be between 0 and 1 (a fraction of the tension stiffness)"),
            ));
        }
        m.compression = v;
    }
    if let Some(d) = job.density {
        m.density = positive("--density", d)?;
    }
    Ok(MaterialReport {
        preset,
        material: m,
    })
}

/// Applies `--up`, `--scale` and `--translate` to a loaded body.
fn place(mesh: &mut Mesh, job: &ClothJob) -> Result<()> {
    let scale = positive("--scale", job.scale)?;
    if !job.translate.is_finite() {
        return Err(Error::option("--translate", "must be finite"));
    }
    if job.up_z {
        for p in &mut mesh.positions {
            *p = DVec3::new(p.x, p.z, -p.y);
        }
    }
    if scale != 1.0 || job.translate != DVec3::ZERO {
        for p in &mut mesh.positions {
            *p = *p * scale + job.translate;
        }
    }
    Ok(())
}

/// Loads the colliders and resolves `--thickness` and `--friction`.
fn prepare_colliders(job: &ClothJob, model: &ClothModel) -> Result<Colliders> {
    let shapes = job
        .colliders
        .iter()
        .map(Collider::from_spec)
        .collect::<Result<Vec<_>>>()?;
    let thickness = match job.thickness {
        Some(t) => positive("--thickness", t)?,
        None => DEFAULT_THICKNESS_FRACTION * mean_edge_length(model),
    };
    Ok(Colliders {
        shapes,
        thickness,
        friction: non_negative("--friction", job.friction)?,
    })
}

/// Mean rest length of the model's stretch springs (its edges), m; 1 cm when there are none.
fn mean_edge_length(model: &ClothModel) -> f64 {
    let edges: Vec<f64> = model
        .springs
        .iter()
        .filter(|s| s.kind == SpringKind::Stretch)
        .map(|s| s.rest)
        .collect();
    if edges.is_empty() {
        0.01
    } else {
        edges.iter().sum::<f64>() / edges.len() as f64
    }
}

/// The aerodynamics, on when any of `--wind`, `--drag` or `--lift` is given.
fn prepare_wind(job: &ClothJob) -> Result<Option<Wind>> {
    if job.wind.is_none() && job.drag.is_none() && job.lift.is_none() {
        if job.turbulence != 0.0 {
            return Err(Error::option(
                "--turbulence",
                "gusts need a mean wind: give --wind X,Y,Z too",
            ));
        }
        return Ok(None);
    }
    Ok(Some(Wind {
        velocity: job.wind.unwrap_or(DVec3::ZERO),
        drag: non_negative("--drag", job.drag.unwrap_or(wind::DEFAULT_DRAG))?,
        lift: non_negative("--lift", job.lift.unwrap_or(wind::DEFAULT_LIFT))?,
        turbulence: non_negative("--turbulence", job.turbulence)?,
        seed: job.seed,
    }))
}

/// Checks the export options that need no mesh: `--keyframe-tolerance`, `--vat`,
/// `--vat-max-width`.
///
/// # Errors
/// [`Error::InvalidOption`] naming the option.
pub fn check_export_options(job: &ClothJob) -> Result<()> {
    if let Some(t) = job.keyframe_tolerance {
        non_negative("--keyframe-tolerance", t)?;
    }
    if let Some(m) = job.basis_tolerance {
        non_negative("--basis-tolerance", m)?;
    }
    if job.max_targets == Some(0) {
        return Err(Error::option("--max-targets", "0: must be at least 1"));
    }
    if job.basis.is_none() {
        if job.basis_tolerance.is_some() {
            return Err(Error::option(
                "--basis-tolerance",
                "applies to a morph basis: give --basis K or --basis auto too",
            ));
        }
        if job.quantize == Some(QuantizeMode::On) {
            return Err(Error::option(
                "--quantize",
                "on: quantisation is written for a morph basis: give --basis K or --basis auto too",
            ));
        }
    }
    if let Some(path) = &job.vat {
        vat_paths(path)?;
    }
    if job.vat_max_width == 0 {
        return Err(Error::option(
            "--vat-max-width",
            "0: must be at least 1 pixel",
        ));
    }
    Ok(())
}

/// Loads a body file by extension: `.obj`, `.gltf`/`.glb`, `.tet`.
///
/// # Errors
/// Unknown extensions, unreadable or malformed files.
pub fn load_body(path: &Path, job: &ClothJob) -> Result<Mesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if path.is_dir() {
        return Err(Error::io(
            path,
            std::io::Error::other("is a directory, not a mesh file"),
        ));
    }
    // Options that select inside one format only.
    let gltf = matches!(ext.as_deref(), Some("gltf") | Some("glb"));
    if job.mesh.is_some() && !gltf {
        return Err(Error::option(
            "--mesh",
            format!(
                "picks a mesh of a .gltf/.glb input, and {} is not one (for an OBJ, --object NAME picks an object or group)",
                path.display()
            ),
        ));
    }
    if job.object.is_some() && ext.as_deref() != Some("obj") {
        return Err(Error::option(
            "--object",
            format!(
                "picks an object or group of an .obj input, and {} is not one{}",
                path.display(),
                if gltf {
                    " (for a glTF, --mesh NAME picks a mesh)"
                } else {
                    ""
                }
            ),
        ));
    }
    match ext.as_deref() {
        Some("obj") => obj::load_obj(
            path,
            &obj::ObjOptions {
                object: job.object.clone(),
            },
        ),
        Some("gltf") | Some("glb") => load_gltf_mesh(path, job.mesh.as_deref()),
        Some("tet") => load_tet(path),
        _ => Err(Error::invalid(
            path,
            "unknown mesh format: expected .obj, .gltf, .glb or .tet",
        )),
    }
}

/// `--basis-tolerance` when neither it nor `--keyframe-tolerance` is given: 1 mm.
pub const DEFAULT_BASIS_TOLERANCE: f64 = 1e-3;

/// A cloth job simulated but not exported.
#[derive(Debug, Clone)]
pub struct SimulatedCloth {
    /// The model and the parameters used.
    pub prepared: PreparedCloth,
    /// The frames and per-frame solver figures.
    pub simulation: Simulation,
}

/// Prepares and simulates `job` (calling `progress(frame, frames)`) without writing anything.
///
/// # Errors
/// As [`prepare_cloth`]; [`Error::Diverged`] when the simulation blows up.
pub fn simulate_cloth(
    job: &ClothJob,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<SimulatedCloth> {
    let prepared = prepare_cloth(job)?;
    let PreparedCloth { model, params, .. } = &prepared;
    let mut solver = make_solver(model, params)?;
    let frames = params.frames;
    let simulation = simulate(model, solver.as_mut(), params, &mut |f| progress(f, frames))?;
    Ok(SimulatedCloth {
        prepared,
        simulation,
    })
}

/// Runs a whole bake: prepare, simulate (calling `progress(frame, frames)`), export, report.
///
/// # Errors
/// As [`prepare_cloth`]; [`Error::Diverged`] when the simulation blows up (nothing is written);
/// write errors.
pub fn bake_cloth(job: &ClothJob, progress: &mut dyn FnMut(usize, usize)) -> Result<ClothReport> {
    let SimulatedCloth {
        prepared,
        simulation: sim,
    } = simulate_cloth(job, progress)?;
    let PreparedCloth { model, params, .. } = &prepared;

    let export_start = Instant::now();
    let name = job.name.clone().unwrap_or_else(|| match &job.source {
        ClothSource::File(p) => p
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("cloth")
            .to_owned(),
        ClothSource::LabCloth { .. } => "lab_cloth".to_owned(),
    });
    let options = MorphOptions {
        fps: params.fps,
        interpolation: job.interpolation,
        name,
        normals: job.normals,
        keyframe_tolerance: job.keyframe_tolerance,
        sparse: job.sparse,
        static_meshes: collider_meshes(model, &params.colliders),
    };
    let exported = export(job, model, &sim.cache, options)?;
    let seconds_export = export_start.elapsed().as_secs_f64();
    Ok(report(
        &prepared,
        job,
        &sim.frames,
        sim.seconds,
        seconds_export,
        exported,
    ))
}

/// The colliders as static meshes named `collider_1`, `collider_2`...; planes as squares twice
/// the cloth's diagonal (at least 1 m), under its centre.
fn collider_meshes(model: &ClothModel, colliders: &Colliders) -> Vec<crate::export::StaticMesh> {
    let (lo, hi) = model.mesh.bounds();
    let size = 2.0 * (hi - lo).length().max(0.5);
    colliders
        .shapes
        .iter()
        .enumerate()
        .map(|(i, c)| c.static_mesh(format!("collider_{}", i + 1), (lo + hi) * 0.5, size))
        .collect()
}

/// What the export step wrote.
struct Exported {
    written: Written,
    cache: CacheReport,
    vat: Option<VatReport>,
}

/// Encodes the morph glTF and, when asked, the VAT, then writes them all as one atomic set.
fn export(
    job: &ClothJob,
    model: &ClothModel,
    cache: &crate::cloth::FrameCache,
    options: MorphOptions,
) -> Result<Exported> {
    check_cache(&job.output, &model.mesh, cache)?;
    let frames = RenderFrames::new(&model.mesh, cache);
    let (morph, basis) = match job.basis {
        Some(size) => {
            let basis = BasisOptions {
                size,
                tolerance: job
                    .basis_tolerance
                    .or(job.keyframe_tolerance)
                    .unwrap_or(DEFAULT_BASIS_TOLERANCE),
                max_targets: job.max_targets,
                quantize: job.quantize.unwrap_or_default(),
            };
            let e = encode_basis_gltf(&job.output, &model.mesh, &frames, &options, &basis)?;
            (e.morph, Some(e.basis))
        }
        None => {
            let morph = encode_morph_gltf(&job.output, &model.mesh, &frames, &options)?;
            if let Some(n) = job.max_targets.filter(|&n| morph.stats.targets > n) {
                return Err(Error::option(
                    "--max-targets",
                    format!(
                        "{n}: the cache needs {} targets (one per kept frame); use --basis auto, \
                         or a larger --keyframe-tolerance",
                        morph.stats.targets
                    ),
                ));
            }
            (morph, None)
        }
    };
    let gltf_bytes = morph.files.iter().map(|(_, b)| b.len() as u64).sum();
    let mut files = morph.files;
    let vat = match &job.vat {
        Some(path) => {
            let gltf = job
                .output
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let vat_options = VatOptions {
                mode: job.vat_mode,
                max_width: job.vat_max_width,
                fps: options.fps,
                normals: job.normals,
                gltf,
            };
            let encoded = encode_vat(path, &frames, &vat_options)?;
            let report = VatReport {
                files: encoded.files.iter().map(|(p, _)| p.clone()).collect(),
                bytes: encoded.files.iter().map(|(_, b)| b.len() as u64).sum(),
                manifest: encoded.manifest,
            };
            files.extend(encoded.files);
            Some(report)
        }
        None => None,
    };
    let written = Written::write_all(files)?;
    Ok(Exported {
        written,
        cache: CacheReport {
            keyframe_tolerance: options.keyframe_tolerance,
            gltf_bytes,
            stats: morph.stats,
            basis,
        },
        vat,
    })
}

fn environment_report(params: &BakeParams, frames: &[StepStats]) -> Option<EnvironmentReport> {
    if params.colliders.is_empty() && params.wind.is_none() {
        return None;
    }
    let c = &params.colliders;
    Some(EnvironmentReport {
        colliders: c.shapes.iter().map(Collider::describe).collect(),
        thickness: c.thickness,
        friction: c.friction,
        contacts: frames.iter().map(|f| f.contacts).collect(),
        wind: params.wind.as_ref().map(|w| WindReport {
            velocity: w.velocity.to_array(),
            drag: w.drag,
            lift: w.lift,
            turbulence: w.turbulence,
            seed: w.seed,
        }),
    })
}

fn report(
    prepared: &PreparedCloth,
    job: &ClothJob,
    frames: &[StepStats],
    seconds_simulate: f64,
    seconds_export: f64,
    exported: Exported,
) -> ClothReport {
    let Exported {
        written,
        cache,
        vat,
    } = exported;
    let PreparedCloth { model, params, .. } = prepared;
    let total_iterations: usize = frames.iter().map(|f| f.iterations).sum();
    ClothReport {
        input: match &job.source {
            ClothSource::File(p) => p.display().to_string(),
            ClothSource::LabCloth { resolution } => format!("lab-cloth (resolution {resolution})"),
        },
        particles: model.particle_count(),
        springs: model.springs.len(),
        springs_by_kind: prepared.counts,
        pinned: model.pinned_count(),
        triangles: model.mesh.render_triangles.len(),
        frames: params.frames,
        fps: params.fps,
        substeps: params.substeps,
        solver: params.solver,
        time_step: params.time_step(),
        tolerance: params.tolerance,
        max_iterations: match params.solver {
            SolverKind::Fast => params.iterations,
            SolverKind::Newton => params.max_newton,
        },
        material: prepared.material.clone(),
        stiffness: prepared.stiffness,
        bend_stiffness: prepared.bend_stiffness,
        damping: params.damping,
        gravity: params.gravity.to_array(),
        total_mass: model.mass.iter().sum(),
        iterations: frames.iter().map(|f| f.iterations).collect(),
        residuals: frames.iter().map(|f| f.residual).collect(),
        unconverged_frames: frames
            .iter()
            .enumerate()
            .filter(|(_, f)| !f.converged)
            .map(|(i, _)| i + 1)
            .collect(),
        seconds_simulate,
        ms_per_frame: 1e3 * seconds_simulate / params.frames as f64,
        ms_per_iteration: 1e3 * seconds_simulate / total_iterations.max(1) as f64,
        seconds_export,
        output: written.files,
        output_bytes: written.bytes,
        cache,
        vat,
        environment: environment_report(params, frames),
        warnings: {
            let mut w = model.warnings.clone();
            w.extend(convergence_warning(frames, params.tolerance));
            w
        },
    }
}

/// "31 of 48 frames ended above the tolerance 0.05 (worst 3.2 at frame 7)", when any did.
pub fn convergence_warning(frames: &[StepStats], tolerance: f64) -> Option<String> {
    let above = frames.iter().filter(|f| !f.converged).count();
    if above == 0 {
        return None;
    }
    let (worst_frame, worst) = frames
        .iter()
        .enumerate()
        .map(|(i, f)| (i + 1, f.residual))
        .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
    let worst = if worst >= 0.01 {
        format!("{worst:.3}")
    } else {
        format!("{worst:.2e}")
    };
    Some(format!(
        "{above} of {} frames ended above the tolerance {tolerance} (worst {worst} at frame \
         {worst_frame}); raise --max-iterations or --substeps, or see unconverged_frames",
        frames.len()
    ))
}
