//! A garment baked on an animated character (`--rig`): the animation drives the pins and the
//! body collider ([`crate::cloth::drive`]), loops are warmed up and cut, and the garment is
//! written into the character's document ([`crate::export::character`]), with the VAT, point
//! caches and USD layer asked for holding the same written loops.

use glam::DVec3;
use std::time::Instant;

use super::{
    check_export_options, export, length_words, prepare_cloth, quality_report, report,
    scaled_words, simulate_on_body, CharacterReport, ClothJob, ClothReport, Host, LoopBlend,
    PinStrain, PreparedCloth, Switch,
};
use crate::cloth::drive::CharacterDrive;
use crate::cloth::model::ClothModel;
use crate::cloth::{FrameCache, SolverKind};
use crate::data::animation::{Clip, Skeleton, SkinnedMesh};
use crate::error::{Error, ForParam, Result};
use crate::export::character::{CharacterHost, CharacterOptions};
use crate::export::morph::AnimatedBody;
use crate::export::{MorphOptions, RenderFrames};
use crate::io::rig::RigDocument;
use crate::mesh::Mesh;
use crate::param::Param;
use crate::spec::positive;
use crate::text;

/// The loop seam above which the report warns, metres.
pub const SEAM_WARNING: f64 = 0.01;

/// Runs a `--rig` bake: prepare, simulate blend-in + warm-up + written loops, cut, export,
/// report.
///
/// # Errors
/// Option errors (a solver other than Newton, `--frames`), rig errors (no such animation or
/// joint, no skinned mesh to bind to), and those of [`super::bake_cloth`].
pub fn bake_on_character(
    job: &ClothJob,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<ClothReport> {
    let rig_path = job.rig.clone().expect("called for --rig jobs");
    if job.solver != SolverKind::Newton {
        return Err(Error::param_value(
            Param::Solver,
            text!(
                "fast: a bake on a character (",
                Param::Rig,
                ") needs newton"
            ),
        ));
    }
    if job.frames.is_some() {
        return Err(Error::param_value(
            Param::Frames,
            text!(
                "not with ",
                Param::Rig,
                ": the frames follow the animation (use ",
                Param::Cycles,
                ")"
            ),
        ));
    }
    if job.cycles == 0 {
        return Err(Error::param_value(Param::Cycles, "0: must be at least 1"));
    }
    let rig_scale = positive(job.rig_scale).for_param(Param::RigScale)?;
    // A duration and a distance, each zero or more.
    let at_least_zero = |value: f64, param: Param, unit: &str| {
        if value.is_finite() && value >= 0.0 {
            Ok(())
        } else {
            Err(Error::param_value(
                param,
                format!("{value}: must be zero or a positive number of {unit}"),
            ))
        }
    };
    at_least_zero(job.blend_in, Param::BlendIn, "seconds")?;
    at_least_zero(job.pin_smooth, Param::PinSmooth, "metres")?;
    if let Some(seconds) = job.loop_blend {
        at_least_zero(seconds, Param::LoopBlend, "seconds")?;
    }
    check_export_options(job)?;

    let doc = RigDocument::load(&rig_path)?;
    let rig_warnings = doc.warnings.clone();
    let clip = doc
        .clip(job.animation.as_deref().unwrap_or("#0"))
        .for_param(Param::Animation)?;
    let skeleton = doc.skeleton()?;
    let all_bodies = doc.body_meshes()?;
    let character_diagonal = {
        let world = skeleton.world_at(None, 0.0);
        let points: Vec<DVec3> = all_bodies
            .iter()
            .flat_map(|m| m.deform(&world))
            .map(|p| p * rig_scale)
            .collect();
        let (lo, hi) = crate::mesh::bounds(&points);
        (hi - lo).length()
    };
    // The USD layer holds the whole character's skinned meshes, whether they collide or not.
    let usd_bodies = (job.usd.is_some() && !job.garment_only).then(|| all_bodies.clone());
    let bodies = exclude_bodies(&doc, &skeleton, all_bodies, &job.body_exclude)?;
    let cycle = clip.duration();
    let fps = positive(job.fps.unwrap_or(super::defaults::FPS)).for_param(Param::Fps)?;
    // Whole frames per loop, so every loop starts on a frame: the bake's rate is adjusted to
    // frames_per_cycle / cycle (29.97 instead of 30 for a 1.0333 s walk).
    let frames_per_cycle = ((cycle * fps).round() as usize).max(1);
    let fps = frames_per_cycle as f64 / cycle;
    let blend_frames = (job.blend_in * fps).ceil() as usize;
    let first_written = blend_frames + job.warmup_cycles * frames_per_cycle;
    let total = first_written + job.cycles * frames_per_cycle;
    let loop_blend = blended_frames(job, fps, frames_per_cycle)?;

    let sized = ClothJob {
        frames: Some(total),
        fps: Some(fps),
        ..job.clone()
    };
    let mut prepared = prepare_cloth(&sized)?;
    // Only the written loops are measured (and reported).
    prepared.params.measure_from = first_written;
    prepared.params.loop_closure = (loop_blend > 0).then_some(crate::cloth::LoopClosure {
        frames: loop_blend,
        span: total - first_written,
    });
    check_units(
        &prepared.model.mesh,
        character_diagonal,
        job.scale,
        rig_scale,
    )?;
    let mut drive = CharacterDrive::new(
        skeleton,
        clip.clone(),
        if job.body_collider == Switch::On || job.pin_to.is_none() {
            bodies
        } else {
            Vec::new()
        },
        rig_scale,
        blend_frames as f64 / fps,
    )
    .for_param(Param::Animation)?;
    let model = &prepared.model;
    let pinned: Vec<u32> = (0..model.particle_count() as u32)
        .filter(|&i| model.pinned[i as usize])
        .collect();
    let (on_surface, on_joint) = match &job.pin_to {
        Some(joint) => {
            let node = doc.find_node(joint)?;
            drive.bind_to_node(&pinned, model.positions(), node);
            (0, pinned.len())
        }
        None => {
            if !pinned.is_empty() {
                if !drive.has_body() {
                    return Err(Error::param_value(
                        Param::Rig,
                        text!(
                            "the character has no skinned mesh to bind the pins to (bind them \
                             to a joint with ",
                            Param::PinTo,
                            ")"
                        ),
                    ));
                }
                drive.bind_to_surface(&pinned, model.positions())?;
                drive.smooth_pins(job.pin_smooth);
            }
            (pinned.len(), 0)
        }
    };
    let (sim, body_triangles) = simulate_on_body(
        &mut prepared,
        &drive,
        job.body_collider == Switch::On,
        &mut |f| progress(f, total),
    )
    .map_err(|e| match e {
        // Frames count from the animation's start; the blend-in before it is named as such.
        Error::Diverged {
            frame,
            reason,
            advice,
        } => Error::Diverged {
            frame: frame.saturating_sub(blend_frames),
            reason: if frame <= blend_frames {
                format!("{reason}; in blend-in frame {frame} of {blend_frames}, before the animation")
            } else {
                reason
            },
            advice,
        },
        e => e,
    })?;
    let PreparedCloth { model, .. } = &prepared;

    // The written loops: frames first_written..=total, as frames 0.. of the output.
    let mut cache = FrameCache::new(sim.cache.particle_count());
    let mut buffer = Vec::new();
    for k in first_written..=total {
        buffer.clear();
        buffer.extend(sim.cache.frame(k).iter().map(|p| p.as_dvec3()));
        cache.push(&buffer);
    }
    let pin_strain = pin_strain(model, &cache);
    let seam = seam_between(sim.cache.frame(first_written), sim.cache.frame(total));
    // Where the steering began: how far the loop was from joining up there.
    let blend = (loop_blend > 0).then(|| LoopBlend {
        frames: loop_blend,
        gap: seam_between(
            sim.cache.frame(first_written - loop_blend),
            sim.cache.frame(total - loop_blend),
        ),
    });

    let export_start = Instant::now();
    let name = job.display_name();
    let options = MorphOptions {
        fps,
        interpolation: job.interpolation,
        name,
        normals: job.normals == Switch::On,
        keyframe_tolerance: job.keyframe_tolerance,
        sparse: job.sparse,
        static_meshes: Vec::new(),
        start_time: clip.start(),
    };
    let body_frames = match &usd_bodies {
        Some(meshes) => skinned_frames(&doc, meshes, &drive, &clip, cache.frame_count(), fps),
        None => Vec::new(),
    };
    let character = CharacterOptions {
        clip: &clip,
        cycles: job.cycles,
        rig_scale,
    };
    let host = (!job.garment_only).then(|| {
        Box::new(CharacterHost {
            doc,
            character: &character,
        })
    });
    let usd_body: Vec<AnimatedBody<'_>> = body_frames
        .iter()
        .map(|(name, mesh, frames)| AnimatedBody { name, mesh, frames })
        .collect();
    let exported = export(
        job,
        model,
        &cache,
        options,
        Host::Character {
            on: host,
            bodies: &usd_body,
        },
    )?;
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
    if seam > SEAM_WARNING {
        out.warnings.push(text!(
            format!(
                "the written loop does not join up: a particle is {:.1} mm apart in its first and \
             last frames (more than {:.0} mm); raise ",
                seam * 1e3,
                SEAM_WARNING * 1e3
            ),
            Param::WarmupCycles,
            " or ",
            Param::LoopBlend
        ));
    }
    if job.body_collider == Switch::On && sim.frames.iter().any(|f| f.pinched + f.pinched_pairs > 0)
    {
        out.warnings.push(text!(
            "where a part of the body closes on another through the garment (an arm on the \
             hips, thighs meeting), ",
            Param::BodyExclude,
            " with a joint of the skin leaves out the part it and the joints below it move"
        ));
    }
    if let Some(worst) = pin_strain.filter(|s| s.strain > job.strain_limit) {
        out.warnings.push(text!(
            format!(
                "the pins alone stretch an edge between two of them by {:.1} % at frame {}, \
                 past the strain limit (the body's skinning moves them apart); raise ",
                worst.strain * 100.0,
                worst.frame,
            ),
            Param::PinSmooth,
            " or bind them to one joint with ",
            Param::PinTo
        ));
    }
    out.character = Some(CharacterReport {
        rig: rig_path,
        animation: clip.name.clone(),
        cycle_seconds: cycle,
        frames_per_cycle,
        blend_frames,
        warmup_cycles: job.warmup_cycles,
        cycles: job.cycles,
        first_written_frame: first_written,
        pins_on_surface: on_surface,
        pins_on_joint: on_joint,
        body_triangles,
        loop_seam: seam,
        loop_blend: blend,
        pin_strain,
    });
    out.warnings
        .extend(rig_warnings.into_iter().map(|w| text!(w)));
    Ok(out)
}

/// How many written frames `--loop-blend` steers at `fps` (at least one when asked, 0 when
/// not), checked against the loops: the steered frames lie within the written loops, and the
/// frames they are steered onto, one written span earlier, within the animation (in the warm-up
/// loops, not the blend-in from the rest pose). By default a quarter of the written loops, or
/// as many frames as the warm-up loops have where they have fewer.
fn blended_frames(job: &ClothJob, fps: f64, frames_per_cycle: usize) -> Result<usize> {
    let written = job.cycles * frames_per_cycle;
    let warmup = job.warmup_cycles * frames_per_cycle;
    let Some(seconds) = job.loop_blend else {
        return Ok((written / 4).min(warmup));
    };
    if seconds == 0.0 {
        return Ok(0);
    }
    let frames = ((seconds * fps).round() as usize).max(1);
    if frames > written {
        return Err(Error::param_value(
            Param::LoopBlend,
            format!(
                "{seconds} s: {frames} frames at {fps:.3} fps, longer than the written loops \
                 ({written} frames)"
            ),
        ));
    }
    if frames > warmup {
        return Err(Error::param_value(
            Param::LoopBlend,
            text!(
                format!(
                    "{seconds} s: the last {frames} written frames are steered onto the {frames} \
                     frames before the written loops, but only {warmup} warm-up frames precede \
                     them; raise "
                ),
                Param::WarmupCycles
            ),
        ));
    }
    Ok(frames)
}

/// The largest distance between a particle's positions in two frames, metres.
fn seam_between(a: &[glam::Vec3], b: &[glam::Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| f64::from(a.distance(*b)))
        .fold(0.0, f64::max)
}

/// The edge between two pinned particles stretched most, over the written frames of `cache`,
/// against its rest length in `model`: what the pins' motion alone does to the cloth, whatever
/// the solver does between them. `None` without such an edge.
fn pin_strain(model: &ClothModel, cache: &FrameCache) -> Option<PinStrain> {
    let rest = model.positions();
    let edges: Vec<([u32; 2], f64)> = crate::mesh::edges(&model.mesh.triangles)
        .into_iter()
        .filter(|e| e.iter().all(|&i| model.pinned[i as usize]))
        .map(|[a, b]| ([a, b], rest[a as usize].distance(rest[b as usize])))
        .filter(|&(_, r)| r > 0.0)
        .collect();
    let mut worst: Option<PinStrain> = None;
    for frame in 0..cache.frame_count() {
        let x = cache.frame(frame);
        for &([a, b], r) in &edges {
            let strain = f64::from(x[a as usize].distance(x[b as usize])) / r - 1.0;
            if worst.is_none_or(|w| strain > w.strain) {
                worst = Some(PinStrain {
                    strain,
                    frame,
                    particles: [a, b],
                });
            }
        }
    }
    worst
}

/// The ratios of the garment's size to the character's (bounding-box diagonals) taken as the
/// same units. A garment is rarely larger than its wearer: a cape is about 0.3 of the Fox, a
/// dress 0.9 of the mannequin, so that cape in centimetres on the metre-scale Fox is 28 (above
/// 10), in millimetres 280; a metre-scale garment on a character in centimetres is below 1/30.
pub const SAME_UNITS: (f64, f64) = (1.0 / 30.0, 10.0);

/// A garment whose size against the character's is outside [`SAME_UNITS`]: an error suggesting
/// the `scale` (or `rig_scale`) by the power of ten that brings the ratio nearest the middle of
/// the range.
fn check_units(garment: &Mesh, character_diagonal: f64, scale: f64, rig_scale: f64) -> Result<()> {
    let (lo, hi) = garment.bounds();
    let diagonal = (hi - lo).length();
    if !(diagonal > 0.0 && character_diagonal > 0.0) {
        return Ok(());
    }
    let ratio = diagonal / character_diagonal;
    let (min, max) = SAME_UNITS;
    if (min..=max).contains(&ratio) {
        return Ok(());
    }
    let middle = (min * max).sqrt();
    let power = (middle / ratio).log10().round() as i32;
    let size = if ratio > 1.0 {
        format!("{ratio:.0} times the size of")
    } else {
        format!("1/{:.0} of the size of", 1.0 / ratio)
    };
    Err(Error::param_value(
        Param::Scale,
        text!(
            format!(
                "{scale}: the garment ({} across) is {size} the character ({} across, with ",
                length_words(diagonal),
                length_words(character_diagonal)
            ),
            Param::RigScale,
            format!(" {rig_scale}): are they in different units? try "),
            Param::Scale,
            format!(" {} for the garment, or ", scaled_words(scale, power)),
            Param::RigScale,
            format!(" {} for the character", scaled_words(rig_scale, -power))
        ),
    ))
}

/// The character's skinned `meshes` as the written file plays them: `frames` frames at `fps`
/// from the clip's start (frame k at clip time start + k / fps, loops after the first repeating
/// it, as the file's looped keys do), in metres, each named after its node (its mesh name where
/// the node has none).
fn skinned_frames(
    doc: &RigDocument,
    meshes: &[SkinnedMesh],
    drive: &CharacterDrive,
    clip: &Clip,
    frames: usize,
    fps: f64,
) -> Vec<(String, Mesh, RenderFrames)> {
    let per_cycle = ((clip.duration() * fps).round() as usize).max(1);
    let worlds: Vec<_> = (0..frames)
        .map(|k| {
            let into = if k > 0 && k % per_cycle == 0 {
                per_cycle
            } else {
                k % per_cycle
            };
            drive.world_in_clip(clip.start() + into as f64 / fps)
        })
        .collect();
    meshes
        .iter()
        .map(|m| {
            let at = |world| -> Vec<DVec3> {
                m.deform(world)
                    .into_iter()
                    .map(|p| p * drive.scale)
                    .collect()
            };
            let mesh = Mesh::from_triangles(m.name.clone(), at(&worlds[0]), m.triangles.clone());
            let mut cache = FrameCache::new(m.positions.len());
            for world in &worlds {
                cache.push(&at(world));
            }
            let name = doc.root.nodes[m.node]
                .name
                .clone()
                .unwrap_or_else(|| m.name.clone());
            let frames = RenderFrames::new(&mesh, &cache);
            (name, mesh, frames)
        })
        .collect()
}

/// The body meshes less what `exclude` names: a body mesh (a mesh name, or its node as `NAME`,
/// `#N` or Blender's `Node_N`), or a joint of a body's skin, which leaves out the triangles of
/// that body with any corner carrying more than half its skin weight on the joint and the joints
/// below it (a hand of a character made as one mesh; the triangles across the joint's crease
/// go too, as they swing partly with the part; a body left with no triangle is left out whole).
/// A name that is neither is an error listing the body meshes.
fn exclude_bodies(
    doc: &RigDocument,
    skeleton: &Skeleton,
    mut bodies: Vec<SkinnedMesh>,
    exclude: &[String],
) -> Result<Vec<SkinnedMesh>> {
    let mut drop = vec![false; bodies.len()];
    for name in exclude {
        let node = doc.find_node(name).ok();
        let mut found = false;
        for (d, b) in drop.iter_mut().zip(&bodies) {
            if b.name == *name || Some(b.node) == node {
                *d = true;
                found = true;
            }
        }
        if let Some(joint) = node.filter(|_| !found) {
            let below = skeleton.subtree(joint);
            for (d, b) in drop.iter_mut().zip(&mut bodies) {
                if !b.joints.contains(&joint) {
                    continue;
                }
                found = true;
                let held = b.weight_on(|j| below[j]);
                b.triangles
                    .retain(|t| !t.iter().any(|&v| held[v as usize] > 0.5));
                *d |= b.triangles.is_empty();
            }
        }
        if !found {
            let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
            return Err(Error::param_value(
                Param::BodyExclude,
                format!(
                    "`{name}` names no body mesh or skin joint of {} (its body meshes: {})",
                    doc.path.display(),
                    names.join(", ")
                ),
            ));
        }
    }
    Ok(bodies
        .into_iter()
        .zip(drop)
        .filter_map(|(b, d)| (!d).then_some(b))
        .collect())
}
