//! Quadratic bending as a term: ½‖Σᵢ wᵢxᵢ + fixed‖² per stencil ([`FreeBends`]), gradient
//! wᵢ·(Σ wⱼxⱼ + fixed) at corner i and the constant Hessian blocks wᵢwⱼ·I.
//!
//! Newton assembles bending's blocks itself (`newton::pattern`, from [`corner`] and
//! [`coupling`]): they are constant, a stencil may hold one particle twice, and the split factor
//! moves the opposite corners' block onto their diagonals; the sweeps take a corner's part from
//! [`corner`] too.

use glam::{DMat3, DVec3};

use super::{Local, Term};
use crate::cloth::system::{FreeBends, PINNED};

/// The bending stencils over the free particles.
#[derive(Debug, Clone, Copy)]
pub struct Bending<'a>(pub &'a FreeBends);

/// A stencil's gradient at a corner of weight `w` (N), given the stencil's value Σ wⱼxⱼ + fixed,
/// and that corner's diagonal block w²·I as its scalar w² (N/m).
#[inline(always)]
pub(crate) fn corner(value: DVec3, w: f64) -> (DVec3, f64) {
    (value * w, w * w)
}

/// The block wₐw_b·I coupling two corners of a stencil, as its scalar (N/m).
#[inline(always)]
pub(crate) fn coupling(wa: f64, wb: f64) -> f64 {
    wa * wb
}

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
                corner(value, w[a]).0
            };
            for b in 0..4 {
                let ww = coupling(w[a], w[b]);
                local.hessian[a][b] = [[ww, 0.0, 0.0], [0.0, ww, 0.0], [0.0, 0.0, ww]];
            }
        }
    }

    #[inline(always)]
    fn add_local(&self, e: usize, a: usize, x: &[DVec3], g: &mut DVec3, h: &mut DMat3) {
        let (gb, hb) = corner(self.0.value(e, x), self.0.w[e][a]);
        *g += gb;
        *h += DMat3::from_diagonal(DVec3::splat(hb));
    }
}
