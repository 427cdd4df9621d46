//! Exact counts of crossing triangle pairs: a cloth against itself and against a body.
//!
//! Two triangles *cross* when an edge of one meets the other (touching included). Pairs that
//! share a vertex are adjacent in the mesh and never counted against each other. Every sign is
//! Shewchuk's exact `orient3d` (the `robust` crate), so a count is exact for the coordinates
//! given: call it with the positions as written (the cache's single-precision values, widened)
//! and it states what a reader of the file sees. Coplanar pairs (both ends of every edge in the
//! other's plane) are touching without crossing and are not counted.
//!
//! The broad phase is a uniform grid over the triangles' boxes (cell size about twice the mean
//! box extent); each pair is tested once, in the cell holding the low corner of the overlap of
//! its two boxes. Triangles whose box spans more than [`MAX_CELLS_PER_TRIANGLE`] cells (a
//! ground plane beside a fine cloth) are tested against every other triangle instead.

use glam::DVec3;
use robust::{orient3d, Coord3D};

/// Triangles spanning more grid cells than this are tested against every triangle.
pub const MAX_CELLS_PER_TRIANGLE: usize = 64;

/// A triangle soup: positions and counter-clockwise (or any) index triples.
#[derive(Debug, Clone, Copy)]
pub struct Soup<'a> {
    /// Vertex positions.
    pub positions: &'a [DVec3],
    /// Triangles as indices into `positions`.
    pub triangles: &'a [[u32; 3]],
}

/// Pairs of triangles of `soup` that share no vertex and cross.
pub fn self_crossings(soup: Soup<'_>) -> usize {
    let boxes: Vec<Aabb> = soup.triangles.iter().map(|t| Aabb::of(soup, t)).collect();
    let mut count = 0;
    candidate_pairs(&boxes, None, |i, j| {
        let (s, t) = (soup.triangles[i], soup.triangles[j]);
        if s.iter().any(|v| t.contains(v)) {
            return;
        }
        if triangles_cross(corners(soup, &s), corners(soup, &t)) {
            count += 1;
        }
    });
    count
}

/// Pairs (a triangle of `a`, a triangle of `b`) that cross.
pub fn crossings_between(a: Soup<'_>, b: Soup<'_>) -> usize {
    let mut boxes: Vec<Aabb> = a.triangles.iter().map(|t| Aabb::of(a, t)).collect();
    boxes.extend(b.triangles.iter().map(|t| Aabb::of(b, t)));
    let n = a.triangles.len();
    let mut count = 0;
    candidate_pairs(&boxes, Some(n), |i, j| {
        let (i, j) = (i.min(j), i.max(j));
        let s = corners(a, &a.triangles[i]);
        let t = corners(b, &b.triangles[j - n]);
        if triangles_cross(s, t) {
            count += 1;
        }
    });
    count
}

/// True when an edge of `s` meets triangle `t` or an edge of `t` meets `s` (exact signs).
pub fn triangles_cross(s: [DVec3; 3], t: [DVec3; 3]) -> bool {
    (0..3).any(|k| segment_meets_triangle(s[k], s[(k + 1) % 3], t))
        || (0..3).any(|k| segment_meets_triangle(t[k], t[(k + 1) % 3], s))
}

/// True when segment pq meets triangle abc in a point (not when it lies in the triangle's plane).
pub fn segment_meets_triangle(p: DVec3, q: DVec3, [a, b, c]: [DVec3; 3]) -> bool {
    let o = |w: DVec3, x: DVec3, y: DVec3, z: DVec3| orient3d(c3(w), c3(x), c3(y), c3(z));
    let dp = o(a, b, c, p);
    let dq = o(a, b, c, q);
    if (dp > 0.0 && dq > 0.0) || (dp < 0.0 && dq < 0.0) || (dp == 0.0 && dq == 0.0) {
        return false;
    }
    // The line pq passes through the triangle when it sees the three edges turn the same way.
    let e = [o(p, q, a, b), o(p, q, b, c), o(p, q, c, a)];
    let nonneg = e.iter().all(|&x| x >= 0.0);
    let nonpos = e.iter().all(|&x| x <= 0.0);
    (nonneg || nonpos) && e.iter().any(|&x| x != 0.0)
}

fn c3(p: DVec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

fn corners(soup: Soup<'_>, t: &[u32; 3]) -> [DVec3; 3] {
    t.map(|i| soup.positions[i as usize])
}

#[derive(Debug, Clone, Copy)]
struct Aabb {
    lo: DVec3,
    hi: DVec3,
}

impl Aabb {
    fn of(soup: Soup<'_>, t: &[u32; 3]) -> Self {
        let [a, b, c] = corners(soup, t);
        Aabb {
            lo: a.min(b).min(c),
            hi: a.max(b).max(c),
        }
    }

    fn overlaps(&self, o: &Aabb) -> bool {
        self.lo.cmple(o.hi).all() && o.lo.cmple(self.hi).all()
    }
}

/// Calls `test(i, j)` once for every pair of boxes that overlap: every pair, or with
/// `split: Some(n)` only pairs of a box below `n` and one at or above it.
fn candidate_pairs(boxes: &[Aabb], split: Option<usize>, mut test: impl FnMut(usize, usize)) {
    let wanted = |i: usize, j: usize| split.is_none_or(|n| (i < n) != (j < n));
    let finite: Vec<usize> = (0..boxes.len())
        .filter(|&i| boxes[i].lo.is_finite() && boxes[i].hi.is_finite())
        .collect();
    if finite.len() < 2 {
        return;
    }
    let mean_extent = finite
        .iter()
        .map(|&i| (boxes[i].hi - boxes[i].lo).max_element())
        .sum::<f64>()
        / finite.len() as f64;
    let lo = finite
        .iter()
        .fold(DVec3::INFINITY, |m, &i| m.min(boxes[i].lo));
    let size = (2.0 * mean_extent).max(1e-9);
    let cell = |p: DVec3| ((p - lo) / size).floor().as_ivec3();

    // (cell key, box) entries of the boxes small enough for the grid; the rest are "large".
    let mut entries: Vec<(glam::IVec3, u32)> = Vec::new();
    let mut large: Vec<usize> = Vec::new();
    for &i in &finite {
        let (c0, c1) = (cell(boxes[i].lo), cell(boxes[i].hi));
        let span = (c1 - c0 + glam::IVec3::ONE).as_i64vec3();
        if span.x * span.y * span.z > MAX_CELLS_PER_TRIANGLE as i64 {
            large.push(i);
            continue;
        }
        for z in c0.z..=c1.z {
            for y in c0.y..=c1.y {
                for x in c0.x..=c1.x {
                    entries.push((glam::IVec3::new(x, y, z), i as u32));
                }
            }
        }
    }
    entries.sort_unstable_by_key(|&(c, i)| (c.x, c.y, c.z, i));
    let mut start = 0;
    while start < entries.len() {
        let key = entries[start].0;
        let end = start + entries[start..].partition_point(|e| e.0 == key);
        let group = &entries[start..end];
        for (k, &(_, i)) in group.iter().enumerate() {
            let bi = &boxes[i as usize];
            for &(_, j) in &group[k + 1..] {
                let bj = &boxes[j as usize];
                let (i, j) = (i as usize, j as usize);
                // Once per pair: in the cell of the overlap's low corner.
                if wanted(i, j) && bi.overlaps(bj) && cell(bi.lo.max(bj.lo)) == key {
                    test(i, j);
                }
            }
        }
        start = end;
    }
    // Large boxes against everything (each large pair once).
    let mut is_large = vec![false; boxes.len()];
    for &i in &large {
        is_large[i] = true;
    }
    for &i in &large {
        for &j in &finite {
            if (is_large[j] && j <= i) || !wanted(i, j) || !boxes[i].overlaps(&boxes[j]) {
                continue;
            }
            test(i, j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_self(soup: Soup<'_>) -> usize {
        let t = soup.triangles;
        let mut n = 0;
        for i in 0..t.len() {
            for j in i + 1..t.len() {
                if t[i].iter().any(|v| t[j].contains(v)) {
                    continue;
                }
                n += usize::from(triangles_cross(corners(soup, &t[i]), corners(soup, &t[j])));
            }
        }
        n
    }

    #[test]
    fn a_segment_through_a_triangle_meets_it_and_one_beside_it_does_not() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let z = DVec3::Z;
        let p = DVec3::new(0.2, 0.2, 0.0);
        assert!(segment_meets_triangle(p - z, p + z, t));
        let q = DVec3::new(0.8, 0.8, 0.0);
        assert!(!segment_meets_triangle(q - z, q + z, t));
        // Ending short of the plane.
        assert!(!segment_meets_triangle(p + z, p + 2.0 * z, t));
        // Lying in the plane: touching, not crossing.
        assert!(!segment_meets_triangle(p, q, t));
    }

    #[test]
    fn the_grid_finds_what_every_pair_finds() {
        // A crumpled strip: a 12 × 3 grid whose rows are folded back and forth through each
        // other, so many non-adjacent pairs cross.
        let (nx, ny) = (12u32, 3u32);
        let mut positions = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let x = f64::from(i) * 0.1;
                let y = f64::from(j) * 0.1;
                let z = (f64::from(i) * 2.3).sin() * 0.12 + (f64::from(j) * 1.7).cos() * 0.05;
                positions.push(DVec3::new(x - 0.35 * (f64::from(i) * 0.9).sin(), y, z));
            }
        }
        let mut triangles = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let v = j * (nx + 1) + i;
                triangles.push([v, v + 1, v + nx + 2]);
                triangles.push([v, v + nx + 2, v + nx + 1]);
            }
        }
        let soup = Soup {
            positions: &positions,
            triangles: &triangles,
        };
        let brute = brute_self(soup);
        assert!(brute > 0, "the fixture must cross itself");
        assert_eq!(self_crossings(soup), brute);

        // The same strip against a copy of itself moved along z: every pair of the two.
        let moved: Vec<DVec3> = positions.iter().map(|p| *p + DVec3::Z * 0.03).collect();
        let other = Soup {
            positions: &moved,
            triangles: &triangles,
        };
        let mut brute = 0;
        for s in &triangles {
            for t in &triangles {
                brute += usize::from(triangles_cross(corners(soup, s), corners(other, t)));
            }
        }
        assert!(brute > 0);
        assert_eq!(crossings_between(soup, other), brute);
    }

    #[test]
    fn a_large_triangle_is_tested_against_every_small_one() {
        // A fine grid of small triangles pierced by one huge triangle.
        let mut positions = vec![
            DVec3::new(-10.0, 0.05, -10.0),
            DVec3::new(10.0, 0.05, -10.0),
            DVec3::new(0.0, 0.05, 10.0),
        ];
        let mut triangles = vec![[0, 1, 2]];
        for k in 0..50u32 {
            let x = f64::from(k) * 0.02;
            let b = positions.len() as u32;
            positions.extend([
                DVec3::new(x, 0.0, 0.0),
                DVec3::new(x + 0.01, 0.0, 0.0),
                DVec3::new(x, 0.1, 0.0),
            ]);
            triangles.push([b, b + 1, b + 2]);
        }
        let soup = Soup {
            positions: &positions,
            triangles: &triangles,
        };
        assert_eq!(self_crossings(soup), 50);
    }
}
