//! Cloth driven by a moving body: pins that ride a character's skinned surface (or one joint),
//! and a body that moves as a collider. [`Drive`] is what a bake needs from either source of
//! body positions: a skinned character ([`CharacterDrive`]) or a mesh sequence
//! ([`SequenceDrive`]).
//!
//! A character:
//!
//! Frames: the character's document frame scaled by [`CharacterDrive::scale`] (metres per
//! document unit) is the cloth's frame; the garment is given in the character's rest pose (every
//! node at its own transform), already placed in metres.
//!
//! Time: simulation time τ (seconds from frame 0) runs through three phases:
//! 1. a blend-in of `blend_in` seconds from the rest pose to the animation's first pose (each
//!    animated node's translation and scale lerped, rotation slerped, by a smoothstep of τ), so
//!    the garment is not torn by a jump from the rest pose to the first key;
//! 2. the animation, played in a loop from its first key: τ − blend_in wraps modulo the
//!    animation's duration.
//!
//! A pin bound to the surface follows linear blend skinning with the influences of the nearest
//! body point (the skin weights of its triangle's corners blended by barycentric coordinates):
//! at time τ it is at Σₖ wₖ·Wₖ(τ)·Wₖ(rest)⁻¹·p, with Wₖ the world transform of joint k and p its
//! rest position. It therefore moves exactly as the body surface under it (to the skinning's
//! linearity), keeping its offset from the surface.

use std::sync::Arc;

use glam::{DAffine3, DVec3};

use super::collide::{Collider, MeshCollider};
use crate::data::animation::{Clip, Skeleton, SkinnedMesh, Trs};
use crate::data::MeshSequence;
use crate::error::{Error, Result};

/// A source of body positions (and pin positions) over simulation time.
pub trait Drive: std::fmt::Debug {
    /// The particles the drive moves, in [`DrivenPose::pins`] order.
    fn pins(&self) -> &[Binding];

    /// The body where the simulation starts, metres in the cloth's frame, as a collider; `None`
    /// without a body.
    ///
    /// # Errors
    /// As [`MeshCollider::new`].
    fn rest_body(&self) -> Result<Option<MeshCollider>>;

    /// The pins and the body at simulation time `tau` (seconds), metres in the cloth's frame.
    fn pose(&self, tau: f64) -> DrivenPose;
}

/// A body given as a mesh sequence, moving as a collider: at time τ its vertices are linearly
/// interpolated between the two frames around τ (held at the last frame after it). It carries no
/// pins: pinned particles stay where they are.
#[derive(Debug, Clone)]
pub struct SequenceDrive {
    sequence: MeshSequence,
}

impl SequenceDrive {
    /// A drive playing `sequence` from its first frame at simulation time 0.
    pub fn new(sequence: MeshSequence) -> Self {
        SequenceDrive { sequence }
    }

    /// The sequence.
    pub fn sequence(&self) -> &MeshSequence {
        &self.sequence
    }
}

impl Drive for SequenceDrive {
    fn pins(&self) -> &[Binding] {
        &[]
    }

    fn rest_body(&self) -> Result<Option<MeshCollider>> {
        let s = &self.sequence;
        MeshCollider::from_mesh(&s.files[0], s.frames[0].clone(), s.mesh.triangles.clone())
            .map(Some)
    }

    fn pose(&self, tau: f64) -> DrivenPose {
        DrivenPose {
            pins: Vec::new(),
            body: self.sequence.at(tau),
        }
    }
}

/// How a pinned particle follows the character.
#[derive(Debug, Clone, PartialEq)]
pub struct Binding {
    /// The particle (model index).
    pub particle: u32,
    /// (node, weight) pairs, weights summing to 1.
    pub influences: Vec<(usize, f64)>,
    /// Its rest position in document units.
    pub rest: DVec3,
}

/// An animated character driving a bake.
#[derive(Debug, Clone)]
pub struct CharacterDrive {
    skeleton: Skeleton,
    clip: Clip,
    posed: Vec<bool>,
    /// Inverse rest world transform of every node.
    rest_inverse: Vec<DAffine3>,
    /// The skinned body merged into one mesh, if it collides.
    body: Option<Body>,
    /// Metres per document unit.
    pub scale: f64,
    /// Blend-in from the rest pose, seconds.
    pub blend_in: f64,
    /// The pinned particles' bindings.
    pub pins: Vec<Binding>,
}

/// The character's skinned meshes merged into one body.
#[derive(Debug, Clone)]
struct Body {
    meshes: Vec<SkinnedMesh>,
    triangles: Vec<[u32; 3]>,
}

/// A pose of the character at one time, in the cloth's frame (metres).
#[derive(Debug, Clone)]
pub struct DrivenPose {
    /// Each binding's position, in [`CharacterDrive::pins`] order.
    pub pins: Vec<DVec3>,
    /// The body's vertex positions (empty without a body collider).
    pub body: Vec<DVec3>,
}

impl CharacterDrive {
    /// A drive from a skeleton, the animation that moves it, and its skinned meshes
    /// (`bodies`, used both to bind pins and, when `collide`, as the moving collider).
    /// `scale` is metres per document unit, `blend_in` seconds.
    ///
    /// # Errors
    /// [`Error::Value`] when the animation has no duration (the job names the option).
    pub fn new(
        skeleton: Skeleton,
        clip: Clip,
        bodies: Vec<SkinnedMesh>,
        scale: f64,
        blend_in: f64,
    ) -> Result<Self> {
        if clip.duration().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(Error::value(format!(
                "`{}` has no duration (one key or none)",
                clip.name
            )));
        }
        let posed = clip.animated_nodes(skeleton.len());
        let rest_inverse = skeleton
            .world_at(None, 0.0)
            .iter()
            .map(DAffine3::inverse)
            .collect();
        let mut triangles = Vec::new();
        let mut base = 0u32;
        for m in &bodies {
            triangles.extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
            base += m.positions.len() as u32;
        }
        Ok(CharacterDrive {
            skeleton,
            clip,
            posed,
            rest_inverse,
            body: (!bodies.is_empty()).then_some(Body {
                meshes: bodies,
                triangles,
            }),
            scale,
            blend_in,
            pins: Vec::new(),
        })
    }

    /// The animation's name.
    pub fn clip_name(&self) -> &str {
        &self.clip.name
    }

    /// The animation's duration (one cycle), seconds.
    pub fn cycle(&self) -> f64 {
        self.clip.duration()
    }

    /// True when the character has skinned meshes (a body to bind pins to and collide with).
    pub fn has_body(&self) -> bool {
        self.body.is_some()
    }

    /// Node world transforms at simulation time `tau` (seconds), document units.
    pub fn world(&self, tau: f64) -> Vec<DAffine3> {
        let start = self.clip.start();
        if tau < self.blend_in {
            let s = tau / self.blend_in;
            let s = s * s * (3.0 - 2.0 * s);
            let first = self.skeleton.pose(Some(&self.clip), start);
            let pose: Vec<Trs> = self
                .skeleton
                .rest
                .iter()
                .zip(&first)
                .map(|(a, b)| Trs {
                    translation: a.translation.lerp(b.translation, s),
                    rotation: a.rotation.slerp(b.rotation, s),
                    scale: a.scale.lerp(b.scale, s),
                })
                .collect();
            return self.skeleton.world(&pose, &self.posed);
        }
        self.world_in_clip(start + (tau - self.blend_in).rem_euclid(self.cycle()))
    }

    /// Node world transforms at time `t` of the animation itself (seconds on the clip's clock:
    /// no blend-in, no wrap), the pose a player of the file shows at `t`; document units.
    pub fn world_in_clip(&self, t: f64) -> Vec<DAffine3> {
        self.skeleton
            .world(&self.skeleton.pose(Some(&self.clip), t), &self.posed)
    }

    /// The body at rest (every node at its own transform), metres in the cloth's frame, as a
    /// collider; `None` without skinned meshes.
    ///
    /// # Errors
    /// As [`MeshCollider::new`].
    pub fn rest_body(&self) -> Result<Option<MeshCollider>> {
        let Some(body) = &self.body else {
            return Ok(None);
        };
        let positions = self.body_positions(body, &self.skeleton.world_at(None, 0.0));
        MeshCollider::new(positions, body.triangles.clone()).map(Some)
    }

    fn body_positions(&self, body: &Body, world: &[DAffine3]) -> Vec<DVec3> {
        body.meshes
            .iter()
            .flat_map(|m| m.deform(world))
            .map(|p| p * self.scale)
            .collect()
    }

    /// Binds `particles` (model indices, rest positions `rest` in metres) to the body surface:
    /// each to the influences of the nearest body point (see the module documentation).
    ///
    /// # Errors
    /// [`Error::Value`] when the character has no skinned mesh to bind to ([`Self::has_body`];
    /// the job checks it first, naming its options).
    pub fn bind_to_surface(&mut self, particles: &[u32], rest: &[DVec3]) -> Result<()> {
        let Some(body) = &self.body else {
            return Err(Error::value(
                "the character has no skinned mesh to bind the pins to",
            ));
        };
        let collider = self
            .rest_body()?
            .expect("a body exists, so its rest pose does");
        // Vertex → (mesh, vertex in mesh).
        let owner: Vec<(usize, usize)> = body
            .meshes
            .iter()
            .enumerate()
            .flat_map(|(m, mesh)| (0..mesh.positions.len()).map(move |v| (m, v)))
            .collect();
        for &p in particles {
            let at = rest[p as usize];
            let (corners, bary) = collider
                .closest(at, f64::INFINITY)
                .expect("an unbounded search finds the nearest triangle");
            let mut influences: Vec<(usize, f64)> = Vec::new();
            for (&c, b) in corners.iter().zip(bary.to_array()) {
                let (m, v) = owner[c as usize];
                let mesh = &body.meshes[m];
                let range = v * mesh.per_vertex..(v + 1) * mesh.per_vertex;
                for (&j, &w) in mesh.influence_joint[range.clone()]
                    .iter()
                    .zip(&mesh.influence_weight[range])
                {
                    let w = b.clamp(0.0, 1.0) * f64::from(w);
                    if w == 0.0 {
                        continue;
                    }
                    let node = mesh.joints[j as usize];
                    match influences.iter_mut().find(|(n, _)| *n == node) {
                        Some((_, sum)) => *sum += w,
                        None => influences.push((node, w)),
                    }
                }
            }
            let total: f64 = influences.iter().map(|(_, w)| w).sum();
            for (_, w) in &mut influences {
                *w /= total;
            }
            self.pins.push(Binding {
                particle: p,
                influences,
                rest: at / self.scale,
            });
        }
        Ok(())
    }

    /// Averages the pins' influences (as [`Self::bind_to_surface`] bound them) over their
    /// neighbourhoods: each pin takes the mean of the influences of the pins within `radius`
    /// metres of it at rest, weighted by a Gaussian of standard deviation `radius` / 2, so that
    /// two neighbouring pins move almost alike even where the skin weights under them change
    /// abruptly (a band pinned across the hips and a thigh, or the torso and an arm). A zero
    /// radius changes nothing. The pins keep their rest positions: every influence moves a
    /// point not at all in the rest pose.
    pub fn smooth_pins(&mut self, radius: f64) {
        if radius.is_nan() || radius <= 0.0 || self.pins.len() < 2 {
            return;
        }
        let reach = radius / self.scale;
        let sigma2 = (0.5 * reach) * (0.5 * reach);
        // Pins in order of x, so that each looks only at those within `reach` along x.
        let mut order: Vec<usize> = (0..self.pins.len()).collect();
        order.sort_by(|&a, &b| self.pins[a].rest.x.total_cmp(&self.pins[b].rest.x));
        let nodes = self
            .pins
            .iter()
            .flat_map(|b| b.influences.iter().map(|&(n, _)| n + 1))
            .max()
            .unwrap_or(0);
        let mut sum = vec![0.0; nodes];
        let mut smoothed = Vec::with_capacity(self.pins.len());
        for (k, &i) in order.iter().enumerate() {
            let at = self.pins[i].rest;
            sum.fill(0.0);
            let mut total = 0.0;
            let near = order[..k]
                .iter()
                .rev()
                .take_while(|&&j| at.x - self.pins[j].rest.x <= reach)
                .chain(
                    order[k..]
                        .iter()
                        .take_while(|&&j| self.pins[j].rest.x - at.x <= reach),
                );
            for &j in near {
                let d2 = self.pins[j].rest.distance_squared(at);
                if d2 > reach * reach {
                    continue;
                }
                let g = (-0.5 * d2 / sigma2).exp();
                total += g;
                for &(n, w) in &self.pins[j].influences {
                    sum[n] += g * w;
                }
            }
            let influences: Vec<(usize, f64)> = sum
                .iter()
                .enumerate()
                .filter(|&(_, &w)| w > 0.0)
                .map(|(n, &w)| (n, w / total))
                .collect();
            smoothed.push((i, influences));
        }
        for (i, influences) in smoothed {
            self.pins[i].influences = influences;
        }
    }

    /// Binds `particles` rigidly to node `node`.
    pub fn bind_to_node(&mut self, particles: &[u32], rest: &[DVec3], node: usize) {
        self.pins.extend(particles.iter().map(|&p| Binding {
            particle: p,
            influences: vec![(node, 1.0)],
            rest: rest[p as usize] / self.scale,
        }));
    }

    /// The pins and the body at simulation time `tau` (seconds), metres in the cloth's frame.
    pub fn pose(&self, tau: f64) -> DrivenPose {
        let world = self.world(tau);
        let pins = self
            .pins
            .iter()
            .map(|b| {
                b.influences
                    .iter()
                    .map(|&(n, w)| (world[n] * self.rest_inverse[n]).transform_point3(b.rest) * w)
                    .sum::<DVec3>()
                    * self.scale
            })
            .collect();
        let body = self
            .body
            .as_ref()
            .map_or_else(Vec::new, |b| self.body_positions(b, &world));
        DrivenPose { pins, body }
    }

    /// The body collider for a step that ends at `tau`, moving from `before` (the previous
    /// step's end pose).
    ///
    /// # Errors
    /// As [`MeshCollider::new`] (a pose with non-finite positions).
    pub fn moving_body(before: &Arc<MeshCollider>, after: Vec<DVec3>) -> Result<Collider> {
        Collider::moving(Arc::clone(before), after)
    }
}

impl Drive for CharacterDrive {
    fn pins(&self) -> &[Binding] {
        &self.pins
    }

    fn rest_body(&self) -> Result<Option<MeshCollider>> {
        CharacterDrive::rest_body(self)
    }

    fn pose(&self, tau: f64) -> DrivenPose {
        CharacterDrive::pose(self, tau)
    }
}
