//! Placeholder until the mesh collider branch lands (replaced on merge).
use std::path::Path;

use glam::DVec3;

use super::SurfacePoint;
use crate::error::{Error, Result};

/// A static triangle mesh collider.
#[derive(Debug)]
pub struct MeshCollider {
    triangles: Vec<[u32; 3]>,
}

impl MeshCollider {
    /// Not available yet.
    pub fn from_obj(path: &Path) -> Result<Self> {
        Err(Error::invalid(path, "mesh colliders are not available yet"))
    }
    /// Triangles.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }
    /// Closed?
    pub fn is_closed(&self) -> bool {
        false
    }
    /// Contact.
    pub fn contact(&self, _p: DVec3, _from: DVec3, _reach: f64) -> Option<SurfacePoint> {
        None
    }
}
