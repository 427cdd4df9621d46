//! Chains taken from rigged glTF documents (`--rig FILE --chain ROOT..TIP`).
//!
//! The document is kept whole so the bake can write it back with one animation added. All its
//! buffers are merged into one binary buffer (for a GLB, the BIN chunk stays first and unchanged,
//! so new data is appended to it), and images stored in external files are embedded, so the
//! result can be written as `.glb` or `.gltf` anywhere.

use std::path::{Path, PathBuf};

use glam::{DAffine3, DMat4, DQuat, DVec3};
use gltf_json as json;
use json::validation::USize64;

use crate::data::chain::{Chain, Joint};
use crate::error::{Error, Result};
use crate::param::Param;
use crate::text;

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
    /// [`Error::InvalidOption`] when `spec` is not `ROOT..TIP`; [`Error::UnknownJoint`];
    /// [`Error::JointNotBelow`] when TIP is not a strict descendant of ROOT; [`Error::Chain`] for
    /// a degenerate chain (zero-length bone, zero scale).
    pub fn chain(&self, spec: &str) -> Result<RigChain> {
        let (root_name, tip_name) = spec
            .split_once("..")
            .map(|(a, b)| (a.trim(), b.trim()))
            .filter(|(a, b)| !a.is_empty() && !b.is_empty())
            .ok_or_else(|| {
                Error::param_value(
                    Param::Chain,
                    format!("`{spec}`: expected ROOT..TIP (node names or #N)"),
                )
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
        let chain = Chain::new(joints, base).map_err(|e| match e {
            Error::Chain(m) => {
                Error::invalid(&self.path, text!(Param::Chain, format!(" {spec}: {m}")))
            }
            other => other,
        })?;
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
