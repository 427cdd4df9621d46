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
use super::material::{from_frame, hinge_frame};
use super::membrane::Membrane;
use super::model::ClothModel;
use super::term::Term;
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
                let len = x[s.a[i] as usize].distance(x[s.b[i] as usize]);
                spring_energy(len, s.rest[i], s.k[i], s.kc[i], self.jam_strain)
            })
            .sum();
        let an = &self.anchors;
        let anchor: f64 = (0..an.a.len())
            .map(|i| {
                let len = x[an.a[i] as usize].distance(an.at[i]);
                spring_energy(len, an.rest[i], an.k[i], an.kc[i], self.jam_strain)
            })
            .sum();
        let b = &self.bends;
        let bend: f64 = (0..b.len())
            .map(|s| 0.5 * b.value(s, x).length_squared())
            .sum();
        inertia + spring + anchor + bend + self.membrane.total_energy(x)
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

/// Half-width of the jamming ramp as a fraction of the jamming strain J: a spring softer in
/// compression than in tension stiffens from kc at a compression of (1 − JAM_RAMP)·J to kc + k
/// at (1 + JAM_RAMP)·J, as yarns pressed together jam gradually. With a sharp step the
/// tension's slope jumps from kc to kc + k (1000× for cotton), and Newton's quadratic model
/// overshoots into the jammed region and backtracks: on the 8k-vertex skirt over 30 frames a
/// sharp 9 % jam took 645 Newton iterations, a linear ramp of ±0.02 around it 467, and ±50 %
/// around the default 8 % 466 (`docs/performance.md`). The ramp is a smoothstep 3s² − 2s³ of
/// s = (compression − start)/width, so the slope's own derivative is continuous too.
pub const JAM_RAMP: f64 = 0.5;

/// The toe of a spring softer in compression than in tension, as a fraction of its rest
/// length: from the rest length to this stretch its stiffness rises linearly from kc to k, the
/// low-strain toe of woven fabric's J-shaped tensile curve (the yarns' crimp straightening).
/// Without it the tension's slope jumps from kc to k (1000× for cotton) at the rest length,
/// where many springs of a draping garment sit; with it and the smoothstep jamming ramp
/// ([`JAM_RAMP`]) the slope is continuous everywhere, and Newton on the 8k-vertex skirt hanging
/// for 30 frames took 404 iterations instead of 451 (`docs/performance.md`). A wider toe
/// converges sooner still (with the sweeps and the longer step: 1 % 137 iterations against 158)
/// but makes a garment sway longer: the robot skirt demo's loop seam grew from 2.1 mm to 7.0 mm,
/// and to 17 mm after six warm-up loops (`docs/performance.md`, "A longer step, and a wider toe
/// measured"). The toe lengthens a
/// spring under a given tension by half the toe, (k − kc)/k · TOE_STRAIN/2 of its rest length.
pub const TOE_STRAIN: f64 = 0.003;

/// A spring's tension f (N, positive when stretched) and its derivative df/d|r| (N/m) at length
/// `len`, with extension e = len − rest: f = k·e for e ≥ 0 and kc·e in compression, for
/// symmetric springs (kc = k: the labs' model). When kc < k the spring has a toe and jams:
/// - in tension its stiffness rises linearly from kc at the rest length to k at a stretch of
///   [`TOE_STRAIN`]·rest and stays k beyond: f = k·e − (k − kc)·τ(e), τ the toe's deficit
///   (e − e²/(2t) up to the toe t, t/2 past it);
/// - in compression, past (1 − [`JAM_RAMP`])·J·rest (J = `jam`, a fraction of the rest length),
///   the full tension stiffness k is added back along a smoothstep ramp that completes at
///   (1 + JAM_RAMP)·J·rest.
///
/// So df/d|r| is continuous for every length.
#[inline(always)]
pub fn spring_response(len: f64, rest: f64, k: f64, kc: f64, jam: f64) -> (f64, f64) {
    let e = len - rest;
    if kc >= k {
        let stiffness = if e >= 0.0 { k } else { kc };
        (stiffness * e, stiffness)
    } else if e >= 0.0 {
        let t = TOE_STRAIN * rest;
        let m = e.min(t);
        (
            k * e - (k - kc) * (m - m * m / (2.0 * t)),
            k - (k - kc) * (1.0 - m / t),
        )
    } else {
        let (lo, hi) = jam_ramp(rest, jam);
        (
            kc * e - k * ramp_integral(-e, lo, hi),
            kc + k * ramp(-e, lo, hi),
        )
    }
}

/// Energy of a spring of length `len` (J): the integral of [`spring_response`]'s tension.
#[inline]
pub fn spring_energy(len: f64, rest: f64, k: f64, kc: f64, jam: f64) -> f64 {
    let e = len - rest;
    if kc >= k {
        0.5 * (if e >= 0.0 { k } else { kc }) * e * e
    } else if e >= 0.0 {
        // ½k·e² less (k − kc)·∫τ, ∫τ = e²/2 − e³/(6t) up to the toe, t²/3 + t/2·(e − t) past it.
        let t = TOE_STRAIN * rest;
        let deficit = if e < t {
            e * e / 2.0 - e * e * e / (6.0 * t)
        } else {
            t * t / 3.0 + t / 2.0 * (e - t)
        };
        0.5 * k * e * e - (k - kc) * deficit
    } else {
        let (lo, hi) = jam_ramp(rest, jam);
        0.5 * kc * e * e + k * ramp_integral2(-e, lo, hi)
    }
}

/// The compressions (m) where the jamming ramp of a spring of rest length `rest` starts and ends.
#[inline(always)]
pub(crate) fn jam_ramp(rest: f64, jam: f64) -> (f64, f64) {
    ((1.0 - JAM_RAMP) * jam * rest, (1.0 + JAM_RAMP) * jam * rest)
}

/// The smoothstep ramp 3s² − 2s³ from 0 at `lo` to 1 at `hi`, s = (t − lo)/(hi − lo) clamped
/// to [0, 1].
#[inline(always)]
fn ramp(t: f64, lo: f64, hi: f64) -> f64 {
    let s = ((t - lo) / (hi - lo)).clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

/// ∫ ramp from −∞ to t: w·(s³ − s⁴/2) on the ramp (w = hi − lo), w/2 + (t − hi) past it.
#[inline(always)]
fn ramp_integral(t: f64, lo: f64, hi: f64) -> f64 {
    let w = hi - lo;
    if t <= lo {
        0.0
    } else if t < hi {
        let s = (t - lo) / w;
        w * s * s * s * (1.0 - 0.5 * s)
    } else {
        0.5 * w + (t - hi)
    }
}

/// ∫ [`ramp_integral`] from −∞ to t: w²·(s⁴/4 − s⁵/10) on the ramp, 3w²/20 + w/2·(t − hi) +
/// (t − hi)²/2 past it.
#[inline(always)]
fn ramp_integral2(t: f64, lo: f64, hi: f64) -> f64 {
    let w = hi - lo;
    if t <= lo {
        0.0
    } else if t < hi {
        let s = (t - lo) / w;
        w * w * s.powi(4) * (0.25 - 0.1 * s)
    } else {
        0.15 * w * w + 0.5 * w * (t - hi) + 0.5 * (t - hi) * (t - hi)
    }
}

/// The gradient f·u and the projected Hessian block of one spring, as rows: df/d|r| along u
/// and f/|r| across it, the latter clamped at zero for a compressed spring (whose exact
/// transverse term is negative), so every block is positive semi-definite.
#[inline(always)]
pub(crate) fn spring_terms(
    r: DVec3,
    rest: f64,
    k: f64,
    kc: f64,
    jam: f64,
) -> (DVec3, [[f64; 3]; 3]) {
    let len = r.length();
    if len > 0.0 {
        let (f, along) = spring_response(len, rest, k, kc, jam);
        let u = r / len;
        let t = (f / len).max(0.0);
        let p = along - t;
        let he = [
            [t + p * u.x * u.x, p * u.x * u.y, p * u.x * u.z],
            [p * u.y * u.x, t + p * u.y * u.y, p * u.y * u.z],
            [p * u.z * u.x, p * u.z * u.y, t + p * u.z * u.z],
        ];
        (u * f, he)
    } else {
        // Coincident ends: no force and no defined direction; the inertia keeps H definite.
        (DVec3::ZERO, [[0.0; 3]; 3])
    }
}

/// ∂/∂xa of a spring's energy with r = xa − xb: f·r/|r| with f from [`spring_response`] (zero
/// for coincident ends).
#[inline]
pub fn spring_gradient(r: DVec3, rest: f64, k: f64, kc: f64, jam: f64) -> DVec3 {
    let len = r.length();
    if len > 0.0 {
        r * (spring_response(len, rest, k, kc, jam).0 / len)
    } else {
        DVec3::ZERO
    }
}

/// Euclidean norm of a stack of vectors.
pub fn norm(v: &[DVec3]) -> f64 {
    v.iter().map(|x| x.length_squared()).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tension is the derivative of the energy and its slope the derivative of the tension
    /// (central differences), from past the toe in tension through the toe, the soft
    /// compression, the jamming ramp and past it; the slope is continuous everywhere (between
    /// neighbouring samples it changes by no more than its steepest rise, (k − kc)/t in the toe
    /// and 1.5·k/w on the ramp, times their distance: the former jump of k − kc at the rest
    /// length is 45 times that), is kc at the rest length and k past the toe, and reaches kc + k
    /// past the ramp.
    #[test]
    fn spring_response_is_the_energys_derivative_through_the_toe_and_the_jamming_ramp() {
        let (rest, k, kc, jam) = (0.01, 1000.0, 1.0, 0.08);
        let (lo, hi) = jam_ramp(rest, jam);
        assert!(lo < jam * rest && hi > jam * rest);
        assert!(((lo + hi) / 2.0 - jam * rest).abs() < 1e-15);
        let toe = TOE_STRAIN * rest;
        let d = 1e-9;
        let (mut on_ramp, mut in_toe) = (0, 0);
        let samples = 3000;
        let spacing = 0.2 * rest / samples as f64;
        let steepest = ((k - kc) / toe).max(1.5 * k / (hi - lo));
        let mut last_slope: Option<f64> = None;
        for i in 0..=samples {
            let len = rest * 1.05 - spacing * i as f64;
            let (f, slope) = spring_response(len, rest, k, kc, jam);
            let fd_f = (spring_energy(len + d, rest, k, kc, jam)
                - spring_energy(len - d, rest, k, kc, jam))
                / (2.0 * d);
            let fd_slope = (spring_response(len + d, rest, k, kc, jam).0
                - spring_response(len - d, rest, k, kc, jam).0)
                / (2.0 * d);
            assert!((f - fd_f).abs() < 1e-6, "len {len}: f {f} vs {fd_f}");
            assert!(
                (slope - fd_slope).abs() < 1e-4 * k,
                "len {len}: slope {slope} vs {fd_slope}"
            );
            if let Some(last) = last_slope {
                assert!(
                    (slope - last).abs() <= steepest * spacing * 1.001,
                    "len {len}: slope {slope} after {last}"
                );
            }
            last_slope = Some(slope);
            let e = len - rest;
            if e > 0.0 && e < toe {
                in_toe += 1;
                assert!(slope >= kc && slope <= k);
            }
            if -e > lo && -e < hi {
                on_ramp += 1;
                assert!(slope >= kc && slope <= kc + k);
            }
        }
        assert!(on_ramp > 200 && in_toe > 20, "{on_ramp} {in_toe}");
        assert!(k - kc > 40.0 * steepest * spacing);
        assert_eq!(spring_response(rest, rest, k, kc, jam), (0.0, kc));
        let past = rest * (1.0 + 2.0 * TOE_STRAIN);
        let (f, slope) = spring_response(past, rest, k, kc, jam);
        assert_eq!(slope, k);
        assert!((f - (k * (past - rest) - (k - kc) * toe / 2.0)).abs() < 1e-12);
        assert_eq!(spring_response(rest - hi * 1.1, rest, k, kc, jam).1, kc + k);
        assert_eq!(spring_response(rest - lo * 0.9, rest, k, kc, jam).1, kc);
        // Symmetric springs never jam and have no toe.
        assert_eq!(
            spring_response(rest * 0.5, rest, k, k, jam),
            (-k * rest * 0.5, k)
        );
        let len = rest + 0.5 * toe;
        assert_eq!(spring_response(len, rest, k, k, jam), (k * (len - rest), k));
    }
}
