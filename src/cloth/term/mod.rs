//! One term of the step's objective, element by element: what a solver needs from an energy.
//!
//! A term is a sum of element energies, each coupling a few unknowns (a triangle's three
//! corners, say). An element gives its energy, its gradient with respect to each of its
//! unknowns and its Hessian blocks, projected positive semi-definite (so Newton's matrix stays
//! definite); a solver assembles them through the element's vertex list, once a pattern is
//! built from [`Term::vertices`]. Each term lives in its own file: [`Inertia`], [`Springs`] and
//! [`Anchors`] (the fabric's law of [`super::law`]), [`Bending`], and the triangle membrane
//! ([`super::membrane`]); one test checks every term against finite differences (`tests`
//! below). Newton assembles each through one generic path (`newton::pattern::add_term`,
//! monomorphic per term), and the step's objective is their sum
//! ([`super::system::ReducedSystem::objective`]).

pub(crate) mod bending;
pub(crate) mod inertia;
mod spring;

use glam::{DMat3, DVec3};

pub use bending::Bending;
pub use inertia::Inertia;
pub use spring::{Anchors, Springs};

use super::system::PINNED;

/// An element's gradient (N, per corner) and Hessian blocks (N/m, `hessian[a][b]` =
/// ∂²E/∂x_a∂x_b as rows), for its `N` corners.
#[derive(Debug, Clone, Copy)]
pub struct Local<const N: usize> {
    /// ∂E/∂x_a.
    pub gradient: [DVec3; N],
    /// ∂²E/∂x_a∂x_b, projected positive semi-definite over the element.
    pub hessian: [[[[f64; 3]; 3]; N]; N],
}

impl<const N: usize> Default for Local<N> {
    fn default() -> Self {
        Local {
            gradient: [DVec3::ZERO; N],
            hessian: [[[[0.0; 3]; 3]; N]; N],
        }
    }
}

/// A term of the objective made of elements of `N` corners over the solver's unknowns (free
/// particles in solver order).
pub trait Term<const N: usize> {
    /// Number of elements.
    fn len(&self) -> usize;

    /// True when the term has no element.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The unknowns element `e` couples, [`PINNED`] for a corner held by a pin (which the
    /// element reads as a constant and has no unknown).
    fn vertices(&self, e: usize) -> [u32; N];

    /// Element `e`'s energy at `x`, J.
    fn energy(&self, e: usize, x: &[DVec3]) -> f64;

    /// Element `e`'s gradient and Hessian blocks at `x`, written into `local` (entries of
    /// pinned corners are unspecified).
    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local<N>);

    /// Element `e`'s part of the local step at its free corner `a`: adds its gradient there to
    /// `g` (N) and its diagonal Hessian block (a, a) to `h` (N/m), what a Gauss–Seidel sweep
    /// moving one particle with the others held needs: the kernel the sweeps (`cloth::smooth`)
    /// call, checked against [`Term::derivatives`] by the tests below.
    fn add_local(&self, e: usize, a: usize, x: &[DVec3], g: &mut DVec3, h: &mut DMat3);

    /// The term's energy, J: the elements' in order.
    fn total_energy(&self, x: &[DVec3]) -> f64 {
        (0..self.len()).map(|e| self.energy(e, x)).sum()
    }

    /// Adds the term's gradient to `grad` (N).
    fn add_gradient(&self, x: &[DVec3], grad: &mut [DVec3]) {
        let mut local = Local::default();
        for e in 0..self.len() {
            self.derivatives(e, x, &mut local);
            for (&v, g) in self.vertices(e).iter().zip(&local.gradient) {
                if v != PINNED {
                    grad[v as usize] += *g;
                }
            }
        }
    }

    /// Every pair of distinct unknowns an element couples, once per element.
    fn pairs(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for e in 0..self.len() {
            let v = self.vertices(e);
            for a in 0..v.len() {
                for b in a + 1..v.len() {
                    if v[a] != PINNED && v[b] != PINNED && v[a] != v[b] {
                        out.push((v[a], v[b]));
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::cloth::material::{fabric_model_terms, MaterialPreset};
    use crate::cloth::membrane::membrane_triangles;
    use crate::cloth::preset::lab_cloth;
    use crate::cloth::system::{ReducedSystem, StepParams};
    use crate::cloth::ClothModel;

    /// A cotton sheet of 6 × 6 particles, 0.1 m wide, its two corners pinned, with the fabric's
    /// edge springs or its triangle membrane and bending, stretched 10 % one way and 4 % the
    /// other, sheared and lifted out of its plane (every spring and fibre past the toe, so no
    /// projection is in play), pins moved with it: the system and its free positions.
    fn stretched_sheet(membrane: bool) -> (ReducedSystem, Vec<DVec3>) {
        let mut lab = lab_cloth(6, 100.0);
        let pinned = lab.pinned_flags();
        for p in &mut lab.mesh.positions {
            *p *= 0.1;
        }
        let material = MaterialPreset::Cotton.material();
        let terms = fabric_model_terms(&lab.mesh, &material);
        let count = lab.mesh.positions.len();
        let mass = vec![0.15 * 0.01 / count as f64; count];
        let mut model = if membrane {
            let (tris, _) = membrane_triangles(&lab.mesh, &material);
            ClothModel::new(lab.mesh, Default::default(), mass, pinned)
                .unwrap()
                .with_membrane(tris)
                .unwrap()
        } else {
            ClothModel::new(lab.mesh, terms.springs, mass, pinned).unwrap()
        };
        model = model.with_bending(terms.bending).unwrap();
        let mut sys = ReducedSystem::new(&model, StepParams::garment()).unwrap();
        let all: Vec<DVec3> = model
            .positions()
            .iter()
            .map(|p| DVec3::new(1.1 * p.x + 0.02 * p.z, 0.05 * p.x * p.z, 1.04 * p.z))
            .collect();
        sys.move_pins(&all);
        let x = sys.gather(&all);
        (sys, x)
    }

    /// Every term of the step's objective (inertia, springs, anchors, bending, the membrane)
    /// against finite differences of itself: gradient against energy, Hessian blocks against
    /// gradient, to 1e-5 of the element's largest; and every term's local step (the sweeps'
    /// kernel) against its gradient and the Hessian's diagonal block.
    #[test]
    fn every_term_matches_finite_differences_of_itself() {
        let (sys, x) = stretched_sheet(false);
        assert!(
            sys.springs.a.len() > 50 && !sys.anchors.a.is_empty() && sys.bends.len() > 20,
            "the sheet has every kind of element"
        );
        let y: Vec<DVec3> = x
            .iter()
            .enumerate()
            .map(|(i, p)| *p + DVec3::new(0.01, -0.02 * (i % 3) as f64, 0.003 * i as f64))
            .collect();
        check_against_finite_differences(&sys.inertia_term(&y), &x, 1e-5);
        check_against_finite_differences(&sys.spring_term(), &x, 1e-5);
        check_against_finite_differences(&sys.anchor_term(), &x, 1e-5);
        check_against_finite_differences(&Bending(&sys.bends), &x, 1e-5);
        check_local_against_hessian(&sys.inertia_term(&y), &x);
        check_local_against_hessian(&sys.spring_term(), &x);
        check_local_against_hessian(&sys.anchor_term(), &x);
        check_local_against_hessian(&Bending(&sys.bends), &x);
        let (sys, x) = stretched_sheet(true);
        assert!(sys.membrane.len() > 50 && sys.springs.a.is_empty());
        check_against_finite_differences(&sys.membrane, &x, 1e-5);
        check_local_against_hessian(&sys.membrane, &x);
        // The objective is the terms' sum.
        let sum = sys.inertia_term(&y).total_energy(&x)
            + Bending(&sys.bends).total_energy(&x)
            + sys.membrane.total_energy(&x);
        assert!((sys.objective(&x, &y) - sum).abs() <= 1e-12 * sum);
    }

    /// Checks every element's local step ([`Term::add_local`], the sweeps' kernel) against its
    /// [`Term::derivatives`] at each free corner: the same gradient and the Hessian's diagonal
    /// block, to rounding (1e-12 of the element's largest entry).
    pub(crate) fn check_local_against_hessian<const N: usize>(term: &impl Term<N>, x: &[DVec3]) {
        let mut local = Local::default();
        let mut checked = 0;
        for e in 0..term.len() {
            term.derivatives(e, x, &mut local);
            let v = term.vertices(e);
            for a in (0..N).filter(|&a| v[a] != PINNED) {
                let (mut g, mut h) = (DVec3::ZERO, DMat3::ZERO);
                term.add_local(e, a, x, &mut g, &mut h);
                let want = DMat3::from_cols_array_2d(&local.hessian[a][a]).transpose();
                let scale = local.gradient[a].abs().max_element().max(1e-300);
                let hscale = want
                    .abs()
                    .to_cols_array()
                    .into_iter()
                    .fold(1e-300, f64::max);
                assert!(
                    (g - local.gradient[a]).abs().max_element() <= 1e-12 * scale,
                    "element {e} corner {a}: local gradient {g}, the term's {}",
                    local.gradient[a]
                );
                assert!(
                    (h - want)
                        .abs()
                        .to_cols_array()
                        .into_iter()
                        .fold(0.0, f64::max)
                        <= 1e-12 * hscale,
                    "element {e} corner {a}: local block {h}, the Hessian's diagonal block {want}"
                );
                checked += 1;
            }
        }
        assert!(checked > 0, "nothing checked");
    }

    /// Checks `term` at `x` against central differences of itself: every element's gradient
    /// against its energy, and its Hessian blocks against its gradient (at a state where the
    /// projection is inactive: the caller stretches the cloth), to a relative `tol`.
    pub(crate) fn check_against_finite_differences<const N: usize>(
        term: &impl Term<N>,
        x: &[DVec3],
        tol: f64,
    ) {
        let d = 1e-7;
        let mut local = Local::default();
        let (mut plus, mut minus) = (Local::default(), Local::default());
        let mut y = x.to_vec();
        let mut checked = 0;
        for e in 0..term.len() {
            term.derivatives(e, x, &mut local);
            let v = term.vertices(e);
            let scale = (0..v.len())
                .filter(|&a| v[a] != PINNED)
                .map(|a| local.gradient[a].length())
                .fold(1e-12, f64::max);
            let hscale = (0..v.len())
                .flat_map(|a| (0..v.len()).map(move |b| (a, b)))
                .filter(|&(a, b)| v[a] != PINNED && v[b] != PINNED)
                .flat_map(|(a, b)| local.hessian[a][b].into_iter().flatten())
                .fold(1e-12_f64, |m, h| m.max(h.abs()));
            for (b, &vb) in v.iter().enumerate() {
                if vb == PINNED {
                    continue;
                }
                for c in 0..3 {
                    y[vb as usize][c] = x[vb as usize][c] + d;
                    let ep = term.energy(e, &y);
                    term.derivatives(e, &y, &mut plus);
                    y[vb as usize][c] = x[vb as usize][c] - d;
                    let em = term.energy(e, &y);
                    term.derivatives(e, &y, &mut minus);
                    y[vb as usize][c] = x[vb as usize][c];
                    let fd = (ep - em) / (2.0 * d);
                    let g = local.gradient[b][c];
                    assert!(
                        (fd - g).abs() <= tol * scale,
                        "element {e} corner {b} axis {c}: gradient {g}, from energy {fd}"
                    );
                    checked += 1;
                    for (a, &va) in v.iter().enumerate() {
                        if va == PINNED {
                            continue;
                        }
                        for r in 0..3 {
                            let fd = (plus.gradient[a][r] - minus.gradient[a][r]) / (2.0 * d);
                            let h = local.hessian[a][b][r][c];
                            assert!(
                                (fd - h).abs() <= tol * hscale,
                                "element {e} block ({a}, {b}) [{r}][{c}]: Hessian {h}, from \
                                 gradient {fd}"
                            );
                        }
                    }
                }
            }
        }
        assert!(checked > 0, "nothing checked");
    }
}
