//! The body to simulate: particles, surface triangles, optional tetrahedra, and the render surface
//! (UVs, seams) that the exporter writes.
//!
//! Units and frames are those of the input file, untouched: no recentring or rescaling. glTF is
//! +Y up and right-handed; an OBJ authored Z-up stays Z-up (choose `--gravity` to match).

use std::collections::BTreeMap;

use glam::DVec3;

/// One corner of the render surface: the particle it follows and its texture coordinate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderVertex {
    /// Index of the particle whose position this vertex takes.
    pub particle: u32,
    /// Texture coordinate (u, v) with v pointing up (OBJ's convention; the glTF writer flips it),
    /// or `None` when the file has none.
    pub uv: Option<[f32; 2]>,
}

/// A simulation body.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Where the body came from (file path or preset name), for messages.
    pub name: String,
    /// Particle positions in the file's units and frame (metres by convention).
    pub positions: Vec<DVec3>,
    /// Surface triangles as particle indices, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Tetrahedra as particle indices (volumetric bodies only).
    pub tets: Vec<[u32; 4]>,
    /// Render vertices: several may share one particle (UV seams).
    pub render_vertices: Vec<RenderVertex>,
    /// Render triangles as render-vertex indices, parallel to [`Mesh::triangles`].
    pub render_triangles: Vec<[u32; 3]>,
    /// Named particle sets (OBJ groups and objects), for `--pin group:NAME`.
    pub groups: BTreeMap<String, Vec<u32>>,
    /// For each particle, its index among the file's positions (pins by `index:` use file order).
    pub file_index: Vec<u32>,
    /// The named objects (OBJ `o` statements) whose faces the body holds, in file order; empty
    /// for other formats.
    pub objects: Vec<String>,
    /// Non-fatal quirks found while loading (skipped degenerate faces, unused positions...).
    pub warnings: Vec<String>,
}

impl Mesh {
    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.positions.len()
    }

    /// True when every render vertex has a texture coordinate.
    pub fn has_uvs(&self) -> bool {
        !self.render_vertices.is_empty() && self.render_vertices.iter().all(|v| v.uv.is_some())
    }

    /// Axis-aligned bounds (min, max) of the particles; zeros for an empty mesh.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        bounds(&self.positions)
    }

    /// Builds a mesh whose render surface is its simulation surface (one render vertex per
    /// particle, no UVs), as for `.tet` volumes and generated grids.
    pub fn from_triangles(name: String, positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        let n = positions.len() as u32;
        Mesh {
            name,
            render_vertices: (0..n)
                .map(|particle| RenderVertex { particle, uv: None })
                .collect(),
            render_triangles: triangles.clone(),
            file_index: (0..n).collect(),
            positions,
            triangles,
            ..Default::default()
        }
    }
}

/// Every distinct edge of `triangles`, its lower index first, sorted.
pub fn edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> = triangles
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// Axis-aligned bounds (min, max) of a point set; zeros when empty.
pub fn bounds(points: &[DVec3]) -> (DVec3, DVec3) {
    if points.is_empty() {
        return (DVec3::ZERO, DVec3::ZERO);
    }
    points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

/// Area-weighted vertex normals of a triangle soup over `positions` (unit length; +Y where a
/// vertex touches no triangle of non-zero area).
pub fn vertex_normals(positions: &[DVec3], triangles: &[[u32; 3]], out: &mut Vec<DVec3>) {
    out.clear();
    out.resize(positions.len(), DVec3::ZERO);
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        // The cross product's length is twice the area: area weighting for free.
        let n = (b - a).cross(c - a);
        for &i in t {
            out[i as usize] += n;
        }
    }
    for n in out.iter_mut() {
        *n = n.try_normalize().unwrap_or(DVec3::Y);
    }
}

/// Removes degenerate triangles (repeated index or zero area), returning how many were dropped.
/// `render` is filtered in step with `triangles` when given.
pub(crate) fn drop_degenerate(
    positions: &[DVec3],
    triangles: &mut Vec<[u32; 3]>,
    render: Option<&mut Vec<[u32; 3]>>,
) -> usize {
    let keep: Vec<bool> = triangles
        .iter()
        .map(|&[a, b, c]| {
            let [pa, pb, pc] = [a, b, c].map(|i| positions[i as usize]);
            a != b && b != c && a != c && (pb - pa).cross(pc - pa).length_squared() > 0.0
        })
        .collect();
    let mut it = keep.iter();
    triangles.retain(|_| *it.next().unwrap_or(&true));
    if let Some(render) = render {
        let mut it = keep.iter();
        render.retain(|_| *it.next().unwrap_or(&true));
    }
    keep.iter().filter(|k| !**k).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_a_ccw_triangle_point_up() {
        let p = [DVec3::ZERO, DVec3::X, DVec3::NEG_Z];
        let mut n = Vec::new();
        vertex_normals(&p, &[[0, 1, 2]], &mut n);
        for v in n {
            assert!((v - DVec3::Y).length() < 1e-12);
        }
    }

    #[test]
    fn degenerate_triangles_are_dropped_in_step() {
        let p = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::X * 2.0];
        let mut t = vec![[0, 1, 2], [0, 0, 1], [0, 1, 3]];
        let mut r = vec![[10, 11, 12], [13, 14, 15], [16, 17, 18]];
        assert_eq!(drop_degenerate(&p, &mut t, Some(&mut r)), 2);
        assert_eq!(t, vec![[0, 1, 2]]);
        assert_eq!(r, vec![[10, 11, 12]]);
    }
}
