//! An independent reader of baked node animations (the IK tests' forward kinematics).
//!
//! Nothing here uses scenebake's solver or chain code: node transforms come from the `gltf`
//! crate, animation keys are sampled by a small linear/step sampler written here, and world
//! positions are products of 4×4 matrices.

use std::collections::HashMap;
use std::path::Path;

use glam::{DMat4, DQuat, DVec3};

/// A loaded document with its buffers.
pub struct Loaded {
    pub doc: gltf::Document,
    pub buffers: Vec<super::gltf_read::Data>,
}

pub fn load(path: &Path) -> Loaded {
    let (doc, buffers, _images) =
        super::gltf_read::import(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Loaded { doc, buffers }
}

/// Times, values and whether the track is STEP-interpolated.
pub type Vec3Track = (Vec<f32>, Vec<[f32; 3]>, bool);

/// Per-node animation tracks of one animation: times and values.
#[derive(Default, Clone, Debug, PartialEq)]
pub struct Tracks {
    pub rotation: HashMap<usize, (Vec<f32>, Vec<[f32; 4]>)>,
    pub translation: HashMap<usize, Vec3Track>,
    pub scale: HashMap<usize, Vec3Track>,
}

impl Loaded {
    pub fn node_by_name(&self, name: &str) -> usize {
        self.doc
            .nodes()
            .find(|n| n.name() == Some(name))
            .unwrap_or_else(|| panic!("no node {name}"))
            .index()
    }

    pub fn animation(&self, name: &str) -> Tracks {
        let anim = self
            .doc
            .animations()
            .find(|a| a.name() == Some(name))
            .unwrap_or_else(|| panic!("no animation {name}"));
        let mut t = Tracks::default();
        for ch in anim.channels() {
            let reader = ch.reader(|b| Some(&self.buffers[b.index()]));
            let times: Vec<f32> = reader.read_inputs().unwrap().collect();
            let node = ch.target().node().index();
            let step = ch.sampler().interpolation() == gltf::animation::Interpolation::Step;
            match reader.read_outputs().unwrap() {
                gltf::animation::util::ReadOutputs::Rotations(r) => {
                    t.rotation.insert(node, (times, r.into_f32().collect()));
                }
                gltf::animation::util::ReadOutputs::Translations(v) => {
                    t.translation.insert(node, (times, v.collect(), step));
                }
                gltf::animation::util::ReadOutputs::Scales(v) => {
                    t.scale.insert(node, (times, v.collect(), step));
                }
                _ => {}
            }
        }
        t
    }

    pub fn parents(&self) -> Vec<Option<usize>> {
        let mut p = vec![None; self.doc.nodes().len()];
        for n in self.doc.nodes() {
            for c in n.children() {
                p[c.index()] = Some(n.index());
            }
        }
        p
    }

    /// Local matrix of `node` at time `t` (rest TRS overridden by sampled tracks).
    pub fn local(&self, tracks: &Tracks, node: usize, t: f32) -> DMat4 {
        let n = self.doc.nodes().nth(node).unwrap();
        let (tr, rot, sc) = n.transform().decomposed();
        let mut tr = DVec3::from_array(tr.map(f64::from));
        let mut rot = DQuat::from_array(rot.map(f64::from));
        let mut sc = DVec3::from_array(sc.map(f64::from));
        if let Some((times, vals)) = tracks.rotation.get(&node) {
            rot = sample_quat(times, vals, t);
        }
        if let Some((times, vals, step)) = tracks.translation.get(&node) {
            tr = sample_vec3(times, vals, t, *step);
        }
        if let Some((times, vals, step)) = tracks.scale.get(&node) {
            sc = sample_vec3(times, vals, t, *step);
        }
        DMat4::from_scale_rotation_translation(sc, rot, tr)
    }

    /// World matrix of `node` at time `t`.
    pub fn world(&self, tracks: &Tracks, node: usize, t: f32) -> DMat4 {
        let parents = self.parents();
        let mut m = self.local(tracks, node, t);
        let mut cur = parents[node];
        while let Some(p) = cur {
            m = self.local(tracks, p, t) * m;
            cur = parents[p];
        }
        m
    }

    pub fn world_pos(&self, tracks: &Tracks, node: usize, t: f32) -> DVec3 {
        self.world(tracks, node, t).w_axis.truncate()
    }
}

fn bracket(times: &[f32], t: f32) -> (usize, usize, f64) {
    if t <= times[0] {
        return (0, 0, 0.0);
    }
    let last = times.len() - 1;
    if t >= times[last] {
        return (last, last, 0.0);
    }
    let k = times.partition_point(|&x| x <= t) - 1;
    let span = (times[k + 1] - times[k]) as f64;
    (
        k,
        k + 1,
        if span > 0.0 {
            (t - times[k]) as f64 / span
        } else {
            0.0
        },
    )
}

/// LINEAR quaternion sampling (normalised lerp on the short arc; exact at keys).
pub fn sample_quat(times: &[f32], vals: &[[f32; 4]], t: f32) -> DQuat {
    let (a, b, u) = bracket(times, t);
    let qa = DQuat::from_array(vals[a].map(f64::from));
    let mut qb = DQuat::from_array(vals[b].map(f64::from));
    if qa.dot(qb) < 0.0 {
        qb = -qb;
    }
    (qa * (1.0 - u) + qb * u).normalize()
}

pub fn sample_vec3(times: &[f32], vals: &[[f32; 3]], t: f32, step: bool) -> DVec3 {
    let (a, b, u) = bracket(times, t);
    let va = DVec3::from_array(vals[a].map(f64::from));
    if step {
        return va;
    }
    va.lerp(DVec3::from_array(vals[b].map(f64::from)), u)
}
