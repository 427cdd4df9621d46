//! The IK solver trait, its configuration and per-solve report, and the behaviour shared by all
//! solvers (unreachable targets, the per-frame rotation limit).

use glam::DVec3;

use super::chain::{Chain, Pose};
use super::constraints::{self, Constraints, Limit};
use crate::error::{Error, Result};

/// Settings shared by the solvers.
///
/// ```
/// use scenebake::ik::SolverConfig;
/// let c = SolverConfig::default();
/// assert_eq!(c.max_iterations, 100);
/// assert_eq!(c.tolerance, 1e-4);
/// assert_eq!(c.max_angle, None);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverConfig {
    /// Iteration cap per solve (CCD: sweeps over the joints; FABRIK: backward + forward passes).
    pub max_iterations: usize,
    /// Distance between end effector and target (scene units) under which a solve stops and
    /// counts as reached.
    pub tolerance: f64,
    /// Largest rotation of any joint per solve, in radians, measured from the pose the solve
    /// started from (the previous frame when warm-starting); `None` = unlimited.
    pub max_angle: Option<f64>,
}

impl Default for SolverConfig {
    fn default() -> Self {
        SolverConfig {
            max_iterations: 100,
            tolerance: 1e-4,
            max_angle: None,
        }
    }
}

/// What one solve did. Non-convergence is reported here, never as an error.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SolveReport {
    /// Iterations performed (0 when the start pose already reached the target).
    pub iterations: usize,
    /// Final distance from end effector to target (scene units).
    pub error: f64,
    /// `error <= tolerance`.
    pub reached: bool,
    /// The target lies beyond the chain's reach: the chain was stretched straight towards it.
    pub unreachable: bool,
}

/// An inverse-kinematics solver: moves `pose` (warm start: whatever it holds) so the chain's end
/// effector reaches `target` (world coordinates).
pub trait IkSolver {
    /// Solves in place under `constraints` (pole, joint limits) and reports. The returned pose
    /// respects every limit.
    ///
    /// # Errors
    /// [`Error::Chain`] when the pose does not belong to the chain, the target is not finite or
    /// a limit names a joint the chain cannot limit.
    fn solve_with(
        &self,
        chain: &Chain,
        pose: &mut Pose,
        target: DVec3,
        constraints: &Constraints,
    ) -> Result<SolveReport>;

    /// Solves in place without constraints and reports.
    ///
    /// # Errors
    /// As [`IkSolver::solve_with`].
    fn solve(&self, chain: &Chain, pose: &mut Pose, target: DVec3) -> Result<SolveReport> {
        self.solve_with(chain, pose, target, &Constraints::default())
    }

    /// Short name (`"ccd"`, `"fabrik"`).
    fn name(&self) -> &'static str;
}

/// Checks a solve's preconditions.
pub(crate) fn check(chain: &Chain, pose: &Pose, target: DVec3, c: &Constraints) -> Result<()> {
    if let Some((i, _)) = c.limits.iter().find(|(i, _)| *i + 1 >= chain.len()) {
        return Err(Error::Chain(format!(
            "a limit on joint {i}: the chain's limitable joints are 0..{}",
            chain.len() - 2
        )));
    }
    if pose.rotations.len() != chain.len() || pose.world.len() != chain.len() {
        return Err(Error::Chain(format!(
            "pose has {} joints, chain has {}",
            pose.rotations.len(),
            chain.len()
        )));
    }
    if !target.is_finite() {
        return Err(Error::Chain(format!("target {target} is not finite")));
    }
    Ok(())
}

/// Handles targets the chain cannot reach. Beyond the reach (farther from the root than the sum
/// of the bone lengths) the chain is stretched straight from the root towards the target (the
/// same deterministic pose for every solver: each bone swings minimally from where it was) and
/// the report is returned. Closer to the root than the chain can fold (the longest bone minus
/// all the others) the frame is marked unreachable too; a two-joint chain then also points
/// straight at the target (its best pose), longer chains let the solver do its best.
/// Returns `None` to let the solver iterate, with `unreachable` set for a too-close target.
pub(crate) fn stretch_if_unreachable(
    chain: &Chain,
    pose: &mut Pose,
    target: DVec3,
    config: &SolverConfig,
) -> Option<SolveReport> {
    let root = pose.position(0);
    let lengths: Vec<f64> = (1..chain.len())
        .map(|i| pose.position(i).distance(pose.position(i - 1)))
        .collect();
    let reach: f64 = lengths.iter().sum();
    let longest = lengths.iter().cloned().fold(0.0, f64::max);
    let inner = (2.0 * longest - reach).max(0.0);
    let dist = root.distance(target);
    let too_far = dist > reach + config.tolerance;
    let too_close = dist < inner - config.tolerance;
    if !(too_far || (too_close && chain.len() == 2)) || dist < 1e-12 {
        return None;
    }
    let dir = (target - root) / dist;
    let mut desired = Vec::with_capacity(chain.len());
    let mut along = 0.0;
    desired.push(root);
    for d in &lengths {
        along += d;
        desired.push(root + dir * along);
    }
    aim_at_positions(chain, pose, &desired);
    let error = pose.tip().distance(target);
    Some(SolveReport {
        iterations: 1,
        error,
        reached: error <= config.tolerance,
        unreachable: true,
    })
}

/// Whether `target` is closer to the root than the chain can fold (see
/// [`stretch_if_unreachable`]).
pub(crate) fn too_close(chain: &Chain, pose: &Pose, target: DVec3, config: &SolverConfig) -> bool {
    let lengths: Vec<f64> = (1..chain.len())
        .map(|i| pose.position(i).distance(pose.position(i - 1)))
        .collect();
    let reach: f64 = lengths.iter().sum();
    let longest = lengths.iter().cloned().fold(0.0, f64::max);
    pose.position(0).distance(target) < (2.0 * longest - reach).max(0.0) - config.tolerance
}

/// Sets each joint's rotation so its child lies in the direction of `desired[i + 1]`, sweeping
/// from the root (each rotation is the smallest swing from the current one, so twist is kept),
/// and leaves `pose.world` consistent. O(n).
pub(crate) fn aim_at_positions(chain: &Chain, pose: &mut Pose, desired: &[DVec3]) {
    aim_constrained(chain, pose, desired, &Constraints::default());
}

/// [`aim_at_positions`] under joint limits: before a hinged joint, its parent twists about its
/// own bone so the hinge can bend towards the wanted direction; each joint is clamped to its
/// limit before the next is aimed.
pub(crate) fn aim_constrained(chain: &Chain, pose: &mut Pose, desired: &[DVec3], c: &Constraints) {
    aim_constrained_twist(chain, pose, desired, c);
}

/// [`aim_constrained`], returning whether a twist limit changed a rotation.
fn aim_constrained_twist(
    chain: &Chain,
    pose: &mut Pose,
    desired: &[DVec3],
    c: &Constraints,
) -> bool {
    let n = chain.len();
    let mut twist_bound = false;
    for i in 0..n - 1 {
        let parent = if i == 0 {
            chain.base()
        } else {
            pose.world[i - 1]
        };
        let inv = parent.matrix3.inverse();
        let p_i = parent.transform_point3(chain.joints()[i].translation);
        let j1 = &chain.joints()[i + 1];
        // The child's offset expressed in the parent's frame, with the current rotation.
        let current = pose.rotations[i] * (chain.joints()[i].scale * j1.translation);
        let wanted = inv * (desired[i + 1] - p_i);
        super::chain::rotate_local(&mut pose.rotations[i], current, wanted);
        if let (Some(Limit::Hinge { axis, min, max }), true) = (c.hinge(i + 1), i + 2 < n) {
            let frame = parent * chain.local(i, pose.rotations[i]);
            let rest_child = j1.rotation * (j1.scale * chain.joints()[i + 2].translation);
            let bone = desired[i + 1] - p_i;
            if let Some(psi) = constraints::hinge_twist(
                (frame.matrix3 * *axis).normalize(),
                frame.matrix3 * rest_child,
                bone,
                desired[i + 2] - desired[i + 1],
                (*min, *max),
            ) {
                if let Some(u) = (inv * bone).try_normalize() {
                    pose.rotations[i] =
                        (glam::DQuat::from_axis_angle(u, psi) * pose.rotations[i]).normalize();
                }
            }
        }
        for l in c.limits_of(i) {
            let changed = constraints::clamp_rotation(chain, i, l, &mut pose.rotations[i]);
            twist_bound |= changed && matches!(l, Limit::Twist { .. });
        }
        pose.world[i] = parent * chain.local(i, pose.rotations[i]);
    }
    pose.world[n - 1] = pose.world[n - 2] * chain.local(n - 1, pose.rotations[n - 1]);
    twist_bound
}

/// [`aim_constrained`] choosing the swivel of the inner joints about the root–tip line when a
/// twist limit binds. A twist-limited joint cannot roll its child's hinge into an arbitrary
/// bend plane, so the bend plane the passes (or the pole) chose may be out of its reach; other
/// swivels may not be. The swivel asked for (0) is kept when no twist limit changes a rotation or
/// the limits still let the tip land on `desired`'s tip (within `tolerance / 100`); otherwise
/// swivels of ±15°, ±30° … ±180° are tried, then ±5° and ±1° steps around the best: the pose
/// whose tip lands nearest `desired`'s tip wins, ties going to the smallest swivel.
pub(crate) fn aim_swivelled(
    chain: &Chain,
    pose: &mut Pose,
    desired: &[DVec3],
    tolerance: f64,
    c: &Constraints,
) {
    let n = desired.len();
    let start = pose.clone();
    let bound = aim_constrained_twist(chain, pose, desired, c);
    let tie = tolerance / 100.0;
    let e0 = pose.tip().distance(desired[n - 1]);
    let axis = (desired[n - 1] - desired[0]).try_normalize();
    let (true, true, Some(axis)) = (bound && e0 > tie, n >= 3, axis) else {
        return;
    };
    let root = desired[0];
    let mut trial_p = desired.to_vec();
    let mut trial = start.clone();
    let mut best_pose = pose.clone();
    let mut best = (e0, 0.0);
    let mut try_swivel = |phi: f64, best: &mut (f64, f64), best_pose: &mut Pose| {
        let q = glam::DQuat::from_axis_angle(axis, phi);
        for (t, d) in trial_p[1..n - 1].iter_mut().zip(&desired[1..n - 1]) {
            *t = root + q * (*d - root);
        }
        trial.clone_from(&start);
        aim_constrained(chain, &mut trial, &trial_p, c);
        let e = trial.tip().distance(desired[n - 1]);
        if e < best.0 - tie || (e <= best.0 + tie && phi.abs() < best.1.abs()) {
            *best = (e, phi);
            best_pose.clone_from(&trial);
        }
    };
    for step in [15.0, 5.0, 1.0f64] {
        let centre = best.1;
        let count = if step == 15.0 { 12 } else { 2 };
        for k in 1..=count {
            for sign in [1.0, -1.0] {
                try_swivel(
                    centre + sign * (k as f64 * step).to_radians(),
                    &mut best,
                    &mut best_pose,
                );
            }
        }
    }
    *pose = best_pose;
}

/// How a solve starts, shared by every solver.
pub(crate) enum Begin {
    /// Nothing to iterate: the target is out of reach and the chain was stretched towards it.
    Done(SolveReport),
    /// Iterate; `start` is the pose to limit rotations against (with `max_angle`).
    Iterate {
        /// The pose before the solve, when a rotation limit applies.
        start: Option<Pose>,
    },
}

/// The common start of a solve: checks the input, stretches the chain towards an unreachable
/// target, and unfolds a straight chain whose target lies on its line.
pub(crate) fn begin(
    chain: &Chain,
    pose: &mut Pose,
    target: DVec3,
    cfg: &SolverConfig,
    c: &Constraints,
) -> Result<Begin> {
    check(chain, pose, target, c)?;
    let start = cfg.max_angle.map(|_| pose.clone());
    if let Some(r) = stretch_if_unreachable(chain, pose, target, cfg) {
        return Ok(Begin::Done(SolveReport {
            unreachable: true,
            ..finish(chain, pose, start.as_ref(), target, r.iterations, cfg, c)
        }));
    }
    if pose.tip().distance(target) > cfg.tolerance {
        unfold_if_degenerate(chain, pose, target, c.pole);
    }
    Ok(Begin::Iterate { start })
}

/// The common end of an iterated solve: the final report, with targets too close to the root
/// to be reached counted as unreachable.
pub(crate) fn end(
    chain: &Chain,
    pose: &mut Pose,
    start: Option<&Pose>,
    target: DVec3,
    iterations: usize,
    cfg: &SolverConfig,
    c: &Constraints,
) -> SolveReport {
    let inside = too_close(chain, pose, target, cfg);
    SolveReport {
        unreachable: inside,
        ..finish(chain, pose, start, target, iterations, cfg, c)
    }
}

/// Applies the optional per-frame rotation limit relative to `start`, then the joint limits,
/// then the tip axis, and computes the final report.
pub(crate) fn finish(
    chain: &Chain,
    pose: &mut Pose,
    start: Option<&Pose>,
    target: DVec3,
    iterations: usize,
    config: &SolverConfig,
    c: &Constraints,
) -> SolveReport {
    if let (Some(max), Some(start)) = (config.max_angle, start) {
        chain.clamp_to(pose, start, max);
    }
    constraints::clamp_all(chain, pose, c);
    constraints::orient_tip(chain, pose, c);
    let error = pose.tip().distance(target);
    SolveReport {
        iterations,
        error,
        reached: error <= config.tolerance,
        unreachable: false,
    }
}

/// Both CCD and FABRIK stall when the chain is straight and the target lies on its line inside
/// the reach (every rotation they compute is the identity). Detects that case and bends the
/// inner joints slightly (0.05 rad each, about a fixed axis perpendicular to the line) so the
/// solvers can fold the chain; with a pole, the bend puts the inner joints on the pole's side.
/// Returns true if it bent the chain.
pub(crate) fn unfold_if_degenerate(
    chain: &Chain,
    pose: &mut Pose,
    target: DVec3,
    pole: Option<DVec3>,
) -> bool {
    let n = chain.len();
    if n < 3 {
        return false;
    }
    let root = pose.position(0);
    let line = pose.tip() - root;
    let len = line.length();
    if len < 1e-12 {
        return false;
    }
    let dir = line / len;
    let eps = 1e-9 * chain.reach(pose).max(1e-12);
    let off_line = |p: DVec3| (p - root).reject_from_normalized(dir).length();
    if off_line(target) > eps || (1..n - 1).any(|i| off_line(pose.position(i)) > eps) {
        return false;
    }
    // Turning each inner joint about w × dir swings the bones below it away from w, leaving
    // the joints on w's side of the line.
    let axis = pole
        .and_then(|p| (p - root).reject_from_normalized(dir).try_normalize())
        .map_or_else(|| dir.any_orthonormal_vector(), |w| w.cross(dir));
    for i in 1..n - 1 {
        let inv = chain.parent_linear(pose, i).inverse();
        let local_axis = (inv * axis).normalize();
        pose.rotations[i] =
            (glam::DQuat::from_axis_angle(local_axis, 0.05) * pose.rotations[i]).normalize();
        chain.fk(pose, i);
    }
    true
}

/// Which solver runs (`--solver`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SolverKind {
    /// FABRIK (the default).
    #[default]
    Fabrik,
    /// Cyclic coordinate descent.
    Ccd,
}

impl SolverKind {
    /// The option value (`fabrik`, `ccd`).
    pub fn as_str(self) -> &'static str {
        match self {
            SolverKind::Fabrik => "fabrik",
            SolverKind::Ccd => "ccd",
        }
    }
}
