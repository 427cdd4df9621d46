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

use super::factor::fill_reducing_order;
use super::model::ClothModel;
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

/// Springs between two free particles, structure of arrays, solver indices.
#[derive(Debug, Clone, Default)]
pub struct FreeSprings {
    /// First end.
    pub a: Vec<u32>,
    /// Second end.
    pub b: Vec<u32>,
    /// Rest length, m.
    pub rest: Vec<f64>,
    /// Stiffness, N/m.
    pub k: Vec<f64>,
}

/// Springs from a free particle to a pinned (fixed) point.
#[derive(Debug, Clone, Default)]
pub struct Anchors {
    /// The free end (solver index).
    pub a: Vec<u32>,
    /// The fixed end's position, m.
    pub at: Vec<DVec3>,
    /// Rest length, m.
    pub rest: Vec<f64>,
    /// Stiffness, N/m.
    pub k: Vec<f64>,
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
}

impl ReducedSystem {
    /// Removes the pins from `model` and orders the free particles.
    ///
    /// # Errors
    /// Only when the ordering fails (out of memory).
    pub fn new(model: &ClothModel, params: StepParams) -> Result<Self> {
        let n = model.particle_count();
        let mut solver_of = vec![u32::MAX; n];
        let free: Vec<u32> = (0..n as u32)
            .filter(|&i| !model.pinned[i as usize])
            .collect();
        for (s, &p) in free.iter().enumerate() {
            solver_of[p as usize] = s as u32;
        }
        let pairs = model.springs.iter().filter_map(|s| {
            let (a, b) = (solver_of[s.a as usize], solver_of[s.b as usize]);
            (a != u32::MAX && b != u32::MAX).then_some((a as usize, b as usize))
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
                }
                (true, false) | (false, true) => {
                    let (free_end, pinned_end) = if a != u32::MAX { (a, s.b) } else { (b, s.a) };
                    anchors.a.push(free_end);
                    anchors.at.push(model.mesh.positions[pinned_end as usize]);
                    anchors.rest.push(s.rest);
                    anchors.k.push(s.stiffness);
                }
                (false, false) => {}
            }
        }
        let mass = particle_of
            .iter()
            .map(|&p| model.mass[p as usize])
            .collect();
        Ok(ReducedSystem {
            params,
            particle_of,
            mass,
            springs,
            anchors,
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
        let h = self.params.time_step;
        let w = self.inertia_scale() / (2.0 * h * h);
        let inertia: f64 = x
            .iter()
            .zip(y)
            .zip(&self.mass)
            .map(|((x, y), m)| w * m * x.distance_squared(*y))
            .sum();
        let s = &self.springs;
        let spring: f64 = (0..s.a.len())
            .map(|i| {
                0.5 * s.k[i] * (x[s.a[i] as usize].distance(x[s.b[i] as usize]) - s.rest[i]).powi(2)
            })
            .sum();
        let an = &self.anchors;
        let anchor: f64 = (0..an.a.len())
            .map(|i| 0.5 * an.k[i] * (x[an.a[i] as usize].distance(an.at[i]) - an.rest[i]).powi(2))
            .sum();
        inertia + spring + anchor
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
            let f = spring_gradient(x[a] - x[b], s.rest[i], s.k[i]);
            grad[a] += f;
            grad[b] -= f;
        }
        let an = &self.anchors;
        for i in 0..an.a.len() {
            let a = an.a[i] as usize;
            grad[a] += spring_gradient(x[a] - an.at[i], an.rest[i], an.k[i]);
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

/// ∂/∂xa of ½k(|r| − l)² with r = xa − xb: k(|r| − l) r/|r| (zero for coincident ends).
#[inline]
pub fn spring_gradient(r: DVec3, rest: f64, k: f64) -> DVec3 {
    let len = r.length();
    if len > 0.0 {
        r * (k * (len - rest) / len)
    } else {
        DVec3::ZERO
    }
}

/// Euclidean norm of a stack of vectors.
pub fn norm(v: &[DVec3]) -> f64 {
    v.iter().map(|x| x.length_squared()).sum::<f64>().sqrt()
}
