//! Newton's single-precision preconditioner factored as two halves and a dense top, the halves
//! on two threads at once.
//!
//! faer's supernodal Cholesky runs on one thread (its parallel mode only splits each
//! supernode's dense kernels, which on a garment's small supernodes is slower). A nested-
//! dissection order's elimination tree, though, is two subtrees below a top separator: the
//! columns split into groups A and B, with no entry of H between them, and the top T
//! ([`column_groups`]). Then, with H_AA = L_A·L_Aᵀ and L_TA = H_TA·L_A⁻ᵀ,
//!
//! ```text
//!     [H_AA  0     H_AT]   [L_A  0    0  ] [L_A  0    0  ]ᵀ
//!     [0     H_BB  H_BT] = [0    L_B  0  ] [0    L_B  0  ]
//!     [H_TA  H_TB  H_TT]   [L_TA L_TB L_C] [L_TA L_TB L_C]
//! ```
//!
//! with L_C·L_Cᵀ = C = H_TT − L_TA·L_TAᵀ − L_TB·L_TBᵀ. faer factors each half's principal
//! submatrix M_A = H[A ∪ T] (positive definite, as every principal submatrix of H is) on its
//! own thread: that gives L_A, L_TA, and in its last block L'_A with L'_A·L'_Aᵀ = H_TT −
//! L_TA·L_TAᵀ. So C = L'_A·L'_Aᵀ + L'_B·L'_Bᵀ − H_TT, a dense matrix of the top's size, and
//! L_C its dense Cholesky factor. Each half's extra cost is its top's dense factor and product
//! (the skirt's top is 330 columns); the whole factor's flops are otherwise the same.
//!
//! Solves run the same way: each half's forward substitution on its own columns (its updates to
//! the top summed apart), then the top's dense solves, then each half's backward substitution.
//! One thread runs the same operations in the same order as two, so the result does not depend
//! on the thread count, to the bit.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, MatMut, MatRef, Par, Side};

use super::factor::analyse_upper;
use super::handoff::{wait_for, PanicGuard};

/// Tops larger than this many columns are not split off: their three dense factorisations (a
/// 1,500-column one is about 1.1 Gflop) would cost more than a garment's whole sparse factor.
pub const MAX_TOP: usize = 1500;

/// A factor of H in two halves and a dense top (see the module's doc), with an optional helper
/// thread for half B.
#[derive(Debug)]
pub struct SplitCholesky {
    n: usize,
    /// Global columns of the top, ascending.
    top: Vec<u32>,
    /// The top's upper entries of H: (row, column) in the top, and the entry's index in H's
    /// value array.
    top_entries: Vec<(u32, u32, u32)>,
    halves: [Arc<Mutex<Half>>; 2],
    helper: Option<Helper>,
    /// C, then its lower Cholesky factor L_C, column-major nT × nT.
    dense: Vec<f32>,
    dense_scratch: Workspace,
    /// The top's part of a solve.
    xt: Vec<f32>,
}

/// One half's principal submatrix M = H[own ∪ T], its factor, and a solve's local vector.
#[derive(Debug)]
struct Half {
    /// Global column of each local column: the half's own (0..m), then the top's.
    cols: Vec<u32>,
    m: usize,
    /// M's upper triangle (local indices) and, per entry, its index in H's value array.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    from: Vec<u32>,
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f32>,
    l: Vec<f32>,
    scratch: Workspace,
    /// The supernodes of M's factor.
    layout: Layout,
    /// L'·L'ᵀ, the top's block of M's factor times its transpose (lower part), nT × nT.
    product: Vec<f32>,
    /// L' itself, nT × nT.
    corner: Vec<f32>,
    /// A solve's local vector: the half's own columns, then the top's (updates, then values).
    x: Vec<f32>,
    tmp: Vec<f32>,
    /// Whether the last numeric factorisation failed (M not positive definite in single
    /// precision).
    failed: bool,
}

impl SplitCholesky {
    /// Splits the factor of the n×n matrix with upper-triangle pattern (`col_ptr`, `row_idx`)
    /// whose symbolic analysis is `symbolic`. `None` when its tree does not split into two
    /// balanced groups, the top is larger than [`MAX_TOP`], or a half's factor is not
    /// supernodal.
    pub fn new(
        col_ptr: &[usize],
        row_idx: &[usize],
        symbolic: &SymbolicCholesky<usize>,
    ) -> Option<Self> {
        let [a, b, top] = column_groups(symbolic)?;
        let n = col_ptr.len() - 1;
        let nt = top.len();
        if nt == 0 || nt > MAX_TOP {
            return None;
        }
        let mut local = vec![u32::MAX; n];
        for (i, &c) in top.iter().enumerate() {
            local[c as usize] = i as u32;
        }
        let mut top_entries = Vec::new();
        for (j, &c) in top.iter().enumerate() {
            for p in col_ptr[c as usize]..col_ptr[c as usize + 1] {
                let i = local[row_idx[p]];
                if i != u32::MAX {
                    top_entries.push((i, j as u32, p as u32));
                }
            }
        }
        let half_a = Half::new(col_ptr, row_idx, &a, &top)?;
        let half_b = Half::new(col_ptr, row_idx, &b, &top)?;
        let par = Par::Seq;
        let dense_scratch = Workspace(MemBuffer::new(
            faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f32>(
                nt,
                par,
                Default::default(),
            ),
        ));
        Some(SplitCholesky {
            n,
            top,
            top_entries,
            halves: [Arc::new(Mutex::new(half_a)), Arc::new(Mutex::new(half_b))],
            helper: None,
            dense: vec![0.0; nt * nt],
            dense_scratch,
            xt: vec![0.0; nt],
        })
    }

    /// Runs half B on a helper thread (`on`), or both halves on the caller's thread.
    pub fn use_helper(&mut self, on: bool) {
        self.helper = if on {
            Helper::spawn(Arc::clone(&self.halves[1]))
        } else {
            None
        };
    }

    /// Whether half B runs on a helper thread.
    pub fn has_helper(&self) -> bool {
        self.helper.is_some()
    }

    /// Columns in the top, and in each half.
    pub fn sizes(&self) -> [usize; 3] {
        [
            self.top.len(),
            lock(&self.halves[0]).m,
            lock(&self.halves[1]).m,
        ]
    }

    /// Factors H, whose upper triangle's values (in the pattern's order) are `values`, in
    /// single precision. Returns false when that fails (H, a half or the top's C is not
    /// positive definite in single precision).
    pub fn factor(&mut self, values: &[f64]) -> bool {
        run(&self.halves, &mut self.helper, FACTOR, |half| {
            half.load(values)
        });
        let (a, b) = (lock(&self.halves[0]), lock(&self.halves[1]));
        if a.failed || b.failed {
            return false;
        }
        // C = L'_A·L'_Aᵀ + L'_B·L'_Bᵀ − H_TT (lower part).
        let nt = self.top.len();
        for ((c, pa), pb) in self.dense.iter_mut().zip(&a.product).zip(&b.product) {
            *c = pa + pb;
        }
        for &(i, j, p) in &self.top_entries {
            // Upper entry (i ≤ j) of H_TT: stored at row j, column i of the lower part.
            self.dense[j as usize + i as usize * nt] -= values[p as usize] as f32;
        }
        drop((a, b));
        let c = MatMut::from_column_major_slice_mut(&mut self.dense, nt, nt);
        faer::linalg::cholesky::llt::factor::cholesky_in_place(
            c,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut self.dense_scratch.0),
            Default::default(),
        )
        .is_ok()
    }

    /// Solves L·Lᵀ·x = b in place with the last factor.
    ///
    /// # Panics
    /// When `x` is not of the matrix's dimension.
    pub fn solve(&mut self, x: &mut [f32]) {
        assert_eq!(x.len(), self.n, "right-hand side length");
        let nt = self.top.len();
        run(&self.halves, &mut self.helper, FORWARD, |half| {
            half.gather(x)
        });
        {
            let (a, b) = (lock(&self.halves[0]), lock(&self.halves[1]));
            for (i, (t, &c)) in self.xt.iter_mut().zip(&self.top).enumerate() {
                *t = x[c as usize] + a.x[a.m + i] + b.x[b.m + i];
            }
        }
        // L_C·L_Cᵀ·x_T = the top's right-hand side, less the halves' updates.
        let l = MatRef::from_column_major_slice(&self.dense, nt, nt);
        let mut xt = MatMut::from_column_major_slice_mut(&mut self.xt, nt, 1);
        solve_lower_triangular_in_place(l, xt.as_mut(), Par::Seq);
        solve_upper_triangular_in_place(l.transpose(), xt, Par::Seq);
        let xt = &self.xt;
        run(&self.halves, &mut self.helper, BACKWARD, |half| {
            half.set_top(xt)
        });
        for half in &self.halves {
            lock(half).scatter(x);
        }
        for (t, &c) in self.xt.iter().zip(&self.top) {
            x[c as usize] = *t;
        }
    }
}

/// Runs `prepare` on both halves, then `task`: on half B on the helper when there is one
/// (while this thread runs it on half A), else on half A and then half B here.
fn run(
    halves: &[Arc<Mutex<Half>>; 2],
    helper: &mut Option<Helper>,
    task: usize,
    prepare: impl Fn(&mut Half),
) {
    prepare(&mut lock(&halves[1]));
    if let Some(helper) = helper {
        helper.hand(task);
        {
            let mut a = lock(&halves[0]);
            prepare(&mut a);
            a.task(task);
        }
        helper.wait();
    } else {
        let mut a = lock(&halves[0]);
        prepare(&mut a);
        a.task(task);
        drop(a);
        lock(&halves[1]).task(task);
    }
}

/// The columns of `symbolic`'s groups A and B and of its top T, each ascending, or `None` when
/// its factor is not supernodal, the tree does not branch, or the lighter group would hold
/// less than a quarter of the factor's values.
///
/// A supernode's parent holds its first pattern row, and parents follow their children. The
/// top is the chain from the root down to the first supernode with two or more children (a
/// virtual root above several roots); those children's subtrees are dealt, heaviest first, to
/// the group with fewer values. A supernode's pattern rows are its ancestors', so no entry of
/// the matrix joins the two groups, and every column of the top follows theirs.
fn column_groups(symbolic: &SymbolicCholesky<usize>) -> Option<[Vec<u32>; 3]> {
    let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
        return None;
    };
    let s_count = sn.n_supernodes();
    let begin = sn.supernode_begin();
    let end = |s: usize| begin.get(s + 1).map_or(sn.nrows(), |&b| b);
    let (row_ptr, rows, val_ptr) = (sn.col_ptr_for_row_idx(), sn.row_idx(), sn.col_ptr_for_val());
    // Children of each supernode and each subtree's values (children come before parents, so
    // one ascending pass sums them).
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); s_count];
    let mut roots = Vec::new();
    let mut subtree: Vec<usize> = (0..s_count).map(|s| val_ptr[s + 1] - val_ptr[s]).collect();
    for s in 0..s_count {
        if row_ptr[s] < row_ptr[s + 1] {
            let p = begin.partition_point(|&b| b <= rows[row_ptr[s]]) - 1;
            children[p].push(s);
            subtree[p] += subtree[s];
        } else {
            roots.push(s);
        }
    }
    let mut top = Vec::new();
    let mut branches = roots;
    while let [s] = branches[..] {
        top.push(s);
        branches = children[s].clone();
    }
    if branches.len() < 2 {
        return None;
    }
    branches.sort_by_key(|&s| (std::cmp::Reverse(subtree[s]), s));
    let mut group = vec![2u8; s_count];
    let mut load = [0usize; 2];
    for head in branches {
        let g = usize::from(load[1] < load[0]);
        load[g] += subtree[head];
        let mut stack = vec![head];
        while let Some(s) = stack.pop() {
            group[s] = g as u8;
            stack.extend_from_slice(&children[s]);
        }
    }
    if load[0].min(load[1]) * 4 < val_ptr[s_count] {
        return None;
    }
    let columns = |g: u8| -> Vec<u32> {
        (0..s_count)
            .filter(|&s| group[s] == g)
            .flat_map(|s| begin[s] as u32..end(s) as u32)
            .collect()
    };
    Some([columns(0), columns(1), columns(2)])
}

/// faer's workspace (which has no `Debug`).
struct Workspace(MemBuffer);

impl std::fmt::Debug for Workspace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Workspace")
    }
}

fn lock(half: &Mutex<Half>) -> MutexGuard<'_, Half> {
    half.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Half {
    /// The half on columns `own` (ascending, all below the top's) and the top `top`.
    fn new(col_ptr: &[usize], row_idx: &[usize], own: &[u32], top: &[u32]) -> Option<Half> {
        let n = col_ptr.len() - 1;
        let cols: Vec<u32> = own.iter().chain(top).copied().collect();
        let mut local = vec![u32::MAX; n];
        for (i, &c) in cols.iter().enumerate() {
            local[c as usize] = i as u32;
        }
        let m = own.len();
        let (mut lcol, mut lrow, mut from) = (vec![0usize], Vec::new(), Vec::new());
        for (j, &c) in cols.iter().enumerate() {
            for p in col_ptr[c as usize]..col_ptr[c as usize + 1] {
                let i = local[row_idx[p]];
                if i == u32::MAX {
                    if j < m {
                        // An entry between the two halves: they are not independent.
                        return None;
                    }
                    continue;
                }
                // Rows ascend within a column, in the upper triangle.
                let start = *lcol.last()?;
                if i as usize > j || lrow.len() > start && lrow[lrow.len() - 1] >= i as usize {
                    return None;
                }
                lrow.push(i as usize);
                from.push(u32::try_from(p).ok()?);
            }
            lcol.push(lrow.len());
        }
        let dim = cols.len();
        let symbolic = analyse_upper(dim, &lcol, &lrow).ok()?;
        if symbolic.perm().is_some() {
            return None;
        }
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        let mut begin: Vec<u32> = sn.supernode_begin().iter().map(|&c| c as u32).collect();
        begin.push(dim as u32);
        let row_ptr: Vec<u32> = sn.col_ptr_for_row_idx().iter().map(|&p| p as u32).collect();
        let val_ptr = sn.col_ptr_for_val().to_vec();
        let rows: Vec<u32> = sn.row_idx().iter().map(|&r| r as u32).collect();
        let nodes = begin.partition_point(|&b| (b as usize) < m);
        let layout = Layout {
            begin,
            row_ptr,
            val_ptr,
            rows,
            nodes,
        };
        let max_pattern = (0..nodes)
            .map(|s| layout.node(s, m).rows.len())
            .max()
            .unwrap_or(0);
        let nt = top.len();
        let scratch = Workspace(MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f32>(Par::Seq, Default::default()),
        ));
        Some(Half {
            values: vec![0.0; from.len()],
            l: vec![0.0; symbolic.len_val()],
            scratch,
            cols,
            m,
            col_ptr: lcol,
            row_idx: lrow,
            from,
            symbolic,
            layout,
            product: vec![0.0; nt * nt],
            corner: vec![0.0; nt * nt],
            x: vec![0.0; dim],
            tmp: vec![0.0; max_pattern],
            failed: false,
        })
    }

    /// M's values from H's.
    fn load(&mut self, values: &[f64]) {
        for (v, &p) in self.values.iter_mut().zip(&self.from) {
            *v = values[p as usize] as f32;
        }
    }

    fn task(&mut self, task: usize) {
        match task {
            FACTOR => self.factor(),
            FORWARD => self.forward(),
            BACKWARD => self.backward(),
            _ => {}
        }
    }

    /// Factors M, then forms L'·L'ᵀ from the top's block of its factor.
    fn factor(&mut self) {
        let dim = self.cols.len();
        let pattern =
            SymbolicSparseColMatRef::new_checked(dim, dim, &self.col_ptr, None, &self.row_idx);
        self.failed = self
            .symbolic
            .factorize_numeric_llt(
                &mut self.l,
                SparseColMatRef::new(pattern, &self.values),
                Side::Upper,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.scratch.0),
                Default::default(),
            )
            .is_err();
        if self.failed {
            return;
        }
        let (m, nt) = (self.m, dim - self.m);
        self.corner.fill(0.0);
        for c in m..dim {
            let node = self.layout.node(self.layout.owner(c), m);
            let (w, j) = (node.c1 - node.c0, c - node.c0);
            let col = &self.l[node.values][j * node.ld..(j + 1) * node.ld];
            let out = &mut self.corner[(c - m) * nt..(c - m + 1) * nt];
            for i in j..w {
                out[node.c0 + i - m] = col[i];
            }
            for (&r, v) in node.rows.iter().zip(&col[w..]) {
                out[r as usize - m] = *v;
            }
        }
        let corner = MatRef::from_column_major_slice(&self.corner, nt, nt);
        matmul(
            MatMut::from_column_major_slice_mut(&mut self.product, nt, nt),
            BlockStructure::TriangularLower,
            Accum::Replace,
            corner,
            BlockStructure::TriangularLower,
            corner.transpose(),
            BlockStructure::TriangularUpper,
            1.0f32,
            Par::Seq,
        );
    }

    /// The half's own columns of `x` into the local vector, and zeros in the top's (where the
    /// forward substitution sums its updates).
    fn gather(&mut self, x: &[f32]) {
        for (v, &c) in self.x.iter_mut().zip(&self.cols[..self.m]) {
            *v = x[c as usize];
        }
        self.x[self.m..].fill(0.0);
    }

    /// The solved top into the local vector.
    fn set_top(&mut self, xt: &[f32]) {
        self.x[self.m..].copy_from_slice(xt);
    }

    /// The half's own columns of the local vector into `x`.
    fn scatter(&self, x: &mut [f32]) {
        for (v, &c) in self.x.iter().zip(&self.cols[..self.m]) {
            x[c as usize] = *v;
        }
    }

    /// Forward substitution over the half's own columns: they are solved, and the top's
    /// entries of the local vector receive minus their updates.
    fn forward(&mut self) {
        let Half {
            layout,
            l,
            x,
            tmp,
            m,
            ..
        } = self;
        for s in 0..layout.nodes {
            let Node {
                c0,
                c1,
                own,
                ld,
                rows,
                values,
            } = layout.node(s, *m);
            let (w, block) = (c1 - c0, &l[values]);
            for j in 0..own {
                let col = &block[j * ld..j * ld + w];
                let xj = x[c0 + j] / col[j];
                x[c0 + j] = xj;
                for (xi, lij) in x[c0 + j + 1..c1].iter_mut().zip(&col[j + 1..]) {
                    *xi -= lij * xj;
                }
            }
            let tmp = &mut tmp[..rows.len()];
            tmp.fill(0.0);
            for j in 0..own {
                let xj = x[c0 + j];
                for (t, lij) in tmp.iter_mut().zip(&block[j * ld + w..(j + 1) * ld]) {
                    *t += lij * xj;
                }
            }
            for (&r, t) in rows.iter().zip(tmp.iter()) {
                x[r as usize] -= t;
            }
        }
    }

    /// Backward substitution over the half's own columns, the top's already solved.
    fn backward(&mut self) {
        let Half {
            layout,
            l,
            x,
            tmp,
            m,
            ..
        } = self;
        for s in (0..layout.nodes).rev() {
            let Node {
                c0,
                c1,
                own,
                ld,
                rows,
                values,
            } = layout.node(s, *m);
            let (w, block) = (c1 - c0, &l[values]);
            let tmp = &mut tmp[..rows.len()];
            for (t, &r) in tmp.iter_mut().zip(rows) {
                *t = x[r as usize];
            }
            for j in 0..own {
                x[c0 + j] -= dot(&block[j * ld + w..(j + 1) * ld], tmp);
            }
            for j in (0..own).rev() {
                let col = &block[j * ld..j * ld + w];
                let below = dot(&col[j + 1..], &x[c0 + j + 1..c1]);
                x[c0 + j] = (x[c0 + j] - below) / col[j];
            }
        }
    }
}

/// The supernodes of a half's factor M = L·Lᵀ.
#[derive(Debug)]
struct Layout {
    /// First column of each supernode, plus the dimension.
    begin: Vec<u32>,
    /// Start of each supernode's pattern in `rows`.
    row_ptr: Vec<u32>,
    /// Start of each supernode's values in faer's value array: a (w + p) × w column-major block
    /// for w columns and p pattern rows, its top w × w part lower triangular.
    val_ptr: Vec<usize>,
    /// Pattern rows below each supernode's diagonal block (local columns), ascending.
    rows: Vec<u32>,
    /// Supernodes holding the half's own columns (the last may hold top columns too).
    nodes: usize,
}

/// One supernode of a [`Layout`].
struct Node<'a> {
    /// Its columns c0..c1, of which the first `own` are the half's own (below m).
    c0: usize,
    c1: usize,
    own: usize,
    /// The column stride of its values, w + p.
    ld: usize,
    /// Its pattern rows.
    rows: &'a [u32],
    /// Where its values lie in the factor's value array.
    values: std::ops::Range<usize>,
}

impl Layout {
    /// Supernode `s`, the half owning the columns below `m`.
    fn node(&self, s: usize, m: usize) -> Node<'_> {
        let (c0, c1) = (self.begin[s] as usize, self.begin[s + 1] as usize);
        let rows = &self.rows[self.row_ptr[s] as usize..self.row_ptr[s + 1] as usize];
        Node {
            c0,
            c1,
            own: c1.min(m).saturating_sub(c0),
            ld: c1 - c0 + rows.len(),
            rows,
            values: self.val_ptr[s]..self.val_ptr[s + 1],
        }
    }

    /// The supernode holding column `c`.
    fn owner(&self, c: usize) -> usize {
        self.begin.partition_point(|&b| b as usize <= c) - 1
    }
}

/// Σ a·b in eight independent lanes (so that the compiler may vectorise the sum).
#[inline(always)]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let (a8, b8) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (a8.remainder(), b8.remainder());
    for (x, y) in a8.zip(b8) {
        for k in 0..8 {
            lanes[k] += x[k] * y[k];
        }
    }
    let mut sum = lanes.iter().sum::<f32>();
    for (x, y) in ra.iter().zip(rb) {
        sum += x * y;
    }
    sum
}

const FACTOR: usize = 1;
const FORWARD: usize = 2;
const BACKWARD: usize = 3;
const QUIT: usize = 4;

/// How long the helper spins for its next task before it parks.
const SPIN: Duration = Duration::from_micros(300);

/// A thread that runs tasks on half B while the caller runs them on half A.
#[derive(Debug)]
struct Helper {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    handed: usize,
}

#[derive(Debug)]
struct Shared {
    half: Arc<Mutex<Half>>,
    task: AtomicUsize,
    go: AtomicUsize,
    done: AtomicUsize,
}

impl Helper {
    fn spawn(half: Arc<Mutex<Half>>) -> Option<Helper> {
        let shared = Arc::new(Shared {
            half,
            task: AtomicUsize::new(0),
            go: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
        });
        let serving = Arc::clone(&shared);
        let thread = std::thread::Builder::new()
            .name("scenebake-factor".into())
            .spawn(move || serving.serve())
            .ok()?;
        Some(Helper {
            shared,
            thread: Some(thread),
            handed: 0,
        })
    }

    fn hand(&mut self, task: usize) {
        self.handed += 1;
        self.shared.task.store(task, Ordering::Relaxed);
        self.shared.go.store(self.handed, Ordering::Release);
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
    }

    fn wait(&self) {
        wait_for(&self.shared.done, self.handed);
        if self.shared.done.load(Ordering::Acquire) == usize::MAX {
            panic!("the factor's helper thread panicked");
        }
    }
}

impl Drop for Helper {
    fn drop(&mut self) {
        self.hand(QUIT);
        if let Some(t) = self.thread.take() {
            // A panic on the helper was reported by `wait` already.
            let _ = t.join();
        }
    }
}

impl Shared {
    fn serve(&self) {
        let _guard = PanicGuard(&self.done);
        let mut seen = 0;
        loop {
            let since = Instant::now();
            let k = loop {
                let k = self.go.load(Ordering::Acquire);
                if k > seen {
                    break k;
                }
                if since.elapsed() < SPIN {
                    std::hint::spin_loop();
                } else {
                    std::thread::park_timeout(Duration::from_millis(50));
                }
            };
            seen = k;
            let task = self.task.load(Ordering::Relaxed);
            if task == QUIT {
                return;
            }
            lock(&self.half).task(task);
            self.done.store(k, Ordering::Release);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth::linalg::{fill_reducing_order, upper_from_triplets};

    type Triplets = Vec<(usize, usize, f64)>;

    /// A side×side grid with three unknowns per vertex (as Newton's Hessian has), coupled to its
    /// eight neighbours by 3×3 blocks, diagonally dominant, in nested-dissection order: its
    /// upper triangle as (row, col, value).
    fn grid(side: usize) -> (usize, Triplets) {
        let n = side * side;
        let id = |i: usize, j: usize| i * side + j;
        let mut pairs = Vec::new();
        for i in 0..side {
            for j in 0..side {
                for (di, dj) in [(1, 0), (0, 1), (1, 1)] {
                    if i + di < side && j + dj < side {
                        pairs.push((id(i, j), id(i + di, j + dj)));
                    }
                }
                if i + 1 < side && j >= 1 {
                    pairs.push((id(i, j), id(i + 1, j - 1)));
                }
            }
        }
        let order = fill_reducing_order(n, pairs.iter().copied()).unwrap();
        let mut new_of_old = vec![0; n];
        for (new, &old) in order.iter().enumerate() {
            new_of_old[old as usize] = new;
        }
        // Entries that vary from block to block, so that a misplaced value shows.
        let value = |a: usize, b: usize, k: usize| -0.3 - 0.1 * (((a * 7 + b * 13 + k) % 5) as f64);
        let mut t = Vec::new();
        for v in 0..n {
            for r in 0..3 {
                for c in r..3 {
                    let d = if r == c { 40.0 + (v % 3) as f64 } else { 0.5 };
                    t.push((3 * v + r, 3 * v + c, d));
                }
            }
        }
        for &(a, b) in &pairs {
            let (a, b) = (
                new_of_old[a].min(new_of_old[b]),
                new_of_old[a].max(new_of_old[b]),
            );
            for r in 0..3 {
                for c in 0..3 {
                    t.push((3 * a + r, 3 * b + c, value(a, b, 3 * r + c)));
                }
            }
        }
        (3 * n, t)
    }

    /// The grid's upper triangle (pattern and values) and faer's symbolic analysis of it.
    fn system(side: usize) -> (Vec<usize>, Vec<usize>, Vec<f64>, SymbolicCholesky<usize>) {
        let (dim, t) = grid(side);
        let upper = upper_from_triplets(dim, &t);
        let col_ptr = upper.indptr().into_raw_storage().to_vec();
        let row_idx = upper.indices().to_vec();
        let symbolic = analyse_upper(dim, &col_ptr, &row_idx).unwrap();
        (col_ptr, row_idx, upper.data().to_vec(), symbolic)
    }

    /// x solves the double-precision system A·x = b to the single-precision factor's accuracy:
    /// the two halves, the top's C and the solves' bookkeeping together make a factor of A.
    #[test]
    fn the_split_factor_solves_the_whole_system() {
        let (col_ptr, row_idx, values, symbolic) = system(40);
        let mut split = SplitCholesky::new(&col_ptr, &row_idx, &symbolic).expect("a split");
        let [top, a, b] = split.sizes();
        assert!(
            top > 0 && a > 0 && b > 0 && top * 10 < a + b,
            "sizes {top}, {a}, {b}"
        );
        assert!(split.factor(&values));
        let dim = col_ptr.len() - 1;
        let rhs: Vec<f32> = (0..dim)
            .map(|i| ((i * 37 % 101) as f32 - 50.0) / 7.0)
            .collect();
        let mut x = rhs.clone();
        split.solve(&mut x);
        let mut ax = vec![0.0f64; dim];
        for c in 0..dim {
            for p in col_ptr[c]..col_ptr[c + 1] {
                let r = row_idx[p];
                ax[r] += values[p] * f64::from(x[c]);
                if r != c {
                    ax[c] += values[p] * f64::from(x[r]);
                }
            }
        }
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|a| a * a).sum::<f64>().sqrt();
        let residual = norm(&mut ax.iter().zip(&rhs).map(|(a, b)| a - f64::from(*b)));
        let scale = norm(&mut rhs.iter().map(|&b| f64::from(b)));
        assert!(residual <= 1e-5 * scale, "residual {residual} of {scale}");
    }

    /// With the helper thread, factor and solves give the one-thread result to the bit, and the
    /// helper serves factor after factor.
    #[test]
    fn two_threads_factor_and_solve_as_one() {
        let (col_ptr, row_idx, values, symbolic) = system(40);
        let mut one = SplitCholesky::new(&col_ptr, &row_idx, &symbolic).unwrap();
        let mut two = SplitCholesky::new(&col_ptr, &row_idx, &symbolic).unwrap();
        two.use_helper(true);
        assert!(two.helper.is_some());
        for round in 0..3 {
            let scaled: Vec<f64> = values.iter().map(|v| v * (1.0 + round as f64)).collect();
            assert!(one.factor(&scaled) && two.factor(&scaled));
            let rhs: Vec<f32> = (0..col_ptr.len() - 1)
                .map(|i| (i % 13) as f32 - 6.0)
                .collect();
            let (mut x1, mut x2) = (rhs.clone(), rhs);
            one.solve(&mut x1);
            two.solve(&mut x2);
            assert!(x1 == x2, "round {round}: one thread and two differ");
        }
    }

    /// No entry of the matrix joins group A to group B (what lets their halves be factored
    /// apart), the top follows both, every column has one group, and the groups balance.
    #[test]
    fn the_groups_share_no_entry_and_balance() {
        let (col_ptr, row_idx, _, symbolic) = system(40);
        let [a, b, top] = column_groups(&symbolic).expect("the grid's tree splits");
        let dim = col_ptr.len() - 1;
        let mut group = vec![u8::MAX; dim];
        for (g, cols) in [&a, &b, &top].into_iter().enumerate() {
            for &c in cols {
                assert_eq!(group[c as usize], u8::MAX, "column {c} in two groups");
                group[c as usize] = g as u8;
            }
        }
        assert!(group.iter().all(|&g| g < 3), "every column has a group");
        for c in 0..dim {
            for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
                let pair = (group[r].min(group[c]), group[r].max(group[c]));
                assert_ne!(pair, (0, 1), "entry ({r}, {c}) joins A and B");
            }
        }
        let first_top = *top.first().unwrap();
        assert!(
            a.iter().chain(&b).all(|&c| c < first_top),
            "the top follows both groups"
        );
        let (na, nb) = (a.len(), b.len());
        assert!(
            na.min(nb) * 3 >= na.max(nb),
            "groups of {na} and {nb} columns"
        );
        assert!(top.len() * 10 < na + nb, "a top of {} columns", top.len());
    }
}
