//! The cloth export tests' helpers: the reference simulation (the library's solver run directly,
//! no writer involved) and an independent reload of morph-target files with the `gltf` crate and
//! a weight sampler written here.

use std::path::Path;

use scenebake::bake::cloth::{prepare_cloth, ClothJob};
use scenebake::cloth::{make_solver, simulate, FrameCache};
use scenebake::glam::Vec3;
use scenebake::mesh::Mesh;

/// Simulates `job` through the library directly: the reference the exports must match.
pub fn reference(job: &ClothJob) -> (Mesh, FrameCache) {
    let (mesh, cache, _) = reference_with_pins(job);
    (mesh, cache)
}

/// As [`reference`], with which particles are pinned.
pub fn reference_with_pins(job: &ClothJob) -> (Mesh, FrameCache, Vec<bool>) {
    let p = prepare_cloth(job).unwrap();
    let mut solver = make_solver(&p.model, &p.params).unwrap();
    let sim = simulate(&p.model, solver.as_mut(), &p.params, &mut |_| {}).unwrap();
    (p.model.mesh.clone(), sim.cache, p.model.pinned.clone())
}

/// Render-vertex positions of frame `k` of the reference.
pub fn reference_positions(mesh: &Mesh, cache: &FrameCache, k: usize) -> Vec<Vec3> {
    let particles = cache.frame(k);
    mesh.render_vertices
        .iter()
        .map(|v| particles[v.particle as usize])
        .collect()
}

/// A morph-target glTF as the `gltf` crate reads it.
pub struct Morph {
    pub base: Vec<Vec3>,
    pub base_normals: Option<Vec<Vec3>>,
    pub deltas: Vec<Vec<Vec3>>,
    pub normal_deltas: Vec<Option<Vec<Vec3>>>,
    pub times: Vec<f32>,
    /// Weights per key, `targets` values each.
    pub weights: Vec<f32>,
    pub linear: bool,
}

impl Morph {
    pub fn targets(&self) -> usize {
        self.deltas.len()
    }

    /// Positions of target `j` (base + delta), as a player computes them at weight 1.
    pub fn target_positions(&self, j: usize) -> Vec<Vec3> {
        self.base
            .iter()
            .zip(&self.deltas[j])
            .map(|(b, d)| *b + *d)
            .collect()
    }

    /// The weights at time `t`, interpolated from the animation's keys (our own sampler).
    pub fn weights_at(&self, t: f32) -> Vec<f32> {
        let n = self.targets();
        let row = |i: usize| &self.weights[i * n..(i + 1) * n];
        if t <= self.times[0] {
            return row(0).to_vec();
        }
        let last = self.times.len() - 1;
        if t >= self.times[last] {
            return row(last).to_vec();
        }
        let i = self
            .times
            .windows(2)
            .position(|w| w[0] <= t && t < w[1])
            .unwrap();
        if !self.linear {
            return row(i).to_vec();
        }
        let s = (t - self.times[i]) / (self.times[i + 1] - self.times[i]);
        row(i)
            .iter()
            .zip(row(i + 1))
            .map(|(a, b)| a + s * (b - a))
            .collect()
    }

    /// Blended positions at time `t`: base + Σ wⱼ·Δⱼ.
    pub fn positions_at(&self, t: f32) -> Vec<Vec3> {
        let w = self.weights_at(t);
        let mut p = self.base.clone();
        for (j, wj) in w.iter().enumerate() {
            if *wj != 0.0 {
                for (p, d) in p.iter_mut().zip(&self.deltas[j]) {
                    *p += *wj * *d;
                }
            }
        }
        p
    }
}

fn vec3s(it: impl Iterator<Item = [f32; 3]>) -> Vec<Vec3> {
    it.map(Vec3::from).collect()
}

/// Reloads a morph-target glTF with the `gltf` crate.
pub fn load_morph(path: &Path) -> Morph {
    let (doc, buffers, _) = super::gltf_read::import(path).expect("reload with the gltf crate");
    let mesh = doc.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let base = vec3s(reader.read_positions().unwrap());
    let base_normals = reader.read_normals().map(vec3s);
    let mut deltas = Vec::new();
    let mut normal_deltas = Vec::new();
    for (p, n, _) in reader.read_morph_targets() {
        deltas.push(vec3s(p.expect("POSITION delta")));
        normal_deltas.push(n.map(vec3s));
    }
    let anim = doc.animations().next().expect("an animation");
    let channel = anim.channels().next().unwrap();
    let linear = channel.sampler().interpolation() == gltf::animation::Interpolation::Linear;
    let r = channel.reader(|b| Some(&buffers[b.index()]));
    let times: Vec<f32> = r.read_inputs().unwrap().collect();
    let weights: Vec<f32> = match r.read_outputs().unwrap() {
        gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
        _ => panic!("weights output"),
    };
    Morph {
        base,
        base_normals,
        deltas,
        normal_deltas,
        times,
        weights,
        linear,
    }
}

/// Largest distance between two point lists.
#[track_caller]
pub fn max_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f32::max)
}
