//! Fast mass-spring (Liu, Bargteil, O'Brien and Kavan 2013): local/global minimisation of the
//! implicit Euler objective with a prefactored system matrix.
//!
//! With d_s = l_s (xa − xb)/|xa − xb| (local step, per spring) the objective becomes quadratic in
//! x, and its minimiser solves the global step A x = b(x), A = s M + h² L, b = s M y + h² J d
//! (+ anchor terms). The matrix is n×n (the same for x, y and z), constant during a bake, and
//! factored once.
//!
//! The global step is taken as a correction: r = b(x) − A·x is evaluated in f64 together with the
//! local step (r = −h²∇g(x), so its norm is also the convergence measure), Ã δ = r is solved with
//! the factor stored in f32 (half the memory traffic of the triangular sweeps, which dominate an
//! iteration), and x ← x + δ. With an exact factor this is the classic iteration x ← A⁻¹ b(x);
//! with Ã ≈ A the fixed point is unchanged (r = 0 there, whatever Ã is) and the error Ã makes in
//! δ shrinks with δ. Systems too ill-conditioned for an f32 factor keep an f64 one (see
//! [`FastSolver::new`]).

use glam::DVec3;
use sprs::CsMat;

use super::factor::{upper_from_triplets, Cholesky, Lanes4, Lanes4f};
use super::system::ReducedSystem;
use super::{StepSolver, StepStats};
use crate::error::Result;

/// The f32 factor is used only when it contracts the error of the linear correction iteration
/// x ← x + Ã⁻¹(b − A·x) by at least this factor per iteration (estimated at construction);
/// otherwise the solver keeps the f64 factor.
pub const MAX_SINGLE_RATE: f64 = 1e-3;

/// Values of the f32 factor below this fraction of its largest entry are dropped (see
/// [`Cholesky::to_f32_dropping`]).
pub const SINGLE_DROP_RELATIVE: f64 = 1e-8;

/// The factor of the global step's matrix A = s·M + h²·L that a [`FastSolver`] solves with.
#[derive(Debug, Clone)]
pub enum GlobalFactor {
    /// f32 values; corrections solved in f32 lanes ([`Cholesky::solve4f`]). The default.
    Single(Cholesky<f32>),
    /// f64 values, for systems whose f32 factor would slow the iteration down.
    Double(Cholesky<f64>),
}

impl GlobalFactor {
    /// Stored entries of the factor, diagonal included.
    pub fn nnz(&self) -> usize {
        match self {
            GlobalFactor::Single(f) => f.nnz(),
            GlobalFactor::Double(f) => f.nnz(),
        }
    }

    /// Size n of the factored matrix.
    pub fn dimension(&self) -> usize {
        match self {
            GlobalFactor::Single(f) => f.dimension(),
            GlobalFactor::Double(f) => f.dimension(),
        }
    }

    /// True for the f32 factor.
    pub fn is_single(&self) -> bool {
        matches!(self, GlobalFactor::Single(_))
    }

    /// Solves Ã·X = B in place for `DVec3` right-hand sides (see [`Cholesky::solve3`]).
    pub fn solve3(&self, b: &mut [DVec3]) {
        match self {
            GlobalFactor::Single(f) => f.solve3(b),
            GlobalFactor::Double(f) => f.solve3(b),
        }
    }

    /// Solves Ã·X = B in place for padded f64 right-hand sides (see [`Cholesky::solve4`]).
    pub fn solve4(&self, b: &mut [Lanes4]) {
        match self {
            GlobalFactor::Single(f) => f.solve4(b),
            GlobalFactor::Double(f) => f.solve4(b),
        }
    }
}

/// Local/global solver with a fixed iteration count per step.
#[derive(Debug)]
pub struct FastSolver {
    sys: ReducedSystem,
    factor: GlobalFactor,
    /// Estimated contraction per iteration of the linear correction iteration with `factor`
    /// (0 up to roundoff for an exact factor).
    factor_rate: f64,
    iterations: usize,
    /// Both ends of each free spring (solver indices), packed for the local step.
    ends: Vec<[u32; 2]>,
    /// [h²·k·l (N·s²), h²·k (kg)] per free spring.
    coef: Vec<[f64; 2]>,
    /// h²·k per anchor, kg.
    hk_anchor: Vec<f64>,
    /// s·m per particle, kg.
    sm: Vec<f64>,
    /// The current iterate's positions (m, solver order, lane 3 zero).
    pos: Vec<Lanes4>,
    /// The inertial target y (m, padded like `pos`).
    y: Vec<Lanes4>,
    /// The residual r = b(pos) − A·pos = −h²∇g(pos), kg·m; solved in place for the correction
    /// when the factor is f64.
    res: Vec<Lanes4>,
    /// The scaled residual, then the scaled correction, in f32 (f32 factor only).
    delta: Vec<Lanes4f>,
    /// Positions at the start of the step (m).
    x0: Vec<DVec3>,
    /// Relative residual after each iteration of the last step, when recording.
    history: Option<Vec<f64>>,
}

impl FastSolver {
    /// Builds the solver and factors s·M + h²·L. The factor is stored in f32 (small values
    /// dropped, [`SINGLE_DROP_RELATIVE`]) when the linear correction iteration with it contracts
    /// by [`MAX_SINGLE_RATE`] or better per iteration (estimated here by three iterations on a
    /// pseudo-random error), and in f64 otherwise.
    ///
    /// # Errors
    /// [`crate::Error::Factorisation`] when the matrix cannot be factored.
    pub fn new(sys: ReducedSystem, iterations: usize) -> Result<Self> {
        let upper = Self::matrix(&sys);
        let exact = Cholesky::new(&upper)?;
        let single = exact.to_f32_dropping(SINGLE_DROP_RELATIVE);
        let single = GlobalFactor::Single(single);
        let rate = correction_rate(&upper, &single);
        let (factor, factor_rate) = if rate <= MAX_SINGLE_RATE {
            (single, rate)
        } else {
            let exact = GlobalFactor::Double(exact);
            let rate = correction_rate(&upper, &exact);
            (exact, rate)
        };
        Ok(Self::with_factor(sys, iterations, factor, factor_rate))
    }

    /// Builds the solver around a given factor of its matrix ([`FastSolver::matrix`]), e.g. to
    /// compare precisions. `factor_rate` is what [`FastSolver::factor_rate`] reports.
    ///
    /// # Panics
    /// When the factor's dimension is not the system's.
    pub fn with_factor(
        sys: ReducedSystem,
        iterations: usize,
        factor: GlobalFactor,
        factor_rate: f64,
    ) -> Self {
        let n = sys.len();
        assert_eq!(factor.dimension(), n, "factor dimension");
        let h2 = sys.params.time_step.powi(2);
        let s = sys.inertia_scale();
        let sp = &sys.springs;
        FastSolver {
            ends: sp.a.iter().zip(&sp.b).map(|(&a, &b)| [a, b]).collect(),
            coef: sp
                .k
                .iter()
                .zip(&sp.rest)
                .map(|(k, l)| [h2 * k * l, h2 * k])
                .collect(),
            hk_anchor: sys.anchors.k.iter().map(|k| h2 * k).collect(),
            sm: sys.mass.iter().map(|m| s * m).collect(),
            pos: vec![Lanes4::default(); n],
            y: vec![Lanes4::default(); n],
            res: vec![Lanes4::default(); n],
            delta: vec![Lanes4f::default(); if factor.is_single() { n } else { 0 }],
            x0: vec![DVec3::ZERO; n],
            history: None,
            factor,
            factor_rate,
            iterations,
            sys,
        }
    }

    /// The upper triangle of the global step's matrix A = s·M + h²·L (kg), solver order.
    pub fn matrix(sys: &ReducedSystem) -> CsMat<f64> {
        let n = sys.len();
        let h2 = sys.params.time_step.powi(2);
        let s = sys.inertia_scale();
        let mut triplets: Vec<(usize, usize, f64)> =
            Vec::with_capacity(n + 3 * sys.springs.a.len() + sys.anchors.a.len());
        triplets.extend(sys.mass.iter().enumerate().map(|(i, m)| (i, i, s * m)));
        let sp = &sys.springs;
        for i in 0..sp.a.len() {
            let (a, b, w) = (sp.a[i] as usize, sp.b[i] as usize, h2 * sp.k[i]);
            triplets.push((a, a, w));
            triplets.push((b, b, w));
            triplets.push((a.min(b), a.max(b), -w));
        }
        let an = &sys.anchors;
        triplets
            .extend((0..an.a.len()).map(|i| (an.a[i] as usize, an.a[i] as usize, h2 * an.k[i])));
        upper_from_triplets(n, &triplets)
    }

    /// Records the relative residual after every iteration of each step, readable with
    /// [`FastSolver::history`].
    pub fn record_history(&mut self, on: bool) {
        self.history = on.then(Vec::new);
    }

    /// Relative residuals ‖∇g‖/force scale after each iteration of the last step.
    pub fn history(&self) -> Option<&[f64]> {
        self.history.as_deref()
    }

    /// The factor (for reports and benchmarks).
    pub fn factor(&self) -> &GlobalFactor {
        &self.factor
    }

    /// The estimated contraction per iteration of the linear correction iteration with the
    /// factor in use: how much the factor's rounding (and dropped values) slow an iteration down
    /// at worst (dimensionless; about 1e-16 for the f64 factor).
    pub fn factor_rate(&self) -> f64 {
        self.factor_rate
    }

    /// ‖∇g(pos)‖ / force scale from the residual in `res`: ‖r‖ / h² / force scale.
    fn relative_residual(&self) -> f64 {
        let h2 = self.sys.params.time_step.powi(2);
        let r2: f64 = self.res.iter().map(|r| r.xyz().length_squared()).sum();
        r2.sqrt() / h2 / self.sys.force_scale()
    }

    /// The local step at `pos` folded into the residual: res = b(pos) − A·pos, that is
    /// s·m·(y − x) per particle, h²k·(l/|d| − 1)·d per spring (d = xa − xb, added to a and
    /// subtracted from b) and per anchor (d = xa − pin).
    fn residual_step(&mut self) {
        let (x, r) = (&self.pos[..], &mut self.res[..]);
        for (((r, x), y), &sm) in r.iter_mut().zip(x).zip(&self.y).zip(&self.sm) {
            *r = (*y - *x) * sm;
        }
        for (&[a, b], &[hkl, hk]) in self.ends.iter().zip(&self.coef) {
            let (a, b) = (a as usize, b as usize);
            let d = x[a] - x[b];
            let len2 = d.0[0] * d.0[0] + d.0[1] * d.0[1] + d.0[2] * d.0[2];
            if len2 > 0.0 {
                let f = d * (hkl / len2.sqrt() - hk);
                r[a] += f;
                r[b] -= f;
            }
        }
        let an = &self.sys.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            let d = x[a].xyz() - an.at[i];
            let len = d.length();
            if len > 0.0 {
                let hk = self.hk_anchor[i];
                r[a] += Lanes4::from_vec3(d * (hk * an.rest[i] / len - hk));
            }
        }
    }

    /// The global step as a correction: pos ← pos + Ã⁻¹·res.
    fn global_step(&mut self) {
        match &self.factor {
            GlobalFactor::Double(f) => {
                f.solve4(&mut self.res);
                for (p, d) in self.pos.iter_mut().zip(&self.res) {
                    *p += *d;
                }
            }
            GlobalFactor::Single(f) => {
                // Scale each lane (x, y, z: independent right-hand sides) by a power of two that
                // puts its largest component near 1 (exact in any precision), so that the f32
                // correction neither overflows nor goes subnormal (a roundoff-level lane, such as
                // z in a symmetric scene, would); components 2⁻⁹⁰ below the lane's largest are
                // flushed to zero for the same reason.
                let largest = self.res.iter().fold([0.0f64; 4], |m, r| {
                    std::array::from_fn(|k| m[k].max(r.0[k].abs()))
                });
                if largest == [0.0; 4] {
                    return; // already stationary
                }
                let scale = Lanes4(largest.map(|m| {
                    if m > 0.0 && m.is_finite() {
                        2f64.powi(-m.log2().round() as i32)
                    } else {
                        1.0 // zero, or non-finite: let it through for the divergence check
                    }
                }));
                for (d, r) in self.delta.iter_mut().zip(&self.res) {
                    *d = Lanes4f(std::array::from_fn(|k| {
                        let v = r.0[k] * scale.0[k];
                        if v.abs() < 1e-27 {
                            0.0
                        } else {
                            v as f32
                        }
                    }));
                }
                f.solve4f(&mut self.delta);
                let unscale = Lanes4(scale.0.map(|s| 1.0 / s));
                for (p, d) in self.pos.iter_mut().zip(&self.delta) {
                    *p += d.to_lanes4() * unscale;
                }
            }
        }
    }
}

/// Estimated contraction per iteration of x ← x + Ã⁻¹(b − A·x) (A's upper triangle `upper`,
/// Ã from `factor`): the error e ← (I − Ã⁻¹A)·e shrinks by ‖e₃‖/‖e₂‖ in the third of three
/// iterations from a pseudo-random e₀ (power iteration towards the worst case).
pub fn correction_rate(upper: &CsMat<f64>, factor: &GlobalFactor) -> f64 {
    let n = upper.cols();
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut e: Vec<Lanes4> = (0..n)
        .map(|_| Lanes4([random(), random(), random(), 0.0]))
        .collect();
    let norm = |v: &[Lanes4]| {
        v.iter()
            .map(|x| x.xyz().length_squared())
            .sum::<f64>()
            .sqrt()
    };
    let mut before = norm(&e);
    let mut rate = 0.0;
    let mut ae = vec![Lanes4::default(); n];
    for _ in 0..3 {
        symmetric_product(upper, &e, &mut ae);
        factor.solve4(&mut ae);
        for (e, z) in e.iter_mut().zip(&ae) {
            *e = *e - *z;
        }
        let after = norm(&e);
        if before == 0.0 {
            return 0.0;
        }
        rate = after / before;
        before = after;
    }
    rate
}

/// out = A·v for the symmetric A whose upper triangle is `upper` (compressed columns).
pub fn symmetric_product(upper: &CsMat<f64>, v: &[Lanes4], out: &mut [Lanes4]) {
    out.fill(Lanes4::default());
    for (c, col) in upper.outer_iterator().enumerate() {
        for (r, &a) in col.iter() {
            out[r] += v[c] * a;
            if r != c {
                out[c] += v[r] * a;
            }
        }
    }
}

impl StepSolver for FastSolver {
    fn system(&self) -> &ReducedSystem {
        &self.sys
    }

    fn step(&mut self, x: &mut [DVec3], v: &mut [DVec3]) -> Result<StepStats> {
        let h = self.sys.params.time_step;
        self.x0.copy_from_slice(x);
        // y goes through `x` (its DVec3 scratch) into the padded layout; the first iterate is y.
        self.sys.predict(&self.x0, v, x);
        for ((y, p), x) in self.y.iter_mut().zip(&mut self.pos).zip(x.iter()) {
            *y = Lanes4::from_vec3(*x);
            *p = *y;
        }
        if let Some(h) = &mut self.history {
            h.clear();
        }
        for k in 0..self.iterations {
            self.residual_step();
            if k > 0 && self.history.is_some() {
                let r = self.relative_residual();
                if let Some(h) = &mut self.history {
                    h.push(r);
                }
            }
            self.global_step();
            // `pos` is the new iterate here (y and x0 unchanged since the start of the step).
        }
        // One more residual measures how far the last iterate is from stationary.
        self.residual_step();
        let residual = self.relative_residual();
        if let Some(h) = &mut self.history {
            h.push(residual);
        }
        for (x, p) in x.iter_mut().zip(&self.pos) {
            *x = p.xyz();
        }
        for ((v, x), x0) in v.iter_mut().zip(x.iter()).zip(&self.x0) {
            *v = (*x - *x0) / h;
        }
        Ok(StepStats {
            iterations: self.iterations,
            residual,
            converged: true,
        })
    }
}
