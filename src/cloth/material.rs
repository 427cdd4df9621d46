//! Physical fabric materials and their mapping to a mesh's springs and bending stencils.
//!
//! A [`Material`] is given in the units fabric is measured in, independent of any mesh:
//! a stretch modulus Y (N/m: force per unit width per unit strain, the membrane's 2-D Young's
//! modulus), a compression fraction, a bending rigidity B (N·m: moment per unit width per unit
//! curvature) and an areal density ρ (kg/m²). [`fabric_model_terms`] turns it into per-spring
//! constants and per-edge bending stencils scaled by the mesh's rest lengths and areas, so that
//! the same material on a coarse, a fine or an irregular mesh of the same sheet stores the same
//! energy for the same deformation:
//!
//! - **Stretch**: a spring on every edge e, k_e = (8/3)·Y·A_e/l_e², with A_e a third of the area
//!   of each triangle on the edge. On a mesh whose edges point every way equally (and exactly on
//!   an equilateral one) a uniform strain ε then stores ½·Y·ε² per unit area.
//! - **Compression**: real fabric buckles rather than shortens, so a compressed spring resists
//!   with only `compression`·k_e (Choi and Ko 2002; Blender's cloth has a separate compression
//!   stiffness too). This is also what makes the implicit step solvable: a spring that resists
//!   compression as hard as tension turns every step into a buckling problem, whose Hessian is
//!   indefinite and on which Newton crawls (`docs/cloth.md`, "Materials").
//! - **Bending**: the quadratic isometric bending energy of Bergou, Wardetzky, Harmon, Zorin and
//!   Grinspun (2006), E = ½·B·Σ_e |Σᵢ Kᵢ xᵢ|²/(A₁+A₂) over interior edges, with Kᵢ the
//!   cotangent weights of the edge's four vertices and A₁, A₂ its triangles' areas. It
//!   approximates ½·B·∫(2H)² dA (a cylinder of radius R stores B/(2R²) per unit area: within 3 %
//!   on a 30×30 grid, 2 % on a jittered 60×60 one), its Hessian is constant, and it is the same
//!   energy on any triangulation of the sheet. Its rest state is flat (garments are cut flat).
//! - **Mass**: each triangle gives a third of ρ·area to each corner.

use std::collections::BTreeMap;

use glam::DVec3;

use super::springs::{Spring, SpringKind, SpringSet};
use crate::mesh::Mesh;

/// A fabric's mechanical properties, independent of the mesh.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Material {
    /// Stretch modulus Y, N/m (2-D Young's modulus of the membrane).
    pub stretch: f64,
    /// Stiffness in compression as a fraction of the stiffness in tension (0..=1).
    pub compression: f64,
    /// Jamming strain J: the compression strain (a fraction of the rest length, 0 < J < 1)
    /// around which an edge that is softer in compression gets its full tension stiffness added
    /// back, along a smoothstep ramp from (1 − [`super::law::JAM_RAMP`])·J to (1 + JAM_RAMP)·J,
    /// as yarns pressed together do. (Such an edge also has a toe in tension,
    /// [`super::law::TOE_STRAIN`].) Default [`DEFAULT_JAM_STRAIN`].
    pub jam_strain: f64,
    /// Bending rigidity B, N·m.
    pub bend: f64,
    /// The shape bending returns to: flat, or the input mesh's own curvature. Default
    /// [`BendRest::Mesh`].
    pub bend_rest: BendRest,
    /// Areal density ρ, kg/m².
    pub density: f64,
}

/// The rest shape of the bending energy (`--bend-rest`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum BendRest {
    // (The variants' doc comments are `--help` text.)
    /// The input mesh's own curvature: a garment modelled draped keeps its folds, as Blender's
    /// cloth keeps its rest angles (each hinge's rest value Σwᵢxᵢ, kept in the hinge's own frame
    /// and turned with it)
    #[default]
    Mesh,
    /// Flat: each hinge's energy ½|Σwᵢxᵢ|² is zero only when it is flat (the quadratic model of
    /// Bergou et al. 2006, the behaviour before this option)
    Flat,
}

/// The named fabrics of `--material`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum MaterialPreset {
    /// A medium-weight woven cotton: the default.
    Cotton,
    /// A light silk (charmeuse).
    Silk,
    /// A heavy denim (11 oz).
    Denim,
    /// A garment leather, about 1 mm thick.
    Leather,
    /// A 1 mm rubber sheet (resists compression as much as tension).
    Rubber,
}

impl MaterialPreset {
    /// Every preset, for listings.
    pub const ALL: [MaterialPreset; 5] = [
        MaterialPreset::Cotton,
        MaterialPreset::Silk,
        MaterialPreset::Denim,
        MaterialPreset::Leather,
        MaterialPreset::Rubber,
    ];

    /// The preset's name as `--material` spells it.
    pub fn name(self) -> &'static str {
        match self {
            MaterialPreset::Cotton => "cotton",
            MaterialPreset::Silk => "silk",
            MaterialPreset::Denim => "denim",
            MaterialPreset::Leather => "leather",
            MaterialPreset::Rubber => "rubber",
        }
    }

    /// Parses a `--material` name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }

    /// The material's figures. Densities are fabric weights (cotton: Penava et al. 2014, 0.150
    /// kg/m²; 11 oz/yd² denim = 0.373 kg/m²; 19 momme silk = 0.081 kg/m²; leather and rubber
    /// from 1 mm at 900 and 1100 kg/m³). Stretch moduli are small-strain values in the ranges
    /// measured by Wang, O'Brien and Ramamoorthi (2011) for woven fabrics (cotton, denim) and
    /// from E·t for the solids (rubber: 2 MPa × 1 mm). Bending rigidities are Kawabata (KES-FB2)
    /// magnitudes: a medium-weight cotton ≈ 0.15 gf·cm²/cm ≈ 1.5e-5 N·m (a light shirting is a
    /// third of that), silk ≈ 1e-6 N·m, denim ≈ 0.5 gf·cm²/cm ≈ 5e-5 N·m; for the solids
    /// E·t³/12. They are representative figures, not a
    /// measurement of one bolt of cloth: give `--stretch`, `--bend`, `--density` for a measured
    /// fabric.
    pub fn material(self) -> Material {
        let (stretch, compression, bend, density) = match self {
            MaterialPreset::Cotton => (1000.0, FABRIC_COMPRESSION, 1.5e-5, 0.15),
            MaterialPreset::Silk => (300.0, FABRIC_COMPRESSION, 1e-6, 0.081),
            MaterialPreset::Denim => (3000.0, FABRIC_COMPRESSION, 5e-5, 0.373),
            MaterialPreset::Leather => (8000.0, 0.3, 5e-4, 0.9),
            MaterialPreset::Rubber => (2000.0, 1.0, 1.7e-4, 1.1),
        };
        Material {
            stretch,
            compression,
            jam_strain: DEFAULT_JAM_STRAIN,
            bend,
            bend_rest: BendRest::default(),
            density,
        }
    }
}

/// Compression stiffness of woven and knitted fabrics as a fraction of their tension stiffness.
pub const FABRIC_COMPRESSION: f64 = 0.001;

/// The default jamming strain of every preset ([`Material::jam_strain`], `--jam-strain`): a
/// fabric edge compressed by about 6 % of its length resists with its tension stiffness, added
/// back along a smoothstep ramp from 3 % to 9 % ([`super::law::JAM_RAMP`]). Chosen by
/// measurement (`docs/performance.md`, "A jamming ramp instead of a step" and "Sweeps on two
/// cores, and a cap of 200"). On the 8k-vertex skirt hanging from its waist over 30 frames, a
/// ramp of ±50 % took the fewest Newton iterations, and 8 % the fewest of 7, 8 and 10 % (466
/// against 493 and 501). With a cap of 200 iterations and the sweeps, 6 % kept every edge of
/// the garments bench within 7.4 % of its rest length, the skirts crushed on the table
/// included, where 8 % let circle_skirt's edges shorten by 8.2 % and 7 % skirt8K's by 8.3 %.
/// Every frame of every case still converged. The hanging skirt's default 120 frames took 306
/// Newton iterations against 315, though its first 30 frames took 175 against 152.
pub const DEFAULT_JAM_STRAIN: f64 = 0.06;

/// The default material (`cotton`).
pub const DEFAULT_MATERIAL: MaterialPreset = MaterialPreset::Cotton;

/// A four-vertex bending stencil: energy ½·|Σᵢ wᵢ xᵢ|² (J), the weights carrying √(B/(A₁+A₂))
/// times the cotangent weights, vertices `[e0, e1, opposite0, opposite1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendStencil {
    /// The shared edge's two vertices, then the two opposite vertices.
    pub vertices: [u32; 4],
    /// Weights, √(N/m) (so that ½|Σ wᵢxᵢ|² is in joules).
    pub weights: [f64; 4],
    /// The rest value Σwᵢxᵢ of the input mesh in the hinge's frame ([`hinge_frame`]: edge,
    /// normal, binormal), √(N/m)·m; zero for a flat rest. The energy is ½|Σwᵢxᵢ − F·rest|² with
    /// F the hinge's frame.
    pub rest: DVec3,
}

impl BendStencil {
    /// The stencil's vertices at `x` (model order), m.
    #[inline]
    pub fn corners(&self, x: &[DVec3]) -> [DVec3; 4] {
        self.vertices.map(|i| x[i as usize])
    }

    /// Σ wᵢpᵢ at corners `p` ([`BendStencil::corners`]), √(N/m)·m.
    #[inline]
    pub fn value(&self, p: [DVec3; 4]) -> DVec3 {
        (0..4).map(|i| p[i] * self.weights[i]).sum()
    }
}

/// The frame of a hinge with edge (p0, p1) and opposite vertices p2, p3: the unit edge
/// t = (p1 − p0)/|p1 − p0|, the normal n = t × (p2 − p3) normalised (the two triangles' mean
/// normal: p2 and p3 lie on either side of the edge), and t × n; `None` when degenerate
/// (a zero-length edge, or a hinge folded shut).
pub fn hinge_frame(p: [DVec3; 4]) -> Option<[DVec3; 3]> {
    let t = (p[1] - p[0]).try_normalize()?;
    let n = t.cross(p[2] - p[3]).try_normalize()?;
    Some([t, n, t.cross(n)])
}

/// The world vector F·c of frame-coordinates `c` (none: zero).
#[inline]
pub fn from_frame(frame: Option<[DVec3; 3]>, c: DVec3) -> DVec3 {
    frame.map_or(DVec3::ZERO, |[t, n, b]| t * c.x + n * c.y + b * c.z)
}

/// The springs and bending stencils of `material` on a triangle mesh.
pub struct FabricTerms {
    /// One stretch spring per edge.
    pub springs: SpringSet,
    /// One bending stencil per interior edge (none when B = 0).
    pub bending: Vec<BendStencil>,
}

/// Maps `material` onto `mesh` (see the module documentation for the formulas).
pub fn fabric_model_terms(mesh: &Mesh, material: &Material) -> FabricTerms {
    let p = &mesh.positions;
    // edge (lo, hi) -> (area share, opposite vertices)
    let mut edges: BTreeMap<(u32, u32), (f64, Vec<u32>)> = BTreeMap::new();
    for &[a, b, c] in &mesh.triangles {
        let area = 0.5
            * (p[b as usize] - p[a as usize])
                .cross(p[c as usize] - p[a as usize])
                .length();
        for (u, v, opposite) in [(a, b, c), (b, c, a), (c, a, b)] {
            let e = edges.entry((u.min(v), u.max(v))).or_default();
            e.0 += area / 3.0;
            e.1.push(opposite);
        }
    }
    let mut springs = SpringSet {
        jam_strain: material.jam_strain,
        ..SpringSet::default()
    };
    let mut bending = Vec::new();
    for (&(a, b), (share, opposite)) in &edges {
        let rest = p[a as usize].distance(p[b as usize]);
        if rest <= 0.0 {
            springs.skipped_zero_length += 1;
            continue;
        }
        let k = (8.0 / 3.0) * material.stretch * share / (rest * rest);
        if k > 0.0 {
            springs.springs.push(Spring {
                a,
                b,
                rest,
                stiffness: k,
                compression: material.compression * k,
                kind: SpringKind::Stretch,
            });
        }
        if material.bend > 0.0 {
            if let [c, d] = opposite[..] {
                if let Some(mut s) = bend_stencil([a, b, c, d], p, material.bend) {
                    if material.bend_rest == BendRest::Mesh {
                        let x = s.corners(p);
                        let value = s.value(x);
                        if let Some([t, n, b]) = hinge_frame(x) {
                            s.rest = DVec3::new(value.dot(t), value.dot(n), value.dot(b));
                        }
                    }
                    bending.push(s);
                }
            }
        }
    }
    FabricTerms { springs, bending }
}

/// The stencil of the hinge with edge (x0, x1) and opposite vertices x2, x3, or `None` for a
/// degenerate hinge (a zero-area triangle).
fn bend_stencil(v: [u32; 4], p: &[DVec3], bend: f64) -> Option<BendStencil> {
    let [x0, x1, x2, x3] = v.map(|i| p[i as usize]);
    let cot = |a: DVec3, b: DVec3| {
        let s = a.cross(b).length();
        (s > 0.0).then(|| a.dot(b) / s)
    };
    let e0 = x1 - x0;
    // Angles at x0 and x1 in each triangle.
    let c01 = cot(e0, x2 - x0)?;
    let c02 = cot(e0, x3 - x0)?;
    let c03 = cot(-e0, x2 - x1)?;
    let c04 = cot(-e0, x3 - x1)?;
    let a1 = 0.5 * e0.cross(x2 - x0).length();
    let a2 = 0.5 * e0.cross(x3 - x0).length();
    let k = [c03 + c04, c01 + c02, -c01 - c03, -c02 - c04];
    let scale = (bend / (a1 + a2)).sqrt();
    Some(BendStencil {
        vertices: v,
        weights: k.map(|w| w * scale),
        rest: DVec3::ZERO,
    })
}

/// The bending energy of `stencils` at positions `x`, joules: ½|Σwᵢxᵢ − F·rest|² per hinge,
/// with F the hinge's frame at `x`.
pub fn bending_energy(stencils: &[BendStencil], x: &[DVec3]) -> f64 {
    stencils
        .iter()
        .map(|s| {
            let p = s.corners(x);
            let v = s.value(p) - from_frame(hinge_frame(p), s.rest);
            0.5 * v.length_squared()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A w×w-cell grid of `size` metres in the xz plane, each cell split on its diagonal,
    /// optionally with every interior vertex jittered in the plane.
    fn grid(cells: u32, size: f64, jitter: f64) -> Mesh {
        let n = cells + 1;
        let h = size / cells as f64;
        let positions = (0..n)
            .flat_map(|i| {
                (0..n).map(move |j| {
                    let interior = i > 0 && j > 0 && i < cells && j < cells;
                    let t = (i * 31 + j * 17) as f64;
                    let (dx, dz) = if interior {
                        (jitter * h * (t * 0.37).sin(), jitter * h * (t * 0.91).cos())
                    } else {
                        (0.0, 0.0)
                    };
                    DVec3::new(i as f64 * h + dx, 0.0, j as f64 * h + dz)
                })
            })
            .collect();
        let mut triangles = Vec::new();
        for i in 0..cells {
            for j in 0..cells {
                let v = |a: u32, b: u32| a * n + b;
                triangles.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
                triangles.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
            }
        }
        Mesh::from_triangles("grid".into(), positions, triangles)
    }

    fn spring_energy(springs: &SpringSet, x: &[DVec3]) -> f64 {
        springs
            .springs
            .iter()
            .map(|s| {
                let len = x[s.a as usize].distance(x[s.b as usize]);
                let k = if len >= s.rest {
                    s.stiffness
                } else {
                    s.compression
                };
                0.5 * k * (len - s.rest).powi(2)
            })
            .sum()
    }

    /// Uniaxial strain ε (no lateral contraction) on a right-triangle grid stores, per unit
    /// area, ½·ε²·(8/3)·Y·(1/3 + 1/12) by the mapping's formula (edges along the strain count
    /// fully, diagonals by cos⁴45°): the same on a coarse, a fine and a jittered grid.
    #[test]
    fn stretch_energy_density_is_resolution_independent() {
        let material = Material {
            stretch: 500.0,
            compression: 1.0,
            jam_strain: DEFAULT_JAM_STRAIN,
            bend: 0.0,
            bend_rest: BendRest::Mesh,
            density: 0.2,
        };
        let eps = 0.01;
        let mut densities = Vec::new();
        for (cells, jitter) in [(10, 0.0), (40, 0.0), (40, 0.25)] {
            let mesh = grid(cells, 1.0, jitter);
            let terms = fabric_model_terms(&mesh, &material);
            let x: Vec<DVec3> = mesh
                .positions
                .iter()
                .map(|p| DVec3::new(p.x * (1.0 + eps), p.y, p.z))
                .collect();
            densities.push(spring_energy(&terms.springs, &x) / 1.0);
        }
        let closed = 0.5 * material.stretch * eps * eps * (8.0 / 3.0) * (5.0 / 12.0);
        for d in &densities[..2] {
            assert!((d / closed - 1.0).abs() < 0.01, "{d} vs {closed}");
        }
        // Jitter turns edges away from the grid's directions: the same stiffness spread over
        // other orientations (the isotropic mapping's constant is 3/8 rather than 5/12).
        assert!(
            (densities[2] / closed - 1.0).abs() < 0.15,
            "jittered {} vs {closed}",
            densities[2]
        );
    }

    /// A flat sheet rolled onto a cylinder of radius R stores B/(2R²) per unit area (interior
    /// hinges only, so the sheet's border loses a strip of half a cell).
    #[test]
    fn bending_energy_of_a_cylinder_matches_the_closed_form() {
        let bend = 2e-5;
        let material = Material {
            stretch: 100.0,
            compression: 1.0,
            jam_strain: DEFAULT_JAM_STRAIN,
            bend,
            bend_rest: BendRest::Mesh,
            density: 0.2,
        };
        for (cells, jitter) in [(30, 0.0), (60, 0.2)] {
            let mesh = grid(cells, 1.0, jitter);
            let terms = fabric_model_terms(&mesh, &material);
            let radius = 0.5;
            // Roll along x: arc length x ↦ angle x/R; the sheet keeps its lengths.
            let x: Vec<DVec3> = mesh
                .positions
                .iter()
                .map(|p| {
                    let t = p.x / radius;
                    DVec3::new(radius * t.sin(), radius * (1.0 - t.cos()), p.z)
                })
                .collect();
            let e = bending_energy(&terms.bending, &x);
            let closed = bend / (2.0 * radius * radius) * 1.0;
            assert!(
                (e / closed - 1.0).abs() < 0.05,
                "{cells} cells: {e} vs {closed}"
            );
            // Flat: no bending energy at all (the weights are a discrete Laplacian).
            assert!(bending_energy(&terms.bending, &mesh.positions) < 1e-12 * closed);
        }
    }

    /// A sheet modelled rolled (radius 0.5 m) keeps its curvature with the mesh rest: no energy
    /// at rest or turned and moved rigidly, and unrolling it flat costs what rolling a flat sheet
    /// costs (the closed form ½·B/R² per unit area); with the flat rest it costs that as it is.
    #[test]
    fn a_curved_rest_is_kept_and_turns_with_the_hinge() {
        let bend = 2e-5;
        let radius = 0.5;
        let closed = bend / (2.0 * radius * radius) * 1.0;
        let flat = grid(40, 1.0, 0.2);
        let mut rolled = flat.clone();
        for p in &mut rolled.positions {
            let t = p.x / radius;
            *p = DVec3::new(radius * t.sin(), radius * (1.0 - t.cos()), p.z);
        }
        let material = |bend_rest| Material {
            stretch: 100.0,
            compression: 1.0,
            jam_strain: DEFAULT_JAM_STRAIN,
            bend,
            bend_rest,
            density: 0.2,
        };
        let kept = fabric_model_terms(&rolled, &material(BendRest::Mesh)).bending;
        assert!(kept.iter().all(|s| s.rest.length() > 0.0));
        assert!(bending_energy(&kept, &rolled.positions) < 1e-12 * closed);
        let q = glam::DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.1);
        let turned: Vec<DVec3> = rolled
            .positions
            .iter()
            .map(|p| q * *p + DVec3::new(0.3, -2.0, 5.0))
            .collect();
        assert!(bending_energy(&kept, &turned) < 1e-12 * closed);
        let e = bending_energy(&kept, &flat.positions);
        assert!((e / closed - 1.0).abs() < 0.05, "unrolled: {e} vs {closed}");
        let flat_rest = fabric_model_terms(&rolled, &material(BendRest::Flat)).bending;
        assert!(flat_rest.iter().all(|s| s.rest == DVec3::ZERO));
        let e = bending_energy(&flat_rest, &rolled.positions);
        assert!(
            (e / closed - 1.0).abs() < 0.05,
            "flat rest: {e} vs {closed}"
        );
    }

    #[test]
    fn presets_round_trip_their_names() {
        for p in MaterialPreset::ALL {
            assert_eq!(MaterialPreset::from_name(p.name()), Some(p));
            let m = p.material();
            assert!(m.stretch > 0.0 && m.density > 0.0 && m.bend > 0.0);
            assert!((0.0..=1.0).contains(&m.compression));
            assert!(m.jam_strain > 0.0 && m.jam_strain < 1.0);
        }
    }
}
