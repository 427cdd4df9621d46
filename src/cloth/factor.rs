//! Sparse symmetric positive-definite factorisation for the cloth solvers.
//!
//! Matrices are assembled with `sprs` and factored by `faer`'s simplicial Cholesky. The factor is
//! then kept as plain compressed columns with the diagonal split out, so that [`Cholesky::solve3`]
//! can run both triangular sweeps over `DVec3` right-hand sides in one pass per sweep (x, y and z
//! share every index load) without allocating. Callers order their unknowns once with
//! [`fill_reducing_order`], so the factor needs no permutation at solve time.

use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{dyn_stack::MemBuffer, dyn_stack::MemStack, Par, Side};
use glam::DVec3;
use sprs::{CsMat, TriMat};

use crate::error::{Error, Result};

/// A lower-triangular Cholesky factor L (A = L·Lᵀ) in compressed columns, diagonal stored apart.
#[derive(Debug, Clone)]
pub struct Cholesky {
    /// Start of each column's strictly-lower entries in `rows`/`values` (length n + 1).
    col_start: Vec<u32>,
    /// Row of each strictly-lower entry.
    rows: Vec<u32>,
    /// Value of each strictly-lower entry.
    values: Vec<f64>,
    /// 1 / L[j, j].
    inv_diagonal: Vec<f64>,
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

fn faer_view(upper: &CsMat<f64>) -> SparseColMatRef<'_, usize, f64> {
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

/// A fill-reducing (approximate minimum degree) order for the n×n symmetric pattern given by
/// `pairs` (plus the diagonal): `order[new] = old`.
pub fn fill_reducing_order(
    n: usize,
    pairs: impl Iterator<Item = (usize, usize)>,
) -> Result<Vec<u32>> {
    let mut triplets: Vec<(usize, usize, f64)> = (0..n).map(|i| (i, i, 1.0)).collect();
    triplets.extend(pairs.map(|(a, b)| (a.min(b), a.max(b), 1.0)));
    let upper = upper_from_triplets(n, &triplets);
    let view = faer_view(&upper);
    let symbolic = factorize_symbolic_cholesky(
        view.symbolic(),
        Side::Upper,
        SymmetricOrdering::Amd,
        simplicial(),
    )
    .map_err(|e| Error::Factorisation(format!("ordering: {e:?}")))?;
    Ok(match symbolic.perm() {
        Some(perm) => perm.arrays().0.iter().map(|&i| i as u32).collect(),
        None => (0..n as u32).collect(),
    })
}

fn simplicial() -> CholeskySymbolicParams<'static> {
    CholeskySymbolicParams {
        supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SIMPLICIAL,
        ..Default::default()
    }
}

impl Cholesky {
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
            simplicial(),
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
        let SymbolicCholeskyRaw::Simplicial(simp) = symbolic.raw() else {
            return Err(Error::Factorisation("expected a simplicial factor".into()));
        };
        let (col_ptr, row_idx) = (simp.col_ptr(), simp.row_idx());
        let mut f = Cholesky {
            col_start: Vec::with_capacity(n + 1),
            rows: Vec::with_capacity(l_values.len() - n),
            values: Vec::with_capacity(l_values.len() - n),
            inv_diagonal: Vec::with_capacity(n),
        };
        for j in 0..n {
            f.col_start.push(f.rows.len() as u32);
            let mut diagonal = None;
            for p in col_ptr[j]..col_ptr[j + 1] {
                let (r, v) = (row_idx[p], l_values[p]);
                if r == j {
                    diagonal = Some(v);
                } else {
                    debug_assert!(r > j, "lower factor");
                    f.rows.push(r as u32);
                    f.values.push(v);
                }
            }
            let d = diagonal
                .filter(|d| *d > 0.0 && d.is_finite())
                .ok_or_else(|| {
                    Error::Factorisation(format!("zero or non-finite pivot in column {j}"))
                })?;
            f.inv_diagonal.push(1.0 / d);
        }
        f.col_start.push(f.rows.len() as u32);
        Ok(f)
    }

    /// Size n of the factored matrix.
    pub fn dimension(&self) -> usize {
        self.inv_diagonal.len()
    }

    /// Stored entries of L, diagonal included.
    pub fn nnz(&self) -> usize {
        self.rows.len() + self.inv_diagonal.len()
    }

    /// Solves A·X = B in place for three right-hand sides at once (the x, y and z columns of
    /// `b`). No allocation.
    ///
    /// # Panics
    /// When `b.len()` differs from [`Cholesky::dimension`].
    pub fn solve3(&self, b: &mut [DVec3]) {
        let n = self.dimension();
        assert_eq!(b.len(), n, "right-hand side length");
        let (starts, rows, values) = (&self.col_start[..], &self.rows[..], &self.values[..]);
        // Forward: L·Y = B, column by column (scatter).
        for j in 0..n {
            let yj = b[j] * self.inv_diagonal[j];
            b[j] = yj;
            let (s, e) = (starts[j] as usize, starts[j + 1] as usize);
            for (&r, &v) in rows[s..e].iter().zip(&values[s..e]) {
                b[r as usize] -= yj * v;
            }
        }
        // Backward: Lᵀ·X = Y, column by column (gather).
        for j in (0..n).rev() {
            let (s, e) = (starts[j] as usize, starts[j + 1] as usize);
            let mut acc = b[j];
            for (&r, &v) in rows[s..e].iter().zip(&values[s..e]) {
                acc -= b[r as usize] * v;
            }
            b[j] = acc * self.inv_diagonal[j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn amd_relabelling_gives_the_same_fill_as_faer_ordering_internally() {
        // A 2-D grid graph: natural order fills more than AMD order.
        let side = 30;
        let id = |i: usize, j: usize| i * side + j;
        let mut pairs = Vec::new();
        for i in 0..side {
            for j in 0..side {
                if i + 1 < side {
                    pairs.push((id(i, j), id(i + 1, j)));
                }
                if j + 1 < side {
                    pairs.push((id(i, j), id(i, j + 1)));
                }
            }
        }
        let n = side * side;
        let build = |label: &dyn Fn(usize) -> usize| {
            let mut t: Vec<_> = (0..n).map(|i| (i, i, 5.0)).collect();
            t.extend(
                pairs
                    .iter()
                    .map(|&(a, b)| (label(a).min(label(b)), label(a).max(label(b)), -1.0)),
            );
            upper_from_triplets(n, &t)
        };
        let natural = Cholesky::new(&build(&|i| i)).unwrap().nnz();
        let order = fill_reducing_order(n, pairs.iter().copied()).unwrap();
        let mut new_of_old = vec![0usize; n];
        for (new, &old) in order.iter().enumerate() {
            new_of_old[old as usize] = new;
        }
        let amd = Cholesky::new(&build(&|i| new_of_old[i])).unwrap().nnz();
        assert!(
            amd < natural * 3 / 4,
            "AMD fill {amd} should beat natural order {natural}"
        );
    }

    #[test]
    fn indefinite_matrix_is_an_error() {
        let a = upper_from_triplets(2, &[(0, 0, 1.0), (0, 1, 2.0), (1, 1, 1.0)]);
        assert!(matches!(Cholesky::new(&a), Err(Error::Factorisation(_))));
    }
}
