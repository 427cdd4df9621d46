//! Contact inside Newton's iterations: the particles the colliders hold, and a feasible start.
//!
//! Contact (see [`NewtonContact`]): a projected Newton method. At each iterate the particles
//! resting on a collider whose gradient pushes them into it are held: their normal component is
//! removed from the gradient (what remains is the residual, the removed part is the contact
//! force) and from the Hessian (blocks Sᵢ H_ij Sⱼ, S = I − nnᵀ), every trial point of the line
//! search is projected back out of the colliders, and the held particles are settled back onto
//! the surface they slid over (a slide along a curved surface's tangent plane lifts them off).
//! With the barrier model ([`super::collide::ContactModel::Barrier`]) nothing is held: the
//! barrier's gradient and diagonal blocks join ∇g and H, the step's start is made feasible, and
//! a trial point past a barrier (infinite energy) is halved away; where no trial is feasible the
//! iterate stays.

use glam::DVec3;

use super::NewtonSolver;
use crate::cloth::collide::contact::NewtonContact;
use crate::error::{Error, Result};

/// Sᵢ B Sⱼ with S = I − n nᵀ for a normal, I for none.
pub(super) fn project_block(
    b: [[f64; 3]; 3],
    ni: Option<DVec3>,
    nj: Option<DVec3>,
) -> [[f64; 3]; 3] {
    let mut b = b;
    if let Some(n) = ni {
        // Rows: B ← B − n (nᵀB).
        let nb: [f64; 3] = std::array::from_fn(|c| (0..3).map(|r| n[r] * b[r][c]).sum());
        for (r, row) in b.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v -= n[r] * nb[c];
            }
        }
    }
    if let Some(n) = nj {
        // Columns: B ← B − (B n) nᵀ.
        for row in b.iter_mut() {
            let bn: f64 = (0..3).map(|c| row[c] * n[c]).sum();
            for (c, v) in row.iter_mut().enumerate() {
                *v -= bn * n[c];
            }
        }
    }
    b
}

impl NewtonSolver {
    /// Whether self-contact pairs are in their bands at the assembled iterate (their couplings
    /// are then in the Hessian's products only, so directions come from conjugate gradients).
    pub(super) fn self_coupled(&self) -> bool {
        self.self_contact
            .as_ref()
            .is_some_and(|s| s.active_count() > 0)
    }

    /// Where the cloth touches itself, directions must not make it pass through itself: the
    /// largest fraction of the path from `x` to `to` it can move (1: all of it; see
    /// [`SelfContact::prepare_path`]). 1 without self-contact.
    pub(super) fn self_path(&mut self, x: &[DVec3], to: &[DVec3]) -> f64 {
        match &mut self.self_contact {
            Some(s) => s.prepare_path(x, to),
            None => 1.0,
        }
    }

    /// Moves every particle that entered a collider back out (no-op without colliders).
    pub(super) fn project(&self, x: &mut [DVec3]) {
        if let Some(c) = &self.contact {
            for (i, p) in x.iter_mut().enumerate() {
                c.project(i, p);
            }
        }
    }

    /// Moves the particles held in this iteration back down onto their layers when they lifted
    /// off by less than the thickness (no-op without colliders). The direction keeps a held
    /// particle in its collider's tangent plane, which on a curved surface lifts it off by the
    /// square of its slide over twice the radius: it would then no longer rest there at the
    /// next iterate, be released, driven back in and clipped by the projection, round after
    /// round.
    pub(super) fn settle(&self, x: &mut [DVec3]) {
        if let Some(c) = &self.contact {
            let reach = c.colliders().thickness;
            for (i, (p, held)) in x.iter_mut().zip(&self.held).enumerate() {
                if held.is_some() {
                    c.settle(i, p, reach);
                }
            }
        }
    }

    /// Finds the particles the colliders hold at `x` (resting on one and pushed into it by −∇g)
    /// and writes the gradient less their normal parts into `free_grad`. Returns whether any is
    /// held.
    pub(super) fn hold(&mut self, x: &[DVec3]) -> bool {
        let mut any = false;
        for (i, ((held, free), g)) in self
            .held
            .iter_mut()
            .zip(self.free_grad.iter_mut())
            .zip(&self.grad)
            .enumerate()
        {
            *held = self
                .contact
                .as_ref()
                .filter(|c| !c.is_barrier())
                .and_then(|c| c.resting(i, x[i]))
                .filter(|s| NewtonContact::holds(s, *g))
                .map(|s| s.normal);
            *free = match *held {
                Some(n) => {
                    any = true;
                    *g - n * g.dot(n)
                }
                None => *g,
            };
        }
        self.any_held = any;
        any
    }

    /// Restricts the assembled Hessian to the motions the colliders leave free: every block
    /// (i, j) becomes Sᵢ H_ij Sⱼ with Sᵢ = I − nᵢnᵢᵀ for a held particle (I otherwise), and a held
    /// particle's diagonal block gets nᵢᵀH_iinᵢ·nᵢnᵢᵀ back, so the matrix stays definite and its
    /// solution has no normal component at held particles (the filtered solve of Baraff and
    /// Witkin 1998).
    pub(super) fn filter_hessian(&mut self) {
        let n = self.held.len();
        for j in 0..n {
            let nj = self.held[j];
            // Off-diagonal blocks (i, j), i < j: column 3j + c holds rows 3i..3i+3 of each lower
            // neighbour i before its diagonal rows.
            let start = [
                self.col_ptr[3 * j],
                self.col_ptr[3 * j + 1],
                self.col_ptr[3 * j + 2],
            ];
            let blocks = (self.diag[j][0] as usize - start[0]) / 3;
            for p in 0..blocks {
                let i = self.row_idx[start[0] + 3 * p] / 3;
                let ni = self.held[i];
                if ni.is_none() && nj.is_none() {
                    continue;
                }
                let mut b = [[0.0; 3]; 3];
                for (c, s) in start.iter().enumerate() {
                    for (r, row) in b.iter_mut().enumerate() {
                        row[c] = self.values[s + 3 * p + r];
                    }
                }
                let b = project_block(b, ni, nj);
                for (c, s) in start.iter().enumerate() {
                    for (r, row) in b.iter().enumerate() {
                        self.values[s + 3 * p + r] = row[c];
                    }
                }
            }
            if let Some(nv) = nj {
                let d = self.diag[j];
                // The upper triangle holds (r, c) for r ≤ c at d[c] + r.
                let b: [[f64; 3]; 3] = std::array::from_fn(|r| {
                    std::array::from_fn(|c| self.values[d[r.max(c)] as usize + r.min(c)])
                });
                let along = (0..3)
                    .map(|r| (0..3).map(|c| nv[r] * b[r][c] * nv[c]).sum::<f64>())
                    .sum::<f64>();
                let mut b = project_block(b, nj, nj);
                for r in 0..3 {
                    for c in 0..3 {
                        b[r][c] += along * nv[r] * nv[c];
                    }
                }
                for (c, &dc) in d.iter().enumerate() {
                    for (r, row) in b.iter().enumerate().take(c + 1) {
                        self.values[dc as usize + r] = row[c];
                    }
                }
            }
        }
    }

    /// Makes the step's start `x` feasible: out of the barrier colliders' bands, and reached
    /// from the step's first positions without the cloth passing through itself (the move is
    /// cut where it would; the colliders are asked again after a cut, a few rounds).
    ///
    /// # Errors
    /// [`Error::Diverged`] when particles stay behind a collider's surface (at the first step,
    /// or where no collider moves: a moving body's pinch releases them instead, see
    /// [`NewtonContact::make_feasible`]).
    pub(super) fn feasible_start(&mut self, x: &mut [DVec3]) -> Result<()> {
        const ROUNDS: usize = 3;
        let x0 = std::mem::take(&mut self.x0);
        let mut behind = 0;
        // A body moving between steps may close in on a particle (not the input's start).
        let release = self.steps > 0 && self.contact.as_ref().is_some_and(NewtonContact::moves);
        for round in 0..=ROUNDS {
            if let Some(c) = self.contact.as_mut().filter(|c| c.is_barrier()) {
                behind = c.make_feasible(x, release);
            }
            let t = self.self_path(&x0, x);
            if t == 1.0 {
                break;
            }
            if round == ROUNDS {
                // The colliders win: the start stays out of them, and the cloth's pairs take it
                // as it is (a move out of a collider the cloth started in may pass through
                // itself; the frame's crossing count says so).
                if let Some(s) = &mut self.self_contact {
                    s.accept(x);
                }
                break;
            }
            // A body moving within the step comes from where it was at x₀: a start cut short
            // of where it was going would leave the pair that cut it at its band's bottom, in the
            // body's way; x₀ itself leaves every pair where the last step did.
            let t = if self.body_within.is_some() { 0.0 } else { t };
            for (p, a) in x.iter_mut().zip(&x0) {
                *p = *a + (*p - *a) * t;
            }
        }
        self.x0 = x0;
        let alone = self.self_contact.is_none();
        if let Some(c) = self.contact.as_mut().filter(|c| c.is_barrier()) {
            if behind > 0 {
                return Err(Error::Diverged {
                    frame: 0,
                    reason: format!(
                        "{behind} particles start time step {} behind a collider's surface, where \
                         the barrier cannot push them out{}",
                        self.steps + 1,
                        if alone {
                            " (the constraint contact model may)"
                        } else {
                            ""
                        }
                    ),
                    advice: Vec::new(),
                });
            }
            c.set_iterate(x);
        }
        Ok(())
    }
}
