//! Mass-spring cloth and soft bodies: model, solvers, and the bake loop that records frames.
//!
//! Data flows one way: [`ClothModel`] (particles, springs, masses, pins) → [`ReducedSystem`]
//! (pins removed, unknowns ordered) → a [`StepSolver`] (with its [`collide::Colliders`]) →
//! [`simulate`] (which adds the [`wind`] before each step) records a [`FrameCache`].
//!
//! The layers, each using only those below it:
//! - the model: [`model`], [`springs`], [`material`], [`pins`], [`preset`];
//! - the step's objective: [`system`] (the reduced unknowns), the fabric's one-dimensional
//!   [`law`], and its energy terms in [`term`] (inertia, springs, anchors, bending) and
//!   [`membrane`], each with its value, gradient and projected Hessian blocks, checked by one
//!   finite-difference test; contact with colliders ([`collide`]) and with itself
//!   ([`self_contact`], distances in [`proximity`]);
//! - the solvers: [`newton`] (Newton's method, its pattern, direction and contact glue in
//!   their own files), [`fast`] (the local/global method) and [`smooth`] (the Gauss–Seidel
//!   sweeps);
//! - the linear algebra they share: `linalg` (sparse Cholesky factors, fill-reducing orders,
//!   the factor in two halves on two threads, the thread hand-off).

pub mod collide;
pub mod drive;
pub mod fast;
pub mod law;
// The linear algebra is internal; benches/cloth.rs measures the factors with the `internals`
// feature.
#[cfg(feature = "internals")]
pub mod linalg;
#[cfg(not(feature = "internals"))]
pub(crate) mod linalg;
pub mod material;
pub mod membrane;
pub mod model;
pub mod newton;
pub mod pins;
pub mod preset;
pub mod proximity;
pub mod self_contact;
pub mod smooth;
pub mod springs;
pub mod system;
pub mod term;
pub mod wind;

use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;

pub use fast::FastSolver;
pub use model::ClothModel;
pub use newton::{BendingFactor, LinearSolver, NewtonDiagnostics, NewtonSolver};
pub use system::{ReducedSystem, StepParams};
pub use wind::{Aerodynamics, Wind};

use collide::Colliders;

use crate::cores::Threads;
use crate::error::{Error, Result};

/// What one solver step reports.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StepStats {
    /// Iterations used (local/global iterations, or Newton iterations).
    pub iterations: usize,
    /// Final ‖∇g‖ relative to the free particles' weight (dimensionless).
    pub residual: f64,
    /// False when the step ended above the solver's tolerance (it stopped at its cap).
    pub converged: bool,
    /// Particles touching a collider at the end of the step (the most over a frame's substeps).
    pub contacts: usize,
    /// Cloth–cloth pairs (vertex–triangle, edge–edge) inside their self-contact layer at the
    /// end of the step (the most over a frame's substeps; 0 without self-contact).
    pub self_contacts: usize,
    /// Solver steps taken (1 a step; more where it was split, [`BakeParams::splits`]; summed over
    /// a frame's substeps).
    pub steps: usize,
    /// Particles a moving body pinched behind its surface at the step's start, released from
    /// it until they come out (summed over a frame's steps; see
    /// [`collide::contact::NewtonContact::make_feasible`]).
    pub pinched: usize,
    /// Self-contact pairs of a body's vertex or edge with the cloth released as pinched, the body
    /// let through the cloth there (summed over a frame's steps; see
    /// [`self_contact::SelfContact::release_pinched`]).
    pub pinched_pairs: usize,
}

impl StepStats {
    /// The figures of two steps taken one after the other.
    fn then(self, next: StepStats) -> StepStats {
        StepStats {
            iterations: self.iterations + next.iterations,
            residual: self.residual.max(next.residual),
            converged: self.converged && next.converged,
            contacts: self.contacts.max(next.contacts),
            self_contacts: self.self_contacts.max(next.self_contacts),
            steps: self.steps + next.steps,
            pinched: self.pinched + next.pinched,
            pinched_pairs: self.pinched_pairs + next.pinched_pairs,
        }
    }
}

/// A time integrator advancing the free particles of a [`ReducedSystem`] by one step.
pub trait StepSolver {
    /// The system being solved.
    fn system(&self) -> &ReducedSystem;

    /// Advances positions `x` (m) and velocities `v` (m/s), both free particles in solver order,
    /// by one time step.
    ///
    /// # Errors
    /// A solver may fail when its linear system cannot be factored.
    fn step(&mut self, x: &mut [DVec3], v: &mut [DVec3]) -> Result<StepStats>;

    /// Moves what drives the cloth to where it is at the end of the next step: the pinned
    /// particles to their entries of `pins` (model order, metres; free entries are not read),
    /// and each `(j, shape)` of `shapes` replaces collider `j` (a moving body).
    ///
    /// # Errors
    /// [`Error::Value`] when the solver cannot take moving colliders (only Newton can; a job
    /// refuses the fast solver on a moving body first, naming its options).
    fn drive(&mut self, pins: &[DVec3], shapes: Vec<(usize, collide::Collider)>) -> Result<()>;

    /// Uses up to `threads` threads from the next step on (a bake's share of the cores changes
    /// as other jobs end); the steps' results do not depend on it. Solvers that run on one
    /// thread ignore it.
    fn set_threads(&mut self, _threads: usize) {}

    /// Keeps what the next step changes besides the particles' positions and velocities (the
    /// contacts' lagged forces and layers, where a moving body has got to), so that
    /// [`StepSolver::restore`] can take it again; false when the solver cannot (its steps are
    /// then never split). A saved step may end unconverged before its iteration cap where it
    /// stops making progress: it is to be taken again in halves.
    fn save(&mut self) -> bool {
        false
    }

    /// Returns to what [`StepSolver::save`] kept.
    fn restore(&mut self) {}

    /// Sets the time step (seconds) of the following steps.
    fn set_time_step(&mut self, _h: f64) {}

    /// The fraction of the straight move of the free particles from `from` to `to` (solver
    /// order, between steps) the cloth can make without passing through itself: 1 for the
    /// whole move, and for solvers without self-contact. See [`LoopClosure`].
    fn free_path(&mut self, _from: &[DVec3], _to: &[DVec3]) -> f64 {
        1.0
    }
}

/// Which solver a bake uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SolverKind {
    /// Local/global fast mass-spring with a prefactored matrix ([`FastSolver`]).
    Fast,
    /// Newton's method with a sparse Cholesky per iteration ([`NewtonSolver`]).
    Newton,
}

/// Settings of a bake.
#[derive(Debug, Clone, PartialEq)]
pub struct BakeParams {
    /// Frames to simulate after the initial state (frame 0).
    pub frames: usize,
    /// Frames per second of the output animation.
    pub fps: f64,
    /// Solver steps per frame; the time step is 1 / (fps · substeps) seconds.
    pub substeps: usize,
    /// How many times over a step may be split: a step that ends above the tolerance, or that
    /// the solver fails (a non-finite iterate, a Hessian that no longer factors), is taken again
    /// from its start as two steps of half its length (0: never; solvers that cannot take a
    /// step again ignore it). See [`StepSolver::save`].
    pub splits: usize,
    /// Mass-proportional damping in 1/s.
    pub damping: f64,
    /// Gravity in m/s².
    pub gravity: DVec3,
    /// The solver.
    pub solver: SolverKind,
    /// Local/global iterations per step at most (fast solver).
    pub iterations: usize,
    /// Every solver stops a step when ρ = ‖∇g‖ / force scale falls below this (dimensionless;
    /// see [`ReducedSystem::force_scale`]); a step that ends above it is reported unconverged.
    pub tolerance: f64,
    /// Newton iterations per step at most (default [`newton::DEFAULT_MAX_ITERATIONS`] = 200).
    pub max_newton: usize,
    /// Gauss–Seidel sweeps after each Newton iteration ([`NewtonSolver::with_sweeps`]; 0: none).
    pub sweeps: usize,
    /// Threads a bake may use (1: this one only; see [`NewtonSolver::with_threads`]), read
    /// before every frame.
    pub threads: Threads,
    /// How Newton solves for its directions ([`NewtonSolver::with_linear_solver`]).
    pub linear_solver: LinearSolver,
    /// What the cloth collides with (none when empty).
    pub colliders: Colliders,
    /// The cloth's contact with itself: its layer in metres (pairs of its primitives stay more
    /// than half of it apart; [`self_contact::SelfContact`]), `None` for none. Newton only.
    pub self_contact: Option<f64>,
    /// Aerodynamic forces, when any.
    pub wind: Option<Wind>,
    /// The first frame whose strain and crossings are measured ([`Simulation::quality`]): the
    /// frames before it are simulated but not written (a character's blend-in and warm-up).
    pub measure_from: usize,
    /// Steers the bake's last frames onto the frames one span earlier, so that it ends where the
    /// span began (a character's written loops joined up, `--loop-blend`); `None`: no steering.
    pub loop_closure: Option<LoopClosure>,
}

/// The last `frames` frames of a bake steered onto the frames `span` before them: before the
/// steps into frame k, the cloth's positions and velocities are moved a fraction β of the way to
/// those it had at frame k − 1 − span (the velocity from the two cached frames there), β rising
/// smoothly (3s² − 2s³) over the `frames` to 1 before the last frame's steps (less where the
/// cloth would pass through itself on the way: with self-contact, the move stops where additive
/// CCD stops it); each step is then solved as any other (to the tolerance, with every contact),
/// so the solver, not a cross-fade, carries the cloth onto the earlier frames' path.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoopClosure {
    /// Frames steered (the last of the bake).
    pub frames: usize,
    /// How many frames earlier their targets are: the written loops' length.
    pub span: usize,
}

impl LoopClosure {
    /// The fraction of the way to its target the state before frame `frame`'s steps is moved,
    /// for a bake of `last` frames (0 before the steered frames).
    pub fn weight(&self, frame: usize, last: usize) -> f64 {
        let s = (frame + self.frames).saturating_sub(last) as f64 / self.frames.max(1) as f64;
        s * s * (3.0 - 2.0 * s)
    }
}

impl BakeParams {
    /// Time step h in seconds.
    pub fn time_step(&self) -> f64 {
        1.0 / (self.fps * self.substeps as f64)
    }

    /// The step constants for the solvers.
    pub fn step_params(&self) -> StepParams {
        StepParams {
            time_step: self.time_step(),
            damping: self.damping,
            gravity: self.gravity,
        }
    }
}

pub use crate::data::FrameCache;
use crate::measure::{FrameMeasure, FrameQuality, Soup};

/// What a bake produced.
#[derive(Debug, Clone)]
pub struct Simulation {
    /// Positions of every particle at frames 0..=N.
    pub cache: FrameCache,
    /// Per-frame solver figures (frames 1..=N): iterations summed over substeps, worst residual.
    pub frames: Vec<StepStats>,
    /// Wall time spent stepping, seconds (measuring excluded where the stepping thread did it
    /// or waited for it; a measurement beside the next frame's steps is not subtracted).
    pub seconds: f64,
    /// Each frame's strain and crossings (frames `measured_from..=N`; frame 0 is the initial
    /// state), measured on the positions as cached (single precision) against the bodies as the
    /// solver saw them.
    pub quality: Vec<FrameQuality>,
    /// The first frame measured ([`BakeParams::measure_from`]).
    pub measured_from: usize,
    /// Wall time spent measuring them, seconds.
    pub seconds_measure: f64,
}

/// Builds the solver named by `params` for `model`.
///
/// # Errors
/// When the system cannot be ordered or factored.
pub fn make_solver(model: &ClothModel, params: &BakeParams) -> Result<Box<dyn StepSolver>> {
    make_driven_solver(model, params, None)
}

/// As [`make_solver`], for a bake whose collider `body` (an index into `params.colliders`, the
/// last one: a mesh) moves between frames. With self-contact and Newton, that body moves within
/// each step instead of between steps: it is one of self-contact's obstacles, pushing the cloth
/// along as it goes ([`NewtonSolver::with_body_within_steps`]), and leaves the colliders'
/// barrier (so it has no friction).
///
/// # Errors
/// As [`make_solver`].
pub fn make_driven_solver(
    model: &ClothModel,
    params: &BakeParams,
    body: Option<usize>,
) -> Result<Box<dyn StepSolver>> {
    let mut colliders = (!params.colliders.is_empty()).then(|| params.colliders.clone());
    let step = params.step_params();
    Ok(match params.solver {
        SolverKind::Fast => Box::new(
            FastSolver::new(ReducedSystem::new(model, step)?, params.iterations)?
                .with_tolerance(params.tolerance)
                .with_colliders(colliders),
        ),
        SolverKind::Newton => {
            let sys =
                ReducedSystem::with_coupling(model, step, BendingFactor::default().coupling())?;
            let within = body.filter(|&j| {
                params.self_contact.is_some()
                    && j + 1 == params.colliders.shapes.len()
                    && matches!(params.colliders.shapes[j], collide::Collider::Mesh(_))
            });
            let self_contact = params.self_contact.map(|layer| {
                self_contact::SelfContact::new(model, &sys, layer).with_obstacles(&params.colliders)
            });
            if let (Some(j), Some(c)) = (within, &mut colliders) {
                c.shapes.truncate(j);
                if c.shapes.is_empty() {
                    colliders = None;
                }
            }
            Box::new(
                NewtonSolver::with_linear_solver(
                    sys,
                    params.tolerance,
                    params.max_newton,
                    BendingFactor::default(),
                    params.linear_solver,
                )?
                .with_colliders(colliders)
                .with_self_contact(self_contact)
                .with_body_within_steps(within)
                .with_sweeps(params.sweeps)
                .with_threads(params.threads.now()),
            )
        }
    })
}

/// Simulates `params.frames` frames of `model` with `solver`, calling `progress(frame)` after
/// each frame.
///
/// # Errors
/// [`Error::Diverged`] naming the first frame with non-finite or exploding positions, or a step
/// whose ρ is non-finite or above [`DIVERGED_RESIDUAL`]; solver
/// errors as they come.
pub fn simulate(
    model: &ClothModel,
    solver: &mut dyn StepSolver,
    params: &BakeParams,
    progress: &mut dyn FnMut(usize),
) -> Result<Simulation> {
    simulate_driven(model, solver, params, None, progress)
}

/// A moving body driving a bake (a character or a mesh sequence): its pins and, when
/// `body_shape` is `Some(j)`, its body as collider `j` of the solver's colliders.
#[derive(Debug, Clone, Copy)]
pub struct Driven<'a> {
    /// The source of pin and body positions.
    pub drive: &'a dyn drive::Drive,
    /// Which collider is the body, if it collides.
    pub body_shape: Option<usize>,
}

/// As [`simulate`], with the pins and the body collider moved by a [`drive::Drive`] before every
/// step (to where they are at the end of the step).
///
/// # Errors
/// As [`simulate`]; the solver's refusal of moving colliders.
pub fn simulate_driven(
    model: &ClothModel,
    solver: &mut dyn StepSolver,
    params: &BakeParams,
    driven: Option<Driven<'_>>,
    progress: &mut dyn FnMut(usize),
) -> Result<Simulation> {
    let start = Instant::now();
    let mut all = model.positions().to_vec();
    let mut body_before = match driven {
        Some(Driven {
            drive,
            body_shape: Some(_),
        }) => drive.rest_body()?.map(std::sync::Arc::new),
        _ => None,
    };
    let mut cache = FrameCache::new(all.len());
    cache.push(&all);
    let measure = BodyMeasure::new(model, params, driven.and_then(|d| d.body_shape));
    let measure_from = params.measure_from.min(params.frames);
    let mut quality = Measurements::new(measure, params.frames + 1 - measure_from);
    if measure_from == 0 {
        quality.push(&all, body_before.clone(), false);
    }
    let sys = solver.system();
    let mut x = sys.gather(&all);
    let mut v = vec![DVec3::ZERO; x.len()];
    let guard = DivergenceGuard::new(model, params);
    let mut air = params.wind.clone().map(|w| AirState::new(w, model));
    let h = params.time_step();
    let mut frames = Vec::with_capacity(params.frames);
    for frame in 1..=params.frames {
        let threads = params.threads.now();
        solver.set_threads(threads);
        if let Some(closure) = params.loop_closure {
            let beta = closure.weight(frame, params.frames);
            if beta > 0.0 {
                steer(
                    &mut *solver,
                    &cache,
                    frame - 1 - closure.span,
                    params.fps,
                    beta,
                    &mut x,
                    &mut v,
                );
                solver.system().scatter(&x, &mut all);
            }
        }
        let mut stats: Option<StepStats> = None;
        for substep in 0..params.substeps {
            let step = ((frame - 1) * params.substeps + substep) as u64;
            let mut run = Stepping {
                solver: &mut *solver,
                driven,
                air: air.as_mut(),
                all: &mut all,
                body_before: &mut body_before,
                x: &mut x,
                v: &mut v,
            };
            let s = run.advance(step, h, params.splits).map_err(|e| match e {
                // Solvers don't know frames: name the frame being computed.
                Error::Diverged { reason, advice, .. } => Error::Diverged {
                    frame,
                    reason,
                    advice,
                },
                // A matrix that stops factoring mid-bake, every split tried, is a divergence
                // too (the dress on the whole kick, past its 30th frame).
                Error::Factorisation(m) => Error::Diverged {
                    frame,
                    reason: format!("the solver's matrix did not factor ({m})"),
                    advice: Vec::new(),
                },
                e => e,
            })?;
            stats = Some(stats.map_or(s, |before| before.then(s)));
        }
        let stats = stats.expect("a frame has at least one substep");
        guard.check(frame, &x, solver.system(), stats.residual)?;
        solver.system().scatter(&x, &mut all);
        cache.push(&all);
        if frame >= measure_from {
            // With a second thread, measured while the next frame is stepped.
            quality.push(&all, body_before.clone(), threads >= 2);
        }
        frames.push(stats);
        progress(frame);
    }
    let (quality, seconds_measure, waited) = quality.finish();
    Ok(Simulation {
        cache,
        frames,
        seconds: start.elapsed().as_secs_f64() - waited,
        quality,
        measured_from: measure_from,
        seconds_measure,
    })
}

/// Moves the free particles' positions `x` and velocities `v` (solver order) the fraction `beta`
/// of the way to the state of `cache`'s frame `target`: its positions, and the velocity from
/// the frame before it to it at `fps` (zero at frame 0); less where the cloth would pass
/// through itself on the way ([`StepSolver::free_path`]). See [`LoopClosure`].
fn steer(
    solver: &mut dyn StepSolver,
    cache: &FrameCache,
    target: usize,
    fps: f64,
    beta: f64,
    x: &mut [DVec3],
    v: &mut [DVec3],
) {
    let now = cache.frame(target);
    let before = cache.frame(target.saturating_sub(1));
    let goal = |x: DVec3, p: u32, b: f64| x * (1.0 - b) + now[p as usize].as_dvec3() * b;
    let to: Vec<DVec3> = x
        .iter()
        .zip(&solver.system().particle_of)
        .map(|(&x, &p)| goal(x, p, beta))
        .collect();
    let beta = beta * solver.free_path(x, &to).min(1.0);
    for ((x, v), &p) in x
        .iter_mut()
        .zip(v.iter_mut())
        .zip(&solver.system().particle_of)
    {
        let (p1, p0) = (now[p as usize].as_dvec3(), before[p as usize].as_dvec3());
        *x = goal(*x, p, beta);
        *v = *v * (1.0 - beta) + (p1 - p0) * (fps * beta);
    }
}

/// What a bake's steps move: the solver, what drives it, and the cloth's state.
struct Stepping<'a, 'b> {
    solver: &'a mut dyn StepSolver,
    driven: Option<Driven<'b>>,
    air: Option<&'a mut AirState>,
    /// Model-ordered positions (the pins' entries are where the drive put them).
    all: &'a mut Vec<DVec3>,
    /// The moving body where the last step left it.
    body_before: &'a mut Option<std::sync::Arc<collide::MeshCollider>>,
    x: &'a mut Vec<DVec3>,
    v: &'a mut Vec<DVec3>,
}

impl Stepping<'_, '_> {
    /// Takes step `k` of `h` seconds (from k·h to (k + 1)·h): one step, or, where that step ends
    /// above the tolerance or the solver fails it, two of half its length from the same start
    /// (steps 2k and 2k + 1 of h/2), each split again as needed up to `splits` times over
    /// ([`BakeParams::splits`]). A step that cannot be split further is kept as it ended
    /// (flagged unconverged), or its error returned. (Times counted in steps: a split step's
    /// halves end at the very times two substeps would.)
    fn advance(&mut self, k: u64, h: f64, splits: usize) -> Result<StepStats> {
        let saved = (splits > 0 && self.solver.save()).then(|| {
            (
                self.x.clone(),
                self.v.clone(),
                self.all.clone(),
                self.body_before.clone(),
            )
        });
        let outcome = self.step(k, h);
        let Some((x, v, all, body)) = saved else {
            return outcome;
        };
        // The failed attempt's iterations count (they took their time).
        let wasted = match outcome {
            Ok(s) if s.converged => return Ok(s),
            Ok(s) => s.iterations,
            Err(Error::Diverged { .. } | Error::Factorisation(_)) => 0,
            Err(e) => return Err(e),
        };
        *self.x = x;
        *self.v = v;
        *self.all = all;
        *self.body_before = body;
        self.solver.restore();
        self.solver.set_time_step(0.5 * h);
        let halves = self.advance(2 * k, 0.5 * h, splits - 1).and_then(|first| {
            let second = self.advance(2 * k + 1, 0.5 * h, splits - 1)?;
            Ok(first.then(second))
        });
        self.solver.set_time_step(h);
        halves.map(|s| StepStats {
            iterations: s.iterations + wasted,
            ..s
        })
    }

    /// Step `k` of the solver, from k·h to (k + 1)·h seconds: the wind, then the pins and the
    /// body moved to where they are at its end.
    fn step(&mut self, k: u64, h: f64) -> Result<StepStats> {
        if let Some(air) = self.air.as_deref_mut() {
            air.apply(self.solver.system(), k as f64 * h, h, self.x, self.v);
        }
        if let Some(d) = self.driven {
            let pose = d.drive.pose((k + 1) as f64 * h);
            for (b, p) in d.drive.pins().iter().zip(&pose.pins) {
                self.all[b.particle as usize] = *p;
            }
            let mut shapes = Vec::new();
            if let (Some(j), Some(before)) = (d.body_shape, self.body_before.as_ref()) {
                let moving = collide::Collider::moving(before.clone(), pose.body)?;
                if let collide::Collider::Moving { after, .. } = &moving {
                    *self.body_before = Some(after.clone());
                }
                shapes.push((j, moving));
            }
            self.solver.drive(self.all, shapes)?;
        }
        self.solver.step(self.x, self.v)
    }
}

/// The per-frame measurement of a bake: the cloth, and its mesh colliders (the moving body in
/// place of collider `moving`, when driven).
struct BodyMeasure {
    cloth: FrameMeasure,
    meshes: Vec<(usize, std::sync::Arc<collide::MeshCollider>)>,
    moving: Option<usize>,
}

impl BodyMeasure {
    fn new(model: &ClothModel, params: &BakeParams, moving: Option<usize>) -> Self {
        BodyMeasure {
            cloth: FrameMeasure::new(model.positions(), &model.mesh.triangles),
            meshes: params
                .colliders
                .shapes
                .iter()
                .enumerate()
                .filter_map(|(i, c)| match c {
                    collide::Collider::Mesh(m) => Some((i, m.clone())),
                    _ => None,
                })
                .collect(),
            moving,
        }
    }

    /// Measures `all` (model order) rounded as the cache stores it, `body` standing in for the
    /// moving collider; adds the time taken to `seconds`.
    fn frame(
        &self,
        all: &[DVec3],
        body: Option<&collide::MeshCollider>,
        seconds: &mut f64,
    ) -> FrameQuality {
        let start = Instant::now();
        let written: Vec<DVec3> = all.iter().map(|p| p.as_vec3().as_dvec3()).collect();
        let bodies: Vec<Soup<'_>> = self
            .meshes
            .iter()
            .map(|(i, m)| match body {
                Some(b) if Some(*i) == self.moving => b,
                _ => m.as_ref(),
            })
            .map(|m| Soup {
                positions: m.positions(),
                triangles: m.triangles(),
            })
            .collect();
        let q = self.cloth.frame(&written, &bodies);
        *seconds += start.elapsed().as_secs_f64();
        q
    }
}

/// A bake's per-frame measurements: each at once, or on a second thread while the stepping
/// thread goes on to the next frame (the same figures either way).
struct Measurements {
    measure: Arc<BodyMeasure>,
    pending: Option<std::thread::JoinHandle<(FrameQuality, f64)>>,
    quality: Vec<FrameQuality>,
    /// Seconds spent measuring, on either thread.
    seconds: f64,
    /// Seconds the stepping thread spent measuring, or waiting for a measurement.
    waited: f64,
}

impl Measurements {
    fn new(measure: BodyMeasure, frames: usize) -> Self {
        Measurements {
            measure: Arc::new(measure),
            pending: None,
            quality: Vec::with_capacity(frames),
            seconds: 0.0,
            waited: 0.0,
        }
    }

    /// Measures the next frame, `all` (model order) with `body` standing in for the moving
    /// collider: on a second thread when `aside`.
    fn push(&mut self, all: &[DVec3], body: Option<Arc<collide::MeshCollider>>, aside: bool) {
        let start = Instant::now();
        self.collect();
        if aside {
            let (measure, all) = (Arc::clone(&self.measure), all.to_vec());
            self.pending = Some(std::thread::spawn(move || {
                let mut seconds = 0.0;
                (measure.frame(&all, body.as_deref(), &mut seconds), seconds)
            }));
        } else {
            let q = self.measure.frame(all, body.as_deref(), &mut self.seconds);
            self.quality.push(q);
        }
        self.waited += start.elapsed().as_secs_f64();
    }

    /// Waits for the measurement on the second thread, if any.
    fn collect(&mut self) {
        if let Some(pending) = self.pending.take() {
            // A panic while measuring is passed on.
            let (q, seconds) = pending
                .join()
                .unwrap_or_else(|e| std::panic::resume_unwind(e));
            self.quality.push(q);
            self.seconds += seconds;
        }
    }

    /// Every frame's figures, the seconds spent measuring them, and the seconds the stepping
    /// thread spent measuring or waiting.
    fn finish(mut self) -> (Vec<FrameQuality>, f64, f64) {
        let start = Instant::now();
        self.collect();
        self.waited += start.elapsed().as_secs_f64();
        (self.quality, self.seconds, self.waited)
    }
}

/// The aerodynamics of a bake with model-ordered copies of the state (pinned particles keep
/// their rest positions and zero velocity).
struct AirState {
    aero: Aerodynamics,
    x: Vec<DVec3>,
    v: Vec<DVec3>,
}

impl AirState {
    fn new(wind: Wind, model: &ClothModel) -> Self {
        AirState {
            aero: Aerodynamics::new(wind, model),
            x: model.positions().to_vec(),
            v: vec![DVec3::ZERO; model.particle_count()],
        }
    }

    /// Integrates the aerodynamic forces over one step into the solver-ordered velocities `v`.
    fn apply(&mut self, sys: &ReducedSystem, time: f64, h: f64, x: &[DVec3], v: &mut [DVec3]) {
        sys.scatter(x, &mut self.x);
        sys.scatter(v, &mut self.v);
        self.aero.apply(time, h, &self.x, &mut self.v);
        for (v, &p) in v.iter_mut().zip(&sys.particle_of) {
            *v = self.v[p as usize];
        }
    }
}

/// A step that ends with forces this many times the cloth's weight unbalanced (ρ) did not solve
/// anything: its positions are noise, not an unconverged answer. Unconverged steps of real bakes
/// end orders of magnitude lower (the dress on the kicking mannequin stops its steps at ρ 5–12).
pub const DIVERGED_RESIDUAL: f64 = 1e6;

/// Detects a simulation that has blown up: non-finite positions, particles farther from the
/// start than free fall plus a wide margin could take them, or a step that ended with a
/// non-finite ρ or one above [`DIVERGED_RESIDUAL`].
struct DivergenceGuard {
    centre: DVec3,
    radius: f64,
}

impl DivergenceGuard {
    fn new(model: &ClothModel, params: &BakeParams) -> Self {
        let (lo, hi) = model.mesh.bounds();
        let duration = params.frames as f64 / params.fps;
        let fall = 0.5 * params.gravity.length() * duration * duration;
        // Beyond 1e9 m nothing is a cloth any more, and f32 caches lose every digit.
        let radius = (100.0 * ((hi - lo).length() + 1.0) + 2.0 * fall).min(1e9);
        DivergenceGuard {
            centre: (lo + hi) * 0.5,
            radius,
        }
    }

    fn check(&self, frame: usize, x: &[DVec3], sys: &ReducedSystem, residual: f64) -> Result<()> {
        if residual.is_nan() || residual > DIVERGED_RESIDUAL {
            return Err(Error::Diverged {
                frame,
                reason: format!(
                    "a step ended with forces {residual:.3e} times the cloth's weight unbalanced"
                ),
                advice: Vec::new(),
            });
        }
        for (i, p) in x.iter().enumerate() {
            let particle = sys.particle_of[i];
            if !p.is_finite() {
                return Err(Error::Diverged {
                    frame,
                    reason: format!("non-finite position at particle {particle}"),
                    advice: Vec::new(),
                });
            }
            if p.distance(self.centre) > self.radius {
                return Err(Error::Diverged {
                    frame,
                    reason: format!(
                        "particle {particle} flew {:.3e} m from the body's centre",
                        p.distance(self.centre)
                    ),
                    advice: Vec::new(),
                });
            }
        }
        Ok(())
    }
}
