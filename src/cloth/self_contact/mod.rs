//! Self-contact: the cloth's vertex–triangle and edge–edge pairs kept apart by a barrier energy,
//! and every motion of an iterate bounded by continuous collision detection, so that a step
//! never makes the cloth pass through itself.
//!
//! **The energy.** Each pair (a vertex and a triangle not holding it, or two edges sharing no
//! vertex) at distance d has a band (ℓ/2, 3ℓ/2), ℓ its layer (the self-contact thickness): zero
//! energy above the band, c·ℓ·β(u) inside it with u = (d − ℓ/2)/ℓ and β the colliders' barrier
//! shape ([`super::collide::contact`]: β(u) = −(u − 1)² ln u), infinite at its bottom. The
//! strength c is the colliders' (ten weights of the pair's mean particle at the band's middle).
//! The separation is Σₖ wₖxₖ over the pair's four vertices ([`super::proximity`]), so the
//! gradient is c·β′(u)·wₖ·n at vertex k (n the unit separation) and the Hessian's blocks are
//! c·β″(u)/ℓ · wᵢwⱼ · n nᵀ (the distance's curvature term, negative for a barrier pushing
//! apart, left out as incremental potential contact's projection does: every block pair is
//! positive semi-definite). Only diagonal blocks enter the factored matrix; the pairs'
//! couplings enter Newton's products by the Hessian ([`SelfContact::add_product`]), so the
//! sparsity pattern stays fixed while the pairs change every iteration.
//!
//! **Pairs that start close.** A pair found inside its band when a bake starts (folds of a
//! draped garment, slivers of an irregular mesh) gets a thinner layer, d/1.5, so the input is at
//! rest; one found at or below its band's bottom at the start of a later step (pins jump between
//! steps) gets the same. Thinned layers grow back as their pairs move apart
//! ([`SelfContact::end_step`]). A pair touching (d below 1 % of the layer: an input that already
//! crosses itself, coincident vertices, a vertex in a neighbour's plane) is left out while it
//! touches, so around it the cloth can pass through itself, either way (the draped dress has
//! 1,540 such pairs, most under 1 µm apart: its file is rounded to the micrometre where its layers
//! lay on each other; it loses 63 of its 132 crossing pairs in its first frame, and its 6 with the
//! body become 119). Elsewhere no step adds a crossing. A step whose start a
//! collider pushed out of itself is taken as it is ([`SelfContact::accept`]).
//!
//! **Colliders' edges and corners.** The mesh colliders join the pairs
//! ([`SelfContact::with_obstacles`]): their vertices against the cloth's triangles, their edges
//! against the cloth's edges (their triangles against the cloth's vertices repeat the colliders'
//! own barrier). Their vertices are fixed within a step, as pins are, so a body's sharp edge
//! cannot pass between two particles through the cloth's triangles.
//!
//! **A moving body** ([`SelfContact::moving_obstacles`]) moves within each step instead: the
//! step starts with it where the last one ended, where the cloth was kept off it, and pushes
//! ([`SelfContact::add_drag`], [`SelfContact::commit_obstacles`]) take it on towards where it
//! is going, the cloth along with it, each as far as additive CCD over both motions allows
//! ([`SelfContact::prepare_joint_path`]). A body that jumps between steps instead lands on cloth it
//! would have had to pass through: the pairs it lands next to thin to micrometres and hold the
//! cloth on the wrong side of its edges, and Newton's steps stall against them
//! (`docs/cloth.md`, "A moving body").
//!
//! **Broad phase.** A uniform grid over the pairs' swept boxes from one iterate to the farthest
//! point a search may try, each box grown by half the band's top, so every pair that can come
//! within its band on the way is a candidate ([`SelfContact::prepare_path`]). Triangles and
//! edges are binned once per path and each vertex and edge looks up the cells it overlaps.
//!
//! **Continuous collision detection.** Additive CCD (Li, Kaufman and Jiang 2021, "Codimensional
//! incremental potential contact", §4): along a linear path, the distance between two primitives
//! changes no faster than l_p, the largest displacement of a vertex of each less their mean,
//! summed over the two; so from a distance d the pair cannot reach the target distance before
//! (d − target)/l_p of the path, and advancing by a fraction of that, re-measuring, gives a
//! conservative time of impact. The target keeps a tenth of the starting gap above the band's
//! bottom, so the barrier stays finite on every point a search tries.

use std::collections::HashMap;

use glam::DVec3;

mod broad;

use self::broad::{pair_key, Aabb, HashGrid};
use crate::cloth::collide::barrier::{barrier_shape, barrier_strength};
use crate::cloth::collide::{Collider, Colliders};
use crate::cloth::model::ClothModel;
use crate::cloth::proximity::{point_triangle, segment_segment, Separation};
use crate::cloth::system::{ReducedSystem, PINNED};

/// The fraction of its starting gap above the band's bottom a pair keeps along a path
/// (see the module documentation).
const CCD_GAP: f64 = 0.1;

/// Pairs closer than this fraction of the layer touch and are left out while they do. A layer
/// thinned further would hold its pair with a stiffness growing as 1/layer and 1/u²: on the
/// draped dress a pair found 7 nm apart got a 4.5 nm layer, the kicking body pressed it a
/// decade of u per Newton iteration, and at 7.6e18 N/m the Hessian no longer factored.
const TOUCHING: f64 = 1e-2;

/// Obstacles moving within a step are taken to have arrived this close to their goal, in layers.
const ARRIVED: f64 = 1e-2;

/// A push that moves the obstacles less than this fraction of their remaining way is stalled
/// (see [`SelfContact::release_pinched`]).
pub(crate) const STALLED_PUSH: f64 = 1e-2;

/// Pairs of an obstacle with the cloth this deep into their band or deeper (u, 0 at its bottom)
/// when a push stalls are pinched (see [`SelfContact::release_pinched`]).
const PINCHED: f64 = 1e-2;

/// How much of the distance a pair may cover safely each additive-CCD round advances by.
const CCD_ADVANCE: f64 = 0.9;

/// Additive-CCD rounds before a pair's time of impact is taken as where they stopped (still
/// conservative).
const CCD_ROUNDS: usize = 64;

/// The longest path [`SelfContact::prepare_path`] looks along at once, in the grid's cells at
/// rest (a longer one is cut).
const MAX_PATH_CELLS: f64 = 64.0;

/// Cells a path may sweep a primitive across: past it, the path's grid has larger cells.
const SWEPT_CELLS: f64 = 4.0;

/// Vertices plus edges from which the broad and narrow phases split over two threads (a
/// thread's start costs tens of microseconds; a smaller cloth's phases take about that).
const PARALLEL_MIN: usize = 4096;

/// A candidate pair of primitives.
#[derive(Debug, Clone, Copy)]
struct Pair {
    /// Which pair (see [`pair_key`]).
    key: u64,
    /// Its four vertices (model indices): a vertex and a triangle's three, or two edges' two.
    v: [u32; 4],
    /// True for two edges.
    edges: bool,
    /// The pair's layer ℓ, m (0: left out while touching).
    layer: f64,
    /// The barrier's strength c, N.
    strength: f64,
}

/// A pair inside its band at the assembled iterate: what the Hessian's products need.
#[derive(Debug, Clone, Copy)]
struct Active {
    /// Solver index of each vertex ([`PINNED`] where pinned).
    free: [u32; 4],
    weights: [f64; 4],
    normal: DVec3,
    /// c·β″(u)/ℓ, N/m.
    stiffness: f64,
    /// Σ w_k (n·(goal − position)) n over the pair's obstacle vertices, m (zero when none
    /// moves): the normal part of their remaining motion, weighted as the separation weighs them.
    drag: DVec3,
}

/// Self-contact of one cloth (see the module documentation).
#[derive(Debug, Clone)]
pub struct SelfContact {
    /// The layer ℓ of pairs that did not start close, m.
    layer: f64,
    triangles: Vec<[u32; 3]>,
    edges: Vec<[u32; 2]>,
    /// Solver index of each model particle ([`PINNED`] where pinned).
    slot: Vec<u32>,
    /// Model-ordered positions; the pinned entries are where the pins are.
    fixed: Vec<DVec3>,
    /// Per model particle: the barrier's strength for a pair of such particles, N.
    strength: Vec<f64>,
    /// The grid's cell size at rest (paths that sweep farther get larger ones), m.
    cell: f64,
    /// Layers thinned from [`SelfContact::layer`] (see the module documentation), by pair key.
    thinned: HashMap<u64, f64>,
    /// Whether the first step has begun (the input's close pairs are thinned to rest).
    started: bool,
    /// Candidates of the last prepared path.
    pairs: Vec<Pair>,
    /// Whether `pairs` covers the iterate the solver holds (false between steps).
    ready: bool,
    /// Pairs in their band at the last assembled iterate.
    active: Vec<Active>,
    /// Scratch: per model particle, its two path ends; binned primitives; visit stamps.
    ends: Vec<(DVec3, DVec3)>,
    bins: Vec<(u64, u32)>,
    /// Scratch: the swept, grown box of every triangle, then of every edge.
    boxes: Vec<Aabb>,
    grid: HashGrid,
    stamp: Vec<u32>,
    /// The end of a cut path.
    cut_end: Vec<DVec3>,
    /// Threads the broad and narrow phases may use (see [`SelfContact::with_threads`]).
    threads: usize,
    /// Scratch of a second thread: its visit stamps and its pairs.
    stamp2: Vec<u32>,
    pairs2: Vec<Pair>,
    /// The mesh colliders whose vertices, edges and triangles join the pairs
    /// ([`SelfContact::with_obstacles`]): collider index, first vertex, vertex count.
    obstacles: Vec<(usize, u32, u32)>,
    /// Where the obstacles' vertices go within the step (indexed as `fixed`; empty until a body
    /// moving with the steps first moves: [`SelfContact::moving_obstacles`]).
    obstacle_to: Vec<DVec3>,
    /// Where they were at the last committed iterate.
    obstacle_from: Vec<DVec3>,
    /// Whether the obstacles are still on their way.
    obstacles_moving: bool,
    /// The fraction of their remaining way the obstacles move along a path being prepared (0
    /// but inside [`SelfContact::prepare_joint_path`]).
    path_span: f64,
    /// Whether obstacles move within the step (else they jump between steps).
    move_within: bool,
    /// Pairs released in this step: pinched between the obstacles and the cloth
    /// ([`SelfContact::release_pinched`]).
    pinched: usize,
}

impl SelfContact {
    /// Self-contact of `model`'s triangles at layer `layer` (m), for the solver of `sys`.
    pub fn new(model: &ClothModel, sys: &ReducedSystem, layer: f64) -> Self {
        let n = model.particle_count();
        let mut slot = vec![PINNED; n];
        for (i, &p) in sys.particle_of.iter().enumerate() {
            slot[p as usize] = i as u32;
        }
        let triangles = model.mesh.triangles.clone();
        let edges = crate::mesh::edges(&triangles);
        let x = model.positions();
        let mean_edge = if edges.is_empty() {
            layer
        } else {
            edges
                .iter()
                .map(|e| (x[e[0] as usize] - x[e[1] as usize]).length())
                .sum::<f64>()
                / edges.len() as f64
        };
        let strength = model.mass.iter().map(|m| barrier_strength(*m)).collect();
        SelfContact {
            layer,
            triangles,
            edges,
            slot,
            fixed: x.to_vec(),
            strength,
            cell: mean_edge.max(1.5 * layer),
            thinned: HashMap::new(),
            started: false,
            pairs: Vec::new(),
            ready: false,
            active: Vec::new(),
            ends: vec![(DVec3::ZERO, DVec3::ZERO); n],
            bins: Vec::new(),
            boxes: Vec::new(),
            grid: HashGrid::default(),
            stamp: Vec::new(),
            cut_end: Vec::new(),
            obstacles: Vec::new(),
            threads: 1,
            stamp2: Vec::new(),
            pairs2: Vec::new(),
            obstacle_to: Vec::new(),
            obstacle_from: Vec::new(),
            obstacles_moving: false,
            path_span: 0.0,
            move_within: false,
            pinched: 0,
        }
    }

    /// Runs the broad and narrow phases of a large cloth (at least [`PARALLEL_MIN`] primitives)
    /// on two threads when `threads` ≥ 2: each takes half of the vertices, of the edges and of
    /// the candidates, in order, so the pairs, their order and every time of impact are those
    /// of one thread.
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.use_threads(threads);
        self
    }

    /// As [`SelfContact::with_threads`], from the next phase on.
    pub fn use_threads(&mut self, threads: usize) {
        self.threads = threads.max(1);
    }

    /// Whether the phases run on two threads now.
    fn parallel(&self) -> bool {
        self.threads >= 2 && self.slot.len() + self.edges.len() >= PARALLEL_MIN
    }

    /// Adds the mesh colliders of `colliders` (a body, a table) to the pairs: their vertices
    /// against the cloth's triangles, their triangles against the cloth's vertices and their
    /// edges against the cloth's edges, so that a collider's corners and edges are kept off the
    /// cloth as its faces are, and no step passes the cloth through them. A collider's vertices
    /// are fixed, as pins are ([`SelfContact::move_obstacle`] moves them between steps);
    /// collider–collider pairs are never formed.
    pub fn with_obstacles(mut self, colliders: &Colliders) -> Self {
        let mean = if self.strength.is_empty() {
            0.0
        } else {
            self.strength.iter().sum::<f64>() / self.strength.len() as f64
        };
        for (j, shape) in colliders.shapes.iter().enumerate() {
            let (Collider::Mesh(m) | Collider::Moving { after: m, .. }) = shape else {
                continue;
            };
            let first = self.slot.len() as u32;
            let count = m.positions().len() as u32;
            self.slot
                .extend(std::iter::repeat_n(PINNED, count as usize));
            self.fixed.extend_from_slice(m.positions());
            self.strength
                .extend(std::iter::repeat_n(mean, count as usize));
            self.ends
                .resize(self.slot.len(), (DVec3::ZERO, DVec3::ZERO));
            let shift = |t: &[u32; 3]| t.map(|v| v + first);
            self.triangles.extend(m.triangles().iter().map(shift));
            self.edges.extend(
                crate::mesh::edges(m.triangles())
                    .iter()
                    .map(|e| e.map(|v| v + first)),
            );
            self.obstacles.push((j, first, count));
        }
        self
    }

    /// Moves the vertices of collider `j` (one of [`SelfContact::with_obstacles`]; others are
    /// ignored) to `positions`, in its vertex order.
    pub fn move_obstacle(&mut self, j: usize, positions: &[DVec3]) {
        if let Some(&(_, first, count)) = self.obstacles.iter().find(|o| o.0 == j) {
            debug_assert_eq!(positions.len(), count as usize);
            let range = first as usize..(first + count) as usize;
            if self.move_within {
                if self.obstacle_to.len() != self.fixed.len() {
                    // Obstacles not moved here (a table beside the body) stay where they are.
                    self.obstacle_to.clone_from(&self.fixed);
                    self.obstacle_from.clone_from(&self.fixed);
                }
                self.obstacle_to[range.clone()].copy_from_slice(positions);
                self.obstacle_from[range.clone()].copy_from_slice(&self.fixed[range]);
                self.obstacles_moving = true;
                self.ready = false;
            } else {
                self.fixed[range].copy_from_slice(positions);
            }
        }
    }

    /// Moves the obstacles within each step, from where they were to where
    /// [`SelfContact::move_obstacle`] puts them, along with the cloth's iterates
    /// ([`SelfContact::set_obstacle_fraction`]), instead of between steps.
    pub fn moving_obstacles(mut self, on: bool) -> Self {
        self.move_within = on;
        self
    }

    /// Whether the obstacles are still on their way within the step.
    pub fn obstacles_moving(&self) -> bool {
        self.obstacles_moving
    }

    /// As [`SelfContact::prepare_path`], with the obstacles still on their way moving along the
    /// same fraction of their remaining way as the cloth of its path.
    pub fn prepare_joint_path(&mut self, a: &[DVec3], b: &[DVec3]) -> f64 {
        self.path_span = if self.obstacles_moving { 1.0 } else { 0.0 };
        let toi = self.prepare_path(a, b);
        self.path_span = 0.0;
        toi
    }

    /// Puts the obstacles `alpha` of the way from their committed positions to their goal.
    pub fn set_obstacle_fraction(&mut self, alpha: f64) {
        if !self.obstacles_moving {
            return;
        }
        for v in self.obstacle_range() {
            self.fixed[v] =
                self.obstacle_from[v] + (self.obstacle_to[v] - self.obstacle_from[v]) * alpha;
        }
    }

    /// Commits the obstacles `alpha` of the way (1: they arrived).
    pub fn commit_obstacles(&mut self, alpha: f64) {
        if !self.obstacles_moving {
            return;
        }
        if alpha >= 1.0 {
            for v in self.obstacle_range() {
                self.fixed[v] = self.obstacle_to[v];
            }
            self.obstacles_moving = false;
        } else {
            self.set_obstacle_fraction(alpha);
            let mut left: f64 = 0.0;
            for v in self.obstacle_range() {
                self.obstacle_from[v] = self.fixed[v];
                left = left.max(self.fixed[v].distance(self.obstacle_to[v]));
            }
            // Within a hundredth of the layer of their goal, the obstacles are there.
            if left <= ARRIVED * self.layer {
                self.obstacles_moving = false;
            }
        }
        self.ready = false;
    }

    /// Adds to `rhs` (solver order) the barrier Hessian's blocks between the cloth and the
    /// obstacles times the obstacles' remaining motion, over the pairs in their bands at the
    /// last assembled iterate: how the cloth is dragged along.
    pub fn add_drag(&self, rhs: &mut [DVec3]) {
        for a in &self.active {
            if a.drag == DVec3::ZERO {
                continue;
            }
            for (&i, &w) in a.free.iter().zip(&a.weights) {
                if i != PINNED {
                    rhs[i as usize] += a.drag * (a.stiffness * w);
                }
            }
        }
    }

    fn is_obstacle(&self, v: usize) -> bool {
        self.obstacles.first().is_some_and(|o| v >= o.1 as usize)
    }

    fn obstacle_range(&self) -> std::ops::Range<usize> {
        match self.obstacles.first() {
            Some(o) => o.1 as usize..self.fixed.len(),
            None => 0..0,
        }
    }

    /// Moves the pinned particles to their entries of `all` (model order, m).
    pub fn move_pins(&mut self, all: &[DVec3]) {
        // (The zip stops at the cloth's particles: the obstacles' vertices follow them.)
        for (f, (s, a)) in self.fixed.iter_mut().zip(self.slot.iter().zip(all)) {
            if *s == PINNED {
                *f = *a;
            }
        }
    }

    #[inline]
    fn at(&self, x: &[DVec3], v: u32) -> DVec3 {
        match self.slot[v as usize] {
            PINNED => self.fixed[v as usize],
            s => x[s as usize],
        }
    }

    #[inline]
    fn separation(&self, pair: &Pair, p: [DVec3; 4]) -> Separation {
        if pair.edges {
            segment_segment(p[0], p[1], p[2], p[3])
        } else {
            point_triangle(p[0], p[1], p[2], p[3])
        }
    }

    #[inline]
    fn positions(&self, pair: &Pair, x: &[DVec3]) -> [DVec3; 4] {
        pair.v.map(|v| self.at(x, v))
    }

    /// Starts a step from `x0` (solver order): finds the pairs around it and thins the layers
    /// of those too close for their barrier (see the module documentation).
    pub fn begin_step(&mut self, x0: &[DVec3]) {
        let first = !self.started;
        self.started = true;
        self.pinched = 0;
        self.thin(x0, if first { 1.5 } else { 0.5 });
        // The start of the step is where the solver's search begins: it checks its own path.
        self.ready = false;
    }

    /// Takes `x` (solver order) as the iterate although it was not reached along a checked path
    /// (a collider pushed particles out of it): pairs at or below their band's bottom there get
    /// the layer they rest at, as at a step's start, so the energy is finite at `x`.
    pub fn accept(&mut self, x: &[DVec3]) {
        self.thin(x, 0.5);
    }

    /// Leaves out, while they touch, the pairs of an obstacle and the cloth at `x` (solver order)
    /// pressed to within [`PINCHED`] of their band's bottom, as [`TOUCHING`] pairs are, counting
    /// them in [`SelfContact::pinched`]. Called when a push stalls: where two parts of a body close on the cloth between
    /// them (thighs passing each other through a skirt), the cloth cannot get out of the way,
    /// and each push took the body a tenth of the remaining gap further, until the matrix no
    /// longer factored (the CesiumMan mini skirt, a body vertex at 1e-8 of its band under a
    /// cloth triangle). Released, the body
    /// passes through the cloth there (the crossings are measured and reported), and the pair's
    /// layer grows back as it moves apart ([`SelfContact::end_step`]).
    pub fn release_pinched(&mut self, x: &[DVec3]) {
        for k in 0..self.pairs.len() {
            let pair = self.pairs[k];
            if pair.layer == 0.0 || !pair.v.iter().any(|&v| self.is_obstacle(v as usize)) {
                continue;
            }
            let d = self.separation(&pair, self.positions(&pair, x)).distance();
            if d - 0.5 * pair.layer <= PINCHED * pair.layer {
                self.thinned.insert(pair.key, 0.0);
                self.pairs[k].layer = 0.0;
                self.pinched += 1;
            }
        }
    }

    /// Pairs released as pinched in this step ([`SelfContact::release_pinched`]).
    pub fn pinched(&self) -> usize {
        self.pinched
    }

    /// Finds the pairs around `x` and thins the layer of each closer than `below` layers.
    fn thin(&mut self, x: &[DVec3], below: f64) {
        self.prepare_path(x, x);
        for k in 0..self.pairs.len() {
            let pair = self.pairs[k];
            if pair.layer == 0.0 {
                continue;
            }
            let d = self.separation(&pair, self.positions(&pair, x)).distance();
            if d <= below * pair.layer {
                let layer = self.rest_layer(d, 0.0);
                self.thinned.insert(pair.key, layer);
                self.pairs[k].layer = layer;
            }
        }
    }

    /// Ends a step at `x`: thinned layers grow back towards the layer as their pairs move apart,
    /// and pairs that left the neighbourhood are forgotten.
    pub fn end_step(&mut self, x: &[DVec3]) {
        self.prepare_path(x, x);
        let mut kept = HashMap::with_capacity(self.thinned.len());
        for pair in &self.pairs {
            let Some(&layer) = self.thinned.get(&pair.key) else {
                continue;
            };
            let d = self.separation(pair, self.positions(pair, x)).distance();
            let grown = self.rest_layer(d, layer);
            if grown < self.layer {
                kept.insert(pair.key, grown);
            }
        }
        self.thinned = kept;
        self.ready = false;
    }

    /// The layer of a pair at distance `d` that rests there, never below `layer`: d/1.5, or 0
    /// (touching: left out) where d is below [`TOUCHING`] of the layer (a crossing input, a
    /// vertex in the plane of a neighbouring triangle, coincident vertices).
    fn rest_layer(&self, d: f64, layer: f64) -> f64 {
        if d > TOUCHING * self.layer {
            layer.max(d / 1.5)
        } else {
            layer
        }
    }

    /// Whether the candidates cover the solver's iterate (between
    /// [`SelfContact::begin_step`] and [`SelfContact::end_step`]).
    pub fn ready(&self) -> bool {
        self.ready
    }

    /// The fraction of the path from `a` to `b` (solver order) the cloth can move between steps
    /// without any pair reaching its target distance, as [`SelfContact::prepare_path`] finds it;
    /// the candidates are then left for the next step to find again.
    pub fn free_fraction(&mut self, a: &[DVec3], b: &[DVec3]) -> f64 {
        let toi = self.prepare_path(a, b);
        self.ready = false;
        toi
    }

    /// Finds the candidate pairs of the path from `a` to `b` (solver order) and returns the
    /// fraction of it the cloth can move without any pair reaching its target distance (1: the
    /// whole path). [`SelfContact::energy`] is then exact anywhere on the path.
    pub fn prepare_path(&mut self, a: &[DVec3], b: &[DVec3]) -> f64 {
        // A path longer than a few cells (a wild first direction) is cut first, so the swept
        // boxes stay small.
        let longest = a
            .iter()
            .zip(b)
            .map(|(p, q)| (*q - *p).length_squared())
            .fold(0.0, f64::max)
            .sqrt();
        let span = self.path_span;
        let longest = if span > 0.0 {
            self.obstacle_range()
                .map(|v| self.fixed[v].distance(self.obstacle_to[v]) * span)
                .fold(longest, f64::max)
        } else {
            longest
        };
        let limit = MAX_PATH_CELLS * self.cell;
        let cell = self.cell.max(longest.min(limit) / SWEPT_CELLS);
        if longest <= limit {
            return self.prepare_segment(a, b, cell);
        }
        let cut = limit / longest;
        // The obstacles' part of the path is cut alike.
        self.path_span = span * cut;
        let mut end = std::mem::take(&mut self.cut_end);
        end.clear();
        end.extend(a.iter().zip(b).map(|(p, q)| *p + (*q - *p) * cut));
        let toi = self.prepare_segment(a, &end, cell);
        self.path_span = span;
        self.cut_end = end;
        cut * toi
    }

    /// [`SelfContact::prepare_path`] without the cut.
    fn prepare_segment(&mut self, a: &[DVec3], b: &[DVec3], cell: f64) -> f64 {
        self.find_pairs(a, b, cell);
        self.ready = true;
        let mut pairs = std::mem::take(&mut self.pairs);
        // A pair whose distance cannot fall into its band on the path is dropped: a pair's
        // distance changes no faster than its relative motion. (Whether a pair is near does
        // not depend on the limit a search is given, and a time of impact found below it does
        // not either: the halves' minimum is the whole's.)
        let keep = |pairs: &mut Vec<Pair>| {
            let mut toi: f64 = 1.0;
            pairs.retain(|pair| {
                if pair.layer == 0.0 {
                    return true;
                }
                let (near, t) = self.pair_toi(pair, toi);
                toi = toi.min(t);
                near
            });
            toi
        };
        let toi = if self.parallel() && pairs.len() >= 2 {
            let mut right = pairs.split_off(pairs.len() / 2);
            let (l, r) = std::thread::scope(|scope| {
                let helper = scope.spawn(|| keep(&mut right));
                let l = keep(&mut pairs);
                (l, helper.join().expect("the narrow phase's thread"))
            });
            pairs.append(&mut right);
            l.min(r)
        } else {
            keep(&mut pairs)
        };
        self.pairs = pairs;
        toi
    }

    /// Whether `pair` can come within its band on the path [`SelfContact::find_pairs`] last
    /// looked along (its vertices' ends), and its conservative time of impact there (1 when
    /// none), looking no farther than `limit`.
    fn pair_toi(&self, pair: &Pair, limit: f64) -> (bool, f64) {
        let p0 = pair.v.map(|v| self.ends[v as usize].0);
        let p1 = pair.v.map(|v| self.ends[v as usize].1);
        let d: [DVec3; 4] = std::array::from_fn(|k| p1[k] - p0[k]);
        let mean = (d[0] + d[1] + d[2] + d[3]) * 0.25;
        let len = |k: usize| (d[k] - mean).length();
        let lp = if pair.edges {
            len(0).max(len(1)) + len(2).max(len(3))
        } else {
            len(0) + len(1).max(len(2)).max(len(3))
        };
        let lo = 0.5 * pair.layer;
        let d0 = self.separation(pair, p0).distance();
        if d0 - lp >= 3.0 * lo {
            return (false, 1.0);
        }
        let target = lo + CCD_GAP * (d0 - lo);
        if lp * limit <= d0 - target {
            return (true, 1.0);
        }
        let mut t = 0.0;
        let mut p = p0;
        let mut sep = self.separation(pair, p0);
        let mut dist = d0;
        for _ in 0..CCD_ROUNDS {
            let dt = CCD_ADVANCE
                * ((dist - target) / lp).max(plane_advance(pair.edges, &p, &d, sep, target));
            if t + dt >= limit {
                return (true, 1.0);
            }
            t += dt;
            p = std::array::from_fn(|k| p0[k] + d[k] * t);
            sep = self.separation(pair, p);
            dist = sep.distance();
            if dist - target <= 1e-3 * (d0 - target) {
                break;
            }
        }
        (true, t)
    }

    fn pair(&self, edges: bool, a: u32, b: u32, v: [u32; 4]) -> Pair {
        let key = pair_key(edges, a, b);
        let strength = v.iter().map(|&u| self.strength[u as usize]).sum::<f64>() * 0.25;
        Pair {
            key,
            v,
            edges,
            layer: self.thinned.get(&key).copied().unwrap_or(self.layer),
            strength,
        }
    }

    /// The barrier energy at `x` (solver order) over the candidates, J: infinite where a pair is
    /// at or below its band's bottom. Exact on the last prepared path.
    pub fn energy(&self, x: &[DVec3]) -> f64 {
        let mut total = 0.0;
        for pair in &self.pairs {
            if pair.layer == 0.0 {
                continue;
            }
            let d = self.separation(pair, self.positions(pair, x)).distance();
            let (lo, width) = (0.5 * pair.layer, pair.layer);
            if d >= lo + width {
                continue;
            }
            let u = (d - lo) / width;
            if u <= 0.0 {
                return f64::INFINITY;
            }
            total += pair.strength * width * barrier_shape(u).0;
        }
        total
    }

    /// Adds the barrier's gradient at `x` to `grad` (solver order), passes each free vertex's
    /// diagonal Hessian block to `block`, and keeps the pairs in their bands for
    /// [`SelfContact::add_product`]. Returns how many pairs are in their bands.
    pub fn add_derivatives(
        &mut self,
        x: &[DVec3],
        grad: &mut [DVec3],
        mut block: impl FnMut(usize, [[f64; 3]; 3]),
    ) -> usize {
        let mut active = std::mem::take(&mut self.active);
        active.clear();
        for pair in &self.pairs {
            if pair.layer == 0.0 {
                continue;
            }
            let s = self.separation(pair, self.positions(pair, x));
            let d = s.distance();
            let (lo, width) = (0.5 * pair.layer, pair.layer);
            if d >= lo + width || d <= lo {
                continue;
            }
            let (_, d1, d2) = barrier_shape((d - lo) / width);
            let n = s.vector / d;
            let force = pair.strength * d1;
            let stiffness = pair.strength * d2 / width;
            let free = pair.v.map(|v| self.slot[v as usize]);
            for k in 0..4 {
                if free[k] == PINNED {
                    continue;
                }
                let w = s.weights[k];
                grad[free[k] as usize] += n * (force * w);
                let c = stiffness * w * w;
                block(
                    free[k] as usize,
                    std::array::from_fn(|r| std::array::from_fn(|col| c * n[r] * n[col])),
                );
            }
            let mut drag = DVec3::ZERO;
            if self.obstacles_moving {
                for (&v, &w) in pair.v.iter().zip(&s.weights) {
                    let v = v as usize;
                    if self.is_obstacle(v) {
                        drag += n * (w * n.dot(self.obstacle_to[v] - self.fixed[v]));
                    }
                }
            }
            active.push(Active {
                free,
                weights: s.weights,
                normal: n,
                stiffness,
                drag,
            });
        }
        let count = active.len();
        self.active = active;
        count
    }

    /// Pairs in their bands at the last assembled iterate.
    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    /// out += the off-diagonal blocks of the barrier's Hessian times `v` (3n scalars, solver
    /// order), each free vertex's vector passed through `filter` on the way in and out (the
    /// colliders' constraint filter; the identity with the barrier model).
    pub fn add_product(&self, v: &[f64], out: &mut [f64], filter: impl Fn(usize, DVec3) -> DVec3) {
        let at = |i: usize| filter(i, DVec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]));
        for a in &self.active {
            // Each vertex's share of the normal motion, w_k n·v_k (0 where pinned).
            let along: [f64; 4] = std::array::from_fn(|k| match a.free[k] {
                PINNED => 0.0,
                i => a.weights[k] * a.normal.dot(at(i as usize)),
            });
            let sum: f64 = along.iter().sum();
            for (k, (&i, &own)) in a.free.iter().zip(&along).enumerate() {
                if i == PINNED {
                    continue;
                }
                let i = i as usize;
                let u = filter(i, a.normal * (a.stiffness * a.weights[k] * (sum - own)));
                out[3 * i] += u.x;
                out[3 * i + 1] += u.y;
                out[3 * i + 2] += u.z;
            }
        }
    }
}

/// How far along its path a pair certainly keeps `target` apart (its four vertices at `p`,
/// moving by `d` over the whole path), by the plane through its closest points normal to their
/// separation `sep`: every point of the first primitive less one of the second is a convex
/// combination of the corner differences (the vertex less each triangle corner; each end of
/// the one edge less each end of the other), so while every corner difference reaches at least
/// `target` along the separation's direction, so does the distance. Each such reach is linear
/// along the path. Zero when a corner is already below `target`.
///
/// Additive CCD's bound alone lets a pair sliding within micrometres of its target advance by
/// its gap over its relative motion a round: a layer of cloth sliding over another, or over a
/// body, then stops a path after a few per cent. Along the plane such a pair is cleared at once.
fn plane_advance(edges: bool, p: &[DVec3; 4], d: &[DVec3; 4], sep: Separation, target: f64) -> f64 {
    let len = sep.distance();
    if len <= target {
        return 0.0;
    }
    let n = sep.vector / len;
    let corners: &[(usize, usize)] = if edges {
        &[(0, 2), (0, 3), (1, 2), (1, 3)]
    } else {
        &[(0, 1), (0, 2), (0, 3)]
    };
    let mut advance = f64::INFINITY;
    for &(i, j) in corners {
        let reach = n.dot(p[i] - p[j]) - target;
        if reach < 0.0 {
            return 0.0;
        }
        let rate = n.dot(d[i] - d[j]);
        if rate < 0.0 {
            advance = advance.min(reach / -rate);
        }
    }
    advance
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::DVec3;

    use super::SelfContact;
    use crate::cloth::collide::mesh::MeshCollider;
    use crate::cloth::collide::{Collider, Colliders, ContactModel};
    use crate::cloth::preset::lab_cloth;
    use crate::cloth::system::ReducedSystem;
    use crate::cloth::{ClothModel, StepParams};

    /// The barrier's gradient against central differences of its energy (every free
    /// coordinate, at a state where pairs sit inside their bands), and its Gauss–Newton blocks
    /// positive semi-definite: the finite-difference check of the terms in `cloth::term`, for
    /// the term whose pairs change every step.
    #[test]
    fn the_barriers_gradient_matches_finite_differences_of_its_energy() {
        let lab = lab_cloth(4, 100.0);
        let pinned = lab.pinned_flags();
        let mass = vec![0.01; lab.mesh.positions.len()];
        let mut model = ClothModel::new(lab.mesh, lab.springs, mass, pinned).unwrap();
        // A wavy sheet, so that pairs' normals point every way.
        for p in &mut model.mesh.positions {
            p.y += 0.3 * (2.0 * p.x).sin() * (1.5 * p.z).cos();
        }
        let sys = ReducedSystem::new(&model, StepParams::garment()).unwrap();
        let x0 = sys.gather(model.positions());
        let mut s = SelfContact::new(&model, &sys, 0.4);
        s.begin_step(&x0);
        // Pairs rest at the top of their (thinned) bands at x0; move every particle a little.
        let x: Vec<DVec3> = x0
            .iter()
            .enumerate()
            .map(|(i, p)| {
                *p + 0.02
                    * DVec3::new(
                        (i as f64).sin(),
                        (1.7 * i as f64).cos(),
                        (2.3 * i as f64).sin(),
                    )
            })
            .collect();
        s.prepare_path(&x, &x);
        let mut grad = vec![DVec3::ZERO; x.len()];
        let mut blocks = Vec::new();
        let active = s.add_derivatives(&x, &mut grad, |_, b| blocks.push(b));
        assert!(active > 20, "{active} pairs in their bands");
        let e = s.energy(&x);
        assert!(e.is_finite() && e > 0.0);
        let scale = grad
            .iter()
            .map(|g| g.abs().max_element())
            .fold(0.0, f64::max);
        let h = 1e-7;
        let mut y = x.clone();
        for i in 0..x.len() {
            for c in 0..3 {
                y[i][c] = x[i][c] + h;
                let plus = s.energy(&y);
                y[i][c] = x[i][c] - h;
                let minus = s.energy(&y);
                y[i][c] = x[i][c];
                let fd = (plus - minus) / (2.0 * h);
                assert!(
                    (fd - grad[i][c]).abs() <= 1e-5 * scale,
                    "particle {i} axis {c}: gradient {}, from the energy {fd}",
                    grad[i][c]
                );
            }
        }
        for b in blocks {
            let m = glam::DMat3::from_cols_array_2d(&b);
            assert!(m.determinant().abs() <= 1e-9 * m.x_axis.length().max(1.0));
            assert!(b[0][0] >= 0.0 && b[1][1] >= 0.0 && b[2][2] >= 0.0);
        }
    }

    /// A body moving within the steps moves alone: a second mesh obstacle beside it (a table
    /// under it) keeps its vertices while the body is pushed halfway, then all the way.
    #[test]
    fn only_the_moving_obstacle_moves_within_a_step() {
        let lab = lab_cloth(4, 100.0);
        let pinned = lab.pinned_flags();
        let mass = vec![0.01; lab.mesh.positions.len()];
        let model = ClothModel::new(lab.mesh, lab.springs, mass, pinned).unwrap();
        let sys = ReducedSystem::new(&model, StepParams::garment()).unwrap();
        let square = |y: f64| {
            let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
            corners.map(|(x, z)| DVec3::new(x, y, z)).to_vec()
        };
        let quad = vec![[0, 2, 1], [0, 3, 2]];
        let mesh = |y: f64| {
            Collider::Mesh(Arc::new(
                MeshCollider::new(square(y), quad.clone()).unwrap(),
            ))
        };
        let colliders = Colliders {
            shapes: vec![mesh(-2.0), mesh(-1.0)],
            thickness: 0.01,
            friction: 0.0,
            model: ContactModel::Barrier,
        };
        let mut s = SelfContact::new(&model, &sys, 0.01)
            .with_obstacles(&colliders)
            .moving_obstacles(true);
        let cloth = model.particle_count();
        let table = cloth..cloth + 4;
        let body = cloth + 4..cloth + 8;
        s.move_obstacle(1, &square(-0.5));
        assert!(s.obstacles_moving());
        s.commit_obstacles(0.5);
        for v in table.clone() {
            assert_eq!(s.fixed[v].y, -2.0, "the table moved");
        }
        for v in body.clone() {
            assert!(
                (s.fixed[v].y + 0.75).abs() < 1e-12,
                "the body halfway: {}",
                s.fixed[v]
            );
        }
        s.commit_obstacles(1.0);
        assert!(!s.obstacles_moving());
        for v in table {
            assert_eq!(s.fixed[v].y, -2.0, "the table moved");
        }
        for v in body {
            assert_eq!(s.fixed[v].y, -0.5);
        }
    }

    /// The plane's advance never lets a pair come closer than its target: sampled densely along
    /// the path, for point–triangle and edge–edge pairs of every shape and motion; and it clears
    /// a point sliding a centimetre over a triangle a micrometre above its target in one go,
    /// where additive CCD's bound allows a ten-thousandth of the path a round.
    #[test]
    fn the_planes_advance_is_conservative_and_clears_sliding_pairs() {
        use super::plane_advance;
        use crate::cloth::proximity::{point_triangle, segment_segment};
        let mut seed = 0.5_f64;
        let mut next = || {
            seed = (seed * 9301.0 + 49297.0) % 233280.0;
            seed / 233280.0 - 0.5
        };
        let mut cleared = 0;
        for case in 0..4000 {
            let edges = case % 2 == 1;
            let p: [DVec3; 4] = std::array::from_fn(|_| DVec3::new(next(), next(), next()));
            let d: [DVec3; 4] =
                std::array::from_fn(|_| DVec3::new(next(), next(), next()) * (0.1 + next()));
            let sep = |p: &[DVec3; 4]| {
                if edges {
                    segment_segment(p[0], p[1], p[2], p[3])
                } else {
                    point_triangle(p[0], p[1], p[2], p[3])
                }
            };
            let s0 = sep(&p);
            let target = 0.8 * s0.distance();
            let t = plane_advance(edges, &p, &d, s0, target).min(1.0);
            if t > 0.0 {
                cleared += 1;
            }
            for k in 0..=1000 {
                let tk = t * k as f64 / 1000.0;
                let q: [DVec3; 4] = std::array::from_fn(|i| p[i] + d[i] * tk);
                let dist = sep(&q).distance();
                assert!(
                    dist >= target * (1.0 - 1e-9),
                    "case {case}: {dist} < {target} at {tk}"
                );
            }
        }
        assert!(
            cleared > 400,
            "the plane cleared only {cleared} of 4000 paths"
        );

        // A point 1 µm above its target over a tilted triangle, sliding 1 cm along it.
        let n = DVec3::new(0.3, 1.0, -0.2).normalize();
        let u = n.any_orthonormal_vector();
        let v = n.cross(u);
        let (a, b, c) = (DVec3::ZERO - 0.05 * (u + v), 0.05 * u, 0.05 * v);
        let target = 1e-3;
        let point = 0.01 * (u + v) + n * (target + 1e-6);
        let p = [point, a, b, c];
        let slide = 0.01 * (u - 0.5 * v);
        let d = [slide, DVec3::ZERO, DVec3::ZERO, DVec3::ZERO];
        let s0 = point_triangle(point, a, b, c);
        assert!(plane_advance(false, &p, &d, s0, target) >= 1.0);
    }
}
