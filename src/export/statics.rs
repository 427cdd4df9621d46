//! Static, unanimated meshes written beside the cloth: the colliders, so that Blender shows what
//! the cloth lies on.
//!
//! Each [`StaticMesh`] becomes its own glTF node and mesh (POSITION with min/max, NORMAL,
//! indices, a neutral grey material) after the cloth's, with no morph targets and no animation.

use gltf_json as json;
use json::validation::Checked::Valid;

use super::gltf_doc::{primitive, GltfBuilder};
pub use crate::data::StaticMesh;

/// Makes the document's one scene: the animated `node` first, then `statics` (as
/// [`push_static_meshes`]). Returns the bytes the static meshes added to the buffer.
pub(crate) fn push_scene(
    b: &mut GltfBuilder,
    node: json::Index<json::Node>,
    statics: &[StaticMesh],
) -> u64 {
    let start = b.buffer_len();
    let mut nodes = vec![node];
    nodes.extend(push_static_meshes(b, statics));
    let bytes = (b.buffer_len() - start) as u64;
    let scene = b.root.push(json::Scene {
        name: Some("scenebake".into()),
        nodes,
        extensions: None,
        extras: Default::default(),
    });
    b.root.scene = Some(scene);
    bytes
}

/// Writes `statics` into `b` as one node each (with its mesh and a shared grey material) and
/// returns the nodes, in order. The caller has checked [`StaticMesh::problem`].
pub(crate) fn push_static_meshes(
    b: &mut GltfBuilder,
    statics: &[StaticMesh],
) -> Vec<json::Index<json::Node>> {
    if statics.is_empty() {
        return Vec::new();
    }
    let material = b.root.push(json::Material {
        name: Some("static".into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor([0.6, 0.6, 0.6, 1.0]),
            metallic_factor: json::material::StrengthFactor(0.0),
            roughness_factor: json::material::StrengthFactor(0.9),
            ..Default::default()
        },
        ..Default::default()
    });
    let array = Some(json::buffer::Target::ArrayBuffer);
    statics
        .iter()
        .map(|s| {
            let mut attributes = std::collections::BTreeMap::new();
            attributes.insert(
                Valid(json::mesh::Semantic::Positions),
                b.vec3(&s.positions, array, true),
            );
            attributes.insert(
                Valid(json::mesh::Semantic::Normals),
                b.vec3(&s.normals, array, false),
            );
            let indices = b.indices(&s.indices);
            let mesh = b.root.push(json::Mesh {
                name: Some(s.name.clone()),
                primitives: vec![primitive(
                    attributes,
                    Some(indices),
                    material,
                    json::mesh::Mode::Triangles,
                )],
                weights: None,
                extensions: None,
                extras: Default::default(),
            });
            b.root.push(json::Node {
                name: Some(s.name.clone()),
                mesh: Some(mesh),
                ..Default::default()
            })
        })
        .collect()
}
