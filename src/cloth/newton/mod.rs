//! Newton's method on the implicit Euler objective, with a sparse Hessian refactored every
//! iteration into a fixed symbolic pattern.
//!
//! Each step minimises the same g(x) = s/(2h²)‖x − y‖²_M + E(x) as [`super::FastSolver`]
//! (see [`ReducedSystem`]): solve H Δx = −∇g with a sparse Cholesky factor, backtrack on g along
//! Δx, repeat until ‖∇g‖ / [`ReducedSystem::force_scale`] falls below the tolerance or the
//! iteration cap is hit.
//!
//! The Hessian is 3n×3n with unknown `3i + c` for coordinate c of free particle i. Per spring,
//! with r = xa − xb, u = r/|r| and tension f(|r|) (see [`super::law::spring_response`]: k·e
//! stretched, kc·e compressed, jammed past the jamming strain):
//!
//! ```text
//! H_e = f′ u uᵀ + max(0, f/|r|) (I − u uᵀ)
//! ```
//! added to blocks (a,a) and (b,b) and subtracted from (a,b), (b,a); an anchor adds H_e to its
//! free end's diagonal block only. Clamping the transverse term at zero (compressed springs)
//! keeps every H_e positive semi-definite, so H = sM/h² + Σ H_e is positive definite. Bending
//! stencils add their constant blocks wᵢwⱼ·I.
//!
//! Gauss–Seidel sweeps ([`NewtonSolver::with_sweeps`], [`Smoother`]): on stiff, nearly
//! inextensible cloth (h²k/m ≈ 1e4) a full Newton step moves particles along their springs'
//! tangents and so lengthens the springs by the square of the move over twice their length;
//! that residual is local, and Newton removes it only at a linear rate (≈ 0.7 per iteration on
//! the 8k-vertex skirt). A few sweeps of one local Newton step per particle after each
//! iteration remove it for a fraction of a factorisation, and Newton's quadratic phase starts
//! sooner: on that skirt over 30 frames, 404 iterations (median 12) without sweeps, 173
//! (median 5) with ten.
//!
//! Convergence: quadratic near the solution while no spring is compressed there. A compressed
//! spring's clamped block is not the exact second derivative, so on crumpling cloth Newton falls
//! back to a linear rate (≈ 0.1–0.9 per iteration); on stiff, light cloth such as tableCloth
//! (h²k/m ≈ 10⁵) it can then reach the iteration cap, which the step reports as not converged.

//!
//! The parts: `pattern` lays out the Hessian's sparsity pattern once and assembles it;
//! `direction` factors it and solves for the Newton direction (single precision refined,
//! or conjugate gradients on the split factor); `contact` holds particles on the colliders
//! and makes a step's start feasible; this module runs the iterations and the line search.

mod contact;
mod direction;
mod pattern;

use faer::sparse::linalg::cholesky::SymbolicCholesky;
use glam::DVec3;

pub use self::direction::{LinearSolver, MULTIGRID_MIN};
use self::direction::{Precision, Scratch};
use self::pattern::BlockCols;
use super::collide::contact::NewtonContact;
use super::collide::{Collider, Colliders};
use super::linalg::multigrid::Multigrid;
use super::linalg::split::SplitCholesky;
use super::self_contact::SelfContact;
use super::smooth::{Smoother, SweepScratch};
use super::system::{BendCoupling, ReducedSystem};
use super::{StepSolver, StepStats};
use crate::error::{Error, Result};

/// Default relative gradient tolerance ‖∇g‖ / force scale at which Newton stops.
///
/// On the lab cloth this puts positions within ~1e-11 m of the exact minimiser (the error is
/// about h²/(s·m) · ‖∇g‖), far inside the 1e-6 m the cross-checks ask for.
pub const DEFAULT_TOLERANCE: f64 = 1e-8;

/// Default Gauss–Seidel sweeps after each Newton iteration in a bake ([`NewtonSolver::with_sweeps`];
/// `--sweeps`). Over 30 frames of the 8k-vertex skirt hanging from its waist: none 404 Newton
/// iterations, 5 sweeps 203, 10 sweeps 173, 20 sweeps 152, the last the slowest of the three
/// (a sweep costs about 1.6 ms there, a thirty-fifth of a factorisation; `docs/performance.md`).
pub const DEFAULT_SWEEPS: usize = 10;

/// Default cap on Newton iterations per time step: a safety net, not a budget (a step stops on
/// the tolerance). Hanging garments and the draped dress converge within 15; a skirt crushed
/// against a table or a sphere buckles into new folds and takes 50–140 on a few frames after
/// impact (circle_skirt on the table over 30 frames: 95, 140, 103, 108 on four frames, every
/// frame converged; at a cap of 100, 25 of 30, at 50, 22). Only frames that would otherwise end
/// unconverged pay for the higher cap (`docs/performance.md`, "A cap of 100 Newton iterations"
/// and "Sweeps on two cores, and a cap of 200").
pub const DEFAULT_MAX_ITERATIONS: usize = 200;

/// Armijo sufficient-decrease constant of the backtracking line search.
const ARMIJO: f64 = 1e-4;

/// The longer step the line search tries after accepting a full Newton step (α = 1), kept when
/// it lowers g further by more than roundoff. Newton's model of a stiff, nearly inextensible
/// garment underestimates how far it may go where springs are compressed (their negative
/// transverse curvature is left out of the projected Hessian) and in the slow phase where full
/// steps converge only linearly. Over 30 frames of the 8k-vertex skirt hanging from its waist the
/// longer step takes Newton from 173 to 158 iterations (with a 1 % toe, 148 to 137; doubling up
/// to three times there, 142; `docs/performance.md`, "A longer step, and a wider toe measured").
const LONGER_STEP: f64 = 2.0;

/// A step that may be split ([`StepSolver::save`]) ends unconverged once this many iterations
/// have passed without halving the lowest residual it had reached, while that is still more
/// than [`STALLED_FAR`] times the tolerance: it is then taken again as two half steps rather
/// than run on to the cap. (Closer to the tolerance a step may wander for a hundred iterations
/// and still converge: the skirts dropped on the table do.)
const STALLED: usize = 30;

/// See [`STALLED`].
const STALLED_FAR: f64 = 10.0;

/// Halvings before the line search gives up and takes the smallest step tried.
const MAX_HALVINGS: usize = 30;

/// Relative roundoff allowance when comparing objective values (g is a sum of non-negative
/// terms, so its own size bounds the roundoff of its evaluation).
const ROUNDOFF: f64 = 1e-12;

/// What Newton's sparse Cholesky factors.
///
/// A bending stencil's Hessian w wᵀ couples its two opposite vertices, which are two edges
/// apart on the mesh; those pairs double the factor's entries and more than double its cost.
/// [`BendingFactor::Split`] factors instead H' = H + D, D = Σ |w_c w_d|·(e_c e_cᵀ + e_d e_dᵀ) −
/// w_c w_d·(e_c e_dᵀ + e_d e_cᵀ) (⊗ I₃) over the stencils' opposite vertices c, d: the pair's
/// block moved onto the two diagonals, so the pattern loses it, and D is positive
/// semi-definite, so H' ≥ H stays definite. The Newton direction still solves H Δx = −∇g, by
/// conjugate gradients preconditioned with the factor of H': the preconditioned matrix
/// H'⁻¹H has its eigenvalues in (0, 1], and about six gradients reach `CG_TOLERANCE` (`direction.rs`) on the
/// garments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BendingFactor {
    /// Factor H' and solve by preconditioned conjugate gradients (the default).
    #[default]
    Split,
    /// Factor the Hessian itself, bending stencils whole.
    Whole,
}

impl BendingFactor {
    /// The coupling a system ordered for this factor should be ordered with
    /// ([`ReducedSystem::with_coupling`]).
    pub fn coupling(self) -> BendCoupling {
        match self {
            BendingFactor::Split => BendCoupling::WithoutOpposite,
            BendingFactor::Whole => BendCoupling::All,
        }
    }
}

/// What [`NewtonSolver::diagnostics`] shows of the last step: per free particle, in solver
/// order (all zeros, and none held, before the first step).
#[derive(Debug, Clone, Copy)]
pub struct NewtonDiagnostics<'a> {
    /// Positions at the start of the step, m.
    pub x0: &'a [DVec3],
    /// The inertial target the step's objective pulls towards ([`ReducedSystem::predict`]), m.
    pub y: &'a [DVec3],
    /// ∇g at the step's final iterate, N.
    pub grad: &'a [DVec3],
    /// ∇g less the normal parts the colliders hold (equal to `grad` without colliders, and
    /// with the barrier contact model), N; the step's residual is its norm over
    /// [`ReducedSystem::force_scale`].
    pub free_grad: &'a [DVec3],
    /// Per particle: the normal of the collider holding it at the final iterate, if any.
    pub held: &'a [Option<DVec3>],
    /// The colliders the step ran against (with their moved shapes), when there are any.
    pub colliders: Option<&'a Colliders>,
}

/// Newton's method with a backtracking line search and a reused symbolic factorisation.
#[derive(Debug)]
pub struct NewtonSolver {
    sys: ReducedSystem,
    tolerance: f64,
    max_iterations: usize,
    /// Upper-triangle column starts (length 3n + 1).
    col_ptr: Vec<usize>,
    /// Upper-triangle row indices, sorted within each column.
    row_idx: Vec<usize>,
    /// The same row indices in 32 bits, for the products by H (a third fewer bytes to read).
    row_idx32: Vec<u32>,
    /// Upper-triangle values, overwritten by every assembly.
    values: Vec<f64>,
    /// Per free particle: its diagonal block's columns.
    diag: Vec<BlockCols>,
    /// Per free spring: its off-diagonal block's columns (rows of the lower-indexed end).
    off: Vec<[Option<BlockCols>; 1]>,
    /// Per bending stencil and vertex pair (0,1), (0,2), (0,3), (1,2), (1,3), (2,3): the pair's
    /// off-diagonal block, `None` where either vertex is pinned or both are the same particle.
    bend_off: Vec<[Option<BlockCols>; 6]>,
    /// Per membrane triangle and corner pair ([`pattern::pair_slots`]): the pair's off-diagonal block,
    /// `None` where either corner is pinned.
    membrane_off: Vec<[Option<BlockCols>; 3]>,
    /// The factor's symbolic analysis; `None` with multigrid until a step needs a factor.
    symbolic: Option<SymbolicCholesky<usize>>,
    l_values: Vec<f64>,
    /// The Hessian's values rounded to single precision, and their factor (see
    /// [`NewtonSolver::solve_direction`]).
    values32: Vec<f32>,
    l_values32: Vec<f32>,
    /// Single-precision right-hand side and solution of one pair of triangular solves.
    rhs32: Vec<f32>,
    /// −∇g − H·Δx for the direction being refined, 3n scalars.
    refine: Vec<f64>,
    /// Which factor the current iteration holds.
    held_factor: Precision,
    /// Whether the factored matrix is H' rather than H ([`BendingFactor::Split`] with at least
    /// one split stencil), so that directions come from preconditioned conjugate gradients.
    split: bool,
    /// With the split factor: per split stencil, its opposite vertices c, d and w_c·w_d (the
    /// pair's coupling that the products by H take off H').
    opposite: Vec<(u32, u32, f64)>,
    /// Conjugate-gradient vectors (preconditioned residual, search direction, its product).
    cg: [Vec<f64>; 3],
    /// Conjugate-gradient iterations and directions since the solver was made.
    cg_count: [usize; 2],
    /// Newton directions taken from a single-precision factor and from a double-precision one,
    /// since the solver was made.
    directions: [usize; 2],
    /// Whether each step first tries the approximate preconditioner: a single-precision factor
    /// ([`NewtonSolver::single_precision`]), or the multigrid hierarchy.
    allow_single: bool,
    /// False once a single-precision factor failed in this step: the rest of the step factors
    /// in double precision.
    try_single: bool,
    /// Scratch for numeric factorisation and solves.
    scratch: Scratch,
    grad: Vec<DVec3>,
    /// Newton direction, 3n scalars.
    dx: Vec<f64>,
    trial: Vec<DVec3>,
    /// The trial at [`LONGER_STEP`] times the direction.
    longer: Vec<DVec3>,
    /// Scratch: the obstacles' drag on the cloth ([`NewtonSolver::push`]).
    drag: Vec<DVec3>,
    /// Whether the line search tries [`LONGER_STEP`] after a full step
    /// ([`NewtonSolver::with_longer_step`]).
    try_longer: bool,
    y: Vec<DVec3>,
    x0: Vec<DVec3>,
    /// Relative residual at the start of each iteration of the last step (and the final one).
    history: Option<Vec<f64>>,
    /// The line search's step length in each iteration of the last step (recorded with
    /// `history`).
    step_lengths: Option<Vec<f64>>,
    /// Time steps taken (for error messages).
    steps: usize,
    /// Contact constraints and friction, when there are colliders.
    contact: Option<NewtonContact>,
    /// Per particle: the normal of the collider holding it in this iteration, if any.
    held: Vec<Option<DVec3>>,
    /// Whether any particle is held in this iteration.
    any_held: bool,
    /// The gradient less the normal parts the colliders hold (the contact forces).
    free_grad: Vec<DVec3>,
    /// Gauss–Seidel sweeps after each Newton iteration ([`NewtonSolver::with_sweeps`]), and
    /// the incidence lists they run over (built when the count is not zero).
    sweeps: usize,
    smoother: Option<Smoother>,
    sweep_scratch: SweepScratch,
    /// Sweep passes tried and kept, since the solver was made.
    passes: [usize; 2],
    /// Threads the solver may use ([`NewtonSolver::with_threads`]).
    threads: usize,
    /// The single-precision factor in two halves and a dense top, the halves factored and
    /// solved on two threads at once ([`SplitCholesky`]), when the directions come from
    /// conjugate gradients and the factor's elimination tree splits.
    split_factor: Option<SplitCholesky>,
    /// The multigrid preconditioner, when it replaces the factor
    /// ([`NewtonSolver::with_linear_solver`]).
    multigrid: Option<Multigrid>,
    /// The cloth's contact with itself, when on ([`NewtonSolver::with_self_contact`]).
    self_contact: Option<SelfContact>,
    /// The collider that moves within each step as one of self-contact's obstacles
    /// ([`NewtonSolver::with_body_within_steps`]).
    body_within: Option<usize>,
    /// The contacts as [`StepSolver::save`] kept them.
    saved: Option<(Option<NewtonContact>, Option<SelfContact>)>,
    /// Whether the next step may end early where it stalls ([`STALLED`]): it was saved, to be
    /// split if it fails.
    may_stop_early: bool,
}

impl NewtonSolver {
    /// Builds the Hessian pattern and its symbolic factorisation.
    ///
    /// `tolerance` is the relative gradient norm ‖∇g‖ / [`ReducedSystem::force_scale`] at which a
    /// step stops ([`DEFAULT_TOLERANCE`]); `max_iterations` caps Newton iterations per step
    /// ([`DEFAULT_MAX_ITERATIONS`]).
    ///
    /// # Errors
    /// [`Error::Factorisation`] when the symbolic analysis fails (out of memory).
    pub fn new(sys: ReducedSystem, tolerance: f64, max_iterations: usize) -> Result<Self> {
        Self::with_bending_factor(sys, tolerance, max_iterations, BendingFactor::default())
    }

    /// Whether to factor in single precision first (the default where the factor is supernodal:
    /// about 1.5× faster factors on the 8k-vertex skirt, the same directions to 1e-4 after
    /// refinement, see [`NewtonSolver::solve_direction`]), or always in double precision (the
    /// default for the small, simplicial factors, where single precision gains nothing).
    pub fn single_precision(mut self, on: bool) -> Self {
        self.allow_single = on;
        self.try_single = on;
        self
    }

    /// How many Newton directions came from a single-precision factor (after refinement) and
    /// how many from a double-precision one, since the solver was made.
    pub fn directions_by_precision(&self) -> (usize, usize) {
        (self.directions[0], self.directions[1])
    }

    /// Whether directions come from conjugate gradients on a split factor
    /// ([`BendingFactor::Split`] on a model with bending stencils), and how many gradients
    /// they took over how many directions since the solver was made.
    pub fn conjugate_gradients(&self) -> (bool, usize, usize) {
        (self.split, self.cg_count[0], self.cg_count[1])
    }

    /// Adds colliders, as constraints or a barrier ([`Colliders::model`]), with lagged Coulomb
    /// friction (see [`NewtonContact`]).
    pub fn with_colliders(mut self, colliders: Option<Colliders>) -> Self {
        self.contact = colliders.map(|c| NewtonContact::new(c, &self.sys));
        self
    }

    /// Keeps the cloth from passing through itself ([`SelfContact`]; `None`: off).
    pub fn with_self_contact(mut self, self_contact: Option<SelfContact>) -> Self {
        self.self_contact = self_contact;
        self
    }

    /// Moves collider `body` (one of self-contact's obstacles, left out of the colliders given
    /// to [`NewtonSolver::with_colliders`]) within each step rather than between steps: each
    /// step starts with the body where the last one ended, and while it is on its way every
    /// other iteration pushes the body and the cloth on together ([`NewtonSolver::push`]);
    /// a step converges once the body has arrived and the residual is within the tolerance.
    /// (Call it after [`NewtonSolver::with_self_contact`].)
    pub fn with_body_within_steps(mut self, body: Option<usize>) -> Self {
        self.body_within = body;
        self.self_contact = self
            .self_contact
            .take()
            .map(|s| s.moving_obstacles(body.is_some()));
        self
    }

    /// Whether the line search tries twice a full Newton step ([`LONGER_STEP`]) and keeps it
    /// when it lowers g further (on by default). Either way a step stops on its own residual,
    /// so this changes how many iterations a step takes, not what it converges to.
    pub fn with_longer_step(mut self, on: bool) -> Self {
        self.try_longer = on;
        self
    }

    /// Runs `sweeps` nonlinear Gauss–Seidel sweeps ([`Smoother`]) after every Newton iteration
    /// and before the first one of a step that does not start converged (0: none;
    /// [`DEFAULT_SWEEPS`] in bakes). A pass is kept only when it lowers the objective, so Newton
    /// still stops on its own residual: the sweeps change how many iterations a step takes, not
    /// what it converges to. Not with the constraint contact model, whose active set the
    /// sweeps would not respect.
    pub fn with_sweeps(mut self, sweeps: usize) -> Self {
        self.sweeps = sweeps;
        self.smoother = (sweeps > 0).then(|| Smoother::new(&self.sys));
        self
    }

    /// Runs on up to `threads` threads (default 1). With two or more, a large model's
    /// Gauss–Seidel sweeps move its two parts at once ([`Smoother`]), its preconditioner's
    /// two halves are factored and solved at once ([`SplitCholesky`]), and self-contact's
    /// phases split ([`SelfContact::with_threads`]): the same iterates as on one thread, to the
    /// bit, sooner. (Call it after [`NewtonSolver::with_self_contact`].)
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.use_threads(threads);
        self
    }

    /// As [`NewtonSolver::with_threads`], from the next step on (a helper thread is started or
    /// ended only when the count crosses two).
    fn use_threads(&mut self, threads: usize) {
        let threads = threads.max(1);
        let two = threads >= 2;
        self.threads = threads;
        if let Some(split) = self.split_factor.as_mut().filter(|s| s.has_helper() != two) {
            split.use_helper(two);
        }
        if let Some(mg) = &mut self.multigrid {
            mg.use_threads(two);
        }
        if let Some(s) = &mut self.self_contact {
            s.use_threads(threads);
        }
    }

    /// When the single-precision factor is split ([`SplitCholesky`]): the columns of its top
    /// and of its two halves.
    pub fn factor_halves(&self) -> Option<[usize; 3]> {
        self.split_factor.as_ref().map(SplitCholesky::sizes)
    }

    /// Sweep passes tried, and kept (lowering the objective), since the solver was made.
    pub fn sweep_passes(&self) -> (usize, usize) {
        (self.passes[0], self.passes[1])
    }

    /// Whether iterations are followed by sweeps: a count above zero, and no constraint contact.
    fn sweeping(&self) -> bool {
        self.smoother.is_some() && self.contact.as_ref().is_none_or(|c| c.is_barrier())
    }

    /// One pass of the Gauss–Seidel sweeps from `x`, whose objective is `g`: keeps the result
    /// when it lowers the objective.
    fn sweep(&mut self, x: &mut [DVec3], g: f64) {
        if !self.sweeping() {
            return;
        }
        let Some(smoother) = &self.smoother else {
            return;
        };
        let contact = self.contact.as_ref();
        let mut trial = std::mem::take(&mut self.trial);
        trial.copy_from_slice(x);
        smoother.sweep(
            &self.sys,
            &mut trial,
            &self.y,
            self.sweeps,
            contact,
            &mut self.sweep_scratch,
            self.threads >= 2,
        );
        self.passes[0] += 1;
        if self.self_contact.is_some() {
            // The sweeps do not see the cloth's contact with itself: their move is cut where it
            // would pass through.
            let t = self.self_path(x, &trial);
            if t < 1.0 {
                for (p, x) in trial.iter_mut().zip(x.iter()) {
                    *p = *x + (*p - *x) * t;
                }
            }
        }
        if self.energy(&trial) < g {
            x.copy_from_slice(&trial);
            self.passes[1] += 1;
            if let Some(c) = self.contact.as_mut() {
                c.set_iterate(x);
            }
        }
        self.trial = trial;
    }

    /// The objective g(x) plus the friction potential, joules.
    fn energy(&self, x: &[DVec3]) -> f64 {
        self.sys.objective(x, &self.y)
            + self.contact.as_ref().map_or(0.0, |c| c.energy(x))
            + self
                .self_contact
                .as_ref()
                .filter(|s| s.ready())
                .map_or(0.0, |s| s.energy(x))
    }

    /// Writes the line search's trial x + α·Δx into `trial` (projected out of the colliders and
    /// settled onto them, unless contact is a barrier, whose energy refuses such trials itself)
    /// and returns the objective there.
    fn energy_along(&mut self, x: &[DVec3], alpha: f64, trial: &mut [DVec3]) -> f64 {
        for ((t, x), d) in trial.iter_mut().zip(x).zip(self.dx.chunks_exact(3)) {
            *t = *x + DVec3::from_slice(d) * alpha;
        }
        if !self.contact.as_ref().is_some_and(NewtonContact::is_barrier) {
            self.project(trial);
            self.settle(trial);
            // The projection left the line: its path is checked on its own.
            if self.contact.is_some() && self.self_path(x, trial) < 1.0 {
                return f64::INFINITY;
            }
        }
        self.energy(trial)
    }

    /// Records the relative residual at every Newton iterate of each step (the starting point
    /// included) and the line search's step lengths, readable with [`NewtonSolver::history`]
    /// and [`NewtonSolver::step_lengths`].
    pub fn record_history(&mut self, on: bool) {
        self.history = on.then(Vec::new);
        self.step_lengths = on.then(Vec::new);
    }

    /// Relative residuals ‖∇g‖/force scale at each iterate of the last step, first to last.
    pub fn history(&self) -> Option<&[f64]> {
        self.history.as_deref()
    }

    /// The step length α (a fraction of the Newton direction, 1 = the full step) the line
    /// search took in each iteration of the last step.
    pub fn step_lengths(&self) -> Option<&[f64]> {
        self.step_lengths.as_deref()
    }

    /// Newton's working vectors at the end of the last step, read-only, for diagnostics
    /// (`examples/newton_probe.rs` splits the gradient into its terms with them).
    pub fn diagnostics(&self) -> NewtonDiagnostics<'_> {
        NewtonDiagnostics {
            x0: &self.x0,
            y: &self.y,
            grad: &self.grad,
            free_grad: &self.free_grad,
            held: &self.held,
            colliders: self.contact.as_ref().map(NewtonContact::colliders),
        }
    }

    /// Whether the line search tries twice a full step: as [`NewtonSolver::with_longer_step`]
    /// sets, but never with a body moving within the steps (the fold on the fast box in
    /// `tests/it/cloth_body_sequence.rs` then cycles through four iterates at ρ 0.15–0.23 until
    /// the cap; with full steps only it converges in a few).
    fn longer_steps(&self) -> bool {
        self.try_longer && self.body_within.is_none()
    }

    /// The fraction of `span` times the direction (`self.dx`) from `x` the cloth can move
    /// without passing through itself ([`SelfContact::prepare_path`]), the obstacles moving
    /// along the same fraction of their remaining way too when `with_obstacles`
    /// ([`SelfContact::prepare_joint_path`]), times `span`.
    fn reach_along(&mut self, x: &[DVec3], span: f64, with_obstacles: bool) -> f64 {
        let Some(s) = &mut self.self_contact else {
            return f64::INFINITY;
        };
        let mut far = std::mem::take(&mut self.longer);
        for ((f, x), d) in far.iter_mut().zip(x).zip(self.dx.chunks_exact(3)) {
            *f = *x + DVec3::from_slice(d) * span;
        }
        let reach = if with_obstacles {
            s.prepare_joint_path(x, &far)
        } else {
            s.prepare_path(x, &far)
        };
        self.longer = far;
        span * reach
    }

    /// Moves the obstacles on towards their goal and the cloth along with them: the direction
    /// H⁻¹ of the barrier's pull by the obstacles' remaining motion, as far as the cloth and the
    /// obstacles can go together without a pair reaching its target distance, and halved until
    /// the objective there is finite.
    fn push(&mut self, x: &mut [DVec3]) -> Result<()> {
        let Some(s) = &self.self_contact else {
            return Ok(());
        };
        // The direction solves H·Δx = −∇g: with the drag in place of ∇g for this solve.
        let mut drag = std::mem::take(&mut self.drag);
        drag.fill(DVec3::ZERO);
        s.add_drag(&mut drag);
        std::mem::swap(&mut self.free_grad, &mut drag);
        let solved = self.solve_direction();
        std::mem::swap(&mut self.free_grad, &mut drag);
        self.drag = drag;
        solved?;
        let mut alpha = self.reach_along(x, 1.0, true).min(1.0);
        let mut trial = std::mem::take(&mut self.trial);
        let mut moved = false;
        for _ in 0..MAX_HALVINGS {
            if let Some(s) = &mut self.self_contact {
                s.set_obstacle_fraction(alpha);
            }
            if self.energy_along(x, alpha, &mut trial).is_finite() {
                x.copy_from_slice(&trial);
                moved = true;
                break;
            }
            alpha *= 0.5;
        }
        self.trial = trial;
        if let Some(s) = &mut self.self_contact {
            s.commit_obstacles(if moved { alpha } else { 0.0 });
            // A stalled push: cloth pinched between the body's parts lets them through.
            if !moved || alpha < super::self_contact::STALLED_PUSH {
                s.release_pinched(x);
            }
        }
        let at: &[DVec3] = x;
        self.self_path(at, at);
        Ok(())
    }

    fn non_finite(&self, what: &str, iteration: usize) -> Error {
        Error::Diverged {
            frame: 0,
            reason: format!(
                "non-finite {what} in Newton iteration {iteration} of time step {}",
                self.steps + 1
            ),
            advice: Vec::new(),
        }
    }
}

impl StepSolver for NewtonSolver {
    fn system(&self) -> &ReducedSystem {
        &self.sys
    }

    fn set_threads(&mut self, threads: usize) {
        self.use_threads(threads);
    }

    fn save(&mut self) -> bool {
        self.saved = Some((self.contact.clone(), self.self_contact.clone()));
        self.may_stop_early = true;
        true
    }

    fn restore(&mut self) {
        if let Some((contact, self_contact)) = self.saved.take() {
            self.contact = contact;
            self.self_contact = self_contact;
        }
    }

    fn free_path(&mut self, from: &[DVec3], to: &[DVec3]) -> f64 {
        match &mut self.self_contact {
            Some(s) => s.free_fraction(from, to),
            None => 1.0,
        }
    }

    fn set_time_step(&mut self, h: f64) {
        self.sys.params.time_step = h;
        if let Some(c) = &mut self.contact {
            c.set_time_step(h);
        }
    }

    fn drive(&mut self, pins: &[DVec3], shapes: Vec<(usize, Collider)>) -> Result<()> {
        self.sys.move_pins(pins);
        if let Some(s) = &mut self.self_contact {
            s.move_pins(pins);
            for (j, shape) in &shapes {
                if let Collider::Moving { after, .. } | Collider::Mesh(after) = shape {
                    s.move_obstacle(*j, after.positions());
                }
            }
        }
        if let Some(c) = &mut self.contact {
            for (j, shape) in shapes {
                if Some(j) != self.body_within {
                    c.set_shape(j, shape);
                }
            }
        }
        Ok(())
    }

    fn step(&mut self, x: &mut [DVec3], v: &mut [DVec3]) -> Result<StepStats> {
        let h = self.sys.params.time_step;
        let scale = self.sys.force_scale();
        self.sys.orient_bending(x);
        self.try_single = self.allow_single;
        self.x0.copy_from_slice(x);
        if let Some(c) = &mut self.contact {
            c.begin_step(x);
        }
        if let Some(s) = &mut self.self_contact {
            s.begin_step(x);
        }
        self.sys.predict(x, v, &mut self.y);
        // Start from y, or from x₀ + h·v₀ (no gravity: near pins, y stretches the springs by
        // h²g), whichever has the lower objective, each moved out of the colliders.
        for ((t, x0), v) in self.trial.iter_mut().zip(&self.x0).zip(v.iter()) {
            *t = *x0 + *v * h;
        }
        let mut trial = std::mem::take(&mut self.trial);
        self.project(&mut trial);
        x.copy_from_slice(&self.y);
        self.project(x);
        if self.energy(&trial) < self.energy(x) {
            x.copy_from_slice(&trial);
        }
        // With a moving body: also from x₀ + h·v₀ with the particles near the body carried along
        // with its surface instead (cloth resting on a limb moves with it).
        if let Some(c) = self.contact.as_ref().filter(|c| c.moves()) {
            for (i, ((t, x0), v)) in trial.iter_mut().zip(&self.x0).zip(v.iter()).enumerate() {
                let carry = c.carry(i);
                *t = if carry == DVec3::ZERO {
                    *x0 + *v * h
                } else {
                    *x0 + carry
                };
            }
            self.project(&mut trial);
            if self.energy(&trial) < self.energy(x) {
                x.copy_from_slice(&trial);
            }
        }
        self.trial = trial;
        self.feasible_start(x)?;
        if let Some(hist) = &mut self.history {
            hist.clear();
        }
        if let Some(steps) = &mut self.step_lengths {
            steps.clear();
        }
        let mut iterations = 0;
        let mut swept_start = false;
        let mut pushed = false;
        // (Not where a body moves within the step: there the pushes set the pace, and a box
        // lifting a fold converges its first step whole, after a long stretch without halving
        // its residual, but not as eighths.)
        let may_stop_early = std::mem::take(&mut self.may_stop_early)
            && !self
                .self_contact
                .as_ref()
                .is_some_and(SelfContact::obstacles_moving);
        // The lowest residual reached (halved at least), and when.
        let (mut lowest, mut lowest_at) = (f64::INFINITY, 0);
        let (residual, converged) = loop {
            self.assemble(x);
            let held = self.hold(x);
            let residual = super::system::norm(&self.free_grad) / scale;
            if let Some(hist) = &mut self.history {
                hist.push(residual);
            }
            if !residual.is_finite() {
                return Err(self.non_finite("gradient", iterations));
            }
            let moving = self
                .self_contact
                .as_ref()
                .is_some_and(SelfContact::obstacles_moving);
            if residual <= self.tolerance && !moving {
                break (residual, true);
            }
            if iterations == self.max_iterations {
                break (residual, false);
            }
            // While a body is still on its way, its progress is the step's.
            if moving || residual <= 0.5 * lowest {
                (lowest, lowest_at) = (residual, iterations);
            } else if may_stop_early
                && lowest > STALLED_FAR * self.tolerance
                && iterations - lowest_at >= STALLED
            {
                break (residual, false);
            }
            if !swept_start && self.sweeping() {
                // The start is not converged: sweep it first.
                swept_start = true;
                let g = self.energy(x);
                self.sweep(x, g);
                continue;
            }
            if held {
                self.filter_hessian();
            }
            self.factorize()?;
            if moving && !pushed {
                pushed = true;
                self.push(x)?;
                iterations += 1;
                continue;
            }
            pushed = false;
            self.solve_direction()?;
            iterations += 1;

            // Backtracking line search on g along dx, projecting out of the colliders.
            let g0 = self.energy(x);
            let slope: f64 = self
                .free_grad
                .iter()
                .zip(self.dx.chunks_exact(3))
                .map(|(g, d)| g.dot(DVec3::from_slice(d)))
                .sum();
            if !(g0.is_finite() && slope.is_finite()) {
                return Err(self.non_finite("objective or direction", iterations));
            }
            let slack = ROUNDOFF * g0.abs();
            // With self-contact the search stays on the part of the line the cloth can move
            // along without passing through itself.
            let mut reach = f64::INFINITY;
            if self.self_contact.is_some() {
                let span = if self.longer_steps() {
                    LONGER_STEP
                } else {
                    1.0
                };
                reach = self.reach_along(x, span, false);
            }
            let mut alpha = reach.min(1.0);
            let mut g = f64::INFINITY;
            let mut trial = std::mem::take(&mut self.trial);
            for _ in 0..MAX_HALVINGS {
                g = self.energy_along(x, alpha, &mut trial);
                if g <= g0 + ARMIJO * alpha * slope + slack {
                    break;
                }
                alpha *= 0.5;
            }
            if self.longer_steps() && alpha == 1.0 && reach >= LONGER_STEP && g.is_finite() {
                // The full step was accepted: twice its length is tried too.
                let mut longer = std::mem::take(&mut self.longer);
                // Near the solution g's changes are roundoff, and a longer step kept on noise
                // would throw the iterate to the mirror point: it must gain more than the slack.
                let g_longer = self.energy_along(x, LONGER_STEP, &mut longer);
                if g_longer < g - slack {
                    (g, alpha) = (g_longer, LONGER_STEP);
                    std::mem::swap(&mut trial, &mut longer);
                }
                self.longer = longer;
            }
            if let Some(steps) = &mut self.step_lengths {
                steps.push(alpha);
            }
            // A barrier's infinite energy never enters x: with no feasible trial, x stays (a
            // NaN still does, and is reported as non-finite at the next gradient).
            if g != f64::INFINITY {
                x.copy_from_slice(&trial);
                if let Some(c) = self.contact.as_mut().filter(|c| c.is_barrier()) {
                    c.set_iterate(x);
                }
                if self.contact.as_ref().is_some_and(|c| !c.is_barrier()) {
                    // The projected trials each checked their own path: the pairs around the
                    // new iterate are found again.
                    let at: &[DVec3] = x;
                    self.self_path(at, at);
                }
            }
            self.trial = trial;
            if g != f64::INFINITY {
                self.sweep(x, g);
            }
        };
        for ((v, x), x0) in v.iter_mut().zip(x.iter()).zip(&self.x0) {
            *v = (*x - *x0) / h;
        }
        self.steps += 1;
        let self_contacts = match &mut self.self_contact {
            Some(s) => {
                let active = s.active_count();
                s.end_step(x);
                active
            }
            None => 0,
        };
        let (contacts, pinched) = match &mut self.contact {
            Some(c) => (c.end_step(x, &self.grad), c.pinched()),
            None => (0, 0),
        };
        Ok(StepStats {
            iterations,
            residual,
            converged,
            contacts,
            self_contacts,
            steps: 1,
            pinched,
            pinched_pairs: self.self_contact.as_ref().map_or(0, SelfContact::pinched),
        })
    }
}

#[cfg(test)]
mod tests;
