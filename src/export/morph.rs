//! Cloth export as a morph-target vertex cache: one glTF mesh whose base is frame 0, one morph
//! target per baked frame (POSITION and NORMAL deltas), and a weights animation that switches the
//! targets on one after another.
//!
//! With LINEAR interpolation between one-hot weight keys, the blend between frames k and k+1 is
//! exactly the linear interpolation of their positions. Blender imports the targets as shape keys
//! named by `mesh.extras.targetNames` (`frame_0001`...).

use std::path::Path;

use glam::{DVec3, Vec3};
use gltf_json as json;
use json::validation::Checked::Valid;

use super::gltf_doc::{GltfBuilder, Written};
use crate::cloth::FrameCache;
use crate::error::{Error, Result};
use crate::mesh::{vertex_normals, Mesh};

/// How weights are interpolated between frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
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
}

/// Render-vertex positions and normals of one frame.
pub struct RenderFrame {
    /// Position per render vertex, m.
    pub positions: Vec<Vec3>,
    /// Unit normal per render vertex.
    pub normals: Vec<Vec3>,
}

/// Maps particle positions to render vertices, with smooth normals from the surface triangles.
pub fn render_frame(mesh: &Mesh, particles: &[Vec3], scratch: &mut Vec<DVec3>) -> RenderFrame {
    let p64: Vec<DVec3> = particles.iter().map(|p| p.as_dvec3()).collect();
    vertex_normals(&p64, &mesh.triangles, scratch);
    RenderFrame {
        positions: mesh
            .render_vertices
            .iter()
            .map(|v| particles[v.particle as usize])
            .collect(),
        normals: mesh
            .render_vertices
            .iter()
            .map(|v| scratch[v.particle as usize].as_vec3())
            .collect(),
    }
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
    if cache.particle_count() != mesh.particle_count() || cache.frame_count() < 2 {
        return Err(Error::Export {
            path: path.into(),
            message: format!(
                "cache of {} frames × {} particles does not fit a mesh of {} particles",
                cache.frame_count(),
                cache.particle_count(),
                mesh.particle_count()
            ),
        });
    }
    let mut b = GltfBuilder::new();
    let mut scratch = Vec::new();
    let base = render_frame(mesh, cache.frame(0), &mut scratch);
    let array = Some(json::buffer::Target::ArrayBuffer);

    let mut attributes = std::collections::BTreeMap::new();
    attributes.insert(
        Valid(json::mesh::Semantic::Positions),
        b.vec3(&base.positions, array, true),
    );
    if options.normals {
        attributes.insert(
            Valid(json::mesh::Semantic::Normals),
            b.vec3(&base.normals, array, false),
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
    let indices = b.indices(&indices);

    let frames = cache.frame_count();
    let mut targets = Vec::with_capacity(frames - 1);
    let mut names = Vec::with_capacity(frames - 1);
    for k in 1..frames {
        let f = render_frame(mesh, cache.frame(k), &mut scratch);
        let dp: Vec<Vec3> = f
            .positions
            .iter()
            .zip(&base.positions)
            .map(|(p, q)| *p - *q)
            .collect();
        let positions = Some(b.vec3(&dp, array, true));
        let normals = options.normals.then(|| {
            let dn: Vec<Vec3> = f
                .normals
                .iter()
                .zip(&base.normals)
                .map(|(n, m)| *n - *m)
                .collect();
            b.vec3(&dn, array, false)
        });
        targets.push(json::mesh::MorphTarget {
            positions,
            normals,
            tangents: None,
        });
        names.push(format!("frame_{k:04}"));
    }

    let material = b.root.push(json::Material {
        name: Some("cloth".into()),
        double_sided: true,
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([0.8, 0.45, 0.3, 1.0]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(0.8),
            ..Default::default()
        },
        ..Default::default()
    });
    let target_count = targets.len();
    let gmesh = b.root.push(json::Mesh {
        name: Some(options.name.clone()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            indices: Some(indices),
            material: Some(material),
            mode: Valid(json::mesh::Mode::Triangles),
            targets: Some(targets),
            extensions: None,
            extras: Default::default(),
        }],
        weights: Some(vec![0.0; target_count]),
        extensions: None,
        extras: Some(
            serde_json::value::to_raw_value(&serde_json::json!({ "targetNames": names })).map_err(
                |error| Error::Json {
                    path: path.into(),
                    error,
                },
            )?,
        ),
    });
    let node = b.root.push(json::Node {
        name: Some(options.name.clone()),
        mesh: Some(gmesh),
        ..Default::default()
    });
    let scene = b.root.push(json::Scene {
        name: Some("scenebake".into()),
        nodes: vec![node],
        extensions: None,
        extras: Default::default(),
    });
    b.root.scene = Some(scene);

    // Weights: all zero at frame 0, one-hot on target k-1 at frame k.
    let times: Vec<f32> = (0..frames)
        .map(|k| (k as f64 / options.fps) as f32)
        .collect();
    let mut weights = vec![0.0f32; frames * target_count];
    for k in 1..frames {
        weights[k * target_count + (k - 1)] = 1.0;
    }
    let input = b.scalars(&times, true);
    let output = b.scalars(&weights, false);
    let interpolation = match options.interpolation {
        Interpolation::Linear => json::animation::Interpolation::Linear,
        Interpolation::Step => json::animation::Interpolation::Step,
    };
    b.root.push(json::Animation {
        name: Some(options.name.clone()),
        channels: vec![json::animation::Channel {
            sampler: json::Index::new(0),
            target: json::animation::Target {
                node,
                path: Valid(json::animation::Property::MorphTargetWeights),
                extensions: None,
                extras: Default::default(),
            },
            extensions: None,
            extras: Default::default(),
        }],
        samplers: vec![json::animation::Sampler {
            input,
            output,
            interpolation: Valid(interpolation),
            extensions: None,
            extras: Default::default(),
        }],
        extensions: None,
        extras: Default::default(),
    });
    b.write(path)
}

/// OBJ texture coordinates have v up; glTF's have v down.
fn flip_v(uv: [f32; 2]) -> [f32; 2] {
    [uv[0], 1.0 - uv[1]]
}
