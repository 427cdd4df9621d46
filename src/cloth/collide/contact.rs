//! Contact response inside the solvers.
//!
//! - The fast solver keeps its prefactored matrix A and iterates on corrections δ to x, with
//!   r = −h²∇g(x) the force residual. At a particle resting on a collider the collider pushes
//!   back: the inward normal part of r is cancelled and the tangential part is reduced by the
//!   Coulomb limit μ·(normal reaction), to zero when static ([`contact_reaction`]); the particle
//!   is then held along the normal (or entirely, when sticking) in the correction, which solves
//!   A·δ = r on the subspace the colliders leave free, by conjugate gradients preconditioned with
//!   the prefactored Cholesky factor of A (the filtered solve of Baraff and Witkin 1998). After
//!   each correction, particles that entered a collider are moved out along its normal to the
//!   thickness ([`push_out`]). A fixed point is an equilibrium of the implicit step with contact
//!   forces obeying Coulomb's law.
//! - Newton minimises the objective plus a stiff penalty ½κ(t − φ)² for every particle closer
//!   than the thickness t, and a friction potential built from the normal force and normal of
//!   the previous step (lagged, as in incremental potential contact): μN·f(|slip|) with f
//!   quadratic below a slip of ε and linear above, so static friction holds the particle and
//!   sliding costs μN per metre ([`Penalty`]).
//!
//! Positions are metres in the cloth's frame; forces newtons.

use glam::DVec3;

use super::{Colliders, SurfacePoint};
use crate::cloth::system::ReducedSystem;

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

/// Penalty stiffness per particle: κ = [`PENALTY_INERTIA`]·s·m/h² + [`PENALTY_SPRINGS`]·Σk
/// (Σk over the springs the particle belongs to). Resting under its weight a particle sinks into
/// the thickness layer by g·h²/(s·1000); pressed by its springs, by a tenth of what those springs
/// would stretch under the same force. Larger factors buy nothing but round-off: Newton's
/// residual floor grows with κ.
pub const PENALTY_INERTIA: f64 = 1e3;

/// See [`PENALTY_INERTIA`].
pub const PENALTY_SPRINGS: f64 = 10.0;

/// Slip speed (m/s) below which Newton's friction acts as a stiff spring: static friction holds a
/// particle on a slope up to a creep of about this speed × tan(slope)/μ.
pub const STATIC_SLIP_SPEED: f64 = 1e-4;

/// A particle's contact with one collider in the previous step: what the friction is built on.
#[derive(Debug, Clone, Copy)]
struct LaggedContact {
    particle: u32,
    normal: DVec3,
    /// Normal force at the end of the previous step, N.
    force: f64,
}

/// Newton's contact and friction terms for the free particles of a [`ReducedSystem`].
#[derive(Debug, Clone)]
pub struct Penalty {
    colliders: Colliders,
    /// κ per free particle, N/m.
    stiffness: Vec<f64>,
    /// Friction slip scale ε, m.
    slip_scale: f64,
    lagged: Vec<LaggedContact>,
    x0: Vec<DVec3>,
}

impl Penalty {
    /// Penalty stiffnesses for `sys`'s particles.
    pub fn new(colliders: Colliders, sys: &ReducedSystem) -> Self {
        let h = sys.params.time_step;
        let s = sys.inertia_scale();
        let mut stiffness: Vec<f64> = sys
            .mass
            .iter()
            .map(|m| PENALTY_INERTIA * s * m / (h * h))
            .collect();
        let sp = &sys.springs;
        for ((&a, &b), &k) in sp.a.iter().zip(&sp.b).zip(&sp.k) {
            stiffness[a as usize] += PENALTY_SPRINGS * k;
            stiffness[b as usize] += PENALTY_SPRINGS * k;
        }
        for (&a, &k) in sys.anchors.a.iter().zip(&sys.anchors.k) {
            stiffness[a as usize] += PENALTY_SPRINGS * k;
        }
        Penalty {
            colliders,
            stiffness,
            slip_scale: STATIC_SLIP_SPEED * h,
            lagged: Vec::new(),
            x0: vec![DVec3::ZERO; sys.len()],
        }
    }

    /// Remembers the start of the step (the friction's reference positions).
    pub fn begin_step(&mut self, x0: &[DVec3]) {
        self.x0.copy_from_slice(x0);
    }

    /// Calls `f(particle, surface point, penetration t − φ > 0)` for every contact at `x`.
    #[inline]
    fn for_each_contact(&self, x: &[DVec3], mut f: impl FnMut(usize, SurfacePoint, f64)) {
        let t = self.colliders.thickness;
        for (i, (p, x0)) in x.iter().zip(&self.x0).enumerate() {
            for shape in &self.colliders.shapes {
                let reach = t + p.distance(*x0);
                if let Some(sp) = shape.contact(*p, *x0, reach) {
                    if sp.distance < t {
                        f(i, sp, t - sp.distance);
                    }
                }
            }
        }
    }

    /// The friction slip of a lagged contact at `x`: the particle's displacement since the step
    /// began, less its part along the contact normal (m).
    #[inline]
    fn slip(&self, c: &LaggedContact, x: &[DVec3]) -> DVec3 {
        let i = c.particle as usize;
        let d = x[i] - self.x0[i];
        d - c.normal * d.dot(c.normal)
    }

    /// Penalty plus friction energy at `x`, joules.
    pub fn energy(&self, x: &[DVec3]) -> f64 {
        let mut e = 0.0;
        self.for_each_contact(x, |i, _, depth| {
            e += 0.5 * self.stiffness[i] * depth * depth
        });
        let (mu, eps) = (self.colliders.friction, self.slip_scale);
        for c in &self.lagged {
            let u = self.slip(c, x).length();
            let f = if u < eps {
                u * u / (2.0 * eps)
            } else {
                u - 0.5 * eps
            };
            e += mu * c.force * f;
        }
        e
    }

    /// Adds the gradient of [`Penalty::energy`] to `grad` and passes each particle's 3×3 Hessian
    /// block (rows) to `block`.
    pub fn add_derivatives(
        &self,
        x: &[DVec3],
        grad: &mut [DVec3],
        mut block: impl FnMut(usize, [[f64; 3]; 3]),
    ) {
        self.for_each_contact(x, |i, sp, depth| {
            let k = self.stiffness[i];
            grad[i] -= sp.normal * (k * depth);
            block(i, outer(sp.normal, sp.normal, k));
        });
        let (mu, eps) = (self.colliders.friction, self.slip_scale);
        for c in &self.lagged {
            let i = c.particle as usize;
            let slip = self.slip(c, x);
            let u = slip.length();
            let scale = mu * c.force;
            // Tangent projector T = I − n nᵀ.
            let tangent = |w: f64| {
                let mut b = outer(c.normal, c.normal, -w);
                for (r, row) in b.iter_mut().enumerate() {
                    row[r] += w;
                }
                b
            };
            if u < eps {
                grad[i] += slip * (scale / eps);
                block(i, tangent(scale / eps));
            } else {
                let dir = slip / u;
                grad[i] += dir * scale;
                // μN/u (T − d dᵀ): positive semi-definite.
                let mut b = tangent(scale / u);
                let dd = outer(dir, dir, scale / u);
                for r in 0..3 {
                    for c in 0..3 {
                        b[r][c] -= dd[r][c];
                    }
                }
                block(i, b);
            }
        }
    }

    /// Records the contacts at the end of a step (normal forces for the next step's friction)
    /// and returns how many particles touch a collider.
    pub fn end_step(&mut self, x: &[DVec3]) -> usize {
        let mut lagged = std::mem::take(&mut self.lagged);
        lagged.clear();
        let mut touching = 0;
        let mut last = usize::MAX;
        self.for_each_contact(x, |i, sp, depth| {
            lagged.push(LaggedContact {
                particle: i as u32,
                normal: sp.normal,
                force: self.stiffness[i] * depth,
            });
            if i != last {
                touching += 1;
                last = i;
            }
        });
        self.lagged = lagged;
        touching
    }
}

/// w·a bᵀ as rows.
#[inline]
fn outer(a: DVec3, b: DVec3, w: f64) -> [[f64; 3]; 3] {
    [
        (b * (w * a.x)).to_array(),
        (b * (w * a.y)).to_array(),
        (b * (w * a.z)).to_array(),
    ]
}
