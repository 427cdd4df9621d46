//! IK export: joint rotations as LINEAR quaternion channels, one key per frame.
//!
//! For a generated chain the document is built from scratch: joint nodes `joint_0`… (parented in
//! order, rest translation = offset), a skinned arm mesh (a tapered box per bone, each rigidly
//! weighted to its bone's joint) at the scene root, a pen-tip marker under the end effector, the
//! target path as a LINES mesh (a guide for viewers that draw lines; renderers skip it), and the
//! drawn trail as tube pieces ([`super::tube`]) revealed one after another by STEP scale keys
//! (half a frame before the frame that draws each piece's end). For a rig the input document is
//! written back with one animation added, and the drawn trail (the same tubes, in the
//! document's world frame, revealed by that animation) at the root of its scene.
//!
//! Quaternions are written (x, y, z, w), normalised in `f32` and sign-continuous (each key is
//! negated if needed to lie in the same hemisphere as the previous one).

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DMat4, DQuat, DVec3, Vec3};
use gltf_json as json;
use json::validation::Checked::Valid;

use super::gltf_doc::{channel, primitive, sampler, GltfBuilder, Written};
use crate::data::animation::Trs;
use crate::data::chain::{Chain, Pose};
use crate::error::Result;
use crate::io::rig::RigDocument;
use crate::path::PenTarget;

/// Scale of a trail piece before it is revealed (the validator dislikes exactly 0).
pub const HIDDEN_SCALE: f32 = 1e-4;
/// Frames per trail piece.
const TRAIL_PIECE: usize = 12;

/// The pen's drawn trail, written as tubes ([`super::tube`]).
#[derive(Debug, Clone, Copy)]
pub struct Trail<'a> {
    /// The pen path, one target per frame (its strokes say when the pen is down).
    pub targets: &'a [PenTarget],
    /// The end-effector positions reached, one per frame, in the document's world frame.
    pub tips: &'a [DVec3],
    /// Tube radius, scene units.
    pub radius: f64,
}

/// Per-frame local transforms of a set of nodes: an animation the IK is layered on, with the
/// chain's solved rotations already in place. Written as one TRS key per frame and node.
#[derive(Debug, Clone, Copy)]
pub struct NodeFrames<'a> {
    /// Node indices, sorted.
    pub nodes: &'a [usize],
    /// Local transforms, frame-major: `trs[k * nodes.len() + j]` is `nodes[j]` at frame k.
    pub trs: &'a [Trs],
}

/// Baked joint rotations.
#[derive(Debug, Clone, Copy)]
pub struct IkFrames<'a> {
    /// Frames per second; frame k is keyed at k / fps seconds.
    pub fps: f64,
    /// Joints per frame.
    pub joints: usize,
    /// Local rotations, frame-major: `rotations[k * joints + i]` is joint i at frame k.
    pub rotations: &'a [DQuat],
    /// Animation name.
    pub name: &'a str,
}

impl IkFrames<'_> {
    fn frames(&self) -> usize {
        self.rotations.len() / self.joints.max(1)
    }

    fn times(&self) -> Vec<f32> {
        (0..self.frames())
            .map(|k| (k as f64 / self.fps) as f32)
            .collect()
    }

    /// Number of joints to key: all of them when the end effector turns (a tip axis), else all
    /// but the end effector (its rotation moves nothing and stays at rest).
    fn keyed(&self, chain: &Chain) -> usize {
        let tip = self.joints - 1;
        let rest = chain.joints()[tip].rotation;
        let turns = (0..self.frames())
            .any(|k| self.rotations[k * self.joints + tip].dot(rest).abs() < 1.0 - 1e-12);
        if turns {
            self.joints
        } else {
            tip
        }
    }

    /// Normalised, sign-continuous keys of joint i.
    fn keys(&self, i: usize) -> Vec<[f32; 4]> {
        let mut out: Vec<[f32; 4]> = Vec::with_capacity(self.frames());
        for k in 0..self.frames() {
            let q = self.rotations[k * self.joints + i].as_quat().normalize();
            let mut a = q.to_array();
            if let Some(prev) = out.last() {
                let dot: f32 = prev.iter().zip(&a).map(|(x, y)| x * y).sum();
                if dot < 0.0 {
                    a = a.map(|x| -x);
                }
            }
            out.push(a);
        }
        out
    }
}

fn rotation_channels(
    b: &mut GltfBuilder,
    frames: &IkFrames<'_>,
    joints: &[(usize, json::Index<json::Node>)],
) -> (Vec<json::animation::Channel>, Vec<json::animation::Sampler>) {
    let input = b.scalars(&frames.times(), true);
    let mut channels = Vec::new();
    let mut samplers = Vec::new();
    for &(i, node) in joints {
        let output = b.vec4(&frames.keys(i), None);
        channels.push(channel(
            samplers.len(),
            node,
            json::animation::Property::Rotation,
        ));
        samplers.push(sampler(
            input,
            output,
            json::animation::Interpolation::Linear,
        ));
    }
    (channels, samplers)
}

fn material(
    b: &mut GltfBuilder,
    name: &str,
    rgba: [f32; 4],
    metallic: f32,
) -> json::Index<json::Material> {
    b.root.push(json::Material {
        name: Some(name.into()),
        pbr_metallic_roughness: json::material::PbrMetallicRoughness {
            base_color_factor: json::material::PbrBaseColorFactor(rgba),
            metallic_factor: json::material::StrengthFactor(metallic),
            roughness_factor: json::material::StrengthFactor(0.6),
            ..Default::default()
        },
        ..Default::default()
    })
}

fn mesh(
    b: &mut GltfBuilder,
    name: &str,
    primitives: Vec<json::mesh::Primitive>,
) -> json::Index<json::Mesh> {
    b.root.push(json::Mesh {
        name: Some(name.into()),
        primitives,
        weights: None,
        extensions: None,
        extras: Default::default(),
    })
}

fn f32v(v: DVec3) -> [f32; 3] {
    v.as_vec3().to_array()
}

/// A tapered box from `a` to `b`: square sections of half-width `w0` at `a` and `w1` at `b`,
/// 24 vertices (flat normals) and 12 triangles, appended to the buffers.
fn tapered_box(
    a: DVec3,
    b: DVec3,
    w0: f64,
    w1: f64,
    pos: &mut Vec<Vec3>,
    nrm: &mut Vec<Vec3>,
    idx: &mut Vec<u32>,
) {
    let axis = (b - a).normalize();
    let side = axis.any_orthonormal_vector();
    let other = axis.cross(side);
    let corner = |base: DVec3, w: f64, k: usize| {
        let (s, o) = [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)][k];
        base + side * (s * w) + other * (o * w)
    };
    let lo: Vec<DVec3> = (0..4).map(|k| corner(a, w0, k)).collect();
    let hi: Vec<DVec3> = (0..4).map(|k| corner(b, w1, k)).collect();
    let mut quad = |q: [DVec3; 4]| {
        let n = (q[1] - q[0])
            .cross(q[2] - q[0])
            .normalize_or_zero()
            .as_vec3();
        let start = pos.len() as u32;
        for p in q {
            pos.push(p.as_vec3());
            nrm.push(n);
        }
        idx.extend_from_slice(&[start, start + 1, start + 2, start, start + 2, start + 3]);
    };
    for k in 0..4 {
        let k1 = (k + 1) % 4;
        quad([lo[k], lo[k1], hi[k1], hi[k]]);
    }
    quad([lo[3], lo[2], lo[1], lo[0]]);
    quad([hi[0], hi[1], hi[2], hi[3]]);
}

/// Adds the drawn trail under a `trail` node (returned; `None` when the pen never drew): per
/// stroke, a tube of `trail.radius` around the reached tip positions, cut into pieces of
/// [`TRAIL_PIECE`] frames (`trail_000`, ...), each revealed (scale from [`HIDDEN_SCALE`] to 1,
/// STEP, about its first point) half a frame before the frame that draws its last point, so
/// every viewer shows it from that frame on (a STEP key exactly on a frame is at the mercy of
/// f32 rounding of the key time).
fn trail_nodes(
    b: &mut GltfBuilder,
    frames: &IkFrames<'_>,
    trail: &Trail<'_>,
    channels: &mut Vec<json::animation::Channel>,
    samplers: &mut Vec<json::animation::Sampler>,
) -> Option<json::Index<json::Node>> {
    let array = Some(json::buffer::Target::ArrayBuffer);
    let targets = trail.targets;
    let trail_mat = material(b, "trail", [0.02, 0.04, 0.2, 1.0], 0.0);
    let mut pieces = Vec::new();
    let mut k = 0;
    while k < targets.len() {
        let Some(stroke) = targets[k].stroke else {
            k += 1;
            continue;
        };
        let mut last = k;
        while last + 1 < targets.len() && targets[last + 1].stroke == Some(stroke) {
            last += 1;
        }
        let points = &trail.tips[k..=last];
        let tube = super::tube::Tube::new(points, trail.radius);
        let mut from = 0;
        while from < points.len() {
            let to = (from + TRAIL_PIECE - 1).min(points.len() - 1);
            let origin = points[from];
            let m = tube.mesh(from, to, origin);
            let end = k + to;
            from = to + 1;
            if m.indices.is_empty() {
                continue;
            }
            let name = format!("trail_{:03}", pieces.len());
            let mut attrs = BTreeMap::new();
            attrs.insert(
                Valid(json::mesh::Semantic::Positions),
                b.vec3(&m.positions, array, true),
            );
            attrs.insert(
                Valid(json::mesh::Semantic::Normals),
                b.vec3(&m.normals, array, false),
            );
            let indices = b.indices(&m.indices);
            let mesh = mesh(
                b,
                &name,
                vec![primitive(
                    attrs,
                    Some(indices),
                    trail_mat,
                    json::mesh::Mode::Triangles,
                )],
            );
            let hidden = end > 0;
            let node = b.root.push(json::Node {
                name: Some(name),
                mesh: Some(mesh),
                translation: Some(f32v(origin)),
                scale: hidden.then_some([HIDDEN_SCALE; 3]),
                ..Default::default()
            });
            if hidden {
                let reveal = ((end as f64 - 0.5) / frames.fps) as f32;
                let input = b.scalars(&[0.0, reveal], true);
                let output = b.vec3(&[Vec3::splat(HIDDEN_SCALE), Vec3::ONE], None, false);
                channels.push(channel(
                    samplers.len(),
                    node,
                    json::animation::Property::Scale,
                ));
                samplers.push(sampler(input, output, json::animation::Interpolation::Step));
            }
            pieces.push(node);
        }
        k = last + 1;
    }
    (!pieces.is_empty()).then(|| {
        b.root.push(json::Node {
            name: Some("trail".into()),
            children: Some(pieces),
            ..Default::default()
        })
    })
}

/// Adds `node` to the roots of the document's default scene (the first when none is set).
fn add_to_scene(root: &mut json::Root, node: json::Index<json::Node>) {
    let scene = root.scene.map_or(0, |s| s.value());
    if let Some(s) = root.scenes.get_mut(scene) {
        s.nodes.push(node);
    }
}

/// Writes a generated chain's bake: armature, skinned arm, pen marker, target path, trail.
/// `rest` is the chain's rest pose (bind pose); `trail` holds the pen path and the end-effector
/// positions reached (one per frame).
///
/// # Errors
/// Write errors ([`crate::Error::Io`], [`crate::Error::Export`]).
pub fn write_chain_gltf(
    path: &Path,
    chain: &Chain,
    rest: &Pose,
    frames: &IkFrames<'_>,
    trail: &Trail<'_>,
) -> Result<Written> {
    let mut b = GltfBuilder::new();
    let n = chain.len();
    let reach = chain.reach(rest).max(1e-9);
    let array = Some(json::buffer::Target::ArrayBuffer);

    // Joint nodes, parented in order (pushed first so joint i is node i).
    let joint_nodes: Vec<json::Index<json::Node>> =
        (0..n).map(|i| json::Index::new(i as u32)).collect();
    for (i, j) in chain.joints().iter().enumerate() {
        let mut children = Vec::new();
        if i + 1 < n {
            children.push(joint_nodes[i + 1]);
        }
        let r = j.rotation.as_quat().normalize();
        b.root.push(json::Node {
            name: Some(j.name.clone()),
            translation: Some(f32v(j.translation)),
            rotation: (r != glam::Quat::IDENTITY)
                .then(|| json::scene::UnitQuaternion(r.to_array())),
            scale: (j.scale != DVec3::ONE).then(|| f32v(j.scale)),
            children: (!children.is_empty()).then_some(children),
            ..Default::default()
        });
    }

    // Skinned arm: a tapered box per bone, rigidly weighted to the bone's joint.
    let (mut pos, mut nrm, mut idx, mut jnt) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..n - 1 {
        let (a, c) = (rest.position(i), rest.position(i + 1));
        let before = pos.len();
        let w = reach * 0.025;
        tapered_box(a, c, w, w * 0.6, &mut pos, &mut nrm, &mut idx);
        jnt.extend(std::iter::repeat_n(i, pos.len() - before));
    }
    // Joint indices as u8 when they fit, else u16 (both valid for JOINTS_0).
    let (bytes, component): (Vec<u8>, _) = if n <= 256 {
        (
            jnt.iter().flat_map(|&j| [j as u8, 0, 0, 0]).collect(),
            json::accessor::ComponentType::U8,
        )
    } else {
        (
            jnt.iter()
                .flat_map(|&j| [j as u16, 0, 0, 0])
                .flat_map(u16::to_le_bytes)
                .collect(),
            json::accessor::ComponentType::U16,
        )
    };
    let joints_acc = b.accessor(
        &bytes,
        jnt.len(),
        json::accessor::Type::Vec4,
        component,
        array,
        None,
        false,
    );
    let weights: Vec<[f32; 4]> = vec![[1.0, 0.0, 0.0, 0.0]; jnt.len()];
    let mut attrs = BTreeMap::new();
    attrs.insert(
        Valid(json::mesh::Semantic::Positions),
        b.vec3(&pos, array, true),
    );
    attrs.insert(
        Valid(json::mesh::Semantic::Normals),
        b.vec3(&nrm, array, false),
    );
    attrs.insert(Valid(json::mesh::Semantic::Joints(0)), joints_acc);
    attrs.insert(
        Valid(json::mesh::Semantic::Weights(0)),
        b.vec4(&weights, array),
    );
    let indices = b.indices(&idx);
    let arm_mat = material(&mut b, "arm", [0.75, 0.75, 0.78, 1.0], 0.3);
    let arm_mesh = mesh(
        &mut b,
        "arm",
        vec![primitive(
            attrs,
            Some(indices),
            arm_mat,
            json::mesh::Mode::Triangles,
        )],
    );
    let ibm: Vec<[f32; 16]> = (0..n)
        .map(|i| {
            DMat4::from(rest.world[i])
                .inverse()
                .as_mat4()
                .to_cols_array()
        })
        .collect();
    let ibm = b.mat4(&ibm);
    let skin = b.root.push(json::Skin {
        name: Some("arm".into()),
        inverse_bind_matrices: Some(ibm),
        joints: joint_nodes.clone(),
        skeleton: Some(joint_nodes[0]),
        extensions: None,
        extras: Default::default(),
    });
    let arm = b.root.push(json::Node {
        name: Some("arm".into()),
        mesh: Some(arm_mesh),
        skin: Some(skin),
        ..Default::default()
    });

    // Pen-tip marker: an octahedron under the end effector.
    let s = (reach * 0.015) as f32;
    let oct: Vec<Vec3> = vec![
        Vec3::X * s,
        -Vec3::X * s,
        Vec3::Y * s,
        -Vec3::Y * s,
        Vec3::Z * s,
        -Vec3::Z * s,
    ];
    let oct_idx: Vec<u32> = vec![
        0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5,
    ];
    let mut attrs = BTreeMap::new();
    attrs.insert(
        Valid(json::mesh::Semantic::Positions),
        b.vec3(&oct, array, true),
    );
    let oct_idx = b.indices(&oct_idx);
    let pen_mat = material(&mut b, "pen", [0.9, 0.1, 0.1, 1.0], 0.0);
    let pen_mesh = mesh(
        &mut b,
        "pen_tip",
        vec![primitive(
            attrs,
            Some(oct_idx),
            pen_mat,
            json::mesh::Mode::Triangles,
        )],
    );
    let pen = b.root.push(json::Node {
        name: Some("pen_tip".into()),
        mesh: Some(pen_mesh),
        ..Default::default()
    });
    b.root.nodes[n - 1].children = Some(vec![pen]);

    let mut scene_nodes = vec![joint_nodes[0], arm];

    // Target path: the pen-down segments of the path, as LINES.
    let mut line_pos = Vec::new();
    for w in trail.targets.windows(2) {
        if w[0].stroke.is_some() && w[0].stroke == w[1].stroke {
            line_pos.push(w[0].position.as_vec3());
            line_pos.push(w[1].position.as_vec3());
        }
    }
    let path_mat = material(&mut b, "target_path", [0.1, 0.35, 0.9, 1.0], 0.0);
    if !line_pos.is_empty() {
        let mut attrs = BTreeMap::new();
        attrs.insert(
            Valid(json::mesh::Semantic::Positions),
            b.vec3(&line_pos, array, true),
        );
        let m = mesh(
            &mut b,
            "target_path",
            vec![primitive(attrs, None, path_mat, json::mesh::Mode::Lines)],
        );
        scene_nodes.push(b.root.push(json::Node {
            name: Some("target_path".into()),
            mesh: Some(m),
            ..Default::default()
        }));
    }

    let (mut channels, mut samplers) = rotation_channels(
        &mut b,
        frames,
        &(0..frames.keyed(chain))
            .map(|i| (i, joint_nodes[i]))
            .collect::<Vec<_>>(),
    );
    if let Some(node) = trail_nodes(&mut b, frames, trail, &mut channels, &mut samplers) {
        scene_nodes.push(node);
    }

    b.root.push(json::Animation {
        name: Some(frames.name.into()),
        channels,
        samplers,
        extensions: None,
        extras: Default::default(),
    });
    super::playback::stamp(
        &mut b.root,
        &super::playback::Playback::frames(frames.fps, frames.frames(), frames.name),
    );
    let scene = b.root.push(json::Scene {
        name: Some("scenebake ik".into()),
        nodes: scene_nodes,
        extensions: None,
        extras: Default::default(),
    });
    b.root.scene = Some(scene);
    b.write(path)
}

/// Writes `doc` back with one animation added, placed first in `animations` (viewers play the
/// first animation: Blender makes it the active action, three.js loaders list it first):
/// rotation channels for the chain joints `nodes` (all but the tip, whose rotation does not move
/// the end effector), and constant channels (their node transforms, keyed at the first and last
/// frame) for every other transform of every joint of the skins the chain belongs to, and of the
/// nodes between those joints. So the animation gives every bone a defined pose: Blender keeps a
/// bone's pose from the previously active action where the new action has no key for it.
///
/// Keyed nodes stored as a `matrix` are rewritten as the equivalent translation/rotation/scale,
/// as glTF requires for animated nodes. Nodes holding a skinned mesh that are not scene roots are
/// moved to the root of their scenes (glTF ignores parent transforms for skinned meshes, so
/// nothing changes visually, and the validator warns otherwise). Everything else (meshes, skins,
/// materials, textures, existing animations) is kept; the new data is appended to the single
/// binary buffer. The bake's fps and frame range go into `asset.extras` (see
/// [`super::playback`]). The drawn `trail` is added at the root of the default scene, its
/// reveal keyed in the new animation (see [`write_chain_gltf`]).
///
/// # Errors
/// Write errors ([`crate::Error::Io`], [`crate::Error::Export`]).
pub fn write_rig_gltf(
    path: &Path,
    doc: RigDocument,
    chain: &Chain,
    nodes: &[usize],
    frames: &IkFrames<'_>,
    layer: Option<&NodeFrames<'_>>,
    trail: &Trail<'_>,
) -> Result<Written> {
    let mut b = GltfBuilder::from_parts(doc.root, doc.bin);
    for (i, &node) in nodes.iter().enumerate() {
        let nd = &mut b.root.nodes[node];
        if nd.matrix.is_some() {
            let j = &chain.joints()[i];
            nd.matrix = None;
            nd.translation = Some(f32v(j.translation));
            nd.rotation = Some(json::scene::UnitQuaternion(
                j.rotation.as_quat().normalize().to_array(),
            ));
            nd.scale = Some(f32v(j.scale));
        }
    }
    lift_skinned_meshes_to_root(&mut b.root);
    if let Some(layer) = layer {
        let (mut channels, mut samplers) = layer_channels(&mut b, frames, layer);
        if let Some(node) = trail_nodes(&mut b, frames, trail, &mut channels, &mut samplers) {
            add_to_scene(&mut b.root, node);
        }
        b.root.animations.insert(
            0,
            json::Animation {
                name: Some(frames.name.into()),
                channels,
                samplers,
                extensions: None,
                extras: Default::default(),
            },
        );
        super::playback::stamp(
            &mut b.root,
            &super::playback::Playback::frames(frames.fps, frames.frames(), frames.name),
        );
        return b.write(path);
    }
    let keyed = frames.keyed(chain);
    let animated: Vec<(usize, json::Index<json::Node>)> = nodes[..keyed]
        .iter()
        .enumerate()
        .map(|(i, &nd)| (i, json::Index::new(nd as u32)))
        .collect();
    let (mut channels, mut samplers) = rotation_channels(&mut b, frames, &animated);
    hold_channels(&mut b, frames, nodes, keyed, &mut channels, &mut samplers);
    if let Some(node) = trail_nodes(&mut b, frames, trail, &mut channels, &mut samplers) {
        add_to_scene(&mut b.root, node);
    }
    b.root.animations.insert(
        0,
        json::Animation {
            name: Some(frames.name.into()),
            channels,
            samplers,
            extensions: None,
            extras: Default::default(),
        },
    );
    super::playback::stamp(
        &mut b.root,
        &super::playback::Playback::frames(frames.fps, frames.frames(), frames.name),
    );
    b.write(path)
}

/// The nodes a skinning viewer poses with the chain `nodes`: every joint of each skin holding a
/// chain node, the nodes between those joints (Blender makes them bones too), and the chain
/// itself; sorted.
pub fn posed_nodes(root: &json::Root, nodes: &[usize]) -> Vec<usize> {
    let mut parents = vec![None; root.nodes.len()];
    for (i, n) in root.nodes.iter().enumerate() {
        for c in n.children.iter().flatten() {
            if let Some(p) = parents.get_mut(c.value()) {
                *p = Some(i);
            }
        }
    }
    let mut posed = vec![false; root.nodes.len()];
    for &n in nodes {
        posed[n] = true;
    }
    for skin in &root.skins {
        let joints: Vec<usize> = skin.joints.iter().map(|j| j.value()).collect();
        if !joints.iter().any(|j| nodes.contains(j)) {
            continue;
        }
        let is_joint = |i: usize| joints.contains(&i);
        for &j in &joints {
            posed[j] = true;
            // Walk up to the nearest ancestor joint; the nodes passed on the way are between
            // joints. The walk is bounded in case the hierarchy has a cycle.
            let mut between = Vec::new();
            let mut cur = parents[j];
            let mut steps = 0;
            while let Some(p) = cur {
                if is_joint(p) {
                    for &n in &between {
                        posed[n] = true;
                    }
                    break;
                }
                between.push(p);
                cur = parents[p];
                steps += 1;
                if steps > root.nodes.len() {
                    break;
                }
            }
        }
    }
    (0..posed.len()).filter(|&i| posed[i]).collect()
}

/// Constant channels holding every transform the chain's rotation keys leave out, for every
/// node of [`posed_nodes`]: LINEAR keys at the first and last frame time, with the node's own
/// translation, rotation and scale (node matrices are decomposed and replaced by TRS).
fn hold_channels(
    b: &mut GltfBuilder,
    frames: &IkFrames<'_>,
    chain_nodes: &[usize],
    keyed: usize,
    channels: &mut Vec<json::animation::Channel>,
    samplers: &mut Vec<json::animation::Sampler>,
) {
    let rotated = &chain_nodes[..keyed];
    let posed = posed_nodes(&b.root, chain_nodes);
    let end = frames.times().last().copied().unwrap_or(0.0);
    let times: Vec<f32> = if end > 0.0 { vec![0.0, end] } else { vec![0.0] };
    let skip = |node: usize, p| p == json::animation::Property::Rotation && rotated.contains(&node);
    push_hold_channels(b, &posed, &times, &skip, channels, samplers);
}

/// Constant LINEAR channels (the node's own transform, keyed at each of `times`, seconds) for
/// the translation, rotation and scale of each of `nodes`, except where `skip(node, property)`.
/// Nodes stored as a `matrix` are rewritten as translation/rotation/scale.
pub(crate) fn push_hold_channels(
    b: &mut GltfBuilder,
    nodes: &[usize],
    times: &[f32],
    skip: &dyn Fn(usize, json::animation::Property) -> bool,
    channels: &mut Vec<json::animation::Channel>,
    samplers: &mut Vec<json::animation::Sampler>,
) {
    if nodes.is_empty() {
        return;
    }
    let key = LinearKeys {
        input: b.scalars(times, true),
        count: times.len(),
    };
    for &node in nodes {
        let (t, r, s) = node_trs_f32(&mut b.root.nodes[node]);
        let index = json::Index::new(node as u32);
        let repeat = |v: &[f32]| super::gltf_doc::f32_bytes(times.iter().flat_map(|_| v.to_vec()));
        for (property, bytes, type_) in [
            (
                json::animation::Property::Translation,
                repeat(&t),
                json::accessor::Type::Vec3,
            ),
            (
                json::animation::Property::Rotation,
                repeat(&r),
                json::accessor::Type::Vec4,
            ),
            (
                json::animation::Property::Scale,
                repeat(&s),
                json::accessor::Type::Vec3,
            ),
        ] {
            if skip(node, property) {
                continue;
            }
            key.push(b, index, property, &bytes, type_, channels, samplers);
        }
    }
}

/// The shared time accessor (`count` keys) of LINEAR channels written one after another.
#[derive(Clone, Copy)]
struct LinearKeys {
    input: json::Index<json::Accessor>,
    count: usize,
}

impl LinearKeys {
    /// Adds a LINEAR channel for `property` of `node`, its values `bytes` (f32, `type_`, one per
    /// key).
    #[allow(clippy::too_many_arguments)]
    fn push(
        self,
        b: &mut GltfBuilder,
        node: json::Index<json::Node>,
        property: json::animation::Property,
        bytes: &[u8],
        type_: json::accessor::Type,
        channels: &mut Vec<json::animation::Channel>,
        samplers: &mut Vec<json::animation::Sampler>,
    ) {
        let output = b.accessor(
            bytes,
            self.count,
            type_,
            json::accessor::ComponentType::F32,
            None,
            None,
            false,
        );
        channels.push(channel(samplers.len(), node, property));
        samplers.push(sampler(
            self.input,
            output,
            json::animation::Interpolation::Linear,
        ));
    }
}

/// One LINEAR key per frame for the translation, rotation and scale of every node of `layer`
/// (quaternions normalised and sign-continuous).
fn layer_channels(
    b: &mut GltfBuilder,
    frames: &IkFrames<'_>,
    layer: &NodeFrames<'_>,
) -> (Vec<json::animation::Channel>, Vec<json::animation::Sampler>) {
    let times = frames.times();
    let input = b.scalars(&times, true);
    let count = layer.nodes.len();
    let mut channels = Vec::new();
    let mut samplers = Vec::new();
    for (j, &node) in layer.nodes.iter().enumerate() {
        node_trs_f32(&mut b.root.nodes[node]);
        let at = |k: usize| &layer.trs[k * count + j];
        let translations: Vec<f32> = (0..times.len())
            .flat_map(|k| at(k).translation.as_vec3().to_array())
            .collect();
        let scales: Vec<f32> = (0..times.len())
            .flat_map(|k| at(k).scale.as_vec3().to_array())
            .collect();
        let mut rotations: Vec<[f32; 4]> = Vec::with_capacity(times.len());
        for k in 0..times.len() {
            let mut a = at(k).rotation.as_quat().normalize().to_array();
            if let Some(prev) = rotations.last() {
                let dot: f32 = prev.iter().zip(&a).map(|(x, y)| x * y).sum();
                if dot < 0.0 {
                    a = a.map(|x| -x);
                }
            }
            rotations.push(a);
        }
        let index = json::Index::new(node as u32);
        let key = LinearKeys {
            input,
            count: times.len(),
        };
        for (property, bytes, type_) in [
            (
                json::animation::Property::Translation,
                super::gltf_doc::f32_bytes(translations.into_iter()),
                json::accessor::Type::Vec3,
            ),
            (
                json::animation::Property::Rotation,
                super::gltf_doc::f32_bytes(rotations.into_iter().flatten()),
                json::accessor::Type::Vec4,
            ),
            (
                json::animation::Property::Scale,
                super::gltf_doc::f32_bytes(scales.into_iter()),
                json::accessor::Type::Vec3,
            ),
        ] {
            key.push(
                b,
                index,
                property,
                &bytes,
                type_,
                &mut channels,
                &mut samplers,
            );
        }
    }
    (channels, samplers)
}

/// A node's translation, rotation (x, y, z, w; unit) and scale; a `matrix` is decomposed and
/// replaced by the equivalent TRS (glTF forbids animating matrix nodes).
fn node_trs_f32(node: &mut json::Node) -> ([f32; 3], [f32; 4], [f32; 3]) {
    if let Some(m) = node.matrix.take() {
        let (s, r, t) = glam::Mat4::from_cols_array(&m).to_scale_rotation_translation();
        node.translation = Some(t.to_array());
        node.rotation = Some(json::scene::UnitQuaternion(r.normalize().to_array()));
        node.scale = Some(s.to_array());
    }
    let t = node.translation.unwrap_or([0.0; 3]);
    let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| {
        glam::Quat::from_array(q.0).normalize().to_array()
    });
    let s = node.scale.unwrap_or([1.0; 3]);
    (t, r, s)
}

/// Moves nodes with a skinned mesh that have a parent to the root of the scenes holding that
/// parent's hierarchy.
pub(crate) fn lift_skinned_meshes_to_root(root: &mut json::Root) {
    let mut parents = vec![None; root.nodes.len()];
    for (i, n) in root.nodes.iter().enumerate() {
        for c in n.children.iter().flatten() {
            if let Some(p) = parents.get_mut(c.value()) {
                *p = Some(i);
            }
        }
    }
    for i in 0..root.nodes.len() {
        let (Some(parent), true) = (
            parents[i],
            root.nodes[i].skin.is_some() && root.nodes[i].mesh.is_some(),
        ) else {
            continue;
        };
        if let Some(children) = root.nodes[parent].children.as_mut() {
            children.retain(|c| c.value() != i);
            if children.is_empty() {
                root.nodes[parent].children = None;
            }
        }
        let mut top = parent;
        let mut guard = 0;
        while let Some(p) = parents[top] {
            top = p;
            guard += 1;
            if guard > parents.len() {
                break;
            }
        }
        let node = json::Index::new(i as u32);
        for scene in &mut root.scenes {
            if scene.nodes.iter().any(|n| n.value() == top) && !scene.nodes.contains(&node) {
                scene.nodes.push(node);
            }
        }
        parents[i] = None;
    }
}
