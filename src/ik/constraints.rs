//! Natural-joint constraints: a pole that keeps the chain's bend towards a point, per-joint
//! rotation limits (hinges, cones and twists), and the end effector's orientation (a tip axis),
//! enforced by both solvers.
//!
//! Limits are measured from the joint's rest rotation, in its parent's frame. A joint's
//! rotation `r` is written `r = d · rest` with `d` the rotation added to the rest pose:
//!
//! - **hinge** `MIN..MAX` about a unit axis `a` (parent frame): `d` must be a rotation about `a`
//!   by an angle in `[MIN, MAX]`; any swing off the axis is removed and the angle clamped
//!   (swing–twist decomposition of `d` about `a`).
//! - **cone** `DEG`: the bone to the joint's child stays within `DEG` of its rest direction;
//!   a larger swing is scaled back along the same great circle (twist kept).
//! - **twist** `MIN..MAX`: the roll of `d` about the joint's rest bone axis `b` (the direction
//!   to its child in the parent frame at rest) stays within `[MIN, MAX]`: with the swing–twist
//!   decomposition `d = swing · twist(b, τ)` (the swing the shortest arc from `b` to the bone's
//!   current direction), `τ` is clamped and the swing kept, so the bone's direction, and every
//!   joint position, is unchanged. A joint may carry a twist limit together with a cone.
//!
//! The tip axis turns the end effector (whose rotation moves no joint, so the position solve
//! is untouched) by the shortest arc that points its pen direction along a world axis.
//!
//! The pole (a world point) turns the chain rigidly about the line from its root to its tip, so
//! the bend (the inner joints' offsets from that line) faces the pole; the tip and every bone
//! length are unchanged, so a reached target stays reached.
//!
//! Both solvers apply the limits after every update (CCD after each joint, FABRIK after each
//! rotation rebuild) and once more at the end of a solve, after the per-frame `max_angle`
//! clamp, so every returned pose respects them.

use glam::{DQuat, DVec3};

use super::chain::{Chain, Pose};
use crate::error::{Error, Result};

/// A rotation limit on one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Limit {
    /// One degree of freedom: a rotation about `axis` (unit, in the joint's parent frame) by an
    /// angle in `[min, max]` radians from the rest rotation.
    Hinge {
        /// Hinge axis in the parent frame.
        axis: DVec3,
        /// Smallest angle (radians).
        min: f64,
        /// Largest angle (radians).
        max: f64,
    },
    /// The bone to the child stays within `max` radians of its rest direction.
    Cone {
        /// Half-angle of the cone (radians).
        max: f64,
    },
    /// The roll about the joint's rest bone axis stays within `[min, max]` radians.
    Twist {
        /// Smallest twist (radians).
        min: f64,
        /// Largest twist (radians).
        max: f64,
    },
}

impl Limit {
    fn kind(&self) -> &'static str {
        match self {
            Limit::Hinge { .. } => "hinge",
            Limit::Cone { .. } => "cone",
            Limit::Twist { .. } => "twist",
        }
    }

    /// Clamping order on one joint: the direction first (hinge, cone), then the twist, which
    /// keeps the direction.
    fn order(&self) -> u8 {
        u8::from(matches!(self, Limit::Twist { .. }))
    }
}

/// The end effector's orientation: its pen direction is turned onto a world axis after every
/// solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipAxis {
    /// The wanted world direction of the pen (unit).
    pub axis: DVec3,
    /// The pen's direction in the end effector's own frame (unit): for a rig, the direction to
    /// the tip node's first child; otherwise the last bone's direction at rest.
    pub pen: DVec3,
}

impl TipAxis {
    /// Checks and normalises both directions.
    ///
    /// # Errors
    /// [`Error::Value`] for a zero or non-finite axis (the job names `--tip-axis`);
    /// [`Error::Chain`] for a zero pen direction.
    pub fn new(axis: DVec3, pen: DVec3) -> Result<Self> {
        if !axis.is_finite() || axis.length() < 1e-12 {
            return Err(Error::value(format!(
                "{axis}: must be a finite, non-zero direction"
            )));
        }
        let pen = pen
            .try_normalize()
            .ok_or_else(|| Error::Chain("the tip's pen direction is zero".into()))?;
        Ok(TipAxis {
            axis: axis.normalize(),
            pen,
        })
    }

    /// The pen direction of the end effector of a chain at rest: its last bone's direction in
    /// the end effector's rest frame (the pen continues the last bone).
    pub fn continuing(chain: &Chain) -> DVec3 {
        let tip = &chain.joints()[chain.len() - 1];
        (tip.rotation.inverse() * tip.translation).normalize_or(DVec3::Y)
    }
}

/// The constraints of a solve.
///
/// ```
/// use scenebake::ik::Constraints;
/// let c = Constraints::default();
/// assert!(c.pole.is_none() && c.limits.is_empty() && c.is_empty());
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Constraints {
    /// World point the chain's bend faces.
    pub pole: Option<DVec3>,
    /// Limits by joint index (root = 0), sorted by joint, a twist after the direction limit of
    /// its joint; the end effector cannot be limited.
    pub limits: Vec<(usize, Limit)>,
    /// The end effector's pen direction, applied after each solve.
    pub tip_axis: Option<TipAxis>,
}

impl Constraints {
    /// No pole and no limit.
    pub fn is_empty(&self) -> bool {
        self.pole.is_none() && self.limits.is_empty() && self.tip_axis.is_none()
    }

    /// The limits on joint `i`, in clamping order.
    pub fn limits_of(&self, i: usize) -> impl Iterator<Item = &Limit> {
        self.limits
            .iter()
            .filter(move |(j, _)| *j == i)
            .map(|(_, l)| l)
    }

    /// The hinge on joint `i`, if any.
    pub fn hinge(&self, i: usize) -> Option<&Limit> {
        self.limits_of(i).find(|l| matches!(l, Limit::Hinge { .. }))
    }

    /// Clamps joint `i`'s rotation to its limits; true if it changed.
    pub(crate) fn clamp(&self, chain: &Chain, i: usize, r: &mut DQuat) -> bool {
        let mut changed = false;
        for l in self.limits_of(i) {
            changed |= clamp_rotation(chain, i, l, r);
        }
        changed
    }

    /// Builds constraints from `--pole` and `--limit` specifications
    /// (`JOINT:hinge:MIN..MAX[:X,Y,Z]`, `JOINT:cone:DEG`, `JOINT:twist:MIN..MAX`, degrees; JOINT
    /// a joint name). A joint takes one hinge or one cone, and one twist (not with a hinge, which
    /// already fixes the twist).
    ///
    /// A hinge's axis is, in order: the `X,Y,Z` given (world direction in the rest pose); with a
    /// pole, the normal of the plane through the bone into the joint and the pole, turned so that
    /// positive angles bend the joint out towards the pole (an elbow limited to `0..150` never
    /// bends backwards); the axis of the joint's bend in the rest pose (positive = bending
    /// further).
    ///
    /// # Errors
    /// [`Error::Value`] naming the specification (the job names `--limit`): malformed, an unknown
    /// joint (listing the chain's), the end effector, two limits of a kind (or a hinge and a
    /// twist) on a joint, an empty or out-of-range interval; [`Error::HingeAxis`] for a hinge
    /// whose axis cannot be derived. `pole` is finite (the job checks it; a non-finite one is
    /// ignored).
    pub fn from_specs(chain: &Chain, pole: Option<DVec3>, specs: &[String]) -> Result<Self> {
        let pole = pole.filter(|p| p.is_finite());
        let rest = chain.rest_pose();
        let mut limits: Vec<(usize, Limit)> = Vec::new();
        for spec in specs {
            let bad = |m: String| Error::value(format!("`{spec}`: {m}"));
            let parts: Vec<&str> = spec.split(':').map(str::trim).collect();
            if parts.len() < 3 {
                return Err(bad(
                    "expected JOINT:hinge:MIN..MAX[:X,Y,Z], JOINT:cone:DEG or JOINT:twist:MIN..MAX"
                        .into(),
                ));
            }
            let i = chain
                .joints()
                .iter()
                .position(|j| j.name == parts[0])
                .ok_or_else(|| {
                    let names: Vec<&str> = chain.joints().iter().map(|j| j.name.as_str()).collect();
                    bad(format!(
                        "no joint `{}` in the chain ({})",
                        parts[0],
                        names.join(", ")
                    ))
                })?;
            if i + 1 == chain.len() {
                return Err(bad(format!(
                    "`{}` is the end effector: its rotation moves no bone",
                    parts[0]
                )));
            }
            let number = |s: &str| {
                s.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(format!("`{s}` is not a number of degrees")))
            };
            let limit = match parts[1].to_ascii_lowercase().as_str() {
                "hinge" => {
                    let (lo, hi) = parts[2]
                        .split_once("..")
                        .ok_or_else(|| bad("a hinge needs MIN..MAX in degrees".into()))?;
                    let (min, max) = (number(lo)?, number(hi)?);
                    if min > max || min < -180.0 || max > 180.0 {
                        return Err(bad(format!(
                            "{min}..{max}: need MIN <= MAX within -180..180"
                        )));
                    }
                    let axis = match parts.get(3) {
                        Some(a) => {
                            let v = crate::spec::parse_vec3(a)?;
                            if v.length() < 1e-12 {
                                return Err(bad("the hinge axis is zero".into()));
                            }
                            v.normalize()
                        }
                        None => {
                            default_hinge_axis(&rest, i, pole).ok_or_else(|| Error::HingeAxis {
                                spec: spec.clone(),
                                joint: parts[0].to_owned(),
                            })?
                        }
                    };
                    if parts.len() > 4 {
                        return Err(bad("too many fields".into()));
                    }
                    let parent = chain.parent_linear(&rest, i);
                    let local = (parent.inverse() * axis).normalize();
                    Limit::Hinge {
                        axis: local,
                        min: min.to_radians(),
                        max: max.to_radians(),
                    }
                }
                "cone" => {
                    if parts.len() > 3 {
                        return Err(bad("too many fields".into()));
                    }
                    let deg = number(parts[2])?;
                    if !(0.0..=180.0).contains(&deg) {
                        return Err(bad(format!("{deg}: the cone angle must be within 0..180")));
                    }
                    Limit::Cone {
                        max: deg.to_radians(),
                    }
                }
                "twist" => {
                    if parts.len() > 3 {
                        return Err(bad("too many fields".into()));
                    }
                    let (lo, hi) = parts[2]
                        .split_once("..")
                        .ok_or_else(|| bad("a twist needs MIN..MAX in degrees".into()))?;
                    let (min, max) = (number(lo)?, number(hi)?);
                    if min > max || min < -180.0 || max > 180.0 {
                        return Err(bad(format!(
                            "{min}..{max}: need MIN <= MAX within -180..180"
                        )));
                    }
                    Limit::Twist {
                        min: min.to_radians(),
                        max: max.to_radians(),
                    }
                }
                other => return Err(bad(format!("`{other}`: expected hinge, cone or twist"))),
            };
            for (_, l) in limits.iter().filter(|(j, _)| *j == i) {
                let clash = l.order() == limit.order()
                    || matches!(
                        (l, &limit),
                        (Limit::Hinge { .. }, Limit::Twist { .. })
                            | (Limit::Twist { .. }, Limit::Hinge { .. })
                    );
                if clash {
                    return Err(bad(format!(
                        "`{}` already has a {} limit{}",
                        parts[0],
                        l.kind(),
                        if l.order() == limit.order() {
                            ""
                        } else {
                            " (a hinge fixes the twist)"
                        }
                    )));
                }
            }
            limits.push((i, limit));
        }
        limits.sort_by_key(|(i, l)| (*i, l.order()));
        Ok(Constraints {
            pole,
            limits,
            tip_axis: None,
        })
    }
}

/// The world hinge axis of joint `i` in the rest pose (see [`Constraints::from_specs`]).
fn default_hinge_axis(rest: &Pose, i: usize, pole: Option<DVec3>) -> Option<DVec3> {
    let child = (rest.position(i + 1) - rest.position(i)).normalize_or_zero();
    let inward = if i == 0 {
        DVec3::ZERO
    } else {
        (rest.position(i) - rest.position(i - 1)).normalize_or_zero()
    };
    if let Some(p) = pole {
        // The bend plane holds the bone into the joint and the pole: the axis is its normal,
        // turned so that positive angles carry the child bone away from the pole.
        let along = if inward == DVec3::ZERO { child } else { inward };
        let w = (p - rest.position(i)).reject_from(along);
        let axis = w.cross(along);
        if axis.length() > 1e-9 && along != DVec3::ZERO {
            return Some(axis.normalize());
        }
    }
    if i == 0 {
        return None;
    }
    let axis = inward.cross(child);
    (axis.length() > 1e-6).then(|| axis.normalize())
}

/// The child bone's offset in joint `i`'s parent frame for rotation `r`.
fn child_offset(chain: &Chain, i: usize, r: DQuat) -> DVec3 {
    r * (chain.joints()[i].scale * chain.joints()[i + 1].translation)
}

/// Clamps rotation `r` of joint `i` to `limit`; returns true if it changed.
pub(crate) fn clamp_rotation(chain: &Chain, i: usize, limit: &Limit, r: &mut DQuat) -> bool {
    let rest = chain.joints()[i].rotation;
    let old = *r;
    match *limit {
        Limit::Hinge { axis, min, max } => {
            let d = *r * rest.inverse();
            let d = if d.w < 0.0 { -d } else { d };
            let along = DVec3::new(d.x, d.y, d.z).dot(axis);
            let angle = 2.0 * along.atan2(d.w);
            let angle = if angle > std::f64::consts::PI {
                angle - std::f64::consts::TAU
            } else {
                angle
            };
            *r = (DQuat::from_axis_angle(axis, angle.clamp(min, max)) * rest).normalize();
        }
        Limit::Twist { min, max } => {
            let b0 = child_offset(chain, i, rest).normalize();
            let d = *r * rest.inverse();
            let d = if d.w < 0.0 { -d } else { d };
            let tau = 2.0 * DVec3::new(d.x, d.y, d.z).dot(b0).atan2(d.w);
            let tau = if tau > std::f64::consts::PI {
                tau - std::f64::consts::TAU
            } else {
                tau
            };
            if tau < min || tau > max {
                let swing = d * DQuat::from_axis_angle(b0, tau).inverse();
                *r = (swing * DQuat::from_axis_angle(b0, tau.clamp(min, max)) * rest).normalize();
            }
        }
        Limit::Cone { max } => {
            let b0 = child_offset(chain, i, rest).normalize();
            let b = child_offset(chain, i, *r).normalize();
            let angle = b0.angle_between(b);
            if angle > max {
                // Swing the bone back along the great circle towards its rest direction.
                let back = DQuat::from_rotation_arc(b, b0);
                let (axis, full) = back.to_axis_angle();
                let q = DQuat::from_axis_angle(axis, full * (angle - max) / angle);
                *r = (q * *r).normalize();
            }
        }
    }
    old.dot(*r).abs() < 1.0 - 1e-15
}

/// Clamps every limited joint (root first, refreshing FK below each change); true if any
/// changed.
pub(crate) fn clamp_all(chain: &Chain, pose: &mut Pose, c: &Constraints) -> bool {
    let mut first: Option<usize> = None;
    for (i, l) in &c.limits {
        if clamp_rotation(chain, *i, l, &mut pose.rotations[*i]) {
            first = Some(first.map_or(*i, |f: usize| f.min(*i)));
        }
    }
    if let Some(i) = first {
        chain.fk(pose, i);
    }
    first.is_some()
}

/// Turns the end effector by the shortest arc that points its pen along the tip axis; true if
/// it turned. Joint positions do not change.
pub(crate) fn orient_tip(chain: &Chain, pose: &mut Pose, c: &Constraints) -> bool {
    let Some(tip) = c.tip_axis else {
        return false;
    };
    let n = chain.len();
    let j = &chain.joints()[n - 1];
    let inv = chain.parent_linear(pose, n - 1).inverse();
    let current = pose.rotations[n - 1] * (j.scale * tip.pen);
    let turned = super::chain::rotate_local(&mut pose.rotations[n - 1], current, inv * tip.axis);
    if turned {
        chain.fk(pose, n - 1);
    }
    turned
}

/// Turns the inner joint positions `p[1..n-1]` rigidly about the line from `p[0]` to `p[n-1]`
/// so their summed offset from that line faces `pole`. Returns false when the chain is
/// straight or the pole lies on the line.
pub(crate) fn face_pole(p: &mut [DVec3], pole: DVec3) -> bool {
    let n = p.len();
    if n < 3 {
        return false;
    }
    let (root, tip) = (p[0], p[n - 1]);
    let Some(u) = (tip - root).try_normalize() else {
        return false;
    };
    let bend: DVec3 = p[1..n - 1].iter().map(|q| (*q - root).reject_from(u)).sum();
    let want = (pole - root).reject_from(u);
    let scale = (tip - root).length();
    if bend.length() < 1e-9 * scale || want.length() < 1e-9 * scale {
        return false;
    }
    let angle = bend.cross(want).dot(u).atan2(bend.dot(want));
    if angle.abs() < 1e-12 {
        return false;
    }
    let q = DQuat::from_axis_angle(u, angle);
    for x in &mut p[1..n - 1] {
        *x = root + q * (*x - root);
    }
    true
}

/// For a hinge on joint `i + 1`, the twist of joint `i` about its own bone (world axis `bone`)
/// that lets the hinge reach the child direction `wanted` (world). The hinge turns the child
/// bone on a cone about its axis (half-angle: the rest angle between axis and child), so the
/// twist must bring the axis to that same angle from `wanted`: with the axis split into parts
/// along and across the bone, `a(ψ)·f = a∥·f + cos ψ a⊥·f + sin ψ (u × a⊥)·f = a·c`. Of the (up to
/// two) solutions, the one whose hinge angle falls in `range` (or nearest to it) wins, then the
/// smaller twist. Returns the twist angle (radians).
pub(crate) fn hinge_twist(
    hinge_axis_world: DVec3,
    rest_child_world: DVec3,
    bone: DVec3,
    wanted: DVec3,
    range: (f64, f64),
) -> Option<f64> {
    let u = bone.try_normalize()?;
    let a = hinge_axis_world.try_normalize()?;
    let f = wanted.try_normalize()?;
    let c = rest_child_world.try_normalize()?;
    let (along, across) = (a.dot(u) * u, a.reject_from(u));
    let (cc, aa, bb) = (along.dot(f), across.dot(f), u.cross(across).dot(f));
    let r = aa.hypot(bb);
    if r < 1e-12 {
        return None;
    }
    let phi = bb.atan2(aa);
    let delta = ((a.dot(c) - cc) / r).clamp(-1.0, 1.0).acos();
    let mut best: Option<(f64, f64)> = None;
    for psi in [phi + delta, phi - delta] {
        let psi =
            (psi + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        let q = DQuat::from_axis_angle(u, psi);
        let (axis, c0) = (q * a, q * c);
        let (c0p, wp) = (c0.reject_from(axis), f.reject_from(axis));
        let theta = c0p.cross(wp).dot(axis).atan2(c0p.dot(wp));
        let miss = (range.0 - theta).max(theta - range.1).max(0.0);
        let score = miss * 10.0 + psi.abs();
        if best.is_none_or(|(s, _)| score < s) {
            best = Some((score, psi));
        }
    }
    best.map(|(_, psi)| psi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn arm() -> Chain {
        Chain::straight(3, 2.6).unwrap()
    }

    #[test]
    fn hinge_clamp_removes_swing_and_clamps_the_angle() {
        let c = arm();
        let limit = Limit::Hinge {
            axis: DVec3::Z,
            min: 0.0,
            max: 1.0,
        };
        let mut r = DQuat::from_rotation_z(1.5) * DQuat::from_rotation_x(0.3);
        assert!(clamp_rotation(&c, 1, &limit, &mut r));
        assert!(r.dot(DQuat::from_rotation_z(1.0)).abs() > 1.0 - 1e-12);
        let mut r = DQuat::from_rotation_z(-0.4);
        assert!(clamp_rotation(&c, 1, &limit, &mut r));
        assert!(r.dot(DQuat::IDENTITY).abs() > 1.0 - 1e-12);
        let mut r = DQuat::from_rotation_z(0.5);
        assert!(!clamp_rotation(&c, 1, &limit, &mut r));
    }

    #[test]
    fn cone_clamp_keeps_the_bone_inside() {
        let c = arm();
        let mut r = DQuat::from_rotation_x(1.2) * DQuat::from_rotation_y(0.7);
        assert!(clamp_rotation(&c, 0, &Limit::Cone { max: 0.5 }, &mut r));
        let b = (r * DVec3::NEG_Y).angle_between(DVec3::NEG_Y);
        assert_abs_diff_eq!(b, 0.5, epsilon = 1e-9);
    }

    #[test]
    fn pole_turn_keeps_ends_and_lengths() {
        let mut p = vec![
            DVec3::ZERO,
            DVec3::new(0.5, -1.0, 0.3),
            DVec3::new(0.0, -2.0, 0.0),
        ];
        let before = p.clone();
        assert!(face_pole(&mut p, DVec3::new(-3.0, -1.0, 0.0)));
        assert_eq!(p[0], before[0]);
        assert_eq!(p[2], before[2]);
        assert_abs_diff_eq!(
            p[1].distance(p[0]),
            before[1].distance(before[0]),
            epsilon = 1e-12
        );
        assert!(p[1].x < -0.5 && p[1].z.abs() < 1e-12);
    }

    #[test]
    fn specs_are_checked() {
        let c = arm();
        let ok = Constraints::from_specs(
            &c,
            Some(DVec3::new(0.0, 0.0, 5.0)),
            &["joint_1:hinge:0..150".into(), "joint_0:cone:80".into()],
        )
        .unwrap();
        assert_eq!(ok.limits.len(), 2);
        for (bad, needle) in [
            ("joint_1:hinge:10", "MIN..MAX"),
            ("elbow:cone:30", "joint_0, joint_1, joint_2"),
            ("joint_2:cone:30", "end effector"),
            ("joint_1:spin:30", "hinge, cone or twist"),
            ("joint_1:twist:30", "MIN..MAX"),
            ("joint_0:twist:-200..10", "MIN <= MAX"),
            ("joint_1:hinge:50..10", "MIN <= MAX"),
            ("joint_1:cone:x", "`x`"),
        ] {
            let e = Constraints::from_specs(&c, None, &[bad.into()]).unwrap_err();
            assert!(matches!(e, Error::Value { .. }), "{bad}: {e}");
            let e = e.detail();
            assert!(
                e.starts_with(&format!("`{bad}`: ")) && e.contains(needle),
                "{bad}: {e}"
            );
        }
        // A straight joint without a pole has no bend axis to hinge about.
        let e = Constraints::from_specs(&c, None, &["joint_1:hinge:0..90".into()]).unwrap_err();
        assert!(matches!(e, Error::HingeAxis { .. }), "{e}");
    }
}
