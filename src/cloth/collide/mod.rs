//! Colliders: static shapes the cloth rests on or is pushed away from.

pub mod mesh;

/// The nearest surface point of a collider as seen from a particle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Signed distance of the particle from the surface, metres: positive on the free side.
    pub distance: f64,
    /// Unit normal at the nearest surface point, pointing to the free side.
    pub normal: glam::DVec3,
}
