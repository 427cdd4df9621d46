//! A triangle membrane whose stiffness does not depend on the triangulation
//! (`--membrane triangles`).
//!
//! Edge springs carry the mesh's directions into the material: the same cotton sheet swings
//! 2.1 cm apart as a regular and as a jittered 61×61 grid, where this membrane keeps it within
//! 0.05 mm (`tests/it/cloth_material.rs`). Here every triangle carries three *fibres* of the
//! continuum through it, 60° apart in its own rest plane. A fibre's
//! direction d (a unit vector of the rest plane) is stretched to r = F·d, with F the triangle's
//! deformation gradient: a fixed combination r = Σᵢ wᵢ xᵢ of the corners (Σ wᵢ = 0, |r| = 1 at
//! rest), the first along the fabric's warp ([`warp`]). Each fibre stores the fabric's one-dimensional law of [`spring_response`](super::law::spring_response) in strain
//! units (a toe in tension, a soft compression that jams), scaled by the triangle's area:
//!
//! ```text
//! E_t = A_t · Σ_k ψ(|F d_k|),   ψ(s) = ∫₁ˢ f(σ) dσ with f from spring_response(σ, 1, Y, c·Y, J)
//! ```
//!
//! Three fibres 60° apart make a fourth-order tensor that is isotropic, so in the linear range
//! the energy density is W = ½·Y·Σ_k (d_kᵀ ε d_k)² = (3Y/8)·(ε:ε) + (3Y/16)·(tr ε)²: Lamé
//! constants λ = μ = 3Y/8, a 2-D Young's modulus of exactly Y (a strip pulled along any
//! direction carries Y·ε per unit width, `tests::a_strip_carries_y_times_its_strain`) and a
//! Poisson ratio of 1/3. The energy is a function of F alone, so any triangulation of a
//! uniformly strained sheet stores the same energy. On an equilateral triangle the fibres run
//! along its edges, and the membrane is the edge springs of [`super::material`] scaled by 9/8
//! (those were calibrated for a strip held at its sides, where the stiffness is λ + 2μ).

use glam::{DMat3, DVec2, DVec3};

use super::law::{spring_energy, spring_terms};
use super::material::Material;
use super::system::PINNED;
use super::term::{Local, Term};
use crate::mesh::Mesh;

/// How a fabric resists stretch (`--membrane`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum MembraneModel {
    // (The variants' doc comments are `--help` text.)
    /// A spring on every edge, stiffness scaled by the edge's area share (see the material
    /// model)
    #[default]
    Springs,
    /// Three fibres through every triangle, 60° apart: the same response on any triangulation
    /// (2-D Young's modulus = --stretch, Poisson ratio 1/3)
    Triangles,
}

/// The fibres' directions from a triangle's warp ([`warp`]), radians.
const FIBRE_ANGLES: [f64; 3] = [
    0.0,
    std::f64::consts::FRAC_PI_3,
    2.0 * std::f64::consts::FRAC_PI_3,
];

/// One triangle of the membrane, in the model's particle indices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneTriangle {
    /// The triangle's corners.
    pub corners: [u32; 3],
    /// Per fibre, the weights wᵢ of r = Σ wᵢ x_{corners[i]} (1/m).
    pub fibres: [[f64; 3]; 3],
    /// Y·A: stiffness in tension of each fibre, N·m (its energy is in J for a dimensionless
    /// strain).
    pub stiffness: f64,
    /// The same in compression, N·m.
    pub compression: f64,
}

/// The membrane of `mesh` in `material`, with the number of triangles skipped as degenerate
/// (zero area).
pub fn membrane_triangles(mesh: &Mesh, material: &Material) -> (Vec<MembraneTriangle>, usize) {
    let p = &mesh.positions;
    let mut out = Vec::with_capacity(mesh.triangles.len());
    let mut skipped = 0;
    for (index, &corners) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = corners.map(|i| p[i as usize]);
        let (e1, e2) = (b - a, c - a);
        let normal = e1.cross(e2);
        let area = 0.5 * normal.length();
        let len1 = e1.length();
        // A sliver (area below 1e-12 of its first edge squared) has no plane to measure in.
        if !(area > 1e-12 * len1 * len1 && len1 > 0.0) {
            skipped += 1;
            continue;
        }
        let n = normal.normalize();
        let t = warp(mesh, index, e1, e2, n);
        let s = n.cross(t);
        // The rest edges in the triangle's plane: columns of Dm = [e1 e2].
        let (u1, u2) = (
            DVec2::new(e1.dot(t), e1.dot(s)),
            DVec2::new(e2.dot(t), e2.dot(s)),
        );
        let det = u1.x * u2.y - u2.x * u1.y;
        let fibres = FIBRE_ANGLES.map(|angle| {
            let d = DVec2::new(angle.cos(), angle.sin());
            // (α, β) = Dm⁻¹ d: F d = α (x1 − x0) + β (x2 − x0).
            let alpha = (u2.y * d.x - u2.x * d.y) / det;
            let beta = (u1.x * d.y - u1.y * d.x) / det;
            [-alpha - beta, alpha, beta]
        });
        out.push(MembraneTriangle {
            corners,
            fibres,
            stiffness: material.stretch * area,
            compression: material.stretch * material.compression * area,
        });
    }
    (out, skipped)
}

/// The direction of triangle `index`'s first fibre, a unit vector of its plane (normal `n`,
/// edges `e1`, `e2` from its first corner): the fabric's warp, where u grows along its texture
/// coordinates; else the world's x axis laid into the plane (z where x is nearly normal to it).
/// In the linear range the choice does not matter (the fibres' response is isotropic); past it,
/// one direction for the whole sheet keeps its response the same on every triangulation.
fn warp(mesh: &Mesh, index: usize, e1: DVec3, e2: DVec3, n: DVec3) -> DVec3 {
    let uv = mesh.render_triangles.get(index).and_then(|rt| {
        let uv = rt.map(|r| mesh.render_vertices.get(r as usize).and_then(|v| v.uv));
        Some([uv[0]?, uv[1]?, uv[2]?].map(|[u, v]| DVec2::new(f64::from(u), f64::from(v))))
    });
    if let Some([t0, t1, t2]) = uv {
        let (d1, d2) = (t1 - t0, t2 - t0);
        let det = d1.x * d2.y - d2.x * d1.y;
        if det.abs() > 1e-12 * d1.length_squared().max(d2.length_squared()) {
            // ∂x/∂u with v held: (d2.v·e1 − d1.v·e2) / det.
            let along = ((e1 * d2.y - e2 * d1.y) / det).reject_from_normalized(n);
            if along.length_squared() > 0.0 {
                return along.normalize();
            }
        }
    }
    let x = DVec3::X.reject_from_normalized(n);
    if x.length_squared() > 0.25 {
        x.normalize()
    } else {
        DVec3::Z.reject_from_normalized(n).normalize()
    }
}

/// The membrane over the solver's unknowns: a [`Term`] whose elements are triangles.
#[derive(Debug, Clone, Default)]
pub struct Membrane {
    /// Corners in solver indices, [`PINNED`] where pinned.
    v: Vec<[u32; 3]>,
    /// Corners in model indices (to move the pins).
    corners: Vec<[u32; 3]>,
    /// Per triangle and fibre, the corner weights.
    w: Vec<[[f64; 3]; 3]>,
    /// Per triangle and fibre, the pinned corners' part Σ wᵢ pᵢ of r, m / m.
    fixed: Vec<[DVec3; 3]>,
    k: Vec<f64>,
    kc: Vec<f64>,
    /// Jamming strain of the fabric's law.
    jam: f64,
}

impl Membrane {
    /// The triangles with a free corner, renumbered by `solver_of` (model index → solver
    /// index, [`PINNED`] for a pinned particle), their pinned corners at `positions`.
    pub fn new(
        triangles: &[MembraneTriangle],
        solver_of: &[u32],
        positions: &[DVec3],
        jam: f64,
    ) -> Self {
        let mut m = Membrane {
            jam,
            ..Membrane::default()
        };
        for t in triangles {
            let v = t.corners.map(|c| solver_of[c as usize]);
            if v.iter().all(|&i| i == PINNED) {
                continue;
            }
            m.v.push(v);
            m.corners.push(t.corners);
            m.w.push(t.fibres);
            m.fixed.push([DVec3::ZERO; 3]);
            m.k.push(t.stiffness);
            m.kc.push(t.compression);
        }
        m.move_pins(positions);
        m
    }

    /// Moves the pinned corners to their positions in `all` (model order).
    pub fn move_pins(&mut self, all: &[DVec3]) {
        for ((fixed, v), (corners, w)) in self
            .fixed
            .iter_mut()
            .zip(&self.v)
            .zip(self.corners.iter().zip(&self.w))
        {
            for (f, wk) in fixed.iter_mut().zip(w) {
                *f = (0..3)
                    .filter(|&i| v[i] == PINNED)
                    .map(|i| all[corners[i] as usize] * wk[i])
                    .sum();
            }
        }
    }

    /// Fibre `k` of triangle `e` at `x`: F·d_k.
    #[inline(always)]
    fn fibre(&self, e: usize, k: usize, x: &[DVec3]) -> DVec3 {
        let (v, w) = (&self.v[e], &self.w[e][k]);
        let mut r = self.fixed[e][k];
        for i in 0..3 {
            if v[i] != PINNED {
                r += x[v[i] as usize] * w[i];
            }
        }
        r
    }
}

impl Membrane {
    /// Adds triangle `e`'s part of the gradient at its corner `a` to `g` and its diagonal block
    /// there to `h` (the sweeps' local step), reading the free corners' positions from
    /// `corner` (called with a corner's index 0..3).
    #[inline(always)]
    pub(crate) fn add_local_with(
        &self,
        e: usize,
        a: usize,
        corner: impl Fn(usize) -> DVec3,
        g: &mut DVec3,
        h: &mut DMat3,
    ) {
        let v = &self.v[e];
        for k in 0..3 {
            let w = &self.w[e][k];
            let mut r = self.fixed[e][k];
            for (b, &wb) in w.iter().enumerate() {
                if v[b] != PINNED {
                    r += corner(b) * wb;
                }
            }
            let (f, he) = spring_terms(r, 1.0, self.k[e], self.kc[e], self.jam);
            *g += f * w[a];
            *h += DMat3::from_cols_array_2d(&he) * (w[a] * w[a]);
        }
    }
}

impl Term<3> for Membrane {
    #[inline(always)]
    fn add_local(&self, e: usize, a: usize, x: &[DVec3], g: &mut DVec3, h: &mut DMat3) {
        let v = &self.v[e];
        self.add_local_with(e, a, |b| x[v[b] as usize], g, h);
    }

    fn len(&self) -> usize {
        self.v.len()
    }

    fn vertices(&self, e: usize) -> [u32; 3] {
        self.v[e]
    }

    fn energy(&self, e: usize, x: &[DVec3]) -> f64 {
        (0..3)
            .map(|k| {
                let len = self.fibre(e, k, x).length();
                spring_energy(len, 1.0, self.k[e], self.kc[e], self.jam)
            })
            .sum()
    }

    fn derivatives(&self, e: usize, x: &[DVec3], local: &mut Local<3>) {
        *local = Local::default();
        for k in 0..3 {
            let r = self.fibre(e, k, x);
            let (f, he) = spring_terms(r, 1.0, self.k[e], self.kc[e], self.jam);
            let w = &self.w[e][k];
            for a in 0..3 {
                local.gradient[a] += f * w[a];
                // The blocks wₐ·w_b·He are symmetric, and (b, a) is (a, b): the upper ones here.
                for b in a..3 {
                    let ww = w[a] * w[b];
                    for (row, he_row) in local.hessian[a][b].iter_mut().zip(&he) {
                        for (h, he) in row.iter_mut().zip(he_row) {
                            *h += ww * he;
                        }
                    }
                }
            }
        }
        for a in 0..3 {
            for b in a + 1..3 {
                local.hessian[b][a] = local.hessian[a][b];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth::law::spring_gradient;
    use crate::cloth::material::{fabric_model_terms, MaterialPreset};
    use crate::cloth::term::tests::check_against_finite_differences;

    /// A w × h grid of unit size in the xy plane, its interior vertices moved by up to
    /// `jitter` of the spacing (a fixed pseudo-random sequence).
    fn sheet(n: usize, jitter: f64) -> Mesh {
        let mut positions = Vec::new();
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let h = 1.0 / (n - 1) as f64;
        for j in 0..n {
            for i in 0..n {
                let mut p = DVec3::new(i as f64 * h, j as f64 * h, 0.0);
                if i > 0 && j > 0 && i + 1 < n && j + 1 < n {
                    p.x += jitter * h * random();
                    p.y += jitter * h * random();
                }
                positions.push(p);
            }
        }
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
                // Alternate the diagonal, so no direction is preferred.
                if (i + j) % 2 == 0 {
                    triangles.extend([[a, b, d], [a, d, c]]);
                } else {
                    triangles.extend([[a, b, c], [b, d, c]]);
                }
            }
        }
        Mesh::from_triangles("sheet".into(), positions, triangles)
    }

    fn every_free(n: usize) -> Vec<u32> {
        (0..n as u32).collect()
    }

    #[test]
    fn the_membrane_matches_finite_differences_of_itself() {
        let mesh = sheet(6, 0.3);
        let (tris, skipped) = membrane_triangles(&mesh, &MaterialPreset::Cotton.material());
        assert_eq!((tris.len(), skipped), (50, 0));
        let n = mesh.positions.len();
        // Stretched 10 % one way and 4 % the other, sheared and lifted out of plane: every fibre
        // past the toe, so the projection of compressed fibres is not in play.
        let x: Vec<DVec3> = mesh
            .positions
            .iter()
            .map(|p| DVec3::new(1.1 * p.x + 0.02 * p.y, 1.04 * p.y, 0.05 * p.x * p.y))
            .collect();
        let m = Membrane::new(&tris, &every_free(n), &mesh.positions, 0.08);
        check_against_finite_differences(&m, &x, 1e-5);
        // With pinned corners (the first row): the fixed part moves with the pins.
        let mut solver_of = every_free(n);
        for s in solver_of.iter_mut().take(6) {
            *s = PINNED;
        }
        let mut pinned = Membrane::new(&tris, &solver_of, &mesh.positions, 0.08);
        pinned.move_pins(&x);
        assert_eq!(pinned.total_energy(&x), m.total_energy(&x));
        check_against_finite_differences(&pinned, &x, 1e-5);
    }

    /// The sweeps' local step sees the same gradient as the whole term, and the diagonal
    /// block of its Hessian.
    #[test]
    fn the_local_terms_are_the_terms_rows() {
        let mesh = sheet(5, 0.3);
        let (tris, _) = membrane_triangles(&mesh, &MaterialPreset::Cotton.material());
        let mut solver_of = every_free(25);
        solver_of[0] = PINNED;
        let m = Membrane::new(&tris, &solver_of, &mesh.positions, 0.08);
        let x: Vec<DVec3> = mesh
            .positions
            .iter()
            .map(|p| DVec3::new(1.05 * p.x, 0.97 * p.y, 0.1 * p.x * p.x))
            .collect();
        let mut grad = vec![DVec3::ZERO; 25];
        m.add_gradient(&x, &mut grad);
        let mut diag = vec![DMat3::ZERO; 25];
        let mut local = Local::default();
        for e in 0..m.len() {
            m.derivatives(e, &x, &mut local);
            for (a, &v) in m.vertices(e).iter().enumerate() {
                if v != PINNED {
                    diag[v as usize] += DMat3::from_cols_array_2d(&local.hessian[a][a]);
                }
            }
        }
        for i in 1..25u32 {
            let (mut g, mut h) = (DVec3::ZERO, DMat3::ZERO);
            for e in 0..m.len() {
                let v = m.vertices(e);
                if let Some(a) = v.iter().position(|&c| c == i) {
                    m.add_local_with(e, a, |c| x[v[c] as usize], &mut g, &mut h);
                }
            }
            let gi = grad[i as usize];
            assert!(
                (g - gi).length() <= 1e-12 * gi.length().max(1.0),
                "{i}: {g} against {gi}"
            );
            assert!(
                h.abs_diff_eq(diag[i as usize], 1e-9 * h.x_axis.x.abs()),
                "{i}"
            );
        }
    }

    /// A uniformly strained sheet: the strip test of fabric. Stretched by ε along x and left to
    /// contract across (by the Poisson ratio 1/3, to first order; exactly so that the 60° and
    /// 120° fibres keep their length), the membrane pulls every interior vertex equally both
    /// ways and the edge x = 1 with Y·ε per unit width, on any triangulation.
    #[test]
    fn a_strip_carries_y_times_its_strain() {
        let material = crate::cloth::material::Material {
            compression: 1.0, // the symmetric law: no toe, so the closed form is exact
            ..MaterialPreset::Cotton.material()
        };
        let y_modulus = material.stretch;
        for (n, jitter) in [(7, 0.0), (11, 0.3), (21, 0.25)] {
            let mesh = sheet(n, jitter);
            // (A jitter that folded a triangle over would count its area twice.)
            for t in &mesh.triangles {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                assert!((b - a).cross(c - a).z > 0.0, "{t:?} folded");
            }
            let (tris, _) = membrane_triangles(&mesh, &material);
            let m = Membrane::new(&tris, &every_free(n * n), &mesh.positions, 0.08);
            for strain in [0.01_f64, 0.2] {
                let sx: f64 = 1.0 + strain;
                // |F d| = 1 at 60°: sx²/4 + sy²·3/4 = 1.
                let sy = ((4.0 - sx * sx) / 3.0).sqrt();
                let x: Vec<DVec3> = mesh
                    .positions
                    .iter()
                    .map(|p| DVec3::new(sx * p.x, sy * p.y, 0.0))
                    .collect();
                let mut grad = vec![DVec3::ZERO; n * n];
                m.add_gradient(&x, &mut grad);
                let force = y_modulus * strain;
                let mut pull = 0.0;
                for (i, g) in grad.iter().enumerate() {
                    let (col, row) = (i % n, i / n);
                    if col == n - 1 {
                        pull += g.x;
                    } else if col > 0 {
                        assert!(g.length() < 1e-9 * force, "vertex {i}: {g}");
                    }
                    if col > 0 && col < n - 1 && row > 0 && row < n - 1 {
                        assert!(g.length() < 1e-9 * force);
                    }
                }
                // The unit-wide edge pulls back with Y·ε (the gradient is minus the force).
                assert!(
                    (pull - force).abs() < 1e-9 * force,
                    "{n}×{n}, jitter {jitter}, strain {strain}: {pull} N/m, expected {force}"
                );
                // And the energy is the strip's ½·Y·ε² per unit area, whatever the triangles.
                let energy = m.total_energy(&x);
                let expected = 0.5 * y_modulus * strain * strain;
                assert!(
                    (energy - expected).abs() < 1e-9 * expected,
                    "{energy} J, {expected}"
                );
            }
        }
    }

    /// On an equilateral triangle the fibres are its edges: the membrane's gradient is the
    /// edge springs' (built by the material code) times 9/8.
    #[test]
    fn on_equilateral_triangles_the_membrane_is_the_edge_springs_scaled() {
        let h = 3f64.sqrt() / 2.0;
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, h, 0.0),
            DVec3::new(1.5, h, 0.0),
        ];
        let mesh = Mesh::from_triangles("pair".into(), positions, vec![[0, 1, 2], [1, 3, 2]]);
        let material = MaterialPreset::Cotton.material();
        let (tris, _) = membrane_triangles(&mesh, &material);
        let m = Membrane::new(&tris, &every_free(4), &mesh.positions, material.jam_strain);
        let springs = fabric_model_terms(&mesh, &material).springs;
        let x = [
            DVec3::new(0.0, 0.0, 0.1),
            DVec3::new(1.2, 0.1, 0.0),
            DVec3::new(0.4, 0.9, 0.0),
            DVec3::new(1.5, 0.8, -0.2),
        ];
        let mut grad = vec![DVec3::ZERO; 4];
        m.add_gradient(&x, &mut grad);
        let mut expected = vec![DVec3::ZERO; 4];
        for s in &springs.springs {
            let (a, b) = (s.a as usize, s.b as usize);
            let f = spring_gradient(
                x[a] - x[b],
                s.rest,
                s.stiffness,
                s.compression,
                springs.jam_strain,
            );
            expected[a] += f * 9.0 / 8.0;
            expected[b] -= f * 9.0 / 8.0;
        }
        for (g, e) in grad.iter().zip(&expected) {
            assert!(
                (*g - *e).length() < 1e-9 * e.length().max(1.0),
                "{g} against {e}"
            );
        }
    }
}
