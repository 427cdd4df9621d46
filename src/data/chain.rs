//! Joint chains and forward kinematics.
//!
//! A [`Chain`] is a path of joints 0..n-1 (joint 0 the root, joint n-1 the end effector). Joint i
//! has a local transform relative to its parent, in glTF order translation · rotation · scale:
//! the translation is the joint's rest offset `o_i` in its parent's frame, the rotation `r_i` is a
//! unit quaternion (x, y, z, w) and the scale is usually (1, 1, 1). The parent of joint 0 is the
//! chain's `base` frame: the world transform of everything above the chain root (identity for
//! generated chains, the product of the ancestors' node transforms for a rig).
//!
//! Solvers change only the rotations; a [`Pose`] holds them together with the world frames that
//! forward kinematics derives from them.

use glam::{DAffine3, DMat3, DQuat, DVec3};

use crate::error::{Error, Result};

/// One joint of a chain: its rest local transform and name.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Node name (`joint_0`… for generated chains, the node's name in a rig).
    pub name: String,
    /// Rest offset in the parent's frame (scene units).
    pub translation: DVec3,
    /// Rest local rotation (unit quaternion).
    pub rotation: DQuat,
    /// Local scale (non-zero on every axis).
    pub scale: DVec3,
}

impl Joint {
    /// A joint with identity rotation and unit scale.
    pub fn new(name: impl Into<String>, translation: DVec3) -> Self {
        Joint {
            name: name.into(),
            translation,
            rotation: DQuat::IDENTITY,
            scale: DVec3::ONE,
        }
    }
}

/// A validated chain of at least two joints.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    joints: Vec<Joint>,
    base: DAffine3,
}

/// The rotations of a chain and the world frames computed from them.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    /// Local rotation of each joint (unit quaternions, in the parent's frame).
    pub rotations: Vec<DQuat>,
    /// World frame of each joint (kept up to date by [`Chain::fk`]).
    pub world: Vec<DAffine3>,
}

impl Pose {
    /// World position of joint `i`.
    pub fn position(&self, i: usize) -> DVec3 {
        self.world[i].translation
    }

    /// World position of the end effector.
    pub fn tip(&self) -> DVec3 {
        self.world[self.world.len() - 1].translation
    }
}

impl Chain {
    /// Builds a chain, checking that it has at least two joints, finite values, non-zero scales
    /// and non-zero bone offsets; rotations are normalised.
    ///
    /// # Errors
    /// [`Error::Chain`] naming the offending joint.
    pub fn new(mut joints: Vec<Joint>, base: DAffine3) -> Result<Self> {
        if joints.len() < 2 {
            return Err(Error::Chain(format!(
                "a chain needs at least 2 joints, got {}",
                joints.len()
            )));
        }
        if !base.is_finite() || base.matrix3.determinant().abs() < 1e-12 {
            return Err(Error::Chain(
                "the frame above the chain root is degenerate or not finite".into(),
            ));
        }
        for (i, j) in joints.iter_mut().enumerate() {
            if !(j.translation.is_finite() && j.rotation.is_finite() && j.scale.is_finite()) {
                return Err(Error::Chain(format!(
                    "joint `{}`: non-finite transform",
                    j.name
                )));
            }
            if j.scale.abs().min_element() < 1e-12 {
                return Err(Error::Chain(format!("joint `{}`: zero scale", j.name)));
            }
            if j.rotation.length() < 1e-6 {
                return Err(Error::Chain(format!(
                    "joint `{}`: zero rotation quaternion",
                    j.name
                )));
            }
            j.rotation = j.rotation.normalize();
            if i > 0 && j.translation.length() < 1e-12 {
                return Err(Error::Chain(format!(
                    "joint `{}`: zero offset from its parent (bone of length 0)",
                    j.name
                )));
            }
        }
        Ok(Chain { joints, base })
    }

    /// The labs' 5-joint arm: root at (0, 1.7, 0), child offsets (0,-0.8,0), (0,-0.4,0),
    /// (0,-0.2,0), (0,-1.2,0) (reach 2.6), identity rotations, joints `joint_0`…`joint_4`.
    pub fn lab_arm() -> Self {
        let offsets = [
            DVec3::new(0.0, 1.7, 0.0),
            DVec3::new(0.0, -0.8, 0.0),
            DVec3::new(0.0, -0.4, 0.0),
            DVec3::new(0.0, -0.2, 0.0),
            DVec3::new(0.0, -1.2, 0.0),
        ];
        let joints = offsets
            .iter()
            .enumerate()
            .map(|(i, o)| Joint::new(format!("joint_{i}"), *o))
            .collect();
        Chain::new(joints, DAffine3::IDENTITY).expect("the lab arm is valid")
    }

    /// A straight chain of `n` joints and total length `length` hanging down (-Y) from a root
    /// at (0, length·1.7/2.6, 0), the lab arm's proportions; bones are `length / (n-1)` long.
    ///
    /// # Errors
    /// [`Error::Chain`] for `n < 2` or a length that is not a positive number (a job checks
    /// both first, naming its options).
    pub fn straight(n: usize, length: f64) -> Result<Self> {
        if n < 2 {
            return Err(Error::Chain(format!(
                "a chain needs at least 2 joints, got {n}"
            )));
        }
        if !(length.is_finite() && length > 0.0) {
            return Err(Error::Chain(format!(
                "a chain's length must be a positive number, got {length}"
            )));
        }
        let bone = length / (n - 1) as f64;
        let joints = (0..n)
            .map(|i| {
                let o = if i == 0 {
                    DVec3::new(0.0, length * ROOT_HEIGHT_FRACTION, 0.0)
                } else {
                    DVec3::new(0.0, -bone, 0.0)
                };
                Joint::new(format!("joint_{i}"), o)
            })
            .collect();
        Chain::new(joints, DAffine3::IDENTITY)
    }

    /// Number of joints (the end effector included).
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// Always false: a chain has at least two joints.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The joints, root first.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// World frame of the root's parent.
    pub fn base(&self) -> DAffine3 {
        self.base
    }

    /// Local transform of joint `i` with rotation `r`.
    #[inline]
    pub fn local(&self, i: usize, r: DQuat) -> DAffine3 {
        let j = &self.joints[i];
        DAffine3::from_scale_rotation_translation(j.scale, r, j.translation)
    }

    /// The rest pose (the joints' own rotations), with world frames computed.
    pub fn rest_pose(&self) -> Pose {
        let mut pose = Pose {
            rotations: self.joints.iter().map(|j| j.rotation).collect(),
            world: vec![DAffine3::IDENTITY; self.len()],
        };
        self.fk(&mut pose, 0);
        pose
    }

    /// Forward kinematics from joint `start`: recomputes `pose.world[start..]` from the rotations
    /// (`R_i = R_{i-1} · r_i`, `p_i = p_{i-1} + R_{i-1} · o_i` for unit scales), renormalising
    /// the rotations it touches.
    pub fn fk(&self, pose: &mut Pose, start: usize) {
        for i in start..self.len() {
            let r = pose.rotations[i].normalize();
            pose.rotations[i] = r;
            let parent = if i == 0 { self.base } else { pose.world[i - 1] };
            pose.world[i] = parent * self.local(i, r);
        }
    }

    /// The linear part of joint `i`'s parent frame.
    #[inline]
    pub fn parent_linear(&self, pose: &Pose, i: usize) -> DMat3 {
        if i == 0 {
            self.base.matrix3
        } else {
            pose.world[i - 1].matrix3
        }
    }

    /// Sum of the world bone lengths in `pose` (the reach from the root).
    pub fn reach(&self, pose: &Pose) -> f64 {
        (1..self.len())
            .map(|i| pose.position(i).distance(pose.position(i - 1)))
            .sum()
    }

    /// Rotates joint `i` (in its parent's frame) by the smallest rotation that turns the current
    /// world direction `from` (a vector from joint i) into `to`; both are world vectors. The
    /// rotation is expressed in the parent's frame: `r_i ← (A⁻¹ q A) r_i` where `A` is the parent
    /// frame (for a rotation frame `R_{i-1}`, `r_i ← R_{i-1}⁻¹ q R_{i-1} r_i`). Does not run FK.
    /// Returns false (and changes nothing) when either vector is degenerate.
    pub fn rotate_joint_towards(&self, pose: &mut Pose, i: usize, from: DVec3, to: DVec3) -> bool {
        let inv = self.parent_linear(pose, i).inverse();
        rotate_local(&mut pose.rotations[i], inv * from, inv * to)
    }

    /// Limits every joint's rotation to at most `max_angle` radians away from `previous`
    /// (slerping towards it), then runs FK. Returns true if any joint was clamped.
    pub fn clamp_to(&self, pose: &mut Pose, previous: &Pose, max_angle: f64) -> bool {
        let mut clamped = false;
        for (r, p) in pose.rotations.iter_mut().zip(&previous.rotations) {
            let p = if p.dot(*r) < 0.0 { -*p } else { *p };
            let angle = p.angle_between(*r);
            if angle > max_angle && angle > 1e-12 {
                *r = p.slerp(*r, max_angle / angle).normalize();
                clamped = true;
            }
        }
        if clamped {
            self.fk(pose, 0);
        }
        clamped
    }
}

/// Height of a generated chain's root as a fraction of its length (the lab arm's 1.7 / 2.6).
pub const ROOT_HEIGHT_FRACTION: f64 = 1.7 / 2.6;

/// `r ← from_to(a, b) · r` for local vectors a, b; false when either is degenerate.
#[inline]
pub(crate) fn rotate_local(r: &mut DQuat, a: DVec3, b: DVec3) -> bool {
    let (la, lb) = (a.length(), b.length());
    if la < 1e-12 || lb < 1e-12 {
        return false;
    }
    let q = DQuat::from_rotation_arc(a / la, b / lb);
    *r = (q * *r).normalize();
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn lab_arm_rest_tip_and_reach() {
        let c = Chain::lab_arm();
        let p = c.rest_pose();
        assert_abs_diff_eq!(p.tip().y, -0.9, epsilon = 1e-12);
        assert_abs_diff_eq!(c.reach(&p), 2.6, epsilon = 1e-12);
    }

    #[test]
    fn fk_follows_the_lab_formula() {
        let c = Chain::lab_arm();
        let mut p = c.rest_pose();
        p.rotations[1] = DQuat::from_rotation_z(0.3);
        p.rotations[2] = DQuat::from_rotation_x(-0.5);
        c.fk(&mut p, 1);
        // R_i = R_{i-1} r_i, p_i = p_{i-1} + R_{i-1} o_i.
        let mut rw = DQuat::IDENTITY;
        let mut pos = DVec3::ZERO;
        for i in 0..c.len() {
            pos = if i == 0 {
                c.joints()[0].translation
            } else {
                pos + rw * c.joints()[i].translation
            };
            rw *= p.rotations[i];
            assert_abs_diff_eq!(pos.distance(p.position(i)), 0.0, epsilon = 1e-12);
        }
    }

    #[test]
    fn straight_chain_rejects_bad_options() {
        assert!(matches!(Chain::straight(1, 1.0), Err(Error::Chain(_))));
        assert!(matches!(Chain::straight(3, -1.0), Err(Error::Chain(_))));
        assert!(matches!(Chain::straight(3, f64::NAN), Err(Error::Chain(_))));
        let c = Chain::straight(4, 3.0).unwrap();
        assert_abs_diff_eq!(c.reach(&c.rest_pose()), 3.0, epsilon = 1e-12);
    }

    #[test]
    fn clamp_limits_angle() {
        let c = Chain::lab_arm();
        let prev = c.rest_pose();
        let mut p = prev.clone();
        p.rotations[0] = DQuat::from_rotation_z(1.0);
        assert!(c.clamp_to(&mut p, &prev, 0.1));
        assert_abs_diff_eq!(
            p.rotations[0].angle_between(DQuat::IDENTITY),
            0.1,
            epsilon = 1e-9
        );
    }
}
