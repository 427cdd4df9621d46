//! Fast mass-spring (Liu, Bargteil, O'Brien and Kavan 2013): local/global minimisation of the
//! implicit Euler objective with a prefactored system matrix.
//!
//! With d_s = l_s (xa − xb)/|xa − xb| (local step, per spring) the objective becomes quadratic in
//! x, and its minimiser solves the global step (s M + h² L) x = s M y + h² J d (+ anchor terms).
//! The matrix is n×n (the same for x, y and z), constant during a bake, and factored once.

use glam::DVec3;

use super::collide::contact::{self, Hold};
use super::collide::Colliders;
use super::factor::{upper_from_triplets, Cholesky, Lanes4};
use super::system::ReducedSystem;
use super::{StepSolver, StepStats};
use crate::error::Result;

/// Local/global solver with a fixed iteration count per step.
///
/// Each iteration is a correction x ← x + A⁻¹r with r = −h²∇g(x) (A = s·M + h²·L): the local step
/// and the residual are one pass over the springs, and the fixed point is where the gradient
/// vanishes, whatever the accuracy of the factor. With an exact factor this is the same iterate
/// as the classic x ← A⁻¹b(x).
#[derive(Debug)]
pub struct FastSolver {
    sys: ReducedSystem,
    factor: Cholesky,
    iterations: usize,
    /// Both ends of each free spring (solver indices), packed for the local step.
    ends: Vec<[u32; 2]>,
    /// h²·k·l and h²·k per free spring.
    hkl_hk: Vec<[f64; 2]>,
    /// h²·k per anchor.
    hk_anchor: Vec<f64>,
    /// s·m per particle (the inertia part of A's diagonal).
    sm: Vec<f64>,
    /// s·M·y: the part of the residual that is constant in a step.
    base: Vec<Lanes4>,
    /// The current iterate's positions.
    pos: Vec<Lanes4>,
    /// The residual r at `pos` (after the colliders' reactions).
    res: Vec<Lanes4>,
    /// The correction δ of the global step.
    delta: Vec<Lanes4>,
    /// Particles held by a collider in the global step, with how.
    held: Vec<(u32, Hold)>,
    /// Conjugate-gradient work vectors (used only while particles are held).
    cg: [Vec<Lanes4>; 3],
    y: Vec<DVec3>,
    x0: Vec<DVec3>,
    /// Relative residual after each iteration of the last step, when recording.
    history: Option<Vec<f64>>,
    /// Colliders, when any (see [`contact`]).
    colliders: Option<Colliders>,
}

impl FastSolver {
    /// Builds the solver and factors s·M + h²·L.
    ///
    /// # Errors
    /// [`crate::Error::Factorisation`] when the matrix cannot be factored.
    pub fn new(sys: ReducedSystem, iterations: usize) -> Result<Self> {
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
        let factor = Cholesky::new(&upper_from_triplets(n, &triplets))?;
        Ok(FastSolver {
            ends: sp.a.iter().zip(&sp.b).map(|(&a, &b)| [a, b]).collect(),
            hkl_hk: sp
                .k
                .iter()
                .zip(&sp.rest)
                .map(|(k, l)| [h2 * k * l, h2 * k])
                .collect(),
            hk_anchor: an.k.iter().map(|k| h2 * k).collect(),
            sm: sys.mass.iter().map(|m| s * m).collect(),
            base: vec![Lanes4::default(); n],
            pos: vec![Lanes4::default(); n],
            res: vec![Lanes4::default(); n],
            delta: vec![Lanes4::default(); n],
            held: Vec::new(),
            cg: std::array::from_fn(|_| vec![Lanes4::default(); n]),
            y: vec![DVec3::ZERO; n],
            x0: vec![DVec3::ZERO; n],
            history: None,
            colliders: None,
            factor,
            iterations,
            sys,
        })
    }

    /// Adds colliders (see [`contact`]).
    pub fn with_colliders(mut self, colliders: Option<Colliders>) -> Self {
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
    pub fn factor(&self) -> &Cholesky {
        &self.factor
    }

    /// Local step and residual in one pass: res = r(pos) = −h²∇g(pos) (newtons × s²).
    fn residual(&mut self) {
        let (x, r) = (&self.pos[..], &mut self.res[..]);
        for (((r, b), x), sm) in r.iter_mut().zip(&self.base).zip(x).zip(&self.sm) {
            *r = *b - *x * *sm;
        }
        for (&[a, b], &[hkl, hk]) in self.ends.iter().zip(&self.hkl_hk) {
            let (a, b) = (a as usize, b as usize);
            let d = x[a] - x[b];
            let len2 = d.0[0] * d.0[0] + d.0[1] * d.0[1] + d.0[2] * d.0[2];
            // h²k (l·d/|d| − d): the projected spring minus the current one.
            let f = if len2 > 0.0 {
                d * (hkl / len2.sqrt() - hk)
            } else {
                d * -hk
            };
            r[a] += f;
            r[b] -= f;
        }
        let an = &self.sys.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            let d = x[a].xyz() - an.at[i];
            let len = d.length();
            let target = if len > 0.0 { d * (an.rest[i] / len) } else { d };
            r[a] += Lanes4::from_vec3((target - d) * self.hk_anchor[i]);
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
        for (i, ((r, p), x0)) in self.res.iter_mut().zip(&self.pos).zip(&self.x0).enumerate() {
            if let Some(surface) = contact::resting_on(colliders, p.xyz(), *x0) {
                resting += 1;
                let mut force = r.xyz();
                let hold = contact::contact_reaction(colliders.friction, &surface, &mut force);
                if hold != Hold::Free {
                    *r = Lanes4::from_vec3(force);
                    self.held.push((i as u32, hold));
                }
            }
        }
        resting
    }

    /// The correction δ: A⁻¹r when nothing is held, else the solution of A·δ = r on the
    /// subspace the colliders leave free, by conjugate gradients preconditioned with A⁻¹.
    fn global_step(&mut self) {
        self.delta.copy_from_slice(&self.res);
        self.factor.solve4(&mut self.delta);
        if self.held.is_empty() {
            return;
        }
        let held = &self.held;
        let filter = |v: &mut [Lanes4]| {
            for &(i, hold) in held {
                let i = i as usize;
                v[i] = Lanes4::from_vec3(hold.filter(v[i].xyz()));
            }
        };
        let [res, z, p] = &mut self.cg;
        res.copy_from_slice(&self.res);
        filter(res);
        z.copy_from_slice(&self.delta);
        filter(z);
        p.copy_from_slice(z);
        self.delta.fill(Lanes4::default());
        let mut rz = dot(res, z);
        let start = rz;
        for _ in 0..CG_ITERATIONS {
            // Also stops on a zero or non-finite residual.
            if rz.is_nan() || rz <= CG_TOLERANCE * CG_TOLERANCE * start {
                break;
            }
            // z doubles as q = S·A·p.
            apply_matrix(
                &self.ends,
                &self.hkl_hk,
                &self.sm,
                &self.sys.anchors.a,
                &self.hk_anchor,
                p,
                z,
            );
            filter(z);
            let alpha = rz / dot(p, z);
            for ((d, r), (p, q)) in self
                .delta
                .iter_mut()
                .zip(res.iter_mut())
                .zip(p.iter().zip(z.iter()))
            {
                *d += *p * alpha;
                *r -= *q * alpha;
            }
            z.copy_from_slice(res);
            self.factor.solve4(z);
            filter(z);
            let rz_next = dot(res, z);
            let beta = rz_next / rz;
            rz = rz_next;
            for (p, z) in p.iter_mut().zip(z.iter()) {
                *p = *z + *p * beta;
            }
        }
    }

    /// ‖res‖ / (h²·force scale) = ‖∇g‖ / force scale (contact reactions applied).
    fn relative_residual(&self) -> f64 {
        let h2 = self.sys.params.time_step.powi(2);
        let sum: f64 = self.res.iter().map(|r| r.xyz().length_squared()).sum();
        sum.sqrt() / h2 / self.sys.force_scale()
    }

    /// The first iterate: the inertial target y, except for particles resting on a collider at
    /// the start of the step, which start where they are (so friction sees their whole slip).
    fn initial_guess(&mut self) {
        for ((p, y), x0) in self.pos.iter_mut().zip(&self.y).zip(&self.x0) {
            let resting = self
                .colliders
                .as_ref()
                .is_some_and(|c| contact::resting_on(c, *x0, *x0).is_some());
            *p = Lanes4::from_vec3(if resting { *x0 } else { *y });
        }
    }

    /// Moves particles that entered a collider back out along its normal.
    fn push_out(&mut self) {
        let Some(colliders) = &self.colliders else {
            return;
        };
        for (p, x0) in self.pos.iter_mut().zip(&self.x0) {
            let mut q = p.xyz();
            if contact::push_out(colliders, &mut q, *x0) {
                *p = Lanes4::from_vec3(q);
            }
        }
    }
}

/// Conjugate-gradient iterations of a global step at most while particles are held.
const CG_ITERATIONS: usize = 20;

/// The held global step stops when the preconditioned residual norm has fallen by this factor:
/// the outer iterations refine further, and truncating much earlier (2 iterations) lets smooth
/// modes of stiff cloth run away.
const CG_TOLERANCE: f64 = 0.1;

/// Σ aᵢ·bᵢ over the x, y, z lanes.
fn dot(a: &[Lanes4], b: &[Lanes4]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a.xyz().dot(b.xyz())).sum()
}

/// out = A·p with A = s·M + h²·L (springs and anchors).
fn apply_matrix(
    ends: &[[u32; 2]],
    hkl_hk: &[[f64; 2]],
    sm: &[f64],
    anchors: &[u32],
    hk_anchor: &[f64],
    p: &[Lanes4],
    out: &mut [Lanes4],
) {
    for ((o, p), sm) in out.iter_mut().zip(p).zip(sm) {
        *o = *p * *sm;
    }
    for (&[a, b], &[_, hk]) in ends.iter().zip(hkl_hk) {
        let (a, b) = (a as usize, b as usize);
        let f = (p[a] - p[b]) * hk;
        out[a] += f;
        out[b] -= f;
    }
    for (&a, &hk) in anchors.iter().zip(hk_anchor) {
        out[a as usize] += p[a as usize] * hk;
    }
}

impl StepSolver for FastSolver {
    fn system(&self) -> &ReducedSystem {
        &self.sys
    }

    fn step(&mut self, x: &mut [DVec3], v: &mut [DVec3]) -> Result<StepStats> {
        let h = self.sys.params.time_step;
        self.x0.copy_from_slice(x);
        self.sys.predict(x, v, &mut self.y);
        for (b, (y, sm)) in self.base.iter_mut().zip(self.y.iter().zip(&self.sm)) {
            *b = Lanes4::from_vec3(*y * *sm);
        }
        self.initial_guess();
        if let Some(h) = &mut self.history {
            h.clear();
        }
        for k in 0..self.iterations {
            self.residual();
            self.contact_reactions();
            if k > 0 && self.history.is_some() {
                let r = self.relative_residual();
                if let Some(h) = &mut self.history {
                    h.push(r);
                }
            }
            self.global_step();
            for (p, d) in self.pos.iter_mut().zip(&self.delta) {
                *p += *d;
            }
            self.push_out();
        }
        // One more residual measures how far the last iterate is from stationary.
        self.residual();
        let contacts = self.contact_reactions();
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
            contacts,
        })
    }
}
