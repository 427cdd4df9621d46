//! Cloth export as a morph-target vertex cache: one glTF mesh whose base is frame 0, one morph
//! target per baked frame (POSITION and NORMAL deltas), and a weights animation that switches the
//! targets on one after another.
//!
//! With LINEAR interpolation between one-hot weight keys, the blend between frames k and k+1 is
//! exactly the linear interpolation of their positions. Blender imports the targets as shape keys
//! named by `mesh.extras.targetNames` (`frame_0001`...).
//!
//! Compact caches (see [`super::compact`]): with a keyframe tolerance only the selected frames get
//! a target and a key (at their true times, so playback stays in sync), and each delta accessor
//! may be sparse.

use std::path::{Path, PathBuf};

use glam::Vec3;
use gltf_json as json;
use json::validation::Checked::Valid;

use super::compact::{
    delta_accessor, select_keyframes, DeltaEncoding, KeyframeSelection, SparseMode,
};
use super::frames::RenderFrames;
use super::gltf_doc::{channel, primitive, sampler, GltfBuilder, Written};
use super::statics::{push_scene, StaticMesh};
use crate::data::FrameCache;
use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// How weights are interpolated between frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Interpolation {
    /// Positions blend linearly between frames.
    #[default]
    Linear,
    /// Each frame holds until the next.
    Step,
}

/// Options of the morph-target export.
#[derive(Debug, Clone)]
pub struct MorphOptions {
    /// Frames per second: frame k is keyed at k / fps seconds.
    pub fps: f64,
    /// Weight interpolation.
    pub interpolation: Interpolation,
    /// Name of the mesh, node and animation.
    pub name: String,
    /// Write NORMAL deltas (recomputed from the simulated surface).
    pub normals: bool,
    /// `--keyframe-tolerance`: keep only the frames needed to reproduce every frame within this
    /// distance (scene units; finite and not negative, the job checks it); `None` keeps every
    /// frame.
    pub keyframe_tolerance: Option<f64>,
    /// `--sparse`: whether delta accessors may be sparse.
    pub sparse: SparseMode,
    /// Unanimated meshes (the colliders) written as their own nodes after the cloth's, in the
    /// same scene; the cloth stays mesh 0 and node 0.
    pub static_meshes: Vec<StaticMesh>,
    /// Time of frame 0 in seconds (frame k is keyed at start_time + k / fps): the first key of
    /// an animation the cache plays beside.
    pub start_time: f64,
}

impl MorphOptions {
    /// Options at their defaults (linear, normals on, every frame, sparse where smaller, no
    /// static mesh).
    pub fn new(name: impl Into<String>, fps: f64) -> Self {
        MorphOptions {
            fps,
            interpolation: Interpolation::Linear,
            name: name.into(),
            normals: true,
            keyframe_tolerance: None,
            sparse: SparseMode::Auto,
            static_meshes: Vec::new(),
            start_time: 0.0,
        }
    }
}

/// Size and shape of the morph cache a write produced.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CacheStats {
    /// Morph targets written (kept frames after frame 0).
    pub targets: usize,
    /// Frames baked, the initial state included.
    pub frames: usize,
    /// The frames that got a target and a key (frame 0 is the base).
    pub kept_frames: Vec<usize>,
    /// Largest distance between a dropped frame as played back and as baked (scene units); 0
    /// when every frame is kept.
    pub max_interpolation_error: f64,
    /// Delta accessors written sparse.
    pub sparse_accessors: usize,
    /// Delta accessors written dense.
    pub dense_accessors: usize,
    /// Binary bytes of the morph-target deltas (padding included).
    pub target_bytes: u64,
}

/// A morph-target glTF encoded in memory, ready to be written with other files.
#[derive(Debug, Clone)]
pub struct EncodedMorph {
    /// (path, bytes) of the `.glb`, or of the `.bin` and `.gltf`, in rename order.
    pub files: Vec<(PathBuf, Vec<u8>)>,
    /// What the cache holds.
    pub stats: CacheStats,
}

/// Writes `cache` (frames 0..=N of `mesh`'s particles) as a morph-target glTF at `path`
/// (`.glb` or `.gltf`).
///
/// # Errors
/// [`Error::Export`] when the cache does not match the mesh or has no baked frame; write errors.
pub fn write_morph_gltf(
    path: &Path,
    mesh: &Mesh,
    cache: &FrameCache,
    options: &MorphOptions,
) -> Result<Written> {
    check_cache(path, mesh, cache)?;
    let frames = RenderFrames::new(mesh, cache);
    Written::write_all(encode_morph_gltf(path, mesh, &frames, options)?.files)
}

/// Checks that `cache` holds at least two frames of `mesh`'s particles.
///
/// # Errors
/// [`Error::Export`] naming `path` otherwise.
pub fn check_cache(path: &Path, mesh: &Mesh, cache: &FrameCache) -> Result<()> {
    if cache.particle_count() != mesh.particle_count() || cache.frame_count() < 2 {
        return Err(Error::Export {
            path: path.into(),
            message: format!(
                "cache of {} frames × {} particles does not fit a mesh of {} particles",
                cache.frame_count(),
                cache.particle_count(),
                mesh.particle_count()
            )
            .into(),
        });
    }
    Ok(())
}

/// Encodes the morph-target glTF of `frames` (render frames of `mesh`, at least two) for `path`
/// without writing it.
///
/// # Errors
/// [`Error::Export`] for a bad extension, too few frames, or a static mesh that cannot be
/// written (no triangle, index out of range, non-finite position); [`Error::Json`].
pub fn encode_morph_gltf(
    path: &Path,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
) -> Result<EncodedMorph> {
    encode_morph_gltf_with_body(path, mesh, frames, options, None)
}

/// A body moving beside the cloth (a mesh sequence), written as its own morph-animated mesh:
/// `frames` of `mesh`, frame k at the cloth's frame k's time.
#[derive(Debug, Clone, Copy)]
pub struct AnimatedBody<'a> {
    /// Name of its mesh and node.
    pub name: &'a str,
    /// Its surface (positions of frame 0, triangles, texture coordinates).
    pub mesh: &'a Mesh,
    /// Its render frames, as many as the cloth's.
    pub frames: &'a RenderFrames,
}

/// As [`encode_morph_gltf`], with `body` (when given) written as a second morph-animated mesh
/// whose weights are keyed on the cloth's frames in the same animation, so that a viewer playing
/// the animation plays both in step. The body gets every frame (no keyframe reduction), a grey
/// material, and its node after the cloth's and the static meshes.
///
/// # Errors
/// As [`encode_morph_gltf`]; [`Error::Export`] when the body's frame count differs from the
/// cloth's.
pub fn encode_morph_gltf_with_body(
    path: &Path,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
    body: Option<AnimatedBody<'_>>,
) -> Result<EncodedMorph> {
    if frames.frame_count() < 2 || frames.vertex_count() != mesh.render_vertices.len() {
        return Err(Error::Export {
            path: path.into(),
            message: format!(
                "{} frames of {} vertices: need at least 2 frames of the mesh's {} render vertices",
                frames.frame_count(),
                frames.vertex_count(),
                mesh.render_vertices.len()
            )
            .into(),
        });
    }
    if let Some((name, problem)) = options
        .static_meshes
        .iter()
        .find_map(|s| s.problem().map(|p| (&s.name, p)))
    {
        return Err(Error::Export {
            path: path.into(),
            message: format!("static mesh `{name}` {problem}").into(),
        });
    }
    let mut b = GltfBuilder::new();
    let (node, stats) = push_morph(&mut b, path, mesh, frames, options)?;
    push_scene(&mut b, node, &options.static_meshes);
    if let Some(body) = body {
        push_body(&mut b, path, body, frames.frame_count(), options)?;
    }
    stamp_and_encode(b, path, frames, options, stats)
}

/// Adds `body` (see [`encode_morph_gltf_with_body`]) to `b`, whose last animation is the
/// cloth's and whose scene exists.
fn push_body(
    b: &mut GltfBuilder,
    path: &Path,
    body: AnimatedBody<'_>,
    frames: usize,
    options: &MorphOptions,
) -> Result<()> {
    if body.frames.frame_count() != frames
        || body.frames.vertex_count() != body.mesh.render_vertices.len()
    {
        return Err(Error::Export {
            path: path.into(),
            message: format!(
                "the body `{}` has {} frames of {} vertices, where the cloth has {frames} frames \
                 and the body's mesh {} render vertices",
                body.name,
                body.frames.frame_count(),
                body.frames.vertex_count(),
                body.mesh.render_vertices.len()
            )
            .into(),
        });
    }
    let body_options = MorphOptions {
        name: body.name.to_owned(),
        keyframe_tolerance: None,
        static_meshes: Vec::new(),
        ..options.clone()
    };
    let (node, _) = push_morph(b, path, body.mesh, body.frames, &body_options)?;
    let weights = b
        .root
        .animations
        .pop()
        .expect("push_morph adds the weights animation last");
    let animation = b
        .root
        .animations
        .last_mut()
        .expect("the cloth's animation comes before");
    let offset = animation.samplers.len() as u32;
    for mut ch in weights.channels {
        ch.sampler = json::Index::new(ch.sampler.value() as u32 + offset);
        animation.channels.push(ch);
    }
    animation.samplers.extend(weights.samplers);
    // push_morph gave the body a cloth material of its own: make it the body's.
    let gmesh = b.root.nodes[node.value()]
        .mesh
        .expect("push_morph's node has a mesh");
    if let Some(material) = b.root.meshes[gmesh.value()].primitives[0].material {
        b.root.materials[material.value()] = json::Material {
            name: Some("body".into()),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor([0.6, 0.6, 0.6, 1.0]),
                metallic_factor: json::material::StrengthFactor(0.0),
                roughness_factor: json::material::StrengthFactor(0.9),
                ..Default::default()
            },
            ..Default::default()
        };
    }
    let scene = b.root.scene.map_or(0, |s| s.value());
    b.root.scenes[scene].nodes.push(node);
    Ok(())
}

/// Records the bake's fps and frame range in `b` (see [`super::playback`]) and encodes it for
/// `path`.
pub(crate) fn stamp_and_encode(
    mut b: GltfBuilder,
    path: &Path,
    frames: &RenderFrames,
    options: &MorphOptions,
    stats: CacheStats,
) -> Result<EncodedMorph> {
    super::playback::stamp(
        &mut b.root,
        &super::playback::Playback::frames(options.fps, frames.frame_count(), &options.name),
    );
    Ok(EncodedMorph {
        files: b.encode(path)?,
        stats,
    })
}

/// Adds the morph-animated mesh of `frames` to `b`: its mesh, its node (returned, in no scene
/// yet) and its weights animation (pushed last in `b`'s animations). `path` names errors.
///
/// # Errors
/// As [`encode_morph_gltf`].
pub(crate) fn push_morph(
    b: &mut GltfBuilder,
    path: &Path,
    mesh: &Mesh,
    frames: &RenderFrames,
    options: &MorphOptions,
) -> Result<(json::Index<json::Node>, CacheStats)> {
    let selection = match options.keyframe_tolerance {
        Some(t) => select_keyframes(frames, t, options.interpolation),
        None => KeyframeSelection::all(frames.frame_count()),
    };
    let normals = options
        .normals
        .then(|| super::shading::base_normals(mesh, frames));
    let (attributes, indices) = base_primitive(b, mesh, frames, normals.as_deref());
    let (targets, mut stats) = morph_targets(b, frames, &selection, options, normals.as_deref());
    let names: Vec<String> = selection.kept[1..]
        .iter()
        .map(|k| format!("frame_{k:04}"))
        .collect();
    let material = cloth_material(b);
    let gmesh = b.root.push(json::Mesh {
        name: Some(options.name.clone()),
        primitives: vec![json::mesh::Primitive {
            targets: Some(targets),
            ..primitive(
                attributes,
                Some(indices),
                material,
                json::mesh::Mode::Triangles,
            )
        }],
        weights: Some(vec![0.0; names.len()]),
        extensions: None,
        extras: Some(
            serde_json::value::to_raw_value(&serde_json::json!({ "targetNames": names })).map_err(
                |error| Error::Json {
                    path: path.into(),
                    source: error,
                },
            )?,
        ),
    });
    let node = b.root.push(json::Node {
        name: Some(options.name.clone()),
        mesh: Some(gmesh),
        ..Default::default()
    });
    weights_animation(b, node, &selection.kept, options);
    stats.frames = frames.frame_count();
    stats.kept_frames = selection.kept;
    stats.max_interpolation_error = selection.max_error;
    Ok((node, stats))
}

/// A primitive's vertex attributes.
type Attributes = std::collections::BTreeMap<
    json::validation::Checked<json::mesh::Semantic>,
    json::Index<json::Accessor>,
>;

/// The base (frame 0) attributes and the triangle indices; `normals` is the base NORMAL (see
/// [`super::shading::base_normals`]), none with `--normals off`.
fn base_primitive(
    b: &mut GltfBuilder,
    mesh: &Mesh,
    frames: &RenderFrames,
    normals: Option<&[Vec3]>,
) -> (Attributes, json::Index<json::Accessor>) {
    let array = Some(json::buffer::Target::ArrayBuffer);
    let mut attributes = std::collections::BTreeMap::new();
    attributes.insert(
        Valid(json::mesh::Semantic::Positions),
        b.vec3(frames.positions(0), array, true),
    );
    if let Some(normals) = normals {
        attributes.insert(
            Valid(json::mesh::Semantic::Normals),
            b.vec3(normals, array, false),
        );
    }
    if mesh.has_uvs() {
        let uvs: Vec<[f32; 2]> = mesh
            .render_vertices
            .iter()
            .map(|v| flip_v(v.uv.unwrap_or_default()))
            .collect();
        attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), b.vec2(&uvs));
    }
    let indices: Vec<u32> = mesh.render_triangles.iter().flatten().copied().collect();
    (attributes, b.indices(&indices))
}

/// One target per kept frame after frame 0: POSITION (and, from `base_normals`, NORMAL) deltas
/// from the base, dense or sparse.
fn morph_targets(
    b: &mut GltfBuilder,
    frames: &RenderFrames,
    selection: &KeyframeSelection,
    options: &MorphOptions,
    base_normals: Option<&[Vec3]>,
) -> (Vec<json::mesh::MorphTarget>, CacheStats) {
    let mut stats = CacheStats {
        targets: 0,
        frames: 0,
        kept_frames: Vec::new(),
        max_interpolation_error: 0.0,
        sparse_accessors: 0,
        dense_accessors: 0,
        target_bytes: 0,
    };
    let start = b.buffer_len();
    let mut count = |e: DeltaEncoding| match e {
        DeltaEncoding::Sparse => stats.sparse_accessors += 1,
        DeltaEncoding::Dense => stats.dense_accessors += 1,
    };
    let mut targets = Vec::with_capacity(selection.kept.len().saturating_sub(1));
    for &k in &selection.kept[1..] {
        let dp = difference(frames.positions(k), frames.positions(0));
        let (positions, e) = delta_accessor(b, &dp, options.sparse, true);
        count(e);
        let normals = base_normals.map(|base| {
            let (n, e) = delta_accessor(
                b,
                &super::shading::normal_deltas(frames.normals(k), frames.normals(0), base),
                options.sparse,
                false,
            );
            count(e);
            n
        });
        targets.push(json::mesh::MorphTarget {
            positions: Some(positions),
            normals,
            tangents: None,
        });
    }
    stats.targets = targets.len();
    stats.target_bytes = (b.buffer_len() - start) as u64;
    (targets, stats)
}

/// `a - b` element by element.
fn difference(a: &[Vec3], b: &[Vec3]) -> Vec<Vec3> {
    a.iter().zip(b).map(|(p, q)| *p - *q).collect()
}

/// The double-sided cloth material.
pub(crate) fn cloth_material(b: &mut GltfBuilder) -> json::Index<json::Material> {
    b.root.push(json::Material {
        name: Some("cloth".into()),
        double_sided: true,
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([0.8, 0.45, 0.3, 1.0]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(0.8),
            ..Default::default()
        },
        ..Default::default()
    })
}

/// Weights keyed at each kept frame's true time k / fps: all zero at frame 0, one-hot on the
/// frame's own target after.
fn weights_animation(
    b: &mut GltfBuilder,
    node: json::Index<json::Node>,
    kept: &[usize],
    options: &MorphOptions,
) {
    let targets = kept.len() - 1;
    let mut weights = vec![0.0f32; kept.len() * targets];
    for i in 1..kept.len() {
        weights[i * targets + (i - 1)] = 1.0;
    }
    push_weights_animation(b, node, kept, &weights, options);
}

/// The mesh's weights animation named after the bake: one key per frame of `keys` at its true
/// time k / fps, `weights` holding every key's weights in turn (targets values each).
pub(crate) fn push_weights_animation(
    b: &mut GltfBuilder,
    node: json::Index<json::Node>,
    keys: &[usize],
    weights: &[f32],
    options: &MorphOptions,
) {
    let times: Vec<f32> = keys
        .iter()
        .map(|&k| (options.start_time + k as f64 / options.fps) as f32)
        .collect();
    let input = b.scalars(&times, true);
    let output = b.scalars(weights, false);
    let interpolation = match options.interpolation {
        Interpolation::Linear => json::animation::Interpolation::Linear,
        Interpolation::Step => json::animation::Interpolation::Step,
    };
    b.root.push(json::Animation {
        name: Some(options.name.clone()),
        channels: vec![channel(
            0,
            node,
            json::animation::Property::MorphTargetWeights,
        )],
        samplers: vec![sampler(input, output, interpolation)],
        extensions: None,
        extras: Default::default(),
    });
}

/// OBJ texture coordinates have v up; glTF's have v down.
pub(crate) fn flip_v(uv: [f32; 2]) -> [f32; 2] {
    [uv[0], 1.0 - uv[1]]
}
