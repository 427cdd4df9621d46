//! Nonlinear Gauss–Seidel sweeps on a step's objective, between Newton iterations.
//!
//! A sweep visits the free particles in solver order and moves each by one local Newton step
//! on g (see [`ReducedSystem`]) with every other particle held: Δxᵢ = −Hᵢᵢ⁻¹ ∇ᵢg, where Hᵢᵢ is
//! the particle's 3×3 block of Newton's Hessian (inertia, its springs' projected blocks, its
//! bending weights, and with the barrier contact model its barrier and friction blocks). This is
//! the local solve of vertex block descent (Chen et al. 2024), used here as a smoother: stiff
//! cloth's Newton steps leave a local residual (springs lengthened by the square of a tangential
//! move) that Gauss–Seidel removes for a fraction of a factorisation's cost, while Newton keeps
//! the global, low-frequency part. [`super::NewtonSolver`] keeps a pass only when it lowers g
//! and checks its tolerance on the full gradient as before.
//!
//! With colliders, each particle's barrier is evaluated against the tangent planes of the
//! surfaces within reach where the pass starts ([`NewtonContact::barrier_planes`]), and no
//! particle moves farther than the collision thickness from there in one pass (so the planes
//! stay close to the surfaces; on a convex collider a plane is never farther than the surface).
//! A local step that would cross a barrier is halved until it does not.

use glam::{DMat3, DVec3};

use super::collide::contact::{BarrierPlane, NewtonContact};
use super::system::{spring_response, ReducedSystem, PINNED};

/// The terms of g each free particle appears in, as compressed lists per particle (particle i's
/// entries are `start[i]..start[i + 1]`).
#[derive(Debug, Clone)]
pub struct Smoother {
    spring_start: Vec<u32>,
    /// The particle's springs to other free particles.
    springs: Vec<Link>,
    anchor_start: Vec<u32>,
    /// The particle's springs to pins (indices into [`ReducedSystem::anchors`]).
    anchors: Vec<u32>,
    bend_start: Vec<u32>,
    /// The bending stencils the particle is in, with its weight there, √(N/m).
    bends: Vec<(u32, f64)>,
}

/// A spring seen from one end.
#[derive(Debug, Clone, Copy, Default)]
struct Link {
    /// The other end's solver index.
    other: u32,
    /// Rest length, m.
    rest: f64,
    /// Stiffness in tension and in compression, N/m.
    k: f64,
    kc: f64,
}

/// Groups `(owner, item)` pairs by owner (0..n): the starts and the items in owner order.
fn csr<T: Copy + Default>(
    n: usize,
    items: impl Iterator<Item = (usize, T)> + Clone,
) -> (Vec<u32>, Vec<T>) {
    let mut start = vec![0u32; n + 1];
    for (i, _) in items.clone() {
        start[i + 1] += 1;
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut out = vec![T::default(); start[n] as usize];
    for (i, item) in items {
        out[fill[i] as usize] = item;
        fill[i] += 1;
    }
    (start, out)
}

impl Smoother {
    /// The incidence lists of `sys` (whose springs and stencils must not change afterwards).
    pub fn new(sys: &ReducedSystem) -> Self {
        let n = sys.len();
        let sp = &sys.springs;
        let link = |s: usize, other: u32| Link {
            other,
            rest: sp.rest[s],
            k: sp.k[s],
            kc: sp.kc[s],
        };
        let (spring_start, springs) = csr(
            n,
            (0..sp.a.len()).flat_map(|s| {
                [
                    (sp.a[s] as usize, link(s, sp.b[s])),
                    (sp.b[s] as usize, link(s, sp.a[s])),
                ]
            }),
        );
        let an = &sys.anchors;
        let (anchor_start, anchors) = csr(n, (0..an.a.len()).map(|i| (an.a[i] as usize, i as u32)));
        let b = &sys.bends;
        let (bend_start, bends) = csr(
            n,
            (0..b.len()).flat_map(|s| {
                (0..4)
                    .filter(move |&k| b.v[s][k] != PINNED)
                    .map(move |k| (b.v[s][k] as usize, (s as u32, b.w[s][k])))
            }),
        );
        Smoother {
            spring_start,
            springs,
            anchor_start,
            anchors,
            bend_start,
            bends,
        }
    }

    /// Runs `sweeps` sweeps on `x` (solver order, m) for the objective with inertial target `y`
    /// (see [`ReducedSystem::objective`]) and, when given, the contact's barrier and friction.
    /// `x` may end with a higher objective than it started with (the local steps are not line
    /// searched); the caller compares.
    pub fn sweep(
        &self,
        sys: &ReducedSystem,
        x: &mut [DVec3],
        y: &[DVec3],
        sweeps: usize,
        contact: Option<&NewtonContact>,
        scratch: &mut SweepScratch,
    ) {
        let h = sys.params.time_step;
        let w = sys.inertia_scale() / (h * h);
        let an = &sys.anchors;
        let b = &sys.bends;
        let jam = sys.jam_strain;
        let SweepScratch {
            bend_values,
            plane_start,
            planes,
            start,
        } = scratch;
        bend_values.clear();
        bend_values.extend((0..b.len()).map(|s| b.value(s, x)));
        // With colliders every particle stays within `margin` of where it starts, where its
        // barrier planes stand for the colliders' surfaces.
        let margin = contact.map(|c| c.colliders().thickness);
        plane_start.clear();
        planes.clear();
        start.clear();
        if let (Some(c), Some(margin)) = (contact, margin) {
            start.extend_from_slice(x);
            plane_start.push(0);
            for (i, p) in x.iter().enumerate() {
                c.barrier_planes(i, *p, margin, planes);
                plane_start.push(planes.len() as u32);
            }
        }
        for _ in 0..sweeps {
            'particles: for i in 0..x.len() {
                let xi = x[i];
                let wm = w * sys.mass[i];
                let mut g = (xi - y[i]) * wm;
                let mut diag = wm;
                let mut hm = DMat3::ZERO;
                let mut add = |r: DVec3, rest: f64, k: f64, kc: f64| {
                    let len = r.length();
                    if len > 0.0 {
                        let (f, along) = spring_response(len, rest, k, kc, jam);
                        let u = r / len;
                        let t = (f / len).max(0.0);
                        g += u * f;
                        diag += t;
                        let p = along - t;
                        hm += DMat3::from_cols(u * (u.x * p), u * (u.y * p), u * (u.z * p));
                    }
                };
                for l in
                    &self.springs[self.spring_start[i] as usize..self.spring_start[i + 1] as usize]
                {
                    add(xi - x[l.other as usize], l.rest, l.k, l.kc);
                }
                for &a in
                    &self.anchors[self.anchor_start[i] as usize..self.anchor_start[i + 1] as usize]
                {
                    let a = a as usize;
                    add(xi - an.at[a], an.rest[a], an.k[a], an.kc[a]);
                }
                let incident =
                    &self.bends[self.bend_start[i] as usize..self.bend_start[i + 1] as usize];
                for &(s, wi) in incident {
                    g += bend_values[s as usize] * wi;
                    diag += wi * wi;
                }
                hm += DMat3::from_diagonal(DVec3::splat(diag));
                let mine = match contact {
                    Some(_) => &planes[plane_start[i] as usize..plane_start[i + 1] as usize],
                    None => &[][..],
                };
                if let Some(c) = contact {
                    if !c.particle_terms(i, xi, mine, &mut g, &mut hm) {
                        continue;
                    }
                }
                let det = hm.determinant();
                let m2 = hm.x_axis.x * hm.y_axis.y - hm.x_axis.y * hm.y_axis.x;
                if !(det > 0.0 && det.is_finite() && m2 > 0.0 && hm.x_axis.x > 0.0) {
                    continue;
                }
                let mut d = -(hm.inverse() * g);
                if let Some(margin) = margin {
                    // Stay within the margin, and in front of the barrier.
                    let from = start[i];
                    let far = (xi + d).distance(from);
                    if far > margin {
                        d = (from + (xi + d - from) * (margin / far)) - xi;
                    }
                    let mut halvings = 0;
                    while !mine.iter().all(|plane| plane.allows(xi + d)) {
                        if halvings == 8 {
                            continue 'particles;
                        }
                        d *= 0.5;
                        halvings += 1;
                    }
                }
                x[i] = xi + d;
                for &(s, wi) in incident {
                    bend_values[s as usize] += d * wi;
                }
            }
        }
    }
}

/// Buffers of [`Smoother::sweep`], kept between calls.
#[derive(Debug, Clone, Default)]
pub struct SweepScratch {
    bend_values: Vec<DVec3>,
    plane_start: Vec<u32>,
    planes: Vec<BarrierPlane>,
    start: Vec<DVec3>,
}
