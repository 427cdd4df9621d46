//! Nonlinear Gauss–Seidel sweeps on a step's objective, between Newton iterations.
//!
//! A sweep visits the free particles in solver order and moves each by one local Newton step
//! on g (see [`ReducedSystem`]) with every other particle held: Δxᵢ = −Hᵢᵢ⁻¹ ∇ᵢg, where Hᵢᵢ is
//! the particle's 3×3 block of Newton's Hessian (inertia, its springs' projected blocks, its
//! bending weights, and with the barrier contact model its barrier and friction blocks). This is
//! the local solve of vertex block descent (Chen et al. 2024), used here as a smoother: stiff
//! cloth's Newton steps leave a local residual (springs lengthened by the square of a tangential
//! move) that Gauss–Seidel removes for a fraction of a factorisation's cost, while Newton keeps
//! the global, low-frequency part. [`super::NewtonSolver`] keeps a pass only when it lowers g
//! and checks its tolerance on the full gradient as before.
//!
//! With colliders, each particle's barrier is evaluated against the tangent planes of the
//! surfaces within reach where the pass starts ([`NewtonContact::barrier_planes`]), and no
//! particle moves farther than the collision thickness from there in one pass (so the planes
//! stay close to the surfaces; on a convex collider a plane is never farther than the surface).
//! A local step that would cross a barrier is halved until it does not.
//!
//! On two threads ([`Smoother::sweep`]'s `parallel`): a large model's particles are split once
//! into two parts A and B that share no spring and no bending stencil, and the separator S
//! between them ([`Smoother::new`]: a level set of a breadth-first search over the particles'
//! couplings). Every sweep visits A, then B, then S, so A's and B's local steps read nothing the
//! other writes and run at once, and the result is the same on one thread or two.

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{DMat3, DVec3};

use super::collide::barrier::BarrierPlane;
use super::collide::contact::NewtonContact;
use super::law::spring_local;
use super::linalg::handoff::{wait_for, PanicGuard};
use super::system::{ReducedSystem, PINNED};
use super::term::{bending, inertia, Term};

/// Models with fewer free particles than this are swept in solver order, on one thread: below
/// it a sweep takes about as long as starting a thread (a sweep of the 8k-vertex skirt takes
/// about 1.5 ms, a thread tens of microseconds). From it, the split order (on one thread or
/// two): the demo's robot skirt (1,560 particles) alone on two threads bakes in 0.80× the wall
/// time it takes swept in solver order (`farm-bench -n 3 --vs`, side by side).
const PARALLEL_MIN: usize = 1024;

/// The terms of g each free particle appears in, as compressed lists per particle (particle i's
/// entries are `start[i]..start[i + 1]`), in the smoother's own order of particles and stencils.
#[derive(Debug, Clone)]
pub struct Smoother {
    /// The sweep's order: local index → solver index; part A, then B, then the separator S.
    order: Vec<u32>,
    /// Where B and S start in `order` (A is `0..parts[0]`).
    parts: [usize; 2],
    /// Local stencil index → stencil: those with a particle in A, then in B, then in S only.
    stencil_order: Vec<u32>,
    /// Where B's and S's stencils start in `stencil_order`.
    stencil_parts: [usize; 2],
    spring_start: Vec<u32>,
    /// The particle's springs to other free particles.
    springs: Vec<Link>,
    anchor_start: Vec<u32>,
    /// The particle's springs to pins (indices into [`ReducedSystem::anchors`]).
    anchors: Vec<u32>,
    bend_start: Vec<u32>,
    /// The bending stencils the particle is in (local stencil index), with its weight there,
    /// √(N/m).
    bends: Vec<(u32, f64)>,
    tri_start: Vec<u32>,
    /// The membrane triangles the particle is in: the triangle, the particle's corner there,
    /// and the corners' local indices ([`PINNED`] for a pinned corner).
    tris: Vec<(u32, u32, [u32; 3])>,
}

/// A spring seen from one end.
#[derive(Debug, Clone, Copy, Default)]
struct Link {
    /// The other end's local index.
    other: u32,
    /// Rest length, m.
    rest: f64,
    /// Stiffness in tension and in compression, N/m.
    k: f64,
    kc: f64,
}

/// Groups `(owner, item)` pairs by owner (0..n): the starts and the items in owner order.
fn csr<T: Copy + Default>(
    n: usize,
    items: impl Iterator<Item = (usize, T)> + Clone,
) -> (Vec<u32>, Vec<T>) {
    let mut start = vec![0u32; n + 1];
    for (i, _) in items.clone() {
        start[i + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut out = vec![T::default(); start[n] as usize];
    for (i, item) in items {
        out[fill[i] as usize] = item;
        fill[i] += 1;
    }
    (start, out)
}

/// Which part of [`Smoother`]'s split a particle is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Part {
    A,
    B,
    S,
}

/// Splits the `n` particles coupled by `pairs` into parts A and B with no pair between them and
/// a separator S: the level sets of a breadth-first search from a far particle (a pair joins
/// the same or neighbouring levels), A the levels before the one that balances A and B best, S
/// that level, B the rest (particles the search does not reach included). `None` when a part
/// would hold less than an eighth of the particles.
fn bisect(n: usize, pairs: &[(u32, u32)]) -> Option<Vec<Part>> {
    let (start, adjacent) = csr(
        n,
        pairs
            .iter()
            .flat_map(|&(a, b)| [(a as usize, b), (b as usize, a)]),
    );
    let levels = |from: usize| {
        let mut level = vec![u32::MAX; n];
        let mut queue = vec![from as u32];
        level[from] = 0;
        let mut head = 0;
        while let Some(&i) = queue.get(head) {
            head += 1;
            let i = i as usize;
            for &j in &adjacent[start[i] as usize..start[i + 1] as usize] {
                if level[j as usize] == u32::MAX {
                    level[j as usize] = level[i] + 1;
                    queue.push(j);
                }
            }
        }
        let last = *queue.last().expect("the start") as usize;
        (level, last)
    };
    // From the particle farthest from particle 0: far from the middle, so the levels are short
    // fronts across the mesh.
    let (_, far) = levels(0);
    let (level, _) = levels(far);
    let depth = level.iter().filter(|&&l| l != u32::MAX).max().copied()? as usize;
    let mut count = vec![0usize; depth + 1];
    for &l in level.iter().filter(|&&l| l != u32::MAX) {
        count[l as usize] += 1;
    }
    let mut before = 0;
    let mut best: Option<(usize, usize)> = None;
    for (k, &here) in count.iter().enumerate() {
        let after = n - before - here;
        let imbalance = before.abs_diff(after);
        if best.is_none_or(|(_, b)| imbalance < b) {
            best = Some((k, imbalance));
        }
        before += here;
    }
    let (cut, _) = best?;
    let parts: Vec<Part> = level
        .iter()
        .map(|&l| match (l as usize).cmp(&cut) {
            std::cmp::Ordering::Less => Part::A,
            std::cmp::Ordering::Equal => Part::S,
            std::cmp::Ordering::Greater => Part::B,
        })
        .collect();
    let smallest = [Part::A, Part::B]
        .iter()
        .map(|p| parts.iter().filter(|q| *q == p).count())
        .min()?;
    (smallest * 8 >= n).then_some(parts)
}

impl Smoother {
    /// The incidence lists of `sys` (whose springs and stencils must not change afterwards), and
    /// for a model of at least [`PARALLEL_MIN`] free particles its split into two parts and a
    /// separator.
    pub fn new(sys: &ReducedSystem) -> Self {
        let n = sys.len();
        let sp = &sys.springs;
        let b = &sys.bends;
        let free = |s: usize| b.v[s].into_iter().filter(|&v| v != PINNED);
        let parts = (n >= PARALLEL_MIN)
            .then(|| {
                let pairs: Vec<(u32, u32)> = sp
                    .a
                    .iter()
                    .zip(&sp.b)
                    .map(|(&a, &b)| (a, b))
                    .chain((0..b.len()).flat_map(|s| {
                        free(s)
                            .flat_map(move |i| free(s).filter(move |&j| j > i).map(move |j| (i, j)))
                    }))
                    .chain(sys.membrane.pairs())
                    .collect();
                bisect(n, &pairs)
            })
            .flatten()
            .unwrap_or_else(|| vec![Part::S; n]);
        // Solver order within each part.
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by_key(|&i| parts[i as usize]);
        let count = |p: Part| parts.iter().filter(|&&q| q == p).count();
        let (na, nb) = (count(Part::A), count(Part::B));
        let mut local = vec![0u32; n];
        for (l, &i) in order.iter().enumerate() {
            local[i as usize] = l as u32;
        }
        // A stencil is in the part of its particles (no stencil has particles in both A and B).
        let stencil_parts: Vec<Part> = (0..b.len())
            .map(|s| free(s).map(|v| parts[v as usize]).min().unwrap_or(Part::S))
            .collect();
        let mut stencil_order: Vec<u32> = (0..b.len() as u32).collect();
        stencil_order.sort_by_key(|&s| stencil_parts[s as usize]);
        let stencil_count = |p: Part| stencil_parts.iter().filter(|&&q| q == p).count();
        let (sa, sb) = (stencil_count(Part::A), stencil_count(Part::B));
        let mut stencil_local = vec![0u32; b.len()];
        for (l, &s) in stencil_order.iter().enumerate() {
            stencil_local[s as usize] = l as u32;
        }

        let link = |s: usize, other: u32| Link {
            other: local[other as usize],
            rest: sp.rest[s],
            k: sp.k[s],
            kc: sp.kc[s],
        };
        let (spring_start, springs) = csr(
            n,
            (0..sp.a.len()).flat_map(|s| {
                [
                    (local[sp.a[s] as usize] as usize, link(s, sp.b[s])),
                    (local[sp.b[s] as usize] as usize, link(s, sp.a[s])),
                ]
            }),
        );
        let an = &sys.anchors;
        let (anchor_start, anchors) = csr(
            n,
            (0..an.a.len()).map(|i| (local[an.a[i] as usize] as usize, i as u32)),
        );
        let (bend_start, bends) = csr(
            n,
            (0..b.len()).flat_map(|s| {
                let (local, stencil_local) = (&local, &stencil_local);
                (0..4).filter(move |&k| b.v[s][k] != PINNED).map(move |k| {
                    (
                        local[b.v[s][k] as usize] as usize,
                        (stencil_local[s], b.w[s][k]),
                    )
                })
            }),
        );
        let m = &sys.membrane;
        let (tri_start, tris) = csr(
            n,
            (0..m.len()).flat_map(|e| {
                let v = m.vertices(e);
                let corners: [u32; 3] = std::array::from_fn(|c| {
                    if v[c] == PINNED {
                        PINNED
                    } else {
                        local[v[c] as usize]
                    }
                });
                (0..3)
                    .filter(move |&c| corners[c] != PINNED)
                    .map(move |c| (corners[c] as usize, (e as u32, c as u32, corners)))
            }),
        );
        Smoother {
            tri_start,
            tris,
            order,
            parts: [na, na + nb],
            stencil_order,
            stencil_parts: [sa, sa + sb],
            spring_start,
            springs,
            anchor_start,
            anchors,
            bend_start,
            bends,
        }
    }

    /// The particles of the two parts swept at once (0 and 0 when the model is not split).
    pub fn parts(&self) -> (usize, usize) {
        (self.parts[0], self.parts[1] - self.parts[0])
    }

    /// Runs `sweeps` sweeps on `x` (solver order, m) for the objective with inertial target `y`
    /// (see [`ReducedSystem::objective`]) and, when given, the contact's barrier and friction;
    /// the two parts of a split model at once on two threads when `parallel` (the same result as
    /// on one). `x` may end with a higher objective than it started with (the local steps are not
    /// line searched); the caller compares.
    #[allow(clippy::too_many_arguments)]
    pub fn sweep(
        &self,
        sys: &ReducedSystem,
        x: &mut [DVec3],
        y: &[DVec3],
        sweeps: usize,
        contact: Option<&NewtonContact>,
        scratch: &mut SweepScratch,
        parallel: bool,
    ) {
        let b = &sys.bends;
        let SweepScratch {
            local,
            bend_values,
            plane_start,
            planes,
            start,
        } = scratch;
        local.clear();
        local.extend(self.order.iter().map(|&i| x[i as usize]));
        bend_values.clear();
        bend_values.extend(self.stencil_order.iter().map(|&s| b.value(s as usize, x)));
        // With colliders every particle stays within `margin` of where it starts, where its
        // barrier planes stand for the colliders' surfaces.
        let margin = contact.map(|c| c.colliders().thickness);
        plane_start.clear();
        planes.clear();
        start.clear();
        if let (Some(c), Some(margin)) = (contact, margin) {
            start.extend_from_slice(local);
            plane_start.push(0);
            for (l, p) in local.iter().enumerate() {
                c.barrier_planes(self.order[l] as usize, *p, margin, planes);
                plane_start.push(planes.len() as u32);
            }
        }
        let h = sys.params.time_step;
        let step = Step {
            sys,
            y,
            w: sys.inertia_scale() / (h * h),
            contact,
            margin,
            plane_start,
            planes,
            start,
        };
        if parallel && self.parts[0] > 0 {
            self.sweep_parallel(&step, local, bend_values, sweeps);
        } else {
            // A, B and S in turn: the parallel sweep's order.
            let n = local.len();
            for _ in 0..sweeps {
                self.relax(0..n, &step, View::new(local, 0, &[], n), (bend_values, 0));
            }
        }
        for (l, &i) in self.order.iter().enumerate() {
            x[i as usize] = local[l];
        }
    }

    /// [`Smoother::sweep`]'s `sweeps` sweeps over `local` (positions in the smoother's order) and
    /// `bend_values` (by local stencil) with a second thread: in each, this thread moves part A
    /// while the other moves part B, then this one moves the separator S.
    fn sweep_parallel(
        &self,
        step: &Step<'_>,
        local: &mut [DVec3],
        bend_values: &mut [DVec3],
        sweeps: usize,
    ) {
        let (n, stencils) = (local.len(), bend_values.len());
        let [a, b] = self.parts;
        let [sa, sb] = self.stencil_parts;
        let shared = Shared {
            x: local.as_mut_ptr(),
            bends: bend_values.as_mut_ptr(),
        };
        let shared = &shared;
        // Sweep k's part B may start once `go` is k; it is done once `done` is k.
        let (go, done) = (AtomicUsize::new(0), AtomicUsize::new(0));
        std::thread::scope(|threads| {
            threads.spawn(|| {
                let _done_if_panicking = PanicGuard(&done);
                for k in 1..=sweeps {
                    wait_for(&go, k);
                    // SAFETY: from `go` = k to `done` = k the other thread holds only part A's
                    // positions (local 0..a) and stencils (0..sa) mutably and S's positions
                    // (b..n) shared: this thread takes B's (a..b, sa..sb) mutably and S's
                    // shared, so no element is borrowed mutably twice or written while shared.
                    // Both pointers cover `n` and `stencils` elements, and a <= b <= n,
                    // sa <= sb <= stencils. (That no spring or stencil joins A and B, `bisect`,
                    // makes each part's steps read only its own slices and S's; were it broken,
                    // the slices' bounds checks would panic, not race.)
                    let (xb, xs, bb) = unsafe {
                        (
                            std::slice::from_raw_parts_mut(shared.x.add(a), b - a),
                            std::slice::from_raw_parts(shared.x.add(b), n - b),
                            std::slice::from_raw_parts_mut(shared.bends.add(sa), sb - sa),
                        )
                    };
                    self.relax(a..b, step, View::new(xb, a, xs, b), (bb, sa));
                    done.store(k, Ordering::Release);
                }
            });
            let _go_if_panicking = PanicGuard(&go);
            for k in 1..=sweeps {
                go.store(k, Ordering::Release);
                {
                    // SAFETY: as above, for part A, while the other thread moves part B.
                    let (xa, xs, ba) = unsafe {
                        (
                            std::slice::from_raw_parts_mut(shared.x, a),
                            std::slice::from_raw_parts(shared.x.add(b), n - b),
                            std::slice::from_raw_parts_mut(shared.bends, sa),
                        )
                    };
                    self.relax(0..a, step, View::new(xa, 0, xs, b), (ba, 0));
                }
                wait_for(&done, k);
                // SAFETY: the other thread is done with sweep k and waits for `go` = k + 1,
                // holding no slice: this thread has every position and stencil to itself.
                let (x, bends) = unsafe {
                    (
                        std::slice::from_raw_parts_mut(shared.x, n),
                        std::slice::from_raw_parts_mut(shared.bends, stencils),
                    )
                };
                self.relax(b..n, step, View::new(x, 0, &[], n), (bends, 0));
            }
        });
    }

    /// One local Newton step for each particle of `range` (local indices) in turn, reading and
    /// moving positions through `x` and the bending values of local stencils `bends.1..` in
    /// `bends.0`.
    fn relax(
        &self,
        range: std::ops::Range<usize>,
        step: &Step<'_>,
        mut x: View<'_>,
        bends: (&mut [DVec3], usize),
    ) {
        let Step {
            sys,
            y,
            w,
            contact,
            margin,
            plane_start,
            planes,
            start,
        } = *step;
        let an = &sys.anchors;
        let jam = sys.jam_strain;
        let (bend_values, bend_base) = bends;
        'particles: for i in range {
            let xi = x.get(i);
            let solver = self.order[i] as usize;
            let (mut g, mut diag) = inertia::pull(xi, y[solver], w * sys.mass[solver]);
            let mut hm = DMat3::ZERO;
            let mut add = |r: DVec3, rest: f64, k: f64, kc: f64| {
                if let Some((f, t, across)) = spring_local(r, rest, k, kc, jam) {
                    g += f;
                    diag += t;
                    hm += across;
                }
            };
            for l in &self.springs[self.spring_start[i] as usize..self.spring_start[i + 1] as usize]
            {
                add(xi - x.get(l.other as usize), l.rest, l.k, l.kc);
            }
            for &a in
                &self.anchors[self.anchor_start[i] as usize..self.anchor_start[i + 1] as usize]
            {
                let a = a as usize;
                add(xi - an.at[a], an.rest[a], an.k[a], an.kc[a]);
            }
            let incident =
                &self.bends[self.bend_start[i] as usize..self.bend_start[i + 1] as usize];
            for &(s, wi) in incident {
                let (gb, hb) = bending::corner(bend_values[s as usize - bend_base], wi);
                g += gb;
                diag += hb;
            }
            hm += DMat3::from_diagonal(DVec3::splat(diag));
            for &(e, a, corners) in
                &self.tris[self.tri_start[i] as usize..self.tri_start[i + 1] as usize]
            {
                let corner = |c: usize| x.get(corners[c] as usize);
                sys.membrane
                    .add_local_with(e as usize, a as usize, corner, &mut g, &mut hm);
            }
            let mine = match contact {
                Some(_) => &planes[plane_start[i] as usize..plane_start[i + 1] as usize],
                None => &[][..],
            };
            if let Some(c) = contact {
                if !c.particle_terms(solver, xi, mine, &mut g, &mut hm) {
                    continue;
                }
            }
            let det = hm.determinant();
            let m2 = hm.x_axis.x * hm.y_axis.y - hm.x_axis.y * hm.y_axis.x;
            if !(det > 0.0 && det.is_finite() && m2 > 0.0 && hm.x_axis.x > 0.0) {
                continue;
            }
            let mut d = -(hm.inverse() * g);
            if let Some(margin) = margin {
                // Stay within the margin, and in front of the barrier.
                let from = start[i];
                let far = (xi + d).distance(from);
                if far > margin {
                    d = (from + (xi + d - from) * (margin / far)) - xi;
                }
                let mut halvings = 0;
                while !mine.iter().all(|plane| plane.allows(xi + d)) {
                    if halvings == 8 {
                        continue 'particles;
                    }
                    d *= 0.5;
                    halvings += 1;
                }
            }
            x.set(i, xi + d);
            for &(s, wi) in incident {
                bend_values[s as usize - bend_base] += d * wi;
            }
        }
    }
}

/// The positions and bending values of a parallel sweep, shared by its two threads
/// ([`Smoother::sweep_parallel`], whose phases keep their accesses apart).
struct Shared {
    x: *mut DVec3,
    bends: *mut DVec3,
}

// SAFETY: the pointers are only dereferenced as [`Smoother::sweep_parallel`] describes: in each
// phase the two threads take disjoint parts mutably and share only reads of the separator.
unsafe impl Sync for Shared {}

/// What every local step of a sweep reads.
#[derive(Clone, Copy)]
struct Step<'a> {
    sys: &'a ReducedSystem,
    /// The inertial target, solver order.
    y: &'a [DVec3],
    /// s/h², 1/s².
    w: f64,
    contact: Option<&'a NewtonContact>,
    /// How far a particle may move from `start` in one pass (with colliders), m.
    margin: Option<f64>,
    /// Per particle (local order): its barrier planes, and where the pass started.
    plane_start: &'a [u32],
    planes: &'a [BarrierPlane],
    start: &'a [DVec3],
}

/// Positions by local index: the range a sweep moves (`mine`, from local index `base`) and,
/// read-only, the separator's (`shared`, from `shared_base`).
struct View<'a> {
    mine: &'a mut [DVec3],
    base: usize,
    shared: &'a [DVec3],
    shared_base: usize,
}

impl<'a> View<'a> {
    fn new(mine: &'a mut [DVec3], base: usize, shared: &'a [DVec3], shared_base: usize) -> Self {
        View {
            mine,
            base,
            shared,
            shared_base,
        }
    }

    #[inline(always)]
    fn get(&self, i: usize) -> DVec3 {
        match self.mine.get(i.wrapping_sub(self.base)) {
            Some(p) => *p,
            None => self.shared[i - self.shared_base],
        }
    }

    #[inline(always)]
    fn set(&mut self, i: usize, p: DVec3) {
        self.mine[i - self.base] = p;
    }
}

/// Buffers of [`Smoother::sweep`], kept between calls.
#[derive(Debug, Clone, Default)]
pub struct SweepScratch {
    /// Positions in the smoother's order.
    local: Vec<DVec3>,
    bend_values: Vec<DVec3>,
    plane_start: Vec<u32>,
    planes: Vec<BarrierPlane>,
    start: Vec<DVec3>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pairs of a `w`×`h` grid of particles: each with its right and lower neighbour, and
    /// each cell's corners with one another (a bending stencil couples all four).
    fn grid_pairs(w: usize, h: usize) -> Vec<(u32, u32)> {
        let id = |i: usize, j: usize| (j * w + i) as u32;
        let mut pairs = Vec::new();
        for j in 0..h {
            for i in 0..w {
                if i + 1 < w {
                    pairs.push((id(i, j), id(i + 1, j)));
                }
                if j + 1 < h {
                    pairs.push((id(i, j), id(i, j + 1)));
                }
                if i + 1 < w && j + 1 < h {
                    pairs.push((id(i, j), id(i + 1, j + 1)));
                    pairs.push((id(i + 1, j), id(i, j + 1)));
                }
            }
        }
        pairs
    }

    /// No pair joins parts A and B, so their sweeps can run at once; the parts are balanced and
    /// the separator is one front across the grid.
    #[test]
    fn bisect_leaves_no_pair_between_its_parts() {
        let (w, h) = (60, 40);
        let pairs = grid_pairs(w, h);
        let parts = bisect(w * h, &pairs).expect("a grid splits");
        for &(a, b) in &pairs {
            let (pa, pb) = (parts[a as usize], parts[b as usize]);
            assert!(
                !matches!((pa, pb), (Part::A, Part::B) | (Part::B, Part::A)),
                "particles {a} and {b} are coupled across the parts"
            );
        }
        let count = |p: Part| parts.iter().filter(|&&q| q == p).count();
        let (a, b, s) = (count(Part::A), count(Part::B), count(Part::S));
        assert!(a.abs_diff(b) <= w + h, "parts of {a} and {b} particles");
        assert!(s <= w + h, "a separator of {s} particles");
        // Two grids side by side, not coupled: the one the search does not reach joins B.
        let mut twice = pairs.clone();
        let offset = (w * h) as u32;
        twice.extend(pairs.iter().map(|&(a, b)| (a + offset, b + offset)));
        let parts = bisect(2 * w * h, &twice).expect("two grids split");
        for &(a, b) in &twice {
            let (pa, pb) = (parts[a as usize], parts[b as usize]);
            assert!(!matches!((pa, pb), (Part::A, Part::B) | (Part::B, Part::A)));
        }
        // A star (every particle coupled through one) has no balanced split.
        let star: Vec<(u32, u32)> = (1..20).map(|i| (0, i)).collect();
        assert!(bisect(20, &star).is_none());
    }
}
