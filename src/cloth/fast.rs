//! Fast mass-spring (Liu, Bargteil, O'Brien and Kavan 2013): local/global minimisation of the
//! implicit Euler objective with a prefactored system matrix.
//!
//! With d_s = l_s (xa − xb)/|xa − xb| (local step, per spring) the objective becomes quadratic in
//! x, and its minimiser solves the global step (s M + h² L) x = s M y + h² J d (+ anchor terms).
//! The matrix is n×n (the same for x, y and z), constant during a bake, and factored once.

use glam::DVec3;

use super::factor::{upper_from_triplets, Cholesky, Lanes4};
use super::system::ReducedSystem;
use super::{StepSolver, StepStats};
use crate::error::Result;

/// Local/global solver with a fixed iteration count per step.
#[derive(Debug)]
pub struct FastSolver {
    sys: ReducedSystem,
    factor: Cholesky,
    iterations: usize,
    /// Both ends of each free spring (solver indices), packed for the local step.
    ends: Vec<[u32; 2]>,
    /// h²·k·l per free spring: the local step's d_s scaled into the right-hand side.
    hkl: Vec<f64>,
    /// h²·k per anchor.
    hk_anchor: Vec<f64>,
    /// Constant right-hand side part s·M·y + Σ h²k·(pin position), refreshed per step.
    base: Vec<Lanes4>,
    /// The current iterate's positions.
    pos: Vec<Lanes4>,
    /// The global step's right-hand side, solved in place (then swapped into `pos`).
    sol: Vec<Lanes4>,
    /// The right-hand side that produced `pos` (kept when a residual will be measured).
    last_rhs: Vec<Lanes4>,
    y: Vec<DVec3>,
    x0: Vec<DVec3>,
    /// Relative residual after each iteration of the last step, when recording.
    history: Option<Vec<f64>>,
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
            hkl: sp.k.iter().zip(&sp.rest).map(|(k, l)| h2 * k * l).collect(),
            hk_anchor: an.k.iter().map(|k| h2 * k).collect(),
            base: vec![Lanes4::default(); n],
            pos: vec![Lanes4::default(); n],
            sol: vec![Lanes4::default(); n],
            last_rhs: vec![Lanes4::default(); n],
            y: vec![DVec3::ZERO; n],
            x0: vec![DVec3::ZERO; n],
            history: None,
            factor,
            iterations,
            sys,
        })
    }

    /// Records the relative residual after every iteration of each step (costs one vector
    /// difference per iteration), readable with [`FastSolver::history`].
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

    /// ‖∇g(x)‖ / force scale, where x solved Q·x = `last_rhs` and `sol` holds the local step at
    /// x: then h²∇g(x) = Q·x − rhs = last_rhs − sol.
    fn relative_residual(&self) -> f64 {
        let h2 = self.sys.params.time_step.powi(2);
        let diff: f64 = self
            .last_rhs
            .iter()
            .zip(&self.sol)
            .map(|(a, b)| (a.xyz() - b.xyz()).length_squared())
            .sum();
        diff.sqrt() / h2 / self.sys.force_scale()
    }

    /// Local step at `self.pos` folded into the right-hand side: sol = base + h²·J·d(pos).
    fn local_step(&mut self) {
        self.sol.copy_from_slice(&self.base);
        let (x, rhs) = (&self.pos[..], &mut self.sol[..]);
        for (&[a, b], &hkl) in self.ends.iter().zip(&self.hkl) {
            let (a, b) = (a as usize, b as usize);
            let r = x[a] - x[b];
            let len2 = r.0[0] * r.0[0] + r.0[1] * r.0[1] + r.0[2] * r.0[2];
            if len2 > 0.0 {
                let d = r * (hkl / len2.sqrt());
                rhs[a] += d;
                rhs[b] -= d;
            }
        }
        let an = &self.sys.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            let r = x[a].xyz() - an.at[i];
            let len = r.length();
            if len > 0.0 {
                rhs[a] += Lanes4::from_vec3(r * (self.hk_anchor[i] * an.rest[i] / len));
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
        let s = self.sys.inertia_scale();
        self.x0.copy_from_slice(x);
        self.sys.predict(x, v, &mut self.y);
        for (b, (y, m)) in self.base.iter_mut().zip(self.y.iter().zip(&self.sys.mass)) {
            *b = Lanes4::from_vec3(*y * (s * m));
        }
        let an = &self.sys.anchors;
        for i in 0..an.a.len() {
            self.base[an.a[i] as usize] += Lanes4::from_vec3(an.at[i] * self.hk_anchor[i]);
        }
        for (p, y) in self.pos.iter_mut().zip(&self.y) {
            *p = Lanes4::from_vec3(*y);
        }
        if let Some(h) = &mut self.history {
            h.clear();
        }
        for k in 0..self.iterations {
            self.local_step();
            if k > 0 && self.history.is_some() {
                let r = self.relative_residual();
                if let Some(h) = &mut self.history {
                    h.push(r);
                }
            }
            if self.history.is_some() || k + 1 == self.iterations {
                self.last_rhs.copy_from_slice(&self.sol);
            }
            self.factor.solve4(&mut self.sol);
            std::mem::swap(&mut self.pos, &mut self.sol);
        }
        // One more local step measures how far the last global solution is from stationary.
        self.local_step();
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
