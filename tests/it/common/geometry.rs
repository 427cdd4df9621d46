//! Signed distances computed from first principles, to check contact without the library's
//! `Collider::contact`: positive outside a solid, negative inside, metres.

use std::path::Path;

use glam::DVec3;

/// Signed distance of `p` from the plane n·x = d (the solid is below it); `n` need not be unit.
pub fn plane_distance(normal: DVec3, offset: f64, p: DVec3) -> f64 {
    (normal.dot(p) - offset) / normal.length()
}

/// Signed distance of `p` from the surface of the ball (`centre`, `radius`): |p − c| − r.
pub fn sphere_distance(centre: DVec3, radius: f64, p: DVec3) -> f64 {
    (p - centre).length() - radius
}

/// Signed distance of `p` from the surface of the axis-aligned box `min..max`: the Euclidean
/// distance to the box outside, minus the distance to the nearest face inside.
pub fn box_distance(min: DVec3, max: DVec3, p: DVec3) -> f64 {
    let centre = (min + max) * 0.5;
    let half = (max - min) * 0.5;
    // Per axis: how far p lies beyond the slab (negative inside it).
    let q = (p - centre).abs() - half;
    let outside = q.max(DVec3::ZERO).length();
    let inside = q.max_element().min(0.0);
    outside + inside
}

/// The point of triangle `abc` closest to `p`, by the region tests of Ericson, *Real-Time
/// Collision Detection* §5.1.5 (vertex, edge and face regions in turn).
pub fn closest_point_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

/// Solid angle subtended by triangle `abc` at `p` (signed by the triangle's orientation), by
/// Van Oosterom and Strackee's formula.
fn solid_angle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (a, b, c) = (a - p, b - p, c - p);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let det = a.dot(b.cross(c));
    let div = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * det.atan2(div)
}

/// A triangle soup read with `tobj` (not scenebake's OBJ reader), for brute-force queries.
pub struct Triangles {
    pub triangles: Vec<[DVec3; 3]>,
}

impl Triangles {
    /// Every object of the OBJ file at `path`, triangulated.
    pub fn from_obj(path: &Path) -> Self {
        let (models, _) = tobj::load_obj(
            path,
            &tobj::LoadOptions {
                triangulate: true,
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut triangles = Vec::new();
        for m in &models {
            let v = |i: u32| {
                let i = i as usize * 3;
                let p = &m.mesh.positions;
                DVec3::new(p[i] as f64, p[i + 1] as f64, p[i + 2] as f64)
            };
            for t in m.mesh.indices.chunks(3) {
                triangles.push([v(t[0]), v(t[1]), v(t[2])]);
            }
        }
        Triangles { triangles }
    }

    /// Distance from `p` to the nearest point of any triangle (every triangle tried).
    pub fn distance(&self, p: DVec3) -> f64 {
        self.triangles
            .iter()
            .map(|[a, b, c]| p.distance(closest_point_on_triangle(p, *a, *b, *c)))
            .fold(f64::INFINITY, f64::min)
    }

    /// The generalised winding number of the surface around `p`: the solid angles of all the
    /// triangles over 4π. About ±1 inside a closed surface (the sign is its orientation), 0
    /// outside; it adds up over the closed parts of a mesh.
    pub fn winding_number(&self, p: DVec3) -> f64 {
        self.triangles
            .iter()
            .map(|[a, b, c]| solid_angle(p, *a, *b, *c))
            .sum::<f64>()
            / (4.0 * std::f64::consts::PI)
    }

    /// Signed distance from the surface of the solid the closed mesh bounds: negative where the
    /// winding number says `p` is inside.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        let d = self.distance(p);
        if self.winding_number(p).abs() > 0.5 {
            -d
        } else {
            d
        }
    }
}
