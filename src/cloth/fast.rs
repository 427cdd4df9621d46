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
//!
//! With colliders (see [`reaction`]) the residual of a particle resting on one gets the collider's
//! reaction and Coulomb friction, the held directions are filtered out of the correction (solved
//! then by conjugate gradients preconditioned with Ã), and particles that entered a collider are
//! moved back out after each correction.

use super::term::{bending, Term};
use glam::DVec3;
use sprs::CsMat;

use super::collide::reaction::{self, Hold};
use super::collide::{Collider, Colliders, SurfacePoint};
#[cfg(target_arch = "x86_64")]
use super::law::springs_avx2;
use super::law::{spring_response, springs_scalar, JamRamps, TOE_STRAIN};
use super::linalg::cg::{self, Stop};
use super::linalg::{upper_from_triplets, Cholesky, Lanes4, Lanes4f};
use super::system::{FreeBends, ReducedSystem, PINNED};
use super::{StepSolver, StepStats};
use crate::error::{Error, Result};

/// The f32 factor is used only when it contracts the error of the linear correction iteration
/// x ← x + Ã⁻¹(b − A·x) by at least this factor per iteration (estimated at construction);
/// otherwise the solver keeps the f64 factor.
pub const MAX_SINGLE_RATE: f64 = 1e-3;

/// Drop tolerances tried for the f32 factor, in order: values below this fraction of its
/// largest entry are dropped (see [`Cholesky::to_f32_dropping`]); the first whose factor passes
/// [`MAX_SINGLE_RATE`] is kept. The lab grids' factors lose 37 % (1e-6) or 27 % (1e-8) of their
/// entries this way.
pub const SINGLE_DROP_RELATIVE: [f64; 2] = [1e-6, 1e-8];

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

/// Local/global solver: iterates until the residual falls below a tolerance, or a cap.
#[derive(Debug)]
pub struct FastSolver {
    sys: ReducedSystem,
    /// Stop a step when ρ = ‖∇g‖ / force scale ≤ this (0: always run the cap).
    tolerance: f64,
    factor: GlobalFactor,
    /// Estimated contraction per iteration of the linear correction iteration with `factor`
    /// (0 up to roundoff for an exact factor).
    factor_rate: f64,
    iterations: usize,
    /// Both ends of each free spring (solver indices), packed for the local step.
    ends: Vec<[u32; 2]>,
    /// h²·k·l per free spring, kg·m.
    hkl: Vec<f64>,
    /// h²·k per free spring, kg.
    hk: Vec<f64>,
    /// kc/k per free spring: the local step's pull scaled for a compressed spring, so that the
    /// residual is the exact −h²∇g whatever the compression stiffness (1 for the labs' springs).
    soft: Vec<f64>,
    /// Where each free spring's jamming ramp starts and how it rises (see [`JamRamps`]).
    jam: JamRamps,
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
    /// The per-lane powers of two `res` is scaled by before rounding into `delta`, 1/(kg·m).
    scale: [f64; 4],
    /// Positions at the start of the step (m).
    x0: Vec<DVec3>,
    /// Relative residual after each iteration of the last step, when recording.
    history: Option<Vec<f64>>,
    /// Colliders, when any (see [`contact`]).
    colliders: Option<Colliders>,
    /// The collider surface each particle rests on at `pos` (see [`reaction::resting_on`]), kept
    /// up to date wherever `pos` changes (allocated with the colliders).
    resting: Vec<Option<SurfacePoint>>,
    /// Particles held by a collider in the global step, with how.
    held: Vec<(u32, Hold)>,
    /// Work vectors of the held global step: residual, preconditioned residual, search
    /// direction, its product, correction (allocated with the colliders).
    cg: [Vec<Lanes4>; 5],
    /// The f32 lane scales of the held global step's preconditioner (see [`solve_single`]).
    cg_scale: [f64; 4],
}

impl FastSolver {
    /// Builds the solver and factors s·M + h²·L. The factor is stored in f32 (small values
    /// dropped, [`SINGLE_DROP_RELATIVE`]) when the linear correction iteration with it contracts
    /// by [`MAX_SINGLE_RATE`] or better per iteration (estimated here by three iterations on a
    /// pseudo-random error, [`correction_rate`]), and in f64 otherwise.
    ///
    /// # Errors
    /// [`crate::Error::Factorisation`] when the matrix cannot be factored;
    /// [`crate::Error::Value`] for a system with a triangle membrane, which the local steps do
    /// not model (a job refuses the pair first, naming its options).
    pub fn new(sys: ReducedSystem, iterations: usize) -> Result<Self> {
        if !sys.membrane.is_empty() {
            return Err(crate::Error::value(
                "triangles: the fast solver models edge springs only",
            ));
        }
        let upper = Self::matrix(&sys);
        let exact = Cholesky::new(&upper)?;
        for drop in SINGLE_DROP_RELATIVE {
            let single = GlobalFactor::Single(exact.to_f32_dropping(drop));
            let rate = correction_rate(&upper, &single);
            if rate <= MAX_SINGLE_RATE {
                return Ok(Self::with_factor(sys, iterations, single, rate));
            }
        }
        let exact = GlobalFactor::Double(exact);
        let rate = correction_rate(&upper, &exact);
        Ok(Self::with_factor(sys, iterations, exact, rate))
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
        let sp = &sys.springs;
        assert!(
            sp.a.iter().chain(&sp.b).all(|&i| (i as usize) < n),
            "spring ends index the free particles"
        );
        let h2 = sys.params.time_step.powi(2);
        let s = sys.inertia_scale();
        FastSolver {
            ends: sp.a.iter().zip(&sp.b).map(|(&a, &b)| [a, b]).collect(),
            hkl: sp.k.iter().zip(&sp.rest).map(|(k, l)| h2 * k * l).collect(),
            hk: sp.k.iter().map(|k| h2 * k).collect(),
            soft: sp.kc.iter().zip(&sp.k).map(|(kc, k)| kc / k).collect(),
            jam: JamRamps::new(&sp.rest, &sp.k, &sp.kc, sys.jam_strain, TOE_STRAIN),
            hk_anchor: sys.anchors.k.iter().map(|k| h2 * k).collect(),
            sm: sys.mass.iter().map(|m| s * m).collect(),
            pos: vec![Lanes4::default(); n],
            y: vec![Lanes4::default(); n],
            res: vec![Lanes4::default(); n],
            delta: vec![Lanes4f::default(); if factor.is_single() { n } else { 0 }],
            x0: vec![DVec3::ZERO; n],
            scale: [1.0; 4],
            history: None,
            colliders: None,
            resting: Vec::new(),
            held: Vec::new(),
            cg: Default::default(),
            cg_scale: [1.0; 4],
            factor,
            factor_rate,
            iterations,
            tolerance: 0.0,
            sys,
        }
    }

    /// Stops each step as soon as ρ = ‖∇g‖ / force scale ≤ `tolerance` (with the iteration
    /// count given at construction as the cap); steps that end above it report
    /// `converged: false`. Without this every step runs the cap.
    pub fn with_tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
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
        // Bending is quadratic: its Hessian h²·Σ w wᵀ is exact and constant.
        let b = &sys.bends;
        for (v, w) in b.v.iter().zip(&b.w) {
            for i in 0..4 {
                for j in i..4 {
                    if v[i] != PINNED && v[j] != PINNED {
                        let (r, c) = (v[i].min(v[j]) as usize, v[i].max(v[j]) as usize);
                        let value = h2 * bending::coupling(w[i], w[j]);
                        triplets.push((r, c, if i == j || r != c { value } else { 2.0 * value }));
                    }
                }
            }
        }
        upper_from_triplets(n, &triplets)
    }

    /// Adds colliders (see [`reaction`]).
    pub fn with_colliders(mut self, colliders: Option<Colliders>) -> Self {
        let n = if colliders.is_some() {
            self.sys.len()
        } else {
            0
        };
        self.cg = std::array::from_fn(|_| vec![Lanes4::default(); n]);
        self.resting = vec![None; n];
        self.colliders = colliders;
        self
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
        let mut done = 0;
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2; `pos` and `res` have the system's length and every
            // spring end is below it (asserted in `with_factor`).
            done = unsafe {
                springs_avx2(x, r, &self.ends, &self.hkl, &self.hk, &self.soft, &self.jam)
            };
        }
        let springs = (&self.ends[..], &self.hkl[..], &self.hk[..]);
        springs_scalar(x, r, springs, &self.soft, &self.jam, done);
        let h2 = self.sys.params.time_step.powi(2);
        let an = &self.sys.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            let d = x[a].xyz() - an.at[i];
            let len = d.length();
            if len > 0.0 {
                let (f, _) =
                    spring_response(len, an.rest[i], an.k[i], an.kc[i], self.sys.jam_strain);
                r[a] -= Lanes4::from_vec3(d * (h2 * f / len));
            }
        }
        bend_product(&self.sys.bends, -h2, x, true, r);
    }

    /// The first iterate: the inertial target y, except for particles resting on a collider at
    /// the start of the step, which start where they are (so friction sees their whole slip).
    fn initial_guess(&mut self) {
        let Some(colliders) = &self.colliders else {
            self.pos.copy_from_slice(&self.y);
            return;
        };
        for (((p, y), x0), resting) in self
            .pos
            .iter_mut()
            .zip(&self.y)
            .zip(&self.x0)
            .zip(&mut self.resting)
        {
            *resting = reaction::resting_on(colliders, *x0, *x0);
            *p = if resting.is_some() {
                Lanes4::from_vec3(*x0)
            } else {
                *resting = reaction::resting_on(colliders, y.xyz(), *x0);
                *y
            };
        }
    }

    /// Applies the colliders' reaction to the residual of every resting particle and lists the
    /// held ones; returns how many particles rest on a collider.
    fn contact_reactions(&mut self) -> usize {
        self.held.clear();
        let Some(colliders) = &self.colliders else {
            return 0;
        };
        let mut resting = 0;
        for (i, (r, surface)) in self.res.iter_mut().zip(&self.resting).enumerate() {
            if let Some(surface) = surface {
                resting += 1;
                let mut force = r.xyz();
                let hold = reaction::contact_reaction(colliders.friction, surface, &mut force);
                if hold != Hold::Free {
                    *r = Lanes4::from_vec3(force);
                    self.held.push((i as u32, hold));
                }
            }
        }
        resting
    }

    /// Moves particles that entered a collider back out along its normal.
    fn push_out(&mut self) {
        let Some(colliders) = &self.colliders else {
            return;
        };
        for ((p, x0), resting) in self.pos.iter_mut().zip(&self.x0).zip(&mut self.resting) {
            let mut q = p.xyz();
            *resting = reaction::push_out(colliders, &mut q, *x0);
            if q != p.xyz() {
                *p = Lanes4::from_vec3(q);
            }
        }
    }

    /// The global step while particles are held: pos ← pos + δ with δ the solution of A·δ = res
    /// on the subspace the colliders leave free (held components zero), by conjugate gradients
    /// preconditioned with Ã⁻¹ (Baraff and Witkin's filtered solve).
    fn held_global_step(&mut self) {
        let held = &self.held;
        let filter = |v: &mut [Lanes4]| {
            for &(i, hold) in held {
                let i = i as usize;
                v[i] = Lanes4::from_vec3(hold.filter(v[i].xyz()));
            }
        };
        let (factor, scale, single) = (&self.factor, &mut self.cg_scale, &mut self.delta);
        // z = S·Ã⁻¹·r, in the factor's own precision.
        let precondition = |r: &[Lanes4], z: &mut [Lanes4]| {
            match factor {
                GlobalFactor::Double(f) => {
                    z.copy_from_slice(r);
                    f.solve4(z);
                }
                GlobalFactor::Single(f) => {
                    let unscale = solve_single(f, r, scale, single);
                    for (z, d) in z.iter_mut().zip(single.iter()) {
                        *z = d.to_lanes4() * unscale;
                    }
                }
            }
            filter(z);
        };
        let [res, z, p, q, delta] = &mut self.cg;
        res.copy_from_slice(&self.res);
        filter(res);
        let (ends, hk, sm) = (&self.ends, &self.hk, &self.sm);
        let anchors = (&self.sys.anchors.a[..], &self.hk_anchor[..]);
        let bends = (&self.sys.bends, self.sys.params.time_step.powi(2));
        // q = S·A·p.
        let product = |p: &[Lanes4], q: &mut [Lanes4]| {
            apply_matrix(ends, hk, sm, anchors, bends, p, q);
            filter(q);
        };
        let work = cg::Work { r: res, z, p, q };
        let system = &mut cg::Closures(product, precondition);
        cg::solve(
            delta,
            work,
            system,
            Stop::Reduction(HELD_CG_REDUCTION),
            HELD_CG_ITERATIONS,
        );
        for (x, d) in self.pos.iter_mut().zip(delta.iter()) {
            *x += *d;
        }
    }

    /// The global step as a correction: pos ← pos + Ã⁻¹·res.
    fn global_step(&mut self) {
        if !self.held.is_empty() {
            self.held_global_step();
            return;
        }
        match &self.factor {
            GlobalFactor::Double(f) => {
                f.solve4(&mut self.res);
                for (p, d) in self.pos.iter_mut().zip(&self.res) {
                    *p += *d;
                }
            }
            GlobalFactor::Single(f) => {
                let unscale = solve_single(f, &self.res, &mut self.scale, &mut self.delta);
                for (p, d) in self.pos.iter_mut().zip(&self.delta) {
                    *p += d.to_lanes4() * unscale;
                }
            }
        }
    }
}

/// Solves Ã·δ = `rhs` with the f32 factor `f`: `delta` gets δ scaled per lane, and the returned
/// lanes unscale it (δ = delta · unscale).
///
/// Each lane (x, y, z: independent right-hand sides) is scaled by a power of two (exact in any
/// precision) that puts its largest component near 1, so that the f32 correction neither
/// overflows nor goes subnormal (a roundoff-level lane, such as z in a symmetric scene, would).
/// The scale is the previous call's (`scale`, updated), redone when the right-hand side has moved
/// too far from it.
fn solve_single(
    f: &Cholesky<f32>,
    rhs: &[Lanes4],
    scale: &mut [f64; 4],
    delta: &mut [Lanes4f],
) -> Lanes4 {
    let mut used = *scale;
    for pass in 0..3 {
        let largest = to_f32_scaled(rhs, used, delta);
        let (next, redo) = rescale(used, largest);
        *scale = next;
        if !redo || pass == 2 {
            break;
        }
        used = next;
    }
    f.solve4f(delta);
    Lanes4(used.map(|s| 1.0 / s))
}

/// Local/global iterations a step with colliders takes at least, whatever its residual: the
/// particles pushed out of colliders and the friction holds are only settled after several.
pub const MIN_CONTACT_ITERATIONS: usize = 10;

/// Conjugate-gradient iterations of a held global step at most.
const HELD_CG_ITERATIONS: usize = 10;

/// The held global step stops when the preconditioned residual norm has fallen by this factor
/// (about four iterations on a tablecloth with 2,000 particles on the table). The outer
/// iterations refine further; 0.1 costs half as much again for the same drape, and stopping
/// after two iterations whatever the residual lets smooth modes of stiff cloth run away.
const HELD_CG_REDUCTION: f64 = 0.3;

/// out = A·p with A = s·M + h²·L: `sm` on the diagonal, h²k (`hk`) per spring between its
/// `ends`, and h²k per anchor on its free end.
#[allow(clippy::too_many_arguments)]
fn apply_matrix(
    ends: &[[u32; 2]],
    hk: &[f64],
    sm: &[f64],
    (anchors, hk_anchor): (&[u32], &[f64]),
    (bends, h2): (&FreeBends, f64),
    p: &[Lanes4],
    out: &mut [Lanes4],
) {
    for ((o, p), sm) in out.iter_mut().zip(p).zip(sm) {
        *o = *p * *sm;
    }
    for (&[a, b], &hk) in ends.iter().zip(hk) {
        let (a, b) = (a as usize, b as usize);
        let f = (p[a] - p[b]) * hk;
        out[a] += f;
        out[b] -= f;
    }
    for (&a, &hk) in anchors.iter().zip(hk_anchor) {
        out[a as usize] += p[a as usize] * hk;
    }
    bend_product(bends, h2, p, false, out);
}

/// out += c·wᵢ·(Σⱼ wⱼ pⱼ [+ fixed]) for every free vertex i of every bending stencil: with
/// `c = h²` and no fixed part the bending block of h²·A·p, with `c = −h²` and the fixed part the
/// bending forces' share of the residual.
fn bend_product(bends: &FreeBends, c: f64, p: &[Lanes4], fixed: bool, out: &mut [Lanes4]) {
    for s in 0..bends.len() {
        let (v, w) = (&bends.v[s], &bends.w[s]);
        let mut sum = if fixed { bends.fixed(s) } else { DVec3::ZERO };
        for i in 0..4 {
            if v[i] != PINNED {
                sum += p[v[i] as usize].xyz() * w[i];
            }
        }
        for i in 0..4 {
            if v[i] != PINNED {
                out[v[i] as usize] += Lanes4::from_vec3(sum * (c * w[i]));
            }
        }
    }
}

/// delta = res·scale per lane, rounded to f32 with components below 1e-27 flushed to zero;
/// returns the largest |res·scale| per lane.
fn to_f32_scaled(res: &[Lanes4], scale: [f64; 4], delta: &mut [Lanes4f]) -> [f64; 4] {
    let mut largest = [0.0f64; 4];
    for (d, r) in delta.iter_mut().zip(res) {
        let v: [f64; 4] = std::array::from_fn(|k| r.0[k] * scale[k]);
        largest = std::array::from_fn(|k| largest[k].max(v[k].abs()));
        *d = Lanes4f(v.map(|v| if v.abs() < 1e-27 { 0.0 } else { v as f32 }));
    }
    largest
}

/// The scale for the next conversion given the largest scaled component per lane, and whether
/// the conversion just made must be redone: some lane's largest component is outside
/// [2⁻²⁰, 2²⁰] (a lane of zeros is fine, a non-finite one is let through at scale 1).
fn rescale(scale: [f64; 4], largest: [f64; 4]) -> ([f64; 4], bool) {
    let mut redo = false;
    let next = std::array::from_fn(|k| {
        let m = largest[k];
        if m == 0.0 {
            scale[k]
        } else if !m.is_finite() {
            redo |= scale[k] != 1.0;
            1.0
        } else {
            redo |= !(2f64.powi(-20)..=2f64.powi(20)).contains(&m);
            let unscaled = m / scale[k];
            if unscaled > 0.0 && unscaled.is_finite() {
                2f64.powi(-unscaled.log2().round() as i32)
            } else {
                1.0
            }
        }
    });
    (next, redo)
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
            *e -= *z;
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

    fn drive(&mut self, pins: &[DVec3], shapes: Vec<(usize, Collider)>) -> Result<()> {
        if !shapes.is_empty() {
            return Err(Error::value(
                "fast: a moving body collider needs the Newton solver",
            ));
        }
        self.sys.move_pins(pins);
        Ok(())
    }

    fn step(&mut self, x: &mut [DVec3], v: &mut [DVec3]) -> Result<StepStats> {
        let h = self.sys.params.time_step;
        self.sys.orient_bending(x);
        self.x0.copy_from_slice(x);
        // y goes through `x` (its DVec3 scratch) into the padded layout; the first iterate is y.
        self.sys.predict(&self.x0, v, x);
        for (y, x) in self.y.iter_mut().zip(x.iter()) {
            *y = Lanes4::from_vec3(*x);
        }
        self.initial_guess();
        if let Some(h) = &mut self.history {
            h.clear();
        }
        let mut iterations = 0;
        for k in 0..self.iterations {
            self.residual_step();
            self.contact_reactions();
            if self.tolerance > 0.0 || (k > 0 && self.history.is_some()) {
                let r = self.relative_residual();
                if k > 0 {
                    if let Some(h) = &mut self.history {
                        h.push(r);
                    }
                }
                // With colliders the contact set and the friction holds settle over the
                // iterations too: never stop before MIN_CONTACT_ITERATIONS.
                let settled = self.colliders.is_none() || k >= MIN_CONTACT_ITERATIONS;
                if r <= self.tolerance && settled {
                    break;
                }
            }
            self.global_step();
            self.push_out();
            iterations += 1;
        }
        // One more residual measures how far the last iterate is from stationary.
        self.residual_step();
        let contacts = self.contact_reactions();
        let residual = self.relative_residual();
        if let Some(h) = &mut self.history {
            h.push(residual);
        }
        if !residual.is_finite() {
            return Err(crate::error::Error::Diverged {
                frame: 0,
                reason: "non-finite residual in the local/global iteration".into(),
                advice: Vec::new(),
            });
        }
        for (x, p) in x.iter_mut().zip(&self.pos) {
            *x = p.xyz();
        }
        for ((v, x), x0) in v.iter_mut().zip(x.iter()).zip(&self.x0) {
            *v = (*x - *x0) / h;
        }
        Ok(StepStats {
            iterations,
            residual,
            converged: residual <= self.tolerance || self.tolerance == 0.0,
            contacts,
            self_contacts: 0,
            steps: 1,
            pinched: 0,
            pinched_pairs: 0,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth::preset::{defaults, lab_cloth};
    use crate::cloth::StepParams;

    /// The lab cloth at `resolution` cells per side, pinned at two corners, with stiffness `k`
    /// (N/m), mass `m` (kg per particle) and time step `h` (s).
    fn lab(resolution: u32, k: f64, m: f64, h: f64) -> (ReducedSystem, Vec<DVec3>) {
        lab_pinned(resolution, k, m, h, true)
    }

    fn lab_pinned(
        resolution: u32,
        k: f64,
        m: f64,
        h: f64,
        pins: bool,
    ) -> (ReducedSystem, Vec<DVec3>) {
        let params = StepParams {
            time_step: h,
            damping: defaults::DAMPING,
            gravity: DVec3::from_array(defaults::GRAVITY),
        };
        lab_cloth(resolution, k).system(m, pins, params)
    }

    /// A moving state: `frames` steps of a converged solve from rest.
    fn moving(sys: &ReducedSystem, x: &[DVec3], frames: usize) -> (Vec<DVec3>, Vec<DVec3>) {
        let mut solver = FastSolver::new(sys.clone(), 30).unwrap();
        let (mut x, mut v) = (x.to_vec(), vec![DVec3::ZERO; x.len()]);
        for _ in 0..frames {
            solver.step(&mut x, &mut v).unwrap();
        }
        (x, v)
    }

    fn exact_solver(sys: &ReducedSystem, iterations: usize) -> FastSolver {
        let f = Cholesky::new(&FastSolver::matrix(sys)).unwrap();
        FastSolver::with_factor(sys.clone(), iterations, GlobalFactor::Double(f), 0.0)
    }

    /// The f32-factor iteration converges to the f64 one's fixed point (the implicit Euler step),
    /// not just near it: after enough iterations the two steps agree to 1e-9 of the step's
    /// displacement, and both residuals reach the f64 roundoff floor.
    #[test]
    fn single_precision_correction_has_the_double_fixed_point() {
        // A stiffer lab cloth (h²k/m ≈ 0.28) so the iteration has work to do, 41×41 particles.
        let (sys, start) = lab(40, 1e3, 1.0, 1.0 / 60.0);
        let (x0, v0) = moving(&sys, &start, 20);
        let mut single = FastSolver::new(sys.clone(), 200).unwrap();
        assert!(
            single.factor().is_single(),
            "the lab cloth uses the f32 factor"
        );
        assert!(single.factor_rate() < 1e-4, "rate {}", single.factor_rate());
        let mut double = exact_solver(&sys, 200);
        single.record_history(true);
        double.record_history(true);
        let (mut xs, mut vs) = (x0.clone(), v0.clone());
        let (mut xd, mut vd) = (x0.clone(), v0.clone());
        let rs = single.step(&mut xs, &mut vs).unwrap().residual;
        let rd = double.step(&mut xd, &mut vd).unwrap().residual;
        let moved = xd
            .iter()
            .zip(&x0)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        let diff = xs
            .iter()
            .zip(&xd)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max);
        assert!(moved > 1e-3, "the step moves the cloth ({moved} m)");
        assert!(
            diff <= 1e-9 * moved,
            "single vs double: {diff:e} m of {moved:e} m"
        );
        assert!(
            rs < 1e-12 && rd < 1e-12,
            "residuals {rs:e} (f32) {rd:e} (f64)"
        );
        // Iteration by iteration the two agree while far from the floor: the f32 factor does
        // not slow the iteration down.
        let (hs, hd) = (single.history().unwrap(), double.history().unwrap());
        for (k, (s, d)) in hs.iter().zip(hd).enumerate().take(20) {
            assert!((s - d).abs() <= 1e-3 * d, "iteration {k}: {s:e} vs {d:e}");
        }
    }

    /// With an exact factor the correction form is the classic iteration x ← A⁻¹·b(x): one
    /// iteration from y lands on A⁻¹·b(y), computed here independently with the f64 factor.
    #[test]
    fn one_correction_is_one_classic_global_step() {
        let (sys, start) = lab(12, defaults::STIFFNESS, 1.0, 1.0 / 60.0);
        let (x0, v0) = moving(&sys, &start, 5);
        let mut solver = exact_solver(&sys, 1);
        let (mut x, mut v) = (x0.clone(), v0.clone());
        solver.step(&mut x, &mut v).unwrap();
        // b(y) = s·M·y + h²·J·d(y) + Σ h²k·(pin + l·dir).
        let h2 = sys.params.time_step.powi(2);
        let s = sys.inertia_scale();
        let mut y = vec![DVec3::ZERO; x0.len()];
        sys.predict(&x0, &v0, &mut y);
        let mut b: Vec<DVec3> = y.iter().zip(&sys.mass).map(|(y, m)| *y * (s * m)).collect();
        let sp = &sys.springs;
        for i in 0..sp.a.len() {
            let (a, bb) = (sp.a[i] as usize, sp.b[i] as usize);
            let d = (y[a] - y[bb]).normalize() * (h2 * sp.k[i] * sp.rest[i]);
            b[a] += d;
            b[bb] -= d;
        }
        let an = &sys.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            let dir = (y[a] - an.at[i]).normalize();
            b[a] += (an.at[i] + dir * an.rest[i]) * (h2 * an.k[i]);
        }
        Cholesky::new(&FastSolver::matrix(&sys))
            .unwrap()
            .solve3(&mut b);
        for (got, want) in x.iter().zip(&b) {
            assert!(got.distance(*want) < 1e-12, "{got} vs {want}");
        }
    }

    /// A system too ill-conditioned for an f32 factor keeps the f64 factor, and still converges:
    /// a free cloth (no pins: only inertia resists a rigid translation) with stiff springs and
    /// light particles, h²k/m = 1e8, so the condition number is ~1e9.
    #[test]
    fn ill_conditioned_systems_keep_the_double_factor() {
        let (sys, start) = lab_pinned(30, 1e5, 1e-5, 1.0 / 10.0, false);
        let mut solver = FastSolver::new(sys.clone(), 5).unwrap();
        assert!(
            !solver.factor().is_single(),
            "f32 rate would be {}",
            correction_rate(
                &FastSolver::matrix(&sys),
                &GlobalFactor::Single(
                    Cholesky::new(&FastSolver::matrix(&sys))
                        .unwrap()
                        .to_f32_dropping(1e-8)
                )
            )
        );
        assert!(solver.factor_rate() < 1e-6, "rate {}", solver.factor_rate());
        let (mut x, mut v) = (start.clone(), vec![DVec3::ZERO; start.len()]);
        let stats = solver.step(&mut x, &mut v).unwrap();
        assert!(stats.residual.is_finite());
    }

    #[test]
    fn rescaling_keeps_lanes_near_one() {
        // In range: no redo; the next scale follows the residual.
        let (next, redo) = rescale([1.0; 4], [0.5, 2.0, 1e-3, 0.0]);
        assert!(!redo);
        assert_eq!(next, [2.0, 0.5, 1024.0, 1.0]);
        // Far out of range (a new step's residual): redo at the right scale.
        let (next, redo) = rescale([1.0, 1.0, 1.0, 1.0], [1e-12, 1.0, 1.0, 0.0]);
        assert!(redo);
        assert_eq!(next[0], 2f64.powi(40));
        // Non-finite: scale 1, so the value passes through unchanged.
        let (next, redo) = rescale([4.0, 1.0, 1.0, 1.0], [f64::INFINITY, 1.0, 1.0, 0.0]);
        assert!(redo);
        assert_eq!(next[0], 1.0);
        let mut delta = vec![Lanes4f::default(); 2];
        let res = [
            Lanes4([3.0, 1e-40, -8.0, 0.0]),
            Lanes4([1.0, 2.0, 0.5, 0.0]),
        ];
        let largest = to_f32_scaled(&res, [0.5, 1.0, 0.25, 1.0], &mut delta);
        assert_eq!(largest, [1.5, 2.0, 2.0, 0.0]);
        assert_eq!(delta[0].0, [1.5, 0.0, -2.0, 0.0], "1e-40 is flushed");
    }
}
