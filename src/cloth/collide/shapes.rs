//! Analytic solid colliders: signed distances and outward normals in closed form.
//!
//! All positions are metres in the cloth's frame. A signed distance is positive outside the solid
//! and negative inside; the normal is the unit direction of steepest increase (outwards).

use glam::DVec3;

use super::SurfacePoint;

/// The half-space n·x ≤ d is solid (for example the ground below y = 0 with n = +y, d = 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace {
    /// Unit outward normal n.
    pub normal: DVec3,
    /// Offset d (m): the boundary plane is n·x = d.
    pub offset: f64,
}

impl HalfSpace {
    /// The half-space below the plane n·x = d; `normal` need not be unit length but must not be
    /// zero (the offset is rescaled with it).
    pub fn new(normal: DVec3, offset: f64) -> Option<Self> {
        let len = normal.length();
        (len > 0.0 && len.is_finite()).then(|| HalfSpace {
            normal: normal / len,
            offset: offset / len,
        })
    }

    /// Signed distance of `p` from the plane, with the plane's normal.
    pub fn surface_point(&self, p: DVec3) -> SurfacePoint {
        SurfacePoint {
            distance: self.normal.dot(p) - self.offset,
            normal: self.normal,
        }
    }
}

/// A solid ball.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ball {
    /// Centre, m.
    pub centre: DVec3,
    /// Radius, m (positive).
    pub radius: f64,
}

impl Ball {
    /// Signed distance of `p` from the sphere and the radial normal (+y at the exact centre).
    pub fn surface_point(&self, p: DVec3) -> SurfacePoint {
        let r = p - self.centre;
        let len = r.length();
        SurfacePoint {
            distance: len - self.radius,
            normal: if len > 0.0 { r / len } else { DVec3::Y },
        }
    }
}

/// A solid axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cuboid {
    /// Minimum corner, m.
    pub min: DVec3,
    /// Maximum corner, m.
    pub max: DVec3,
}

impl Cuboid {
    /// Exact signed distance of `p` from the box surface. Outside, the normal points from the
    /// nearest surface point to `p` (edges and corners round off); inside, it is the normal of
    /// the nearest face.
    pub fn surface_point(&self, p: DVec3) -> SurfacePoint {
        let centre = (self.min + self.max) * 0.5;
        let half = (self.max - self.min) * 0.5;
        let local = p - centre;
        let q = local.abs() - half;
        let outside = q.max(DVec3::ZERO);
        let out_len = outside.length();
        if out_len > 0.0 {
            return SurfacePoint {
                distance: out_len,
                normal: outside * local.signum() / out_len,
            };
        }
        // Inside (or on the surface): the nearest face is the axis with the largest q.
        let axis = if q.x >= q.y && q.x >= q.z {
            0
        } else if q.y >= q.z {
            1
        } else {
            2
        };
        let mut normal = DVec3::ZERO;
        normal[axis] = if local[axis] >= 0.0 { 1.0 } else { -1.0 };
        SurfacePoint {
            distance: q[axis],
            normal,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_space_is_normalised() {
        let h = HalfSpace::new(DVec3::new(0.0, 2.0, 0.0), 1.0).unwrap();
        assert_eq!(h.normal, DVec3::Y);
        assert!((h.surface_point(DVec3::new(3.0, 1.5, -2.0)).distance - 1.0).abs() < 1e-15);
        assert!(HalfSpace::new(DVec3::ZERO, 1.0).is_none());
    }

    #[test]
    fn ball_distance_and_normal() {
        let b = Ball {
            centre: DVec3::new(1.0, 0.0, 0.0),
            radius: 0.5,
        };
        let s = b.surface_point(DVec3::new(1.0, 0.2, 0.0));
        assert!((s.distance + 0.3).abs() < 1e-15);
        assert_eq!(s.normal, DVec3::Y);
    }

    /// The box's signed distance agrees with a brute-force distance to its six face rectangles.
    #[test]
    fn cuboid_distance_matches_brute_force() {
        let c = Cuboid {
            min: DVec3::new(-1.0, 0.0, -0.5),
            max: DVec3::new(1.0, 0.5, 0.5),
        };
        let mut state = 12345u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
        };
        for _ in 0..2000 {
            let p = DVec3::new(rnd(), rnd(), rnd());
            // Nearest point on the surface: clamp to the box, and if inside push to every face.
            let clamped = p.clamp(c.min, c.max);
            let inside = clamped == p;
            let expected = if inside {
                -[
                    p.x - c.min.x,
                    c.max.x - p.x,
                    p.y - c.min.y,
                    c.max.y - p.y,
                    p.z - c.min.z,
                    c.max.z - p.z,
                ]
                .into_iter()
                .fold(f64::INFINITY, f64::min)
            } else {
                p.distance(clamped)
            };
            let s = c.surface_point(p);
            assert!(
                (s.distance - expected).abs() < 1e-12,
                "{p}: {s:?} vs {expected}"
            );
            assert!((s.normal.length() - 1.0).abs() < 1e-12);
            // Moving along the normal by the depth lands on the surface.
            let on = p - s.normal * s.distance;
            assert!(c.surface_point(on).distance.abs() < 1e-12, "{p} -> {on}");
        }
    }
}
