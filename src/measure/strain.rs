//! Edge strain of a surface against its rest shape.

use glam::DVec3;

/// The edges of a triangle mesh with their rest lengths.
#[derive(Debug, Clone)]
pub struct EdgeStrain {
    edges: Vec<[u32; 2]>,
    rest: Vec<f64>,
}

/// The extremes of a frame's edge strains (l / l₀ − 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrainRange {
    /// The largest stretch (positive: longer than at rest).
    pub max: f64,
    /// The largest compression (negative: shorter than at rest).
    pub min: f64,
    /// The edge with the largest stretch (its two vertices).
    pub worst_edge: [u32; 2],
}

impl EdgeStrain {
    /// Every distinct edge of `triangles`, its rest length taken from `rest` (edges of zero rest
    /// length are left out).
    pub fn new(rest: &[DVec3], triangles: &[[u32; 3]]) -> Self {
        let mut edges = crate::mesh::edges(triangles);
        edges.retain(|&[a, b]| rest[a as usize].distance(rest[b as usize]) > 0.0);
        let lengths = edges
            .iter()
            .map(|&[a, b]| rest[a as usize].distance(rest[b as usize]))
            .collect();
        EdgeStrain {
            edges,
            rest: lengths,
        }
    }

    /// Number of edges measured.
    pub fn len(&self) -> usize {
        self.edges.len()
    }

    /// True when there is no edge.
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// The strain range of `positions` (zeros for a mesh without edges).
    pub fn range(&self, positions: &[DVec3]) -> StrainRange {
        let mut out = StrainRange {
            max: 0.0,
            min: 0.0,
            worst_edge: [0, 0],
        };
        for (&[a, b], &l0) in self.edges.iter().zip(&self.rest) {
            let s = positions[a as usize].distance(positions[b as usize]) / l0 - 1.0;
            if s > out.max {
                out.max = s;
                out.worst_edge = [a, b];
            }
            out.min = out.min.min(s);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_uniformly_stretched_triangle_has_that_strain_on_every_edge() {
        let rest = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let e = EdgeStrain::new(&rest, &[[0, 1, 2], [2, 1, 0]]);
        assert_eq!(e.len(), 3);
        let stretched: Vec<DVec3> = rest.iter().map(|p| *p * 1.25).collect();
        let r = e.range(&stretched);
        assert!((r.max - 0.25).abs() < 1e-12 && r.min == 0.0);
        let mut squashed = rest.to_vec();
        squashed[1].x = 0.5;
        let r = e.range(&squashed);
        assert!((r.min + 0.5).abs() < 1e-12, "{r:?}");
        // The hypotenuse from (0.5,0) to (0,1) is shorter than √2: no stretch at all.
        assert_eq!(r.max, 0.0);
    }
}
