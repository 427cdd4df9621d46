//! Chains taken from rigged glTF documents (`--rig FILE --chain ROOT..TIP`).
//!
//! The document is kept whole so the bake can write it back with one animation added. All its
//! buffers are merged into one binary buffer (for a GLB, the BIN chunk stays first and unchanged,
//! so new data is appended to it), and images stored in external files are embedded, so the
//! result can be written as `.glb` or `.gltf` anywhere.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat4, DQuat, DVec3, DVec4};
use gltf_json as json;
use json::validation::USize64;

use crate::data::animation::{
    Clip, Interpolation, Property, Skeleton, SkinnedMesh, Track, Trs, WeightsTrack,
};
use crate::data::chain::{Chain, Joint};
use crate::error::{Error, Result};

/// A loaded glTF document with its merged binary buffer.
#[derive(Debug, Clone)]
pub struct RigDocument {
    /// The file it came from.
    pub path: PathBuf,
    /// The document; every buffer view refers to buffer 0, whose bytes are `bin`.
    pub root: json::Root,
    /// The merged binary buffer (4-byte aligned).
    pub bin: Vec<u8>,
    /// What loading repaired (skin weights renormalised), one sentence each.
    pub warnings: Vec<String>,
}

/// A chain found in a rig: the solver chain and the node index of each joint.
#[derive(Debug, Clone)]
pub struct RigChain {
    /// The chain, in the rig's real frames (its base is the world frame above ROOT).
    pub chain: Chain,
    /// Node index of each chain joint, ROOT first, TIP last.
    pub nodes: Vec<usize>,
}

impl RigDocument {
    /// Loads a `.glb` or `.gltf` file (external and base64 buffers supported). Skin weights
    /// that do not sum to 1 are renormalised (see [`crate::io::skin_weights`]) and listed in
    /// `warnings`.
    ///
    /// # Errors
    /// [`Error::Io`] when unreadable, [`Error::Gltf`] when not valid glTF.
    pub fn load(path: &Path) -> Result<Self> {
        let (document, buffers) = crate::io::gltf_import::import_gltf(path)?;
        let mut root = document.into_json();
        let mut bin = Vec::new();
        let mut offsets = Vec::with_capacity(buffers.len());
        for (data, buffer) in buffers.iter().zip(&root.buffers) {
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            offsets.push(bin.len());
            bin.extend_from_slice(&data[..buffer.byte_length.0 as usize]);
        }
        for view in &mut root.buffer_views {
            let off = offsets[view.buffer.value()];
            view.buffer = json::Index::new(0);
            view.byte_offset = Some(USize64::from(
                view.byte_offset.map_or(0, |o| o.0 as usize) + off,
            ));
        }
        root.buffers.clear();
        // Embed images kept in external files.
        let mut new_views = Vec::new();
        for image in &mut root.images {
            let Some(uri) = image.uri.clone() else {
                continue;
            };
            if uri.starts_with("data:") {
                continue;
            }
            let file = crate::io::gltf_import::uri_path(path, &uri);
            let data = std::fs::read(&file).map_err(|e| Error::io(&file, e))?;
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            let mime = if uri.to_ascii_lowercase().ends_with(".png") {
                "image/png"
            } else {
                "image/jpeg"
            };
            new_views.push(json::buffer::View {
                buffer: json::Index::new(0),
                byte_length: USize64::from(data.len()),
                byte_offset: Some(USize64::from(bin.len())),
                byte_stride: None,
                name: None,
                target: None,
                extensions: None,
                extras: Default::default(),
            });
            bin.extend_from_slice(&data);
            image.buffer_view = Some(json::Index::new(
                (root.buffer_views.len() + new_views.len() - 1) as u32,
            ));
            image.mime_type = Some(json::image::MimeType(mime.into()));
            image.uri = None;
        }
        root.buffer_views.extend(new_views);
        let mut warnings = Vec::new();
        let fixed = crate::io::skin_weights::renormalise(&mut root, &mut bin);
        if fixed.vertices > 0 {
            let (lo, hi) = fixed.range;
            let mut w = format!(
                "{}: renormalised the skin weights of {} vertices (they summed to {lo:.3}–{hi:.3}, glTF requires 1)",
                path.display(),
                fixed.vertices
            );
            if fixed.zero > 0 {
                w.push_str(&format!(
                    "; {} vertices had no weight at all and now follow their first joint",
                    fixed.zero
                ));
            }
            warnings.push(w);
        }
        Ok(RigDocument {
            path: path.into(),
            root,
            bin,
            warnings,
        })
    }

    /// Resolves a joint reference: `#N` for node N, otherwise a node name, or `Node_N` for an
    /// unnamed node N (the name Blender gives it).
    ///
    /// # Errors
    /// [`Error::UnknownJoint`].
    pub fn find_node(&self, joint: &str) -> Result<usize> {
        let unknown = || Error::UnknownJoint {
            path: self.path.clone(),
            joint: joint.into(),
        };
        if let Some(n) = joint.strip_prefix('#') {
            let i: usize = n.parse().map_err(|_| unknown())?;
            return if i < self.root.nodes.len() {
                Ok(i)
            } else {
                Err(unknown())
            };
        }
        if let Some(i) = self
            .root
            .nodes
            .iter()
            .position(|n| n.name.as_deref() == Some(joint))
        {
            return Ok(i);
        }
        // Blender names an unnamed node `Node_N` (its importer's default): accept that too.
        joint
            .strip_prefix("Node_")
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|&i| self.root.nodes.get(i).is_some_and(|n| n.name.is_none()))
            .ok_or_else(unknown)
    }

    /// Parent of each node (None for scene roots).
    pub fn parents(&self) -> Vec<Option<usize>> {
        let mut parents = vec![None; self.root.nodes.len()];
        for (i, n) in self.root.nodes.iter().enumerate() {
            for c in n.children.iter().flatten() {
                if let Some(p) = parents.get_mut(c.value()) {
                    *p = Some(i);
                }
            }
        }
        parents
    }

    /// Local transform of node `i` (matrix or TRS) as an affine map.
    pub fn local_transform(&self, i: usize) -> DAffine3 {
        let n = &self.root.nodes[i];
        if let Some(m) = n.matrix {
            let m = DMat4::from_cols_array(&m.map(f64::from));
            return DAffine3::from_mat4(m);
        }
        let (s, r, t) = node_trs(n);
        DAffine3::from_scale_rotation_translation(s, r, t)
    }

    /// Builds the chain `ROOT..TIP`: the parent path from TIP up to ROOT, in the rig's frames
    /// (the chain's base is the world transform of ROOT's parent; node matrices are decomposed).
    ///
    /// # Errors
    /// [`Error::Value`] when `spec` is not `ROOT..TIP` (the job names `--chain`);
    /// [`Error::UnknownJoint`]; [`Error::JointNotBelow`] when TIP is not a strict descendant of
    /// ROOT; [`Error::Chain`] for a degenerate chain (zero-length bone, zero scale).
    pub fn chain(&self, spec: &str) -> Result<RigChain> {
        let (root_name, tip_name) = spec
            .split_once("..")
            .map(|(a, b)| (a.trim(), b.trim()))
            .filter(|(a, b)| !a.is_empty() && !b.is_empty())
            .ok_or_else(|| {
                Error::value(format!("`{spec}`: expected ROOT..TIP (node names or #N)"))
            })?;
        let root = self.find_node(root_name)?;
        let tip = self.find_node(tip_name)?;
        let parents = self.parents();
        let not_below = || Error::JointNotBelow {
            path: self.path.clone(),
            root: root_name.into(),
            tip: tip_name.into(),
        };
        let mut nodes = vec![tip];
        let mut cur = tip;
        while cur != root {
            cur = parents[cur].ok_or_else(not_below)?;
            if nodes.len() > self.root.nodes.len() {
                return Err(Error::invalid(&self.path, "the node hierarchy has a cycle"));
            }
            nodes.push(cur);
        }
        if nodes.len() < 2 {
            return Err(not_below());
        }
        nodes.reverse();
        let mut base = DAffine3::IDENTITY;
        let mut up = parents[root];
        let mut guard = 0;
        while let Some(p) = up {
            base = self.local_transform(p) * base;
            up = parents[p];
            guard += 1;
            if guard > self.root.nodes.len() {
                return Err(Error::invalid(&self.path, "the node hierarchy has a cycle"));
            }
        }
        let joints = nodes
            .iter()
            .enumerate()
            .map(|(k, &i)| {
                let n = &self.root.nodes[i];
                let (scale, rotation, translation) = match n.matrix {
                    Some(_) => self.local_transform(i).to_scale_rotation_translation(),
                    None => node_trs(n),
                };
                Joint {
                    name: n.name.clone().unwrap_or_else(|| format!("#{}", nodes[k])),
                    translation,
                    rotation,
                    scale,
                }
            })
            .collect();
        let chain = Chain::new(joints, base)?;
        Ok(RigChain { chain, nodes })
    }
}

fn node_trs(n: &json::Node) -> (DVec3, DQuat, DVec3) {
    let t = n
        .translation
        .map_or(DVec3::ZERO, |t| DVec3::from_array(t.map(f64::from)));
    let r = n.rotation.map_or(DQuat::IDENTITY, |q| {
        DQuat::from_array(q.0.map(f64::from)).normalize()
    });
    let s = n
        .scale
        .map_or(DVec3::ONE, |s| DVec3::from_array(s.map(f64::from)));
    (s, r, t)
}

impl RigDocument {
    /// The document as a `gltf::Document` whose buffer 0 is [`Self::bin`] (for the gltf crate's
    /// accessor readers).
    fn document(&self) -> Result<gltf::Document> {
        let mut root = self.root.clone();
        root.buffers = vec![json::Buffer {
            byte_length: USize64::from(self.bin.len()),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        }];
        gltf::Document::from_json(root).map_err(|source| Error::Gltf {
            path: self.path.clone(),
            source,
        })
    }

    /// The node hierarchy with each node's own transform.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] when the hierarchy has a cycle.
    pub fn skeleton(&self) -> Result<Skeleton> {
        let rest_affine: Vec<DAffine3> = (0..self.root.nodes.len())
            .map(|i| self.local_transform(i))
            .collect();
        let rest = self
            .root
            .nodes
            .iter()
            .zip(&rest_affine)
            .map(|(n, a)| {
                let (scale, rotation, translation) = match n.matrix {
                    Some(_) => a.to_scale_rotation_translation(),
                    None => node_trs(n),
                };
                Trs {
                    translation,
                    rotation,
                    scale,
                }
            })
            .collect();
        Skeleton::new(self.parents(), rest, rest_affine)
            .ok_or_else(|| Error::invalid(&self.path, "the node hierarchy has a cycle"))
    }

    /// Names of the document's animations (`#N` for an unnamed one).
    pub fn animation_names(&self) -> Vec<String> {
        self.root
            .animations
            .iter()
            .enumerate()
            .map(|(i, a)| a.name.clone().unwrap_or_else(|| format!("#{i}")))
            .collect()
    }

    /// The animation named `spec` (a name, or `#N` for the N-th), read whole.
    ///
    /// # Errors
    /// [`Error::Value`] naming the animations there are when none matches (the job names the
    /// option); [`Error::Gltf`] for an unreadable channel.
    pub fn clip(&self, spec: &str) -> Result<Clip> {
        let names = self.animation_names();
        let index = match spec.strip_prefix('#').map(str::parse::<usize>) {
            Some(Ok(i)) if i < names.len() => Some(i),
            Some(_) => None,
            None => names.iter().position(|n| n == spec),
        };
        let Some(index) = index else {
            let have = if names.is_empty() {
                "it has no animations".to_owned()
            } else {
                format!(
                    "it has {}",
                    names
                        .iter()
                        .enumerate()
                        .map(|(i, n)| format!("#{i} `{n}`"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            };
            return Err(Error::value(format!(
                "{}: no animation `{spec}` ({have})",
                self.path.display()
            )));
        };
        let doc = self.document()?;
        let anim = doc
            .animations()
            .nth(index)
            .expect("index checked against the animation list");
        let bad =
            |m: String| Error::invalid(&self.path, format!("animation `{}`: {m}", names[index]));
        let mut tracks = Vec::new();
        let mut weights = Vec::new();
        for (c, ch) in anim.channels().enumerate() {
            let reader = ch.reader(|_| Some(&self.bin[..]));
            let times: Vec<f64> = reader
                .read_inputs()
                .ok_or_else(|| bad(format!("channel {c} has no key times")))?
                .map(f64::from)
                .collect();
            let f = |v: &[f32]| {
                DVec4::new(
                    v[0].into(),
                    v[1].into(),
                    v[2].into(),
                    v.get(3).copied().unwrap_or(0.0).into(),
                )
            };
            let interpolation = match ch.sampler().interpolation() {
                gltf::animation::Interpolation::Step => Interpolation::Step,
                gltf::animation::Interpolation::Linear => Interpolation::Linear,
                gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
            };
            let per_key = interpolation.values_per_key();
            let bad_times = times.is_empty()
                || times.windows(2).any(|w| w[1] <= w[0])
                || times.iter().any(|t| !t.is_finite());
            let (property, values): (Property, Vec<DVec4>) = match reader.read_outputs() {
                Some(gltf::animation::util::ReadOutputs::Translations(it)) => {
                    (Property::Translation, it.map(|v| f(&v)).collect())
                }
                Some(gltf::animation::util::ReadOutputs::Scales(it)) => {
                    (Property::Scale, it.map(|v| f(&v)).collect())
                }
                Some(gltf::animation::util::ReadOutputs::Rotations(it)) => {
                    (Property::Rotation, it.into_f32().map(|v| f(&v)).collect())
                }
                // Morph weights move no node; they are kept for writers that copy the clip.
                Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(it)) => {
                    let values: Vec<f32> = it.into_f32().collect();
                    let keys = per_key * times.len();
                    let targets = values.len().checked_div(keys).unwrap_or(0);
                    if bad_times || targets == 0 || values.len() != targets * keys {
                        return Err(bad(format!(
                            "weights channel {c} has {} key times (strictly increasing \
                             expected) and {} values (a whole number of weights per key \
                             expected)",
                            times.len(),
                            values.len()
                        )));
                    }
                    weights.push(WeightsTrack {
                        node: ch.target().node().index(),
                        interpolation,
                        times,
                        values,
                        targets,
                    });
                    continue;
                }
                None => return Err(bad(format!("channel {c} has no values"))),
            };
            if bad_times || values.len() != per_key * times.len() {
                return Err(bad(format!(
                    "channel {c} has {} key times (strictly increasing expected) and {} values",
                    times.len(),
                    values.len()
                )));
            }
            tracks.push(Track {
                node: ch.target().node().index(),
                property,
                interpolation,
                times,
                values,
            });
        }
        Ok(Clip {
            name: names[index].clone(),
            index,
            tracks,
            weights,
        })
    }

    /// Every mesh instance of the default scene (its triangle primitives merged) as a skinned
    /// mesh: bind-pose positions and joint influences. A mesh without a skin is carried by its
    /// node (a character made of rigid parts parented to bones): one joint, the node itself,
    /// with an identity inverse bind matrix, so skinning it gives world(node)·p as glTF draws it.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a skinned primitive without positions, joints or weights, or
    /// a joint index past the skin's joints.
    pub fn body_meshes(&self) -> Result<Vec<SkinnedMesh>> {
        let doc = self.document()?;
        let data = |_: gltf::Buffer<'_>| Some(&self.bin[..]);
        let mut in_scene = vec![false; self.root.nodes.len()];
        let mut stack: Vec<usize> = doc
            .default_scene()
            .or_else(|| doc.scenes().next())
            .map(|s| s.nodes().map(|n| n.index()).collect())
            .unwrap_or_default();
        while let Some(i) = stack.pop() {
            if !std::mem::replace(&mut in_scene[i], true) {
                stack.extend(
                    self.root.nodes[i]
                        .children
                        .iter()
                        .flatten()
                        .map(|c| c.value()),
                );
            }
        }
        let mut out = Vec::new();
        for node in doc.nodes().filter(|n| in_scene[n.index()]) {
            let Some(mesh) = node.mesh() else {
                continue;
            };
            let skin = node.skin();
            let name = mesh
                .name()
                .or(node.name())
                .map_or_else(|| format!("#{}", node.index()), str::to_owned);
            let bad = |m: String| Error::invalid(&self.path, format!("skinned mesh `{name}`: {m}"));
            let (joints, inverse_bind): (Vec<usize>, Vec<DAffine3>) = match &skin {
                Some(skin) => {
                    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
                    let ib = match skin.reader(data).read_inverse_bind_matrices() {
                        Some(it) => it
                            .map(|m| {
                                DAffine3::from_mat4(DMat4::from_cols_array_2d(
                                    &m.map(|c| c.map(f64::from)),
                                ))
                            })
                            .collect(),
                        None => vec![DAffine3::IDENTITY; joints.len()],
                    };
                    (joints, ib)
                }
                None => (vec![node.index()], vec![DAffine3::IDENTITY]),
            };
            let mut sm = SkinnedMesh {
                name: name.clone(),
                node: node.index(),
                positions: Vec::new(),
                triangles: Vec::new(),
                joints,
                inverse_bind,
                per_vertex: 0,
                influence_joint: Vec::new(),
                influence_weight: Vec::new(),
            };
            let sets = if skin.is_none() {
                0
            } else {
                mesh.primitives()
                    .map(|p| {
                        p.attributes()
                            .filter(|(s, _)| matches!(s, gltf::Semantic::Joints(_)))
                            .count()
                    })
                    .max()
                    .unwrap_or(0)
            };
            sm.per_vertex = 4 * sets.max(1);
            for prim in mesh.primitives() {
                if prim.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let r = prim.reader(data);
                let base = sm.positions.len() as u32;
                let positions: Vec<DVec3> = r
                    .read_positions()
                    .ok_or_else(|| bad("a primitive has no POSITION".into()))?
                    .map(|p| DVec3::from_array(p.map(f64::from)))
                    .collect();
                let n = positions.len();
                let mut joint_ids = vec![0u16; n * sm.per_vertex];
                let mut weights = vec![0f32; n * sm.per_vertex];
                if skin.is_none() {
                    // Carried by the node: joint 0 (the node), weight 1.
                    for w in weights.chunks_exact_mut(sm.per_vertex) {
                        w[0] = 1.0;
                    }
                }
                for set in 0..sets as u32 {
                    let (Some(j), Some(w)) = (r.read_joints(set), r.read_weights(set)) else {
                        return Err(bad(format!("JOINTS_{set} without WEIGHTS_{set}")));
                    };
                    for (v, (j, w)) in j.into_u16().zip(w.into_f32()).enumerate().take(n) {
                        let at = v * sm.per_vertex + 4 * set as usize;
                        joint_ids[at..at + 4].copy_from_slice(&j);
                        weights[at..at + 4].copy_from_slice(&w);
                    }
                }
                if let Some(&j) = joint_ids
                    .iter()
                    .zip(&weights)
                    .find(|(&j, &w)| w != 0.0 && j as usize >= sm.joints.len())
                    .map(|(j, _)| j)
                {
                    return Err(bad(format!(
                        "joint index {j} past the skin's {} joints",
                        sm.joints.len()
                    )));
                }
                let idx: Vec<u32> = match r.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..n as u32).collect(),
                };
                if idx.iter().any(|&i| i as usize >= n) {
                    return Err(bad("an index past the vertex count".into()));
                }
                sm.triangles.extend(
                    idx.chunks_exact(3)
                        .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
                );
                sm.positions.extend(positions);
                sm.influence_joint.extend(joint_ids);
                sm.influence_weight.extend(weights);
            }
            if !sm.positions.is_empty() {
                out.push(sm);
            }
        }
        Ok(out)
    }
}
