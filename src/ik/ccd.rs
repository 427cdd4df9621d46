//! Cyclic coordinate descent.
//!
//! Each iteration sweeps from the joint before the end effector down to the root. At joint i the
//! world rotation `q` that turns `effector - p_i` onto `target - p_i` is applied in the joint's
//! parent frame, `r_i ← R_{i-1}⁻¹ q R_{i-1} r_i` (the labs' `q r_i` is only right at the root or
//! when every parent rotation is the identity), clamped to the joint's limit if it has one, then
//! FK is refreshed from joint i. With a pole, each sweep ends by turning the chain about its
//! root–tip line to face the pole ([`Constraints`]); under a twist limit, by the nearest swivel
//! about that line the limits allow.

use glam::DVec3;

use super::chain::{Chain, Pose};
use super::constraints::{face_pole, Constraints, Limit};
use super::solver::{aim_swivelled, begin, end, Begin, IkSolver, SolveReport, SolverConfig};
use crate::error::Result;

/// The CCD solver.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Ccd {
    /// Iteration cap, tolerance and rotation limit.
    pub config: SolverConfig,
}

impl IkSolver for Ccd {
    fn solve_with(
        &self,
        chain: &Chain,
        pose: &mut Pose,
        target: DVec3,
        c: &Constraints,
    ) -> Result<SolveReport> {
        let cfg = &self.config;
        let start = match begin(chain, pose, target, cfg, c)? {
            Begin::Done(report) => return Ok(report),
            Begin::Iterate { start } => start,
        };
        let n = chain.len();
        let mut iterations = 0;
        while iterations < cfg.max_iterations && pose.tip().distance(target) > cfg.tolerance {
            iterations += 1;
            for i in (0..n - 1).rev() {
                let p = pose.position(i);
                let (from, to) = (pose.tip() - p, target - p);
                let mut moved = chain.rotate_joint_towards(pose, i, from, to);
                moved |= c.clamp(chain, i, &mut pose.rotations[i]);
                if moved {
                    chain.fk(pose, i);
                }
            }
            let mut p: Vec<DVec3> = (0..n).map(|i| pose.position(i)).collect();
            let faced = c.pole.is_some_and(|pole| face_pole(&mut p, pole));
            if faced
                || c.limits
                    .iter()
                    .any(|(_, l)| matches!(l, Limit::Twist { .. }))
            {
                aim_swivelled(chain, pose, &p, cfg.tolerance, c);
            }
        }
        Ok(end(chain, pose, start.as_ref(), target, iterations, cfg, c))
    }

    fn name(&self) -> &'static str {
        "ccd"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::chain::Joint;
    use approx::assert_abs_diff_eq;
    use glam::{DAffine3, DQuat};

    /// A chain whose root is rotated 90° about Z: the parent frame of joints 1.. is not the
    /// identity, so a world rotation applied as `q r_i` turns the bone the wrong way.
    fn rotated_parent_chain() -> Chain {
        let mut j0 = Joint::new("a", DVec3::ZERO);
        j0.rotation = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
        let mut j1 = Joint::new("b", DVec3::new(1.0, 0.0, 0.0));
        j1.rotation = DQuat::from_rotation_x(0.7);
        let j2 = Joint::new("c", DVec3::new(1.0, 0.0, 0.0));
        Chain::new(vec![j0, j1, j2], DAffine3::IDENTITY).unwrap()
    }

    #[test]
    fn parent_frame_update_aligns_effector_but_root_shortcut_does_not() {
        let chain = rotated_parent_chain();
        let pose = chain.rest_pose();
        let i = 1;
        let p = pose.position(i);
        let target = p + DVec3::new(0.3, 0.2, 0.9).normalize() * p.distance(pose.tip());
        let (a, b) = (pose.tip() - p, target - p);

        // Correct update, through the chain (r_i = R_{i-1}^-1 q R_{i-1} r_i).
        let mut good = pose.clone();
        assert!(chain.rotate_joint_towards(&mut good, i, a, b));
        chain.fk(&mut good, i);
        assert_abs_diff_eq!(good.tip().distance(target), 0.0, epsilon = 1e-9);
        // Same thing written with quaternions as in the docs.
        let q = DQuat::from_rotation_arc(a.normalize(), b.normalize());
        let parent = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
        let expected = (parent.inverse() * q * parent * pose.rotations[i]).normalize();
        assert!(good.rotations[i].dot(expected).abs() > 1.0 - 1e-12);

        // The labs' shortcut r_i = q r_i misses the target when the parent is rotated.
        let mut lab = pose.clone();
        lab.rotations[i] = q * lab.rotations[i];
        chain.fk(&mut lab, i);
        assert!(
            lab.tip().distance(target) > 0.1,
            "shortcut should be wrong here"
        );
    }

    #[test]
    fn ccd_aligns_directions_under_a_non_uniform_parent_scale() {
        // A squashed, rotated frame above the root: the local update is A⁻¹-based, so one CCD
        // step at a joint still points the effector straight at the target in world space.
        let base = DAffine3::from_scale_rotation_translation(
            DVec3::new(1.0, 3.0, 0.5),
            DQuat::from_rotation_z(0.4),
            DVec3::ONE,
        );
        let chain = Chain::new(
            vec![
                Joint::new("a", DVec3::ZERO),
                Joint::new("b", DVec3::new(0.0, 1.0, 0.0)),
                Joint::new("c", DVec3::new(0.0, 1.0, 0.0)),
            ],
            base,
        )
        .unwrap();
        let mut pose = chain.rest_pose();
        let p0 = pose.position(0);
        let target = p0 + DVec3::new(1.0, 0.5, 0.8);
        let (from, to) = (pose.tip() - p0, target - p0);
        assert!(chain.rotate_joint_towards(&mut pose, 0, from, to));
        chain.fk(&mut pose, 0);
        let dir = (pose.tip() - p0).normalize();
        assert_abs_diff_eq!(dir.dot((target - p0).normalize()), 1.0, epsilon = 1e-12);
    }

    #[test]
    fn ccd_reaches_a_target_with_rotated_parents() {
        let chain = rotated_parent_chain();
        let mut pose = chain.rest_pose();
        let target = DVec3::new(-0.8, 1.2, 0.4);
        let r = Ccd::default().solve(&chain, &mut pose, target).unwrap();
        assert!(r.reached && !r.unreachable, "{r:?}");
        assert!(pose.tip().distance(target) <= 1e-4);
    }
}
