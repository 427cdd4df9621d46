//! Contact inside the fast (local/global) solver.
//!
//! The fast solver keeps its prefactored matrix A and iterates on corrections δ to x, with
//! r = −h²∇g(x) the force residual. At a particle resting on a collider the collider pushes
//! back: the inward normal part of r is cancelled and the tangential part is reduced by the
//! Coulomb limit μ·(normal reaction), to zero when static ([`contact_reaction`]); the particle
//! is then held along the normal (or entirely, when sticking) in the correction, which solves
//! A·δ = r on the subspace the colliders leave free, by conjugate gradients preconditioned with
//! the prefactored Cholesky factor of A (the filtered solve of Baraff and Witkin 1998). After
//! each correction, particles that entered a collider are moved out along its normal to the
//! thickness ([`push_out`]). A fixed point is an equilibrium of the implicit step with contact
//! forces obeying Coulomb's law.

use glam::DVec3;

use super::{Colliders, SurfacePoint};

/// Moves `p` out of every collider along the surface normal to the thickness, and returns what
/// [`resting_on`] says of its final position (re-asked only when `p` moved, else read off the
/// same queries).
#[inline]
pub fn push_out(colliders: &Colliders, p: &mut DVec3, x0: DVec3) -> Option<SurfacePoint> {
    let (t, touch) = (colliders.thickness, touch_distance(colliders));
    let mut moved = false;
    let mut resting = None;
    for shape in &colliders.shapes {
        let Some(surface) = shape.contact(*p, x0, touch + p.distance(x0)) else {
            continue;
        };
        if surface.distance < t {
            *p += surface.normal * (t - surface.distance);
            moved = true;
        } else if surface.distance <= touch && resting.is_none() {
            resting = Some(surface);
        }
    }
    if moved {
        resting_on(colliders, *p, x0)
    } else {
        resting
    }
}

/// The collider surface `p` rests on: the first collider it is within the thickness of (up to a
/// relative round-off allowance), as seen from `x0`, the start of the step.
#[inline]
pub fn resting_on(colliders: &Colliders, p: DVec3, x0: DVec3) -> Option<SurfacePoint> {
    let touch = touch_distance(colliders);
    colliders.shapes.iter().find_map(|shape| {
        shape
            .contact(p, x0, touch + p.distance(x0))
            .filter(|s| s.distance <= touch)
    })
}

/// The thickness plus a relative round-off allowance: a particle pushed out to the thickness
/// counts as resting there.
#[inline]
fn touch_distance(colliders: &Colliders) -> f64 {
    colliders.thickness * (1.0 + 1e-9) + 1e-12
}

/// How a collider holds a particle resting on it during a linear solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hold {
    /// Not held: the particle is pulled off the surface.
    Free,
    /// Held along the normal; slides in the tangent plane (kinetic friction applied).
    Slide(DVec3),
    /// Held in place by static friction.
    Stick,
}

impl Hold {
    /// Removes the held components of a displacement or force.
    #[inline]
    pub fn filter(self, v: DVec3) -> DVec3 {
        match self {
            Hold::Free => v,
            Hold::Slide(n) => v - n * v.dot(n),
            Hold::Stick => DVec3::ZERO,
        }
    }
}

/// The collider's reaction to `force` (any units) on a particle resting on `surface`. A force
/// pulling the particle off the surface is left alone ([`Hold::Free`]). Otherwise the collider
/// takes the inward normal part (the reaction λ = −force·n) and Coulomb friction takes up to μλ
/// of the tangential part: all of it when that suffices ([`Hold::Stick`], the force becomes
/// zero), else the tangential part shrinks by μλ ([`Hold::Slide`]).
#[inline]
pub fn contact_reaction(friction: f64, surface: &SurfacePoint, force: &mut DVec3) -> Hold {
    let n = surface.normal;
    let normal = force.dot(n);
    if normal >= 0.0 {
        return Hold::Free;
    }
    let tangential = *force - n * normal;
    let len = tangential.length();
    let limit = -friction * normal;
    if len <= limit {
        *force = DVec3::ZERO;
        Hold::Stick
    } else {
        *force = tangential * (1.0 - limit / len);
        Hold::Slide(n)
    }
}
