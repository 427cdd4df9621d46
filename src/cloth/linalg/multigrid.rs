//! Smoothed-aggregation algebraic multigrid for Newton's systems (3×3 blocks, one per particle
//! pair), used as the preconditioner of conjugate gradients where a sparse factor would cost
//! more than linearly in the mesh (Vaněk, Mandel & Brezina 1996; for cloth, Tamstorf, Jones &
//! McCormick 2015).
//!
//! - **Aggregates** (once, from the pattern): greedy, on the particles' graph; a level's
//!   aggregates are the next level's particles. The near-null space is the three translations:
//!   the tentative prolongator maps an aggregate's 3×3 identity to each of its particles.
//! - **Prolongator** P = (I − ω D⁻¹A) P₀, D the block diagonal, ω = 4 / (3 λ), λ the largest
//!   eigenvalue of D⁻¹A estimated by power iterations; coarse matrix PᵀAP. The patterns of P,
//!   AP and PᵀAP are computed once; every refresh recomputes their values.
//! - **Cycle**: a V-cycle, forward block Gauss–Seidel before the coarse correction and backward
//!   after it (a symmetric preconditioner, as conjugate gradients need), and a dense Cholesky
//!   factor on the coarsest level. The levels hold single-precision blocks (half the memory
//!   traffic of the cycle); the coarsest factor is in double precision.
//!
//! Its cost is linear in the particles: a refresh and a cycle each visit every level's blocks a
//! fixed number of times, and the levels shrink geometrically.

use faer::linalg::solvers::{Llt, SolveCore};
use faer::{Conj, Mat, MatMut, Side};
use glam::{Mat3, Vec3};

/// Levels stop coarsening at this many particles or fewer; that level is factored densely.
pub const COARSEST: usize = 100;

/// Rows from which a level's products and sweeps run on two threads, when the bake has two.
const PARALLEL_ROWS: usize = 4096;

/// Power iterations estimating the largest eigenvalue of D⁻¹A on each level.
const POWER_ITERATIONS: usize = 10;

/// The power iterations' estimate approaches the eigenvalue from below; the prolongator's
/// smoothing uses it enlarged by this factor (a too-small λ over-smooths).
const POWER_MARGIN: f32 = 1.05;

/// A square or rectangular matrix of 3×3 blocks in compressed rows, columns sorted in each row.
#[derive(Debug, Clone, Default)]
struct Blocks {
    start: Vec<u32>,
    col: Vec<u32>,
    val: Vec<Mat3>,
}

impl Blocks {
    fn rows(&self) -> usize {
        self.start.len() - 1
    }

    fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.start[i] as usize..self.start[i + 1] as usize
    }

    /// A pattern from sorted, unique column lists, values zero.
    fn from_rows(rows: impl Iterator<Item = Vec<u32>>) -> Blocks {
        let mut start = vec![0u32];
        let mut col = Vec::new();
        for list in rows {
            col.extend_from_slice(&list);
            start.push(col.len() as u32);
        }
        let val = vec![Mat3::ZERO; col.len()];
        Blocks { start, col, val }
    }

    /// The pattern of `self · b`, `columns` its column count.
    fn product_pattern(&self, b: &Blocks, columns: usize) -> Blocks {
        let mut mark = vec![u32::MAX; columns];
        let rows = (0..self.rows()).map(|i| {
            let mut list = Vec::new();
            for &j in &self.col[self.row(i)] {
                for &c in &b.col[b.row(j as usize)] {
                    if mark[c as usize] != i as u32 {
                        mark[c as usize] = i as u32;
                        list.push(c);
                    }
                }
            }
            list.sort_unstable();
            list
        });
        Blocks::from_rows(rows)
    }

    /// Overwrites `out`'s values (its pattern from [`Blocks::product_pattern`]) with
    /// `self · b`. `slot` is scratch of `out`'s column count.
    fn product_into(&self, b: &Blocks, out: &mut Blocks, slot: &mut [u32]) {
        for i in 0..self.rows() {
            let range = out.row(i);
            for k in range.clone() {
                slot[out.col[k] as usize] = k as u32;
            }
            let vals = &mut out.val[range.clone()];
            vals.fill(Mat3::ZERO);
            let first = range.start;
            for ka in self.row(i) {
                let a = self.val[ka];
                for kb in b.row(self.col[ka] as usize) {
                    vals[slot[b.col[kb] as usize] as usize - first] += a * b.val[kb];
                }
            }
        }
    }

    /// The transpose's pattern (`columns` of `self` become its rows), and for each of its
    /// entries the entry of `self` it mirrors.
    fn transpose_pattern(&self, columns: usize) -> (Blocks, Vec<u32>) {
        let mut start = vec![0u32; columns + 1];
        for &c in &self.col {
            start[c as usize + 1] += 1;
        }
        for c in 0..columns {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut col = vec![0u32; self.col.len()];
        let mut source = vec![0u32; self.col.len()];
        for i in 0..self.rows() {
            for k in self.row(i) {
                let c = self.col[k] as usize;
                let at = fill[c] as usize;
                col[at] = i as u32;
                source[at] = k as u32;
                fill[c] += 1;
            }
        }
        let val = vec![Mat3::ZERO; col.len()];
        (Blocks { start, col, val }, source)
    }

    /// y = self · x, or y += self · x, the two halves of the rows on two threads when `two`.
    fn product(&self, x: &[Vec3], y: &mut [Vec3], add: bool, two: bool) {
        let mid = y.len() / 2;
        halves(y, mid, two, |first, y| {
            for (i, yi) in (first..).zip(y) {
                let mut sum = Vec3::ZERO;
                for k in self.row(i) {
                    sum += self.val[k] * x[self.col[k] as usize];
                }
                *yi = if add { *yi + sum } else { sum };
            }
        });
    }
}

/// Runs `f(first, rows)` on `out[..mid]` and `out[mid..]`: at once on two threads when `two`,
/// else one after the other (the same arithmetic either way).
fn halves<T: Send>(out: &mut [T], mid: usize, two: bool, f: impl Fn(usize, &mut [T]) + Sync) {
    let (low, high) = out.split_at_mut(mid);
    if two {
        std::thread::scope(|s| {
            s.spawn(|| f(mid, high));
            f(0, low);
        });
    } else {
        f(0, low);
        f(mid, high);
    }
}

/// One level of the hierarchy: its matrix, its smoother's inverted diagonal blocks, and (on
/// every level but the coarsest) the prolongator from the next level.
#[derive(Debug, Default)]
struct Level {
    a: Blocks,
    /// Per row, the entry of its diagonal block.
    diag: Vec<u32>,
    inverse: Vec<Mat3>,
    /// Per particle, its aggregate: its particle on the next level.
    aggregate: Vec<u32>,
    p: Blocks,
    pt: Blocks,
    /// Per entry of `pt`, the entry of `p` it mirrors.
    pt_source: Vec<u32>,
    /// A · P, the first half of the next level's Galerkin product.
    ap: Blocks,
    x: Vec<Vec3>,
    b: Vec<Vec3>,
    r: Vec<Vec3>,
    /// The iterate before a sweep (what each half reads of the other).
    prev: Vec<Vec3>,
    /// Whether this level's products and sweeps run on two threads.
    two: bool,
}

/// A smoothed-aggregation hierarchy over a fixed pattern; [`Multigrid::refresh`] takes new
/// values, [`Multigrid::apply`] is one V-cycle.
#[derive(Debug)]
pub struct Multigrid {
    levels: Vec<Level>,
    /// Per particle j of the finest level, its diagonal entry; per lower neighbour i of j (in
    /// the order of the upper triangle's column 3j), the entries of blocks (i, j) and (j, i).
    fine_diag: Vec<u32>,
    fine_pairs: Vec<[u32; 2]>,
    /// The coarsest level's dense Cholesky factor, once refreshed.
    coarse: Option<Llt<f64>>,
    coarse_rhs: Mat<f64>,
    /// Scratch of the largest column count of any product.
    slot: Vec<u32>,
}

/// Greedy aggregation of a graph given as a block pattern (its rows' columns include the row
/// itself): first, every particle whose neighbours are all free makes an aggregate with them;
/// then each particle left joins an aggregate of a neighbour made in that first pass; then those
/// still left make aggregates with their free neighbours. Returns each particle's aggregate
/// and the count.
fn aggregate(a: &Blocks) -> (Vec<u32>, usize) {
    const FREE: u32 = u32::MAX;
    let n = a.rows();
    let mut agg = vec![FREE; n];
    let mut count = 0u32;
    for i in 0..n {
        let row = &a.col[a.row(i)];
        if row.iter().all(|&j| agg[j as usize] == FREE) {
            for &j in row {
                agg[j as usize] = count;
            }
            count += 1;
        }
    }
    let first = agg.clone();
    for (i, agg_i) in agg.iter_mut().enumerate() {
        if *agg_i == FREE {
            if let Some(&j) = a.col[a.row(i)].iter().find(|&&j| first[j as usize] != FREE) {
                *agg_i = first[j as usize];
            }
        }
    }
    for i in 0..n {
        if agg[i] == FREE {
            for &j in &a.col[a.row(i)] {
                if agg[j as usize] == FREE {
                    agg[j as usize] = count;
                }
            }
            count += 1;
        }
    }
    (agg, count as usize)
}

impl Multigrid {
    /// The hierarchy's patterns for the symmetric matrix whose upper triangle is given in
    /// compressed columns over 3 unknowns per particle, in the layout of Newton's pattern:
    /// column 3j + c holds rows 3i..3i+3 of each lower neighbour i of j (ascending), then rows
    /// 3j..=3j+c.
    pub fn new(col_ptr: &[usize], row_idx: &[usize]) -> Multigrid {
        let n = (col_ptr.len() - 1) / 3;
        let mut lower: Vec<Vec<u32>> = vec![Vec::new(); n];
        let mut rows: Vec<Vec<u32>> = (0..n).map(|j| vec![j as u32]).collect();
        for (j, list) in lower.iter_mut().enumerate() {
            let column = col_ptr[3 * j]..col_ptr[3 * j + 1] - 1;
            for k in column.step_by(3) {
                let i = row_idx[k] / 3;
                list.push(i as u32);
                rows[i].push(j as u32);
                rows[j].push(i as u32);
            }
        }
        for row in &mut rows {
            row.sort_unstable();
        }
        let a = Blocks::from_rows(rows.into_iter());
        let entry =
            |i: usize, j: u32| a.start[i] + a.col[a.row(i)].binary_search(&j).unwrap() as u32;
        let fine_diag = (0..n).map(|j| entry(j, j as u32)).collect();
        let fine_pairs = lower
            .iter()
            .enumerate()
            .flat_map(|(j, list)| list.iter().map(move |&i| (i as usize, j)))
            .map(|(i, j)| [entry(i, j as u32), entry(j, i as u32)])
            .collect();

        let mut levels = Vec::new();
        let mut a = a;
        let mut widest = n;
        loop {
            let m = a.rows();
            let diag = (0..m)
                .map(|i| a.start[i] + a.col[a.row(i)].binary_search(&(i as u32)).unwrap() as u32)
                .collect();
            let mut level = Level {
                diag,
                inverse: vec![Mat3::IDENTITY; m],
                x: vec![Vec3::ZERO; m],
                b: vec![Vec3::ZERO; m],
                r: vec![Vec3::ZERO; m],
                prev: vec![Vec3::ZERO; m],
                ..Level::default()
            };
            if m <= COARSEST {
                level.a = a;
                levels.push(level);
                break;
            }
            let (agg, count) = aggregate(&a);
            if count >= m {
                level.a = a;
                levels.push(level);
                break;
            }
            let p = Blocks::from_rows((0..m).map(|i| {
                let mut list: Vec<u32> = a.col[a.row(i)].iter().map(|&j| agg[j as usize]).collect();
                list.sort_unstable();
                list.dedup();
                list
            }));
            let (pt, pt_source) = p.transpose_pattern(count);
            let ap = a.product_pattern(&p, count);
            let next = pt.product_pattern(&ap, count);
            widest = widest.max(count);
            level.a = a;
            level.aggregate = agg;
            level.p = p;
            level.pt = pt;
            level.pt_source = pt_source;
            level.ap = ap;
            levels.push(level);
            a = next;
        }
        let coarse_dim = 3 * levels.last().map_or(0, |l| l.a.rows());
        Multigrid {
            levels,
            fine_diag,
            fine_pairs,
            coarse: None,
            coarse_rhs: Mat::zeros(coarse_dim, 1),
            slot: vec![0; widest],
        }
    }

    /// Whether levels of [`PARALLEL_ROWS`] rows or more run their products and sweeps on two
    /// threads (the same result either way).
    pub fn use_threads(&mut self, two: bool) {
        for level in &mut self.levels {
            level.two = two && level.a.rows() >= PARALLEL_ROWS;
        }
    }

    /// Levels in the hierarchy, finest first: each one's particles.
    #[cfg(test)]
    fn sizes(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.a.rows()).collect()
    }

    /// Recomputes every level from the finest matrix's upper-triangle `values` (the pattern
    /// given to [`Multigrid::new`]). Returns false when a diagonal block or the coarsest matrix
    /// is not positive definite in single precision (the caller factors instead).
    pub fn refresh(&mut self, col_ptr: &[usize], values: &[f64]) -> bool {
        self.load_finest(col_ptr, values);
        let count = self.levels.len();
        for l in 0..count {
            let (fine, rest) = self.levels.split_at_mut(l + 1);
            let level = &mut fine[l];
            for (inv, &d) in level.inverse.iter_mut().zip(&level.diag) {
                let block = level.a.val[d as usize];
                let det = block.determinant();
                if !(det.is_finite() && det > 0.0) {
                    return false;
                }
                *inv = block.inverse();
            }
            let Some(next) = rest.first_mut() else {
                break;
            };
            let omega = 4.0 / (3.0 * POWER_MARGIN * largest_eigenvalue(level));
            // P = (I − ω D⁻¹A) P₀, row by row.
            let (a, p, agg) = (&level.a, &mut level.p, &level.aggregate);
            for i in 0..a.rows() {
                let range = p.row(i);
                let first = range.start;
                for k in range.clone() {
                    self.slot[p.col[k] as usize] = (k - first) as u32;
                }
                let vals = &mut p.val[range];
                vals.fill(Mat3::ZERO);
                vals[self.slot[agg[i] as usize] as usize] = Mat3::IDENTITY;
                let scaled = level.inverse[i] * -omega;
                for k in a.row(i) {
                    vals[self.slot[agg[a.col[k] as usize] as usize] as usize] += scaled * a.val[k];
                }
            }
            for (v, &s) in level.pt.val.iter_mut().zip(&level.pt_source) {
                *v = level.p.val[s as usize].transpose();
            }
            level
                .a
                .product_into(&level.p, &mut level.ap, &mut self.slot);
            level
                .pt
                .product_into(&level.ap, &mut next.a, &mut self.slot);
        }
        self.coarse = self.factor_coarsest();
        self.coarse.is_some()
    }

    fn load_finest(&mut self, col_ptr: &[usize], values: &[f64]) {
        let a = &mut self.levels[0].a;
        let mut pair = 0;
        for (j, &d) in self.fine_diag.iter().enumerate() {
            let columns = [col_ptr[3 * j], col_ptr[3 * j + 1], col_ptr[3 * j + 2]];
            let degree = (col_ptr[3 * j + 1] - col_ptr[3 * j] - 1) / 3;
            let column = |c: usize, p: usize| {
                let at = columns[c] + 3 * p;
                Vec3::new(
                    values[at] as f32,
                    values[at + 1] as f32,
                    values[at + 2] as f32,
                )
            };
            for p in 0..degree {
                let block = Mat3::from_cols(column(0, p), column(1, p), column(2, p));
                let [ij, ji] = self.fine_pairs[pair];
                a.val[ij as usize] = block;
                a.val[ji as usize] = block.transpose();
                pair += 1;
            }
            // Column 3j + c ends with rows 3j..=3j + c.
            let at = |c: usize, r: usize| values[columns[c] + 3 * degree + r] as f32;
            let (xy, xz, yz) = (at(1, 0), at(2, 0), at(2, 1));
            a.val[d as usize] = Mat3::from_cols(
                Vec3::new(at(0, 0), xy, xz),
                Vec3::new(xy, at(1, 1), yz),
                Vec3::new(xz, yz, at(2, 2)),
            );
        }
    }

    fn factor_coarsest(&self) -> Option<Llt<f64>> {
        let a = &self.levels.last()?.a;
        let dim = 3 * a.rows();
        let mut dense = Mat::<f64>::zeros(dim, dim);
        for i in 0..a.rows() {
            for k in a.row(i) {
                let (j, block) = (a.col[k] as usize, a.val[k]);
                for c in 0..3 {
                    let column = block.col(c);
                    for r in 0..3 {
                        dense[(3 * i + r, 3 * j + c)] = f64::from(column[r]);
                    }
                }
            }
        }
        dense.llt(Side::Lower).ok()
    }

    /// z ≈ A⁻¹ r: one V-cycle from zero (3 scalars per particle).
    ///
    /// # Panics
    /// When called before a successful [`Multigrid::refresh`].
    pub fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        for (b, r) in self.levels[0].b.iter_mut().zip(r.chunks_exact(3)) {
            *b = Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32);
        }
        self.cycle(0);
        for (z, x) in z.chunks_exact_mut(3).zip(&self.levels[0].x) {
            z.copy_from_slice(&x.as_dvec3().to_array());
        }
    }

    fn cycle(&mut self, l: usize) {
        if l + 1 == self.levels.len() {
            self.solve_coarsest();
            return;
        }
        let (fine, rest) = self.levels.split_at_mut(l + 1);
        let level = &mut fine[l];
        let next = &mut rest[0];
        level.x.fill(Vec3::ZERO);
        level.gauss_seidel(false);
        level.a.product(&level.x, &mut level.r, false, level.two);
        for (r, b) in level.r.iter_mut().zip(&level.b) {
            *r = *b - *r;
        }
        level.pt.product(&level.r, &mut next.b, false, next.two);
        self.cycle(l + 1);
        let (fine, rest) = self.levels.split_at_mut(l + 1);
        let level = &mut fine[l];
        level.p.product(&rest[0].x, &mut level.x, true, level.two);
        level.gauss_seidel(true);
    }

    fn solve_coarsest(&mut self) {
        let level = self.levels.last_mut().expect("a level");
        let rhs = &mut self.coarse_rhs;
        for (i, b) in level.b.iter().enumerate() {
            for c in 0..3 {
                rhs[(3 * i + c, 0)] = f64::from(b[c]);
            }
        }
        let llt = self.coarse.as_ref().expect("refreshed");
        let view: MatMut<'_, f64> = rhs.as_mut();
        llt.solve_in_place_with_conj(Conj::No, view);
        for (i, x) in level.x.iter_mut().enumerate() {
            *x = Vec3::new(
                rhs[(3 * i, 0)] as f32,
                rhs[(3 * i + 1, 0)] as f32,
                rhs[(3 * i + 2, 0)] as f32,
            );
        }
    }
}

impl Level {
    /// One block Gauss–Seidel sweep on A x = b, forward or backward, in two halves of the rows
    /// (hybrid Gauss–Seidel): within its half a row takes the values just updated, from the
    /// other half those before the sweep. The backward sweep is the forward one's adjoint, so
    /// the cycle stays symmetric; the halves run at once when the level runs on two threads.
    fn gauss_seidel(&mut self, backward: bool) {
        self.prev.copy_from_slice(&self.x);
        let (a, inverse, b, prev) = (&self.a, &self.inverse, &self.b, &self.prev);
        let mid = self.x.len() / 2;
        halves(&mut self.x, mid, self.two, |first, x| {
            let end = first + x.len();
            let mut relax = |i: usize| {
                let mut s = b[i];
                for k in a.row(i) {
                    let j = a.col[k] as usize;
                    if j != i {
                        let xj = if (first..end).contains(&j) {
                            x[j - first]
                        } else {
                            prev[j]
                        };
                        s -= a.val[k] * xj;
                    }
                }
                x[i - first] = inverse[i] * s;
            };
            if backward {
                (first..end).rev().for_each(&mut relax);
            } else {
                (first..end).for_each(&mut relax);
            }
        });
    }
}

/// The largest eigenvalue of D⁻¹A (D the block diagonal), estimated by power iterations from a
/// fixed start (the bake stays deterministic).
fn largest_eigenvalue(level: &mut Level) -> f32 {
    let (x, y) = (&mut level.x, &mut level.r);
    for (i, v) in x.iter_mut().enumerate() {
        // A start with components along every mode: a fixed scramble of the index.
        let h = (i as u32).wrapping_mul(2_654_435_761);
        *v = Vec3::new(
            (h & 0xff) as f32 / 255.0 - 0.5,
            ((h >> 8) & 0xff) as f32 / 255.0 - 0.5,
            ((h >> 16) & 0xff) as f32 / 255.0 - 0.5,
        );
    }
    let mut lambda = 1.0f32;
    for _ in 0..POWER_ITERATIONS {
        let norm = x.iter().map(|v| v.length_squared()).sum::<f32>().sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            break;
        }
        level.a.product(x, y, false, level.two);
        for (yi, inv) in y.iter_mut().zip(&level.inverse) {
            *yi = *inv * *yi / norm;
        }
        lambda = y.iter().map(|v| v.length_squared()).sum::<f32>().sqrt();
        std::mem::swap(x, y);
    }
    lambda.max(f32::EPSILON)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The upper triangle, in Newton's layout, of a 3-D "mass-spring" matrix on an n × n grid:
    /// mass m on every diagonal, and for every grid edge a spring of stiffness k along its
    /// direction plus a little across it.
    fn grid(n: usize, m: f64, k: f64) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
        let id = |x: usize, y: usize| y * n + x;
        let count = n * n;
        let mut lower: Vec<Vec<usize>> = vec![Vec::new(); count];
        for y in 0..n {
            for x in 0..n {
                if x + 1 < n {
                    lower[id(x + 1, y)].push(id(x, y));
                }
                if y + 1 < n {
                    lower[id(x, y + 1)].push(id(x, y));
                }
            }
        }
        for l in &mut lower {
            l.sort_unstable();
        }
        let block = |a: usize, b: usize| -> [[f64; 3]; 3] {
            let horizontal = a.abs_diff(b) == 1;
            let d = if horizontal {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let mut out = [[0.0; 3]; 3];
            for (r, row) in out.iter_mut().enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = -k * (d[r] * d[c] + 0.01 * f64::from(u8::from(r == c)));
                }
            }
            out
        };
        let mut diag = vec![[[0.0; 3]; 3]; count];
        for d in &mut diag {
            for (r, row) in d.iter_mut().enumerate() {
                row[r] = m;
            }
        }
        for (j, l) in lower.iter().enumerate() {
            for &i in l {
                let b = block(i, j);
                for r in 0..3 {
                    for c in 0..3 {
                        diag[i][r][c] -= b[r][c];
                        diag[j][r][c] -= b[r][c];
                    }
                }
            }
        }
        let (mut col_ptr, mut row_idx, mut values) = (vec![0], Vec::new(), Vec::new());
        for j in 0..count {
            for c in 0..3 {
                for &i in &lower[j] {
                    for (r, row) in block(i, j).iter().enumerate() {
                        row_idx.push(3 * i + r);
                        values.push(row[c]);
                    }
                }
                for (r, row) in diag[j].iter().enumerate().take(c + 1) {
                    row_idx.push(3 * j + r);
                    values.push(row[c]);
                }
                col_ptr.push(row_idx.len());
            }
        }
        (col_ptr, row_idx, values)
    }

    fn product(col_ptr: &[usize], row_idx: &[usize], values: &[f64], x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for c in 0..x.len() {
            for k in col_ptr[c]..col_ptr[c + 1] {
                let r = row_idx[k];
                y[r] += values[k] * x[c];
                if r != c {
                    y[c] += values[k] * x[r];
                }
            }
        }
        y
    }

    /// Conjugate gradients preconditioned by the hierarchy, to a relative residual of 1e-6;
    /// returns the iterations taken.
    fn pcg_iterations(n: usize) -> usize {
        let (col_ptr, row_idx, values) = grid(n, 1.0, 1e4);
        let mut mg = Multigrid::new(&col_ptr, &row_idx);
        assert!(mg.refresh(&col_ptr, &values));
        let dim = 3 * n * n;
        let b: Vec<f64> = (0..dim)
            .map(|i| ((i * 7919) % 101) as f64 / 50.0 - 1.0)
            .collect();
        let (mut x, mut r) = (vec![0.0; dim], b.clone());
        let mut z = vec![0.0; dim];
        mg.apply(&r, &mut z);
        let mut p = z.clone();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
        let mut rz = dot(&r, &z);
        let norm0 = dot(&b, &b).sqrt();
        for k in 1..=200 {
            let q = product(&col_ptr, &row_idx, &values, &p);
            let alpha = rz / dot(&p, &q);
            for i in 0..dim {
                x[i] += alpha * p[i];
                r[i] -= alpha * q[i];
            }
            if dot(&r, &r).sqrt() <= 1e-6 * norm0 {
                // The residual recomputed from x agrees: the iterate solves the system.
                let ax = product(&col_ptr, &row_idx, &values, &x);
                let true_r = ax
                    .iter()
                    .zip(&b)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>();
                assert!(true_r.sqrt() <= 2e-6 * norm0);
                return k;
            }
            mg.apply(&r, &mut z);
            let rz_next = dot(&r, &z);
            for i in 0..dim {
                p[i] = z[i] + rz_next / rz * p[i];
            }
            rz = rz_next;
        }
        panic!("no convergence in 200 iterations on {n}×{n}");
    }

    #[test]
    fn conjugate_gradients_take_as_many_cycles_whatever_the_grid_size() {
        // Stiff springs (h²k/m = 1e4): unpreconditioned, the iterations would grow with the grid
        // width; with the hierarchy they stay nearly flat.
        let counts: Vec<usize> = [16, 32, 64, 128]
            .iter()
            .map(|&n| pcg_iterations(n))
            .collect();
        let (small, large) = (counts[0], counts[3]);
        assert!(
            large <= 2 * small.max(8),
            "iterations grow with the grid: {counts:?}"
        );
        assert!(large <= 50, "iterations: {counts:?}");
    }

    #[test]
    fn a_cycle_on_two_threads_equals_one_on_one() {
        let (col_ptr, row_idx, values) = grid(96, 1.0, 1e4);
        let r: Vec<f64> = (0..row_idx.len().min(3 * 96 * 96))
            .map(|i| (i % 13) as f64 - 6.0)
            .collect();
        let cycle = |two: bool| {
            let mut mg = Multigrid::new(&col_ptr, &row_idx);
            mg.use_threads(two);
            assert!(mg.refresh(&col_ptr, &values));
            assert_eq!(mg.levels[0].two, two);
            let mut z = vec![0.0; r.len()];
            mg.apply(&r, &mut z);
            z
        };
        let (one, two) = (cycle(false), cycle(true));
        assert!(one.iter().any(|&z| z != 0.0));
        assert!(one
            .iter()
            .zip(&two)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    #[test]
    fn hierarchy_coarsens_geometrically() {
        let (col_ptr, row_idx, _) = grid(64, 1.0, 1e4);
        let sizes = Multigrid::new(&col_ptr, &row_idx).sizes();
        assert_eq!(sizes[0], 64 * 64);
        assert!(*sizes.last().unwrap() <= COARSEST, "{sizes:?}");
        for pair in sizes.windows(2) {
            assert!(pair[1] * 4 <= pair[0], "{sizes:?}");
        }
    }
}
