//! FABRIK (forward and backward reaching inverse kinematics).
//!
//! One iteration is a backward pass (tip onto the target, each joint pulled onto the line towards
//! its old position at its bone length), a forward pass (root back in place, each child pulled
//! onto the line towards its backward-pass position), then a rotation rebuild: from the root
//! down, each joint turns by the smallest rotation that carries its child's current direction
//! onto the solved one, expressed in the joint's parent frame (so rig frames, rest rotations and
//! scales are respected, and twist carries over continuously from the previous frame), then FK.
//! The error is measured on the FK pose, never on the pass positions.
//!
//! Under [`Constraints`] the passes' positions are first turned to face the pole, and the
//! rebuild clamps each joint to its limit before aiming the next (a hinged joint's parent first
//! twists about its bone so the hinge can bend the right way), so every iteration ends in a pose
//! that respects the limits. Under a twist limit that roll may be out of range: the bend plane
//! then swivels about the root–tip line to the nearest one the limits allow.

use glam::DVec3;

use super::chain::{Chain, Pose};
use super::constraints::{face_pole, Constraints};
use super::solver::{aim_swivelled, begin, end, Begin, IkSolver, SolveReport, SolverConfig};
use crate::error::Result;

/// The FABRIK solver.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Fabrik {
    /// Iteration cap, tolerance and rotation limit.
    pub config: SolverConfig,
}

/// One backward + forward pass over `p` (world joint positions) with bone lengths `d`
/// (`d[i] = |p[i+1] - p[i]|`), keeping `p[0]` fixed.
pub fn fabrik_pass(p: &mut [DVec3], d: &[f64], target: DVec3) {
    let n = p.len();
    let root = p[0];
    p[n - 1] = target;
    for i in (0..n - 1).rev() {
        let dir = (p[i] - p[i + 1]).normalize_or_zero();
        p[i] = p[i + 1] + dir * d[i];
    }
    p[0] = root;
    for i in 0..n - 1 {
        let dir = (p[i + 1] - p[i]).normalize_or_zero();
        p[i + 1] = p[i] + dir * d[i];
    }
}

impl IkSolver for Fabrik {
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
        let mut p: Vec<DVec3> = (0..n).map(|i| pose.position(i)).collect();
        let d: Vec<f64> = (0..n - 1).map(|i| p[i + 1].distance(p[i])).collect();
        let mut iterations = 0;
        while iterations < cfg.max_iterations && pose.tip().distance(target) > cfg.tolerance {
            iterations += 1;
            for (i, q) in p.iter_mut().enumerate() {
                *q = pose.position(i);
            }
            fabrik_pass(&mut p, &d, target);
            if let Some(pole) = c.pole {
                face_pole(&mut p, pole);
            }
            aim_swivelled(chain, pose, &p, cfg.tolerance, c);
        }
        Ok(end(chain, pose, start.as_ref(), target, iterations, cfg, c))
    }

    fn name(&self) -> &'static str {
        "fabrik"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ik::chain::Joint;
    use approx::assert_abs_diff_eq;
    use glam::{DAffine3, DQuat};

    #[test]
    fn pass_keeps_bone_lengths_and_root() {
        let chain = Chain::lab_arm();
        let pose = chain.rest_pose();
        let mut p: Vec<DVec3> = (0..chain.len()).map(|i| pose.position(i)).collect();
        let d: Vec<f64> = (0..chain.len() - 1)
            .map(|i| p[i + 1].distance(p[i]))
            .collect();
        let root = p[0];
        for target in [
            DVec3::new(0.6, 0.0, 0.0),
            DVec3::new(-0.3, 0.2, 0.5),
            DVec3::new(0.0, 1.5, 0.1),
        ] {
            fabrik_pass(&mut p, &d, target);
            assert_abs_diff_eq!(p[0].distance(root), 0.0, epsilon = 1e-12);
            for i in 0..d.len() {
                assert_abs_diff_eq!(p[i + 1].distance(p[i]), d[i], epsilon = 1e-12);
            }
        }
    }

    #[test]
    fn solve_keeps_bone_lengths_in_a_rotated_scaled_rig_frame() {
        let base = DAffine3::from_scale_rotation_translation(
            DVec3::splat(2.0),
            DQuat::from_rotation_y(0.8),
            DVec3::new(1.0, 2.0, 3.0),
        );
        let mut j = vec![
            Joint::new("a", DVec3::ZERO),
            Joint::new("b", DVec3::new(0.0, 1.0, 0.0)),
            Joint::new("c", DVec3::new(0.0, 1.0, 0.0)),
            Joint::new("d", DVec3::new(0.0, 0.5, 0.0)),
        ];
        j[1].rotation = -DQuat::from_rotation_x(0.4); // w < 0, as in RiggedSimple
        j[2].rotation = DQuat::from_rotation_z(-0.9);
        let chain = Chain::new(j, base).unwrap();
        let mut pose = chain.rest_pose();
        let rest = pose.clone();
        let target = pose.position(0) + DVec3::new(1.5, 2.0, -1.0);
        let r = Fabrik::default().solve(&chain, &mut pose, target).unwrap();
        assert!(r.reached, "{r:?}");
        for i in 1..chain.len() {
            assert_abs_diff_eq!(
                pose.position(i).distance(pose.position(i - 1)),
                rest.position(i).distance(rest.position(i - 1)),
                epsilon = 1e-9
            );
        }
        assert_abs_diff_eq!(
            pose.position(0).distance(rest.position(0)),
            0.0,
            epsilon = 1e-12
        );
    }

    #[test]
    fn target_on_the_line_of_a_straight_chain_is_reached_by_both_solvers() {
        // The lab heart starts at the centre, straight below the root of the straight arm.
        let chain = Chain::lab_arm();
        for solver in [
            &Fabrik::default() as &dyn IkSolver,
            &crate::ik::Ccd::default(),
        ] {
            let mut pose = chain.rest_pose();
            let r = solver.solve(&chain, &mut pose, DVec3::ZERO).unwrap();
            assert!(r.reached, "{}: {r:?}", solver.name());
        }
    }

    /// Twist of `delta` about the unit axis `a` (swing-twist decomposition), radians.
    fn twist_about(delta: DQuat, a: DVec3) -> f64 {
        let d = if delta.w < 0.0 { -delta } else { delta };
        2.0 * DVec3::new(d.x, d.y, d.z).dot(a).atan2(d.w)
    }

    #[test]
    fn rebuild_adds_no_twist_about_the_bones_between_frames() {
        // Lab arm with twisted rest rotations: FABRIK must only swing the bones frame to frame.
        let mut j: Vec<Joint> = Chain::lab_arm().joints().to_vec();
        j[1].rotation = DQuat::from_rotation_y(0.9);
        j[2].rotation = DQuat::from_rotation_y(-0.4) * DQuat::from_rotation_x(0.2);
        let chain = Chain::new(j, DAffine3::IDENTITY).unwrap();
        let solver = Fabrik::default();
        let mut pose = chain.rest_pose();
        let mut prev = pose.clone();
        for k in 0..150 {
            let t = std::f64::consts::TAU * k as f64 / 150.0;
            let r = solver
                .solve(
                    &chain,
                    &mut pose,
                    DVec3::new(0.6 * t.cos(), 0.0, 0.6 * t.sin()),
                )
                .unwrap();
            assert!(r.reached);
            if k > 0 {
                for i in 0..chain.len() - 1 {
                    // The child's direction in joint i's parent frame before this frame's solve.
                    let c = (prev.rotations[i] * chain.joints()[i + 1].translation).normalize();
                    let delta = pose.rotations[i] * prev.rotations[i].inverse();
                    assert!(
                        twist_about(delta, c).abs() < 0.2f64.to_radians(),
                        "frame {k} joint {i}: twist {}°",
                        twist_about(delta, c).to_degrees()
                    );
                }
            }
            prev = pose.clone();
        }
    }

    #[test]
    fn unreachable_target_straightens_the_chain() {
        let chain = Chain::lab_arm();
        let mut pose = chain.rest_pose();
        let target = DVec3::new(3.0, 1.7, 1.0);
        let r = Fabrik::default().solve(&chain, &mut pose, target).unwrap();
        assert!(r.unreachable && !r.reached);
        let dir = (target - pose.position(0)).normalize();
        for i in 1..chain.len() {
            let v = (pose.position(i) - pose.position(0)).normalize();
            assert_abs_diff_eq!(v.dot(dir), 1.0, epsilon = 1e-9);
        }
        assert_abs_diff_eq!(
            r.error,
            target.distance(pose.position(0)) - 2.6,
            epsilon = 1e-9
        );
    }
}
