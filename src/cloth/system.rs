//! The per-step problem both solvers minimise, with pinned particles removed from the unknowns.
//!
//! Implicit Euler with mass-proportional damping (force −c·m·v evaluated at the end of the step):
//!
//! ```text
//! m (v₁ − v₀) = h (f_int(x₁) + m g − c m v₁),   x₁ = x₀ + h v₁
//! ⇔ x₁ = argmin g(x),   g(x) = s/(2h²) ‖x − y‖²_M + E(x)
//!    s = 1 + h c,   y = x₀ + (h v₀ + h² g) / s,   v₁ = (x₁ − x₀) / h
//! ```
//! so the damping only scales the inertia term: the matrix stays constant and `c = 0` is plain
//! implicit Euler. Pinned particles are constants (x = Kᵀx_f + b): a spring with one pinned end
//! becomes an *anchor* from a free particle to a fixed point.
//!
//! Free particles are renumbered once in a fill-reducing order, so factors need no permutation
//! and spring loops touch memory in a cache-friendly order.

use glam::DVec3;

use super::law::spring_gradient;
use super::linalg::fill_reducing_order;
use super::material::{from_frame, hinge_frame};
use super::membrane::Membrane;
use super::model::ClothModel;
use super::term::{self, Bending, Inertia, Springs, Term};
use crate::error::Result;

/// Time stepping constants shared by the solvers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepParams {
    /// Time step h in seconds.
    pub time_step: f64,
    /// Mass-proportional damping c in 1/s (0 = none).
    pub damping: f64,
    /// Gravity in m/s², in the body's frame.
    pub gravity: DVec3,
}

#[cfg(test)]
impl StepParams {
    /// A garment's step in tests: 30 steps a second, no damping, full gravity.
    pub(crate) fn garment() -> Self {
        StepParams {
            time_step: 1.0 / 30.0,
            damping: 0.0,
            gravity: DVec3::new(0.0, -9.81, 0.0),
        }
    }
}

/// Springs between two free particles, structure of arrays, solver indices.
#[derive(Debug, Clone, Default)]
pub struct FreeSprings {
    /// First end.
    pub a: Vec<u32>,
    /// Second end.
    pub b: Vec<u32>,
    /// Rest length, m.
    pub rest: Vec<f64>,
    /// Stiffness in tension, N/m.
    pub k: Vec<f64>,
    /// Stiffness in compression, N/m.
    pub kc: Vec<f64>,
}

/// Springs from a free particle to a pinned (fixed) point.
#[derive(Debug, Clone, Default)]
pub struct Anchors {
    /// The free end (solver index).
    pub a: Vec<u32>,
    /// The fixed end's position, m.
    pub at: Vec<DVec3>,
    /// The fixed end's particle (model index), for [`ReducedSystem::move_pins`].
    pub pinned: Vec<u32>,
    /// Rest length, m.
    pub rest: Vec<f64>,
    /// Stiffness in tension, N/m.
    pub k: Vec<f64>,
    /// Stiffness in compression, N/m.
    pub kc: Vec<f64>,
}

/// Quadratic bending stencils on the free particles (see [`super::material`]): energy
/// ½·|Σᵢ wᵢ xᵢ + fixed|² each, pinned vertices and the rest shape folded into
/// [`FreeBends::fixed`].
///
/// A curved rest ([`super::material::BendRest::Mesh`]) is the stencil's rest value in its
/// hinge's frame, turned into the world by the frame at the start of each step
/// ([`ReducedSystem::orient_bending`]): within a step the target is a constant, so the energy
/// stays quadratic with the same constant Hessian, and a hinge that turns rigidly between steps
/// carries its rest shape along.
#[derive(Debug, Clone, Default)]
pub struct FreeBends {
    /// Solver index of each vertex, [`PINNED`] where it is pinned (its weight is then zero).
    pub v: Vec<[u32; 4]>,
    /// Weights, √(N/m).
    pub w: Vec<[f64; 4]>,
    /// (stencil, pinned particle in model order, weight) of every pinned vertex in
    /// `pinned_sum`.
    pub fixed_terms: Vec<(u32, u32, f64)>,
    /// Model index of each vertex (for the hinge's frame).
    pub corners: Vec<[u32; 4]>,
    /// The rest value in the hinge's frame ([`super::material::BendStencil::rest`]).
    pub rest: Vec<DVec3>,
    /// The rest target in the world for the current step, √(N/m)·m.
    pub target: Vec<DVec3>,
    /// Σ wᵢ xᵢ over the pinned vertices, √(N/m)·m.
    pub pinned_sum: Vec<DVec3>,
}

/// The solver index [`FreeBends`] gives a pinned vertex.
pub const PINNED: u32 = u32::MAX;

impl FreeBends {
    /// Number of stencils.
    pub fn len(&self) -> usize {
        self.v.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.v.is_empty()
    }

    /// The constant part of stencil `s`: Σ wᵢ xᵢ over its pinned vertices less its rest target,
    /// √(N/m)·m.
    #[inline]
    pub fn fixed(&self, s: usize) -> DVec3 {
        self.pinned_sum[s] - self.target[s]
    }

    /// Σ wᵢ xᵢ + fixed of stencil `s` at `x`.
    #[inline]
    pub fn value(&self, s: usize, x: &[DVec3]) -> DVec3 {
        let mut sum = self.fixed(s);
        for (&v, &w) in self.v[s].iter().zip(&self.w[s]) {
            if v != PINNED {
                sum += x[v as usize] * w;
            }
        }
        sum
    }

    /// The free pairs (i, j), i ≠ j, that stencils couple, less each stencil's two opposite
    /// vertices when `coupling` leaves them out.
    pub fn pairs(&self, coupling: BendCoupling) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.v
            .iter()
            .flat_map(move |v| stencil_pairs(*v, coupling))
            .filter(|&(a, b)| a != PINNED && b != PINNED && a != b)
            .map(|(a, b)| (a as usize, b as usize))
    }
}

/// Which vertex pairs of a bending stencil a solver's matrix couples (and so which pairs the
/// fill-reducing order of [`ReducedSystem::with_coupling`] sees).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BendCoupling {
    /// All six: the exact bending Hessian (the fast solver's matrix).
    #[default]
    All,
    /// All but the two opposite vertices ([`OPPOSITE`]): Newton's split factor
    /// ([`super::newton::BendingFactor::Split`]). An opposite pair is two edges apart on the
    /// mesh; leaving it out halves the 8k-vertex skirt's factor (2.0 against 4.8 million
    /// entries, 26 against 57 ms in single precision).
    WithoutOpposite,
}

/// The positions, in a [`super::material::BendStencil`]'s vertices, of its two opposite vertices (the
/// triangles' corners off the shared edge).
pub const OPPOSITE: (usize, usize) = (2, 3);

/// The vertex pairs of a stencil with vertices `v` that `coupling` keeps.
fn stencil_pairs<T: Copy>(v: [T; 4], coupling: BendCoupling) -> impl Iterator<Item = (T, T)> {
    (0..4)
        .flat_map(|i| (i + 1..4).map(move |j| (i, j)))
        .filter(move |&ij| coupling == BendCoupling::All || ij != OPPOSITE)
        .map(move |(i, j)| (v[i], v[j]))
}

/// The reduced system: free particles only, in solver order.
#[derive(Debug, Clone)]
pub struct ReducedSystem {
    /// Step constants.
    pub params: StepParams,
    /// Particle index (in the model) of each solver unknown.
    pub particle_of: Vec<u32>,
    /// Mass of each free particle, kg.
    pub mass: Vec<f64>,
    /// Springs between free particles.
    pub springs: FreeSprings,
    /// Springs from free particles to pins.
    pub anchors: Anchors,
    /// Quadratic bending stencils.
    pub bends: FreeBends,
    /// The triangle membrane (empty for edge springs).
    pub membrane: Membrane,
    /// Compression strain past which a spring softer in compression jams (a fraction of its rest
    /// length; [`ClothModel::jam_strain`]).
    pub jam_strain: f64,
    /// Solver index of each model particle ([`PINNED`] where pinned); kept only when a bending
    /// stencil has a curved rest (empty otherwise).
    solver_of: Vec<u32>,
    /// Model-ordered positions whose pinned entries are where the pins are, m; kept only with a
    /// curved rest.
    pinned_at: Vec<DVec3>,
}

impl ReducedSystem {
    /// Removes the pins from `model` and orders the free particles for a matrix that couples
    /// every pair of particles a spring or a bending stencil joins.
    ///
    /// # Errors
    /// Only when the ordering fails (out of memory).
    pub fn new(model: &ClothModel, params: StepParams) -> Result<Self> {
        Self::with_coupling(model, params, BendCoupling::All)
    }

    /// As [`ReducedSystem::new`], ordering for a matrix whose bending stencils couple the
    /// pairs `coupling` keeps.
    ///
    /// # Errors
    /// Only when the ordering fails (out of memory).
    pub fn with_coupling(
        model: &ClothModel,
        params: StepParams,
        coupling: BendCoupling,
    ) -> Result<Self> {
        let n = model.particle_count();
        let mut solver_of = vec![u32::MAX; n];
        let free: Vec<u32> = (0..n as u32)
            .filter(|&i| !model.pinned[i as usize])
            .collect();
        for (s, &p) in free.iter().enumerate() {
            solver_of[p as usize] = s as u32;
        }
        let spring_pairs = model.springs.iter().map(|s| (s.a, s.b));
        let bend_pairs = model
            .bending
            .iter()
            .flat_map(|s| stencil_pairs(s.vertices, coupling));
        let membrane_pairs = model.membrane.iter().flat_map(|t| {
            let [a, b, c] = t.corners;
            [(a, b), (a, c), (b, c)]
        });
        let pairs = spring_pairs
            .chain(bend_pairs)
            .chain(membrane_pairs)
            .filter_map(|(a, b)| {
                let (a, b) = (solver_of[a as usize], solver_of[b as usize]);
                (a != u32::MAX && b != u32::MAX && a != b).then_some((a as usize, b as usize))
            });
        let order = fill_reducing_order(free.len(), pairs)?;
        let particle_of: Vec<u32> = order.iter().map(|&o| free[o as usize]).collect();
        for (s, &p) in particle_of.iter().enumerate() {
            solver_of[p as usize] = s as u32;
        }

        let mut springs = FreeSprings::default();
        let mut anchors = Anchors::default();
        // Visit springs grouped by their lower solver index, for locality in the spring loops.
        let mut sorted: Vec<_> = model.springs.iter().collect();
        sorted.sort_by_key(|s| solver_of[s.a as usize].min(solver_of[s.b as usize]));
        for s in sorted {
            let (a, b) = (solver_of[s.a as usize], solver_of[s.b as usize]);
            match (a != u32::MAX, b != u32::MAX) {
                (true, true) => {
                    springs.a.push(a);
                    springs.b.push(b);
                    springs.rest.push(s.rest);
                    springs.k.push(s.stiffness);
                    springs.kc.push(s.compression);
                }
                (true, false) | (false, true) => {
                    let (free_end, pinned_end) = if a != u32::MAX { (a, s.b) } else { (b, s.a) };
                    anchors.a.push(free_end);
                    anchors.at.push(model.mesh.positions[pinned_end as usize]);
                    anchors.pinned.push(pinned_end);
                    anchors.rest.push(s.rest);
                    anchors.k.push(s.stiffness);
                    anchors.kc.push(s.compression);
                }
                (false, false) => {}
            }
        }
        let mut bends = FreeBends::default();
        for st in &model.bending {
            let mut v = [PINNED; 4];
            let mut w = [0.0; 4];
            let mut fixed = DVec3::ZERO;
            let mut terms = Vec::new();
            for i in 0..4 {
                let p = st.vertices[i] as usize;
                if solver_of[p] == u32::MAX {
                    fixed += model.mesh.positions[p] * st.weights[i];
                    terms.push((bends.v.len() as u32, p as u32, st.weights[i]));
                } else {
                    v[i] = solver_of[p];
                    w[i] = st.weights[i];
                }
            }
            if v.iter().any(|&i| i != PINNED) {
                let target = from_frame(hinge_frame(st.corners(&model.mesh.positions)), st.rest);
                bends.v.push(v);
                bends.w.push(w);
                bends.fixed_terms.extend(terms);
                bends.corners.push(st.vertices);
                bends.rest.push(st.rest);
                bends.target.push(target);
                bends.pinned_sum.push(fixed);
            }
        }
        let membrane = Membrane::new(
            &model.membrane,
            &solver_of,
            &model.mesh.positions,
            model.jam_strain,
        );
        let mass = particle_of
            .iter()
            .map(|&p| model.mass[p as usize])
            .collect();
        let curved = bends.rest.iter().any(|r| *r != DVec3::ZERO);
        Ok(ReducedSystem {
            params,
            solver_of: if curved { solver_of } else { Vec::new() },
            pinned_at: if curved {
                model.mesh.positions.clone()
            } else {
                Vec::new()
            },
            particle_of,
            mass,
            springs,
            anchors,
            bends,
            membrane,
            jam_strain: model.jam_strain,
        })
    }

    /// Number of unknown particles.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// True when there are no unknowns.
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// The inertia scale s = 1 + h·c.
    pub fn inertia_scale(&self) -> f64 {
        1.0 + self.params.time_step * self.params.damping
    }

    /// Moves the pinned particles to their positions in `all` (model order, metres; the free
    /// entries are not read): the constants b of x = Kᵀx_f + b that springs and bending stencils
    /// see. A pin driven along a path (a garment's waist on a walking character) calls this
    /// before each step with the pins' positions at the end of the step.
    pub fn move_pins(&mut self, all: &[DVec3]) {
        self.membrane.move_pins(all);
        for (at, &p) in self.anchors.at.iter_mut().zip(&self.anchors.pinned) {
            *at = all[p as usize];
        }
        let b = &mut self.bends;
        for f in &mut b.pinned_sum {
            *f = DVec3::ZERO;
        }
        for &(s, p, w) in &b.fixed_terms {
            b.pinned_sum[s as usize] += all[p as usize] * w;
            if let Some(at) = self.pinned_at.get_mut(p as usize) {
                *at = all[p as usize];
            }
        }
    }

    /// Turns the curved rest shape of every bending stencil into the world by its hinge's frame
    /// at `x` (solver order; pinned corners where the pins are): called by the solvers at the
    /// start of each step. A no-op for a flat rest.
    pub fn orient_bending(&mut self, x: &[DVec3]) {
        if self.solver_of.is_empty() {
            return;
        }
        let b = &mut self.bends;
        for s in 0..b.v.len() {
            if b.rest[s] == DVec3::ZERO {
                continue;
            }
            let p = b.corners[s].map(|m| match self.solver_of[m as usize] {
                PINNED => self.pinned_at[m as usize],
                i => x[i as usize],
            });
            b.target[s] = from_frame(hinge_frame(p), b.rest[s]);
        }
    }

    /// The free particles' entries of `all` (model order), in solver order.
    pub fn gather(&self, all: &[DVec3]) -> Vec<DVec3> {
        self.particle_of.iter().map(|&p| all[p as usize]).collect()
    }

    /// Writes solver-ordered `free` into the model-ordered `all` (pinned entries untouched).
    pub fn scatter(&self, free: &[DVec3], all: &mut [DVec3]) {
        for (&p, x) in self.particle_of.iter().zip(free) {
            all[p as usize] = *x;
        }
    }

    /// The inertial target y = x₀ + (h v₀ + h² g)/s.
    pub fn predict(&self, x0: &[DVec3], v0: &[DVec3], y: &mut [DVec3]) {
        let StepParams {
            time_step: h,
            gravity,
            ..
        } = self.params;
        let s = self.inertia_scale();
        for ((y, x), v) in y.iter_mut().zip(x0).zip(v0) {
            *y = *x + (*v * h + gravity * (h * h)) / s;
        }
    }

    /// The objective g(x) = s/(2h²)‖x − y‖²_M + E(x), in joules.
    pub fn objective(&self, x: &[DVec3], y: &[DVec3]) -> f64 {
        self.inertia_term(y).total_energy(x)
            + self.spring_term().total_energy(x)
            + self.anchor_term().total_energy(x)
            + Bending(&self.bends).total_energy(x)
            + self.membrane.total_energy(x)
    }

    /// The inertia towards the targets `y` as a term ([`Inertia`]).
    pub fn inertia_term<'a>(&'a self, y: &'a [DVec3]) -> Inertia<'a> {
        let h = self.params.time_step;
        Inertia {
            mass: &self.mass,
            target: y,
            weight: self.inertia_scale() / (h * h),
            half_weight: self.inertia_scale() / (2.0 * h * h),
        }
    }

    /// The springs between free particles as a term ([`Springs`]).
    pub fn spring_term(&self) -> Springs<'_> {
        Springs {
            set: &self.springs,
            jam: self.jam_strain,
        }
    }

    /// The springs to pinned points as a term ([`term::Anchors`]).
    pub fn anchor_term(&self) -> term::Anchors<'_> {
        term::Anchors {
            set: &self.anchors,
            jam: self.jam_strain,
        }
    }

    /// The gradient ∇g(x) (newtons), written into `grad`.
    pub fn gradient(&self, x: &[DVec3], y: &[DVec3], grad: &mut [DVec3]) {
        let h = self.params.time_step;
        let w = self.inertia_scale() / (h * h);
        for ((g, (x, y)), m) in grad.iter_mut().zip(x.iter().zip(y)).zip(&self.mass) {
            *g = (*x - *y) * (w * m);
        }
        let s = &self.springs;
        for i in 0..s.a.len() {
            let (a, b) = (s.a[i] as usize, s.b[i] as usize);
            let f = spring_gradient(x[a] - x[b], s.rest[i], s.k[i], s.kc[i], self.jam_strain);
            grad[a] += f;
            grad[b] -= f;
        }
        let an = &self.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            grad[a] += spring_gradient(
                x[a] - an.at[i],
                an.rest[i],
                an.k[i],
                an.kc[i],
                self.jam_strain,
            );
        }
        self.add_bending_gradient(x, grad);
        self.membrane.add_gradient(x, grad);
    }

    /// Adds the bending stencils' gradient wᵢ·(Σ wⱼ xⱼ + fixed) to `grad` (N).
    pub fn add_bending_gradient(&self, x: &[DVec3], grad: &mut [DVec3]) {
        let b = &self.bends;
        for s in 0..b.len() {
            let value = b.value(s, x);
            for (&v, &w) in b.v[s].iter().zip(&b.w[s]) {
                if v != PINNED {
                    grad[v as usize] += value * w;
                }
            }
        }
    }

    /// The force scale (N) that residuals are measured against: the weight ‖M·g‖ of the free
    /// particles, or their total mass × 1 m/s² when there is no gravity.
    pub fn force_scale(&self) -> f64 {
        let g = self.params.gravity.length().max(1.0);
        let m2: f64 = self.mass.iter().map(|m| m * m).sum();
        m2.sqrt() * g
    }
}

/// Euclidean norm of a stack of vectors.
pub fn norm(v: &[DVec3]) -> f64 {
    v.iter().map(|x| x.length_squared()).sum::<f64>().sqrt()
}
