//! The inertia of implicit Euler: s/(2h²)·mᵢ‖xᵢ − yᵢ‖² per free particle, pulling each towards
//! its inertial target yᵢ ([`ReducedSystem::predict`](crate::cloth::system::ReducedSystem::predict)),
//! s the damping's inertia scale.

use glam::DVec3;

use super::{Local, Term};

/// The inertia term of one step: one element per free particle.
#[derive(Debug, Clone, Copy)]
pub struct Inertia<'a> {
    /// Mass of each free particle, kg.
    pub mass: &'a [f64],
    /// The inertial target of each free particle, m.
    pub target: &'a [DVec3],
    /// s/h², 1/s².
    pub weight: f64,
    /// s/(2h²), 1/s² (computed as such, not halved, so the energy has the bits it always had).
    pub half_weight: f64,
}

impl Term<1> for Inertia<'_> {
    fn len(&self) -> usize {
        self.mass.len()
    }

    fn vertices(&self, e: usize) -> [u32; 1] {
        [e as u32]
    }

    #[inline]
    fn energy(&self, e: usize, x: &[DVec3]) -> f64 {
        self.half_weight * self.mass[e] * x[e].distance_squared(self.target[e])
    }

    #[inline]
    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local<1>) {
        let wm = self.weight * self.mass[e];
        local.gradient[0] = (x[e] - self.target[e]) * wm;
        local.hessian[0][0] = [[wm, 0.0, 0.0], [0.0, wm, 0.0], [0.0, 0.0, wm]];
    }
}
