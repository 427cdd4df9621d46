//! The physical model of a body: particles with masses, springs, and pins.

use glam::DVec3;

use super::material::BendStencil;
use super::membrane::MembraneTriangle;
use super::springs::{Spring, SpringSet};
use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// A body ready to simulate. Built through [`ClothModel::new`], which checks its invariants
/// (matching lengths, positive finite masses and stiffnesses, indices in range, at least one free
/// particle), so solvers rely on them.
#[derive(Debug, Clone)]
pub struct ClothModel {
    /// The body's geometry and render surface; `mesh.positions` is the initial state.
    pub mesh: Mesh,
    /// The springs.
    pub springs: Vec<Spring>,
    /// Quadratic bending stencils (material models; the labs' models bend with springs).
    pub bending: Vec<BendStencil>,
    /// Triangle membrane (`--membrane triangles`; empty for edge springs).
    pub membrane: Vec<MembraneTriangle>,
    /// Compression strain past which springs softer in compression than in tension jam (a
    /// fraction of the rest length, in (0, 1); [`SpringSet::jam_strain`]).
    pub jam_strain: f64,
    /// Mass of each particle in kg.
    pub mass: Vec<f64>,
    /// Whether each particle is held at its initial position.
    pub pinned: Vec<bool>,
    /// Non-fatal quirks (from loading and from building springs).
    pub warnings: Vec<crate::param::Text>,
}

impl ClothModel {
    /// Assembles and checks a model.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the body when an invariant fails.
    pub fn new(mesh: Mesh, springs: SpringSet, mass: Vec<f64>, pinned: Vec<bool>) -> Result<Self> {
        let n = mesh.positions.len();
        let bad = |m: String| Error::invalid(&mesh.name, m);
        if mass.len() != n || pinned.len() != n {
            return Err(bad(format!(
                "{n} particles but {} masses and {} pin flags",
                mass.len(),
                pinned.len()
            )));
        }
        if let Some(i) = mass.iter().position(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(bad(format!(
                "particle {i} has mass {} (must be positive)",
                mass[i]
            )));
        }
        if let Some(s) = springs.springs.iter().find(|s| {
            s.a as usize >= n
                || s.b as usize >= n
                || s.a == s.b
                || !(s.stiffness.is_finite() && s.stiffness > 0.0)
                || !(s.compression.is_finite() && s.compression >= 0.0)
                || s.rest.is_nan()
                || s.rest <= 0.0
        }) {
            return Err(bad(format!("invalid spring {s:?}")));
        }
        if !(springs.jam_strain > 0.0 && springs.jam_strain < 1.0) {
            return Err(bad(format!(
                "jamming strain {} (must be between 0 and 1, a fraction of the rest length)",
                springs.jam_strain
            )));
        }
        if pinned.iter().all(|&p| p) {
            return Err(bad("every particle is pinned: nothing would move".into()));
        }
        let mut warnings = mesh.warnings.clone();
        if springs.skipped_zero_length > 0 {
            warnings.push(format!(
                "{} zero-length edges (coincident particles) got no spring",
                springs.skipped_zero_length
            ));
        }
        Ok(ClothModel {
            jam_strain: springs.jam_strain,
            springs: springs.springs,
            bending: Vec::new(),
            membrane: Vec::new(),
            mass,
            pinned,
            warnings: warnings.into_iter().map(Into::into).collect(),
            mesh,
        })
    }

    /// Adds quadratic bending stencils (see [`super::material`]).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] when a stencil names a particle out of range or has a non-finite
    /// weight.
    pub fn with_bending(mut self, bending: Vec<BendStencil>) -> Result<Self> {
        let n = self.particle_count();
        if let Some(s) = bending.iter().find(|s| {
            s.vertices.iter().any(|&v| v as usize >= n) || s.weights.iter().any(|w| !w.is_finite())
        }) {
            return Err(Error::invalid(
                &self.mesh.name,
                format!("invalid bending stencil {s:?}"),
            ));
        }
        self.bending = bending;
        Ok(self)
    }

    /// Adds a triangle membrane (see [`super::membrane`]).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] when a triangle names a particle out of range or has a
    /// non-finite weight or stiffness.
    pub fn with_membrane(mut self, membrane: Vec<MembraneTriangle>) -> Result<Self> {
        let n = self.particle_count();
        if let Some(t) = membrane.iter().find(|t| {
            t.corners.iter().any(|&v| v as usize >= n)
                || !t.fibres.iter().flatten().all(|w| w.is_finite())
                || !(t.stiffness.is_finite() && t.compression.is_finite())
        }) {
            return Err(Error::invalid(
                &self.mesh.name,
                format!("invalid membrane triangle {t:?}"),
            ));
        }
        self.membrane = membrane;
        Ok(self)
    }

    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.mass.len()
    }

    /// Number of pinned particles.
    pub fn pinned_count(&self) -> usize {
        self.pinned.iter().filter(|p| **p).count()
    }

    /// Initial positions (metres).
    pub fn positions(&self) -> &[DVec3] {
        &self.mesh.positions
    }
}

/// Masses from an areal density (kg/m²): each triangle gives a third of its mass to each corner.
/// Particles on no triangle get the mean mass.
pub fn masses_from_area(mesh: &Mesh, density: f64) -> Vec<f64> {
    let mut mass = vec![0.0; mesh.positions.len()];
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let share = density * 0.5 * (b - a).cross(c - a).length() / 3.0;
        for &i in t {
            mass[i as usize] += share;
        }
    }
    fill_massless(&mut mass);
    mass
}

/// Masses from a volumetric density (kg/m³): each tetrahedron gives a quarter of its mass to each
/// corner. Particles on no tetrahedron get the mean mass.
pub fn masses_from_volume(mesh: &Mesh, density: f64) -> Vec<f64> {
    let mut mass = vec![0.0; mesh.positions.len()];
    for t in &mesh.tets {
        let [a, b, c, d] = t.map(|i| mesh.positions[i as usize]);
        let share = density * ((b - a).cross(c - a).dot(d - a)).abs() / 6.0 / 4.0;
        for &i in t {
            mass[i as usize] += share;
        }
    }
    fill_massless(&mut mass);
    mass
}

fn fill_massless(mass: &mut [f64]) {
    let positive: Vec<f64> = mass.iter().copied().filter(|m| *m > 0.0).collect();
    let mean = if positive.is_empty() {
        1.0
    } else {
        positive.iter().sum::<f64>() / positive.len() as f64
    };
    for m in mass.iter_mut().filter(|m| **m <= 0.0) {
        *m = mean;
    }
}
