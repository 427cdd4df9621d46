//! The Newton direction: the Hessian's factor and the solve, refined or by conjugate gradients.
//!
//! Precision: a supernodal factor is computed in single precision (about 1.5× faster than in
//! double on the 8k-vertex skirt: half the memory traffic, twice the values per SIMD
//! multiply-add; small systems' simplicial factors stay in double precision) and
//! each direction is refined against the double-precision Hessian until a correction is below
//! 1e-4 of it (split factor: conjugate gradients to 1e-2, whose residuals are in double
//! precision); the gradient, the objective, the line search and the residual the tolerance is
//! checked on stay in double precision. A matrix too ill-conditioned for single precision (the
//! factor fails, or refinement stalls) gets a double-precision factor for the rest of the step.
//!
//! Split factor ([`BendingFactor::Split`], the default): what is factored is H' = H + D, each
//! stencil's block between its two opposite vertices moved onto their diagonals (D ≥ 0), which
//! halves the factor; the direction still solves H Δx = −∇g, by conjugate gradients with
//! products by H, preconditioned by the factor of H'.
//!
//! Multigrid ([`LinearSolver::Multigrid`](super::LinearSolver)): no factor; each iteration
//! refreshes a smoothed-aggregation hierarchy of H'
//! ([`Multigrid`](crate::cloth::linalg::multigrid::Multigrid)) and the conjugate gradients are
//! preconditioned by one V-cycle, a cost linear in the mesh. A hierarchy of H itself
//! (bending whole) does far worse: bending is a fourth-order operator, whose smooth modes
//! aggregates of translations do not capture (43–59 gradients to 1e-2 on the 32k- and
//! 128k-vertex skirts, against 12–17 on H').
//!
//! Two halves ([`SplitCholesky`]): with the split factor, when the elimination tree branches
//! into two balanced subtrees below its top separator (garment-sized meshes), the
//! single-precision factor is computed as those two halves and a dense top, the halves on two
//! threads at once, and the preconditioner's solves run the halves at once too
//! ([`NewtonSolver::with_threads`]). One thread does the same arithmetic in the same order, so
//! the bake does not depend on the thread count. On the 8k-vertex skirt (a top of 330 of its
//! 23,979 unknowns) a factorisation takes 12.7 ms on two threads, against 21.9 ms for faer's
//! whole factor and 22.7 ms for the halves one after the other on one thread
//! (`docs/performance.md`, "The factor's two halves on two cores").

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use glam::DVec3;

use super::NewtonSolver;
use crate::cloth::linalg::cg::{self, Stop, Work};
use crate::error::{Error, Result};

/// The numeric factorisation's parallelism: one thread. faer's rayon pool on both cores of our
/// machines made the factor 1.2–1.8× slower (criterion, Newton's factor: 108 → 59 ms on the
/// 100×100 lab grid, 586 → 494 ms on 200×200, 162 → 106 ms on tableCloth), its threads waking and
/// yielding more than they computed (perf: ~40 % of the time in the scheduler).
pub(super) fn factor_par() -> Par {
    Par::Seq
}

/// The precision of the Newton factor an iteration holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Precision {
    Single,
    Double,
    /// No factor: a multigrid hierarchy
    /// ([`Multigrid`](crate::cloth::linalg::multigrid::Multigrid)).
    Multigrid,
}

/// Refinements of a single-precision Newton direction at most (each a Hessian product in double
/// precision and a pair of single-precision triangular solves); there is always at least one.
pub(super) const REFINEMENTS: usize = 3;

/// A single-precision direction stops refining once a correction is below this fraction of the
/// direction: far below what moves Newton's iterates visibly (an inexact Newton method's rate is
/// about the direction's relative error).
pub(super) const REFINED: f64 = 1e-4;

/// A single-precision direction whose last correction is still above this fraction of it (a
/// matrix too ill-conditioned for single precision: refinement does not converge) is replaced by
/// a double-precision one.
pub(super) const DIRECTION_ACCURACY: f64 = 1e-2;

/// A split-factor direction ([`BendingFactor::Split`]) stops its conjugate gradients once an
/// update is below this fraction of the direction, or below a tenth of the Newton tolerance
/// where that is smaller: at the default tolerance (0.1) as accurate as a refined
/// single-precision direction is required to be ([`DIRECTION_ACCURACY`]). On the 8k-vertex skirt
/// hanging for 30 frames, 1e-2 took 6.4 gradients a direction and 154 Newton iterations, 1e-3
/// 9.2 and 152. A tight solve needs the tighter directions: to ρ ≤ 1e-3 the circle skirt's third
/// step wandered between ρ = 3e-3 and 0.3 for 300 iterations with directions to 1e-2, their
/// error left in the slow (bending) modes that the gradients resolve last, and converged with
/// directions to 1e-4 (`gauss_seidel_sweeps_shorten_newton_without_moving_its_solution`).
pub(super) const CG_TOLERANCE: f64 = 1e-2;

/// A split-factor direction also leaves at most this fraction of −∇g unbalanced: ‖H Δx + ∇g‖
/// ≤ 0.1 ‖∇g‖ (Eisenstat and Walker's forcing term of an inexact Newton method, held fixed).
pub(super) const CG_RESIDUAL: f64 = 0.1;

/// Conjugate-gradient iterations per split-factor direction at most; a single-precision
/// preconditioner that has not converged by then is replaced by a double-precision one.
pub(super) const CG_MAX_ITERATIONS: usize = 60;

/// As [`CG_MAX_ITERATIONS`] with a multigrid preconditioner: a V-cycle is a rougher
/// approximation of H'⁻¹ than the factor (36 gradients a direction on the 128k-vertex skirt
/// against the factor's 8–22), and its alternative, a double-precision factor, is what
/// multigrid is there to avoid.
pub(super) const MULTIGRID_CG_MAX_ITERATIONS: usize = 200;

/// How Newton solves for its direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LinearSolver {
    /// The direct factor below 100,000 free particles, multigrid from there.
    #[default]
    Auto,
    /// A sparse Cholesky factor: its cost grows faster than the mesh (its fill).
    Direct,
    /// Conjugate gradients preconditioned by smoothed-aggregation algebraic multigrid: each
    /// gradient's cost linear in the mesh.
    Multigrid,
}

impl LinearSolver {
    /// The solver a system of `free` particles gets: [`LinearSolver::Direct`] or
    /// [`LinearSolver::Multigrid`].
    pub fn resolve(self, free: usize) -> LinearSolver {
        match self {
            LinearSolver::Auto if free >= MULTIGRID_MIN => LinearSolver::Multigrid,
            LinearSolver::Auto => LinearSolver::Direct,
            kind => kind,
        }
    }
}

/// Free particles from which [`LinearSolver::Auto`] takes multigrid.
pub const MULTIGRID_MIN: usize = 100_000;

/// The factor's analysis: every path that solves with the factor runs after a factorisation,
/// which analyses it first.
fn analysed(symbolic: &Option<SymbolicCholesky<usize>>) -> &SymbolicCholesky<usize> {
    symbolic
        .as_ref()
        .expect("a factor is analysed before it is used")
}

/// faer's workspace (which has no `Debug`).
pub(super) struct Scratch(pub(super) MemBuffer);

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Scratch")
    }
}

/// out −= A v, A symmetric, given by its upper triangle in compressed columns.
pub(super) fn subtract_product(
    col_ptr: &[usize],
    row_idx: &[u32],
    values: &[f64],
    v: &[f64],
    out: &mut [f64],
) {
    for c in 0..v.len() {
        let (vc, column) = (v[c], col_ptr[c]..col_ptr[c + 1]);
        let (rows, values) = (&row_idx[column.clone()], &values[column]);
        // Rows ascend, so the diagonal entry, when stored, is the column's last.
        let off = match rows.last() {
            Some(&r) if r as usize == c => rows.len() - 1,
            _ => rows.len(),
        };
        let mut below = 0.0;
        for (&r, &a) in rows[..off].iter().zip(&values[..off]) {
            below += a * v[r as usize];
            out[r as usize] -= a * vc;
        }
        if let Some(&a) = values.get(off) {
            below += a * vc;
        }
        out[c] -= below;
    }
}

/// Writes −g into `out`, 3 scalars per vector.
pub(super) fn negate_into(out: &mut [f64], g: &[DVec3]) {
    for (o, g) in out.chunks_exact_mut(3).zip(g) {
        o.copy_from_slice(&(-*g).to_array());
    }
}

/// Newton's system for its directions: H (its product) preconditioned by H'⁻¹ or a cycle.
struct Directions<'a>(&'a mut NewtonSolver);

impl cg::System<f64> for Directions<'_> {
    fn product(&mut self, p: &[f64], q: &mut [f64]) {
        self.0.hessian_product(p, q);
    }
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.0.precondition(r, z);
    }
}

impl NewtonSolver {
    /// Factors the assembled Hessian: in single precision while that has not failed in this
    /// step, else in double precision.
    pub(super) fn factorize(&mut self) -> Result<()> {
        if let Some(mg) = self.multigrid.as_mut().filter(|_| self.try_single) {
            if mg.refresh(&self.col_ptr, &self.values) {
                self.held_factor = Precision::Multigrid;
                return Ok(());
            }
            // A diagonal block or the coarsest level is not positive definite in single
            // precision: the rest of the step factors in double precision.
            self.try_single = false;
        }
        if let Some(split) = self.split_factor.as_mut().filter(|_| self.try_single) {
            if split.factor(&self.values) {
                self.held_factor = Precision::Single;
                return Ok(());
            }
            self.try_single = false;
        }
        if let (true, Some(symbolic)) = (self.try_single, &self.symbolic) {
            for (v32, v) in self.values32.iter_mut().zip(&self.values) {
                *v32 = *v as f32;
            }
            let dim = self.dx.len();
            let pattern =
                SymbolicSparseColMatRef::new_checked(dim, dim, &self.col_ptr, None, &self.row_idx);
            let factored = symbolic.factorize_numeric_llt(
                &mut self.l_values32,
                SparseColMatRef::new(pattern, &self.values32),
                Side::Upper,
                Default::default(),
                factor_par(),
                MemStack::new(&mut self.scratch.0),
                Default::default(),
            );
            if factored.is_ok() {
                self.held_factor = Precision::Single;
                return Ok(());
            }
            // Rounding to single precision lost definiteness: the matrix is too ill-conditioned
            // for it.
            self.try_single = false;
        }
        self.factorize_double()
    }

    pub(super) fn factorize_double(&mut self) -> Result<()> {
        self.analyse_factor()?;
        let symbolic = analysed(&self.symbolic);
        let dim = self.dx.len();
        let pattern =
            SymbolicSparseColMatRef::new_checked(dim, dim, &self.col_ptr, None, &self.row_idx);
        let a = SparseColMatRef::new(pattern, &self.values);
        symbolic
            .factorize_numeric_llt(
                &mut self.l_values,
                a,
                Side::Upper,
                Default::default(),
                factor_par(),
                MemStack::new(&mut self.scratch.0),
                Default::default(),
            )
            .map_err(|e| {
                Error::Factorisation(format!("Newton Hessian is not positive definite ({e:?})"))
            })?;
        self.held_factor = Precision::Double;
        Ok(())
    }

    /// Overwrites `self.dx` with −H⁻¹∇g (∇g less what the colliders hold).
    ///
    /// With a double-precision factor: one pair of triangular solves. With a single-precision
    /// one, iterative refinement: solve, compute the residual −∇g − H·Δx with the
    /// double-precision Hessian, solve for a correction and add it, at least once and up to
    /// [`REFINEMENTS`] times while the correction is above [`REFINED`] of Δx. A direction whose
    /// last correction is still above [`DIRECTION_ACCURACY`] of it (a matrix too ill-conditioned
    /// for single precision) is recomputed with a double-precision factor, as is every later
    /// one in this step.
    ///
    /// # Errors
    /// [`Error::Factorisation`] when that double-precision factor fails.
    pub(super) fn solve_direction(&mut self) -> Result<()> {
        let dim = self.dx.len();
        if self.split || self.self_coupled() || self.multigrid.is_some() {
            if self.held_factor != Precision::Double {
                if self.cg_direction() {
                    self.directions[0] += 1;
                    return Ok(());
                }
                self.try_single = false;
                self.factorize_double()?;
            }
            // A double-precision preconditioner: its last iterate is a descent direction even
            // where the gradients stopped at the cap.
            self.cg_direction();
            self.directions[1] += 1;
            return Ok(());
        }
        if self.held_factor == Precision::Single {
            self.dx.fill(0.0);
            negate_into(&mut self.refine, &self.free_grad);
            let mut accurate = false;
            for round in 0..=REFINEMENTS {
                for (b, r) in self.rhs32.iter_mut().zip(&self.refine) {
                    *b = *r as f32;
                }
                let llt = LltRef::new(analysed(&self.symbolic), &self.l_values32);
                let rhs = MatMut::from_column_major_slice_mut(&mut self.rhs32, dim, 1);
                llt.solve_in_place_with_conj(
                    Conj::No,
                    rhs,
                    Par::Seq,
                    MemStack::new(&mut self.scratch.0),
                );
                let mut correction = 0.0;
                let mut total = 0.0;
                for (d, c) in self.dx.iter_mut().zip(&self.rhs32) {
                    *d += f64::from(*c);
                    correction += f64::from(*c) * f64::from(*c);
                    total += *d * *d;
                }
                // A correction estimates the error of the direction before it (in every mode,
                // soft ones included, which the residual alone would hide).
                let (correction, total) = (correction.sqrt(), total.sqrt());
                if round > 0 {
                    accurate = correction <= DIRECTION_ACCURACY * total;
                    if correction <= REFINED * total || !accurate && round == REFINEMENTS {
                        break;
                    }
                }
                if round < REFINEMENTS {
                    self.direction_residual();
                }
            }
            if accurate && self.dx.iter().all(|d| d.is_finite()) {
                self.directions[0] += 1;
                return Ok(());
            }
            self.try_single = false;
            self.factorize_double()?;
        }
        negate_into(&mut self.dx, &self.free_grad);
        let llt = LltRef::new(analysed(&self.symbolic), &self.l_values);
        let rhs = MatMut::from_column_major_slice_mut(&mut self.dx, dim, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut self.scratch.0));
        self.directions[1] += 1;
        Ok(())
    }

    /// Overwrites `self.refine` with −∇g − H·Δx, H the assembled (double-precision) Hessian,
    /// stored as its upper triangle.
    pub(super) fn direction_residual(&mut self) {
        negate_into(&mut self.refine, &self.free_grad);
        subtract_product(
            &self.col_ptr,
            &self.row_idx32,
            &self.values,
            &self.dx,
            &mut self.refine,
        );
    }

    /// Solves H Δx = −∇g into `self.dx` by conjugate gradients preconditioned with the held
    /// factor of H' ([`BendingFactor::Split`]), from Δx = 0, until an update is below
    /// [`CG_TOLERANCE`] of Δx (a tenth of the Newton tolerance where smaller) and the residual
    /// below [`CG_RESIDUAL`] of ∇g. Returns whether it got there, finite, within
    /// [`CG_MAX_ITERATIONS`]; otherwise `self.dx` holds the last finite iterate (at worst the
    /// preconditioned gradient, a descent direction).
    pub(super) fn cg_direction(&mut self) -> bool {
        let stop = Stop::UpdateAndResidual {
            update: CG_TOLERANCE.min(0.1 * self.tolerance),
            residual: CG_RESIDUAL,
        };
        let cap = if self.held_factor == Precision::Multigrid {
            MULTIGRID_CG_MAX_ITERATIONS
        } else {
            CG_MAX_ITERATIONS
        };
        let [mut z, mut p, mut q] = std::mem::take(&mut self.cg);
        let mut r = std::mem::take(&mut self.refine);
        let mut dx = std::mem::take(&mut self.dx);
        negate_into(&mut r, &self.free_grad);
        let work = Work {
            r: &mut r,
            z: &mut z,
            p: &mut p,
            q: &mut q,
        };
        let out = cg::solve(&mut dx, work, &mut Directions(self), stop, cap);
        self.cg_count[0] += out.products;
        self.cg_count[1] += 1;
        self.cg = [z, p, q];
        self.refine = r;
        self.dx = dx;
        out.converged
    }

    /// z = H'⁻¹ r with the held factor (single or double precision), or z ≈ H'⁻¹ r by one
    /// multigrid cycle.
    pub(super) fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        let dim = r.len();
        if let (Precision::Multigrid, Some(mg)) = (self.held_factor, &mut self.multigrid) {
            mg.apply(r, z);
            return;
        }
        let stack = MemStack::new(&mut self.scratch.0);
        if self.held_factor == Precision::Single {
            for (b, r) in self.rhs32.iter_mut().zip(r) {
                *b = *r as f32;
            }
            if let Some(split) = &mut self.split_factor {
                split.solve(&mut self.rhs32);
            } else {
                let llt = LltRef::new(analysed(&self.symbolic), &self.l_values32);
                let rhs = MatMut::from_column_major_slice_mut(&mut self.rhs32, dim, 1);
                llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, stack);
            }
            for (z, c) in z.iter_mut().zip(&self.rhs32) {
                *z = f64::from(*c);
            }
        } else {
            z.copy_from_slice(r);
            let llt = LltRef::new(analysed(&self.symbolic), &self.l_values);
            let rhs = MatMut::from_column_major_slice_mut(z, dim, 1);
            llt.solve_in_place_with_conj(Conj::No, rhs, Par::Seq, stack);
        }
    }

    /// out = H v: the assembled matrix H' (filtered, see [`NewtonSolver::filter_hessian`]) less
    /// the split stencils' D, filtered the same way: S D S v, plus, at a held particle i with
    /// normal n, the nᵀD_ii n·n nᵀ v that the filter added back.
    pub(super) fn hessian_product(&self, v: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        subtract_product(&self.col_ptr, &self.row_idx32, &self.values, v, out);
        for o in out.iter_mut() {
            *o = -*o;
        }
        let at = |v: &[f64], i: usize| DVec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
        // Nothing held (the common case): `held` is not read at two random particles per pair.
        let held = |i: usize| if self.any_held { self.held[i] } else { None };
        let filter = |i: usize, u: DVec3| match held(i) {
            Some(n) => u - n * n.dot(u),
            None => u,
        };
        if let Some(s) = &self.self_contact {
            s.add_product(v, out, filter);
        }
        if !self.split {
            return;
        }
        for &(c, d, cross) in &self.opposite {
            let (c, d, a) = (c as usize, d as usize, cross.abs());
            let (vc, vd) = (filter(c, at(v, c)), filter(d, at(v, d)));
            let mut uc = filter(c, vc * a - vd * cross);
            let mut ud = filter(d, vd * a - vc * cross);
            for (i, u) in [(c, &mut uc), (d, &mut ud)] {
                if let Some(n) = held(i) {
                    *u += n * (a * n.dot(at(v, i)));
                }
            }
            for (i, u) in [(c, uc), (d, ud)] {
                out[3 * i] -= u.x;
                out[3 * i + 1] -= u.y;
                out[3 * i + 2] -= u.z;
            }
        }
    }
}
