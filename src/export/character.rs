//! A character and the garment baked on it, in one glTF that plays both in step.
//!
//! The character's document is kept whole (meshes, skins, materials, its animations), as for an
//! IK bake on a rig ([`super::skin::write_rig_gltf`]). The garment is added as a morph-animated
//! mesh on its own scene-root node, scaled from metres back to the document's units. A new first
//! animation, named after the bake, holds the driving animation's keys (repeated for every
//! written loop; its morph-target weights too, such as a face's expressions) and the garment's
//! weights on the same time axis, so a viewer that plays the
//! first animation (Blender's importer makes it active on every object, three.js users take
//! `animations[0]`) plays the character and the garment together. The fps and frame range go into
//! `asset.extras` ([`super::playback`]).

use std::path::Path;

use gltf_json as json;

use super::gltf_doc::{channel, sampler, GltfBuilder};
use super::morph::{push_morph, stamp_and_encode, CacheStats, EncodedMorph, MorphOptions};
use super::skin::{lift_skinned_meshes_to_root, posed_nodes, push_hold_channels};
use super::RenderFrames;
use crate::data::animation::{Clip, Interpolation, Property};
use crate::error::Result;
use crate::io::rig::RigDocument;
use crate::mesh::Mesh;

/// How the garment sits in the character's document.
#[derive(Debug, Clone, Copy)]
pub struct CharacterOptions<'a> {
    /// The animation that drove the bake.
    pub clip: &'a Clip,
    /// Loops of it the garment's frames cover (frame 0 at the clip's first key).
    pub cycles: usize,
    /// Metres per document unit (the garment node is scaled by its inverse).
    pub rig_scale: f64,
}

/// Encodes `doc` with the garment (`frames` of `mesh`, metres) added and the combined
/// animation first, for `path`, without writing it. `options.start_time` should be the clip's
/// first key.
///
/// # Errors
/// As [`super::morph::encode_morph_gltf`].
pub fn encode_character_gltf(
    path: &Path,
    doc: RigDocument,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
    character: &CharacterOptions<'_>,
) -> Result<EncodedMorph> {
    let host = CharacterHost { doc, character };
    let mut b = host.document();
    let (node, stats): (_, CacheStats) = push_morph(&mut b, path, mesh, frames, options)?;
    host.dress(&mut b, node, &options.name);
    stamp_and_encode(b, path, frames, options, stats)
}

/// A character's document that a garment's mesh is added to, by the morph cache's writer or the
/// basis cache's ([`super::basis::encode_basis_gltf`]).
#[derive(Debug)]
pub struct CharacterHost<'a> {
    /// The character.
    pub doc: RigDocument,
    /// How the garment sits in it.
    pub character: &'a CharacterOptions<'a>,
}

impl CharacterHost<'_> {
    /// A new document holding the character, its skinned meshes lifted to the scene root.
    pub(crate) fn document(&self) -> GltfBuilder {
        let mut b = GltfBuilder::from_parts(self.doc.root.clone(), self.doc.bin.clone());
        lift_skinned_meshes_to_root(&mut b.root);
        b
    }

    /// Puts the garment's `node` (in metres, in no scene yet) into the character's scene,
    /// scaled to the document's units, and merges its weights animation (the last of `b`'s)
    /// with the driving animation into a first animation named `name`.
    pub(crate) fn dress(&self, b: &mut GltfBuilder, node: json::Index<json::Node>, name: &str) {
        let character = self.character;
        let s = 1.0 / character.rig_scale;
        // A quantised cache's node already carries its dequantisation (translation and scale):
        // the document's units scale both.
        let garment_node = &mut b.root.nodes[node.value()];
        let scale = garment_node.scale.unwrap_or([1.0; 3]);
        garment_node.scale = Some(scale.map(|c| (f64::from(c) * s) as f32));
        if let Some(t) = garment_node.translation.as_mut() {
            *t = t.map(|c| (f64::from(c) * s) as f32);
        }
        let garment = b
            .root
            .animations
            .pop()
            .expect("the garment's weights animation is pushed last");

        let mut animation = driving_animation(b, character);
        // Every joint of the skins (and the nodes between them) gets a defined pose: Blender
        // keeps a bone's pose from the previously active action where this one has no key for
        // it.
        let joints: Vec<usize> = b
            .root
            .skins
            .iter()
            .flat_map(|s| s.joints.iter().map(|j| j.value()))
            .collect();
        let posed = posed_nodes(&b.root, &joints);
        let keyed = |node: usize, p: json::animation::Property| {
            character.clip.tracks.iter().any(|t| {
                t.node == node
                    && matches!(
                        (t.property, p),
                        (
                            Property::Translation,
                            json::animation::Property::Translation
                        ) | (Property::Rotation, json::animation::Property::Rotation)
                            | (Property::Scale, json::animation::Property::Scale)
                    )
            })
        };
        let start = character.clip.start();
        let end = start + character.cycles.max(1) as f64 * character.clip.duration();
        let times: Vec<f32> = if end > start {
            vec![start as f32, end as f32]
        } else {
            vec![start as f32]
        };
        push_hold_channels(
            b,
            &posed,
            &times,
            &keyed,
            &mut animation.channels,
            &mut animation.samplers,
        );
        let offset = animation.samplers.len() as u32;
        for mut ch in garment.channels {
            ch.sampler = json::Index::new(ch.sampler.value() as u32 + offset);
            animation.channels.push(ch);
        }
        animation.samplers.extend(garment.samplers);
        animation.name = Some(name.to_owned());
        b.root.animations.insert(0, animation);

        let scene = b.root.scene.map_or(0, |s| s.value());
        if b.root.scenes.is_empty() {
            b.root.scenes.push(json::Scene {
                nodes: Vec::new(),
                name: None,
                extensions: None,
                extras: Default::default(),
            });
        }
        b.root.scenes[scene].nodes.push(node);
    }
}

/// The key times of a track over `cycles` loops of `period` seconds, and for each the index of
/// the clip's key it repeats: each loop's keys shifted by `period`, a loop's first key dropped
/// where it repeats the previous loop's last.
fn looped_keys(times: &[f64], period: f64, cycles: usize) -> (Vec<f32>, Vec<usize>) {
    let mut out: Vec<f64> = Vec::new();
    let mut keys = Vec::new();
    for c in 0..cycles.max(1) {
        let shift = c as f64 * period;
        for (k, &t) in times.iter().enumerate() {
            let t = t + shift;
            if out.last().is_some_and(|&last| t <= last) {
                continue;
            }
            out.push(t);
            keys.push(k);
        }
    }
    (out.iter().map(|&t| t as f32).collect(), keys)
}

fn json_interpolation(i: Interpolation) -> json::animation::Interpolation {
    match i {
        Interpolation::Step => json::animation::Interpolation::Step,
        Interpolation::Linear => json::animation::Interpolation::Linear,
        Interpolation::CubicSpline => json::animation::Interpolation::CubicSpline,
    }
}

/// The clip's tracks as a new animation covering `cycles` loops (see [`looped_keys`]): its node
/// transforms and its morph-target weights (a character's face), on one time axis.
fn driving_animation(b: &mut GltfBuilder, character: &CharacterOptions<'_>) -> json::Animation {
    let clip = character.clip;
    let period = clip.duration();
    let mut channels = Vec::new();
    let mut samplers = Vec::new();
    for track in &clip.tracks {
        let per_key = track.interpolation.values_per_key();
        let (times, keys) = looped_keys(&track.times, period, character.cycles);
        let values: Vec<_> = keys
            .iter()
            .flat_map(|&k| &track.values[k * per_key..(k + 1) * per_key])
            .collect();
        let input = b.scalars(&times, true);
        let output = match track.property {
            Property::Rotation => {
                let v: Vec<[f32; 4]> = values.iter().map(|v| v.as_vec4().to_array()).collect();
                b.vec4(&v, None)
            }
            Property::Translation | Property::Scale => {
                let v: Vec<glam::Vec3> = values.iter().map(|v| v.truncate().as_vec3()).collect();
                b.vec3(&v, None, false)
            }
        };
        let property = match track.property {
            Property::Translation => json::animation::Property::Translation,
            Property::Rotation => json::animation::Property::Rotation,
            Property::Scale => json::animation::Property::Scale,
        };
        channels.push(channel(
            samplers.len(),
            json::Index::new(track.node as u32),
            property,
        ));
        samplers.push(sampler(
            input,
            output,
            json_interpolation(track.interpolation),
        ));
    }
    for track in &clip.weights {
        let per_key = track.targets * track.interpolation.values_per_key();
        let (times, keys) = looped_keys(&track.times, period, character.cycles);
        let values: Vec<f32> = keys
            .iter()
            .flat_map(|&k| track.values[k * per_key..(k + 1) * per_key].iter().copied())
            .collect();
        let input = b.scalars(&times, true);
        let output = b.scalars(&values, false);
        channels.push(channel(
            samplers.len(),
            json::Index::new(track.node as u32),
            json::animation::Property::MorphTargetWeights,
        ));
        samplers.push(sampler(
            input,
            output,
            json_interpolation(track.interpolation),
        ));
    }
    json::Animation {
        name: None,
        channels,
        samplers,
        extensions: None,
        extras: Default::default(),
    }
}
