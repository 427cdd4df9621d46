//! Static, unanimated triangle meshes: the colliders a cloth lies on, as written beside it
//! ([`crate::export::statics`] turns each into a glTF node).
//!
//! Shading: the generated shapes carry their own normals. Planes, cuboids and triangle soups are
//! flat shaded (a vertex per face corner, the face's normal), so box edges and table corners
//! stay sharp; spheres are smooth (the radial direction). Positions are metres in the cloth's
//! frame, stored as `f32` like every exported position.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};

/// Longitude segments of a generated sphere.
const SPHERE_SEGMENTS: u32 = 32;
/// Latitude bands of a generated sphere (pole to pole).
const SPHERE_RINGS: u32 = 16;

/// A static, unanimated triangle mesh written beside the cloth (metres, the cloth's frame).
#[derive(Debug, Clone, PartialEq)]
pub struct StaticMesh {
    /// Name of the glTF node and mesh (Blender names the object after it).
    pub name: String,
    /// Vertex positions, metres.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, parallel to `positions`.
    pub normals: Vec<Vec3>,
    /// Triangle corners as indices into `positions`, counter-clockwise seen from the front
    /// (outside), three per triangle.
    pub indices: Vec<u32>,
}

impl StaticMesh {
    /// A square quad of side `size` (m) on the plane n·x = d (`normal` need not be unit; a zero
    /// or non-finite normal means +Y), centred at the projection of `centre` onto the plane,
    /// front face along n. Flat shaded: 4 vertices, 2 triangles.
    pub fn plane(
        normal: DVec3,
        offset: f64,
        centre: DVec3,
        size: f64,
        name: impl Into<String>,
    ) -> Self {
        let length = normal.length();
        let (n, d) = match normal.try_normalize() {
            Some(n) => (n, offset / length),
            None => (DVec3::Y, offset),
        };
        let origin = centre - n * (n.dot(centre) - d);
        // t1 × t2 = n, so (t1, t2) counter-clockwise winds towards n.
        let t1 = n.any_orthonormal_vector();
        let t2 = n.cross(t1);
        let h = 0.5 * size.abs();
        let corners = [(-h, -h), (h, -h), (h, h), (-h, h)];
        StaticMesh {
            name: name.into(),
            positions: corners
                .iter()
                .map(|&(u, v)| (origin + t1 * u + t2 * v).as_vec3())
                .collect(),
            normals: vec![n.as_vec3(); 4],
            indices: vec![0, 1, 2, 0, 2, 3],
        }
    }

    /// A UV sphere (32 segments × 16 rings: 482 vertices, 960 triangles) of `radius` (m, its
    /// absolute value) around `centre`, every vertex on the sphere, outward winding, smooth
    /// radial normals.
    pub fn sphere(centre: DVec3, radius: f64, name: impl Into<String>) -> Self {
        let r = radius.abs();
        let mut directions = vec![DVec3::Y];
        for ring in 1..SPHERE_RINGS {
            let theta = PI * ring as f64 / SPHERE_RINGS as f64;
            for segment in 0..SPHERE_SEGMENTS {
                let phi = 2.0 * PI * segment as f64 / SPHERE_SEGMENTS as f64;
                directions.push(DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    -theta.sin() * phi.sin(),
                ));
            }
        }
        directions.push(-DVec3::Y);
        let bottom = directions.len() as u32 - 1;
        // Vertex of (ring 1.., segment) in `directions`.
        let at =
            |ring: u32, segment: u32| 1 + (ring - 1) * SPHERE_SEGMENTS + segment % SPHERE_SEGMENTS;
        let mut indices = Vec::new();
        for s in 0..SPHERE_SEGMENTS {
            indices.extend([0, at(1, s), at(1, s + 1)]);
            for ring in 1..SPHERE_RINGS - 1 {
                let (a, b) = (at(ring, s), at(ring, s + 1));
                let (c, d) = (at(ring + 1, s), at(ring + 1, s + 1));
                indices.extend([a, c, d, a, d, b]);
            }
            let last = SPHERE_RINGS - 1;
            indices.extend([bottom, at(last, s + 1), at(last, s)]);
        }
        StaticMesh {
            name: name.into(),
            positions: directions
                .iter()
                .map(|&u| (centre + u * r).as_vec3())
                .collect(),
            normals: directions.iter().map(|u| u.as_vec3()).collect(),
            indices,
        }
    }

    /// An axis-aligned box between `min` and `max` (m; the corners may be given in any order):
    /// 12 outward triangles, flat shaded with 24 vertices (4 per face).
    pub fn cuboid(min: DVec3, max: DVec3, name: impl Into<String>) -> Self {
        let (lo, hi) = (min.min(max), min.max(max));
        let mut mesh = StaticMesh {
            name: name.into(),
            positions: Vec::with_capacity(24),
            normals: Vec::with_capacity(24),
            indices: Vec::with_capacity(36),
        };
        for axis in 0..3 {
            for (side, n) in [(lo, -1.0), (hi, 1.0)] {
                let mut normal = DVec3::ZERO;
                normal[axis] = n;
                // Two tangent axes such that t1 × t2 = normal.
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let (u, v) = if n > 0.0 { (u, v) } else { (v, u) };
                let base = mesh.positions.len() as u32;
                for (cu, cv) in [(false, false), (true, false), (true, true), (false, true)] {
                    let mut p = side;
                    p[u] = if cu { hi[u] } else { lo[u] };
                    p[v] = if cv { hi[v] } else { lo[v] };
                    mesh.positions.push(p.as_vec3());
                    mesh.normals.push(normal.as_vec3());
                }
                mesh.indices
                    .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
            }
        }
        mesh
    }

    /// A triangle mesh (metres; triangles counter-clockwise seen from the front), flat shaded:
    /// three vertices per triangle with its face normal. Triangles with an index out of range
    /// or zero area are skipped.
    pub fn from_triangles(
        positions: &[DVec3],
        triangles: &[[u32; 3]],
        name: impl Into<String>,
    ) -> Self {
        let mut mesh = StaticMesh {
            name: name.into(),
            positions: Vec::with_capacity(3 * triangles.len()),
            normals: Vec::with_capacity(3 * triangles.len()),
            indices: Vec::with_capacity(3 * triangles.len()),
        };
        for t in triangles {
            if t.iter().any(|&i| i as usize >= positions.len()) {
                continue;
            }
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let Some(n) = (b - a).cross(c - a).try_normalize() else {
                continue;
            };
            let base = mesh.positions.len() as u32;
            for p in [a, b, c] {
                mesh.positions.push(p.as_vec3());
                mesh.normals.push(n.as_vec3());
            }
            mesh.indices.extend([base, base + 1, base + 2]);
        }
        mesh
    }

    /// Why this mesh cannot be written, if it cannot.
    pub fn problem(&self) -> Option<String> {
        if self.indices.is_empty() {
            return Some("has no triangle".into());
        }
        if !self.indices.len().is_multiple_of(3) {
            return Some(format!(
                "has {} indices, not a multiple of 3",
                self.indices.len()
            ));
        }
        if self.normals.len() != self.positions.len() {
            return Some(format!(
                "has {} normals for {} positions",
                self.normals.len(),
                self.positions.len()
            ));
        }
        if let Some(i) = self
            .indices
            .iter()
            .find(|&&i| i as usize >= self.positions.len())
        {
            return Some(format!(
                "index {i} is out of range ({} positions)",
                self.positions.len()
            ));
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Some(format!("position {i} is not finite"));
        }
        if let Some(i) = self
            .normals
            .iter()
            .position(|n| !n.is_finite() || (n.length() - 1.0).abs() > 1e-3)
        {
            return Some(format!("normal {i} is not a unit vector"));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle's geometric normal agrees with its vertex normals and has non-zero area.
    #[track_caller]
    fn check_winding(m: &StaticMesh) {
        assert!(m.problem().is_none(), "{:?}", m.problem());
        for t in m.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| m.positions[t[k] as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.length() > 0.0);
            for k in 0..3 {
                assert!(n.dot(m.normals[t[k] as usize]) > 0.0, "triangle {t:?}");
            }
        }
    }

    #[test]
    fn plane_lies_on_the_plane_around_the_projected_centre() {
        let n = DVec3::new(0.0, 2.0, 1.0);
        let m = StaticMesh::plane(n, 1.0, DVec3::new(3.0, 0.0, 0.0), 4.0, "ground");
        check_winding(&m);
        let u = n.normalize().as_vec3();
        let centre: Vec3 = m.positions.iter().copied().sum::<Vec3>() / 4.0;
        for p in &m.positions {
            approx::assert_abs_diff_eq!(u.dot(*p), 1.0 / 5f32.sqrt(), epsilon = 1e-5);
            approx::assert_abs_diff_eq!(p.distance(centre), 2.0 * 2f32.sqrt(), epsilon = 1e-5);
        }
        approx::assert_abs_diff_eq!(centre.x, 3.0, epsilon = 1e-6);
        assert_eq!(m.normals[0], u);
        // A zero normal falls back to the ground plane y = offset.
        let m = StaticMesh::plane(DVec3::ZERO, 0.5, DVec3::ZERO, 1.0, "floor");
        assert!(m.positions.iter().all(|p| p.y == 0.5));
        check_winding(&m);
    }

    #[test]
    fn sphere_vertices_are_on_it_and_wound_outward() {
        let c = DVec3::new(0.2, 1.0, -0.5);
        let m = StaticMesh::sphere(c, 0.3, "ball");
        check_winding(&m);
        assert_eq!(m.positions.len(), 482);
        assert_eq!(m.indices.len(), 3 * 960);
        for p in &m.positions {
            approx::assert_abs_diff_eq!(p.distance(c.as_vec3()), 0.3, epsilon = 1e-6);
        }
    }

    #[test]
    fn cuboid_is_closed_flat_and_outward() {
        let m = StaticMesh::cuboid(
            DVec3::new(1.0, 0.75, 0.4),
            DVec3::new(-1.0, 0.0, -0.4),
            "box",
        );
        check_winding(&m);
        assert_eq!((m.positions.len(), m.indices.len()), (24, 36));
        for (p, n) in m.positions.iter().zip(&m.normals) {
            // On the face its normal names.
            let axis = n.abs().max_position();
            let face = if n[axis] > 0.0 {
                [1.0, 0.75, 0.4][axis]
            } else {
                [-1.0, 0.0, -0.4][axis]
            };
            assert_eq!(p[axis], face);
        }
    }

    #[test]
    fn from_triangles_skips_bad_triangles() {
        let p = [DVec3::ZERO, DVec3::X, DVec3::Z, DVec3::X * 2.0];
        let m = StaticMesh::from_triangles(&p, &[[0, 2, 1], [0, 1, 3], [0, 1, 9]], "t");
        check_winding(&m);
        assert_eq!(m.indices, vec![0, 1, 2]);
        assert_eq!(m.normals[0], Vec3::Y);
        let empty = StaticMesh::from_triangles(&p, &[[0, 1, 3]], "none");
        assert_eq!(empty.problem().as_deref(), Some("has no triangle"));
    }
}
