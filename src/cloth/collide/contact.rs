//! Contact response inside the solvers.
//!
//! - Newton keeps every particle at least the thickness from every collider as a constraint:
//!   a projected Newton method holds the particles pushed into a collider along its normal and
//!   moves the others, projecting whatever enters a collider back out and settling the held
//!   ones back onto the surface they slid over; friction is a potential
//!   built from the normal force and normal of the previous step (lagged, as in incremental
//!   potential contact): μN·f(|slip|) with f quadratic below a slip of ε and linear above, so
//!   static friction holds the particle and sliding costs μN per metre ([`NewtonContact`]).
//!   A particle that starts closer to a collider than the thickness (a garment draped by another
//!   tool with a smaller margin) is kept at the distance it starts at until it moves away
//!   ([`rest_layer`]).
//! - With [`ContactModel::Barrier`] Newton has no active set: a barrier energy, zero beyond one
//!   and a half layers from a surface and unbounded at half a layer, joins the objective, and
//!   the line search rejects trial points past a barrier (looking from the last accepted
//!   iterate, so a path that crossed a surface is caught). Friction is the same lagged potential,
//!   built on the barrier's force.
//!
//! Positions are metres in the cloth's frame; forces newtons.

use glam::{DMat3, DVec3};

use super::barrier::{
    barrier_band, barrier_shape, barrier_strength, BarrierPlane, MIN_BARRIER_LAYER,
};
use super::{Collider, Colliders, SurfacePoint};
use crate::cloth::system::ReducedSystem;

/// Slip speed (m/s) below which Newton's friction acts as a stiff spring: static friction holds a
/// particle on a slope up to a creep of about this speed × tan(slope)/μ.
pub const STATIC_SLIP_SPEED: f64 = 1e-4;

/// A particle's contact with one collider in the previous step: what the friction is built on.
#[derive(Debug, Clone, Copy)]
struct LaggedContact {
    particle: u32,
    /// The surface (index into [`NewtonContact::surfaces`]).
    shape: u32,
    normal: DVec3,
    /// Normal force at the end of the previous step, N.
    force: f64,
}

/// a bᵀ.
#[inline]
fn outer3(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Newton's contact constraints and friction for the free particles of a [`ReducedSystem`].
///
/// Contact is a constraint, not an energy: every particle stays at least its layer (the
/// thickness, see [`rest_layer`]) from every collider. [`NewtonContact::project`] moves a
/// particle that went closer back out along the collider's normal; Newton holds the particles
/// that rest on a collider and are pushed into it along the normal ([`NewtonContact::holds`])
/// and solves for the others and the tangential motion (a projected Newton method on the
/// constraint set, the filtered solve of Baraff and Witkin 1998 inside Newton). The normal force
/// a collider exerts is what is left of the gradient along its normal at the end of the step;
/// friction is a potential built on the previous step's normal forces and normals (lagged, as in
/// incremental potential contact): μN·f(|slip|) with f quadratic below a slip of ε and linear
/// above, so static friction holds the particle and sliding costs μN per metre.
#[derive(Debug, Clone)]
pub struct NewtonContact {
    colliders: Colliders,
    /// The colliders as the surfaces particles are held off one by one ([`Collider::parts`]):
    /// the indices `j` below and the lagged contacts' `shape` count these.
    surfaces: Vec<Collider>,
    /// Where each collider's surfaces start in `surfaces` (one more entry than colliders).
    first: Vec<usize>,
    /// Friction slip scale ε, m.
    slip_scale: f64,
    lagged: Vec<LaggedContact>,
    /// Where each particle's entries in `lagged` (which is in particle order) start; length
    /// n + 1.
    lagged_start: Vec<u32>,
    x0: Vec<DVec3>,
    /// Per particle and surface (`i·surfaces + j`): the distance it is kept at, m. The collision
    /// thickness, except for a particle that started closer to that collider (see
    /// [`rest_layer`]), and zero while a moving body has it pinched inside that surface
    /// ([`NewtonContact::make_feasible`]). Empty until the first step.
    layer: Vec<f64>,
    /// Per particle and surface (`i·surfaces + j`): how far the collider's surface near the
    /// particle moves during the step, m (see [`Collider::carry`]). Empty while every collider
    /// is static.
    carry: Vec<DVec3>,
    /// Per particle: how far the moving colliders carry it during the step, m: the sum over
    /// the colliders of their nearest surface's `carry` (see [`NewtonContact::carry`]). Empty
    /// while every collider is static.
    carried: Vec<DVec3>,
    /// Per particle (from `near_start[i]` to `near_start[i + 1]`): the surfaces within
    /// `CLEAR_REACH` thicknesses of where it starts the step (see
    /// [`NewtonContact::candidates`]).
    near: Vec<u32>,
    near_start: Vec<u32>,
    /// Per particle: the least of `clear − 2·|carry|` over the other surfaces (infinite when
    /// there are none), m.
    far_clear: Vec<f64>,
    /// Every surface's index.
    every: Vec<u32>,
    /// Per particle and surface (`i·surfaces + j`): a lower bound on the distance from where the
    /// particle starts the step (as the collider sees it, [`NewtonContact::from`]) to a mesh
    /// collider's surface on the free side, m; zero for analytic shapes (which are cheap to ask)
    /// and for particles touching or behind a surface. See [`NewtonContact::out_of_reach`].
    clear: Vec<f64>,
    /// Per particle: the barrier's force scale c·mᵢ·g₀ (N), where contact is a barrier energy
    /// ([`ContactModel::Barrier`]); empty where it is a constraint.
    barrier: Vec<f64>,
    /// Per particle: the last feasible iterate ([`NewtonContact::set_iterate`]), where a
    /// barrier's queries look from: the segment from it to a trial point is the line search's
    /// path, so a trial that crossed a surface on the way is infeasible.
    iterate: Vec<DVec3>,
    /// Per particle, with the barrier: its least distance above a band's bottom at the last
    /// iterate Newton assembled ([`NewtonContact::add_derivatives`]), infinite where it was in
    /// no band, zero before the step's first assembly (m). A trial keeps [`GAP_KEPT`] of it
    /// (see [`NewtonContact::barrier_contacts`]).
    gap: Vec<f64>,
    /// Particles released in this step: pinched behind a moving body's surface
    /// ([`NewtonContact::make_feasible`]).
    pinched: usize,
    /// Per particle and surface (`i·surfaces + j`), with the barrier: the distance the particle
    /// starts the step at where that is inside its band, else its layer (m): where
    /// [`NewtonContact::project`] puts a particle that went closer, so a particle resting on a
    /// collider starts the step where it rested. Empty with the constraint, and while a
    /// collider moves (on the robot skirt demo, seats on the moving body left its loop seam at
    /// 88.8 mm instead of 6.7 mm; why was not found).
    seat: Vec<f64>,
}

/// How Newton keeps the cloth out of the colliders (`--contact`; the fast solver always uses
/// its filtered solve, see the module documentation).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum ContactModel {
    // (The variants' doc comments are `--help` text.)
    /// Every particle stays at least its layer (the thickness) from every collider: Newton
    /// holds the particles pushed into a collider along its normal (an active set)
    Constraint,
    /// A smooth barrier energy (incremental potential contact, Li et al. 2020) keeps each
    /// particle more than half its layer from every collider: zero beyond one and a half layers,
    /// unbounded towards half a layer, the contact forces part of the converged equilibrium
    #[default]
    Barrier,
}

/// How far [`NewtonContact::begin_step`] looks for a mesh collider's surface around each
/// particle, in collision thicknesses: a particle farther than this from every mesh skips their
/// queries while its motion in the step stays below about half of it.
const CLEAR_REACH: f64 = 16.0;

/// The fraction of its distance above a band's bottom (at most the band's width) a particle
/// keeps from one Newton iterate to the next: additive CCD's safety gap (Li et al. 2021) for
/// the colliders' barrier. Without it a line search may put a particle anywhere above the
/// bottom: on the dress on the kicking mannequin one sat at u = 1e-10, its Hessian block
/// 2e19 N/m against 3.4 N/m elsewhere, and the matrix no longer factored in double precision.
pub(super) const GAP_KEPT: f64 = 0.1;

/// The least depth into a barrier band (u) a step starts a particle at: one a moving body
/// carried deeper is projected out, or its layer thins to its distance
/// ([`NewtonContact::make_feasible`]). On a skirt on the walking CesiumMan a particle started
/// a step at u = 6e-10, its Hessian block 5e18 N/m, and the matrix no longer factored.
const START_DEPTH: f64 = 1e-3;

/// The layer of a particle released from a surface ([`NewtonContact::make_feasible`]).
const RELEASED: f64 = 0.0;

impl NewtonContact {
    /// Contact for `sys`'s particles, by the colliders' model ([`Colliders::model`]).
    pub fn new(colliders: Colliders, sys: &ReducedSystem) -> Self {
        let barrier = match colliders.model {
            ContactModel::Constraint => Vec::new(),
            ContactModel::Barrier => sys.mass.iter().map(|m| barrier_strength(*m)).collect(),
        };
        let mut first = vec![0];
        let mut surfaces = Vec::new();
        for shape in &colliders.shapes {
            surfaces.extend(shape.parts());
            first.push(surfaces.len());
        }
        let every = (0..surfaces.len() as u32).collect();
        NewtonContact {
            colliders,
            surfaces,
            first,
            slip_scale: STATIC_SLIP_SPEED * sys.params.time_step,
            lagged: Vec::new(),
            lagged_start: vec![0; sys.len() + 1],
            x0: vec![DVec3::ZERO; sys.len()],
            layer: Vec::new(),
            carry: Vec::new(),
            carried: Vec::new(),
            near: Vec::new(),
            near_start: Vec::new(),
            far_clear: Vec::new(),
            every,
            clear: Vec::new(),
            barrier,
            iterate: vec![DVec3::ZERO; sys.len()],
            gap: vec![0.0; sys.len()],
            pinched: 0,
            seat: Vec::new(),
        }
    }

    /// Remembers `x`, a feasible iterate, as where the barrier's queries look from (see
    /// [`ContactModel::Barrier`]); [`NewtonContact::begin_step`] sets it to the step's start.
    pub fn set_iterate(&mut self, x: &[DVec3]) {
        self.iterate.copy_from_slice(x);
    }

    /// True when contact is a barrier energy ([`ContactModel::Barrier`]).
    pub fn is_barrier(&self) -> bool {
        !self.barrier.is_empty()
    }

    /// Calls `f(j, surface, u, width)` for every barrier term of particle `i` at `p` (see
    /// [`NewtonContact::band_surfaces`]), u ∈ (0, 1) its depth into surface j's band (see
    /// [`barrier_shape`]) and `width` the band's (m); returns false, having stopped, when `p`
    /// is not above a band's bottom by [`GAP_KEPT`] of the particle's gap at the last
    /// assembled iterate (at most of the band's width; infeasible).
    #[inline]
    fn barrier_contacts(
        &self,
        i: usize,
        p: DVec3,
        mut f: impl FnMut(usize, &SurfacePoint, f64, f64),
    ) -> bool {
        let gap = self.gap[i];
        self.band_surfaces(i, p, 0.0, |j, s, lo, width| {
            if s.distance - lo <= kept(gap, width) {
                return false;
            }
            f(j, s, (s.distance - lo) / width, width);
            true
        })
    }

    /// Calls `f(j, surface, lo, width)` for every barrier term of particle `i` at `p` within its
    /// band's top plus `margin` (m) of surface j, with the band's bottom `lo` and `width` (m);
    /// stops and returns false as soon as `f` does. A term is the surface's nearest point (an
    /// analytic shape; a mesh the particle is at or below the band's bottom of, or whose layer
    /// the particle started within), or else one for each of the mesh's triangles within
    /// reach (their nearest points are no nearer than the surface's).
    #[inline]
    fn band_surfaces(
        &self,
        i: usize,
        p: DVec3,
        margin: f64,
        mut f: impl FnMut(usize, &SurfacePoint, f64, f64) -> bool,
    ) -> bool {
        let at = self.iterate[i];
        let x0 = self.x0[i];
        let moved = p.distance(x0).max(at.distance(x0));
        let (lo, width) = barrier_band(self.colliders.thickness);
        for &j in self.candidates(i, lo + width + margin, moved) {
            let (j, shape) = (j as usize, &self.surfaces[j as usize]);
            let start = self.from(i, j);
            if self.released(i, j) {
                continue;
            }
            let layer = self.layer(i, j);
            let (lo, width) = barrier_band(layer);
            let top = lo + width + margin;
            if self.out_of_reach(i, j, top, p, start) && self.out_of_reach(i, j, top, at, start) {
                continue;
            }
            let Some(s) = shape.contact(p, at, self.reach(top, p, at)) else {
                continue;
            };
            if s.distance >= top {
                continue;
            }
            if s.distance <= lo || !shape.is_mesh() {
                if !f(j, &s, lo, width) {
                    return false;
                }
                continue;
            }
            // In front of a mesh: a barrier for every triangle within the band, as incremental
            // potential contact sums its point–triangle pairs. The nearest point's alone has a
            // kink where two faces of a fold in the body are equally near, and a particle
            // pressed into the fold sat on it, its residual thousands of times the tolerance
            // (the dress on the kicking mannequin). A thinned layer's band sums its triangles
            // too: a skirt's waist on CesiumMan, its layer thinned to 0.3 mm at the hips, sat on
            // such a kink, its gap shrinking tenfold an iteration until a step ended with forces
            // 1.3e7 times the cloth's weight unbalanced.
            let mut feasible = true;
            shape.each_triangle_within(p, top, |t| {
                feasible = feasible && f(j, &t, lo, width);
            });
            if !feasible {
                return false;
            }
        }
        true
    }

    /// Makes `x`, a step's start (projected out of the colliders, [`NewtonContact::project`]),
    /// feasible for the barrier: a particle still at or below a band's bottom, or less than
    /// [`START_DEPTH`] of its width above it (pushed out of one part of a body into another, at
    /// a concave spot; carried towards a surface by a moving body), is projected again, up to
    /// a few times; where it then still is within half a layer of a surface, in front of it, that
    /// layer thins to the distance it is at (it grows back as the particle moves away, see
    /// [`NewtonContact::end_step`]). Returns how many particles remain behind a surface (none
    /// in a feasible start).
    ///
    /// With `release` (a body moving between steps), a particle still behind a surface is
    /// pinched: a body closed in on it closer than two layers (cloth caught where two thighs
    /// meet). It is released from that surface instead, held off it no more until it has come
    /// out of it by a tenth of the thickness ([`NewtonContact::end_step`]), and counted
    /// ([`NewtonContact::pinched`]); the frame's crossing count shows where it went through.
    pub fn make_feasible(&mut self, x: &mut [DVec3], release: bool) -> usize {
        const ROUNDS: usize = 4;
        let mut behind = 0;
        for (i, p) in x.iter_mut().enumerate() {
            let mut feasible = false;
            for _ in 0..ROUNDS {
                feasible = self.deepest(i, *p).is_some_and(|u| u > START_DEPTH);
                if feasible {
                    break;
                }
                self.project(i, p);
            }
            if feasible {
                continue;
            }
            // Pinched where two surfaces close in closer than two layers (an arm against the
            // torso, overlapping pieces of one body): projecting out of one pushes the particle
            // behind the other. Then it stays where it starts as the colliders see it (carried
            // with the surface it is on), in front of every surface there, and its layers thin.
            let at = self.iterate[i];
            if self.behind_any(i, *p, at) {
                *p = at;
            }
            let mut pinched = false;
            for (j, shape) in self.surfaces.iter().enumerate() {
                if self.released(i, j) {
                    continue;
                }
                let k = i * self.surfaces.len() + j;
                let (lo, width) = barrier_band(self.layer(i, j));
                let Some(s) = shape.contact(*p, at, self.reach(lo + width, *p, at)) else {
                    continue;
                };
                if s.distance <= lo + START_DEPTH * width {
                    if s.distance > 0.0 {
                        self.layer[k] = s.distance;
                    } else if release {
                        self.layer[k] = RELEASED;
                        pinched = true;
                    } else {
                        behind += 1;
                    }
                }
            }
            self.pinched += usize::from(pinched);
        }
        behind
    }

    /// The least depth u of particle `i` at `p` into any of its barrier bands (infinite in
    /// none); `None` where `p` is infeasible (see [`NewtonContact::barrier_contacts`]).
    fn deepest(&self, i: usize, p: DVec3) -> Option<f64> {
        let mut deepest = f64::INFINITY;
        self.barrier_contacts(i, p, |_, _, u, _| deepest = deepest.min(u))
            .then_some(deepest)
    }

    /// Particles released in this step, pinched behind a moving body's surface
    /// ([`NewtonContact::make_feasible`]).
    pub fn pinched(&self) -> usize {
        self.pinched
    }

    /// True when particle `i` at `p`, looked at from `at`, is on or behind a collider's surface.
    fn behind_any(&self, i: usize, p: DVec3, at: DVec3) -> bool {
        self.surfaces.iter().enumerate().any(|(j, shape)| {
            let (lo, width) = barrier_band(self.layer(i, j));
            !self.released(i, j)
                && shape
                    .contact(p, at, self.reach(lo + width, p, at))
                    .is_some_and(|s| s.distance <= 0.0)
        })
    }

    /// The barrier energy at `x`, joules: infinite where a particle is at or below a band's
    /// bottom.
    fn barrier_energy(&self, x: &[DVec3]) -> f64 {
        let mut total = 0.0;
        for (i, (p, c)) in x.iter().zip(&self.barrier).enumerate() {
            let feasible = self.barrier_contacts(i, *p, |_, _, u, width| {
                total += c * width * barrier_shape(u).0;
            });
            if !feasible {
                return f64::INFINITY;
            }
        }
        total
    }

    /// Replaces collider `j` (a body that moved: its pose at the end of the coming step, see
    /// [`Collider::Moving`]). Call before [`NewtonContact::begin_step`].
    pub fn set_shape(&mut self, j: usize, shape: Collider) {
        let parts = shape.parts();
        let slots = self.first[j]..self.first[j + 1];
        if parts.len() == slots.len() {
            for (slot, part) in self.surfaces[slots].iter_mut().zip(parts) {
                *slot = part;
            }
        } else {
            // Cut into other parts (not another pose of the same mesh): every per-surface
            // record starts again.
            let grown = parts.len() as isize - slots.len() as isize;
            self.surfaces.splice(slots, parts);
            for f in &mut self.first[j + 1..] {
                *f = (*f as isize + grown) as usize;
            }
            self.every = (0..self.surfaces.len() as u32).collect();
            self.far_clear.clear();
            self.clear.clear();
            self.carry.clear();
            self.seat.clear();
            self.layer.clear();
            self.lagged.clear();
            self.lagged_start.fill(0);
        }
        self.colliders.shapes[j] = shape;
    }

    /// Where particle `i` came from as collider `j` sees it: its position at the start of the
    /// step, carried along with the collider's surface near it (so a particle resting on a body
    /// that moves is still on the free side).
    #[inline]
    fn from(&self, i: usize, j: usize) -> DVec3 {
        match self.carry.get(i * self.surfaces.len() + j) {
            Some(c) => self.x0[i] + *c,
            None => self.x0[i],
        }
    }

    /// The colliders.
    pub fn colliders(&self) -> &Colliders {
        &self.colliders
    }

    /// Takes steps of `h` seconds from the next on (friction's slip scale follows it).
    pub fn set_time_step(&mut self, h: f64) {
        self.slip_scale = STATIC_SLIP_SPEED * h;
    }

    /// Remembers the start of the step (the friction's reference positions, and the side each
    /// particle comes from).
    ///
    /// At the first step, a particle that starts closer to a collider than the thickness (a
    /// garment draped on a body by another tool, with a smaller margin) gets a thinner layer
    /// there: the distance it starts at ([`rest_layer`]).
    pub fn begin_step(&mut self, x0: &[DVec3]) {
        self.x0.copy_from_slice(x0);
        self.gap.fill(0.0);
        self.pinched = 0;
        let shapes = self.surfaces.len();
        self.carry.clear();
        self.carried.clear();
        if self.surfaces.iter().any(Collider::is_moving) {
            let reach = 2.0 * self.colliders.thickness;
            for p in x0 {
                // Each collider carries the particle as its nearest part does.
                let mut carried = DVec3::ZERO;
                for parts in self.first.windows(2) {
                    let mut nearest: Option<(DVec3, f64)> = None;
                    for shape in &self.surfaces[parts[0]..parts[1]] {
                        let c = shape.carry(*p, reach);
                        self.carry.push(c.map_or(DVec3::ZERO, |c| c.0));
                        if let Some(c) = c.filter(|c| nearest.is_none_or(|n| c.1 < n.1)) {
                            nearest = Some(c);
                        }
                    }
                    carried += nearest.map_or(DVec3::ZERO, |n| n.0);
                }
                self.carried.push(carried);
            }
            debug_assert_eq!(self.carry.len(), x0.len() * shapes);
        }
        // The barrier looks from where each particle starts as the colliders see it: carried
        // along with a moving body's surface.
        for (i, p) in x0.iter().enumerate() {
            self.iterate[i] = *p + self.carry(i);
        }
        if self.layer.is_empty() {
            let t = self.colliders.thickness;
            self.layer = x0
                .iter()
                .flat_map(|p| {
                    self.surfaces
                        .iter()
                        .map(move |shape| rest_layer(t, shape.contact(*p, *p, t)))
                })
                .collect();
            if self.is_barrier() {
                // A barrier band needs room: a particle starting closer than a tenth of the
                // thickness (or behind a surface) is moved out to it at the first step.
                for l in &mut self.layer {
                    *l = l.max(MIN_BARRIER_LAYER * t);
                }
            }
        }
        // One query per particle and collider serves both the clearance from a mesh (up to
        // CLEAR_REACH thicknesses) and, with the barrier on static colliders, the seat (up to
        // the band's top, within that reach: a layer is at most the thickness).
        let seats = self.is_barrier() && self.carry.is_empty();
        let reach = CLEAR_REACH * self.colliders.thickness;
        let mut clear = std::mem::take(&mut self.clear);
        let mut seat = std::mem::take(&mut self.seat);
        clear.clear();
        seat.clear();
        for i in 0..x0.len() {
            for (j, shape) in self.surfaces.iter().enumerate() {
                let mesh = shape.is_mesh();
                let layer = self.layer(i, j);
                let (lo, width) = barrier_band(layer);
                let from = self.from(i, j);
                let surface = match (mesh, seats) {
                    (true, _) => shape.contact(from, from, reach),
                    (false, true) => shape.contact(from, from, lo + width),
                    (false, false) => None,
                };
                clear.push(match (mesh, surface) {
                    (false, _) => 0.0,
                    (true, None) => reach,
                    (true, Some(s)) => s.distance.max(0.0),
                });
                if seats {
                    seat.push(match surface {
                        Some(s) if s.distance > lo && s.distance < lo + width => s.distance,
                        _ => layer,
                    });
                }
            }
        }
        // The surfaces nothing of was within reach of a particle's start are out of its reach
        // while it moves less than about half of that (less their own motion), as
        // `out_of_reach` finds them one by one: the others are listed.
        self.near.clear();
        self.near_start.clear();
        self.near_start.push(0);
        self.far_clear.clear();
        for (i, clear) in clear.chunks_exact(shapes.max(1)).enumerate() {
            let mut far_clear = f64::INFINITY;
            for (j, &c) in clear.iter().enumerate() {
                if c >= reach {
                    let carry = self.carry.get(i * shapes + j).map_or(0.0, |c| c.length());
                    far_clear = far_clear.min(c - 2.0 * carry * (1.0 + 1e-9));
                } else {
                    self.near.push(j as u32);
                }
            }
            self.near_start.push(self.near.len() as u32);
            self.far_clear.push(far_clear);
        }
        self.clear = clear;
        self.seat = seat;
    }

    /// The surfaces a query of particle `i` that moved at most `moved` (m) from where it started
    /// the step, looking `layer` (m) around it, may find ([`NewtonContact::out_of_reach`] would
    /// skip every other): the surfaces near it at the start, or all of them when it moved far
    /// enough for the others to come within reach.
    #[inline]
    fn candidates(&self, i: usize, layer: f64, moved: f64) -> &[u32] {
        let needed = layer.max(self.colliders.thickness) + 2.0 * moved;
        match self.far_clear.get(i) {
            Some(&far) if far > needed * (1.0 + 1e-9) + 1e-9 => {
                &self.near[self.near_start[i] as usize..self.near_start[i + 1] as usize]
            }
            _ => &self.every,
        }
    }

    /// True when a query of collider `j` for particle `i` at `p`, from `from` (where it starts
    /// the step, [`NewtonContact::from`]) with the reach [`NewtonContact::reach`]`(layer, p,
    /// from)`, would answer `None`: the surface was at least `clear` away from `from`, so it is
    /// at least `clear − |p − from|` from `p` (beyond the reach `layer.max(t) + |p − from|`) and
    /// the segment from `from` to `p` cannot have crossed it. Exact: skipping such a query
    /// changes nothing (margins of 1e-9 cover the rounding of both distances).
    #[inline]
    fn out_of_reach(&self, i: usize, j: usize, layer: f64, p: DVec3, from: DVec3) -> bool {
        let clear = self
            .clear
            .get(i * self.surfaces.len() + j)
            .copied()
            .unwrap_or(0.0);
        let needed = layer.max(self.colliders.thickness) + 2.0 * p.distance(from);
        clear > needed * (1.0 + 1e-9) + 1e-9
    }

    /// Whether particle `i` is released from surface `j` (pinched behind it by a moving body,
    /// see [`NewtonContact::make_feasible`]): no surface holds it there.
    #[inline]
    fn released(&self, i: usize, j: usize) -> bool {
        self.layer(i, j) == RELEASED
    }

    /// The layer of particle `i` and collider `j`, m.
    #[inline]
    fn layer(&self, i: usize, j: usize) -> f64 {
        self.layer
            .get(i * self.surfaces.len() + j)
            .copied()
            .unwrap_or(self.colliders.thickness)
    }

    /// Moves particle `i` at `p` out of every collider it is closer to than its layer, along the
    /// collider's normal, and returns the surface it then rests on (the first collider it is
    /// within its layer of, up to a relative round-off allowance), if any.
    #[inline]
    pub fn project(&self, i: usize, p: &mut DVec3) -> Option<SurfacePoint> {
        let mut moved = false;
        let mut resting = None;
        let shapes = self.surfaces.len();
        for (j, shape) in self.surfaces.iter().enumerate() {
            let x0 = self.from(i, j);
            if self.released(i, j) {
                continue;
            }
            let layer = match self.seat.get(i * shapes + j) {
                Some(seat) => *seat,
                None => self.layer(i, j),
            };
            let touch = self.touch(layer);
            if self.out_of_reach(i, j, touch, *p, x0) {
                continue;
            }
            let Some(s) = shape.contact(*p, x0, self.reach(touch, *p, x0)) else {
                continue;
            };
            if s.distance < layer {
                *p += s.normal * (layer - s.distance);
                moved = true;
            } else if s.distance <= touch && resting.is_none() {
                resting = Some(s);
            }
        }
        if moved {
            self.resting(i, *p)
        } else {
            resting
        }
    }

    /// The surface particle `i` at `p` rests on: the first collider it is within its layer of
    /// (up to a relative round-off allowance).
    #[inline]
    pub fn resting(&self, i: usize, p: DVec3) -> Option<SurfacePoint> {
        self.resting_on(i, p).map(|(_, s)| s)
    }

    /// How far the moving colliders' surfaces near particle `i` move during the step, m (zero
    /// when none is near or every collider is static).
    #[inline]
    pub fn carry(&self, i: usize) -> DVec3 {
        self.carried.get(i).copied().unwrap_or(DVec3::ZERO)
    }

    /// True when a collider moves (its surface carries the particles near it).
    pub fn moves(&self) -> bool {
        !self.carry.is_empty()
    }

    /// As [`NewtonContact::resting`], with the collider's index.
    #[inline]
    fn resting_on(&self, i: usize, p: DVec3) -> Option<(usize, SurfacePoint)> {
        self.surfaces.iter().enumerate().find_map(|(j, shape)| {
            let x0 = self.from(i, j);
            let touch = self.touch(self.layer(i, j));
            if self.released(i, j) || self.out_of_reach(i, j, touch, p, x0) {
                return None;
            }
            shape
                .contact(p, x0, self.reach(touch, p, x0))
                .filter(|s| s.distance <= touch)
                .map(|s| (j, s))
        })
    }

    /// Moves particle `i` at `p`, held on a collider, back down onto its layer when it is above
    /// it by less than `reach` (m): a held particle sliding along a curved surface's tangent
    /// plane lifts off it by the square of its slide over twice the radius.
    #[inline]
    pub fn settle(&self, i: usize, p: &mut DVec3, reach: f64) {
        let above = self.surfaces.iter().enumerate().find_map(|(j, shape)| {
            let x0 = self.from(i, j);
            let layer = self.layer(i, j);
            let touch = self.touch(layer);
            if self.out_of_reach(i, j, touch + reach, *p, x0) {
                return None;
            }
            shape
                .contact(*p, x0, self.reach(touch + reach, *p, x0))
                .filter(|s| s.distance <= touch + reach)
                .map(|s| (s, layer))
        });
        if let Some((s, layer)) = above.filter(|(s, layer)| s.distance > *layer) {
            *p -= s.normal * (s.distance - layer);
        }
    }

    /// A layer plus a relative round-off allowance: a particle projected to its layer rests
    /// there.
    #[inline]
    fn touch(&self, layer: f64) -> f64 {
        layer + (layer.abs() + self.colliders.thickness) * 1e-9 + 1e-12
    }

    /// How far to look from `p` for a surface within `layer` of it, m.
    #[inline]
    fn reach(&self, layer: f64, p: DVec3, x0: DVec3) -> f64 {
        layer.max(self.colliders.thickness) + p.distance(x0)
    }

    /// Whether a particle resting on `surface` with objective gradient `grad` is held by it: the
    /// descent direction −∇g pushes it into the collider.
    #[inline]
    pub fn holds(surface: &SurfacePoint, grad: DVec3) -> bool {
        grad.dot(surface.normal) > 0.0
    }

    /// The friction slip of a lagged contact at `x`: the particle's displacement since the step
    /// began relative to the collider's surface, less its part along the contact normal (m).
    #[inline]
    fn slip(&self, c: &LaggedContact, p: DVec3) -> DVec3 {
        let i = c.particle as usize;
        let d = p - self.from(i, c.shape as usize);
        d - c.normal * d.dot(c.normal)
    }

    /// The friction potential's gradient and Newton's block for lagged contact `c` with its
    /// particle at `p`, T = I − nnᵀ: μN·s/m and μN/m·T with m = max(|s|, ε), which in the static
    /// regime (slip s shorter than ε) are the potential's gradient and Hessian.
    ///
    /// In the kinetic regime the potential's Hessian is μN/|s|·(T − ŝŝᵀ): zero along the slip,
    /// where the potential μN·|s| is linear. The block adds μN/|s| along ŝ, which makes its
    /// quadratic model μN(|s|²/2 + |s′|²/2)/|s| (at a slip s′) a majorizer of the potential over
    /// the whole tangent plane, static regime included (the reweighting of iteratively
    /// reweighted least squares). With the exact block a Newton step on a particle that slides
    /// and should stop overshoots past zero slip into a rise its model did not predict, and
    /// the line search cuts the whole cloth's step; with the majorizer friction never makes a
    /// line search fail (the draped dress's longest step: 19 Newton iterations with the exact
    /// block, 13 with this one; `docs/performance.md`). The solution is the same: only
    /// Newton's model of friction changes, not the potential.
    #[inline]
    fn friction_terms(&self, c: &LaggedContact, p: DVec3) -> (DVec3, DMat3) {
        let slip = self.slip(c, p);
        let w = self.colliders.friction * c.force / slip.length().max(self.slip_scale);
        (
            slip * w,
            DMat3::from_diagonal(DVec3::splat(w)) - outer3(c.normal, c.normal * w),
        )
    }

    /// The friction potential and, with [`ContactModel::Barrier`], the barrier energy at `x`,
    /// joules (infinite where a particle is at or below its barrier).
    pub fn energy(&self, x: &[DVec3]) -> f64 {
        let barrier = if self.is_barrier() {
            self.barrier_energy(x)
        } else {
            0.0
        };
        let (mu, eps) = (self.colliders.friction, self.slip_scale);
        let friction: f64 = self
            .lagged
            .iter()
            .map(|c| {
                let u = self.slip(c, x[c.particle as usize]).length();
                let f = if u < eps {
                    u * u / (2.0 * eps)
                } else {
                    u - 0.5 * eps
                };
                mu * c.force * f
            })
            .sum();
        barrier + friction
    }

    /// Appends to `out` the barrier planes of particle `i` at `p`: for every barrier term within
    /// its band's top plus `margin` of `p` ([`NewtonContact::band_surfaces`]), the plane through
    /// the term's nearest point facing `p`, for [`NewtonContact::particle_terms`] to evaluate
    /// the barrier against while `p` moves by less than `margin`. A triangle, or a convex
    /// collider, is never nearer than its plane, so a position the planes allow is feasible.
    pub fn barrier_planes(&self, i: usize, p: DVec3, margin: f64, out: &mut Vec<BarrierPlane>) {
        if self.barrier.is_empty() {
            return;
        }
        let gap = self.gap[i];
        self.band_surfaces(i, p, margin, |_, s, lo, width| {
            out.push(BarrierPlane {
                normal: s.normal,
                offset: s.distance - s.normal.dot(p),
                lo,
                width,
                kept: kept(gap, width),
            });
            true
        });
    }

    /// Adds particle `i`'s terms of [`NewtonContact::energy`] at `p` to its gradient `g` and
    /// Hessian block `h`, as [`NewtonContact::add_derivatives`] does for all particles, with the
    /// barrier evaluated against `planes` ([`NewtonContact::barrier_planes`]); false, having
    /// added nothing, when `p` is at or below a band's bottom.
    pub fn particle_terms(
        &self,
        i: usize,
        p: DVec3,
        planes: &[BarrierPlane],
        g: &mut DVec3,
        h: &mut DMat3,
    ) -> bool {
        if let Some(c) = self.barrier.get(i) {
            let (mut dg, mut dh) = (DVec3::ZERO, DMat3::ZERO);
            for plane in planes {
                if !plane.allows(p) {
                    return false;
                }
                let u = plane.depth(p);
                if u >= 1.0 {
                    continue;
                }
                let (_, d1, d2) = barrier_shape(u);
                let n = plane.normal;
                dg += n * (c * d1);
                dh += outer3(n, n * (c * d2 / plane.width));
            }
            *g += dg;
            *h += dh;
        }
        let mine = self.lagged_start[i] as usize..self.lagged_start[i + 1] as usize;
        for c in &self.lagged[mine] {
            let (dg, dh) = self.friction_terms(c, p);
            *g += dg;
            *h += dh;
        }
        true
    }

    /// Adds the gradient of [`NewtonContact::energy`] to `grad` and passes each particle's 3×3
    /// Hessian block (rows) to `block`.
    pub fn add_derivatives(
        &mut self,
        x: &[DVec3],
        grad: &mut [DVec3],
        mut block: impl FnMut(usize, [[f64; 3]; 3]),
    ) {
        // Barrier: gradient c·β′(u)·n, Hessian c·β″(u)/width·n nᵀ (the surface's curvature term
        // c·β′·∇²s is left out: for a convex collider it is negative semi-definite, and leaving
        // it out keeps the block positive semi-definite, as incremental potential contact's
        // projection does). Each particle's least gap is recorded for the trials to keep.
        for (i, (p, c)) in x.iter().zip(&self.barrier).enumerate() {
            let mut gap = f64::INFINITY;
            self.barrier_contacts(i, *p, |_, s, u, width| {
                let (_, d1, d2) = barrier_shape(u);
                grad[i] += s.normal * (c * d1);
                block(i, outer(s.normal, s.normal, c * d2 / width));
                gap = gap.min(u * width);
            });
            self.gap[i] = gap;
        }
        for c in &self.lagged {
            let i = c.particle as usize;
            let (g, h) = self.friction_terms(c, x[i]);
            grad[i] += g;
            // Symmetric: its columns are its rows.
            block(i, h.to_cols_array_2d());
        }
    }

    /// Records the contacts at the end of a step, where `grad` is the objective's gradient
    /// (friction included): each resting particle's normal force is the part of the gradient
    /// the collider takes (∇g·n when positive), or with the barrier model the barrier's force
    /// (each particle inside a band, at its nearest surface), for the next step's friction.
    /// Thinned layers grow back towards the thickness as their particles move away. Returns how
    /// many particles rest on a collider (are inside a band).
    pub fn end_step(&mut self, x: &[DVec3], grad: &[DVec3]) -> usize {
        let mut lagged = std::mem::take(&mut self.lagged);
        lagged.clear();
        if self.is_barrier() {
            // The normal force is the barrier's, at the nearest surface in reach.
            for (i, (p, c)) in x.iter().zip(&self.barrier).enumerate() {
                let mut nearest: Option<(usize, SurfacePoint, f64)> = None;
                self.barrier_contacts(i, *p, |j, s, u, _| {
                    if nearest.as_ref().is_none_or(|n| s.distance < n.1.distance) {
                        nearest = Some((j, *s, u));
                    }
                });
                if let Some((j, s, u)) = nearest {
                    lagged.push(LaggedContact {
                        particle: i as u32,
                        shape: j as u32,
                        normal: s.normal,
                        force: -c * barrier_shape(u).1,
                    });
                }
            }
        } else {
            for (i, (p, g)) in x.iter().zip(grad).enumerate() {
                if let Some((j, s)) = self.resting_on(i, *p) {
                    lagged.push(LaggedContact {
                        particle: i as u32,
                        shape: j as u32,
                        normal: s.normal,
                        force: g.dot(s.normal).max(0.0),
                    });
                }
            }
        }
        let t = self.colliders.thickness;
        let shapes = self.surfaces.len();
        // A layer grows to what the particle's distance is the top of: the layer itself with
        // the constraint; with the barrier the layer whose band ends there (a particle resting
        // inside its band, above its layer where it carries less than ten weights, is not
        // moving away, and its layer stays).
        let top = if self.is_barrier() {
            let (lo, width) = barrier_band(1.0);
            lo + width
        } else {
            1.0
        };
        for k in 0..self.layer.len() {
            if self.layer[k] < t {
                let (i, j) = (k / shapes, k % shapes);
                let from = self.from(i, j);
                let reach = top * t + x[i].distance(from);
                let distance = self.surfaces[j]
                    .contact(x[i], from, reach)
                    .map_or(top * t, |s| s.distance);
                if self.layer[k] == RELEASED && distance < top * MIN_BARRIER_LAYER * t {
                    // Still inside, or too near to hold without a band thinner than a tenth.
                    continue;
                }
                self.layer[k] = self.layer[k].max(distance / top).min(t);
            }
        }
        let touching = lagged.len();
        self.lagged_start.fill(0);
        for c in &lagged {
            self.lagged_start[c.particle as usize + 1] += 1;
        }
        for i in 1..self.lagged_start.len() {
            self.lagged_start[i] += self.lagged_start[i - 1];
        }
        self.lagged = lagged;
        touching
    }
}

/// The distance a particle starting at `start` (its contact with one collider, asked with the
/// thickness `t` as reach; `None` when farther) is kept from that collider, m: `t`, or the
/// distance it starts at when that is smaller. A garment draped on a body by another tool with a
/// smaller margin stays where it is instead of being pushed off the body at the first step (a
/// particle starting behind the surface of a solid is held where it is, not pushed through the
/// body); the layer grows back as the particle moves away ([`NewtonContact::end_step`]).
#[inline]
pub fn rest_layer(t: f64, start: Option<SurfacePoint>) -> f64 {
    start.map_or(t, |s| s.distance.min(t))
}

/// How far above a band's bottom (m) a trial keeps a particle whose gap at the last assembled
/// iterate was `gap`, in a band `width` wide: [`GAP_KEPT`] of the lesser.
#[inline]
fn kept(gap: f64, width: f64) -> f64 {
    GAP_KEPT * gap.min(width)
}

/// w·a bᵀ as rows.
#[inline]
fn outer(a: DVec3, b: DVec3, w: f64) -> [[f64; 3]; 3] {
    [
        (b * (w * a.x)).to_array(),
        (b * (w * a.y)).to_array(),
        (b * (w * a.z)).to_array(),
    ]
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::cloth::collide::mesh::MeshCollider;
    use crate::cloth::collide::HalfSpace;
    use crate::cloth::preset::lab_cloth;
    use crate::cloth::StepParams;
    use crate::data::statics::StaticMesh;

    /// A closed sphere mesh of radius 0.3 m around the origin (the exporter's, see
    /// [`StaticMesh::sphere`]), as a mesh collider.
    fn ball_mesh() -> Collider {
        mesh_collider(&StaticMesh::sphere(DVec3::ZERO, 0.3, "ball"))
    }

    /// An exporter's static mesh as a mesh collider.
    fn mesh_collider(mesh: &StaticMesh) -> Collider {
        let v = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        let t = mesh
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        Collider::Mesh(Arc::new(MeshCollider::new(v, t).unwrap()))
    }

    /// With the barrier, a particle that starts a step resting inside its band and is moved
    /// closer (as the step's predicted start moves a resting particle by h²g) is projected back
    /// to the distance it started at, not to its layer; with the constraint, to its layer.
    #[test]
    fn a_resting_particle_is_projected_back_to_where_it_rested() {
        let sys = lab_system(3, 2e-4);
        let t = 0.004;
        let rested = 1.3 * t;
        for (model, expected) in [
            (ContactModel::Barrier, rested),
            (ContactModel::Constraint, t),
        ] {
            let colliders = Colliders {
                shapes: vec![Collider::Plane(HalfSpace::new(DVec3::Y, 0.0).unwrap())],
                thickness: t,
                friction: 0.0,
                model,
            };
            let mut contact = NewtonContact::new(colliders, &sys);
            let start: Vec<DVec3> = (0..sys.len())
                .map(|i| DVec3::new(0.01 * i as f64, rested, 0.0))
                .collect();
            contact.begin_step(&start);
            let mut p = start[0] - DVec3::Y * 0.8 * t;
            contact.project(0, &mut p);
            assert!(
                (p.y - expected).abs() < 1e-12,
                "{model:?}: projected to {} m, expected {expected} m",
                p.y
            );
        }
    }

    /// A barrier judges a line-search trial along the path from the last accepted iterate, not
    /// from the step's start: a particle that started beside a table top's edge and has reached
    /// the underside (without crossing the top) may move a little further under it, although
    /// the straight line from where it started to there cuts through the top's edge; a trial
    /// that does enter the top is infeasible.
    #[test]
    fn a_barrier_trial_is_judged_along_the_path_from_the_last_iterate() {
        let top = StaticMesh::cuboid(
            DVec3::new(-0.6, 0.71, -0.4),
            DVec3::new(0.6, 0.75, 0.4),
            "table top",
        );
        let sys = lab_system(3, 2e-4);
        let colliders = Colliders {
            shapes: vec![mesh_collider(&top)],
            thickness: 0.004,
            friction: 0.0,
            model: ContactModel::Barrier,
        };
        let mut contact = NewtonContact::new(colliders, &sys);
        // Every other particle far above the table.
        let far = |i: usize| DVec3::new(0.05 * i as f64, 5.0, 0.0);
        let mut start: Vec<DVec3> = (0..sys.len()).map(far).collect();
        start[0] = DVec3::new(0.0, 0.72, 0.41); // 1 cm beside the top's side face
        contact.begin_step(&start);
        let mut x = start.clone();
        x[0] = DVec3::new(0.0, 0.705, 0.39); // 5 mm under the top, inside the band (2–6 mm)
        contact.set_iterate(&x);
        assert!(contact.energy(&x).is_finite());
        let mut further = x.clone();
        further[0] = DVec3::new(0.0, 0.7048, 0.385);
        assert!(
            contact.energy(&further).is_finite(),
            "a trial reached from the iterate without crossing anything is feasible"
        );
        let mut inside = x.clone();
        inside[0] = DVec3::new(0.0, 0.72, 0.39);
        assert_eq!(contact.energy(&inside), f64::INFINITY);
    }

    /// From one assembled iterate to the next, a particle keeps a tenth of its gap above the
    /// band's bottom (of the band's width where it was in no band), in the line search's trials
    /// (the energy) and in the sweeps' local steps (the planes) alike; before a step's first
    /// assembly only the bottom itself is refused.
    #[test]
    fn a_trial_keeps_a_tenth_of_the_gap_above_the_band_bottom() {
        let t = 0.004; // band (2, 6) mm
        let floor = Collider::Plane(HalfSpace::new(DVec3::Y, 0.0).unwrap());
        let (_, mut contact, far) = barrier_on(floor, t);
        let at = |y: f64| {
            let mut x = far.clone();
            x[0] = DVec3::new(0.0, y, 0.0);
            x
        };
        let allowed = |contact: &NewtonContact, y: f64| {
            let energy = contact.energy(&at(y)).is_finite();
            let mut planes = Vec::new();
            contact.barrier_planes(0, DVec3::new(0.0, 0.005, 0.0), t, &mut planes);
            let plane = planes.iter().all(|p| p.allows(DVec3::new(0.0, y, 0.0)));
            assert_eq!(energy, plane, "the energy and the planes agree at y = {y}");
            energy
        };
        for (iterate, kept) in [(0.005, 3e-4), (0.010, 0.1 * t)] {
            let x = at(iterate);
            contact.begin_step(&x);
            contact.set_iterate(&x);
            assert!(
                allowed(&contact, 0.002 + 1e-6),
                "no floor before an assembly"
            );
            let mut grad = vec![DVec3::ZERO; x.len()];
            contact.add_derivatives(&x, &mut grad, |_, _| {});
            assert!(allowed(&contact, 0.002 + 1.05 * kept));
            assert!(
                !allowed(&contact, 0.002 + 0.95 * kept),
                "from y = {iterate}"
            );
        }
    }

    /// A step does not start a particle within [`START_DEPTH`] of its band's bottom (where a
    /// moving body carried it): it is projected out, or where it rests there its layer thins
    /// to its distance; a particle above that depth is left as it is.
    #[test]
    fn a_step_starts_no_particle_at_its_band_bottom() {
        let t = 0.004; // band (2, 6) mm
        for depth in [1e-4, 2e-3] {
            let floor = Collider::Plane(HalfSpace::new(DVec3::Y, 0.0).unwrap());
            let (_, mut contact, mut x) = barrier_on(floor, t);
            x[0] = DVec3::new(0.0, 0.05, 0.0);
            contact.begin_step(&x); // layers are the thickness
            let y = 0.002 + depth * t;
            x[0] = DVec3::new(0.0, y, 0.0);
            contact.begin_step(&x);
            assert_eq!(contact.make_feasible(&mut x, false), 0);
            let deepest = contact.deepest(0, x[0]).expect("feasible");
            assert!(deepest > 1e-3, "from u = {depth}: at u = {deepest}");
            if depth > 1e-3 {
                assert_eq!(x[0].y, y, "left as it is");
                assert!(
                    (deepest - depth).abs() < 1e-12,
                    "its layer too: u = {deepest}"
                );
            }
        }
    }

    /// One mesh of the given boxes (each a closed piece, welded by position only) and, with
    /// `sheet`, an open square far from them.
    fn pieces(boxes: &[(DVec3, DVec3)], sheet: bool) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let (mut v, mut t) = (Vec::new(), Vec::new());
        let mut add = |m: StaticMesh| {
            let base = v.len() as u32;
            v.extend(m.positions.iter().map(|p| p.as_dvec3()));
            t.extend(
                m.indices
                    .chunks_exact(3)
                    .map(|c| [c[0], c[1], c[2]].map(|i| i + base)),
            );
        };
        for (lo, hi) in boxes {
            add(StaticMesh::cuboid(*lo, *hi, "piece"));
        }
        if sheet {
            add(StaticMesh::plane(DVec3::Y, -3.0, DVec3::ZERO, 1.0, "sheet"));
        }
        (v, t)
    }

    /// Barrier contact with the one collider `shape` for the lab cloth's 3×3 grid, and the grid's
    /// particles far from it (for a test to place the ones it looks at).
    fn barrier_on(shape: Collider, thickness: f64) -> (ReducedSystem, NewtonContact, Vec<DVec3>) {
        let sys = lab_system(3, 2e-4);
        let colliders = Colliders {
            shapes: vec![shape],
            thickness,
            friction: 0.0,
            model: ContactModel::Barrier,
        };
        let contact = NewtonContact::new(colliders, &sys);
        let far = (0..sys.len())
            .map(|i| DVec3::new(5.0 + 0.05 * i as f64, 5.0, 0.0))
            .collect();
        (sys, contact, far)
    }

    /// A hip box with a leg box reaching into it from below, and a loose open sheet: as one
    /// mesh neither closed nor one piece.
    fn hips_and_leg() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        pieces(
            &[
                (DVec3::new(-0.2, -0.1, -0.1), DVec3::new(0.2, 0.1, 0.1)),
                (DVec3::new(0.0, -0.6, -0.05), DVec3::new(0.1, 0.0, 0.05)),
            ],
            true,
        )
    }

    /// A body built of closed pieces that overlap (a leg reaching into the hips) is cut into
    /// solids: a particle inside the leg below the hips, which the body as one open mesh (a
    /// two-sided shell) would hold inside, is pushed out of the leg at the step's start, to
    /// the side the leg's nearest face is on.
    #[test]
    fn a_particle_inside_one_piece_of_a_body_is_pushed_out_of_it() {
        let (v, t) = hips_and_leg();
        let body = MeshCollider::new(v, t).unwrap();
        assert!(!body.is_closed());
        let closed: Vec<bool> = body.parts().iter().map(|p| p.is_closed()).collect();
        assert_eq!(closed, [true, true, false], "hips, leg, and the sheet");
        // 1 cm inside the leg's +x face, below the hips.
        let inside = DVec3::new(0.09, -0.3, 0.0);
        let leg = body.parts()[1].contact(inside, inside, 0.05).unwrap();
        assert!((leg.distance + 0.01).abs() < 1e-6, "{leg:?}");
        assert!(leg.normal.abs_diff_eq(DVec3::X, 1e-9));
        assert!(body.contact(inside, inside, 0.05).unwrap().distance > 0.0);

        let thickness = 0.004;
        let (_, mut contact, mut x) = barrier_on(Collider::Mesh(Arc::new(body)), thickness);
        x[0] = inside;
        contact.begin_step(&x);
        assert_eq!(contact.make_feasible(&mut x, false), 0);
        // Outside the leg's +x face (x = 0.1), beyond the bottom of the barrier band of the
        // thinnest layer (a particle that starts behind a surface is moved out to a tenth of
        // the thickness).
        let (lo, _) = barrier_band(MIN_BARRIER_LAYER * thickness);
        assert!(x[0].x > 0.1 + lo, "still in the leg at {}", x[0]);
        assert!(contact.energy(&x).is_finite());
    }

    /// A particle pressed into a fold of a mesh (two faces at a right angle, one open piece)
    /// feels a barrier from each face, as incremental potential contact's point–triangle pairs
    /// do: the energy is the closed-form sum of both faces' barriers, smooth across the fold's
    /// bisector. The nearest face's alone would be half of it there, with a kink. So does one
    /// whose layer thinned because it started closer than the thickness.
    #[test]
    fn a_particle_in_a_fold_feels_both_faces() {
        let v = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0],
            [0.0, 1.0, 1.0],
        ]
        .map(DVec3::from_array)
        .to_vec();
        // The floor y = 0 (normal +y) and the wall x = 0 (normal +x), sharing the edge x = y = 0.
        let t = vec![[0, 3, 2], [0, 2, 1], [0, 4, 5], [0, 5, 3]];
        let fold = Arc::new(MeshCollider::new(v, t).unwrap());
        assert!(!fold.is_closed() && fold.parts().is_empty());
        let thickness = 0.01;
        let (sys, mut contact, mut x) = barrier_on(Collider::Mesh(Arc::clone(&fold)), thickness);
        let c = barrier_strength(sys.mass[0]);
        // At each (a, b) of `at` (its distances from the wall and the floor), particle 0's
        // energy is the sum of both faces' barriers in a band of `layer`.
        let sums_both =
            |contact: &mut NewtonContact, x: &mut [DVec3], layer: f64, at: &[(f64, f64)]| {
                let (lo, width) = barrier_band(layer);
                let barrier = |d: f64| c * width * barrier_shape((d - lo) / width).0;
                for &(a, b) in at {
                    x[0] = DVec3::new(a, b, 0.5);
                    contact.set_iterate(x);
                    let expected = barrier(a) + if b < lo + width { barrier(b) } else { 0.0 };
                    let energy = contact.energy(x);
                    assert!(
                        (energy - expected).abs() <= 1e-9 * expected,
                        "layer {layer}, at ({a}, {b}): {energy} J, both faces' {expected} J"
                    );
                }
            };
        // It starts the step clear of both faces, then moves into the fold.
        x[0] = DVec3::new(0.05, 0.05, 0.5);
        contact.begin_step(&x);
        let at = [
            (0.008, 0.008),
            (0.007, 0.0095),
            (0.0095, 0.007),
            (0.006, 0.02),
        ];
        sums_both(&mut contact, &mut x, thickness, &at);

        // A particle that starts the step 4 mm from both faces, closer than the thickness: its
        // layer thins to 4 mm, and in the fold it still feels both faces, in the thinner band.
        let (_, mut contact, mut x) = barrier_on(Collider::Mesh(fold), thickness);
        x[0] = DVec3::new(0.004, 0.004, 0.5);
        contact.begin_step(&x);
        let at = [
            (0.003, 0.003),
            (0.0025, 0.0045),
            (0.0045, 0.0022),
            (0.0024, 0.02),
        ];
        sums_both(&mut contact, &mut x, 0.004, &at);
    }

    /// Each collider carries a particle as its nearest part moves: a particle resting on a still
    /// piece of a body is not dragged along by another piece that swings past nearby.
    #[test]
    fn a_particle_is_carried_by_the_part_it_rests_on() {
        let still = (DVec3::new(-0.1, -0.1, -0.1), DVec3::new(0.1, 0.1, 0.1));
        let (before, t) = pieces(
            &[
                still,
                (DVec3::new(0.15, -0.1, -0.1), DVec3::new(0.25, 0.1, 0.1)),
            ],
            false,
        );
        // The second box moves 6 cm along z in the step; the first stays.
        let after: Vec<DVec3> = before
            .iter()
            .map(|p| if p.x > 0.12 { *p + DVec3::Z * 0.06 } else { *p })
            .collect();
        let before = Arc::new(MeshCollider::new(before, t).unwrap());
        assert_eq!(before.parts().len(), 2);
        let body = Collider::moving(before, after).unwrap();
        let (_, mut contact, mut x) = barrier_on(body, 0.004);
        // Resting 3 mm off the still box's +x face, 4.7 cm from the moving one.
        x[0] = DVec3::new(0.103, 0.0, 0.0);
        // And one resting on the moving box's +x face.
        x[1] = DVec3::new(0.253, 0.0, 0.0);
        contact.begin_step(&x);
        assert_eq!(contact.carry(0), DVec3::ZERO);
        assert!(contact.carry(1).abs_diff_eq(DVec3::Z * 0.06, 1e-9));
    }

    /// The lab cloth's n×n grid, nothing pinned, every particle `mass` kg, at a garment's step.
    fn lab_system(n: u32, mass: f64) -> ReducedSystem {
        lab_cloth(n, 100.0)
            .system(mass, false, StepParams::garment())
            .0
    }

    /// β′ and β″ are the derivatives of β (central differences), the barrier starts smoothly
    /// at the top of its band (β = β′ = β″ = 0 at u = 1) and grows without bound at its bottom.
    #[test]
    fn barrier_shape_derivatives_match_finite_differences() {
        let e = 1e-6;
        for u in [0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99] {
            let (b, d1, d2) = barrier_shape(u);
            let fd1 = (barrier_shape(u + e).0 - barrier_shape(u - e).0) / (2.0 * e);
            let fd2 = (barrier_shape(u + e).1 - barrier_shape(u - e).1) / (2.0 * e);
            assert!(b > 0.0 && d1 < 0.0 && d2 > 0.0, "u {u}: {b} {d1} {d2}");
            assert!(
                (d1 - fd1).abs() < 1e-6 * (1.0 + fd1.abs()),
                "u {u}: β′ {d1}, FD {fd1}"
            );
            assert!(
                (d2 - fd2).abs() < 1e-5 * (1.0 + fd2.abs()),
                "u {u}: β″ {d2}, FD {fd2}"
            );
        }
        let (b, d1, d2) = barrier_shape(1.0);
        assert_eq!((b, d1, d2), (0.0, 0.0, 0.0));
        assert!(barrier_shape(1e-12).0 > 20.0);
    }

    /// The barrier's gradient is the derivative of its energy, and on a plane (no curvature
    /// term to leave out) its Hessian block is the derivative of its gradient: central
    /// differences at particles spread through the band of a ground plane and of a ball.
    #[test]
    fn barrier_derivatives_match_finite_differences_of_its_energy() {
        let sys = lab_system(3, 2e-4);
        let n = sys.len();
        let t = 0.004;
        for (shape, plane) in [
            (
                Collider::Plane(HalfSpace::new(DVec3::Y, 0.0).unwrap()),
                true,
            ),
            (ball_mesh(), false),
        ] {
            let colliders = Colliders {
                shapes: vec![shape],
                thickness: t,
                friction: 0.0,
                model: ContactModel::Barrier,
            };
            // Heights from 0.55 t to 1.45 t above the surface (the band is 0.5 t to 1.5 t).
            let x: Vec<DVec3> = (0..n)
                .map(|i| {
                    let f = i as f64 / (n - 1) as f64;
                    let lift = t * (0.55 + 0.9 * f);
                    if plane {
                        DVec3::new(0.01 * i as f64, lift, 0.0)
                    } else {
                        let dir = DVec3::new((f * 5.0).sin(), 1.0, (f * 3.0).cos()).normalize();
                        dir * (0.3 + lift)
                    }
                })
                .collect();
            let mut contact = NewtonContact::new(colliders, &sys);
            // The step starts two thicknesses farther out (so every layer is the thickness) and
            // x is the current iterate.
            let normal_at = |p: DVec3| if plane { DVec3::Y } else { p.normalize() };
            let start: Vec<DVec3> = x.iter().map(|p| *p + normal_at(*p) * 2.0 * t).collect();
            contact.begin_step(&start);
            contact.set_iterate(&x);
            let mut grad = vec![DVec3::ZERO; n];
            let mut blocks = vec![[[0.0; 3]; 3]; n];
            contact.add_derivatives(&x, &mut grad, |i, b| blocks[i] = b);
            // (The ball mesh's faces lie inside its sphere: some particles are above the band.)
            let inside = grad.iter().filter(|g| g.length() > 0.0).count();
            assert!(
                inside >= n / 2,
                "only {inside} of {n} particles in the band"
            );
            let e = 1e-8;
            for i in 0..n {
                let normal = contact.resting(i, x[i]).map_or(DVec3::Y, |s| s.normal);
                for dir in [DVec3::X, DVec3::Y, DVec3::Z] {
                    let mut plus = x.clone();
                    let mut minus = x.clone();
                    plus[i] += dir * e;
                    minus[i] -= dir * e;
                    let fd = (contact.energy(&plus) - contact.energy(&minus)) / (2.0 * e);
                    let g = grad[i].dot(dir);
                    let scale = grad[i].length().max(1e-9);
                    assert!((g - fd).abs() < 1e-4 * scale, "{i}: {g} vs {fd}");
                }
                if plane {
                    let mut plus = x.clone();
                    plus[i] += normal * e;
                    let mut g1 = vec![DVec3::ZERO; n];
                    contact.add_derivatives(&plus, &mut g1, |_, _| {});
                    let fd = (g1[i] - grad[i]).dot(normal) / e;
                    let b = &blocks[i];
                    let h = DVec3::from(b[0]).dot(normal) * normal.x
                        + DVec3::from(b[1]).dot(normal) * normal.y
                        + DVec3::from(b[2]).dot(normal) * normal.z;
                    assert!((h - fd).abs() < 1e-4 * h.abs(), "{i}: nᵀHn {h} vs {fd}");
                }
            }
            // Below the band's bottom the energy is infinite.
            let mut under = x.clone();
            let s = contact.resting(0, x[0]).unwrap();
            under[0] -= s.normal * (s.distance - 0.45 * t);
            assert_eq!(contact.energy(&under), f64::INFINITY);
        }
    }

    /// Friction's gradient is the derivative of its potential (central differences of
    /// [`NewtonContact::energy`], which evaluates the potential on its own), in the static
    /// regime (slip below the slip scale) and the kinetic one; its block is the potential's
    /// Hessian in the static regime and that plus μN/|s|·ŝŝᵀ in the kinetic one; and the
    /// block's quadratic model lies on or above the potential for moves in every direction of
    /// the plane, back to zero slip included: particles that rested on a ground plane at the
    /// end of a step, pressed onto it by 1e-3 N, slide along it.
    #[test]
    fn friction_derivatives_match_finite_differences_of_its_potential() {
        let sys = lab_system(3, 2e-4);
        let n = sys.len();
        let t = 0.004;
        let colliders = Colliders {
            shapes: vec![Collider::Plane(HalfSpace::new(DVec3::Y, 0.0).unwrap())],
            thickness: t,
            friction: 0.3,
            model: ContactModel::Constraint,
        };
        let x: Vec<DVec3> = (0..n)
            .map(|i| DVec3::new(0.01 * i as f64, t, -0.02 * i as f64))
            .collect();
        let mut contact = NewtonContact::new(colliders, &sys);
        contact.begin_step(&x);
        let touching = contact.end_step(&x, &vec![DVec3::Y * 1e-3; n]);
        assert_eq!(touching, n);
        contact.begin_step(&x);
        for (slide, e) in [(0.3 * contact.slip_scale, 1e-10), (1e-3, 1e-8)] {
            let moved: Vec<DVec3> = (0..n)
                .map(|i| {
                    let a = i as f64;
                    x[i] + DVec3::new(a.cos(), 0.0, a.sin()) * slide
                })
                .collect();
            let mut grad = vec![DVec3::ZERO; n];
            let mut blocks = vec![[[0.0; 3]; 3]; n];
            contact.add_derivatives(&moved, &mut grad, |i, b| blocks[i] = b);
            for i in 0..n {
                let scale = grad[i].length();
                assert!(scale > 0.0, "slide {slide}, particle {i}: no friction");
                for (c, dir) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().enumerate() {
                    let at = |h: f64| {
                        let mut p = moved.clone();
                        p[i] += dir * h;
                        p
                    };
                    let fd = (contact.energy(&at(e)) - contact.energy(&at(-e))) / (2.0 * e);
                    assert!(
                        (grad[i].dot(dir) - fd).abs() < 1e-4 * scale,
                        "slide {slide}, particle {i}: gradient {} vs {fd}",
                        grad[i].dot(dir)
                    );
                    let mut plus = vec![DVec3::ZERO; n];
                    let mut minus = vec![DVec3::ZERO; n];
                    contact.add_derivatives(&at(e), &mut plus, |_, _| {});
                    contact.add_derivatives(&at(-e), &mut minus, |_, _| {});
                    let mut column = (plus[i] - minus[i]) / (2.0 * e);
                    if slide > contact.slip_scale {
                        // The majorizer's term along the slip ŝ (in the plane, y = 0).
                        let s = (moved[i] - x[i]).normalize();
                        column += s * (s[c] * scale / slide);
                    }
                    let ours = DVec3::new(blocks[i][0][c], blocks[i][1][c], blocks[i][2][c]);
                    assert!(
                        ours.distance(column) < 1e-4 * (scale / slide),
                        "slide {slide}, particle {i}, column {c}: {ours} vs {column}"
                    );
                }
                // Majorizer: the model never falls below the potential, for moves of every
                // length in the plane up to twice the slide (through zero slip and beyond).
                let base = contact.energy(&moved);
                let block = DMat3::from_cols_array_2d(&blocks[i]);
                for k in 0..16 {
                    let a = k as f64 * std::f64::consts::TAU / 16.0;
                    for f in [0.1, 0.5, 1.0, 1.5, 2.0] {
                        let d = DVec3::new(a.cos(), 0.0, a.sin()) * (f * slide);
                        let mut p = moved.clone();
                        p[i] += d;
                        let rise = contact.energy(&p) - base;
                        let model = grad[i].dot(d) + 0.5 * d.dot(block * d);
                        assert!(
                            rise <= model + 1e-6 * model.abs() + 1e-12 * base,
                            "slide {slide}, particle {i}, move {d}: rise {rise} above the model {model}"
                        );
                    }
                }
            }
        }
    }

    /// One particle's barrier and friction terms evaluated on its tangent planes
    /// ([`NewtonContact::particle_terms`], [`NewtonContact::barrier_planes`] taken where it is)
    /// equal its gradient and Hessian block from [`NewtonContact::add_derivatives`], for
    /// particles in the band of a ball mesh, sliding in friction's static and kinetic regimes;
    /// and a particle moved towards the surface past a band's bottom is refused.
    #[test]
    fn particle_terms_on_their_planes_equal_the_assembled_terms() {
        let sys = lab_system(3, 2e-4);
        let n = sys.len();
        let t = 0.004;
        let colliders = Colliders {
            shapes: vec![ball_mesh()],
            thickness: t,
            friction: 0.3,
            model: ContactModel::Barrier,
        };
        let x: Vec<DVec3> = (0..n)
            .map(|i| {
                let f = i as f64 / (n - 1) as f64;
                let dir = DVec3::new((f * 5.0).sin(), 1.0, (f * 3.0).cos()).normalize();
                dir * (0.3 + t * (0.55 + 0.9 * f))
            })
            .collect();
        let mut contact = NewtonContact::new(colliders, &sys);
        let start: Vec<DVec3> = x.iter().map(|p| *p + p.normalize() * 2.0 * t).collect();
        // A step that ends at x leaves lagged friction at x for the next, which starts there.
        contact.begin_step(&start);
        contact.set_iterate(&x);
        let touching = contact.end_step(&x, &vec![DVec3::ZERO; n]);
        assert!(touching >= n / 2, "{touching} of {n} touching");
        contact.begin_step(&x);
        // Slides along the surface: static (below the slip scale) and kinetic.
        for slide in [0.3 * contact.slip_scale, 1e-3] {
            let moved: Vec<DVec3> = x
                .iter()
                .map(|p| *p + p.normalize().cross(DVec3::X).normalize() * slide)
                .collect();
            contact.set_iterate(&moved);
            let mut grad = vec![DVec3::ZERO; n];
            let mut blocks = vec![[[0.0; 3]; 3]; n];
            contact.add_derivatives(&moved, &mut grad, |i, b| {
                for r in 0..3 {
                    for c in 0..3 {
                        blocks[i][r][c] += b[r][c];
                    }
                }
            });
            let mut planes = Vec::new();
            for (i, p) in moved.iter().enumerate() {
                planes.clear();
                contact.barrier_planes(i, *p, t, &mut planes);
                let (mut g, mut h) = (DVec3::ZERO, DMat3::ZERO);
                assert!(contact.particle_terms(i, *p, &planes, &mut g, &mut h));
                let scale = grad[i].length().max(1e-12);
                assert!(
                    g.distance(grad[i]) < 1e-9 * scale,
                    "slide {slide}, particle {i}: {g} vs {}",
                    grad[i]
                );
                for (r, row) in blocks[i].iter().enumerate() {
                    for (c, b) in row.iter().enumerate() {
                        let ours = h.col(c)[r];
                        assert!(
                            (ours - b).abs() <= 1e-9 * (1.0 + b.abs()),
                            "slide {slide}, particle {i}, ({r}, {c}): {ours} vs {b}"
                        );
                    }
                }
                if let Some(plane) = planes.first() {
                    let (mut g, mut h) = (DVec3::ZERO, DMat3::ZERO);
                    let distance = plane.normal.dot(*p) + plane.offset;
                    let below = *p - plane.normal * (distance - 0.45 * t);
                    assert!(!contact.particle_terms(i, below, &planes, &mut g, &mut h));
                }
            }
        }
    }

    /// Skipping the queries of particles out of reach ([`NewtonContact::out_of_reach`]) changes
    /// no answer: for particles starting from a few millimetres to a metre from a mesh collider
    /// and trial points moved by up to 2 cm (half of them) or 20 cm in every direction (into it,
    /// through it, away), the projection, the resting surface and the settling equal those of a
    /// contact that never skips; and a good share of the queries is skipped.
    #[test]
    fn skipping_far_particles_changes_no_answer() {
        let sys = lab_system(9, 1e-4);
        let n = sys.len();
        let colliders = Colliders {
            shapes: vec![ball_mesh()],
            thickness: 0.004,
            friction: 0.3,
            model: ContactModel::Constraint,
        };
        // Start points on rays out of the centre, 0.302 m to 1.3 m from it.
        let x0: Vec<DVec3> = (0..n)
            .map(|i| {
                let t = i as f64;
                let dir = DVec3::new((t * 1.7).sin(), (t * 0.9).cos(), (t * 2.3).sin()).normalize();
                dir * (0.302 + (t * 0.37).fract())
            })
            .collect();
        let mut skipping = NewtonContact::new(colliders, &sys);
        skipping.begin_step(&x0);
        let mut never = skipping.clone();
        never.clear.clear();
        let mut skipped = 0;
        for (i, start) in x0.iter().enumerate() {
            for k in 0..24 {
                let t = (i * 24 + k) as f64;
                let scale = if k % 2 == 0 { 0.02 } else { 0.2 };
                let motion = DVec3::new((t * 0.61).sin(), (t * 1.13).cos(), (t * 0.29).sin())
                    * (scale * (t * 0.77).fract());
                let p = *start + motion;
                let (mut a, mut b) = (p, p);
                assert_eq!(skipping.project(i, &mut a), never.project(i, &mut b));
                assert_eq!(a, b);
                assert_eq!(skipping.resting(i, p), never.resting(i, p));
                let (mut a, mut b) = (p, p);
                skipping.settle(i, &mut a, 0.004);
                never.settle(i, &mut b, 0.004);
                assert_eq!(a, b);
                skipped += usize::from(skipping.out_of_reach(i, 0, 0.004, p, *start));
            }
        }
        assert!(skipped > n * 24 / 4, "only {skipped} of {} skipped", n * 24);
    }
}
