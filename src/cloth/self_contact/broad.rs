//! Self-contact's broad phase: the primitives' boxes swept over a path, hashed into a uniform
//! grid, and the vertex–triangle and edge–edge pairs whose boxes overlap (on two threads for
//! large cloths, each half in order, so the pairs and their order are one thread's).

use glam::DVec3;

use super::{Pair, SelfContact};
use crate::cloth::system::PINNED;

/// A pair's key: a vertex and a triangle, or two edges (the lower index first).
#[inline]
pub(super) fn pair_key(edges: bool, a: u32, b: u32) -> u64 {
    (u64::from(edges) << 63) | (u64::from(a) << 32) | u64::from(b)
}

/// Binned items by cell key, in a table of buckets twice as many as the entries (a counting
/// sort by hashed key): a cell's items are in its bucket, with those of the few cells that
/// share it (queries check boxes anyway).
#[derive(Debug, Clone, Default)]
pub(super) struct HashGrid {
    start: Vec<u32>,
    next: Vec<u32>,
    items: Vec<u32>,
    bits: u32,
}

impl HashGrid {
    #[inline]
    pub(super) fn slot(&self, key: u64) -> usize {
        (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> (64 - self.bits)) as usize
    }

    pub(super) fn build(&mut self, entries: &[(u64, u32)]) {
        self.bits = (2 * entries.len().max(1))
            .next_power_of_two()
            .trailing_zeros()
            .max(1);
        let size = 1usize << self.bits;
        self.start.clear();
        self.start.resize(size + 1, 0);
        for &(k, _) in entries {
            let h = self.slot(k);
            self.start[h + 1] += 1;
        }
        for i in 0..size {
            self.start[i + 1] += self.start[i];
        }
        self.items.clear();
        self.items.resize(entries.len(), 0);
        self.next.clear();
        self.next.extend_from_slice(&self.start[..size]);
        for &(k, item) in entries {
            let h = self.slot(k);
            self.items[self.next[h] as usize] = item;
            self.next[h] += 1;
        }
    }

    #[inline]
    pub(super) fn bucket(&self, key: u64) -> &[u32] {
        let h = self.slot(key);
        &self.items[self.start[h] as usize..self.start[h + 1] as usize]
    }
}

/// An axis-aligned box.
#[derive(Debug, Clone, Copy)]
pub(super) struct Aabb {
    lo: DVec3,
    hi: DVec3,
}

impl Aabb {
    pub(super) fn of(points: &[(DVec3, DVec3)], grow: f64) -> Self {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for (a, b) in points {
            lo = lo.min(a.min(*b));
            hi = hi.max(a.max(*b));
        }
        Aabb {
            lo: lo - grow,
            hi: hi + grow,
        }
    }

    pub(super) fn overlaps(&self, other: &Aabb) -> bool {
        self.lo.cmple(other.hi).all() && other.lo.cmple(self.hi).all()
    }
}

/// The keys of the grid cells of size `cell` (m) that box `b` overlaps (21 bits an axis,
/// wrapping: far cells may share a key, and queries check boxes anyway).
pub(super) fn cells(b: &Aabb, cell: f64) -> impl Iterator<Item = u64> {
    let lo = (b.lo / cell).floor().as_ivec3();
    let hi = (b.hi / cell).floor().as_ivec3();
    let m = |c: i32| u64::from(c as u32 & 0x1f_ffff);
    (lo.x..=hi.x).flat_map(move |x| {
        (lo.y..=hi.y)
            .flat_map(move |y| (lo.z..=hi.z).map(move |z| (m(x) << 42) | (m(y) << 21) | m(z)))
    })
}

impl SelfContact {
    /// Bins primitives' grown swept boxes into the grid and collects the candidate pairs.
    pub(super) fn find_pairs(&mut self, a: &[DVec3], b: &[DVec3], cell: f64) {
        let span = self.path_span;
        let first = self.obstacles.first().map_or(usize::MAX, |o| o.1 as usize);
        for (v, e) in self.ends.iter_mut().enumerate() {
            *e = match self.slot[v] {
                // (A span is set only while obstacles move: `obstacle_to` covers them.)
                PINNED if span > 0.0 && v >= first => {
                    let f = self.fixed[v];
                    (f, f + (self.obstacle_to[v] - f) * span)
                }
                PINNED => (self.fixed[v], self.fixed[v]),
                s => (a[s as usize], b[s as usize]),
            };
        }
        let grow = 0.75 * self.layer;
        let ends = &self.ends;
        let mut boxes = std::mem::take(&mut self.boxes);
        let mut pairs = std::mem::take(&mut self.pairs);
        pairs.clear();
        let mut bins = std::mem::take(&mut self.bins);
        let mut stamp = std::mem::take(&mut self.stamp);
        // Vertex against triangle.
        bins.clear();
        boxes.clear();
        for (t, tri) in self.triangles.iter().enumerate() {
            let b = Aabb::of(&tri.map(|v| ends[v as usize]), grow);
            bins.extend(cells(&b, cell).map(|k| (k, t as u32)));
            boxes.push(b);
        }
        let mut grid = std::mem::take(&mut self.grid);
        grid.build(&bins);
        let mut stamp2 = std::mem::take(&mut self.stamp2);
        let mut pairs2 = std::mem::take(&mut self.pairs2);
        let parallel = self.parallel();
        let vertices = self.slot.len() as u32;
        if parallel {
            let half = vertices / 2;
            std::thread::scope(|scope| {
                let helper = scope.spawn(|| {
                    self.vertex_pairs(
                        half..vertices,
                        &grid,
                        &boxes,
                        &mut stamp2,
                        &mut pairs2,
                        grow,
                        cell,
                    )
                });
                self.vertex_pairs(0..half, &grid, &boxes, &mut stamp, &mut pairs, grow, cell);
                helper.join().expect("the broad phase's thread");
            });
            pairs.append(&mut pairs2);
        } else {
            self.vertex_pairs(
                0..vertices,
                &grid,
                &boxes,
                &mut stamp,
                &mut pairs,
                grow,
                cell,
            );
        }
        // Edge against edge.
        bins.clear();
        boxes.clear();
        for (e, edge) in self.edges.iter().enumerate() {
            let b = Aabb::of(&edge.map(|v| ends[v as usize]), grow);
            bins.extend(cells(&b, cell).map(|k| (k, e as u32)));
            boxes.push(b);
        }
        grid.build(&bins);
        let count = self.edges.len() as u32;
        if parallel {
            let half = count / 2;
            std::thread::scope(|scope| {
                let helper = scope.spawn(|| {
                    self.edge_pairs(half..count, &grid, &boxes, &mut stamp2, &mut pairs2, cell)
                });
                self.edge_pairs(0..half, &grid, &boxes, &mut stamp, &mut pairs, cell);
                helper.join().expect("the broad phase's thread");
            });
            pairs.append(&mut pairs2);
        } else {
            self.edge_pairs(0..count, &grid, &boxes, &mut stamp, &mut pairs, cell);
        }
        self.pairs = pairs;
        self.bins = bins;
        self.boxes = boxes;
        self.grid = grid;
        self.stamp = stamp;
        self.stamp2 = stamp2;
        self.pairs2 = pairs2;
    }

    /// Appends to `out` the vertex–triangle candidates of vertices `range`, the triangles binned
    /// in `grid` with their `boxes`; `stamp` is scratch.
    #[allow(clippy::too_many_arguments)]
    fn vertex_pairs(
        &self,
        range: std::ops::Range<u32>,
        grid: &HashGrid,
        boxes: &[Aabb],
        stamp: &mut Vec<u32>,
        out: &mut Vec<Pair>,
        grow: f64,
        cell: f64,
    ) {
        stamp.clear();
        stamp.resize(self.triangles.len(), 0);
        let mut now = 0u32;
        for v in range {
            let vb = Aabb::of(&[self.ends[v as usize]], grow);
            now += 1;
            for k in cells(&vb, cell) {
                for &t in grid.bucket(k) {
                    if stamp[t as usize] == now {
                        continue;
                    }
                    stamp[t as usize] = now;
                    let tri = self.triangles[t as usize];
                    if tri.contains(&v) || !boxes[t as usize].overlaps(&vb) {
                        continue;
                    }
                    // Pinned to pinned pairs never move: nothing to keep apart.
                    if self.slot[v as usize] == PINNED
                        && tri.iter().all(|&u| self.slot[u as usize] == PINNED)
                    {
                        continue;
                    }
                    out.push(self.pair(false, v, t, [v, tri[0], tri[1], tri[2]]));
                }
            }
        }
    }

    /// Appends to `out` the edge–edge candidates of edges `range` (each against the edges after
    /// it), the edges binned in `grid` with their `boxes`; `stamp` is scratch.
    fn edge_pairs(
        &self,
        range: std::ops::Range<u32>,
        grid: &HashGrid,
        boxes: &[Aabb],
        stamp: &mut Vec<u32>,
        out: &mut Vec<Pair>,
        cell: f64,
    ) {
        stamp.clear();
        stamp.resize(self.edges.len(), 0);
        let mut now = 0u32;
        for e in range {
            let (e, edge) = (e as usize, self.edges[e as usize]);
            let eb = boxes[e];
            now += 1;
            for k in cells(&eb, cell) {
                for &f in grid.bucket(k) {
                    if f as usize <= e || stamp[f as usize] == now {
                        continue;
                    }
                    stamp[f as usize] = now;
                    let other = self.edges[f as usize];
                    if other.contains(&edge[0])
                        || other.contains(&edge[1])
                        || !boxes[f as usize].overlaps(&eb)
                    {
                        continue;
                    }
                    let v = [edge[0], edge[1], other[0], other[1]];
                    if v.iter().all(|&u| self.slot[u as usize] == PINNED) {
                        continue;
                    }
                    out.push(self.pair(true, e as u32, f, v));
                }
            }
        }
    }
}
