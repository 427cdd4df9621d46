//! A cloth bake from start to finish: load the body, build the model, simulate, export, report.
//!
//! [`ClothJob`] (in [`config`]) holds every parameter; [`bake_cloth`] runs it and returns a
//! [`ClothReport`] (in [`report`]) for the caller to write or print.

pub mod character;
pub mod config;
pub mod report;
pub mod sequence;

pub use config::{defaults, ClothJob, ClothPreset, ClothSource, Switch, UpAxis};
pub use report::*;

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;

use crate::cloth::collide::{
    Collider, Colliders, ContactModel, MeshCollider, DEFAULT_THICKNESS_FRACTION,
};
use crate::cloth::material::{fabric_model_terms, DEFAULT_JAM_STRAIN, DEFAULT_MATERIAL};
use crate::cloth::membrane::{membrane_triangles, MembraneModel};
use crate::cloth::model::{masses_from_area, masses_from_volume};
use crate::cloth::pins::pinned_flags;
use crate::cloth::preset::{self, lab_cloth};
use crate::cloth::springs::{surface_springs, volume_springs, SpringKind, SpringSet};
use crate::cloth::wind::{self, Wind};
use crate::cloth::{
    make_solver, simulate, BakeParams, ClothModel, LinearSolver, Simulation, SolverKind, StepStats,
};
use crate::cores::Threads;
use crate::error::{BasisProblem, Error, ForParam, Result};
use crate::export::basis::encode_basis_on;
use crate::export::character::{encode_character_gltf, CharacterHost};
use crate::export::meshopt::compress_files;
use crate::export::morph::{
    check_cache, encode_morph_gltf, encode_morph_gltf_with_body, AnimatedBody,
};
use crate::export::pointcache::{
    check_point_cache_path, encode_point_cache, PointCacheFormat, PointCacheOptions,
};
use crate::export::usd::{check_usd_path, encode_usd, UsdMesh, UsdOptions, UsdPoints};
use crate::export::vat::{encode_vat, vat_paths};
use crate::export::{BasisOptions, BasisSize, Compression, QuantizeMode};
use crate::export::{MorphOptions, RenderFrames, VatOptions, Written};
use crate::io::{collider, gltf_mesh::load_gltf_mesh, obj, tet::load_tet};
use crate::measure::FrameQuality;
use crate::mesh::Mesh;
use crate::param::{Param, Text};
use crate::spec::{non_negative, positive};
use crate::text;

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
        return Err(Error::param_value(Param::Frames, "0: must be at least 1"));
    }
    if job.substeps == 0 {
        return Err(Error::param_value(Param::Substeps, "0: must be at least 1"));
    }
    if job.iterations == 0 {
        return Err(Error::param_value(
            Param::Iterations,
            "0: must be at least 1",
        ));
    }
    if job.max_newton == 0 {
        return Err(Error::param_value(
            Param::MaxNewton,
            "0: must be at least 1",
        ));
    }
    positive(job.strain_limit).for_param(Param::StrainLimit)?;
    if job.threads == Some(0) {
        return Err(Error::param_value(Param::Threads, "0: must be at least 1"));
    }
    if job.max_iterations == Some(0) {
        return Err(Error::param_value(
            Param::MaxIterations,
            "0: must be at least 1",
        ));
    }
    if job.contact == Some(ContactModel::Barrier) && job.solver == SolverKind::Fast {
        return Err(Error::param_value(
            Param::Contact,
            "barrier: Newton's contact model; the fast solver keeps the cloth out with its \
             filtered solve (choose the newton solver, or leave the contact model out)",
        ));
    }
    if job.membrane == Some(MembraneModel::Triangles) && job.solver == SolverKind::Fast {
        return Err(Error::param_value(
            Param::Membrane,
            "triangles: the triangle membrane is part of Newton's solve; the fast solver has \
             springs only (choose the newton solver)",
        ));
    }
    if job.self_contact == Switch::On && job.solver == SolverKind::Fast {
        return Err(Error::param_value(
            Param::SelfContact,
            "on: self-contact is part of Newton's solve; the fast solver has none (choose the \
             newton solver)",
        ));
    }
    if job.linear_solver != LinearSolver::Auto && job.solver == SolverKind::Fast {
        return Err(Error::param_value(
            Param::LinearSolver,
            "how Newton solves for its directions; the fast solver has one prefactored matrix \
             (choose the newton solver, or leave the linear solver out)",
        ));
    }
    if job.mass.is_some() && job.density.is_some() {
        return Err(Error::param_value(
            Param::Mass,
            text!(
                "give either ",
                Param::Mass,
                " (kg per particle) or ",
                Param::Density,
                ", not both"
            ),
        ));
    }
    let source = job.source()?;
    let is_preset = matches!(source, ClothSource::LabCloth { .. });
    let springs_option = [
        (Param::Stiffness, job.stiffness.is_some()),
        (Param::BendStiffness, job.bend_stiffness.is_some()),
    ]
    .into_iter()
    .find_map(|(name, given)| given.then_some(name));
    let material_option = [
        (Param::Material, job.material.is_some()),
        (Param::Stretch, job.stretch.is_some()),
        (Param::Bend, job.bend.is_some()),
        (Param::Compression, job.compression.is_some()),
        (Param::JamStrain, job.jam_strain.is_some()),
        (Param::BendRest, job.bend_rest.is_some()),
        (Param::Membrane, job.membrane.is_some()),
    ]
    .into_iter()
    .find_map(|(name, given)| given.then_some(name));
    if let (Some(springs), Some(material)) = (springs_option, material_option) {
        return Err(Error::param_value(
            material,
            text!(
                springs,
                " sets the labs' symmetric springs (N/m per spring); ",
                material,
                " sets a fabric mapped onto the mesh: give one or the other"
            ),
        ));
    }
    if is_preset {
        if let Some(material) = material_option {
            return Err(Error::param_value(
                material,
                text!(
                    "the lab-cloth preset uses the labs' springs; use ",
                    Param::Stiffness,
                    " and ",
                    Param::BendStiffness
                ),
            ));
        }
    }
    // The labs' spring model: the preset, `--stiffness`/`--bend-stiffness`, and volumes.
    let stiffness = positive(job.stiffness.unwrap_or(if is_preset {
        preset::defaults::STIFFNESS
    } else {
        defaults::STIFFNESS
    }))
    .for_param(Param::Stiffness)?;
    let bend_stiffness = non_negative(job.bend_stiffness.unwrap_or(if is_preset {
        stiffness
    } else {
        defaults::BEND_STIFFNESS
    }))
    .for_param(Param::BendStiffness)?;
    let material = resolve_material(job)?;
    let damping = non_negative(job.damping.unwrap_or(if is_preset {
        preset::defaults::DAMPING
    } else {
        defaults::DAMPING
    }))
    .for_param(Param::Damping)?;
    let fps = positive(job.fps.unwrap_or(if is_preset {
        preset::defaults::FPS
    } else {
        defaults::FPS
    }))
    .for_param(Param::Fps)?;
    let gravity = job.gravity.unwrap_or(DVec3::from_array(if is_preset {
        preset::defaults::GRAVITY
    } else {
        defaults::GRAVITY
    }));
    if let Some(m) = job.mass {
        positive(m).for_param(Param::Mass)?;
    }
    if let Some(d) = job.density {
        positive(d).for_param(Param::Density)?;
    }
    check_export_options(job)?;

    // Set where the body takes the fabric model (a surface file without --stiffness).
    let (mut bending, mut uses_material) = (Vec::new(), false);
    let (mut membrane, mut membrane_warning) = (Vec::new(), None);
    let mut merged_objects = None;
    let (mesh, springs, mut pinned): (Mesh, SpringSet, Vec<bool>) = match &source {
        ClothSource::LabCloth { resolution } => {
            if let Some(option) = [
                (Param::Object, job.object.is_some()),
                (Param::Mesh, job.mesh.is_some()),
            ]
            .into_iter()
            .find_map(|(o, given)| given.then_some(o))
            {
                return Err(Error::param_value(
                    option,
                    "picks part of an input file; the lab-cloth preset has none",
                ));
            }
            if job.scale != 1.0 || job.translate.is_some() || job.up_z() {
                let option = if job.scale != 1.0 {
                    Param::Scale
                } else if job.up_z() {
                    Param::Up
                } else {
                    Param::Translate
                };
                return Err(Error::param_value(
                    option,
                    "places an input file; the lab-cloth preset keeps the labs' coordinates",
                ));
            }
            if *resolution == 0 || *resolution > 2000 {
                return Err(Error::param_value(
                    Param::Resolution,
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
            let pinned = if job.pin.is_empty() {
                lab.pinned_flags()
            } else {
                vec![false; lab.mesh.particle_count()]
            };
            (lab.mesh, lab.springs, pinned)
        }
        ClothSource::File(path) => {
            let mut mesh = load_body(path, job)?;
            place(&mut mesh, job)?;
            merged_objects = merged_objects_warning(path, &mesh, job);
            if !mesh.tets.is_empty() {
                if let Some(option) = material_option {
                    return Err(Error::param_value(
                        option,
                        text!(
                            "fabric materials apply to surfaces; a .tet volume uses ",
                            Param::Stiffness
                        ),
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
                if job.membrane == Some(MembraneModel::Triangles) {
                    let (triangles, skipped) = membrane_triangles(&mesh, &material.material);
                    membrane = triangles;
                    if skipped > 0 {
                        membrane_warning = Some(text!(format!(
                            "{skipped} triangles of zero area carry no membrane"
                        )));
                    }
                    SpringSet {
                        jam_strain: terms.springs.jam_strain,
                        skipped_zero_length: terms.springs.skipped_zero_length,
                        ..SpringSet::default()
                    }
                } else {
                    terms.springs
                }
            };
            let n = mesh.particle_count();
            (mesh, springs, vec![false; n])
        }
    };
    let material = uses_material.then_some(material);
    let size_warning = check_frames(
        frames,
        mesh.render_vertices.len(),
        job.normals == Switch::On,
    )?;
    for (flag, extra) in pinned
        .iter_mut()
        .zip(pinned_flags(&mesh, &job.pin).for_param(Param::Pin)?)
    {
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
    let mut model = ClothModel::new(mesh, springs, mass, pinned)?
        .with_bending(bending)?
        .with_membrane(membrane)?;
    model.warnings.extend(membrane_warning);
    model.warnings.extend(merged_objects);
    if matches!(source, ClothSource::File(_)) {
        model
            .warnings
            .extend(implausible_size_warning(&model.mesh, job.scale));
    }
    model.warnings.extend(size_warning);
    let colliders = prepare_colliders(job, &model)?;
    let wind = prepare_wind(job)?;
    let params = BakeParams {
        frames,
        fps,
        substeps: job.substeps,
        splits: job.splits,
        damping,
        gravity,
        solver: job.solver,
        iterations: job.max_iterations.unwrap_or(job.iterations),
        tolerance: non_negative(job.tolerance).for_param(Param::Tolerance)?,
        max_newton: job.max_iterations.unwrap_or(job.max_newton),
        // The sweeps do not see the cloth's pairs: cut where they would pass through, their
        // passes leave pairs at the bottom of their barriers, and Newton stalls there (the draped
        // dress on its mannequin: 200 iterations and ρ 1,296 at its second step with sweeps,
        // 32 and ρ 0.05 without).
        sweeps: job.sweeps.unwrap_or(match job.self_contact {
            Switch::On => 0,
            Switch::Off => crate::cloth::newton::DEFAULT_SWEEPS,
        }),
        linear_solver: job.linear_solver,
        threads: match (job.threads, &job.share) {
            (Some(n), _) => Threads::Fixed(n),
            (None, Some(share)) => Threads::Shared(share.clone()),
            (None, None) => Threads::Fixed(crate::cores::available()),
        },
        self_contact: match job.self_contact {
            Switch::On => Some(match job.self_thickness {
                Some(t) => positive(t).for_param(Param::SelfThickness)?,
                None => colliders.thickness,
            }),
            Switch::Off => None,
        },
        colliders,
        wind,
        measure_from: 0,
        loop_closure: None,
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

/// The smallest and largest diagonal (of the bounding box, metres) a cloth may plausibly have.
pub const PLAUSIBLE_DIAGONAL: (f64, f64) = (0.01, 100.0);

/// A length in metres in the unit that reads best: `1.7 m`, `35.2 cm`, `0.40 mm`.
pub fn length_words(metres: f64) -> String {
    if metres >= 1.0 {
        format!("{metres:.2} m")
    } else if metres >= 0.01 {
        format!("{:.1} cm", metres * 1e2)
    } else {
        format!("{:.2} mm", metres * 1e3)
    }
}

/// `value` times 10^`power`, written with at most six significant digits: `0.01`, `1000`,
/// `0.0254` (a scale to suggest).
pub fn scaled_words(value: f64, power: i32) -> String {
    let ten = 10f64.powi(power.abs());
    let x = if power >= 0 { value * ten } else { value / ten };
    if !(x.is_finite() && x != 0.0) {
        return x.to_string();
    }
    let decimals = (5 - x.abs().log10().floor() as i32).clamp(0, 17) as usize;
    let text = format!("{x:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        text
    }
}

/// A warning for a cloth whose bounding-box diagonal is outside [`PLAUSIBLE_DIAGONAL`]: most often
/// an input in centimetres or millimetres read as metres.
fn implausible_size_warning(mesh: &Mesh, scale: f64) -> Option<Text> {
    let (lo, hi) = mesh.bounds();
    let diagonal = (hi - lo).length();
    let (min, max) = PLAUSIBLE_DIAGONAL;
    if diagonal <= 0.0 || (min..=max).contains(&diagonal) {
        return None;
    }
    // The power of ten that brings the diagonal nearest 1 m.
    let power = -diagonal.log10().round() as i32;
    Some(text!(
        format!(
            "the cloth is {} across (its bounding box's diagonal{}), not a plausible size in \
             metres ({min} to {max} m); if the input is in other units, ",
            length_words(diagonal),
            if scale == 1.0 {
                String::new()
            } else {
                format!(", scaled by {scale}")
            },
        ),
        Param::Scale,
        format!(
            " {} makes it {}",
            scaled_words(scale, power),
            length_words(diagonal * 10f64.powi(power))
        )
    ))
}

/// "FILE holds 2 objects (Plane, Torus), merged into one body; `object` NAME bakes one of them",
/// for an OBJ of several objects read whole (a scene exported with every object selected).
fn merged_objects_warning(path: &Path, mesh: &Mesh, job: &ClothJob) -> Option<Text> {
    const LISTED: usize = 6;
    let n = mesh.objects.len();
    if job.object.is_some() || n < 2 {
        return None;
    }
    let mut names = mesh.objects[..n.min(LISTED)].join(", ");
    if n > LISTED {
        names += &format!(" and {} more", n - LISTED);
    }
    Some(text!(
        format!(
            "{} holds {n} objects ({names}), merged into one body; ",
            path.display()
        ),
        Param::Object,
        " NAME bakes one of them"
    ))
}

/// `--material` with the `--stretch`, `--bend`, `--compression`, `--jam-strain` and `--density`
/// overrides.
fn resolve_material(job: &ClothJob) -> Result<MaterialReport> {
    let preset = job.material.unwrap_or(DEFAULT_MATERIAL);
    let mut m = preset.material();
    if let Some(v) = job.stretch {
        m.stretch = positive(v).for_param(Param::Stretch)?;
    }
    if let Some(v) = job.bend {
        m.bend = non_negative(v).for_param(Param::Bend)?;
    }
    if let Some(v) = job.compression {
        if !(0.0..=1.0).contains(&v) {
            return Err(Error::param_value(
                Param::Compression,
                format!("{v}: must be between 0 and 1 (a fraction of the tension stiffness)"),
            ));
        }
        m.compression = v;
    }
    if let Some(v) = job.jam_strain {
        if !(v > 0.0 && v < 1.0) {
            return Err(Error::param_value(
                Param::JamStrain,
                format!(
                    "{v}: must be between 0 and 1, exclusive (a compression strain, a fraction \
                     of an edge's rest length: the default {DEFAULT_JAM_STRAIN} is {} %)",
                    DEFAULT_JAM_STRAIN * 100.0
                ),
            ));
        }
        m.jam_strain = v;
    }
    if let Some(r) = job.bend_rest {
        m.bend_rest = r;
    }
    if let Some(d) = job.density {
        m.density = positive(d).for_param(Param::Density)?;
    }
    Ok(MaterialReport {
        preset,
        material: m,
    })
}

/// Applies `--up`, `--scale` and `--translate` to a loaded body.
fn place(mesh: &mut Mesh, job: &ClothJob) -> Result<()> {
    let scale = positive(job.scale).for_param(Param::Scale)?;
    let translate = job.translate.unwrap_or(DVec3::ZERO);
    if !translate.is_finite() {
        return Err(Error::param_value(Param::Translate, "must be finite"));
    }
    if job.up_z() {
        for p in &mut mesh.positions {
            *p = DVec3::new(p.x, p.z, -p.y);
        }
    }
    if scale != 1.0 || translate != DVec3::ZERO {
        for p in &mut mesh.positions {
            *p = *p * scale + translate;
        }
    }
    Ok(())
}

/// Loads the colliders and resolves `--thickness` and `--friction`.
fn prepare_colliders(job: &ClothJob, model: &ClothModel) -> Result<Colliders> {
    let shapes = job
        .collider
        .iter()
        .map(|spec| {
            // The loader's and the specification's value errors are the collider's.
            Collider::from_spec(spec, &|path, part| {
                let mut mesh = collider::load_collider_mesh(path, part)?;
                // A collider file comes from the same tool as the input: turned by --up too
                // (not placed by --scale/--translate: colliders are in the scene's coordinates).
                if job.up_z() {
                    for p in &mut mesh.positions {
                        *p = DVec3::new(p.x, p.z, -p.y);
                    }
                }
                MeshCollider::from_mesh(path, mesh.positions, mesh.triangles)
            })
            .for_param(Param::Collider)
        })
        .collect::<Result<Vec<_>>>()?;
    let thickness = match job.thickness {
        Some(t) => positive(t).for_param(Param::Thickness)?,
        None => DEFAULT_THICKNESS_FRACTION * mean_edge_length(model),
    };
    Ok(Colliders {
        shapes,
        thickness,
        friction: non_negative(job.friction).for_param(Param::Friction)?,
        // The fast solver's filtered solve holds particles at the thickness, as the constraint
        // does: the report says so.
        model: match job.solver {
            SolverKind::Fast => ContactModel::Constraint,
            SolverKind::Newton => job.contact.unwrap_or_default(),
        },
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
            return Err(Error::param_value(
                Param::Turbulence,
                text!("gusts need a mean wind: give ", Param::Wind, " X,Y,Z too"),
            ));
        }
        return Ok(None);
    }
    Ok(Some(Wind {
        velocity: job.wind.unwrap_or(DVec3::ZERO),
        drag: non_negative(job.drag.unwrap_or(wind::DEFAULT_DRAG)).for_param(Param::Drag)?,
        lift: non_negative(job.lift.unwrap_or(wind::DEFAULT_LIFT)).for_param(Param::Lift)?,
        turbulence: non_negative(job.turbulence).for_param(Param::Turbulence)?,
        seed: job.seed,
    }))
}

/// Checks the export options that need no mesh, once, before anything is simulated:
/// `--keyframe-tolerance`, `--basis-tolerance`, `--max-targets` (and that it allows a fixed
/// `--basis`), `--quantize`, `--vat`, `--vat-max-width`, `--pc2`, `--mdd` and `--usd`. The
/// writers take these values as checked.
///
/// # Errors
/// [`Error::Param`] naming the option.
pub fn check_export_options(job: &ClothJob) -> Result<()> {
    if let Some(t) = job.keyframe_tolerance {
        non_negative(t).for_param(Param::KeyframeTolerance)?;
    }
    if let Some(m) = job.basis_tolerance {
        non_negative(m).for_param(Param::BasisTolerance)?;
    }
    if job.max_targets == Some(0) {
        return Err(Error::param_value(
            Param::MaxTargets,
            "0: must be at least 1",
        ));
    }
    if let (Some(BasisSize::Fixed(k)), Some(n)) = (job.basis, job.max_targets) {
        if k > n {
            return Err(Error::param_value(
                Param::MaxTargets,
                text!(
                    format!("{n}: fewer than the {k} targets "),
                    Param::Basis,
                    " asks for"
                ),
            ));
        }
    }
    if job.basis.is_none() {
        if job.basis_tolerance.is_some() {
            return Err(Error::param_value(
                Param::BasisTolerance,
                text!(
                    "applies to a morph basis: give ",
                    Param::Basis,
                    " K or ",
                    Param::Basis,
                    " auto too"
                ),
            ));
        }
        if job.quantize == Some(QuantizeMode::On) {
            return Err(Error::param_value(
                Param::Quantize,
                text!(
                    "on: quantisation is written for a morph basis: give ",
                    Param::Basis,
                    " K or ",
                    Param::Basis,
                    " auto too"
                ),
            ));
        }
    }
    if let Some(path) = &job.vat {
        vat_paths(path).for_param(Param::Vat)?;
    }
    check_point_cache_options(job)?;
    if job.vat_max_width == 0 {
        return Err(Error::param_value(
            Param::VatMaxWidth,
            "0: must be at least 1 pixel",
        ));
    }
    Ok(())
}

/// `--pc2`, `--mdd` and `--usd`: each a file that can be written (a `.usda` for `--usd`), and no
/// file of the job written twice (a cache on the output, its `.bin`, the report, the VAT's files
/// or another cache).
fn check_point_cache_options(job: &ClothJob) -> Result<()> {
    let caches = [
        (Param::Pc2, &job.pc2),
        (Param::Mdd, &job.mdd),
        (Param::Usd, &job.usd),
    ];
    if caches.iter().all(|(_, p)| p.is_none()) {
        return Ok(());
    }
    let mut others: Vec<(Param, PathBuf)> = vec![(Param::Output, job.output.clone())];
    if job
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf"))
    {
        let stem = job.output.file_stem().unwrap_or_default();
        let bin = job
            .output
            .with_file_name(format!("{}.bin", stem.to_string_lossy()));
        others.push((Param::Output, bin));
    }
    if let Some(r) = &job.report {
        others.push((Param::Report, r.clone()));
    }
    if let Some(v) = &job.vat {
        others.push((Param::Vat, v.clone()));
        if let Ok((normals, json)) = vat_paths(v) {
            others.extend([(Param::Vat, normals), (Param::Vat, json)]);
        }
    }
    for (param, path) in caches {
        let Some(path) = path else { continue };
        match param {
            Param::Usd => check_usd_path(path),
            _ => check_point_cache_path(path),
        }
        .for_param(param)?;
        let key = same_file_key(path);
        if let Some((other, other_path)) = others.iter().find(|(_, o)| same_file_key(o) == key) {
            return Err(Error::param_value(
                param,
                text!(
                    format!("{}: the same file as ", path.display()),
                    *other,
                    format!(
                        " ({}) writes: give the cache a file of its own",
                        other_path.display()
                    )
                ),
            ));
        }
        others.push((param, path.clone()));
    }
    Ok(())
}

/// A path made absolute and lexically normal, to tell whether two options name one file.
fn same_file_key(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for c in absolute.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    // A folder reached through a symbolic link is the same folder.
    match (out.parent(), out.file_name()) {
        (Some(dir), Some(name)) => match dir.canonicalize() {
            Ok(dir) => dir.join(name),
            Err(_) => out,
        },
        _ => out,
    }
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
        return Err(Error::param_value(
            Param::Mesh,
            text!(
                format!(
                    "picks a mesh of a .gltf/.glb input, and {} is not one (for an OBJ, ",
                    path.display()
                ),
                Param::Object,
                " NAME picks an object or group)"
            ),
        ));
    }
    if job.object.is_some() && ext.as_deref() != Some("obj") {
        return Err(Error::param_value(
            Param::Object,
            if gltf {
                text!(
                    format!("picks an object or group of an .obj input, and {} is not one (for a glTF, ", path.display()),
                    Param::Mesh,
                    " NAME picks a mesh)"
                )
            } else {
                text!(format!(
                    "picks an object or group of an .obj input, and {} is not one",
                    path.display()
                ))
            },
        ));
    }
    match ext.as_deref() {
        Some("obj") => obj::load_obj(
            path,
            &obj::ObjOptions {
                object: job.object.clone(),
            },
        )
        .for_param(Param::Object),
        Some("gltf") | Some("glb") => {
            load_gltf_mesh(path, job.mesh.as_deref()).for_param(Param::Mesh)
        }
        Some("tet") => load_tet(path),
        _ => Err(Error::invalid(
            path,
            "unknown mesh format: expected .obj, .gltf, .glb or .tet",
        )),
    }
}

/// The output-size warning [`prepare_cloth`] also gives (a dense cache over 1 GiB), computed
/// before anything is simulated so that a front end can show it before a long bake; it loads the
/// input once more. `None` below the threshold, and when the input or the preset's resolution is
/// invalid ([`prepare_cloth`] reports those).
///
/// # Errors
/// [`Error::Param`] naming `--frames` when the cache would not fit in a GLB, as [`prepare_cloth`].
pub fn output_size_warning(job: &ClothJob) -> Result<Option<Text>> {
    let frames = job.frames.unwrap_or(defaults::FRAMES).max(1);
    let vertices = match job.source() {
        Ok(ClothSource::LabCloth { resolution }) if (1..=2000).contains(&resolution) => {
            (resolution as usize + 1).pow(2)
        }
        Ok(ClothSource::File(path)) => match load_body(&path, job) {
            Ok(mesh) => mesh.render_vertices.len(),
            Err(_) => return Ok(None),
        },
        _ => return Ok(None),
    };
    check_frames(frames, vertices, job.normals == Switch::On)
}

/// Checks a cloth bake of `frames` frames after the initial state over `vertices` render
/// vertices ([`crate::export::estimate`]): an error naming `--frames` when the cache would not
/// fit in a GLB, a warning (returned) when it is large.
///
/// # Errors
/// [`Error::Param`] naming `--frames`.
fn check_frames(frames: usize, vertices: usize, normals: bool) -> Result<Option<Text>> {
    use crate::export::estimate::{cache_size, human, CacheSize};
    match cache_size(frames, vertices, normals) {
        CacheSize::Fits => Ok(None),
        CacheSize::Large { bytes } => Ok(Some(text!(
            format!(
                "the output will be about {} ({frames} frames of {vertices} vertices); ",
                human(bytes)
            ),
            Param::KeyframeTolerance,
            " can shrink it"
        ))),
        CacheSize::TooLarge { bytes, most_frames } => Err(Error::param_value(
            Param::Frames,
            text!(
                format!(
                    "{frames}: {frames} frames of {vertices} vertices need about {} in memory and \
                     in the output, over the 4.3 GB a GLB can hold; at most {most_frames} frames \
                     fit (",
                    human(bytes),
                ),
                Param::KeyframeTolerance,
                " shrinks the file, not the bake)"
            ),
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
    let simulation = simulate(model, solver.as_mut(), params, &mut |f| progress(f, frames))
        .map_err(|e| advised(e, params.solver))?;
    Ok(SimulatedCloth {
        prepared,
        simulation,
    })
}

/// Runs a whole bake: prepare, simulate (calling `progress(frame, frames)`), export, report.
///
/// # Errors
/// An output that cannot be written ([`super::outputs::check_writable`]) before anything else;
/// as [`prepare_cloth`]; [`Error::Diverged`] when the simulation blows up (nothing is written);
/// write errors.
pub fn bake_cloth(job: &ClothJob, progress: &mut dyn FnMut(usize, usize)) -> Result<ClothReport> {
    super::outputs::check_writable(&super::outputs::cloth_outputs(job))?;
    if job.body.is_some() {
        return sequence::bake_on_sequence(job, progress);
    }
    if let Some(param) = [
        (Param::BodyFps, job.body_fps.is_some()),
        (Param::BodyStart, job.body_start.is_some()),
    ]
    .into_iter()
    .find_map(|(p, given)| given.then_some(p))
    {
        return Err(Error::param_value(
            param,
            text!("applies to a body sequence: give ", Param::Body, " too"),
        ));
    }
    if job.rig.is_some() {
        return character::bake_on_character(job, progress);
    }
    let SimulatedCloth {
        prepared,
        simulation: sim,
    } = simulate_cloth(job, progress)?;
    let PreparedCloth { model, params, .. } = &prepared;

    let export_start = Instant::now();
    let name = job.display_name();
    let options = MorphOptions {
        fps: params.fps,
        interpolation: job.interpolation,
        name,
        normals: job.normals == Switch::On,
        keyframe_tolerance: job.keyframe_tolerance,
        sparse: job.sparse,
        static_meshes: collider_meshes(model, &params.colliders),
        start_time: 0.0,
    };
    let exported = export(job, model, &sim.cache, options, Host::Alone(None))?;
    let seconds_export = export_start.elapsed().as_secs_f64();
    let quality = quality_report(&sim, job.strain_limit);
    Ok(report(
        &prepared,
        job,
        &sim.frames,
        quality,
        sim.seconds,
        seconds_export,
        exported,
    ))
}

/// Simulates `prepared` driven by `drive` (a character or a body sequence): its pins ride the
/// drive and, when `collide`, its body joins the colliders as a moving mesh. Returns the
/// simulation and the body's triangle count (0 when it does not collide).
pub(crate) fn simulate_on_body(
    prepared: &mut PreparedCloth,
    drive: &dyn crate::cloth::drive::Drive,
    collide: bool,
    progress: &mut dyn FnMut(usize),
) -> Result<(Simulation, usize)> {
    let PreparedCloth { model, params, .. } = prepared;
    let mut body_triangles = 0;
    let body_shape = match (collide, drive.rest_body()?) {
        (true, Some(body)) => {
            body_triangles = body.triangles().len();
            params
                .colliders
                .shapes
                .push(Collider::Mesh(std::sync::Arc::new(body)));
            Some(params.colliders.shapes.len() - 1)
        }
        _ => None,
    };
    let mut solver = crate::cloth::make_driven_solver(model, params, body_shape)?;
    let sim = crate::cloth::simulate_driven(
        model,
        solver.as_mut(),
        params,
        Some(crate::cloth::Driven { drive, body_shape }),
        progress,
    )
    .map_err(|e| advised(e, params.solver))?;
    Ok((sim, body_triangles))
}

/// `e` with the options that could help a diverging `solver`: a shorter time step for both (for
/// Newton also where its steps fail: more splits), more iterations for the local/global method
/// (Newton stops on its residual, flagging a step it could not converge, rather than diverging
/// for want of iterations).
fn advised(e: Error, solver: SolverKind) -> Error {
    match e {
        Error::Diverged { frame, reason, .. } => Error::Diverged {
            frame,
            reason,
            advice: match solver {
                SolverKind::Newton => vec![Param::Substeps, Param::Splits, Param::Fps],
                SolverKind::Fast => vec![Param::Substeps, Param::Fps, Param::Iterations],
            },
        },
        e => e,
    }
}

/// The quality section of the measured frames of `sim`, its written ones: from frame
/// `sim.measured_from`, the output's frame 0 (flagged only when simulated, a character's first
/// written frame).
pub(crate) fn quality_report(sim: &Simulation, strain_limit: f64) -> QualityReport {
    let (q, first) = (&sim.quality[..], sim.measured_from);
    let flagged = |past: &dyn Fn(&FrameQuality) -> bool| -> Vec<usize> {
        q.iter()
            .enumerate()
            .filter(|&(i, f)| (i > 0 || first > 0) && past(f))
            .map(|(i, _)| i)
            .collect()
    };
    QualityReport {
        strain_limit,
        max_strain: q.iter().map(|f| f.max_strain).collect(),
        min_strain: q.iter().map(|f| f.min_strain).collect(),
        self_crossings: q.iter().map(|f| f.self_crossings).collect(),
        body_crossings: q.iter().map(|f| f.body_crossings).collect(),
        overstrained_frames: flagged(&|f| f.max_strain > strain_limit),
        intersecting_frames: flagged(&|f| f.self_crossings + f.body_crossings > 0),
        seconds: sim.seconds_measure,
    }
}

/// The warnings of a quality section: frames past the strain limit, frames with crossings.
fn quality_warnings(q: &QualityReport, self_contact: bool) -> Vec<Text> {
    let mut out = Vec::new();
    let written = q.max_strain.len();
    if let Some(&worst) = q
        .overstrained_frames
        .iter()
        .max_by(|&&a, &&b| q.max_strain[a].total_cmp(&q.max_strain[b]))
    {
        out.push(text!(
            format!(
                "{} of {written} written frames stretch an edge past the strain limit {} % \
                 (worst {:.1} % at frame {worst}); see \
                 quality.overstrained_frames, or raise ",
                q.overstrained_frames.len(),
                q.strain_limit * 100.0,
                q.max_strain[worst] * 100.0,
            ),
            Param::StrainLimit
        ));
    }
    if !q.intersecting_frames.is_empty() {
        let most = |v: &[usize]| {
            q.intersecting_frames
                .iter()
                .map(|&i| (v[i], i))
                .max_by_key(|&(n, i)| (n, std::cmp::Reverse(i)))
                .unwrap_or((0, 0))
        };
        let (own, own_at) = most(&q.self_crossings);
        let (body, body_at) = most(&q.body_crossings);
        let mut worst = Vec::new();
        if own > 0 {
            worst.push(format!(
                "{own} pairs of the cloth with itself at frame {own_at}"
            ));
        }
        if body > 0 {
            worst.push(format!("{body} with a body at frame {body_at}"));
        }
        let head = format!(
            "{} of {written} written frames have crossing triangles (at most {}; frame 0 has {} \
             and {}); ",
            q.intersecting_frames.len(),
            worst.join(", "),
            q.self_crossings[0],
            q.body_crossings[0],
        );
        let tail = ": see quality.intersecting_frames";
        out.push(if own == 0 {
            text!(head, "particles, not triangles, are kept off bodies", tail)
        } else if self_contact {
            // Self-contact adds no crossing in a step: these were in the input, or made by a
            // collider pushing the cloth out of itself.
            text!(
                head,
                "with ",
                Param::SelfContact,
                " on, the input's crossings are kept and a collider the cloth starts in may push \
                 it through itself",
                tail
            )
        } else {
            text!(
                head,
                "the cloth does not collide with itself (",
                Param::SelfContact,
                " on keeps it off)",
                tail
            )
        });
    }
    out
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
    point_caches: Vec<PointCacheReport>,
    usd: Option<UsdReport>,
}

/// A file to write, as (path, bytes).
type File = (PathBuf, Vec<u8>);

/// Files to write.
type Files = Vec<File>;

/// Encodes the point caches `--pc2` and `--mdd` ask for: `cache`'s frames (frame 0 the initial
/// state, as the glTF's) of `mesh`, frame k at `start_time + k / fps` seconds.
fn encode_point_caches(
    job: &ClothJob,
    mesh: &Mesh,
    cache: &crate::cloth::FrameCache,
    fps: f64,
    start_time: f64,
) -> Result<(Files, Vec<PointCacheReport>)> {
    let options = PointCacheOptions { fps, start_time };
    let mut files = Vec::new();
    let mut reports = Vec::new();
    for (format, path) in [
        (PointCacheFormat::Pc2, &job.pc2),
        (PointCacheFormat::Mdd, &job.mdd),
    ] {
        let Some(path) = path else { continue };
        let encoded = encode_point_cache(format, path, mesh, cache, &options)?;
        reports.push(PointCacheReport {
            format,
            file: encoded.path.clone(),
            bytes: encoded.bytes.len() as u64,
            points: encoded.points,
            frames: encoded.frames,
            fps,
        });
        files.push((encoded.path, encoded.bytes));
    }
    Ok((files, reports))
}

/// Encodes the vertex-animation texture `--vat` asks for, if any: every frame of `frames` (the
/// glTF's render vertices, in its vertex order; frame 0 keyed at `start_time` on the glTF's
/// animation, frame k at `start_time + k / fps`), its manifest naming the job's glTF.
fn encode_vat_files(
    job: &ClothJob,
    frames: &RenderFrames,
    fps: f64,
    start_time: f64,
) -> Result<(Files, Option<VatReport>)> {
    let Some(path) = &job.vat else {
        return Ok((Vec::new(), None));
    };
    let gltf = job
        .output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let options = VatOptions {
        mode: job.vat_mode,
        max_width: job.vat_max_width,
        fps,
        start_time,
        normals: job.normals == Switch::On,
        gltf,
    };
    let encoded = encode_vat(path, frames, &options).for_param(Param::Vat)?;
    let report = VatReport {
        files: encoded.files.iter().map(|(p, _)| p.clone()).collect(),
        bytes: encoded.files.iter().map(|(_, b)| b.len() as u64).sum(),
        manifest: encoded.manifest,
    };
    Ok((encoded.files, Some(report)))
}

/// Encodes the USD layer `--usd` asks for: the cloth (`cache`'s frames of `mesh`'s particles,
/// frame k at time code `start_time × fps + k`), the static meshes and the moving `bodies` (a
/// mesh sequence, a character's skinned meshes), each a mesh with time-sampled points.
fn encode_usd_layer(
    job: &ClothJob,
    mesh: &Mesh,
    cache: &crate::cloth::FrameCache,
    options: &MorphOptions,
    bodies: &[AnimatedBody<'_>],
) -> Result<Option<(File, UsdReport)>> {
    let Some(path) = &job.usd else {
        return Ok(None);
    };
    let frames = cache.frame_count();
    let (mut p64, mut scratch) = (Vec::new(), Vec::new());
    let (mut positions, mut normals) = (Vec::with_capacity(frames), Vec::with_capacity(frames));
    for k in 0..frames {
        let p = cache.frame(k);
        p64.clear();
        p64.extend(p.iter().map(|p| p.as_dvec3()));
        crate::export::shading::angle_weighted_normals(&p64, &mesh.triangles, &mut scratch);
        positions.push(p.to_vec());
        normals.push(scratch.iter().map(|n| n.as_vec3()).collect());
    }
    let mut meshes = vec![UsdMesh {
        name: options.name.clone(),
        triangles: mesh.triangles.clone(),
        points: UsdPoints::Animated { positions, normals },
        double_sided: true,
    }];
    meshes.extend(options.static_meshes.iter().map(|s| {
        UsdMesh {
            name: s.name.clone(),
            triangles: s
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
            points: UsdPoints::Static {
                positions: s.positions.clone(),
                normals: s.normals.clone(),
            },
            double_sided: false,
        }
    }));
    for body in bodies {
        let n = body.frames.frame_count();
        meshes.push(UsdMesh {
            name: body.name.to_owned(),
            triangles: body.mesh.render_triangles.clone(),
            points: UsdPoints::Animated {
                positions: (0..n).map(|k| body.frames.positions(k).to_vec()).collect(),
                normals: (0..n).map(|k| body.frames.normals(k).to_vec()).collect(),
            },
            double_sided: false,
        });
    }
    let usd_options = UsdOptions {
        fps: options.fps,
        start_time: options.start_time,
        frames,
    };
    let encoded = encode_usd(path, &meshes, &usd_options).for_param(Param::Usd)?;
    let report = UsdReport {
        file: encoded.path.clone(),
        bytes: encoded.bytes.len() as u64,
        prims: encoded.prims,
        frames,
        time_codes: encoded.time_codes,
        fps: options.fps,
    };
    Ok(Some(((encoded.path, encoded.bytes), report)))
}

/// The basis cache `--basis` asks for, if any.
fn basis_options(job: &ClothJob) -> Option<BasisOptions> {
    job.basis.map(|size| BasisOptions {
        size,
        tolerance: job
            .basis_tolerance
            .or(job.keyframe_tolerance)
            .unwrap_or(DEFAULT_BASIS_TOLERANCE),
        max_targets: job.max_targets,
        quantize: job.quantize.unwrap_or_default(),
    })
}

/// A basis writer's error in the job's words: what stands in the way of `--basis` named by the
/// option that can change it (`--basis`, `--max-targets` or `--basis-tolerance`).
fn basis_error(e: Error) -> Error {
    let Error::Basis { problem, .. } = e else {
        return e;
    };
    match problem {
        BasisProblem::TooFewFrames { targets, available } => Error::param_value(
            Param::Basis,
            format!("{targets} targets: the bake has only {available} frames after frame 0"),
        ),
        BasisProblem::ToleranceUnmet {
            tolerance,
            cap,
            best,
            best_error,
            max_targets,
        } => {
            let message = format!(
                "{tolerance} m cannot be met with at most {cap} targets (best: {best} targets, \
                 {best_error:.3e} m); raise it, or allow more targets"
            );
            match max_targets {
                Some(n) => Error::param_value(
                    Param::MaxTargets,
                    text!(
                        format!("{n}: "),
                        Param::BasisTolerance,
                        format!(" {message}")
                    ),
                ),
                None => Error::param_value(Param::BasisTolerance, message),
            }
        }
        BasisProblem::TooManyTargets { needed } => Error::param_value(
            Param::MaxTargets,
            format!("fewer than the {needed} targets the basis needs"),
        ),
    }
}

/// Refuses a per-frame morph cache of more targets than `--max-targets` allows, suggesting a
/// basis or a larger keyframe tolerance.
fn check_target_count(job: &ClothJob, targets: usize) -> Result<()> {
    match job.max_targets.filter(|&n| targets > n) {
        Some(n) => Err(Error::param_value(
            Param::MaxTargets,
            text!(
                format!("{n}: the cache needs {targets} targets (one per kept frame); use "),
                Param::Basis,
                " auto, or a larger ",
                Param::KeyframeTolerance
            ),
        )),
        None => Ok(()),
    }
}

/// The glTF's files after `--compress`: as encoded, or with EXT_meshopt_compression.
fn compress(
    job: &ClothJob,
    files: Vec<(std::path::PathBuf, Vec<u8>)>,
) -> Result<Vec<(std::path::PathBuf, Vec<u8>)>> {
    match job.compress {
        Compression::None => Ok(files),
        Compression::Meshopt => compress_files(&job.output, files),
    }
}

/// The glTF document a bake's cache is written into.
enum Host<'a> {
    /// The cloth's own document, with the body it moved on beside it (a mesh sequence), which
    /// the USD layer holds too.
    Alone(Option<&'a AnimatedBody<'a>>),
    /// A character's document with the garment added to it, or (`on` is `None`:
    /// `--garment-only`) the garment alone, keyed on the character's animation; `bodies` are
    /// its skinned meshes as the USD layer holds them.
    Character {
        on: Option<Box<CharacterHost<'a>>>,
        bodies: &'a [AnimatedBody<'a>],
    },
}

/// Writes a bake's every file through one pipeline, whatever its host: the glTF (a per-frame
/// morph cache or a morph basis, `--max-targets` held), compressed as asked, then the VAT, the
/// point caches and the USD layer (with the host's bodies beside the cloth), all in one atomic
/// set.
fn export(
    job: &ClothJob,
    model: &ClothModel,
    cache: &crate::cloth::FrameCache,
    options: MorphOptions,
    host: Host<'_>,
) -> Result<Exported> {
    check_cache(&job.output, &model.mesh, cache)?;
    let frames = RenderFrames::new(&model.mesh, cache);
    let (path, mesh) = (&job.output, &model.mesh);
    let usd_bodies = match &host {
        Host::Alone(body) => body.map_or(&[][..], std::slice::from_ref),
        Host::Character { bodies, .. } => *bodies,
    };
    let (morph, basis) = match (basis_options(job), host) {
        (Some(basis), host) => {
            let on = match host {
                Host::Character { on, .. } => on,
                Host::Alone(_) => None,
            };
            let e = encode_basis_on(path, mesh, &frames, &options, &basis, on.as_deref())
                .map_err(basis_error)?;
            (e.morph, Some(e.basis))
        }
        (None, Host::Alone(body)) => (
            encode_morph_gltf_with_body(path, mesh, &frames, &options, body.copied())?,
            None,
        ),
        (None, Host::Character { on: None, .. }) => {
            (encode_morph_gltf(path, mesh, &frames, &options)?, None)
        }
        (None, Host::Character { on: Some(host), .. }) => (
            encode_character_gltf(path, host.doc, mesh, &frames, &options, host.character)?,
            None,
        ),
    };
    if basis.is_none() {
        check_target_count(job, morph.stats.targets)?;
    }
    let mut files = compress(job, morph.files)?;
    let gltf_bytes = files.iter().map(|(_, b)| b.len() as u64).sum();
    // A character's VAT and point caches hold the written loops as the glTF's garment mesh
    // does (its object space, metres; the garment node scales them by 1 / --rig-scale), frame 0
    // at the animation's start (`options.start_time`).
    let (vat_files, vat) = encode_vat_files(job, &frames, options.fps, options.start_time)?;
    files.extend(vat_files);
    let (cache_files, point_caches) =
        encode_point_caches(job, mesh, cache, options.fps, options.start_time)?;
    files.extend(cache_files);
    let usd = match encode_usd_layer(job, mesh, cache, &options, usd_bodies)? {
        Some((file, report)) => {
            files.push(file);
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
        point_caches,
        usd,
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
        contact: c.model,
        contacts: frames.iter().map(|f| f.contacts).collect(),
        pinched: frames.iter().map(|f| f.pinched).collect(),
        pinched_pairs: frames.iter().map(|f| f.pinched_pairs).collect(),
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
    quality: QualityReport,
    seconds_simulate: f64,
    seconds_export: f64,
    exported: Exported,
) -> ClothReport {
    let Exported {
        written,
        cache,
        vat,
        point_caches,
        usd,
    } = exported;
    let PreparedCloth { model, params, .. } = prepared;
    let total_iterations: usize = frames.iter().map(|f| f.iterations).sum();
    ClothReport {
        input: match &job.source().unwrap_or(ClothSource::File(PathBuf::new())) {
            ClothSource::File(p) => p.display().to_string(),
            ClothSource::LabCloth { resolution } => format!("lab-cloth (resolution {resolution})"),
        },
        particles: model.particle_count(),
        springs: model.springs.len(),
        springs_by_kind: prepared.counts,
        membrane_triangles: model.membrane.len(),
        pinned: model.pinned_count(),
        triangles: model.mesh.render_triangles.len(),
        frames: params.frames,
        fps: params.fps,
        substeps: params.substeps,
        splits: match params.solver {
            SolverKind::Fast => 0,
            SolverKind::Newton => params.splits,
        },
        solver: params.solver,
        time_step: params.time_step(),
        tolerance: params.tolerance,
        max_iterations: match params.solver {
            SolverKind::Fast => params.iterations,
            SolverKind::Newton => params.max_newton,
        },
        sweeps: match params.solver {
            SolverKind::Fast => 0,
            SolverKind::Newton => params.sweeps,
        },
        threads: params.threads.most(),
        linear_solver: (params.solver == SolverKind::Newton).then(|| {
            let free = model.pinned.len() - model.pinned_count();
            params.linear_solver.resolve(free)
        }),
        material: prepared.material.clone(),
        stiffness: prepared.stiffness,
        bend_stiffness: prepared.bend_stiffness,
        damping: params.damping,
        gravity: params.gravity.to_array(),
        total_mass: model.mass.iter().sum(),
        iterations: frames.iter().map(|f| f.iterations).collect(),
        steps: frames.iter().map(|f| f.steps).collect(),
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
        point_caches,
        usd,
        environment: environment_report(params, frames),
        self_contact: params.self_contact.map(|thickness| SelfContactReport {
            thickness,
            pairs: frames.iter().map(|f| f.self_contacts).collect(),
        }),
        character: None,
        body: None,
        warnings: {
            let mut w = model.warnings.clone();
            w.extend(convergence_warning(frames, params.tolerance));
            w.extend(pinch_warning(frames));
            w.extend(pinched_pairs_warning(frames));
            w.extend(quality_warnings(&quality, params.self_contact.is_some()));
            w
        },
        quality,
    }
}

/// "a moving body pinched 23 particles behind its surface, in 11 frames (most 4 at frame 29):
/// …", when one did.
fn pinch_warning(frames: &[StepStats]) -> Option<Text> {
    let (pinched, in_frames, most, at) = per_frame(frames, |f| f.pinched)?;
    Some(text!(format!(
        "a moving body pinched {pinched} particles behind its surface, in {in_frames} frames \
         (most {most} at frame {at}): they were let through it until they came out; see \
         environment.pinched and quality.body_crossings"
    )))
}

/// "self-contact released 240 pairs of a body's vertex or edge with the cloth … in 22 frames
/// (most 44 at frame 90): …", when it did.
fn pinched_pairs_warning(frames: &[StepStats]) -> Option<Text> {
    let (pinched, in_frames, most, at) = per_frame(frames, |f| f.pinched_pairs)?;
    Some(text!(format!(
        "self-contact released {pinched} pairs of a body's vertex or edge with the cloth, pressed \
         to the bottom of their layer where the body closed on the cloth, in {in_frames} frames \
         (most {most} at frame {at}): the body was let through the cloth there; see \
         environment.pinched_pairs and quality.body_crossings"
    )))
}

/// A count over the frames: its sum, the frames where it is not zero, its largest value and the
/// first frame (from 1) with it; `None` when it is zero everywhere.
fn per_frame(
    frames: &[StepStats],
    count: impl Fn(&StepStats) -> usize,
) -> Option<(usize, usize, usize, usize)> {
    let sum: usize = frames.iter().map(&count).sum();
    if sum == 0 {
        return None;
    }
    let (most, at) = frames
        .iter()
        .enumerate()
        .map(|(i, f)| (count(f), i + 1))
        .fold((0, 0), |a, b| if b.0 > a.0 { b } else { a });
    let in_frames = frames.iter().filter(|f| count(f) > 0).count();
    Some((sum, in_frames, most, at))
}

/// "31 of 48 frames ended above the tolerance 0.05 (worst 3.2 at frame 7)", when any did.
pub fn convergence_warning(frames: &[StepStats], tolerance: f64) -> Option<Text> {
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
    Some(text!(
        format!(
            "{above} of {} frames ended above the tolerance {tolerance} (worst {worst} at frame \
             {worst_frame}); raise ",
            frames.len()
        ),
        Param::MaxIterations,
        " or ",
        Param::Substeps,
        ", or see unconverged_frames"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flag(p: Param) -> String {
        format!("--{}", p.key().replace('_', "-"))
    }

    #[test]
    fn frames_past_a_glb_are_refused_naming_frames() {
        // 961 vertices with normals: 23,064 bytes a frame; 186,217 frames fit in 4 GiB.
        let fit = (u32::MAX as u64 / 23_064) as usize;
        assert!(check_frames(fit - 1, 961, true).is_ok());
        let e = check_frames(fit, 961, true).unwrap_err().to_string();
        assert!(e.starts_with("invalid value for `frames`: "), "{e}");
        assert!(
            e.contains(&format!("at most {} frames fit", fit - 1)),
            "{e}"
        );
        assert!(check_frames(1_000_000_000, 961, true).is_err());
        assert_eq!(check_frames(120, 961, true).unwrap(), None);
        assert!(check_frames(50_000, 961, true).unwrap().is_some());
    }

    /// The trial run's trap: `--frames 20000` on an 8k-vertex skirt wrote gigabytes silently.
    #[test]
    fn twenty_thousand_frames_of_a_skirt_warn_with_the_size() {
        let warning = check_frames(20_000, 8121, true).unwrap().unwrap();
        assert_eq!(
            warning.render(&flag),
            "the output will be about 3.9 GB (20000 frames of 8121 vertices); \
             --keyframe-tolerance can shrink it"
        );
    }
}
