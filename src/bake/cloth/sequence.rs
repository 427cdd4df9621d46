//! A garment baked on a body given as a mesh sequence (`--body PATTERN --body-fps F`): every
//! frame is read and checked first ([`crate::io::sequence`]), the body moves as a collider
//! ([`crate::cloth::drive::SequenceDrive`], linear between its frames), and the output holds the
//! body beside the garment, morph-animated on the same frames
//! ([`crate::export::morph::encode_morph_gltf_with_body`]).
//!
//! The bake runs at `--fps` (default: the body's rate) for the sequence's duration (`--frames`
//! may shorten it). The body is used as it is; `--translate`, `--scale` and `--up` place the
//! garment.

use std::time::Instant;

use super::{
    collider_meshes, export, prepare_cloth, quality_report, report, simulate_on_body, BodyReport,
    ClothJob, ClothReport, Host, PreparedCloth, Switch,
};
use crate::cloth::drive::SequenceDrive;
use crate::cloth::{FrameCache, SolverKind};
use crate::error::{Error, ForParam, Result};
use crate::export::{AnimatedBody, MorphOptions, RenderFrames};
use crate::io::sequence::{load_gltf_sequence, load_obj_sequence};
use crate::param::Param;
use crate::spec::positive;
use crate::spec::split_mesh_part;
use crate::text;

/// A glTF body sequence's errors in the job's words: the options that answer them.
fn sequence_error(e: Error) -> Error {
    match e {
        Error::NoMorphAnimation { path, part } => Error::param_value(
            Param::Body,
            text!(
                format!(
                    "`{}`: no mesh{} animated by morph-target weights (a skinned character is \
                     given with ",
                    path.display(),
                    part.map_or_else(String::new, |p| format!(" named `{p}`"))
                ),
                Param::Rig,
                ")"
            ),
        ),
        Error::UnknownRate { path } => Error::param_value(
            Param::BodyFps,
            format!(
                "missing: the keys of `{}` are not evenly spaced; give the rate to sample the \
                 body at",
                path.display()
            ),
        ),
        e => e,
    }
}

/// Runs a `--body` bake: check the options, read the sequence, simulate, export, report.
///
/// # Errors
/// Option errors (`--body-fps` missing or not positive, a solver other than Newton, `--rig`,
/// `--basis`, `--frames` longer than the sequence), the sequence's errors (pattern, missing
/// frame, a frame whose vertices or faces differ, naming the file), and those of
/// [`super::bake_cloth`].
pub fn bake_on_sequence(
    job: &ClothJob,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ClothReport> {
    let pattern = job.body.clone().expect("called for --body jobs");
    if job.rig.is_some() {
        return Err(Error::param_value(
            Param::Body,
            text!(
                "a body sequence and a character (",
                Param::Rig,
                ") are two bodies: give one"
            ),
        ));
    }
    if job.solver != SolverKind::Newton {
        return Err(Error::param_value(
            Param::Solver,
            text!(
                "fast: a bake on a moving body (",
                Param::Body,
                ") needs newton"
            ),
        ));
    }
    if job.basis.is_some() {
        return Err(Error::param_value(
            Param::Basis,
            text!(
                "not with ",
                Param::Body,
                ": a bake on a body sequence writes a morph target per frame"
            ),
        ));
    }
    let (file, part) = split_mesh_part(&pattern.to_string_lossy()).map_err(|_| {
        Error::param_value(
            Param::Body,
            format!(
                "`{}`: give a file, and a mesh's name after `#` or no `#` (FILE.glb#NAME, or \
                 FILE.glb for the first animated mesh)",
                pattern.display()
            ),
        )
    })?;
    let is_gltf = file
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    if is_gltf && job.body_start.is_some() {
        return Err(Error::param_value(
            Param::BodyStart,
            text!(
                "numbers the files of an OBJ sequence; a glTF ",
                Param::Body,
                " plays its animation from its first key"
            ),
        ));
    }
    let body_fps = job
        .body_fps
        .map(|f| positive(f).for_param(Param::BodyFps))
        .transpose()?;
    if let Some(fps) = job.fps {
        positive(fps).for_param(Param::Fps)?;
    }
    super::check_export_options(job)?;

    let sequence = match body_fps {
        _ if is_gltf => load_gltf_sequence(&file, part.as_deref(), body_fps)
            .map_err(sequence_error)
            .for_param(Param::Body)?,
        Some(f) => load_obj_sequence(&pattern, f, job.body_start).for_param(Param::Body)?,
        None => {
            return Err(Error::param_value(
                Param::BodyFps,
                text!(
                    "missing: give the frame rate of the ",
                    Param::Body,
                    " sequence (an OBJ sequence does not record it)"
                ),
            ))
        }
    };
    let body_fps = sequence.fps;
    let fps = positive(job.fps.unwrap_or(body_fps)).for_param(Param::Fps)?;
    let duration = sequence.duration();
    // Frames that fit in the sequence (a hair of slack for 1/3-style rates).
    let whole = (duration * fps + 1e-9).floor() as usize;
    if whole == 0 {
        return Err(Error::param_value(
            Param::Fps,
            format!(
                "{fps}: the body sequence lasts {duration} s, less than one frame at this rate"
            ),
        ));
    }
    let frames = match job.frames {
        Some(n) if n > whole => {
            return Err(Error::param_value(
                Param::Frames,
                text!(
                    format!(
                        "{n}: the body sequence lasts {duration} s ({} frames at {body_fps} fps), \
                         {whole} frames at {fps} fps; give at most {whole} (",
                        sequence.frames.len()
                    ),
                    Param::Frames,
                    " shortens the bake, it does not lengthen the sequence)"
                ),
            ))
        }
        Some(n) => n,
        None => whole,
    };
    let sized = ClothJob {
        frames: Some(frames),
        fps: Some(fps),
        ..job.clone()
    };
    let mut prepared = prepare_cloth(&sized)?;
    let drive = SequenceDrive::new(sequence);
    let PreparedCloth { model, params, .. } = &mut prepared;
    let statics = collider_meshes(model, &params.colliders);
    let collides = job.body_collider == Switch::On;
    let (sim, _) = simulate_on_body(&mut prepared, &drive, collides, &mut |f| {
        progress(f, frames)
    })?;
    let PreparedCloth { model, .. } = &prepared;

    let export_start = Instant::now();
    let sequence = drive.sequence();
    let body_name = format!("{}_body", job.display_name());
    let mut body_cache = FrameCache::new(sequence.mesh.particle_count());
    for k in 0..=frames {
        body_cache.push(&sequence.at(k as f64 / fps));
    }
    let body_frames = RenderFrames::new(&sequence.mesh, &body_cache);
    let options = MorphOptions {
        fps,
        interpolation: job.interpolation,
        name: job.display_name(),
        normals: job.normals == Switch::On,
        keyframe_tolerance: job.keyframe_tolerance,
        sparse: job.sparse,
        static_meshes: statics,
        start_time: 0.0,
    };
    let body = AnimatedBody {
        name: &body_name,
        mesh: &sequence.mesh,
        frames: &body_frames,
    };
    let exported = export(job, model, &sim.cache, options, Host::Alone(Some(&body)))?;
    let seconds_export = export_start.elapsed().as_secs_f64();
    let quality = quality_report(&sim, job.strain_limit);
    let mut out = report(
        &prepared,
        job,
        &sim.frames,
        quality,
        sim.seconds,
        seconds_export,
        exported,
    );
    out.body = Some(BodyReport {
        pattern,
        first_file: sequence.files[0].clone(),
        last_file: sequence.files[sequence.files.len() - 1].clone(),
        frames: sequence.frames.len(),
        fps: body_fps,
        duration_seconds: duration,
        vertices: sequence.mesh.particle_count(),
        triangles: sequence.mesh.triangles.len(),
        collides,
        node: body_name,
    });
    out.warnings
        .extend(sequence.mesh.warnings.iter().map(|w| text!(w.clone())));
    Ok(out)
}
