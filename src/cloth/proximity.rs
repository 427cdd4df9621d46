//! Closest points between a point and a triangle and between two segments, as the weights of
//! the four vertices involved: the separation vector is Σₖ wₖ xₖ, so its derivative with respect
//! to vertex k (the closest points held fixed, exact by the envelope theorem where they are
//! unique) is wₖ times the identity.
//!
//! Point–triangle after Ericson, *Real-Time Collision Detection* (2005), §5.1.5 (Voronoi regions
//! of the triangle); segment–segment after §5.1.9 (clamped parameters, parallel segments
//! handled).

use glam::DVec3;

/// The separation of two primitives at their closest points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separation {
    /// Σₖ wₖ xₖ: from the second primitive's closest point to the first's, m.
    pub vector: DVec3,
    /// Per vertex (first primitive's, then the second's): its weight in `vector`.
    pub weights: [f64; 4],
}

impl Separation {
    /// The distance between the primitives, m.
    #[inline]
    pub fn distance(&self) -> f64 {
        self.vector.length()
    }
}

/// The part of a triangle a closest point lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    /// The triangle's inside.
    Face,
    /// Edge i, joining corners i and (i + 1) mod 3.
    Edge(u8),
    /// Corner i.
    Vertex(u8),
}

/// Point `p` against triangle `(a, b, c)`: weights `[1, −u, −v, −w]` with `(u, v, w)` the
/// closest point's barycentric coordinates.
#[inline]
pub fn point_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> Separation {
    point_triangle_feature(p, a, b, c).0
}

/// [`point_triangle`], and the part of the triangle its closest point lies on (a degenerate,
/// zero-area triangle's nearest edge).
pub fn point_triangle_feature(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (Separation, Feature) {
    let done = |u: f64, v: f64, w: f64, feature: Feature| {
        let s = Separation {
            vector: p - (a * u + b * v + c * w),
            weights: [1.0, -u, -v, -w],
        };
        (s, feature)
    };
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return done(1.0, 0.0, 0.0, Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return done(0.0, 1.0, 0.0, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = fraction(d1, d1 - d3);
        return done(1.0 - v, v, 0.0, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return done(0.0, 0.0, 1.0, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = fraction(d2, d2 - d6);
        return done(1.0 - w, 0.0, w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = fraction(d4 - d3, (d4 - d3) + (d5 - d6));
        return done(0.0, 1.0 - w, w, Feature::Edge(1));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // A degenerate (zero-area) triangle: the nearest of its three edges.
        let mut best = (f64::INFINITY, [0.0; 3], 0);
        for (x, y, i, j) in [(a, b, 0, 1), (b, c, 1, 2), (c, a, 2, 0)] {
            let s = segment_segment(p, p, x, y);
            let d = s.vector.length_squared();
            if d < best.0 {
                let mut w = [0.0; 3];
                w[i] = -s.weights[2];
                w[j] = -s.weights[3];
                best = (d, w, i as u8);
            }
        }
        let [u, v, w] = best.1;
        return done(u, v, w, Feature::Edge(best.2));
    }
    let v = vb / denom;
    let w = vc / denom;
    done(1.0 - v - w, v, w, Feature::Face)
}

/// `num / den` in [0, 1], and 0 where both are 0 (an edge of zero length: both its ends are the
/// closest point).
#[inline]
fn fraction(num: f64, den: f64) -> f64 {
    if den > 0.0 {
        (num / den).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Segment `(p1, q1)` against segment `(p2, q2)`: weights `[1 − s, s, −(1 − t), −t]` with `s`
/// and `t` the closest points' parameters along each.
pub fn segment_segment(p1: DVec3, q1: DVec3, p2: DVec3, q2: DVec3) -> Separation {
    const EPS: f64 = 1e-30;
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.length_squared();
    let e = d2.length_squared();
    let f = d2.dot(r);
    let (s, t);
    if a <= EPS && e <= EPS {
        s = 0.0;
        t = 0.0;
    } else if a <= EPS {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= EPS {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            // Parallel segments (denom ≈ 0): any s; 0 is as good as another.
            let s0 = if denom > 1e-14 * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    Separation {
        vector: (p1 + d1 * s) - (p2 + d2 * t),
        weights: [1.0 - s, s, -(1.0 - t), -t],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift), so the tests need no crate.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
        fn vec(&mut self) -> DVec3 {
            DVec3::new(self.next(), self.next(), self.next())
        }
    }

    /// The distance by brute force: the minimum over a fine grid of points on the primitives,
    /// which is never below the exact distance and within the grid's spacing of it.
    fn sampled(points_a: &[DVec3], points_b: &[DVec3]) -> f64 {
        let mut best = f64::INFINITY;
        for a in points_a {
            for b in points_b {
                best = best.min((*a - *b).length());
            }
        }
        best
    }

    fn triangle_samples(a: DVec3, b: DVec3, c: DVec3, n: usize) -> Vec<DVec3> {
        let mut out = Vec::new();
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                out.push(a * (1.0 - u - v) + b * u + c * v);
            }
        }
        out
    }

    fn segment_samples(p: DVec3, q: DVec3, n: usize) -> Vec<DVec3> {
        (0..=n).map(|i| p.lerp(q, i as f64 / n as f64)).collect()
    }

    #[test]
    fn point_triangle_distance_matches_sampling_and_its_weights() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for _ in 0..200 {
            let (p, a, b, c) = (rng.vec() * 2.0, rng.vec(), rng.vec(), rng.vec());
            let s = point_triangle(p, a, b, c);
            let w = s.weights;
            assert!((w[0] + w[1] + w[2] + w[3]).abs() < 1e-12);
            assert!(w[1..].iter().all(|w| *w <= 1e-12 && *w >= -1.0 - 1e-12));
            let rebuilt = p * w[0] + a * w[1] + b * w[2] + c * w[3];
            assert!((rebuilt - s.vector).length() < 1e-12);
            let brute = sampled(&[p], &triangle_samples(a, b, c, 200));
            let d = s.distance();
            // Exact is never above the sampled minimum, and within a grid cell of it.
            assert!(d <= brute + 1e-12, "{d} > {brute}");
            assert!(brute - d < 0.02, "{d} vs {brute}");
        }
    }

    #[test]
    fn segment_distance_matches_sampling_parallel_ones_included() {
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        for k in 0..200 {
            let (p1, q1, p2) = (rng.vec(), rng.vec(), rng.vec());
            // Every fourth pair parallel.
            let q2 = if k % 4 == 0 {
                p2 + (q1 - p1) * 0.7
            } else {
                rng.vec()
            };
            let s = segment_segment(p1, q1, p2, q2);
            let w = s.weights;
            let rebuilt = p1 * w[0] + q1 * w[1] + p2 * w[2] + q2 * w[3];
            assert!((rebuilt - s.vector).length() < 1e-12);
            let brute = sampled(&segment_samples(p1, q1, 400), &segment_samples(p2, q2, 400));
            let d = s.distance();
            assert!(d <= brute + 1e-12, "{d} > {brute}");
            assert!(brute - d < 0.01, "{d} vs {brute}");
        }
    }

    #[test]
    fn degenerate_triangles_give_finite_weights_and_the_nearest_point() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        for k in 0..200 {
            let (p, a, b) = (rng.vec() * 2.0, rng.vec(), rng.vec());
            // Two corners coincide (a zero-length edge), or the three lie on a line.
            let (a, b, c) = match k % 4 {
                0 => (a, a, b),
                1 => (a, b, b),
                2 => (b, a, b),
                _ => (a, b, a.lerp(b, 0.3)),
            };
            let s = point_triangle(p, a, b, c);
            assert!(s.weights.iter().all(|w| w.is_finite()), "{:?}", s.weights);
            let rebuilt = p * s.weights[0] + a * s.weights[1] + b * s.weights[2] + c * s.weights[3];
            assert!((rebuilt - s.vector).length() < 1e-12);
            let brute = sampled(&[p], &segment_samples(a, b, 2000));
            let d = s.distance();
            assert!(d <= brute + 1e-12 && brute - d < 0.01, "{d} vs {brute}");
        }
    }

    #[test]
    fn the_feature_is_where_the_weights_are() {
        let mut rng = Rng(0x0f1e_2d3c_4b5a_6978);
        for _ in 0..500 {
            let (p, a, b, c) = (rng.vec() * 2.0, rng.vec(), rng.vec(), rng.vec());
            let (s, feature) = point_triangle_feature(p, a, b, c);
            let bary = [-s.weights[1], -s.weights[2], -s.weights[3]];
            let on: Vec<usize> = (0..3).filter(|&k| bary[k] > 1e-12).collect();
            match feature {
                Feature::Vertex(i) => assert_eq!(on, vec![i as usize]),
                Feature::Edge(i) => {
                    let (i, j) = (i as usize, (i as usize + 1) % 3);
                    assert!(on.iter().all(|&k| k == i || k == j), "{feature:?} {bary:?}");
                }
                Feature::Face => assert!(bary.iter().all(|&w| w > -1e-12), "{bary:?}"),
            }
        }
    }
}
