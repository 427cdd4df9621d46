//! Preconditioned conjugate gradients, once for every cloth solver: Newton's directions (flat
//! `f64` vectors, preconditioned by a factor or a multigrid cycle) and the local/global method's
//! global step while particles are held (x, y, z [`Lanes4`], preconditioned by its constant
//! factor). Each solver gives its product and preconditioner ([`System`], or two closures in
//! [`Closures`]) and chooses when to stop ([`Stop`]); the vectors' arithmetic is each element
//! type's own ([`Element`]), so a solver's iterates have the bits they had with a loop of its
//! own.

use super::lanes::Lanes4;

/// When conjugate gradients stop.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Stop {
    /// When the preconditioned residual rᵀz has fallen to `reduction²` of its start (checked
    /// before each product, so a zero or non-finite start stops at once).
    Reduction(f64),
    /// After an update α p no longer than `update` of the iterate x, with the residual r at
    /// most `residual` of the right-hand side: ‖α p‖ ≤ update·‖x‖ and ‖r‖ ≤ residual·‖b‖
    /// (converged when ‖x‖ is finite then).
    UpdateAndResidual {
        /// Largest update relative to the iterate.
        update: f64,
        /// Largest residual relative to the right-hand side.
        residual: f64,
    },
}

/// What a solve did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Outcome {
    /// Products with the matrix.
    pub products: usize,
    /// The stopping rule was met with a finite iterate ([`Stop::UpdateAndResidual`] only). When
    /// the first step breaks down (pᵀAp ≤ 0 or not finite), x holds the preconditioned
    /// right-hand side z, a descent direction.
    pub converged: bool,
}

/// One entry of a conjugate-gradient vector, with its own arithmetic.
pub(crate) trait Element: Copy + Default {
    /// Σ aᵢ·bᵢ, summed as this element type always has been.
    fn dot(a: &[Self], b: &[Self]) -> f64;
    /// ‖self‖².
    fn norm2(self) -> f64;
    /// self + x·a.
    fn plus_scaled(self, x: Self, a: f64) -> Self;
    /// self − x·a.
    fn minus_scaled(self, x: Self, a: f64) -> Self;
}

impl Element for f64 {
    #[inline(always)]
    fn dot(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }
    #[inline(always)]
    fn norm2(self) -> f64 {
        self * self
    }
    #[inline(always)]
    fn plus_scaled(self, x: f64, a: f64) -> f64 {
        self + a * x
    }
    #[inline(always)]
    fn minus_scaled(self, x: f64, a: f64) -> f64 {
        self - a * x
    }
}

impl Element for Lanes4 {
    /// Over the x, y, z lanes, particle by particle.
    #[inline(always)]
    fn dot(a: &[Lanes4], b: &[Lanes4]) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.xyz().dot(b.xyz())).sum()
    }
    #[inline(always)]
    fn norm2(self) -> f64 {
        self.xyz().length_squared()
    }
    #[inline(always)]
    fn plus_scaled(self, x: Lanes4, a: f64) -> Lanes4 {
        self + x * a
    }
    #[inline(always)]
    fn minus_scaled(self, x: Lanes4, a: f64) -> Lanes4 {
        self - x * a
    }
}

/// The four work vectors of a solve besides its iterate: the residual r, the preconditioned
/// residual z, the search direction p and the product q = A p.
#[derive(Debug)]
pub(crate) struct Work<'a, E> {
    /// r: holds the right-hand side b on entry (the residual of x = 0), the residual on exit.
    pub r: &'a mut [E],
    /// z = M⁻¹ r.
    pub z: &'a mut [E],
    /// p.
    pub p: &'a mut [E],
    /// q = A p.
    pub q: &'a mut [E],
}

/// The system a solve works on: the matrix A and the preconditioner M⁻¹.
pub(crate) trait System<E> {
    /// q = A p, A symmetric positive definite.
    fn product(&mut self, p: &[E], q: &mut [E]);
    /// z = M⁻¹ r, M symmetric positive definite.
    fn precondition(&mut self, r: &[E], z: &mut [E]);
}

/// A [`System`] of two closures: the product, then the preconditioner.
pub(crate) struct Closures<P, M>(pub P, pub M);

impl<E, P: FnMut(&[E], &mut [E]), M: FnMut(&[E], &mut [E])> System<E> for Closures<P, M> {
    #[inline(always)]
    fn product(&mut self, p: &[E], q: &mut [E]) {
        (self.0)(p, q)
    }
    #[inline(always)]
    fn precondition(&mut self, r: &[E], z: &mut [E]) {
        (self.1)(r, z)
    }
}

/// Solves A x = b from x = 0 by conjugate gradients on `system`, at most `cap` products,
/// stopping by `stop`. `x` is overwritten; `work.r` holds b on entry.
pub(crate) fn solve<E: Element>(
    x: &mut [E],
    work: Work<'_, E>,
    system: &mut impl System<E>,
    stop: Stop,
    cap: usize,
) -> Outcome {
    let Work { r, z, p, q } = work;
    x.fill(E::default());
    system.precondition(r, z);
    p.copy_from_slice(z);
    let mut rz = E::dot(r, z);
    let start = rz;
    let rhs = match stop {
        Stop::UpdateAndResidual { .. } => E::dot(r, r),
        Stop::Reduction(_) => 0.0,
    };
    let mut out = Outcome {
        products: 0,
        converged: false,
    };
    for k in 1..=cap {
        if let Stop::Reduction(t) = stop {
            // Also stops on a zero or non-finite residual.
            if rz.is_nan() || rz <= t * t * start {
                break;
            }
        }
        out.products += 1;
        system.product(p, q);
        let alpha = rz / E::dot(p, q);
        if !(alpha.is_finite() && alpha > 0.0) {
            if k == 1 {
                x.copy_from_slice(z);
            }
            break;
        }
        match stop {
            Stop::UpdateAndResidual { update, residual } => {
                let (mut step, mut total, mut left) = (0.0, 0.0, 0.0);
                for (((d, ri), pi), qi) in x.iter_mut().zip(r.iter_mut()).zip(&*p).zip(&*q) {
                    *d = d.plus_scaled(*pi, alpha);
                    *ri = ri.minus_scaled(*qi, alpha);
                    step += pi.norm2();
                    total += d.norm2();
                    left += ri.norm2();
                }
                if alpha * alpha * step <= update * update * total
                    && left <= residual * residual * rhs
                {
                    out.converged = total.is_finite();
                    break;
                }
            }
            Stop::Reduction(_) => {
                for (((d, ri), pi), qi) in x.iter_mut().zip(r.iter_mut()).zip(&*p).zip(&*q) {
                    *d = d.plus_scaled(*pi, alpha);
                    *ri = ri.minus_scaled(*qi, alpha);
                }
            }
        }
        system.precondition(r, z);
        let rz_next = E::dot(r, z);
        let beta = rz_next / rz;
        rz = rz_next;
        for (pi, zi) in p.iter_mut().zip(&*z) {
            *pi = zi.plus_scaled(*pi, beta);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1-D Laplacian with a small mass term: tridiagonal (2.01, −1), symmetric positive
    /// definite with a condition number near 400, its solution checked against the product (an
    /// independent residual). Conjugate gradients finish in about n products; steepest descent
    /// (β = 0) would need thousands.
    fn laplacian(p: &[f64], q: &mut [f64]) {
        let n = p.len();
        for i in 0..n {
            q[i] = 2.01 * p[i]
                - if i > 0 { p[i - 1] } else { 0.0 }
                - if i + 1 < n { p[i + 1] } else { 0.0 };
        }
    }

    #[test]
    fn both_stopping_rules_solve_a_laplacian_and_lanes_match_scalars() {
        let n = 50;
        let b: Vec<f64> = (0..n).map(|i| ((i * 7) % 11) as f64 - 5.0).collect();
        let mut x = vec![0.0; n];
        let (mut r, mut z, mut p, mut q) = (b.clone(), vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let work = Work {
            r: &mut r,
            z: &mut z,
            p: &mut p,
            q: &mut q,
        };
        let jacobi =
            |r: &[f64], z: &mut [f64]| z.iter_mut().zip(r).for_each(|(z, r)| *z = r / 2.01);
        let stop = Stop::UpdateAndResidual {
            update: 1e-12,
            residual: 1e-10,
        };
        let out = solve(&mut x, work, &mut Closures(laplacian, jacobi), stop, 200);
        assert!(out.converged && out.products < 60, "{out:?}");
        let mut ax = vec![0.0; n];
        laplacian(&x, &mut ax);
        let err = ax
            .iter()
            .zip(&b)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "residual {err}");

        // The same system as three independent lanes of Lanes4: each lane's solution matches.
        let lanes = |i: usize| Lanes4([b[i], 2.0 * b[i], -b[i], 0.0]);
        let bl: Vec<Lanes4> = (0..n).map(lanes).collect();
        let mut xl = vec![Lanes4::default(); n];
        let (mut r, mut z, mut p, mut q) = (bl.clone(), bl.clone(), bl.clone(), bl.clone());
        let work = Work {
            r: &mut r,
            z: &mut z,
            p: &mut p,
            q: &mut q,
        };
        let product = |p: &[Lanes4], q: &mut [Lanes4]| {
            for i in 0..p.len() {
                let mut v = p[i] * 2.01;
                if i > 0 {
                    v -= p[i - 1];
                }
                if i + 1 < p.len() {
                    v -= p[i + 1];
                }
                q[i] = v;
            }
        };
        let jacobi = |r: &[Lanes4], z: &mut [Lanes4]| {
            z.iter_mut()
                .zip(r)
                .for_each(|(z, r)| *z = *r * (1.0 / 2.01))
        };
        let system = &mut Closures(product, jacobi);
        let out = solve(&mut xl, work, system, Stop::Reduction(1e-12), 200);
        assert!(out.products > 5 && out.products < 60, "{out:?}");
        for (xl, x) in xl.iter().zip(&x) {
            assert!((xl.0[0] - x).abs() < 1e-8 && (xl.0[1] - 2.0 * x).abs() < 1e-8);
            assert!((xl.0[2] + x).abs() < 1e-8 && xl.0[3] == 0.0);
        }
    }
}
