//! What a frame of cloth looks like to an exact reader: its largest edge strain and its count of
//! crossing triangle pairs, with itself and with each body. Independent of the solver: it reads
//! positions and triangles only.

pub mod crossing;
pub mod strain;

use glam::DVec3;

pub use crossing::{crossings_between, self_crossings, Soup};
pub use strain::{EdgeStrain, StrainRange};

/// One frame's figures.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FrameQuality {
    /// Largest edge stretch, l / l₀ − 1 (0 when no edge is longer than at rest).
    pub max_strain: f64,
    /// Largest edge compression, l / l₀ − 1 (≤ 0).
    pub min_strain: f64,
    /// Pairs of the cloth's own triangles, sharing no vertex, that cross.
    pub self_crossings: usize,
    /// Pairs (a cloth triangle, a body triangle) that cross, over every mesh body.
    pub body_crossings: usize,
}

/// Measures frames of one cloth: its triangles and its rest edge lengths.
#[derive(Debug, Clone)]
pub struct FrameMeasure {
    triangles: Vec<[u32; 3]>,
    strain: EdgeStrain,
}

impl FrameMeasure {
    /// The cloth's `triangles` over particles at their `rest` positions.
    pub fn new(rest: &[DVec3], triangles: &[[u32; 3]]) -> Self {
        FrameMeasure {
            triangles: triangles.to_vec(),
            strain: EdgeStrain::new(rest, triangles),
        }
    }

    /// The figures of the cloth at `positions` among `bodies`.
    pub fn frame(&self, positions: &[DVec3], bodies: &[Soup<'_>]) -> FrameQuality {
        let cloth = Soup {
            positions,
            triangles: &self.triangles,
        };
        let range = self.strain.range(positions);
        FrameQuality {
            max_strain: range.max,
            min_strain: range.min,
            self_crossings: self_crossings(cloth),
            body_crossings: bodies.iter().map(|b| crossings_between(cloth, *b)).sum(),
        }
    }
}
