//! The inertia of implicit Euler: s/(2h²)·mᵢ‖xᵢ − yᵢ‖² per free particle, pulling each towards
//! its inertial target yᵢ ([`ReducedSystem::predict`](crate::cloth::system::ReducedSystem::predict)),
//! s the damping's inertia scale.

use glam::{DMat3, DVec3};

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

/// A particle's pull towards its inertial target: the gradient (x − y)·wm (N) and the diagonal
/// block wm·I as its scalar wm (N/m), for wm = s/h²·m.
#[inline(always)]
pub(crate) fn pull(x: DVec3, target: DVec3, wm: f64) -> (DVec3, f64) {
    ((x - target) * wm, wm)
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
        let (g, wm) = pull(x[e], self.target[e], self.weight * self.mass[e]);
        local.gradient[0] = g;
        local.hessian[0][0] = [[wm, 0.0, 0.0], [0.0, wm, 0.0], [0.0, 0.0, wm]];
    }

    #[inline(always)]
    fn add_local(&self, e: usize, _a: usize, x: &[DVec3], g: &mut DVec3, h: &mut DMat3) {
        let (ge, wm) = pull(x[e], self.target[e], self.weight * self.mass[e]);
        *g += ge;
        *h += DMat3::from_diagonal(DVec3::splat(wm));
    }
}
