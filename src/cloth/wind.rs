//! Wind: aerodynamic forces on the cloth's triangles, with optional seeded gusts.
//!
//! Each triangle (area A, unit normal n) moving with its vertices' mean velocity v̄ in air of
//! velocity w(t, x) feels, with the relative air velocity u = w − v̄,
//!
//! ```text
//! F = ½ρ A |u| [ (u·n) (C_d n + C_l (n − (n·û) û)) + f C_d (u − (u·n) n) ]
//! ```
//! a pressure (drag) force along the normal, proportional to the normal component of the relative
//! velocity, a lift force perpendicular to the flow, and a skin-friction drag along the cloth
//! (f = [`SKIN_FRICTION`] of the drag coefficient), which is what streams a flag out from its
//! pole. None depends on which way the triangle is wound. A third of F goes to each vertex.
//!
//! The forces are integrated before each implicit step (operator splitting), semi-implicitly in
//! each particle's own velocity: v ← v + h F / (m + h β), where β = Σ ½ρ A |u| (C_d + C_l) / 3
//! bounds dF/dv, so a light cloth in a strong wind cannot overshoot the wind speed however large
//! the time step. Gusts are a sum of a few travelling waves with seeded random directions,
//! wavelengths and frequencies: deterministic for a given `seed`.
//!
//! Units: metres, seconds, kilograms; positions and velocities in the cloth's frame.

use glam::DVec3;

use crate::cloth::ClothModel;

/// Density of air at sea level and 20 °C, kg/m³.
pub const AIR_DENSITY: f64 = 1.2;

/// Default drag coefficient (`--drag`) when wind is on: a flat plate facing the flow has ≈ 1.2.
pub const DEFAULT_DRAG: f64 = 1.0;

/// Default lift coefficient (`--lift`) when wind is on.
pub const DEFAULT_LIFT: f64 = 0.3;

/// Skin-friction drag along the cloth as a fraction of the drag coefficient.
pub const SKIN_FRICTION: f64 = 0.1;

/// Number of travelling waves summed for gusts.
const GUST_WAVES: usize = 6;

/// The air around the cloth.
#[derive(Debug, Clone, PartialEq)]
pub struct Wind {
    /// Mean wind velocity, m/s (`--wind X,Y,Z`).
    pub velocity: DVec3,
    /// Drag coefficient C_d (dimensionless, ≥ 0).
    pub drag: f64,
    /// Lift coefficient C_l (dimensionless, ≥ 0).
    pub lift: f64,
    /// Gust strength: the RMS gust speed as a fraction of the mean wind speed (0 = steady).
    pub turbulence: f64,
    /// Seed of the gusts' random directions, wavelengths and phases.
    pub seed: u64,
}

/// One travelling wave of the gust field.
#[derive(Debug, Clone, Copy)]
struct GustWave {
    /// Wave vector, rad/m.
    k: DVec3,
    /// Angular frequency, rad/s.
    omega: f64,
    phase: f64,
    /// Unit direction of the velocity it adds.
    direction: DVec3,
}

/// Aerodynamic forces on one cloth model (particles in the model's order).
#[derive(Debug, Clone)]
pub struct Aerodynamics {
    wind: Wind,
    triangles: Vec<[u32; 3]>,
    /// Mass (kg) of each free particle; `None` for pinned ones, which the wind does not move.
    free_mass: Vec<Option<f64>>,
    waves: Vec<GustWave>,
    /// Per-particle force and dF/dv bound, reused between steps.
    force: Vec<DVec3>,
    beta: Vec<f64>,
}

impl Aerodynamics {
    /// Forces on `model`'s surface triangles; gust wavelengths scale with the body's size.
    pub fn new(wind: Wind, model: &ClothModel) -> Self {
        let n = model.particle_count();
        let (lo, hi) = model.mesh.bounds();
        let size = (hi - lo).length().max(0.1);
        let mut rng = SplitMix64(wind.seed);
        let waves = (0..GUST_WAVES)
            .map(|_| {
                let wavelength = size * (0.5 + 1.5 * rng.unit());
                let period = 0.7 + 2.3 * rng.unit();
                GustWave {
                    k: rng.direction() * (std::f64::consts::TAU / wavelength),
                    omega: std::f64::consts::TAU / period,
                    phase: std::f64::consts::TAU * rng.unit(),
                    direction: rng.direction(),
                }
            })
            .collect();
        Aerodynamics {
            triangles: model.mesh.triangles.clone(),
            free_mass: model
                .pinned
                .iter()
                .zip(&model.mass)
                .map(|(&pinned, &m)| (!pinned).then_some(m))
                .collect(),
            waves,
            force: vec![DVec3::ZERO; n],
            beta: vec![0.0; n],
            wind,
        }
    }

    /// The wind settings.
    pub fn wind(&self) -> &Wind {
        &self.wind
    }

    /// Air velocity (m/s) at time `t` (s) and position `at` (m): the mean wind plus gusts.
    pub fn air_velocity(&self, t: f64, at: DVec3) -> DVec3 {
        let w = &self.wind;
        if w.turbulence == 0.0 {
            return w.velocity;
        }
        let amplitude = w.turbulence * w.velocity.length() * (2.0 / GUST_WAVES as f64).sqrt();
        let gust: DVec3 = self
            .waves
            .iter()
            .map(|g| g.direction * (g.k.dot(at) - g.omega * t + g.phase).sin())
            .sum();
        w.velocity + gust * amplitude
    }

    /// Integrates the aerodynamic forces over one step of `h` seconds starting at time `t`:
    /// updates the velocities `v` (m/s) of the free particles at positions `x` (m), both in the
    /// model's order. Pinned particles are left alone.
    pub fn apply(&mut self, t: f64, h: f64, x: &[DVec3], v: &mut [DVec3]) {
        self.force.fill(DVec3::ZERO);
        self.beta.fill(0.0);
        let (cd, cl) = (self.wind.drag, self.wind.lift);
        for &[a, b, c] in &self.triangles {
            let (a, b, c) = (a as usize, b as usize, c as usize);
            let cross = (x[b] - x[a]).cross(x[c] - x[a]);
            let twice_area = cross.length();
            if twice_area.is_nan() || twice_area <= 0.0 {
                continue;
            }
            let n = cross / twice_area;
            let centroid = (x[a] + x[b] + x[c]) / 3.0;
            let u = self.air_velocity(t, centroid) - (v[a] + v[b] + v[c]) / 3.0;
            let speed = u.length();
            if speed == 0.0 {
                continue;
            }
            let u_hat = u / speed;
            // ½ρA|u|, with A = |cross|/2, shared by the three vertices.
            let q = 0.25 * AIR_DENSITY * twice_area * speed / 3.0;
            let un = u.dot(n);
            let f = ((n * cd + (n - u_hat * n.dot(u_hat)) * cl) * un
                + (u - n * un) * (SKIN_FRICTION * cd))
                * q;
            let beta = q * (cd * (1.0 + SKIN_FRICTION) + cl);
            for i in [a, b, c] {
                self.force[i] += f;
                self.beta[i] += beta;
            }
        }
        for (i, v) in v.iter_mut().enumerate() {
            if let Some(m) = self.free_mass[i] {
                *v += self.force[i] * (h / (m + h * self.beta[i]));
            }
        }
    }
}

/// SplitMix64 (Steele, Lea and Flood 2014): a tiny seeded generator, enough for a handful of
/// gust parameters.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform on the unit sphere.
    fn direction(&mut self) -> DVec3 {
        let z = 2.0 * self.unit() - 1.0;
        let a = std::f64::consts::TAU * self.unit();
        let r = (1.0 - z * z).sqrt();
        DVec3::new(r * a.cos(), r * a.sin(), z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth::springs::SpringSet;
    use crate::mesh::Mesh;

    fn one_triangle(normal_along: DVec3) -> ClothModel {
        // A unit right triangle in the plane through the origin perpendicular to `normal_along`.
        let n = normal_along.normalize();
        let (t1, t2) = n.any_orthonormal_pair();
        let positions = vec![DVec3::ZERO, t1, t2];
        let tri = if t1.cross(t2).dot(n) > 0.0 {
            [0, 1, 2]
        } else {
            [0, 2, 1]
        };
        let mesh = Mesh::from_triangles("tri".into(), positions, vec![tri]);
        ClothModel::new(mesh, SpringSet::default(), vec![1.0; 3], vec![false; 3])
            .expect("valid model")
    }

    fn wind(velocity: DVec3, drag: f64, lift: f64) -> Wind {
        Wind {
            velocity,
            drag,
            lift,
            turbulence: 0.0,
            seed: 0,
        }
    }

    /// A plate facing the wind gets ½ρC_d A|u|² along the wind, split over its vertices.
    #[test]
    fn plate_facing_the_wind_feels_the_drag_formula() {
        let model = one_triangle(DVec3::X);
        let mut aero = Aerodynamics::new(wind(DVec3::new(10.0, 0.0, 0.0), 1.2, 0.5), &model);
        let x = model.positions().to_vec();
        let mut v = vec![DVec3::ZERO; 3];
        let h = 1e-6; // small: the semi-implicit factor is then ≈ 1
        aero.apply(0.0, h, &x, &mut v);
        let total: DVec3 = v.iter().map(|v| *v / h).sum(); // m = 1 per vertex
        let expected = 0.5 * AIR_DENSITY * 1.2 * 0.5 * 100.0; // A = 1/2
        assert!((total.x - expected).abs() < 1e-4 * expected, "{total}");
        assert!(total.y.abs() < 1e-9 && total.z.abs() < 1e-9, "{total}");
    }

    /// Air gliding along a plate only drags it by skin friction; a 45° plate gets lift across
    /// the flow.
    #[test]
    fn glancing_and_inclined_plates() {
        let model = one_triangle(DVec3::Y);
        let x = model.positions().to_vec();
        let mut aero = Aerodynamics::new(wind(DVec3::new(5.0, 0.0, 0.0), 1.0, 1.0), &model);
        let mut v = vec![DVec3::ZERO; 3];
        let h = 1e-6;
        aero.apply(0.0, h, &x, &mut v);
        let total: DVec3 = v.iter().map(|v| *v / h).sum();
        let skin = 0.5 * AIR_DENSITY * 0.5 * 25.0 * SKIN_FRICTION;
        assert!((total.x - skin).abs() < 1e-4 * skin, "{total}");
        assert!(total.y.abs() < 1e-9 && total.z.abs() < 1e-9, "{total}");

        let model = one_triangle(DVec3::new(1.0, 1.0, 0.0));
        let x = model.positions().to_vec();
        let mut aero = Aerodynamics::new(wind(DVec3::new(5.0, 0.0, 0.0), 0.0, 1.0), &model);
        let mut v = vec![DVec3::ZERO; 3];
        aero.apply(0.0, 1e-6, &x, &mut v);
        // Lift ⟂ flow: no x component, positive y (n⊥ = +y for this plate).
        let total: DVec3 = v.iter().copied().sum();
        assert!(total.x.abs() < 1e-12 * total.y.abs(), "{total}");
        assert!(total.y > 0.0, "{total}");
    }

    /// However strong the wind, one step cannot push a free plate past the wind speed.
    #[test]
    fn strong_wind_never_overshoots() {
        let model = one_triangle(DVec3::X);
        let x = model.positions().to_vec();
        let mut aero = Aerodynamics::new(wind(DVec3::new(50.0, 0.0, 0.0), 1e4, 0.0), &model);
        let mut v = vec![DVec3::ZERO; 3];
        aero.apply(0.0, 0.1, &x, &mut v);
        assert!(v.iter().all(|v| v.x > 0.0 && v.x <= 50.0), "{v:?}");
    }

    #[test]
    fn gusts_are_seeded_and_have_the_requested_strength() {
        let model = one_triangle(DVec3::X);
        let mean = DVec3::new(4.0, 0.0, 0.0);
        let gusty = |seed| {
            Aerodynamics::new(
                Wind {
                    turbulence: 0.5,
                    seed,
                    ..wind(mean, 1.0, 0.0)
                },
                &model,
            )
        };
        let (a, b, c) = (gusty(7), gusty(7), gusty(8));
        let p = DVec3::new(0.3, 0.1, -0.2);
        assert_eq!(a.air_velocity(1.25, p), b.air_velocity(1.25, p));
        assert_ne!(a.air_velocity(1.25, p), c.air_velocity(1.25, p));
        // RMS gust over a long time ≈ 0.5 · 4 m/s.
        let samples = 20_000;
        let ms: f64 = (0..samples)
            .map(|i| (a.air_velocity(i as f64 * 0.05, p) - mean).length_squared())
            .sum::<f64>()
            / samples as f64;
        assert!((ms.sqrt() - 2.0).abs() < 0.3, "rms {}", ms.sqrt());
    }
}
