//! Sparse symmetric positive-definite factorisation for the cloth solvers.
//!
//! Matrices are assembled with `sprs` and factored by `faer`'s supernodal Cholesky (fundamental
//! supernodes, no relaxation, so no stored zeros). The factor is then re-laid out for the
//! solver's only hot operation, the two triangular sweeps over three right-hand sides
//! ([`Cholesky::solve3`] on `DVec3`, [`Cholesky::solve4`] on padded [`Lanes4`]): each supernode's
//! rows are contiguous, so one row index serves a whole row of values and x, y and z share every
//! load; the sweeps accumulate in registers and never allocate. Callers order their unknowns
//! once with [`fill_reducing_order`], so the factor needs no permutation at solve time.

use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::{SupernodalThreshold, SymbolicSupernodalParams};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{dyn_stack::MemBuffer, dyn_stack::MemStack, Par, Side};
use glam::DVec3;
use sprs::{CsMat, TriMat};

use super::lanes::{backward_rows, dot, forward_rows, Lanes, Lanes4, Lanes4f};
use crate::error::{Error, Result};

/// A lower-triangular Cholesky factor L (A = L·Lᵀ) in supernodes laid out for [`Cholesky::solve3`].
///
/// A supernode is a run of consecutive columns c0..c0+w whose rows below the diagonal block share
/// one pattern (m rows). Its values are stored row-major: first the strictly-lower part of the
/// dense w×w diagonal block (row i holds i entries), then the m×w block below it, one row of w
/// contiguous values per pattern row. The diagonal is kept apart as 1/L[j, j]. Every row index is
/// below the supernode's last column and every value slice lies inside `values` (checked at
/// construction).
///
/// `V` is the type the values are stored in: `f64` (the default, exact to roundoff) or `f32`
/// ([`Cholesky::to_f32`]: half the memory traffic of the sweeps, for use as a preconditioner).
#[derive(Debug, Clone)]
pub struct Cholesky<V: FactorValue = f64> {
    /// First column of each supernode, plus n (length S + 1).
    sn_col: Vec<u32>,
    /// Start of each supernode's pattern in `rows` (length S + 1).
    sn_row: Vec<u32>,
    /// Pattern rows (below the diagonal block), ascending within a supernode.
    rows: Vec<u32>,
    /// Start of each supernode's values in `values` (length S + 1).
    sn_val: Vec<usize>,
    /// Strictly-lower values, per supernode as described above.
    values: Vec<V>,
    /// 1 / L[j, j].
    inv_diagonal: Vec<V>,
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for f64 {}
    impl Sealed for f32 {}
}

/// The scalar types a [`Cholesky`] factor's values can be stored in: `f64` or `f32`.
pub trait FactorValue:
    Copy + Default + PartialEq + std::fmt::Debug + Send + Sync + 'static + sealed::Sealed
{
    /// `v` rounded to this type.
    fn from_f64(v: f64) -> Self;
}

impl FactorValue for f64 {
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
}

impl FactorValue for f32 {
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
}

/// Symmetric matrix from upper-triangle triplets (row ≤ col); duplicates are summed.
pub fn upper_from_triplets(n: usize, triplets: &[(usize, usize, f64)]) -> CsMat<f64> {
    let mut tri = TriMat::with_capacity((n, n), triplets.len());
    for &(r, c, v) in triplets {
        debug_assert!(r <= c, "upper triangle only");
        tri.add_triplet(r, c, v);
    }
    tri.to_csc()
}

pub(super) fn faer_view(upper: &CsMat<f64>) -> SparseColMatRef<'_, usize, f64> {
    assert!(upper.is_csc(), "factor expects compressed columns");
    let n = upper.cols();
    let symbolic = SymbolicSparseColMatRef::new_checked(
        n,
        n,
        upper.indptr().into_raw_storage(),
        None,
        upper.indices(),
    );
    SparseColMatRef::new(symbolic, upper.data())
}

/// faer's symbolic Cholesky analysis of the n×n matrix whose upper triangle has the pattern
/// (`col_ptr`, `row_idx`) (compressed columns, rows ascending), in the given order
/// (`SymmetricOrdering::Identity`), supernodal or simplicial as faer judges.
///
/// # Errors
/// [`Error::Factorisation`] when the analysis fails (out of memory).
pub fn analyse_upper(
    n: usize,
    col_ptr: &[usize],
    row_idx: &[usize],
) -> Result<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>> {
    analyse_upper_with(n, col_ptr, row_idx, SupernodalThreshold::AUTO)
}

/// As [`analyse_upper`], choosing the supernodal factor by `threshold` (faer's ratio of
/// factorisation flops to factor entries).
///
/// # Errors
/// As [`analyse_upper`].
pub fn analyse_upper_with(
    n: usize,
    col_ptr: &[usize],
    row_idx: &[usize],
    threshold: SupernodalThreshold,
) -> Result<faer::sparse::linalg::cholesky::SymbolicCholesky<usize>> {
    let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
    factorize_symbolic_cholesky(
        pattern,
        Side::Upper,
        SymmetricOrdering::Identity,
        CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: threshold,
            ..CholeskySymbolicParams::default()
        },
    )
    .map_err(|e| Error::Factorisation(format!("symbolic analysis: {e:?}")))
}

pub(super) fn simplicial() -> CholeskySymbolicParams<'static> {
    CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
        ..Default::default()
    }
}

/// Supernodal analysis with fundamental supernodes only (no relaxation: no explicit zeros).
fn supernodal() -> CholeskySymbolicParams<'static> {
    CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
        supernodal_params: SymbolicSupernodalParams { relax: None },
        ..Default::default()
    }
}

/// [`Cholesky::to_f32`] drops values below this fraction of the factor's largest entry.
pub const DROP_RELATIVE: f64 = 1e-12;

impl Cholesky<f64> {
    /// Factors the symmetric positive-definite matrix whose upper triangle is `upper`, in the
    /// given order (no reordering).
    ///
    /// # Errors
    /// [`Error::Factorisation`] when the matrix is not numerically positive definite.
    pub fn new(upper: &CsMat<f64>) -> Result<Self> {
        let n = upper.cols();
        let view = faer_view(upper);
        let symbolic = factorize_symbolic_cholesky(
            view.symbolic(),
            Side::Upper,
            SymmetricOrdering::Identity,
            supernodal(),
        )
        .map_err(|e| Error::Factorisation(format!("{e:?}")))?;
        let mut l_values = vec![0.0; symbolic.len_val()];
        let par = Par::Seq;
        let mut buffer =
            MemBuffer::new(symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        symbolic
            .factorize_numeric_llt(
                &mut l_values,
                view,
                Side::Upper,
                Default::default(), // no regularisation: an indefinite matrix is an error
                par,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|e| {
                Error::Factorisation(format!("matrix is not positive definite ({e:?})"))
            })?;
        let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
            return Err(Error::Factorisation("expected a supernodal factor".into()));
        };
        let supernodes = sym.n_supernodes();
        let mut f = Cholesky {
            sn_col: Vec::with_capacity(supernodes + 1),
            sn_row: Vec::with_capacity(supernodes + 1),
            rows: Vec::with_capacity(sym.row_idx().len()),
            sn_val: Vec::with_capacity(supernodes + 1),
            values: Vec::with_capacity(l_values.len()),
            inv_diagonal: vec![0.0; n],
        };
        for s in 0..supernodes {
            let node = sym.supernode(s);
            let (c0, pattern) = (node.start(), node.pattern());
            let w = sym.supernode_end()[s] - c0;
            let m = pattern.len();
            // faer: a column-major (w + m)×w block, diagonal block on top.
            let block = &l_values[sym.col_ptr_for_val()[s]..sym.col_ptr_for_val()[s + 1]];
            let at = |p: usize, j: usize| block[j * (w + m) + p];
            f.sn_col.push(c0 as u32);
            f.sn_row.push(f.rows.len() as u32);
            f.sn_val.push(f.values.len());
            for i in 0..w {
                let d = at(i, i);
                if !(d > 0.0 && d.is_finite()) {
                    return Err(Error::Factorisation(format!(
                        "zero or non-finite pivot in column {}",
                        c0 + i
                    )));
                }
                f.inv_diagonal[c0 + i] = 1.0 / d;
                f.values.extend((0..i).map(|j| at(i, j)));
            }
            for (k, &r) in pattern.iter().enumerate() {
                debug_assert!(r >= c0 + w && r < n, "pattern row below the supernode");
                f.rows.push(r as u32);
                f.values.extend((0..w).map(|j| at(w + k, j)));
            }
        }
        f.sn_col.push(n as u32);
        f.sn_row.push(f.rows.len() as u32);
        f.sn_val.push(f.values.len());
        Ok(f)
    }

    /// The same factor with its values rounded to `f32`: L̃ with L̃·L̃ᵀ = A + E, |E| of the order
    /// of 1e-7·|L|·|Lᵀ|. Not a solver on its own for ill-conditioned A; use it to solve for
    /// corrections (x ← x + Ã⁻¹(b − A·x), with the residual in f64).
    pub fn to_f32(&self) -> Cholesky<f32> {
        self.to_f32_dropping(DROP_RELATIVE)
    }

    /// [`Cholesky::to_f32`] dropping every value below `relative` × the factor's largest entry
    /// (diagonal included), and every pattern row of a supernode left without values: a cheaper,
    /// incomplete factor. Dropped entries change Ã by at most a few of them per entry of A.
    pub fn to_f32_dropping(&self, relative: f64) -> Cholesky<f32> {
        // The lab grids' factors decay to 1e-40 and below away from the diagonal: kept, those
        // values would be subnormal in f32, and subnormal operands or products cost a microcode
        // assist per multiply-add on x86; and whole rows of them are traffic for nothing.
        let largest = self.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let largest = self
            .inv_diagonal
            .iter()
            .fold(largest, |m, d| m.max(1.0 / d));
        let drop_below = largest * relative;
        let round = |v: f64| if v.abs() < drop_below { 0.0 } else { v as f32 };
        let supernodes = self.supernodes();
        let mut f = Cholesky {
            sn_col: self.sn_col.clone(),
            sn_row: Vec::with_capacity(supernodes + 1),
            rows: Vec::new(),
            sn_val: Vec::with_capacity(supernodes + 1),
            values: Vec::new(),
            inv_diagonal: self.inv_diagonal.iter().map(|&v| v as f32).collect(),
        };
        for s in 0..supernodes {
            let w = (self.sn_col[s + 1] - self.sn_col[s]) as usize;
            let rows = &self.rows[self.sn_row[s] as usize..self.sn_row[s + 1] as usize];
            let vals = &self.values[self.sn_val[s]..self.sn_val[s + 1]];
            let (tri, below) = vals.split_at(w * (w - 1) / 2);
            f.sn_row.push(f.rows.len() as u32);
            f.sn_val.push(f.values.len());
            f.values.extend(tri.iter().map(|&v| round(v)));
            for (&r, l) in rows.iter().zip(below.chunks_exact(w)) {
                if l.iter().any(|v| v.abs() >= drop_below) {
                    f.rows.push(r);
                    f.values.extend(l.iter().map(|&v| round(v)));
                }
            }
        }
        f.sn_row.push(f.rows.len() as u32);
        f.sn_val.push(f.values.len());
        f
    }
}

impl<V: FactorValue> Cholesky<V> {
    /// Size n of the factored matrix.
    pub fn dimension(&self) -> usize {
        self.inv_diagonal.len()
    }

    /// Stored entries of L, diagonal included.
    pub fn nnz(&self) -> usize {
        self.values.len() + self.inv_diagonal.len()
    }

    /// Stored off-diagonal values (for diagnostics).
    pub fn values(&self) -> &[V] {
        &self.values
    }

    /// Number of supernodes.
    pub fn supernodes(&self) -> usize {
        self.sn_col.len() - 1
    }

    /// Forward then backward substitution, supernode by supernode. Inlined into each caller so
    /// that it is compiled for the caller's target features.
    #[inline(always)]
    fn sweeps<T: Lanes<V>>(&self, b: &mut [T]) {
        let supernodes = self.supernodes();
        // Forward: L·Y = B.
        for s in 0..supernodes {
            let (c0, c1) = (self.sn_col[s] as usize, self.sn_col[s + 1] as usize);
            let w = c1 - c0;
            let rows = &self.rows[self.sn_row[s] as usize..self.sn_row[s + 1] as usize];
            let vals = &self.values[self.sn_val[s]..self.sn_val[s + 1]];
            let (tri, below) = vals.split_at(w * (w - 1) / 2);
            let (head, tail) = b.split_at_mut(c1);
            let y = &mut head[c0..];
            let inv = &self.inv_diagonal[c0..c1];
            let mut t = 0;
            for i in 0..w {
                let row = &tri[t..t + i];
                t += i;
                let acc = y[i] - dot(row, &y[..i]);
                y[i] = acc.scale(inv[i]).flush();
            }
            let y = &*y;
            match w {
                1 => forward_rows::<V, T, 1>(rows, below, y, tail, c1),
                2 => forward_rows::<V, T, 2>(rows, below, y, tail, c1),
                3 => forward_rows::<V, T, 3>(rows, below, y, tail, c1),
                4 => forward_rows::<V, T, 4>(rows, below, y, tail, c1),
                _ => {
                    for (&r, l) in rows.iter().zip(below.chunks_exact(w)) {
                        tail[r as usize - c1] -= dot(l, y);
                    }
                }
            }
        }
        // Backward: Lᵀ·X = Y, supernodes in reverse.
        for s in (0..supernodes).rev() {
            let (c0, c1) = (self.sn_col[s] as usize, self.sn_col[s + 1] as usize);
            let w = c1 - c0;
            let rows = &self.rows[self.sn_row[s] as usize..self.sn_row[s + 1] as usize];
            let vals = &self.values[self.sn_val[s]..self.sn_val[s + 1]];
            let (tri, below) = vals.split_at(w * (w - 1) / 2);
            let (head, tail) = b.split_at_mut(c1);
            let x = &mut head[c0..];
            match w {
                1 => backward_rows::<V, T, 1>(rows, below, x, tail, c1),
                2 => backward_rows::<V, T, 2>(rows, below, x, tail, c1),
                3 => backward_rows::<V, T, 3>(rows, below, x, tail, c1),
                4 => backward_rows::<V, T, 4>(rows, below, x, tail, c1),
                _ => {
                    // Four columns at a time, accumulating in registers (no stores in the
                    // inner loop); each pass re-reads the pattern rows, which are in cache.
                    let mut j0 = 0;
                    while j0 + 4 <= w {
                        let xs: &mut [T; 4] = (&mut x[j0..j0 + 4]).try_into().expect("4 columns");
                        // Two sets of accumulators (even and odd rows): eight independent
                        // multiply-add chains hide the latency.
                        let mut acc = *xs;
                        let mut odd = [<T as Lanes<V>>::ZERO; 4];
                        let pairs = rows.len() / 2;
                        for k2 in 0..pairs {
                            let k = 2 * k2;
                            let (xa, xb) =
                                (tail[rows[k] as usize - c1], tail[rows[k + 1] as usize - c1]);
                            let la: &[V; 4] = below[k * w + j0..k * w + j0 + 4]
                                .try_into()
                                .expect("4 values");
                            let lb: &[V; 4] = below[(k + 1) * w + j0..(k + 1) * w + j0 + 4]
                                .try_into()
                                .expect("4 values");
                            for jj in 0..4 {
                                acc[jj] = acc[jj].mul_add(-xa, la[jj]);
                                odd[jj] = odd[jj].mul_add(-xb, lb[jj]);
                            }
                        }
                        if rows.len() % 2 == 1 {
                            let k = rows.len() - 1;
                            let xa = tail[rows[k] as usize - c1];
                            for jj in 0..4 {
                                acc[jj] = acc[jj].mul_add(-xa, below[k * w + j0 + jj]);
                            }
                        }
                        for jj in 0..4 {
                            acc[jj] += odd[jj];
                        }
                        *xs = acc;
                        j0 += 4;
                    }
                    for j in j0..w {
                        let mut acc = x[j];
                        for (k, &r) in rows.iter().enumerate() {
                            acc = acc.mul_add(-tail[r as usize - c1], below[k * w + j]);
                        }
                        x[j] = acc;
                    }
                }
            }
            // Diagonal block, column j as a dot product down the rows i > j (row i starts at
            // i(i−1)/2 in `tri`).
            let inv = &self.inv_diagonal[c0..c1];
            for j in (0..w).rev() {
                let (mut acc, mut odd) = (x[j], <T as Lanes<V>>::ZERO);
                let mut at = (j + 1) * j / 2 + j;
                let mut i = j + 1;
                while i + 1 < w {
                    acc = acc.mul_add(-x[i], tri[at]);
                    odd = odd.mul_add(-x[i + 1], tri[at + i]);
                    at += 2 * i + 1;
                    i += 2;
                }
                if i < w {
                    acc = acc.mul_add(-x[i], tri[at]);
                }
                acc += odd;
                x[j] = acc.scale(inv[j]).flush();
            }
        }
    }
}

/// The public sweeps for one value type `$v` (the private `Lanes` bounds stay private).
macro_rules! solves {
    ($v:ty) => {
        impl Cholesky<$v> {
            /// Solves A·X = B in place for three right-hand sides at once (the x, y and z columns of
            /// `b`). No allocation.
            ///
            /// # Panics
            /// When `b.len()` differs from [`Cholesky::dimension`].
            pub fn solve3(&self, b: &mut [DVec3]) {
                assert_eq!(b.len(), self.dimension(), "right-hand side length");
                self.sweeps::<_>(b);
            }

            /// [`Cholesky::solve3`] on right-hand sides padded to four lanes (the fourth is solved too,
            /// so keep it zero or use it as a fourth column). Faster: every update is one 4-wide
            /// multiply-add, and on x86-64 CPUs with AVX2 and FMA (detected at run time) a 256-bit one.
            ///
            /// # Panics
            /// When `b.len()` differs from [`Cholesky::dimension`].
            pub fn solve4(&self, b: &mut [Lanes4]) {
                assert_eq!(b.len(), self.dimension(), "right-hand side length");
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                {
                    // SAFETY: the CPU supports the features `sweeps_avx2` is compiled for.
                    unsafe { self.sweeps_avx2(b) };
                    return;
                }
                self.sweeps::<_>(b);
            }

            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            fn sweeps_avx2(&self, b: &mut [Lanes4]) {
                self.sweeps::<_>(b);
            }
        }
    };
}
solves!(f64);
solves!(f32);

impl Cholesky<f32> {
    /// Solves Ã·X = B in place with f32 right-hand sides too: every update is one 128-bit
    /// multiply-add, and half the bytes of [`Cholesky::solve4`] move per sweep. For corrections
    /// (right-hand sides whose relative accuracy is what matters), not for positions. Scale B to
    /// order 1: solved components below [`FLUSH_BELOW`] are set to zero.
    ///
    /// # Panics
    /// When `b.len()` differs from [`Cholesky::dimension`].
    pub fn solve4f(&self, b: &mut [Lanes4f]) {
        assert_eq!(b.len(), self.dimension(), "right-hand side length");
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports the features `sweeps4f_avx2` is compiled for.
            unsafe { self.sweeps4f_avx2(b) };
            return;
        }
        self.sweeps(b);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn sweeps4f_avx2(&self, b: &mut [Lanes4f]) {
        self.sweeps(b);
    }
}

/// The lane-wise arithmetic of a padded right-hand side type `$t` with scalar `$s`: `+`, `−`,
/// `*` lane by lane, `*` by a scalar, negation, `+=` and `−=`.
macro_rules! lane_ops {
    ($t:ident, $s:ty) => {
        impl std::ops::Add for $t {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                $t(std::array::from_fn(|k| self.0[k] + o.0[k]))
            }
        }

        impl std::ops::Sub for $t {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                $t(std::array::from_fn(|k| self.0[k] - o.0[k]))
            }
        }

        impl std::ops::Mul for $t {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                $t(std::array::from_fn(|k| self.0[k] * o.0[k]))
            }
        }

        impl std::ops::Mul<$s> for $t {
            type Output = Self;
            #[inline(always)]
            fn mul(self, l: $s) -> Self {
                $t(self.0.map(|v| v * l))
            }
        }

        impl std::ops::Neg for $t {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                $t(self.0.map(|v| -v))
            }
        }

        impl std::ops::AddAssign for $t {
            #[inline(always)]
            fn add_assign(&mut self, o: Self) {
                *self = *self + o;
            }
        }

        impl std::ops::SubAssign for $t {
            #[inline(always)]
            fn sub_assign(&mut self, o: Self) {
                *self = *self - o;
            }
        }
    };
}
lane_ops!(Lanes4, f64);
lane_ops!(Lanes4f, f32);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth::linalg::ordering::{fill_reducing_order, nested_dissection};

    /// 1-D Laplacian plus identity on a path graph, in a shuffled order.
    fn path_matrix(n: usize) -> Vec<(usize, usize, f64)> {
        let mut t: Vec<_> = (0..n).map(|i| (i, i, 3.0)).collect();
        t.extend((0..n - 1).map(|i| (i, i + 1, -1.0)));
        t
    }

    #[test]
    fn solve3_matches_the_matrix_product() {
        let n = 50;
        let trip = path_matrix(n);
        let a = upper_from_triplets(n, &trip);
        let f = Cholesky::new(&a).unwrap();
        let x_true: Vec<DVec3> = (0..n)
            .map(|i| DVec3::new(i as f64, (i * i) as f64 * 0.01, -1.0))
            .collect();
        // b = A x
        let mut b = vec![DVec3::ZERO; n];
        for &(r, c, v) in &trip {
            b[r] += x_true[c] * v;
            if r != c {
                b[c] += x_true[r] * v;
            }
        }
        f.solve3(&mut b);
        for (got, want) in b.iter().zip(&x_true) {
            assert!((*got - *want).length() < 1e-10, "{got} vs {want}");
        }
    }

    /// The pairs of a side×side grid with the lab cloth's stencil: neighbours one and two apart
    /// along rows and columns, and both diagonals.
    fn grid_pairs(side: usize) -> Vec<(usize, usize)> {
        let id = |i: usize, j: usize| i * side + j;
        let mut pairs = Vec::new();
        for i in 0..side {
            for j in 0..side {
                for (di, dj) in [(1, 0), (0, 1), (1, 1), (2, 0), (0, 2)] {
                    if i + di < side && j + dj < side {
                        pairs.push((id(i, j), id(i + di, j + dj)));
                    }
                }
                if i + 1 < side && j >= 1 {
                    pairs.push((id(i, j), id(i + 1, j - 1)));
                }
            }
        }
        pairs
    }

    /// Factor entries of the grid Laplacian-like matrix on `pairs` with unknown `old` relabelled
    /// `new_of_old[old]`.
    fn fill(n: usize, pairs: &[(usize, usize)], new_of_old: &[usize]) -> usize {
        let mut t: Vec<_> = (0..n).map(|i| (i, i, 13.0)).collect();
        t.extend(pairs.iter().map(|&(a, b)| {
            let (a, b) = (new_of_old[a], new_of_old[b]);
            (a.min(b), a.max(b), -1.0)
        }));
        Cholesky::new(&upper_from_triplets(n, &t)).unwrap().nnz()
    }

    fn inverse(order: &[u32]) -> Vec<usize> {
        let mut new_of_old = vec![0usize; order.len()];
        for (new, &old) in order.iter().enumerate() {
            new_of_old[old as usize] = new;
        }
        new_of_old
    }

    /// On a 2-D grid of 3,600 vertices the order is a permutation that fills less than the
    /// natural (row by row) order and than faer's approximate minimum degree order: the grid's
    /// factor has O(n log n) entries under nested dissection (George 1973), O(n^1.5) by rows, so
    /// nested dissection is the candidate chosen.
    #[test]
    fn the_order_fills_less_than_rows_and_minimum_degree_on_a_grid() {
        let side = 60;
        let n = side * side;
        let pairs = grid_pairs(side);
        let order = fill_reducing_order(n, pairs.iter().copied()).unwrap();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert!(sorted.iter().enumerate().all(|(i, &o)| o as usize == i));
        let nd = fill(n, &pairs, &inverse(&order));
        let natural = fill(n, &pairs, &(0..n).collect::<Vec<_>>());
        let mut trip: Vec<_> = (0..n).map(|i| (i, i, 1.0)).collect();
        trip.extend(pairs.iter().map(|&(a, b)| (a.min(b), a.max(b), 1.0)));
        let upper = upper_from_triplets(n, &trip);
        let amd = factorize_symbolic_cholesky(
            faer_view(&upper).symbolic(),
            Side::Upper,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .unwrap();
        let amd_order: Vec<u32> = amd
            .perm()
            .unwrap()
            .arrays()
            .0
            .iter()
            .map(|&i| i as u32)
            .collect();
        let amd = fill(n, &pairs, &inverse(&amd_order));
        assert!(
            nd < natural / 2,
            "nested dissection {nd}, natural order {natural}"
        );
        assert!(nd < amd, "nested dissection {nd}, minimum degree {amd}");
    }

    /// METIS draws from one process-wide random generator: orders computed on several threads at
    /// once (a scene's jobs run in parallel) must still all be the one a lone call gives.
    #[test]
    fn orders_computed_on_parallel_threads_are_all_the_same() {
        let side = 40;
        let n = side * side;
        let mut edges: Vec<(u32, u32)> = grid_pairs(side)
            .into_iter()
            .flat_map(|(a, b)| [(a as u32, b as u32), (b as u32, a as u32)])
            .collect();
        edges.sort_unstable();
        let alone = nested_dissection(n, &edges).unwrap();
        let orders: Vec<Vec<u32>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..4)
                .map(|_| {
                    scope.spawn(|| {
                        (0..10)
                            .map(|_| nested_dissection(n, &edges).unwrap())
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().unwrap())
                .collect()
        });
        for (k, order) in orders.iter().enumerate() {
            assert!(*order == alone, "order {k} differs from a lone call's");
        }
    }

    /// Tiny graphs and graphs without edges get the identity (METIS is not called).
    #[test]
    fn graphs_without_edges_keep_their_order() {
        assert_eq!(
            fill_reducing_order(5, std::iter::empty()).unwrap(),
            vec![0, 1, 2, 3, 4]
        );
        assert_eq!(
            fill_reducing_order(2, [(0, 1)].into_iter()).unwrap(),
            vec![0, 1]
        );
        assert_eq!(
            fill_reducing_order(4, [(2, 2)].into_iter()).unwrap(),
            vec![0, 1, 2, 3]
        );
    }

    /// A 2-D grid with a wide stencil (the lab cloth's: neighbours one and two apart) in
    /// nested-dissection order has supernodes from 1 to dozens of columns wide: every sweep path is exercised.
    #[test]
    fn supernodal_sweeps_match_the_matrix_product_on_a_grid() {
        let side = 24;
        let pairs = grid_pairs(side);
        let n = side * side;
        let order = fill_reducing_order(n, pairs.iter().copied()).unwrap();
        let mut new_of_old = vec![0usize; n];
        for (new, &old) in order.iter().enumerate() {
            new_of_old[old as usize] = new;
        }
        let mut trip: Vec<_> = (0..n).map(|i| (i, i, 10.0 + (i % 7) as f64)).collect();
        for (k, &(a, b)) in pairs.iter().enumerate() {
            let (a, b) = (new_of_old[a], new_of_old[b]);
            trip.push((a.min(b), a.max(b), -0.5 - 0.1 * (k % 5) as f64));
        }
        let f = Cholesky::new(&upper_from_triplets(n, &trip)).unwrap();
        let widest = (0..f.supernodes())
            .map(|s| f.sn_col[s + 1] - f.sn_col[s])
            .max()
            .unwrap();
        assert!(widest > 8, "expected wide supernodes, widest is {widest}");
        let x_true: Vec<DVec3> = (0..n)
            .map(|i| DVec3::new((i as f64 * 0.37).sin(), (i as f64 * 0.11).cos(), 1.0))
            .collect();
        let mut b = vec![DVec3::ZERO; n];
        for &(r, c, v) in &trip {
            b[r] += x_true[c] * v;
            if r != c {
                b[c] += x_true[r] * v;
            }
        }
        let mut b4: Vec<Lanes4> = b.iter().map(|v| Lanes4::from_vec3(*v)).collect();
        f.solve3(&mut b);
        f.solve4(&mut b4);
        for ((got, got4), want) in b.iter().zip(&b4).zip(&x_true) {
            assert!((*got - *want).length() < 1e-12, "{got} vs {want}");
            assert!((got4.xyz() - *want).length() < 1e-12, "{got4:?} vs {want}");
            assert_eq!(got4.0[3], 0.0, "the spare lane stays zero");
        }
    }

    type Triplets = Vec<(usize, usize, f64)>;

    /// A random sparse SPD matrix (random graph, random weights, diagonally dominant by a
    /// random margin) in nested-dissection order, and its dense copy.
    #[allow(clippy::needless_range_loop)]
    fn random_spd(n: usize, seed: u64) -> (Triplets, Vec<Vec<f64>>) {
        let mut state = seed;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut pairs = Vec::new();
        for i in 0..n {
            for _ in 0..3 {
                let j = (random() * n as f64) as usize % n;
                if j != i {
                    pairs.push((i.min(j), i.max(j)));
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let order = fill_reducing_order(n, pairs.iter().copied()).unwrap();
        let mut new_of_old = vec![0usize; n];
        for (new, &old) in order.iter().enumerate() {
            new_of_old[old as usize] = new;
        }
        let mut dense = vec![vec![0.0; n]; n];
        let mut trip = Vec::new();
        for &(a, b) in &pairs {
            let (a, b) = (new_of_old[a], new_of_old[b]);
            let w = -(0.1 + random());
            trip.push((a.min(b), a.max(b), w));
            dense[a][b] += w;
            dense[b][a] += w;
        }
        for i in 0..n {
            let off: f64 = dense[i].iter().map(|v: &f64| v.abs()).sum();
            let d = off + 0.01 + random();
            trip.push((i, i, d));
            dense[i][i] += d;
        }
        (trip, dense)
    }

    /// Dense Gaussian elimination with partial pivoting, the reference solve.
    #[allow(clippy::needless_range_loop)]
    fn dense_solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
        let n = b.len();
        for c in 0..n {
            let p = (c..n)
                .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
                .unwrap();
            a.swap(c, p);
            b.swap(c, p);
            for r in c + 1..n {
                let f = a[r][c] / a[c][c];
                for k in c..n {
                    a[r][k] -= f * a[c][k];
                }
                b[r] -= f * b[c];
            }
        }
        for c in (0..n).rev() {
            let s: f64 = (c + 1..n).map(|k| a[c][k] * b[k]).sum();
            b[c] = (b[c] - s) / a[c][c];
        }
        b
    }

    /// The f32 factor solves a random SPD system to f32 accuracy (both f32 and f64
    /// right-hand sides), and the f64 factor to f64 accuracy, against a dense solve.
    #[test]
    #[allow(clippy::needless_range_loop)]
    fn f32_factor_solves_random_spd_systems_to_single_precision() {
        for seed in [1, 2, 3] {
            let n = 300;
            let (trip, dense) = random_spd(n, 0x1234_5678 + seed);
            let f = Cholesky::new(&upper_from_triplets(n, &trip)).unwrap();
            let f32f = f.to_f32();
            let cols: [Vec<f64>; 3] = std::array::from_fn(|k| {
                (0..n)
                    .map(|i| ((i * (k + 2)) as f64 * 0.37).sin())
                    .collect()
            });
            let want: Vec<Vec<f64>> = cols
                .iter()
                .map(|b| dense_solve(dense.clone(), b.clone()))
                .collect();
            let rhs: Vec<Lanes4> = (0..n)
                .map(|i| Lanes4([cols[0][i], cols[1][i], cols[2][i], 0.0]))
                .collect();
            let (mut b64, mut bmixed) = (rhs.clone(), rhs.clone());
            let mut b32: Vec<Lanes4f> = rhs.iter().map(|v| Lanes4f::from_lanes4(*v)).collect();
            f.solve4(&mut b64);
            f32f.solve4(&mut bmixed);
            f32f.solve4f(&mut b32);
            let scale = want.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for i in 0..n {
                for k in 0..3 {
                    let w = want[k][i];
                    assert!((b64[i].0[k] - w).abs() < 1e-12 * scale, "f64 {i} {k}");
                    assert!((bmixed[i].0[k] - w).abs() < 1e-5 * scale, "mixed {i} {k}");
                    let e = (f64::from(b32[i].0[k]) - w).abs();
                    assert!(e < 1e-5 * scale, "f32 {i} {k}: {e:e}");
                }
                assert_eq!(b32[i].0[3], 0.0, "the spare lane stays zero");
            }
        }
    }

    /// Dropping small values removes whole rows of the pattern and keeps the solve close; the
    /// f32 sweep never produces subnormal numbers, even for a right-hand side at one node whose
    /// solution decays over many orders of magnitude.
    #[test]
    fn dropping_shrinks_the_f32_factor_and_solutions_stay_normal() {
        // A long, strongly diagonal path: L's fill (none) and solution decay ~ 1/10 per node.
        let n = 400;
        let mut trip: Vec<_> = (0..n).map(|i| (i, i, 10.0)).collect();
        trip.extend((0..n - 1).map(|i| (i, i + 1, -1.0)));
        trip.extend((0..n - 2).map(|i| (i, i + 2, -1e-9)));
        let f = Cholesky::new(&upper_from_triplets(n, &trip)).unwrap();
        let full = f.to_f32_dropping(0.0);
        let dropped = f.to_f32_dropping(1e-6);
        assert!(
            dropped.nnz() < full.nnz(),
            "{} < {}",
            dropped.nnz(),
            full.nnz()
        );
        assert!(dropped.rows.len() < full.rows.len());
        let mut b = vec![Lanes4f::default(); n];
        b[n / 2] = Lanes4f([1.0, -1.0, 0.5, 0.0]);
        let mut b_full = b.clone();
        dropped.solve4f(&mut b);
        full.solve4f(&mut b_full);
        for (got, want) in b.iter().zip(&b_full) {
            for k in 0..4 {
                assert!(!got.0[k].is_subnormal() && !want.0[k].is_subnormal());
                assert!((got.0[k] - want.0[k]).abs() <= 1e-6, "{got:?} vs {want:?}");
            }
        }
        let zeros = b.iter().filter(|v| v.0[0] == 0.0).count();
        assert!(zeros > n / 2, "the decayed tail is flushed ({zeros} zeros)");
    }

    #[test]
    fn indefinite_matrix_is_an_error() {
        let a = upper_from_triplets(2, &[(0, 0, 1.0), (0, 1, 2.0), (1, 1, 1.0)]);
        assert!(matches!(Cholesky::new(&a), Err(Error::Factorisation(_))));
    }
}
