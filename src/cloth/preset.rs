//! The labs' reference cloth, generated.

use glam::DVec3;

use super::springs::{grid_springs, SpringSet};
use crate::mesh::Mesh;

/// The lab cloth's parameters (`../shared/meshes/README.md`), overridable like every preset value.
#[derive(Debug, Clone)]
pub struct LabCloth {
    /// The grid: (n+1)×(n+1) particles at (s·i, 1.5, s·j − 1) with s = 2/n; one render vertex per
    /// particle with UV (j/n, i/n); two triangles per cell.
    pub mesh: Mesh,
    /// Structural, shear and bending springs at the lab stiffness.
    pub springs: SpringSet,
    /// The pinned particles: (0, 0) and (0, n).
    pub pins: Vec<u32>,
}

impl LabCloth {
    /// One flag per particle: true for the lab's two pinned corners.
    pub fn pinned_flags(&self) -> Vec<bool> {
        let mut pinned = vec![false; self.mesh.positions.len()];
        for &p in &self.pins {
            pinned[p as usize] = true;
        }
        pinned
    }
}

#[cfg(test)]
impl LabCloth {
    /// This cloth as a solver's system, every particle `mass` kg, its two corners pinned or not,
    /// stepped with `params`: the system and its free particles' positions (m).
    pub(crate) fn system(
        self,
        mass: f64,
        pins: bool,
        params: super::StepParams,
    ) -> (super::system::ReducedSystem, Vec<DVec3>) {
        let count = self.mesh.positions.len();
        let pinned = if pins {
            self.pinned_flags()
        } else {
            vec![false; count]
        };
        let model = super::ClothModel::new(self.mesh, self.springs, vec![mass; count], pinned)
            .expect("the lab cloth is a valid model");
        let sys = super::system::ReducedSystem::new(&model, params)
            .expect("the lab cloth's system orders and factors");
        let x = sys.gather(model.positions());
        (sys, x)
    }
}

/// Lab values.
pub mod defaults {
    /// Mass per particle, kg.
    pub const MASS: f64 = 1.0;
    /// Spring stiffness, N/m.
    pub const STIFFNESS: f64 = 100.0;
    /// Damping, 1/s.
    pub const DAMPING: f64 = 0.2;
    /// Gravity, m/s².
    pub const GRAVITY: [f64; 3] = [0.0, -0.3, 0.0];
    /// Frames per second (time step 1/60 s).
    pub const FPS: f64 = 60.0;
    /// Grid cells per side.
    pub const RESOLUTION: u32 = 10;
}

/// Builds the lab cloth with `n` cells per side (n = 10 is the lab's 11×11 grid) and spring
/// stiffness `stiffness` (N/m).
pub fn lab_cloth(n: u32, stiffness: f64) -> LabCloth {
    let s = 2.0 / n as f64;
    let side = n + 1;
    let positions: Vec<DVec3> = (0..side)
        .flat_map(|i| (0..side).map(move |j| DVec3::new(s * i as f64, 1.5, s * j as f64 - 1.0)))
        .collect();
    let id = |i: u32, j: u32| i * side + j;
    let mut triangles = Vec::with_capacity((2 * n * n) as usize);
    for i in 0..n {
        for j in 0..n {
            // Counter-clockwise seen from +Y.
            triangles.push([id(i, j), id(i, j + 1), id(i + 1, j)]);
            triangles.push([id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)]);
        }
    }
    let springs = grid_springs(&positions, n, stiffness);
    let mut mesh =
        Mesh::from_triangles(format!("lab-cloth (resolution {n})"), positions, triangles);
    for (k, v) in mesh.render_vertices.iter_mut().enumerate() {
        let (i, j) = (k as u32 / side, k as u32 % side);
        v.uv = Some([j as f32 / n as f32, i as f32 / n as f32]);
    }
    LabCloth {
        mesh,
        springs,
        pins: vec![id(0, 0), id(0, n)],
    }
}
