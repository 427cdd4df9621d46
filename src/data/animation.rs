//! Keyframed node animation (glTF animation channels on translation, rotation and scale), a
//! node hierarchy to pose, and linear-blend skinning of the meshes it drives.
//!
//! Times are seconds on the animation's own axis (the glTF sampler inputs, usually starting at
//! 0). Lengths are in the document's units; nothing here rescales.
//!
//! Sampling follows the glTF 2.0 specification (Appendix C): `STEP` holds the previous key,
//! `LINEAR` interpolates translations and scales linearly and rotations by spherical linear
//! interpolation (shortest arc), `CUBICSPLINE` is the cubic Hermite spline through the keys with
//! their in/out tangents scaled by the key interval (rotations normalised afterwards). Before the
//! first key and after the last, the first and last values hold.

use glam::{DAffine3, DQuat, DVec3, DVec4};

/// A local transform as translation, rotation and scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trs {
    /// Translation in the parent's frame.
    pub translation: DVec3,
    /// Rotation (unit quaternion).
    pub rotation: DQuat,
    /// Scale along the local axes.
    pub scale: DVec3,
}

impl Default for Trs {
    fn default() -> Self {
        Trs {
            translation: DVec3::ZERO,
            rotation: DQuat::IDENTITY,
            scale: DVec3::ONE,
        }
    }
}

impl Trs {
    /// The transform T·R·S as an affine map.
    pub fn affine(&self) -> DAffine3 {
        DAffine3::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// Which node property a track animates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Property {
    /// Translation (xyz).
    Translation,
    /// Rotation (quaternion xyzw).
    Rotation,
    /// Scale (xyz).
    Scale,
}

/// How a track interpolates between keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Hold the previous key.
    Step,
    /// Linear (slerp for rotations).
    Linear,
    /// Cubic Hermite spline with in/out tangents stored beside each key.
    CubicSpline,
}

impl Interpolation {
    /// Sampler output elements stored per key: three for a cubic spline (in-tangent, value,
    /// out-tangent), else one.
    pub fn values_per_key(self) -> usize {
        if self == Interpolation::CubicSpline {
            3
        } else {
            1
        }
    }
}

/// One animated property of one node.
#[derive(Debug, Clone, PartialEq)]
pub struct Track {
    /// Node index in the document.
    pub node: usize,
    /// The property.
    pub property: Property,
    /// The interpolation.
    pub interpolation: Interpolation,
    /// Key times, seconds, strictly increasing.
    pub times: Vec<f64>,
    /// Values (xyz in `x,y,z`, quaternions as `x,y,z,w`); for [`Interpolation::CubicSpline`]
    /// three per key: in-tangent, value, out-tangent.
    pub values: Vec<DVec4>,
}

impl Track {
    /// The property's value at time `t` (seconds; clamped to the keys).
    pub fn sample(&self, t: f64) -> DVec4 {
        let n = self.times.len();
        let cubic = self.interpolation == Interpolation::CubicSpline;
        let value = |k: usize| {
            if cubic {
                self.values[3 * k + 1]
            } else {
                self.values[k]
            }
        };
        if n == 1 || t <= self.times[0] {
            return value(0);
        }
        if t >= self.times[n - 1] {
            return value(n - 1);
        }
        // The key interval [k, k+1] holding t.
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let s = (t - t0) / dt;
        let rotation = self.property == Property::Rotation;
        match self.interpolation {
            Interpolation::Step => value(k),
            Interpolation::Linear if rotation => {
                let a = DQuat::from_vec4(value(k)).normalize();
                let b = DQuat::from_vec4(value(k + 1)).normalize();
                DVec4::from(a.slerp(b, s))
            }
            Interpolation::Linear => value(k).lerp(value(k + 1), s),
            Interpolation::CubicSpline => {
                let p0 = self.values[3 * k + 1];
                let m0 = self.values[3 * k + 2] * dt;
                let p1 = self.values[3 * (k + 1) + 1];
                let m1 = self.values[3 * (k + 1)] * dt;
                let (s2, s3) = (s * s, s * s * s);
                let v = p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + m0 * (s3 - 2.0 * s2 + s)
                    + p1 * (-2.0 * s3 + 3.0 * s2)
                    + m1 * (s3 - s2);
                if rotation {
                    v.normalize()
                } else {
                    v
                }
            }
        }
    }
}

/// One animated morph-target `weights` property of one node: it moves no node, but a copy of
/// the animation carries it (a character's face expressions).
#[derive(Debug, Clone, PartialEq)]
pub struct WeightsTrack {
    /// Node index in the document.
    pub node: usize,
    /// The interpolation.
    pub interpolation: Interpolation,
    /// Key times, seconds, strictly increasing.
    pub times: Vec<f64>,
    /// The weights, `targets` per key (for [`Interpolation::CubicSpline`] three groups of
    /// `targets` per key: in-tangents, values, out-tangents), as the glTF sampler stores them.
    pub values: Vec<f32>,
    /// Morph targets per key (the node's mesh's target count).
    pub targets: usize,
}

/// A glTF animation: tracks on node properties.
#[derive(Debug, Clone, PartialEq)]
pub struct Clip {
    /// Its name (`#N` when the document has none).
    pub name: String,
    /// Its index among the document's animations.
    pub index: usize,
    /// The tracks on node transforms.
    pub tracks: Vec<Track>,
    /// The tracks on morph-target weights.
    pub weights: Vec<WeightsTrack>,
}

impl Clip {
    /// Every track's key times (transforms and weights).
    fn all_times(&self) -> impl Iterator<Item = &[f64]> {
        let tracks = self.tracks.iter().map(|t| &t.times[..]);
        tracks.chain(self.weights.iter().map(|t| &t.times[..]))
    }

    /// Earliest key time over all tracks (weights too, as glTF times an animation), seconds.
    pub fn start(&self) -> f64 {
        self.all_times()
            .filter_map(|t| t.first().copied())
            .fold(f64::INFINITY, f64::min)
            .min(f64::MAX)
    }

    /// Latest key time over all tracks (weights too), seconds.
    pub fn end(&self) -> f64 {
        self.all_times()
            .filter_map(|t| t.last().copied())
            .fold(f64::NEG_INFINITY, f64::max)
            .max(self.start())
    }

    /// `end − start`, seconds.
    pub fn duration(&self) -> f64 {
        self.end() - self.start()
    }

    /// Overwrites the animated properties of `pose` (local transforms, one per node) with their
    /// values at time `t` (seconds).
    pub fn apply(&self, t: f64, pose: &mut [Trs]) {
        for track in &self.tracks {
            let Some(trs) = pose.get_mut(track.node) else {
                continue;
            };
            let v = track.sample(t);
            match track.property {
                Property::Translation => trs.translation = v.truncate(),
                Property::Rotation => trs.rotation = DQuat::from_vec4(v).normalize(),
                Property::Scale => trs.scale = v.truncate(),
            }
        }
    }

    /// Nodes any track animates, flagged by node index (`count` nodes).
    pub fn animated_nodes(&self, count: usize) -> Vec<bool> {
        let mut flags = vec![false; count];
        for t in &self.tracks {
            if let Some(f) = flags.get_mut(t.node) {
                *f = true;
            }
        }
        flags
    }
}

/// A node hierarchy with its rest (node) transforms.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    /// Parent of each node (None for roots).
    pub parents: Vec<Option<usize>>,
    /// Each node's own transform as TRS (a node matrix decomposed).
    pub rest: Vec<Trs>,
    /// Each node's own transform exactly (a node matrix kept as it is, shear included).
    pub rest_affine: Vec<DAffine3>,
    /// Nodes ordered parents first.
    order: Vec<usize>,
}

impl Skeleton {
    /// Per node: whether it is `root` or below it.
    pub fn subtree(&self, root: usize) -> Vec<bool> {
        let mut below = vec![false; self.parents.len()];
        for &n in &self.order {
            below[n] = n == root || self.parents[n].is_some_and(|p| below[p]);
        }
        below
    }

    /// A skeleton from parents and rest transforms; `None` when the hierarchy has a cycle or a
    /// parent index out of range.
    pub fn new(
        parents: Vec<Option<usize>>,
        rest: Vec<Trs>,
        rest_affine: Vec<DAffine3>,
    ) -> Option<Self> {
        let n = parents.len();
        if rest.len() != n || rest_affine.len() != n || parents.iter().flatten().any(|&p| p >= n) {
            return None;
        }
        let mut depth = vec![usize::MAX; n];
        for i in 0..n {
            // Walk up to a node of known depth (or a root), then fill the path on the way back.
            let mut path = Vec::new();
            let mut cur = Some(i);
            while let Some(c) = cur {
                if depth[c] != usize::MAX {
                    break;
                }
                if path.len() > n {
                    return None;
                }
                path.push(c);
                cur = parents[c];
            }
            let first = cur.map_or(0, |c| depth[c] + 1);
            for (d, &c) in (first..).zip(path.iter().rev()) {
                depth[c] = d;
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&i| depth[i]);
        Some(Skeleton {
            parents,
            rest,
            rest_affine,
            order,
        })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.parents.len()
    }

    /// True when there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }

    /// Local transforms at time `t` of `clip` (rest transforms where it has no track).
    pub fn pose(&self, clip: Option<&Clip>, t: f64) -> Vec<Trs> {
        let mut pose = self.rest.clone();
        if let Some(c) = clip {
            c.apply(t, &mut pose);
        }
        pose
    }

    /// World transforms of every node for local transforms `local`; nodes flagged in `posed`
    /// use `local`, the others their exact rest transform.
    pub fn world(&self, local: &[Trs], posed: &[bool]) -> Vec<DAffine3> {
        let mut world = vec![DAffine3::IDENTITY; self.len()];
        for &i in &self.order {
            let own = if posed.get(i).copied().unwrap_or(false) {
                local[i].affine()
            } else {
                self.rest_affine[i]
            };
            world[i] = match self.parents[i] {
                Some(p) => world[p] * own,
                None => own,
            };
        }
        world
    }

    /// World transforms at time `t` of `clip` (rest pose when `None`).
    pub fn world_at(&self, clip: Option<&Clip>, t: f64) -> Vec<DAffine3> {
        let posed = clip.map_or_else(|| vec![false; self.len()], |c| c.animated_nodes(self.len()));
        self.world(&self.pose(clip, t), &posed)
    }
}

/// A skinned triangle mesh: bind-pose positions and each vertex's joint influences.
#[derive(Debug, Clone, PartialEq)]
pub struct SkinnedMesh {
    /// Name (mesh or node name).
    pub name: String,
    /// Index of the node that carries the mesh.
    pub node: usize,
    /// Bind-pose positions (the mesh's own coordinates).
    pub positions: Vec<DVec3>,
    /// Triangles (indices into `positions`).
    pub triangles: Vec<[u32; 3]>,
    /// Node index of each skin joint.
    pub joints: Vec<usize>,
    /// Inverse bind matrix of each skin joint.
    pub inverse_bind: Vec<DAffine3>,
    /// Influences per vertex (4 per JOINTS_n/WEIGHTS_n set).
    pub per_vertex: usize,
    /// Skin-joint index of each influence (`per_vertex` per vertex).
    pub influence_joint: Vec<u16>,
    /// Weight of each influence (sums to 1 per vertex).
    pub influence_weight: Vec<f32>,
}

impl SkinnedMesh {
    /// Each vertex's skin weight on the nodes `on` accepts.
    pub fn weight_on(&self, on: impl Fn(usize) -> bool) -> Vec<f64> {
        let k = self.per_vertex;
        (0..self.positions.len())
            .map(|v| {
                let range = v * k..(v + 1) * k;
                self.influence_joint[range.clone()]
                    .iter()
                    .zip(&self.influence_weight[range])
                    .filter(|&(&j, _)| on(self.joints[j as usize]))
                    .map(|(_, &w)| f64::from(w))
                    .sum()
            })
            .collect()
    }

    /// The skinning matrices Mⱼ = world(jointⱼ) · inverse_bindⱼ for the node world transforms
    /// `world`.
    pub fn joint_matrices(&self, world: &[DAffine3]) -> Vec<DAffine3> {
        self.joints
            .iter()
            .zip(&self.inverse_bind)
            .map(|(&j, ib)| world[j] * *ib)
            .collect()
    }

    /// Vertex `v` skinned by `matrices` (from [`Self::joint_matrices`]), in world coordinates.
    #[inline]
    pub fn skin_vertex(&self, v: usize, matrices: &[DAffine3]) -> DVec3 {
        skin_point(
            self.positions[v],
            &self.influence_joint[v * self.per_vertex..(v + 1) * self.per_vertex],
            &self.influence_weight[v * self.per_vertex..(v + 1) * self.per_vertex],
            matrices,
        )
    }

    /// Every vertex skinned by the world transforms `world` (linear blend skinning, as glTF
    /// defines it: the mesh node's own transform does not apply).
    pub fn deform(&self, world: &[DAffine3]) -> Vec<DVec3> {
        let m = self.joint_matrices(world);
        (0..self.positions.len())
            .map(|v| self.skin_vertex(v, &m))
            .collect()
    }
}

/// The point `p` (bind pose) skinned with `joints`/`weights` by `matrices`.
#[inline]
pub fn skin_point(p: DVec3, joints: &[u16], weights: &[f32], matrices: &[DAffine3]) -> DVec3 {
    let mut out = DVec3::ZERO;
    for (&j, &w) in joints.iter().zip(weights) {
        if w != 0.0 {
            out += matrices[j as usize].transform_point3(p) * f64::from(w);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(
        property: Property,
        interpolation: Interpolation,
        times: &[f64],
        values: &[DVec4],
    ) -> Track {
        Track {
            node: 0,
            property,
            interpolation,
            times: times.to_vec(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn linear_step_and_clamping_follow_the_keys() {
        let v = [
            DVec4::new(0.0, 0.0, 0.0, 0.0),
            DVec4::new(2.0, 4.0, -2.0, 0.0),
        ];
        let lin = track(
            Property::Translation,
            Interpolation::Linear,
            &[1.0, 2.0],
            &v,
        );
        assert_eq!(lin.sample(1.25), DVec4::new(0.5, 1.0, -0.5, 0.0));
        assert_eq!(lin.sample(0.0), v[0]);
        assert_eq!(lin.sample(9.0), v[1]);
        let step = track(Property::Translation, Interpolation::Step, &[1.0, 2.0], &v);
        assert_eq!(step.sample(1.99), v[0]);
        assert_eq!(step.sample(2.0), v[1]);
    }

    #[test]
    fn rotations_take_the_constant_speed_shortest_arc() {
        let a = DQuat::IDENTITY;
        // 170° about z, stored with negative w: the short way from identity is through -w.
        let b = -DQuat::from_rotation_z(170f64.to_radians());
        let t = track(
            Property::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[a.into(), b.into()],
        );
        let q = DQuat::from_vec4(t.sample(0.5));
        let (axis, angle) = q.to_axis_angle();
        assert!((angle - 85f64.to_radians()).abs() < 1e-12, "{angle}");
        assert!((axis.z.abs() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn cubic_spline_reproduces_a_cubic_polynomial() {
        // x(t) = t³ − t on keys 0, 0.5, 2 with exact tangents x'(t) = 3t² − 1.
        let f = |t: f64| t * t * t - t;
        let df = |t: f64| 3.0 * t * t - 1.0;
        let times = [0.0, 0.5, 2.0];
        let mut values = Vec::new();
        for &t in &times {
            values.extend([DVec4::splat(df(t)), DVec4::splat(f(t)), DVec4::splat(df(t))]);
        }
        let tr = track(
            Property::Translation,
            Interpolation::CubicSpline,
            &times,
            &values,
        );
        for t in [0.1, 0.37, 0.8, 1.5, 1.99] {
            assert!((tr.sample(t).x - f(t)).abs() < 1e-12, "t = {t}");
        }
    }

    #[test]
    fn world_transforms_compose_parents_first_and_skinning_is_rigid_per_bone() {
        // Node 1 is child of 0; listed child-first to exercise the ordering.
        let rest = vec![
            Trs {
                translation: DVec3::new(1.0, 0.0, 0.0),
                ..Trs::default()
            },
            Trs {
                translation: DVec3::new(0.0, 2.0, 0.0),
                rotation: DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
                ..Trs::default()
            },
        ];
        let affine = rest.iter().map(Trs::affine).collect();
        let sk = Skeleton::new(vec![None, Some(0)], rest.clone(), affine).unwrap();
        let w = sk.world_at(None, 0.0);
        assert!(w[1]
            .translation
            .abs_diff_eq(DVec3::new(1.0, 2.0, 0.0), 1e-15));
        assert!(Skeleton::new(
            vec![Some(1), Some(0)],
            rest.clone(),
            vec![DAffine3::IDENTITY; 2]
        )
        .is_none());

        // A vertex bound to node 1 alone at the rest pose (inverse bind = inverse rest world)
        // stays where it is at rest and moves rigidly with the node.
        let mesh = SkinnedMesh {
            name: "m".into(),
            node: 1,
            positions: vec![DVec3::new(1.5, 2.0, 0.0)],
            triangles: vec![],
            joints: vec![1],
            inverse_bind: vec![w[1].inverse()],
            per_vertex: 4,
            influence_joint: vec![0, 0, 0, 0],
            influence_weight: vec![1.0, 0.0, 0.0, 0.0],
        };
        assert!(mesh.deform(&w)[0].abs_diff_eq(DVec3::new(1.5, 2.0, 0.0), 1e-15));
        let clip = Clip {
            name: "up".into(),
            index: 0,
            tracks: vec![Track {
                node: 0,
                property: Property::Translation,
                interpolation: Interpolation::Linear,
                times: vec![0.0, 1.0],
                values: vec![
                    DVec4::new(1.0, 0.0, 0.0, 0.0),
                    DVec4::new(1.0, 0.0, 3.0, 0.0),
                ],
            }],
            weights: Vec::new(),
        };
        assert_eq!((clip.start(), clip.end()), (0.0, 1.0));
        let moved = mesh.deform(&sk.world_at(Some(&clip), 0.5));
        assert!(moved[0].abs_diff_eq(DVec3::new(1.5, 2.0, 1.5), 1e-15));
    }
}
