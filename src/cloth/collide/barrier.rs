//! The contact barrier: its shape on the band above a surface, its strength per particle, and
//! a surface's tangent plane for evaluating it while a particle moves a little. Contact with
//! the colliders ([`super::contact::NewtonContact`]) and the cloth's contact with itself
//! ([`crate::cloth::self_contact`]) both use it.

use glam::DVec3;

/// A collider's surface near a particle as its tangent plane, for evaluating the barrier while
/// the particle moves a little ([`NewtonContact::barrier_planes`]).
///
/// [`NewtonContact::barrier_planes`]: super::contact::NewtonContact::barrier_planes
#[derive(Debug, Clone, Copy)]
pub struct BarrierPlane {
    /// Unit normal, towards the free side.
    pub(super) normal: DVec3,
    /// The signed distance of a point p from the plane is normal·p + offset, m.
    pub(super) offset: f64,
    /// The band's bottom and width, m.
    pub(super) lo: f64,
    pub(super) width: f64,
    /// How far above the band's bottom a position must stay to be allowed, m (see
    /// [`super::contact::GAP_KEPT`]).
    pub(super) kept: f64,
}

impl BarrierPlane {
    /// How deep `p` is into this plane's band: 0 at its bottom, 1 at its top (see
    /// [`barrier_shape`]).
    #[inline]
    pub(super) fn depth(&self, p: DVec3) -> f64 {
        (self.normal.dot(p) + self.offset - self.lo) / self.width
    }

    /// Whether `p` is above the band's bottom by more than `kept` (where the barrier is
    /// finite).
    #[inline]
    pub fn allows(&self, p: DVec3) -> bool {
        self.normal.dot(p) + self.offset - self.lo > self.kept
    }
}

/// The barrier's force at the middle of its band (a particle resting one layer from the
/// surface), in weights of the particle (mᵢ·g₀).
pub(super) const BARRIER_HOLD: f64 = 10.0;

/// The thinnest layer a barrier is given, in thicknesses.
pub(super) const MIN_BARRIER_LAYER: f64 = 0.1;

/// Standard gravity, m/s²: the barrier's force unit is a particle's standard weight.
pub(super) const G0: f64 = 9.80665;

/// The barrier's shape on u ∈ (0, 1), the particle's depth into the band (0 at its bottom, 1 at
/// its top): β(u) = −(u − 1)² ln u, with β′ and β″. β(1) = β′(1) = β″(1) = 0 (the barrier starts
/// smoothly), β → ∞ as u → 0.
#[inline]
pub(crate) fn barrier_shape(u: f64) -> (f64, f64, f64) {
    let (v, l) = (u - 1.0, u.ln());
    (
        -v * v * l,
        -(2.0 * v * l + v * v / u),
        -(2.0 * l + 4.0 * v / u - v * v / (u * u)),
    )
}

/// The barrier's strength c for a particle of mass `m` (kg): c·mᵢ·g₀ with c such that the force
/// at the band's middle is [`BARRIER_HOLD`] weights, N. Self-contact uses it per pair.
pub(crate) fn barrier_strength(m: f64) -> f64 {
    BARRIER_HOLD / -barrier_shape(0.5).1 * m * G0
}

/// The barrier band of a particle with layer ℓ: its bottom (where the energy is infinite) and
/// width, m. The band spans (ℓ/2, 3ℓ/2): a particle pushed out to its layer sits at its middle.
#[inline]
pub(super) fn barrier_band(layer: f64) -> (f64, f64) {
    (0.5 * layer, layer)
}
