//! Quadratic bending as a term: ½‖Σᵢ wᵢxᵢ + fixed‖² per stencil ([`FreeBends`]), gradient
//! wᵢ·(Σ wⱼxⱼ + fixed) at corner i and the constant Hessian blocks wᵢwⱼ·I.
//!
//! Newton assembles bending's blocks itself (`newton::pattern`): they are constant, a stencil
//! may hold one particle twice, and the split factor moves the opposite corners' block onto
//! their diagonals; the energy and this term's derivatives are the same quantities.

use glam::DVec3;

use super::{Local, Term};
use crate::cloth::system::{FreeBends, PINNED};

/// The bending stencils over the free particles.
#[derive(Debug, Clone, Copy)]
pub struct Bending<'a>(pub &'a FreeBends);

impl Term<4> for Bending<'_> {
    fn len(&self) -> usize {
        self.0.len()
    }

    #[inline]
    fn vertices(&self, e: usize) -> [u32; 4] {
        self.0.v[e]
    }

    #[inline]
    fn energy(&self, e: usize, x: &[DVec3]) -> f64 {
        0.5 * self.0.value(e, x).length_squared()
    }

    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local<4>) {
        let (v, w) = (&self.0.v[e], &self.0.w[e]);
        let value = self.0.value(e, x);
        for a in 0..4 {
            local.gradient[a] = if v[a] == PINNED {
                DVec3::ZERO
            } else {
                value * w[a]
            };
            for b in 0..4 {
                let ww = w[a] * w[b];
                local.hessian[a][b] = [[ww, 0.0, 0.0], [0.0, ww, 0.0], [0.0, 0.0, ww]];
            }
        }
    }
}
