//! One term of the step's objective, element by element: what a solver needs from an energy.
//!
//! A term is a sum of element energies, each coupling a few unknowns (a triangle's three
//! corners, say). An element gives its energy, its gradient with respect to each of its
//! unknowns and its Hessian blocks, projected positive semi-definite (so Newton's matrix stays
//! definite); a solver assembles them through the element's vertex list, once a pattern is
//! built from [`Term::vertices`]. Each term lives in its own file (the membrane in
//! [`super::membrane`]) and is checked against finite differences by one test for every term
//! (`tests` below).

use glam::DVec3;

use super::system::PINNED;

/// The most unknowns one element couples.
pub const MAX_CORNERS: usize = 4;

/// An element's gradient (N, per corner) and Hessian blocks (N/m, `hessian[a][b]` =
/// ∂²E/∂x_a∂x_b as rows), for its first [`Term::vertices`]`.len()` corners.
#[derive(Debug, Clone, Copy, Default)]
pub struct Local {
    /// ∂E/∂x_a.
    pub gradient: [DVec3; MAX_CORNERS],
    /// ∂²E/∂x_a∂x_b, projected positive semi-definite over the element.
    pub hessian: [[[[f64; 3]; 3]; MAX_CORNERS]; MAX_CORNERS],
}

/// A term of the objective made of elements over the solver's unknowns (free particles in
/// solver order).
pub trait Term {
    /// Number of elements.
    fn len(&self) -> usize;

    /// True when the term has no element.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The unknowns element `e` couples, [`PINNED`] for a corner held by a pin (which the
    /// element reads as a constant and has no unknown).
    fn vertices(&self, e: usize) -> &[u32];

    /// Element `e`'s energy at `x`, J.
    fn energy(&self, e: usize, x: &[DVec3]) -> f64;

    /// Element `e`'s gradient and Hessian blocks at `x`, written into `local` (entries of
    /// pinned corners are unspecified).
    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local);

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

    /// Checks `term` at `x` against central differences of itself: every element's gradient
    /// against its energy, and its Hessian blocks against its gradient (at a state where the
    /// projection is inactive: the caller stretches the cloth), to a relative `tol`.
    pub(crate) fn check_against_finite_differences(term: &dyn Term, x: &[DVec3], tol: f64) {
        let d = 1e-7;
        let mut local = Local::default();
        let (mut plus, mut minus) = (Local::default(), Local::default());
        let mut y = x.to_vec();
        let mut checked = 0;
        for e in 0..term.len() {
            term.derivatives(e, x, &mut local);
            let v = term.vertices(e).to_vec();
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
