//! Render-vertex frames: the particle cache mapped onto the render surface once, shared by every
//! writer that needs it (morph targets, vertex-animation textures, keyframe selection).

use glam::{DVec3, Vec3};

use super::shading::angle_weighted_normals;
use crate::data::FrameCache;
use crate::mesh::Mesh;

/// Positions and normals of every render vertex at every frame 0..=N.
///
/// Layout: frame-major, `positions[frame * vertices + vertex]` (metres) and the same for unit
/// normals; vertices in the order of [`Mesh::render_vertices`], which is the exported glTF's
/// vertex order.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderFrames {
    vertices: usize,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
}

impl RenderFrames {
    /// Maps every frame of `cache` onto `mesh`'s render vertices, with smooth (corner-angle
    /// weighted) normals.
    ///
    /// # Panics
    /// When the cache's particle count differs from the mesh's (callers check first).
    pub fn new(mesh: &Mesh, cache: &FrameCache) -> Self {
        assert_eq!(
            cache.particle_count(),
            mesh.particle_count(),
            "cache and mesh particle counts"
        );
        let vertices = mesh.render_vertices.len();
        let frames = cache.frame_count();
        let mut positions = Vec::with_capacity(frames * vertices);
        let mut normals = Vec::with_capacity(frames * vertices);
        let mut scratch = Vec::new();
        for k in 0..frames {
            let f = render_frame(mesh, cache.frame(k), &mut scratch);
            positions.extend(f.positions);
            normals.extend(f.normals);
        }
        RenderFrames {
            vertices,
            positions,
            normals,
        }
    }

    /// Number of frames (the initial state included).
    pub fn frame_count(&self) -> usize {
        self.positions.len().checked_div(self.vertices).unwrap_or(0)
    }

    /// Number of render vertices per frame.
    pub fn vertex_count(&self) -> usize {
        self.vertices
    }

    /// Render-vertex positions of frame `k`, m.
    ///
    /// # Panics
    /// When `k >= frame_count()`.
    pub fn positions(&self, k: usize) -> &[Vec3] {
        &self.positions[k * self.vertices..(k + 1) * self.vertices]
    }

    /// Render-vertex unit normals of frame `k`.
    ///
    /// # Panics
    /// When `k >= frame_count()`.
    pub fn normals(&self, k: usize) -> &[Vec3] {
        &self.normals[k * self.vertices..(k + 1) * self.vertices]
    }
}

/// Render-vertex positions and normals of one frame.
pub struct RenderFrame {
    /// Position per render vertex, m.
    pub positions: Vec<Vec3>,
    /// Unit normal per render vertex.
    pub normals: Vec<Vec3>,
}

/// Maps particle positions to render vertices, with smooth normals from the surface triangles
/// (corner-angle weighted, as Blender computes them: see [`angle_weighted_normals`]).
pub fn render_frame(mesh: &Mesh, particles: &[Vec3], scratch: &mut Vec<DVec3>) -> RenderFrame {
    let p64: Vec<DVec3> = particles.iter().map(|p| p.as_dvec3()).collect();
    angle_weighted_normals(&p64, &mesh.triangles, scratch);
    RenderFrame {
        positions: mesh
            .render_vertices
            .iter()
            .map(|v| particles[v.particle as usize])
            .collect(),
        normals: mesh
            .render_vertices
            .iter()
            .map(|v| scratch[v.particle as usize].as_vec3())
            .collect(),
    }
}
