//! The Hessian's sparsity pattern, laid out once, and its assembly at each iterate.
//!
//! The sparsity pattern never changes during a bake: the upper triangle is laid out once in
//! compressed columns, every spring knows where its off-diagonal block lives in the value array,
//! the symbolic factorisation (faer's supernodal/simplicial choice) is computed once, and each
//! iteration only overwrites values and refactors numerically. The Newton loop does not allocate.
//!
//! Ordering: the free particles are already in a fill-reducing (nested-dissection) order
//! ([`ReducedSystem`], [`super::factor::fill_reducing_order`]), and unknowns are interleaved per
//! particle, so the 3n×3n matrix is factored in that block order (`SymmetricOrdering::Identity`)
//! and no permutation is applied at each factorisation and solve.

use faer::dyn_stack::{MemBuffer, StackReq};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::linalg::SupernodalThreshold;
use glam::DVec3;

use super::direction::{factor_par, Precision, Scratch};
use super::{BendingFactor, LinearSolver, NewtonSolver};
use crate::cloth::linalg::analyse_upper_with;
use crate::cloth::linalg::multigrid::Multigrid;
use crate::cloth::linalg::split::SplitCholesky;
use crate::cloth::smooth::SweepScratch;
use crate::cloth::system::{BendCoupling, ReducedSystem, OPPOSITE, PINNED};
use crate::cloth::term::{bending, Local, Term};
use crate::error::{Error, Result};

/// Free particles from which Newton's factor is supernodal whatever faer's flop ratio says: the
/// Hessian's 3×3 blocks make supernodes of their own, and the dense kernels (in single
/// precision, refined) beat the scalar simplicial factor. The robot skirt of the demo (1,560
/// particles, simplicial by faer's rule) bakes in 13.3 s instead of 18.6; the 961-particle
/// sheet on the ball 8 % faster per iteration; the 315-particle Fox cape alike either way.
pub(super) const SUPERNODAL_MIN: usize = 600;

/// The vertex pairs of a bending stencil, in the order of [`NewtonSolver`]'s `bend_off`.
pub(super) const BEND_PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The slot of [`OPPOSITE`] in [`BEND_PAIRS`].
pub(super) const OPPOSITE_SLOT: usize = 5;

/// Where a 3×3 symmetric block's upper entries live in the value array: `col[c] + r` holds entry
/// (r, c) for r ≤ c (diagonal blocks) or for every r (off-diagonal blocks).
pub(super) type BlockCols = [u32; 3];

/// The solver indices of a bending stencil's opposite vertices when both are free and
/// distinct: the pairs [`BendingFactor::Split`] leaves out of the factor.
#[inline]
pub(super) fn opposite_split(v: &[u32; 4]) -> Option<(usize, usize)> {
    let (c, d) = (v[OPPOSITE.0], v[OPPOSITE.1]);
    (c != PINNED && d != PINNED && c != d).then_some((c as usize, d as usize))
}

#[inline(always)]
pub(super) fn add_diag(values: &mut [f64], d: &BlockCols, he: &[[f64; 3]; 3]) {
    let (d0, d1, d2) = (d[0] as usize, d[1] as usize, d[2] as usize);
    values[d0] += he[0][0];
    values[d1] += he[0][1];
    values[d1 + 1] += he[1][1];
    values[d2] += he[0][2];
    values[d2 + 1] += he[1][2];
    values[d2 + 2] += he[2][2];
}

/// The block slots of an element's corner pairs (a, b), a < b, in order ((0, 1), (0, 2), …,
/// (1, 2), …: the order [`add_term`] reads them in), `None` where either corner is pinned or
/// both are the same particle. `P` is N(N − 1)/2.
pub(super) fn pair_slots<const N: usize, const P: usize>(
    v: [u32; N],
    block: impl Fn(u32, u32) -> Result<BlockCols>,
) -> Result<[Option<BlockCols>; P]> {
    let mut out = [None; P];
    let mut slot = 0;
    for a in 0..N {
        for b in a + 1..N {
            if v[a] != PINNED && v[b] != PINNED && v[a] != v[b] {
                out[slot] = Some(block(v[a], v[b])?);
            }
            slot += 1;
        }
    }
    Ok(out)
}

/// Adds a term's gradient to `grad` and its Hessian blocks to the upper-triangle `values`,
/// element by element, through each element's pair slots `off` ([`pair_slots`]; empty for a
/// one-corner term) and the diagonal blocks `diag`. Monomorphic per term, so each term's
/// kernel inlines here.
#[inline]
pub(super) fn add_term<const N: usize, const P: usize>(
    term: &impl Term<N>,
    off: &[[Option<BlockCols>; P]],
    diag: &[BlockCols],
    x: &[DVec3],
    grad: &mut [DVec3],
    values: &mut [f64],
) {
    let mut local = Local::<N>::default();
    for e in 0..term.len() {
        term.derivatives(e, x, &mut local);
        let v = term.vertices(e);
        for a in 0..N {
            if v[a] != PINNED {
                grad[v[a] as usize] += local.gradient[a];
                add_diag(values, &diag[v[a] as usize], &local.hessian[a][a]);
            }
        }
        // A one-corner term has no pairs (and `off` is empty).
        let Some(slots) = off.get(e) else {
            continue;
        };
        let mut slot = 0;
        for a in 0..N {
            for b in a + 1..N {
                if let Some(o) = slots[slot] {
                    // The slot holds block (lo, hi) as column c of hi, rows r of lo.
                    let (lo, hi) = if v[a] < v[b] { (a, b) } else { (b, a) };
                    let h = &local.hessian[lo][hi];
                    for (c, &oc) in o.iter().enumerate() {
                        for (r, row) in h.iter().enumerate() {
                            values[oc as usize + r] += row[c];
                        }
                    }
                }
                slot += 1;
            }
        }
    }
}

pub(super) fn index32(i: usize) -> Result<u32> {
    u32::try_from(i).map_err(|_| Error::Factorisation(format!("Hessian too large ({i} entries)")))
}

/// The symbolic analysis of Newton's pattern for `n` particles.
fn analyse(n: usize, col_ptr: &[usize], row_idx: &[usize]) -> Result<SymbolicCholesky<usize>> {
    let threshold = if n >= SUPERNODAL_MIN {
        SupernodalThreshold::FORCE_SUPERNODAL
    } else {
        SupernodalThreshold::AUTO
    };
    analyse_upper_with(3 * n, col_ptr, row_idx, threshold)
}

/// faer's workspace for factoring and solving with `symbolic` in either precision.
fn factor_scratch(symbolic: &SymbolicCholesky<usize>) -> Scratch {
    let par = factor_par();
    Scratch(MemBuffer::new(StackReq::any_of(&[
        symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        symbolic.solve_in_place_scratch::<f64>(1, par),
        symbolic.factorize_numeric_llt_scratch::<f32>(par, Default::default()),
        symbolic.solve_in_place_scratch::<f32>(1, par),
    ])))
}

fn is_supernodal(symbolic: &SymbolicCholesky<usize>) -> bool {
    matches!(
        symbolic.raw(),
        faer::sparse::linalg::cholesky::SymbolicCholeskyRaw::Supernodal(_)
    )
}

impl NewtonSolver {
    /// As [`NewtonSolver::new`], factoring `bending` (see [`BendingFactor`]). Either factor
    /// works with a system in any order; one ordered with [`BendingFactor::coupling`] fills
    /// least.
    ///
    /// # Errors
    /// [`Error::Factorisation`] when the symbolic analysis fails (out of memory).
    pub fn with_bending_factor(
        sys: ReducedSystem,
        tolerance: f64,
        max_iterations: usize,
        bending: BendingFactor,
    ) -> Result<Self> {
        Self::with_linear_solver(
            sys,
            tolerance,
            max_iterations,
            bending,
            LinearSolver::Direct,
        )
    }

    /// As [`NewtonSolver::with_bending_factor`], its directions from `linear` (see
    /// [`LinearSolver`]). With multigrid, each iteration refreshes the hierarchy instead of
    /// factoring, and no factor is analysed unless a step needs one: a step whose hierarchy
    /// fails (a block not positive definite in single precision) or whose gradients do not
    /// converge factors in double precision for the rest of the step.
    ///
    /// # Errors
    /// As [`NewtonSolver::with_bending_factor`].
    pub fn with_linear_solver(
        sys: ReducedSystem,
        tolerance: f64,
        max_iterations: usize,
        bending: BendingFactor,
        linear: LinearSolver,
    ) -> Result<Self> {
        let n = sys.len();
        let multigrid = linear.resolve(n) == LinearSolver::Multigrid;
        let coupling = bending.coupling();
        let sp = &sys.springs;
        // Lower-indexed neighbours of each particle, sorted and unique (CSR by higher end).
        let pairs: Vec<(u32, u32)> =
            sp.a.iter()
                .zip(&sp.b)
                .map(|(&a, &b)| (a, b))
                .chain(sys.bends.pairs(coupling).map(|(a, b)| (a as u32, b as u32)))
                .chain(sys.membrane.pairs())
                .collect();
        let mut start = vec![0u32; n + 1];
        for &(a, b) in &pairs {
            start[a.max(b) as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut lower = vec![0u32; pairs.len()];
        for &(a, b) in &pairs {
            let hi = a.max(b) as usize;
            lower[fill[hi] as usize] = a.min(b);
            fill[hi] += 1;
        }
        drop(pairs);
        let mut neighbours: Vec<Vec<u32>> = Vec::with_capacity(n);
        for i in 0..n {
            let mut list = lower[start[i] as usize..start[i + 1] as usize].to_vec();
            list.sort_unstable();
            list.dedup();
            neighbours.push(list);
        }
        drop(lower);

        // Column 3j + c: rows 3i..3i+3 for each lower neighbour i, then rows 3j..=3j+c.
        let dim = 3 * n;
        let mut col_ptr = Vec::with_capacity(dim + 1);
        let mut row_idx = Vec::new();
        let mut diag = Vec::with_capacity(n);
        let mut col_first = Vec::with_capacity(dim);
        col_ptr.push(0usize);
        for (j, list) in neighbours.iter().enumerate() {
            let mut d = [0u32; 3];
            for (c, dc) in d.iter_mut().enumerate() {
                col_first.push(row_idx.len());
                for &i in list {
                    row_idx.extend((0..3).map(|r| 3 * i as usize + r));
                }
                *dc = index32(row_idx.len())?;
                row_idx.extend((0..=c).map(|r| 3 * j + r));
                col_ptr.push(row_idx.len());
            }
            diag.push(d);
        }
        let block = |a: u32, b: u32| -> Result<BlockCols> {
            let (lo, hi) = (a.min(b), a.max(b) as usize);
            let p = neighbours[hi].binary_search(&lo).expect("neighbour listed");
            let mut o = [0u32; 3];
            for (c, oc) in o.iter_mut().enumerate() {
                *oc = index32(col_first[3 * hi + c] + 3 * p)?;
            }
            Ok(o)
        };
        let off = (0..sys.springs.a.len())
            .map(|e| pair_slots(sys.spring_term().vertices(e), block))
            .collect::<Result<Vec<_>>>()?;
        let bend_off = sys
            .bends
            .v
            .iter()
            .map(|v| {
                let mut out = [None; 6];
                for (slot, (i, j)) in BEND_PAIRS.iter().enumerate() {
                    let (a, b) = (v[*i], v[*j]);
                    let kept = coupling == BendCoupling::All || slot != OPPOSITE_SLOT;
                    if a != PINNED && b != PINNED && a != b && kept {
                        out[slot] = Some(block(a, b)?);
                    }
                }
                Ok(out)
            })
            .collect::<Result<Vec<_>>>()?;
        let membrane_off = (0..sys.membrane.len())
            .map(|e| pair_slots(sys.membrane.vertices(e), block))
            .collect::<Result<Vec<_>>>()?;
        drop(neighbours);
        let opposite: Vec<(u32, u32, f64)> = if bending == BendingFactor::Split {
            let bends = &sys.bends;
            bends
                .v
                .iter()
                .zip(&bends.w)
                .filter_map(|(v, w)| {
                    let (c, d) = opposite_split(v)?;
                    Some((
                        c as u32,
                        d as u32,
                        bending::coupling(w[OPPOSITE.0], w[OPPOSITE.1]),
                    ))
                })
                .collect()
        } else {
            Vec::new()
        };
        let split = !opposite.is_empty();

        let row_idx32 = row_idx.iter().map(|&r| index32(r)).collect::<Result<_>>()?;
        let (symbolic, scratch) = if multigrid {
            (None, Scratch(MemBuffer::new(StackReq::EMPTY)))
        } else {
            let symbolic = analyse(n, &col_ptr, &row_idx)?;
            let scratch = factor_scratch(&symbolic);
            (Some(symbolic), scratch)
        };
        // Single precision pays where faer's supernodal factor spends its time in dense SIMD
        // kernels; a small system's simplicial factor is scalar code, and refinement would only
        // add solves. Multigrid's hierarchy is in single precision.
        let supernodal = symbolic.as_ref().is_some_and(is_supernodal);
        let split_factor = match &symbolic {
            Some(symbolic) if split && supernodal => {
                SplitCholesky::new(&col_ptr, &row_idx, symbolic)
            }
            _ => None,
        };
        let len_val = symbolic.as_ref().map_or(0, |s| s.len_val());
        // The whole single-precision factor is not needed beside the halves (a failed half
        // falls back to double precision), nor with multigrid.
        let single = if split_factor.is_some() || multigrid {
            0
        } else {
            1
        };
        Ok(NewtonSolver {
            split_factor,
            multigrid: multigrid.then(|| Multigrid::new(&col_ptr, &row_idx)),
            self_contact: None,
            body_within: None,
            saved: None,
            may_stop_early: false,
            row_idx32,
            values32: vec![0.0; single * row_idx.len()],
            l_values32: vec![0.0; single * len_val],
            rhs32: vec![0.0; dim],
            refine: vec![0.0; dim],
            held_factor: Precision::Double,
            split,
            opposite,
            cg: [vec![0.0; dim], vec![0.0; dim], vec![0.0; dim]],
            cg_count: [0; 2],
            directions: [0; 2],
            allow_single: supernodal || multigrid,
            try_single: supernodal || multigrid,
            l_values: vec![0.0; len_val],
            values: vec![0.0; row_idx.len()],
            symbolic,
            scratch,
            col_ptr,
            row_idx,
            diag,
            off,
            bend_off,
            membrane_off,
            grad: vec![DVec3::ZERO; n],
            dx: vec![0.0; dim],
            trial: vec![DVec3::ZERO; n],
            longer: vec![DVec3::ZERO; n],
            drag: vec![DVec3::ZERO; n],
            try_longer: true,
            y: vec![DVec3::ZERO; n],
            x0: vec![DVec3::ZERO; n],
            history: None,
            step_lengths: None,
            steps: 0,
            contact: None,
            held: vec![None; n],
            any_held: false,
            free_grad: vec![DVec3::ZERO; n],
            sweeps: 0,
            smoother: None,
            sweep_scratch: SweepScratch::default(),
            passes: [0; 2],
            threads: 1,
            tolerance,
            max_iterations,
            sys,
        })
    }

    /// Stored entries of the Hessian's upper triangle.
    pub fn hessian_nnz(&self) -> usize {
        self.values.len()
    }

    /// Stored entries of the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.l_values.len()
    }

    /// True when the symbolic analysis chose a supernodal factor.
    pub fn is_supernodal(&self) -> bool {
        self.symbolic.as_ref().is_some_and(is_supernodal)
    }

    /// Analyses the factor when it was not (with multigrid, until a step needs a factor).
    ///
    /// # Errors
    /// [`Error::Factorisation`] when the symbolic analysis fails (out of memory).
    pub(super) fn analyse_factor(&mut self) -> Result<()> {
        if self.symbolic.is_none() {
            let symbolic = analyse(self.sys.len(), &self.col_ptr, &self.row_idx)?;
            self.scratch = factor_scratch(&symbolic);
            self.l_values = vec![0.0; symbolic.len_val()];
            self.symbolic = Some(symbolic);
        }
        Ok(())
    }

    /// Assembles the Hessian at `x` and factors it numerically, as one Newton iteration does
    /// (for benchmarks and tests).
    ///
    /// # Errors
    /// [`Error::Factorisation`] when the matrix is not numerically positive definite.
    pub fn factorize_at(&mut self, x: &[DVec3]) -> Result<()> {
        self.y.copy_from_slice(x);
        self.assemble(x);
        self.factorize()
    }

    /// The Hessian at `x` as dense upper-triangle triplets (row ≤ col), for tests.
    pub fn hessian_triplets(&mut self, x: &[DVec3]) -> Vec<(usize, usize, f64)> {
        self.y.copy_from_slice(x);
        self.assemble(x);
        let mut out = Vec::with_capacity(self.values.len());
        for c in 0..self.col_ptr.len() - 1 {
            for p in self.col_ptr[c]..self.col_ptr[c + 1] {
                out.push((self.row_idx[p], c, self.values[p]));
            }
        }
        out
    }

    /// Writes ∇g(x) into `self.grad` and the Hessian's values into `self.values`, in one pass.
    pub(super) fn assemble(&mut self, x: &[DVec3]) {
        let values = &mut self.values[..];
        values.fill(0.0);
        let grad = &mut self.grad[..];
        grad.fill(DVec3::ZERO);
        let (diag, no_pairs) = (&self.diag[..], &[] as &[[Option<BlockCols>; 0]]);
        add_term(
            &self.sys.inertia_term(&self.y),
            no_pairs,
            diag,
            x,
            grad,
            values,
        );
        add_term(&self.sys.spring_term(), &self.off, diag, x, grad, values);
        add_term(&self.sys.anchor_term(), no_pairs, diag, x, grad, values);
        // Bending's blocks are multiples of I (term::bending): only their diagonals are stored.
        let bends = &self.sys.bends;
        for (s, pairs) in self.bend_off.iter().enumerate() {
            let (v, w) = (&bends.v[s], &bends.w[s]);
            let value = bends.value(s, x);
            for i in 0..4 {
                if v[i] != PINNED {
                    let (g, h) = bending::corner(value, w[i]);
                    grad[v[i] as usize] += g;
                    let d = &self.diag[v[i] as usize];
                    for c in 0..3 {
                        values[d[c] as usize + c] += h;
                    }
                }
            }
            for (slot, &(i, j)) in BEND_PAIRS.iter().enumerate() {
                let h = bending::coupling(w[i], w[j]);
                if let Some(o) = pairs[slot] {
                    for c in 0..3 {
                        values[o[c] as usize + c] += h;
                    }
                } else if v[i] != PINNED && v[i] == v[j] {
                    let d = &self.diag[v[i] as usize];
                    for c in 0..3 {
                        values[d[c] as usize + c] += 2.0 * h;
                    }
                } else if slot == OPPOSITE_SLOT && opposite_split(v).is_some() {
                    // Split out of the factor (BendingFactor::Split): |w_c w_d| on both
                    // diagonals, so the factored matrix is H + D, D ≥ 0.
                    let a = h.abs();
                    for p in [v[i], v[j]] {
                        let d = &self.diag[p as usize];
                        for c in 0..3 {
                            values[d[c] as usize + c] += a;
                        }
                    }
                }
            }
        }
        add_term(
            &self.sys.membrane,
            &self.membrane_off,
            diag,
            x,
            grad,
            values,
        );
        if let Some(contact) = &mut self.contact {
            let diag = &self.diag;
            contact.add_derivatives(x, grad, |i, he| add_diag(values, &diag[i], &he));
        }
        if let Some(s) = &mut self.self_contact {
            let diag = &self.diag;
            s.add_derivatives(x, grad, |i, he| add_diag(values, &diag[i], &he));
        }
    }
}
