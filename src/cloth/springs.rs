//! Spring networks: which particle pairs are joined, how stiffly, and at what rest length.

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec3;

use crate::mesh::Mesh;

/// What a spring models; only used for reporting and presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SpringKind {
    /// Along a mesh edge (or a grid's structural neighbour).
    Stretch,
    /// Across a grid cell's diagonal.
    Shear,
    /// Across an interior edge (opposite vertices of two triangles) or two cells apart on a grid.
    Bend,
}

/// A spring between two particles with energy ½·k·(|xa − xb| − rest)², where k is `stiffness`
/// when the spring is stretched (|xa − xb| ≥ rest) and `compression` when it is shorter than its
/// rest length. The labs' springs are symmetric (`compression == stiffness`); fabric hardly
/// resists compression (it buckles instead), which the material model expresses with a small
/// `compression` (see [`super::material`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spring {
    /// First particle.
    pub a: u32,
    /// Second particle.
    pub b: u32,
    /// Rest length in metres (positive).
    pub rest: f64,
    /// Stiffness in tension, N/m.
    pub stiffness: f64,
    /// Stiffness in compression, N/m (non-negative).
    pub compression: f64,
    /// What the spring models.
    pub kind: SpringKind,
}

/// Springs built from a mesh, with the edges that had to be skipped.
#[derive(Debug, Clone)]
pub struct SpringSet {
    /// The springs, in a deterministic order.
    pub springs: Vec<Spring>,
    /// Pairs skipped because their rest length is zero (coincident particles).
    pub skipped_zero_length: usize,
    /// Compression strain (a fraction of the rest length, in (0, 1)) past which a spring softer
    /// in compression than in tension jams: the tension stiffness adds back (see
    /// [`super::law::spring_response`]). Symmetric springs never jam. Default
    /// [`super::material::DEFAULT_JAM_STRAIN`]; a fabric's comes from its material.
    pub jam_strain: f64,
}

impl Default for SpringSet {
    fn default() -> Self {
        SpringSet {
            springs: Vec::new(),
            skipped_zero_length: 0,
            jam_strain: super::material::DEFAULT_JAM_STRAIN,
        }
    }
}

impl SpringSet {
    fn push(&mut self, positions: &[DVec3], a: u32, b: u32, stiffness: f64, kind: SpringKind) {
        let rest = positions[a as usize].distance(positions[b as usize]);
        if rest > 0.0 {
            self.springs.push(Spring {
                a,
                b,
                rest,
                stiffness,
                compression: stiffness,
                kind,
            });
        } else {
            self.skipped_zero_length += 1;
        }
    }

    /// Count of springs of each kind, for reports.
    pub fn count(&self, kind: SpringKind) -> usize {
        self.springs.iter().filter(|s| s.kind == kind).count()
    }
}

/// Stretch springs on the unique edges of the surface triangles, and bending springs joining the
/// two opposite vertices across every interior edge (edges shared by exactly two triangles),
/// unless those vertices are already joined by an edge. `bend_stiffness = 0` adds no bending.
pub fn surface_springs(mesh: &Mesh, stiffness: f64, bend_stiffness: f64) -> SpringSet {
    // edge (lo, hi) -> opposite vertices of the triangles that use it
    let mut edges: BTreeMap<(u32, u32), Vec<u32>> = BTreeMap::new();
    for &[a, b, c] in &mesh.triangles {
        for (p, q, opposite) in [(a, b, c), (b, c, a), (c, a, b)] {
            edges
                .entry((p.min(q), p.max(q)))
                .or_default()
                .push(opposite);
        }
    }
    let mut set = SpringSet::default();
    for &(a, b) in edges.keys() {
        set.push(&mesh.positions, a, b, stiffness, SpringKind::Stretch);
    }
    if bend_stiffness > 0.0 {
        let mut bends = BTreeSet::new();
        for opposite in edges.values() {
            if let [c, d] = opposite[..] {
                let key = (c.min(d), c.max(d));
                if c != d && !edges.contains_key(&key) {
                    bends.insert(key);
                }
            }
        }
        for (a, b) in bends {
            set.push(&mesh.positions, a, b, bend_stiffness, SpringKind::Bend);
        }
    }
    set
}

/// Stretch springs on the unique edges of the tetrahedra.
pub fn volume_springs(mesh: &Mesh, stiffness: f64) -> SpringSet {
    let mut pairs = BTreeSet::new();
    for t in &mesh.tets {
        for i in 0..4 {
            for j in i + 1..4 {
                pairs.insert((t[i].min(t[j]), t[i].max(t[j])));
            }
        }
    }
    let mut set = SpringSet::default();
    for (a, b) in pairs {
        set.push(&mesh.positions, a, b, stiffness, SpringKind::Stretch);
    }
    set
}

/// The labs' grid springs on an (n+1)×(n+1) lattice whose particle (i, j) has index
/// `i·(n+1) + j`: structural (i±1, j), (i, j±1); shear (both diagonals of each cell); bending
/// (i±2, j), (i, j±2).
pub fn grid_springs(positions: &[DVec3], n: u32, stiffness: f64) -> SpringSet {
    let id = |i: u32, j: u32| i * (n + 1) + j;
    let mut set = SpringSet::default();
    let mut add = |a, b, kind| set.push(positions, a, b, stiffness, kind);
    for i in 0..=n {
        for j in 0..=n {
            if i < n {
                add(id(i, j), id(i + 1, j), SpringKind::Stretch);
            }
            if j < n {
                add(id(i, j), id(i, j + 1), SpringKind::Stretch);
            }
            if i < n && j < n {
                add(id(i, j), id(i + 1, j + 1), SpringKind::Shear);
                add(id(i + 1, j), id(i, j + 1), SpringKind::Shear);
            }
            if i + 2 <= n {
                add(id(i, j), id(i + 2, j), SpringKind::Bend);
            }
            if j + 2 <= n {
                add(id(i, j), id(i, j + 2), SpringKind::Bend);
            }
        }
    }
    set
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_grid_has_618_springs() {
        let n = 10;
        let p: Vec<DVec3> = (0..=n)
            .flat_map(|i| {
                (0..=n).map(move |j| DVec3::new(0.2 * i as f64, 1.5, 0.2 * j as f64 - 1.0))
            })
            .collect();
        let s = grid_springs(&p, n, 100.0);
        assert_eq!(s.springs.len(), 618);
        assert_eq!(
            (
                s.count(SpringKind::Stretch),
                s.count(SpringKind::Shear),
                s.count(SpringKind::Bend)
            ),
            (220, 200, 198)
        );
    }

    #[test]
    fn a_quad_has_five_edges_and_no_bend_across_its_diagonal() {
        let m = Mesh::from_triangles(
            "q".into(),
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let s = surface_springs(&m, 10.0, 1.0);
        assert_eq!(s.count(SpringKind::Stretch), 5);
        assert_eq!(
            s.count(SpringKind::Bend),
            1,
            "the other diagonal (1,3) bends"
        );
        let bend = s
            .springs
            .iter()
            .find(|s| s.kind == SpringKind::Bend)
            .unwrap();
        assert_eq!((bend.a, bend.b), (1, 3));
    }
}
