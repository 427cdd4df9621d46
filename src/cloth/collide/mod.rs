//! Static colliders the cloth rests on: half-spaces, balls, boxes and triangle meshes.
//!
//! Positions are metres in the cloth's frame. Every collider answers one question per particle
//! ([`Collider::contact`]): how far is the particle from the surface on the side it came from, and
//! which way is out. A particle is in contact when that distance is below the collision
//! thickness; the solvers then keep it at the thickness (the fast solver by projection with
//! Coulomb friction, Newton as constraints of a projected Newton method with lagged friction, see
//! [`contact`]).

pub mod barrier;
pub mod contact;
pub mod mesh;
pub mod reaction;
pub mod shapes;

use std::path::PathBuf;
use std::str::FromStr;
use std::sync::Arc;

use glam::DVec3;

use crate::data::StaticMesh;
use crate::error::{Error, Result};
use crate::spec::parse_numbers;
pub use contact::ContactModel;
pub use mesh::MeshCollider;
pub use shapes::{Ball, Cuboid, HalfSpace};

/// The nearest surface point of a collider as seen from a particle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Signed distance of the particle from the surface, metres: positive on the free side.
    pub distance: f64,
    /// Unit normal at the nearest surface point, pointing to the free side.
    pub normal: glam::DVec3,
}

/// One parsed `--collider` value, before any file is read.
#[derive(Debug, Clone, PartialEq)]
pub enum ColliderSpec {
    /// `plane:NX,NY,NZ,D`: the half-space n·x ≤ D is solid.
    Plane(DVec3, f64),
    /// `sphere:X,Y,Z,R`.
    Sphere(DVec3, f64),
    /// `box:X0,Y0,Z0,X1,Y1,Z1` (corners in either order).
    Box(DVec3, DVec3),
    /// `mesh:FILE[#NAME]`: a static triangle mesh from an OBJ, glTF or GLB file; `part` keeps
    /// only one of its objects (an OBJ's `o`/`g` name, a glTF's mesh or mesh node name).
    Mesh {
        /// The mesh file.
        path: PathBuf,
        /// The object of the file to use (every object when `None`).
        part: Option<String>,
    },
}

impl ColliderSpec {
    /// `mesh:PATH`: every object of a mesh file.
    pub fn mesh(path: impl Into<PathBuf>) -> Self {
        ColliderSpec::Mesh {
            path: path.into(),
            part: None,
        }
    }
}

impl FromStr for ColliderSpec {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        const FORMS: &str =
            "plane:NX,NY,NZ,D, sphere:X,Y,Z,R, box:X0,Y0,Z0,X1,Y1,Z1 or mesh:FILE[#NAME]";
        let bad = |m: String| Error::value(format!("`{s}`: {m}"));
        let (kind, rest) = s
            .split_once(':')
            .ok_or_else(|| bad(format!("expected {FORMS}")))?;
        match kind.trim() {
            "plane" => {
                let c = parse_numbers::<4>(rest, "plane:NX,NY,NZ,D")?;
                let n = DVec3::new(c[0], c[1], c[2]);
                if n.length() == 0.0 {
                    return Err(bad("the plane's normal is zero".into()));
                }
                Ok(ColliderSpec::Plane(n, c[3]))
            }
            "sphere" => {
                let c = parse_numbers::<4>(rest, "sphere:X,Y,Z,R")?;
                if c[3] <= 0.0 {
                    return Err(bad(format!("radius {} must be positive", c[3])));
                }
                Ok(ColliderSpec::Sphere(DVec3::new(c[0], c[1], c[2]), c[3]))
            }
            "box" => {
                let c = parse_numbers::<6>(rest, "box:X0,Y0,Z0,X1,Y1,Z1")?;
                let (a, b) = (DVec3::new(c[0], c[1], c[2]), DVec3::new(c[3], c[4], c[5]));
                if a.cmpeq(b).any() {
                    return Err(bad("the box is flat: give two opposite corners".into()));
                }
                Ok(ColliderSpec::Box(a.min(b), a.max(b)))
            }
            "mesh" => {
                let (path, part) = crate::spec::split_mesh_part(rest).map_err(bad)?;
                Ok(ColliderSpec::Mesh { path, part })
            }
            other => Err(bad(format!(
                "unknown collider kind `{other}` (use {FORMS})"
            ))),
        }
    }
}

/// How far the vertex that moves farthest from `before` to `after` moves, m.
fn farthest(before: &[DVec3], after: &[DVec3]) -> f64 {
    before
        .iter()
        .zip(after)
        .map(|(a, b)| a.distance_squared(*b))
        .fold(0.0, f64::max)
        .sqrt()
}

/// A collider ready for queries.
#[derive(Debug, Clone)]
pub enum Collider {
    /// A solid half-space (the ground).
    Plane(HalfSpace),
    /// A solid ball.
    Sphere(Ball),
    /// A solid axis-aligned box.
    Box(Cuboid),
    /// A triangle mesh (solid when closed, a two-sided shell when open), shared between solvers.
    Mesh(Arc<MeshCollider>),
    /// A triangle mesh that moves (a character's skinned body): its pose at the start and at
    /// the end of the current step, same triangles. Contacts are taken against the end pose; a
    /// particle's start position is carried along with the surface near it ([`Self::carry`]),
    /// so a body that moves farther than the thickness in one step pushes the cloth ahead of it
    /// instead of passing through. Only Newton supports it.
    Moving {
        /// The pose at the start of the step.
        before: Arc<MeshCollider>,
        /// The pose at the end of the step.
        after: Arc<MeshCollider>,
        /// The largest distance a vertex moves between the two, m.
        motion: f64,
    },
}

impl PartialEq for Collider {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Collider::Plane(a), Collider::Plane(b)) => a == b,
            (Collider::Sphere(a), Collider::Sphere(b)) => a == b,
            (Collider::Box(a), Collider::Box(b)) => a == b,
            (Collider::Mesh(a), Collider::Mesh(b)) => Arc::ptr_eq(a, b),
            (Collider::Moving { after: a, .. }, Collider::Moving { after: b, .. }) => {
                Arc::ptr_eq(a, b)
            }
            _ => false,
        }
    }
}

impl Collider {
    /// Builds the collider a spec names; `load_mesh` reads a mesh collider's file and the part
    /// of it the spec names (the caller's loader: file reading lives in [`crate::io`]).
    ///
    /// # Errors
    /// [`Error::Value`] for a plane whose normal is zero; the mesh loader's errors, naming the
    /// file.
    pub fn from_spec(
        spec: &ColliderSpec,
        load_mesh: &dyn Fn(&std::path::Path, Option<&str>) -> Result<MeshCollider>,
    ) -> Result<Self> {
        Ok(match spec {
            ColliderSpec::Plane(n, d) => Collider::Plane(
                HalfSpace::new(*n, *d).ok_or_else(|| Error::value("the plane's normal is zero"))?,
            ),
            ColliderSpec::Sphere(centre, radius) => Collider::Sphere(Ball {
                centre: *centre,
                radius: *radius,
            }),
            ColliderSpec::Box(min, max) => Collider::Box(Cuboid {
                min: *min,
                max: *max,
            }),
            ColliderSpec::Mesh { path, part } => {
                Collider::Mesh(Arc::new(load_mesh(path, part.as_deref())?))
            }
        })
    }

    /// Where particle `p` is relative to this collider, given `from`, its position at the start
    /// of the time step. `None` when it is farther than `reach` (m) on the free side (analytic
    /// shapes always answer; they are cheap).
    #[inline]
    pub fn contact(&self, p: DVec3, from: DVec3, reach: f64) -> Option<SurfacePoint> {
        match self {
            Collider::Plane(h) => Some(h.surface_point(p)),
            Collider::Sphere(b) => Some(b.surface_point(p)),
            Collider::Box(c) => Some(c.surface_point(p)),
            Collider::Mesh(m) => m.contact(p, from, reach),
            Collider::Moving { after, .. } => after.contact(p, from, reach),
        }
    }

    /// Calls `f` for every triangle of a mesh collider closer to `p` than `radius` (m): its
    /// point nearest to `p` as a surface point (the distance to it, m, and the direction from
    /// it to `p`), whichever side `p` is on. Does nothing for the analytic shapes and for a
    /// triangle `p` lies on.
    pub fn each_triangle_within(&self, p: DVec3, radius: f64, mut f: impl FnMut(SurfacePoint)) {
        if let Collider::Mesh(m) | Collider::Moving { after: m, .. } = self {
            m.each_within(p, radius, |point, distance| {
                if distance > 0.0 {
                    f(SurfacePoint {
                        distance,
                        normal: (p - point) / distance,
                    });
                }
            });
        }
    }

    /// True for a triangle mesh ([`Collider::Mesh`], [`Collider::Moving`]).
    pub fn is_mesh(&self) -> bool {
        matches!(self, Collider::Mesh(_) | Collider::Moving { .. })
    }

    /// A body that moves from `before` to `after` during a step (the same triangles; the
    /// positions are metres in the cloth's frame).
    ///
    /// # Errors
    /// As [`MeshCollider::new`] for the end pose.
    pub fn moving(before: Arc<MeshCollider>, after: Vec<DVec3>) -> Result<Self> {
        let motion = farthest(before.positions(), &after);
        let after = Arc::new(before.posed(after)?);
        Ok(Collider::Moving {
            before,
            after,
            motion,
        })
    }

    /// The collider as the surfaces Newton's contact holds particles off one by one: a mesh's
    /// parts ([`MeshCollider::parts`]), each moving as the whole does, or the collider itself.
    pub fn parts(&self) -> Vec<Collider> {
        match self {
            Collider::Mesh(m) if !m.parts().is_empty() => {
                m.parts().iter().cloned().map(Collider::Mesh).collect()
            }
            Collider::Moving { before, after, .. }
                if !after.parts().is_empty() && before.parts().len() == after.parts().len() =>
            {
                before
                    .parts()
                    .iter()
                    .zip(after.parts())
                    .map(|(before, after)| Collider::Moving {
                        motion: farthest(before.positions(), after.positions()),
                        before: Arc::clone(before),
                        after: Arc::clone(after),
                    })
                    .collect()
            }
            _ => vec![self.clone()],
        }
    }

    /// True for a collider that moves ([`Collider::Moving`]).
    pub fn is_moving(&self) -> bool {
        matches!(self, Collider::Moving { .. })
    }

    /// How far the surface point nearest to `p` (within `reach` plus the surface's own motion,
    /// m) moves during the step, m, and how far that point is from `p` at the step's start, m;
    /// `None` for static colliders and for points out of reach.
    pub fn carry(&self, p: DVec3, reach: f64) -> Option<(DVec3, f64)> {
        let Collider::Moving {
            before,
            after,
            motion,
        } = self
        else {
            return None;
        };
        let (corners, bary) = before.closest(p, reach + motion)?;
        let (mut moved, mut at) = (DVec3::ZERO, DVec3::ZERO);
        for (&v, w) in corners.iter().zip(bary.to_array()) {
            let from = before.positions()[v as usize];
            moved += (after.positions()[v as usize] - from) * w;
            at += from * w;
        }
        Some((moved, p.distance(at)))
    }

    /// The collider as a static mesh for the exported scene, named `name`. A plane becomes a
    /// square of side `size` (m) centred under `centre` (the cloth's centre).
    pub fn static_mesh(&self, name: String, centre: DVec3, size: f64) -> StaticMesh {
        match self {
            Collider::Plane(h) => StaticMesh::plane(h.normal, h.offset, centre, size, name),
            Collider::Sphere(b) => StaticMesh::sphere(b.centre, b.radius, name),
            Collider::Box(c) => StaticMesh::cuboid(c.min, c.max, name),
            Collider::Mesh(m) | Collider::Moving { before: m, .. } => {
                StaticMesh::from_triangles(m.positions(), m.triangles(), name)
            }
        }
    }

    /// A short human-readable description (for reports).
    pub fn describe(&self) -> String {
        match self {
            Collider::Plane(h) => format!(
                "plane n=({:.3},{:.3},{:.3}) d={:.4}",
                h.normal.x, h.normal.y, h.normal.z, h.offset
            ),
            Collider::Sphere(b) => format!(
                "sphere c=({:.3},{:.3},{:.3}) r={:.4}",
                b.centre.x, b.centre.y, b.centre.z, b.radius
            ),
            Collider::Box(c) => format!(
                "box ({:.3},{:.3},{:.3})..({:.3},{:.3},{:.3})",
                c.min.x, c.min.y, c.min.z, c.max.x, c.max.y, c.max.z
            ),
            Collider::Moving { after: m, .. } => {
                format!("moving mesh, {} triangles", m.triangles().len())
            }
            Collider::Mesh(m) => format!(
                "mesh, {} triangles, {}",
                m.triangles().len(),
                if m.is_closed() { "closed" } else { "open" }
            ),
        }
    }
}

/// Default Coulomb friction coefficient (`--friction`): cotton on wood is around 0.3–0.5.
pub const DEFAULT_FRICTION: f64 = 0.4;

/// Default collision thickness as a fraction of the cloth's mean edge length (`--thickness`).
pub const DEFAULT_THICKNESS_FRACTION: f64 = 0.25;

/// The colliders of a bake with their contact parameters.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Colliders {
    /// The colliders, queried in order.
    pub shapes: Vec<Collider>,
    /// Particles stay at least this far (m) from every collider surface; with Newton's barrier
    /// ([`ContactModel::Barrier`]) more than half of it, resting about that far.
    pub thickness: f64,
    /// Coulomb friction coefficient μ (dimensionless, ≥ 0).
    pub friction: f64,
    /// How Newton keeps the particles out (the fast solver ignores it).
    pub model: ContactModel,
}

impl Colliders {
    /// True when there is nothing to collide with.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }
}
