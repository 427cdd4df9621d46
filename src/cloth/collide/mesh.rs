//! A static triangle-mesh collider (a table, a mannequin, a rock) queried through a
//! bounding-volume hierarchy.
//!
//! Hand-written rather than `parry3d-f64`'s `TriMesh`: on the same 5,120-triangle sphere and
//! 10,000 points near it, this BVH answers a reach-pruned signed-distance query about twice as
//! fast, needs no second `glam` version (parry 0.31 brings glam 0.33 through `glamx`) nor its
//! ~40 extra crates, and gives the open-mesh contract below (tunnelling through a two-sided
//! shell) in one traversal instead of a ray cast plus a projection.
//!
//! Conventions: positions in metres, in the cloth's frame. Triangles are counter-clockwise seen
//! from outside (the free side of a closed mesh). Positions with exactly equal coordinates are
//! treated as one vertex for the topology (so a closed surface exported with split vertices is
//! still closed).

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::DVec3;

use super::SurfacePoint;
use crate::cloth::proximity::{point_triangle_feature, Feature};
use crate::error::{ColliderMeshProblem, Error, Result};

/// Triangles per BVH leaf at most.
const LEAF_SIZE: usize = 4;

/// A static triangle mesh that particles collide with.
///
/// Closed, consistently oriented meshes ([`MeshCollider::is_closed`]) are solids: inside is
/// defined and reported as a negative distance. Other meshes are two-sided thin shells.
///
/// ```
/// use scenebake::cloth::collide::mesh::MeshCollider;
/// use scenebake::glam::DVec3;
///
/// // The demo table: a 1.2 × 0.8 m top whose upper face is at y = 0.75 m, on four legs.
/// let path = std::path::Path::new("meshes/table.obj");
/// let mesh = scenebake::io::obj::load_obj(path, &Default::default())?;
/// let table = MeshCollider::from_mesh(path, mesh.positions, mesh.triangles)?;
/// assert!(table.is_closed());
/// // A particle 1 cm above the top, coming from higher up, looking 5 cm around it.
/// let p = DVec3::new(0.1, 0.76, 0.0);
/// let contact = table.contact(p, p + DVec3::Y * 0.01, 0.05).unwrap();
/// assert!((contact.distance - 0.01).abs() < 1e-9);
/// assert!(contact.normal.abs_diff_eq(DVec3::Y, 1e-9));
/// // Far above: nothing within reach.
/// let far = DVec3::new(0.0, 2.0, 0.0);
/// assert_eq!(table.contact(far, far, 0.05), None);
/// # Ok::<(), scenebake::Error>(())
/// ```
pub struct MeshCollider {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Triangle data in BVH leaf order.
    tris: Vec<Tri>,
    /// Flat BVH: node 0 is the root; an inner node's left child follows it.
    nodes: Vec<Node>,
    closed: bool,
    /// Per input triangle, per edge i (corners i and i+1): the sum of the unit normals of the
    /// two triangles sharing it (closed meshes only).
    edge_normals: Vec<[DVec3; 3]>,
    /// Per position: the angle-weighted sum of the unit normals of the triangles around it
    /// (shared by welded positions; closed meshes only).
    vertex_normals: Vec<DVec3>,
    /// Below this distance (m) the direction p − c is noise: the surface normal is used.
    tiny: f64,
    /// The mesh's parts as colliders of their own ([`MeshCollider::parts`]); empty when the mesh
    /// is one part.
    parts: Vec<Arc<MeshCollider>>,
    /// Which vertices and triangles make each part, kept for the mesh's other poses
    /// ([`MeshCollider::posed`]).
    partition: Option<Arc<Partition>>,
}

/// A mesh cut into parts ([`MeshCollider::parts`]): per part, the mesh's vertices it uses and
/// its triangles indexing those.
#[derive(Debug)]
struct Partition {
    parts: Vec<(Vec<u32>, Vec<[u32; 3]>)>,
}

impl std::fmt::Debug for MeshCollider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (lo, hi) = self.bounds();
        f.debug_struct("MeshCollider")
            .field("positions", &self.positions.len())
            .field("triangles", &self.triangles.len())
            .field("bvh_nodes", &self.nodes.len())
            .field("closed", &self.closed)
            .field("bounds", &(lo, hi))
            .finish()
    }
}

/// One triangle as the queries read it.
#[derive(Debug, Clone, Copy)]
struct Tri {
    a: DVec3,
    b: DVec3,
    c: DVec3,
    /// Unit normal, counter-clockwise orientation.
    normal: DVec3,
    /// Index into [`MeshCollider::triangles`].
    id: u32,
}

/// A BVH node: a box and either two children (`count == 0`, left = this + 1, right = `first`)
/// or the leaf triangles `tris[first..first + count]`.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    first: u32,
    count: u32,
}

/// The closest surface point found by a search.
#[derive(Debug, Clone, Copy)]
struct Nearest {
    point: DVec3,
    distance_squared: f64,
    /// Index into `tris`.
    tri: usize,
    feature: Feature,
}

impl MeshCollider {
    /// Validates the mesh and builds its bounding-volume hierarchy.
    ///
    /// `positions` are metres in the cloth's frame; `triangles` index them, counter-clockwise
    /// seen from outside. Degenerate triangles (a repeated corner or zero area) are dropped.
    ///
    /// # Errors
    /// [`Error::ColliderMesh`] (without a path) for a non-finite position, an index out of range,
    /// or when no triangle of non-zero area is left.
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Result<Self> {
        Self::build(positions, triangles, Split::Find)
    }

    /// The same mesh with its vertices at `positions` (another pose: same count and order), cut
    /// into the same parts.
    ///
    /// # Errors
    /// As [`MeshCollider::new`], for the whole mesh or a part.
    pub fn posed(&self, positions: Vec<DVec3>) -> Result<Self> {
        let split = match &self.partition {
            Some(p) => Split::As(Arc::clone(p)),
            None => Split::Whole,
        };
        Self::build(positions, self.triangles.clone(), split)
    }

    /// The mesh's parts, each a collider of its own, when it is made of several connected
    /// pieces (welded positions joined) of which at least one is closed: every closed piece is a
    /// part (a solid), and the open pieces together one more (a shell). Empty otherwise.
    ///
    /// A character is often built of closed pieces that overlap (a leg's top inside the hips):
    /// as one mesh it is not closed, so it would be a two-sided shell, and a particle pushed
    /// into a leg would stay inside it. Part by part, each piece is a solid, and a particle
    /// near where two pieces meet is held off both.
    pub fn parts(&self) -> &[Arc<MeshCollider>] {
        &self.parts
    }

    fn build(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>, split: Split) -> Result<Self> {
        let refuse = |problem| Error::ColliderMesh {
            path: None,
            problem,
        };
        if let Some(index) = positions.iter().position(|p| !p.is_finite()) {
            return Err(refuse(ColliderMeshProblem::NonFinitePosition { index }));
        }
        for (triangle, t) in triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= positions.len()) {
                return Err(refuse(ColliderMeshProblem::IndexOutOfRange {
                    triangle,
                    index,
                    positions: positions.len(),
                }));
            }
        }
        let before = triangles.len();
        let triangles: Vec<[u32; 3]> = triangles
            .into_iter()
            .filter(|&[a, b, c]| {
                let [pa, pb, pc] = [a, b, c].map(|i| positions[i as usize]);
                a != b && b != c && a != c && (pb - pa).cross(pc - pa).try_normalize().is_some()
            })
            .collect();
        if triangles.is_empty() {
            return Err(refuse(ColliderMeshProblem::NoTriangles { dropped: before }));
        }

        let mut tris: Vec<Tri> = triangles
            .iter()
            .enumerate()
            .map(|(id, &[a, b, c])| {
                let [a, b, c] = [a, b, c].map(|i| positions[i as usize]);
                Tri {
                    a,
                    b,
                    c,
                    normal: (b - a).cross(c - a).normalize(),
                    id: id as u32,
                }
            })
            .collect();
        let mut nodes = Vec::with_capacity(2 * tris.len() / LEAF_SIZE + 1);
        build(&mut nodes, &mut tris, 0);

        let weld = weld(&positions);
        let (closed, edge_normals, vertex_normals) = topology(&positions, &triangles, &weld);
        let (lo, hi) = (nodes[0].lo, nodes[0].hi);
        let tiny = 1e-12 * (1.0 + (hi - lo).length() + lo.abs().max(hi.abs()).max_element());
        let partition = match split {
            Split::Find => partition(&positions, &triangles, &weld).map(Arc::new),
            Split::As(p) => Some(p),
            _ => None,
        };
        let parts = match &partition {
            Some(p) => p
                .parts
                .iter()
                .map(|(vertices, triangles)| {
                    let positions = vertices.iter().map(|&v| positions[v as usize]).collect();
                    Self::build(positions, triangles.clone(), Split::Whole).map(Arc::new)
                })
                .collect::<Result<_>>()?,
            None => Vec::new(),
        };
        Ok(MeshCollider {
            positions,
            triangles,
            tris,
            nodes,
            closed,
            edge_normals,
            vertex_normals,
            tiny,
            parts,
            partition,
        })
    }

    /// A collider from a mesh loaded from `path` (named in its errors).
    ///
    /// # Errors
    /// [`Error::ColliderMesh`] naming `path`, as [`MeshCollider::new`].
    pub fn from_mesh(path: &Path, positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Result<Self> {
        MeshCollider::new(positions, triangles).map_err(|e| match e {
            Error::ColliderMesh { problem, .. } => Error::ColliderMesh {
                path: Some(path.into()),
                problem,
            },
            e => e,
        })
    }

    /// True when every edge is shared by exactly two triangles with opposite orientations (a
    /// closed, consistently oriented surface): then inside and outside are defined.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The positions, metres.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// The triangles kept (degenerate ones dropped), in input order.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// Axis-aligned bounds (min, max) of the triangles, metres.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.nodes[0].lo, self.nodes[0].hi)
    }

    /// The surface point nearest to `p` within `reach` (m) as the corners of its triangle
    /// (indices into [`Self::positions`]) and its barycentric coordinates there: where a point
    /// bound to the surface goes when the mesh deforms (same corners, new positions). `None`
    /// when nothing is that close.
    pub fn closest(&self, p: DVec3, reach: f64) -> Option<([u32; 3], DVec3)> {
        let n = self.nearest(p, reach.max(0.0) + self.tiny)?;
        let tri = &self.tris[n.tri];
        let corners = self.triangles[tri.id as usize];
        Some((corners, barycentric(n.point, tri.a, tri.b, tri.c)))
    }

    /// Where particle `p` is relative to the surface, given `from`: the particle's position at
    /// the start of the time step (on the free side). Metres, the cloth's frame.
    ///
    /// - Closed mesh: the free side is the outside; `distance` is negative inside (the sign of
    ///   `p − c` against the angle-weighted pseudo-normal of the feature nearest to `p`,
    ///   Bærentzen & Aanæs 2005). When the segment `from → p` enters the mesh, the entry face
    ///   decides instead: `distance` is p's signed distance from that face's plane and `normal`
    ///   the face's, so a particle that moved deeper than half a thin part in one step is still
    ///   pushed back out on the side it came from.
    /// - Open mesh: a two-sided thin shell; the free side is the side `from` is on. If the
    ///   segment `from → p` crosses the surface, `p` has tunnelled: `distance` is minus the
    ///   distance from `p` to the surface and `normal` the first crossed triangle's normal
    ///   oriented towards `from`. Otherwise `distance = |p − c|` (c the nearest surface point)
    ///   and `normal = (p − c)/|p − c|`, or the nearest face's normal oriented towards `p` (or
    ///   towards `from` when `p` is in its plane) when `p` is on the surface.
    ///
    /// Returns `None` when `p` is on the free side and farther than `reach` (m, ≥ 0) from the
    /// surface, and for non-finite input.
    pub fn contact(&self, p: DVec3, from: DVec3, reach: f64) -> Option<SurfacePoint> {
        // Rounding in the closest-point arithmetic must not turn a particle lying on the
        // surface away with a zero reach.
        let reach = if reach > 0.0 { reach } else { 0.0 } + self.tiny;
        if !p.is_finite() {
            return None;
        }
        if self.closed {
            // Entered since the step began (the first crossing of from → p goes in through a
            // face turned towards `from`): measure against that face, so a particle that went
            // deeper than half a thin part (a table top) still comes back out on its own side.
            if from.is_finite() && from != p {
                if let Some((_, tri)) = self.first_crossing(from, p) {
                    let tri = &self.tris[tri];
                    if tri.normal.dot(from - tri.a) > 0.0 {
                        return Some(SurfacePoint {
                            distance: tri.normal.dot(p - tri.a),
                            normal: tri.normal,
                        });
                    }
                }
            }
            return self.contact_closed(p, reach);
        }
        if from.is_finite() && from != p {
            if let Some((t, tri)) = self.first_crossing(from, p) {
                let crossing = from + (p - from) * t;
                // The crossing point bounds the search: the nearest point is at least as close.
                let bound = (p - crossing).length() * (1.0 + 1e-9) + self.tiny;
                // (The crossing may sit on an edge's tolerance band, just off the triangle:
                // then search without a bound.)
                let distance = self
                    .nearest(p, bound)
                    .or_else(|| self.nearest(p, f64::INFINITY))
                    .map_or(0.0, |n| n.distance_squared.sqrt());
                let tri = &self.tris[tri];
                let normal = if tri.normal.dot(from - tri.a) >= 0.0 {
                    tri.normal
                } else {
                    -tri.normal
                };
                return Some(SurfacePoint {
                    distance: -distance,
                    normal,
                });
            }
        }
        let n = self.nearest(p, reach)?;
        let distance = n.distance_squared.sqrt();
        let normal = if distance > self.tiny {
            (p - n.point) / distance
        } else {
            let tri = &self.tris[n.tri];
            let side = tri.normal.dot(p - tri.a);
            let side = if side != 0.0 {
                side
            } else {
                tri.normal.dot(from - tri.a)
            };
            if side >= 0.0 {
                tri.normal
            } else {
                -tri.normal
            }
        };
        Some(SurfacePoint { distance, normal })
    }

    /// [`MeshCollider::contact`] for a closed mesh.
    fn contact_closed(&self, p: DVec3, reach: f64) -> Option<SurfacePoint> {
        if let Some(n) = self.nearest(p, reach) {
            return Some(self.signed(p, &n));
        }
        // Nothing within reach: p is either far outside or deep inside.
        let (lo, hi) = self.bounds();
        if p.cmplt(lo).any() || p.cmpgt(hi).any() {
            return None;
        }
        let n = self.nearest(p, f64::INFINITY)?;
        let s = self.signed(p, &n);
        (s.distance < 0.0).then_some(s)
    }

    /// The signed distance and outward normal of a closed mesh from its nearest point.
    fn signed(&self, p: DVec3, n: &Nearest) -> SurfacePoint {
        let tri = &self.tris[n.tri];
        let id = tri.id as usize;
        let pseudo = match n.feature {
            Feature::Face => tri.normal,
            Feature::Edge(i) => self.edge_normals[id][i as usize],
            Feature::Vertex(i) => self.vertex_normals[self.triangles[id][i as usize] as usize],
        };
        let offset = p - n.point;
        let distance = n.distance_squared.sqrt();
        let outside = offset.dot(pseudo) >= 0.0;
        let normal = if distance > self.tiny {
            if outside {
                offset / distance
            } else {
                -offset / distance
            }
        } else {
            pseudo.try_normalize().unwrap_or(tri.normal)
        };
        SurfacePoint {
            distance: if outside { distance } else { -distance },
            normal,
        }
    }

    /// Calls `f(point, distance)` for every triangle closer to `p` than `radius` (m), with the
    /// triangle's point nearest to `p` and its distance (m).
    pub fn each_within(&self, p: DVec3, radius: f64, mut f: impl FnMut(DVec3, f64)) {
        let r2 = radius * radius;
        if box_distance_squared(p, &self.nodes[0]) >= r2 {
            return;
        }
        let mut stack = Stack::new(0u32);
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for tri in &self.tris[first..first + node.count as usize] {
                    let (point, _) = closest_on_triangle(p, tri.a, tri.b, tri.c);
                    let d2 = p.distance_squared(point);
                    if d2 < r2 {
                        f(point, d2.sqrt());
                    }
                }
            } else {
                for child in [index + 1, node.first] {
                    if box_distance_squared(p, &self.nodes[child as usize]) < r2 {
                        stack.push(child);
                    }
                }
            }
        }
    }

    /// The surface point nearest to `p` among those within `max_distance` (inclusive).
    fn nearest(&self, p: DVec3, max_distance: f64) -> Option<Nearest> {
        let mut best: Option<Nearest> = None;
        let mut best_d2 = max_distance * max_distance;
        let root_d2 = box_distance_squared(p, &self.nodes[0]);
        if root_d2 > best_d2 {
            return None;
        }
        let mut stack = Stack::<(u32, f64)>::new((0, root_d2));
        while let Some((index, d2)) = stack.pop() {
            if d2 > best_d2 {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for (k, tri) in self.tris[first..first + node.count as usize]
                    .iter()
                    .enumerate()
                {
                    let (point, feature) = closest_on_triangle(p, tri.a, tri.b, tri.c);
                    let d2 = p.distance_squared(point);
                    if d2 <= best_d2 {
                        best_d2 = d2;
                        best = Some(Nearest {
                            point,
                            distance_squared: d2,
                            tri: first + k,
                            feature,
                        });
                    }
                }
            } else {
                let left = index + 1;
                let right = node.first;
                let dl = box_distance_squared(p, &self.nodes[left as usize]);
                let dr = box_distance_squared(p, &self.nodes[right as usize]);
                // Push the farther child first so the nearer one is searched first.
                let (near, far) = if dl <= dr {
                    ((left, dl), (right, dr))
                } else {
                    ((right, dr), (left, dl))
                };
                if far.1 <= best_d2 {
                    stack.push(far);
                }
                if near.1 <= best_d2 {
                    stack.push(near);
                }
            }
        }
        best
    }

    /// The first triangle (smallest parameter t in (0, 1] along `from → to`) whose plane the
    /// segment crosses strictly inside or on the triangle, with t.
    fn first_crossing(&self, from: DVec3, to: DVec3) -> Option<(f64, usize)> {
        let (slo, shi) = (from.min(to), from.max(to));
        let mut best: Option<(f64, usize)> = None;
        let mut stack = Stack::new(0u32);
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index as usize];
            if node.lo.cmpgt(shi).any() || node.hi.cmplt(slo).any() {
                continue;
            }
            if node.count > 0 {
                let first = node.first as usize;
                for (k, tri) in self.tris[first..first + node.count as usize]
                    .iter()
                    .enumerate()
                {
                    if let Some(t) = segment_crosses(from, to, tri) {
                        if best.is_none_or(|(bt, _)| t < bt) {
                            best = Some((t, first + k));
                        }
                    }
                }
            } else {
                stack.push(node.first);
                stack.push(index + 1);
            }
        }
        best
    }
}

/// A traversal stack on the call stack. A median-split tree over fewer than 2³² triangles is
/// at most 31 levels deep and a depth-first traversal holds at most one pending sibling per level
/// plus the node at hand, so 64 slots never overflow.
struct Stack<T: Copy> {
    items: [T; 64],
    len: usize,
}

impl<T: Copy> Stack<T> {
    fn new(first: T) -> Self {
        Stack {
            items: [first; 64],
            len: 1,
        }
    }

    #[inline]
    fn push(&mut self, item: T) {
        self.items[self.len] = item;
        self.len += 1;
    }

    #[inline]
    fn pop(&mut self) -> Option<T> {
        self.len = self.len.checked_sub(1)?;
        Some(self.items[self.len])
    }
}

/// Builds the subtree over `tris` (whose first element is `tris_offset` in the whole array),
/// appending its nodes; returns the subtree root's index.
fn build(nodes: &mut Vec<Node>, tris: &mut [Tri], tris_offset: usize) -> u32 {
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for t in tris.iter() {
        lo = lo.min(t.a.min(t.b).min(t.c));
        hi = hi.max(t.a.max(t.b).max(t.c));
        let centre = (t.a + t.b + t.c) / 3.0;
        clo = clo.min(centre);
        chi = chi.max(centre);
    }
    let index = nodes.len() as u32;
    nodes.push(Node {
        lo,
        hi,
        first: tris_offset as u32,
        count: tris.len() as u32,
    });
    if tris.len() <= LEAF_SIZE {
        return index;
    }
    // Median split along the centroids' longest axis.
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = tris.len() / 2;
    tris.select_nth_unstable_by(mid, |s, t| {
        let cs = (s.a + s.b + s.c)[axis];
        let ct = (t.a + t.b + t.c)[axis];
        cs.total_cmp(&ct)
    });
    let (left, right) = tris.split_at_mut(mid);
    build(nodes, left, tris_offset);
    let right_index = build(nodes, right, tris_offset + mid);
    nodes[index as usize].first = right_index;
    nodes[index as usize].count = 0;
    index
}

/// Squared distance from `p` to a node's box (0 inside).
#[inline]
fn box_distance_squared(p: DVec3, node: &Node) -> f64 {
    let d = (node.lo - p).max(p - node.hi).max(DVec3::ZERO);
    d.length_squared()
}

/// The point of triangle abc closest to p and the feature it lies on (Ericson, Real-Time
/// Collision Detection, 5.1.5). The triangle must not be degenerate.
/// Barycentric coordinates of `p` (in the triangle's plane) in the triangle a, b, c.
fn barycentric(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let denom = d00 * d11 - d01 * d01;
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    DVec3::new(1.0 - v - w, v, w)
}

fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, Feature) {
    let (s, feature) = point_triangle_feature(p, a, b, c);
    (p - s.vector, feature)
}

/// The parameter t ∈ (0, 1) at which segment from → to passes through triangle `tri`, when
/// `from` and `to` are strictly on opposite sides of its plane. Edges count as inside (with a
/// relative tolerance of 1e-12), so a segment through a shared edge is caught by at least one of
/// its triangles.
fn segment_crosses(from: DVec3, to: DVec3, tri: &Tri) -> Option<f64> {
    let da = tri.normal.dot(from - tri.a);
    let db = tri.normal.dot(to - tri.a);
    if !((da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0)) {
        return None;
    }
    let t = da / (da - db);
    let x = from + (to - from) * t;
    // Edge functions against the normal: all non-negative inside.
    let n = tri.normal;
    let e0 = (tri.b - tri.a).cross(x - tri.a).dot(n);
    let e1 = (tri.c - tri.b).cross(x - tri.b).dot(n);
    let e2 = (tri.a - tri.c).cross(x - tri.c).dot(n);
    let area2 = (tri.b - tri.a).cross(tri.c - tri.a).dot(n);
    let tolerance = -1e-12 * area2;
    (e0 >= tolerance && e1 >= tolerance && e2 >= tolerance).then_some(t)
}

/// For each position, the index of the first position with exactly the same coordinates.
fn weld(positions: &[DVec3]) -> Vec<u32> {
    let mut order: Vec<u32> = (0..positions.len() as u32).collect();
    let key = |i: u32| {
        let p = positions[i as usize];
        // +0.0 and -0.0 are the same place.
        [p.x + 0.0, p.y + 0.0, p.z + 0.0].map(f64::to_bits)
    };
    order.sort_by_key(|&i| (key(i), i));
    let mut weld: Vec<u32> = (0..positions.len() as u32).collect();
    for pair in order.windows(2) {
        if key(pair[0]) == key(pair[1]) {
            weld[pair[1] as usize] = weld[pair[0] as usize];
        }
    }
    weld
}

/// Whether [`MeshCollider::build`] looks for parts.
enum Split {
    /// Cut the mesh into its parts where it has several ([`MeshCollider::parts`]).
    Find,
    /// Cut it as another pose of the same mesh was cut.
    As(Arc<Partition>),
    /// Keep it whole.
    Whole,
}

/// The parts of a mesh ([`MeshCollider::parts`]): its connected
/// pieces (triangles sharing a welded position), each closed one a part and the open ones
/// together another; `None` when there is one piece or no closed one.
fn partition(positions: &[DVec3], triangles: &[[u32; 3]], weld: &[u32]) -> Option<Partition> {
    // Union–find over welded positions.
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let up = parent[parent[i as usize] as usize];
            parent[i as usize] = up;
            i = up;
        }
        i
    }
    let mut parent: Vec<u32> = (0..positions.len() as u32).collect();
    for t in triangles {
        let a = root(&mut parent, weld[t[0] as usize]);
        for &v in &t[1..] {
            let b = root(&mut parent, weld[v as usize]);
            parent[b as usize] = a;
        }
    }
    // Pieces in the order of their first triangle.
    let mut piece_of_root: HashMap<u32, usize> = HashMap::new();
    let mut pieces: Vec<Vec<[u32; 3]>> = Vec::new();
    for t in triangles {
        let r = root(&mut parent, weld[t[0] as usize]);
        let k = *piece_of_root.entry(r).or_insert_with(|| {
            pieces.push(Vec::new());
            pieces.len() - 1
        });
        pieces[k].push(*t);
    }
    if pieces.len() < 2 {
        return None;
    }
    // A piece is closed when every edge of it has a twin (always in the same piece).
    let directed = directed_edges(triangles, weld);
    let closed_piece = |piece: &Vec<[u32; 3]>| {
        piece.iter().all(|t| {
            (0..3).all(|e| {
                let (a, b) = welded_edge(weld, t, e);
                twin(&directed, a, b).is_some()
            })
        })
    };
    let (closed, open): (Vec<_>, Vec<_>) = pieces.into_iter().partition(closed_piece);
    if closed.is_empty() {
        return None;
    }
    let mut groups = closed;
    let open: Vec<[u32; 3]> = open.into_iter().flatten().collect();
    if !open.is_empty() {
        groups.push(open);
    }
    // Each part indexes its own vertices.
    let parts = groups
        .into_iter()
        .map(|tris| {
            let mut local: HashMap<u32, u32> = HashMap::new();
            let mut vertices = Vec::new();
            let tris = tris
                .iter()
                .map(|t| {
                    t.map(|v| {
                        *local.entry(v).or_insert_with(|| {
                            vertices.push(v);
                            vertices.len() as u32 - 1
                        })
                    })
                })
                .collect();
            (vertices, tris)
        })
        .collect();
    Some(Partition { parts })
}

/// Edge `e` of triangle `t` (from corner e to the next) as welded positions.
#[inline]
fn welded_edge(weld: &[u32], t: &[u32; 3], e: usize) -> (u32, u32) {
    (weld[t[e] as usize], weld[t[(e + 1) % 3] as usize])
}

/// Directed edges (welded corners) → (the first triangle holding it, how often it occurs).
fn directed_edges(triangles: &[[u32; 3]], weld: &[u32]) -> HashMap<(u32, u32), (usize, u32)> {
    let mut directed: HashMap<(u32, u32), (usize, u32)> =
        HashMap::with_capacity(3 * triangles.len());
    for (t, tri) in triangles.iter().enumerate() {
        for e in 0..3 {
            let key = welded_edge(weld, tri, e);
            directed
                .entry(key)
                .and_modify(|entry| entry.1 += 1)
                .or_insert((t, 1));
        }
    }
    directed
}

/// The triangle across the directed edge a → b, when the edge is a closed surface's: it occurs
/// once, its reverse once, and it is not degenerate.
fn twin(directed: &HashMap<(u32, u32), (usize, u32)>, a: u32, b: u32) -> Option<usize> {
    let once = directed.get(&(a, b)).is_some_and(|entry| entry.1 == 1);
    match directed.get(&(b, a)) {
        Some(&(other, 1)) if once && a != b => Some(other),
        _ => None,
    }
}

/// Whether the surface is closed and consistently oriented, with the edge and vertex
/// pseudo-normals (Bærentzen & Aanæs 2005) a closed surface needs for its sign test. Vertex
/// pseudo-normals are stored per position (welded positions share theirs).
fn topology(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    weld: &[u32],
) -> (bool, Vec<[DVec3; 3]>, Vec<DVec3>) {
    let normals: Vec<DVec3> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            (b - a).cross(c - a).normalize()
        })
        .collect();
    let directed = directed_edges(triangles, weld);
    let mut closed = true;
    let mut edge_normals: Vec<[DVec3; 3]> = normals.iter().map(|&n| [n; 3]).collect();
    for (t, (tri, edges)) in triangles.iter().zip(&mut edge_normals).enumerate() {
        for (e, edge) in edges.iter_mut().enumerate() {
            let (a, b) = welded_edge(weld, tri, e);
            match twin(&directed, a, b) {
                Some(other) => *edge = normals[t] + normals[other],
                None => closed = false,
            }
        }
    }
    let mut welded_normals = vec![DVec3::ZERO; positions.len()];
    for (t, tri) in triangles.iter().enumerate() {
        let p = tri.map(|i| positions[i as usize]);
        for k in 0..3 {
            let u = p[(k + 1) % 3] - p[k];
            let v = p[(k + 2) % 3] - p[k];
            let angle = u.cross(v).length().atan2(u.dot(v));
            welded_normals[weld[tri[k] as usize] as usize] += normals[t] * angle;
        }
    }
    let vertex_normals = (0..positions.len())
        .map(|i| welded_normals[weld[i] as usize])
        .collect();
    (closed, edge_normals, vertex_normals)
}

/// A closed unit icosphere subdivided `levels` times: 20·4^levels triangles wound outwards,
/// vertices on the unit sphere (for tests and benchmarks of mesh colliders).
pub fn icosphere(levels: usize) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(|p| DVec3::from_array(p).normalize())
    .to_vec();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mids: std::collections::BTreeMap<(u32, u32), u32> = Default::default();
        let mut mid = |a: u32, b: u32, v: &mut Vec<DVec3>| {
            *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                v.len() as u32 - 1
            })
        };
        f = f
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = mid(a, b, &mut v);
                let bc = mid(b, c, &mut v);
                let ca = mid(c, a, &mut v);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    (v, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (xorshift64*), uniform in [0, 1).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn in_box(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
            lo + (hi - lo) * DVec3::new(self.next(), self.next(), self.next())
        }
    }

    /// An axis-aligned box, 8 shared corners, 12 outward triangles.
    pub(crate) fn cube(lo: DVec3, hi: DVec3) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let positions = (0..8)
            .map(|i| {
                DVec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                )
            })
            .collect();
        // Corner i has x from bit 0, y from bit 1, z from bit 2.
        let quads = [
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
        ];
        let triangles = quads
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
            .collect();
        (positions, triangles)
    }

    /// A unit square in y = 0 (x, z in [0, 1]), normal +y, two triangles.
    fn quad() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        (
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    /// Nearest distance over every triangle.
    fn brute_distance(m: &MeshCollider, p: DVec3) -> f64 {
        m.tris
            .iter()
            .map(|t| p.distance(closest_on_triangle(p, t.a, t.b, t.c).0))
            .fold(f64::INFINITY, f64::min)
    }

    /// Inside test by ray parity over every triangle (a ray in a generic direction).
    fn brute_inside(m: &MeshCollider, p: DVec3) -> bool {
        let far = p + DVec3::new(0.5377, 0.8123, 0.2269).normalize() * 1e3;
        m.tris
            .iter()
            .filter(|t| segment_crosses(p, far, t).is_some())
            .count()
            % 2
            == 1
    }

    #[track_caller]
    fn assert_close(a: DVec3, b: DVec3, epsilon: f64) {
        assert!(a.abs_diff_eq(b, epsilon), "{a} != {b} (±{epsilon})");
    }

    fn box_signed_distance(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
        let q = (p - (lo + hi) * 0.5).abs() - (hi - lo) * 0.5;
        q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
    }

    #[test]
    fn bvh_matches_brute_force_on_a_closed_sphere() {
        let (v, f) = icosphere(3);
        let m = MeshCollider::new(v, f).unwrap();
        assert!(m.is_closed());
        let mut rng = Rng(7);
        let mut inside = 0;
        for _ in 0..2000 {
            let p = rng.in_box(DVec3::splat(-1.3), DVec3::splat(1.3));
            let exact = brute_distance(&m, p);
            let sign = if brute_inside(&m, p) { -1.0 } else { 1.0 };
            let s = m
                .contact(p, p, f64::INFINITY)
                .expect("infinite reach answers");
            approx::assert_abs_diff_eq!(s.distance, sign * exact, epsilon = 1e-12);
            approx::assert_abs_diff_eq!(s.normal.length(), 1.0, epsilon = 1e-12);
            inside += usize::from(sign < 0.0);
            // With a finite reach: None exactly when outside and beyond it.
            let reach = 0.1;
            match m.contact(p, p, reach) {
                Some(r) => {
                    assert_eq!(r, s);
                    assert!(r.distance <= reach);
                }
                None => assert!(sign > 0.0 && exact > reach),
            }
        }
        assert!(inside > 200, "{inside} samples inside");
    }

    #[test]
    fn bvh_matches_brute_force_on_an_open_quad() {
        let (v, f) = quad();
        let m = MeshCollider::new(v, f).unwrap();
        assert!(!m.is_closed());
        let mut rng = Rng(11);
        for _ in 0..2000 {
            let p = rng.in_box(DVec3::splat(-0.5), DVec3::splat(1.5));
            // From straight above or below p, on p's side: no tunnelling.
            let from = p + DVec3::Y * 0.01 * p.y.signum();
            let exact = brute_distance(&m, p);
            let s = m.contact(p, from, f64::INFINITY).unwrap();
            approx::assert_abs_diff_eq!(s.distance, exact, epsilon = 1e-12);
            let c = p - s.normal * s.distance;
            approx::assert_abs_diff_eq!(brute_distance(&m, c), 0.0, epsilon = 1e-12);
        }
    }

    #[test]
    fn bvh_matches_brute_force_on_a_larger_random_soup() {
        // Many small random triangles: deep trees, overlapping boxes.
        let mut rng = Rng(3);
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for i in 0..600u32 {
            let centre = rng.in_box(DVec3::splat(-1.0), DVec3::splat(1.0));
            for _ in 0..3 {
                positions.push(centre + rng.in_box(DVec3::splat(-0.1), DVec3::splat(0.1)));
            }
            triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let m = MeshCollider::new(positions, triangles).unwrap();
        for _ in 0..1000 {
            let p = rng.in_box(DVec3::splat(-1.5), DVec3::splat(1.5));
            let exact = brute_distance(&m, p);
            match m.contact(p, p, 0.05) {
                Some(s) => approx::assert_abs_diff_eq!(s.distance, exact, epsilon = 1e-12),
                None => assert!(exact > 0.05),
            }
        }
    }

    #[test]
    fn closed_cube_sign_matches_the_analytic_box() {
        let (lo, hi) = (DVec3::new(-0.6, 0.7, -0.4), DVec3::new(0.6, 0.75, 0.4));
        let (v, f) = cube(lo, hi);
        let m = MeshCollider::new(v, f).unwrap();
        assert!(m.is_closed());
        assert_eq!(m.bounds(), (lo, hi));
        let mut rng = Rng(5);
        for _ in 0..5000 {
            let p = rng.in_box(lo - 0.3, hi + 0.3);
            let expected = box_signed_distance(p, lo, hi);
            let s = m.contact(p, p, f64::INFINITY).unwrap();
            approx::assert_abs_diff_eq!(s.distance, expected, epsilon = 1e-12);
            // The normal points to the free side: stepping along it leaves the box.
            let out = p + s.normal * (s.distance.abs() + 1e-6);
            assert!(box_signed_distance(out, lo, hi) > 0.0);
        }
        // Exactly on a face, an edge and a corner of a unit cube (exact arithmetic): distance
        // 0, the pseudo-normals.
        let (v, f) = cube(DVec3::ZERO, DVec3::ONE);
        let m = MeshCollider::new(v, f).unwrap();
        let face = m
            .contact(DVec3::new(0.5, 1.0, 0.25), DVec3::new(0.5, 1.0, 0.25), 0.0)
            .unwrap();
        assert_eq!(face.distance, 0.0);
        assert_close(face.normal, DVec3::Y, 1e-12);
        let edge = m
            .contact(DVec3::new(1.0, 1.0, 0.5), DVec3::new(1.0, 1.0, 0.5), 0.0)
            .unwrap();
        assert_eq!(edge.distance, 0.0);
        assert_close(edge.normal, DVec3::new(1.0, 1.0, 0.0).normalize(), 1e-12);
        let corner = m.contact(DVec3::ONE, DVec3::ONE, 0.0).unwrap();
        assert_eq!(corner.distance, 0.0);
        assert!(corner.normal.cmpgt(DVec3::ZERO).all(), "{}", corner.normal);
    }

    #[test]
    fn tunnelling_through_an_open_quad_is_detected() {
        let (v, f) = quad();
        let m = MeshCollider::new(v, f).unwrap();
        // From 1 cm above to 2 mm below: tunnelled, pushed back up.
        let s = m
            .contact(
                DVec3::new(0.3, -0.002, 0.6),
                DVec3::new(0.3, 0.01, 0.6),
                0.0,
            )
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, -0.002, epsilon = 1e-15);
        assert_eq!(s.normal, DVec3::Y);
        // The same from below: the free side is below, the normal points down.
        let s = m
            .contact(
                DVec3::new(0.3, 0.002, 0.6),
                DVec3::new(0.3, -0.01, 0.6),
                0.0,
            )
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, -0.002, epsilon = 1e-15);
        assert_eq!(s.normal, -DVec3::Y);
        // Through the shared diagonal, at a slant: still caught.
        let s = m
            .contact(
                DVec3::new(0.52, -0.002, 0.48),
                DVec3::new(0.48, 0.002, 0.52),
                0.0,
            )
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, -0.002, epsilon = 1e-15);
        assert_eq!(s.normal, DVec3::Y);
        // Below without crossing (came from below, beside the quad): free side, positive.
        let s = m
            .contact(
                DVec3::new(0.3, -0.002, 0.6),
                DVec3::new(0.3, -0.01, 0.6),
                0.01,
            )
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, 0.002, epsilon = 1e-15);
        assert_close(s.normal, -DVec3::Y, 1e-12);
        // Passing beside the quad's edge is no crossing.
        assert_eq!(
            m.contact(
                DVec3::new(1.2, -0.002, 0.6),
                DVec3::new(1.2, 0.01, 0.6),
                0.01
            ),
            None
        );
        // On the surface: distance 0, the face normal towards `from`.
        let s = m
            .contact(DVec3::new(0.3, 0.0, 0.6), DVec3::new(0.3, -0.01, 0.6), 0.0)
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, 0.0, epsilon = 1e-15);
        assert_eq!(s.normal, -DVec3::Y);
    }

    #[test]
    fn reach_prunes_far_particles() {
        let (v, f) = icosphere(2);
        let m = MeshCollider::new(v, f).unwrap();
        let far = DVec3::new(0.0, 3.0, 0.0);
        assert_eq!(m.contact(far, far, 0.5), None);
        let s = m.contact(far, far, 2.5).unwrap();
        approx::assert_abs_diff_eq!(s.distance, 2.0, epsilon = 1e-12);
        // Deep inside a closed mesh there is always an answer, whatever the reach.
        let s = m.contact(DVec3::ZERO, DVec3::ZERO, 0.01).unwrap();
        assert!(s.distance < -0.9);
        // Open meshes: None beyond reach on either side.
        let (v, f) = quad();
        let q = MeshCollider::new(v, f).unwrap();
        let p = DVec3::new(0.5, -0.3, 0.5);
        assert_eq!(q.contact(p, p, 0.2), None);
        assert!(q.contact(p, p, 0.4).is_some());
        // Non-finite particles get no answer rather than a panic.
        assert_eq!(q.contact(DVec3::NAN, p, 1.0), None);
    }

    #[test]
    fn closedness() {
        let (v, f) = cube(DVec3::ZERO, DVec3::ONE);
        assert!(MeshCollider::new(v.clone(), f.clone()).unwrap().is_closed());
        let (qv, qf) = quad();
        assert!(!MeshCollider::new(qv, qf).unwrap().is_closed());
        // One face removed.
        let open: Vec<[u32; 3]> = f[2..].to_vec();
        assert!(!MeshCollider::new(v.clone(), open).unwrap().is_closed());
        // One face flipped: every edge shared twice, but not consistently oriented.
        let mut flipped = f.clone();
        flipped[0].swap(1, 2);
        flipped[1].swap(1, 2);
        assert!(!MeshCollider::new(v.clone(), flipped).unwrap().is_closed());
        // Split corners (every triangle with its own three positions) are welded back.
        let split: Vec<DVec3> = f.iter().flat_map(|t| t.map(|i| v[i as usize])).collect();
        let split_tris: Vec<[u32; 3]> = (0..f.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
        let welded = MeshCollider::new(split, split_tris).unwrap();
        assert!(welded.is_closed());
        let s = welded
            .contact(DVec3::splat(0.5), DVec3::splat(0.5), 0.0)
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, -0.5, epsilon = 1e-12);
    }

    #[test]
    fn bad_input_is_refused_with_the_element() {
        let (v, f) = quad();
        let mut nan = v.clone();
        nan[2].y = f64::NAN;
        let e = MeshCollider::new(nan, f.clone()).unwrap_err();
        assert!(matches!(
            e,
            Error::ColliderMesh {
                path: None,
                problem: ColliderMeshProblem::NonFinitePosition { index: 2 }
            }
        ));
        let e = MeshCollider::new(v.clone(), vec![[0, 1, 2], [0, 2, 9]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "collider mesh: triangle 1 refers to position 9, but there are 4 positions"
        );
        // Degenerate triangles are dropped; none left is an error.
        let m = MeshCollider::new(v.clone(), vec![[0, 1, 2], [0, 0, 1]]).unwrap();
        assert_eq!(m.triangles(), &[[0, 1, 2]]);
        let collinear = vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        let e = MeshCollider::new(collinear, vec![[0, 1, 2], [1, 1, 2]]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "collider mesh: no triangle of non-zero area (2 degenerate triangles dropped)"
        );
        assert!(MeshCollider::new(v, Vec::new()).is_err());
    }

    #[test]
    fn from_obj_loads_the_table_and_names_bad_files() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/table.obj");
        let from_obj = |path: &Path| {
            let mesh = crate::io::obj::load_obj(path, &Default::default())?;
            MeshCollider::from_mesh(path, mesh.positions, mesh.triangles)
        };
        let m = from_obj(&path).unwrap();
        assert!(m.is_closed());
        let (lo, hi) = m.bounds();
        approx::assert_abs_diff_eq!(hi.y, 0.75, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(lo.y, 0.0, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(hi.x - lo.x, 1.2, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(hi.z - lo.z, 0.8, epsilon = 1e-9);
        // Coming down from above and already past the top slab's middle: still pushed back up
        // through the top it entered by.
        let s = m
            .contact(DVec3::new(0.1, 0.715, 0.1), DVec3::new(0.1, 0.8, 0.1), 0.05)
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, -0.035, epsilon = 1e-9);
        assert_close(s.normal, DVec3::Y, 1e-9);
        // Resting on the top, 1 cm above, and inside the top slab.
        let s = m
            .contact(DVec3::new(0.1, 0.76, 0.1), DVec3::new(0.1, 0.76, 0.1), 0.05)
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, 0.01, epsilon = 1e-9);
        assert_close(s.normal, DVec3::Y, 1e-9);
        let s = m
            .contact(DVec3::new(0.1, 0.74, 0.1), DVec3::new(0.1, 0.74, 0.1), 0.05)
            .unwrap();
        approx::assert_abs_diff_eq!(s.distance, -0.01, epsilon = 1e-9);
        // Under the table, between the legs, far from everything: nothing.
        assert_eq!(
            m.contact(DVec3::new(0.0, 0.3, 0.0), DVec3::new(0.0, 0.3, 0.0), 0.05),
            None
        );

        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.obj");
        std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
        let e = from_obj(&bad).unwrap_err();
        assert!(e.to_string().contains("bad.obj"), "{e}");
    }

    /// The shipped table, `meshes/table.obj`: a 1.2 × 0.8 m top, 4 cm thick, at 0.75 m, on four
    /// 5 cm square legs that end 1 mm under the top (disjoint closed boxes keep the sign test
    /// unambiguous). Run with `SCENEBAKE_WRITE_TABLE=1` to rewrite the file.
    #[test]
    fn table_obj_is_current() {
        let mut boxes = vec![(DVec3::new(-0.6, 0.71, -0.4), DVec3::new(0.6, 0.75, 0.4))];
        for (x, z) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let centre = DVec3::new(x * 0.52, 0.0, z * 0.32);
            boxes.push((
                centre + DVec3::new(-0.025, 0.0, -0.025),
                centre + DVec3::new(0.025, 0.709, 0.025),
            ));
        }
        let mut text = String::from(
            "# scenebake table collider: 1.2 x 0.8 m top at 0.75 m, four legs; metres, y up.\n\
             # Our own work, CC0. Regenerate: SCENEBAKE_WRITE_TABLE=1 cargo test table_obj\n",
        );
        for (k, (lo, hi)) in boxes.iter().enumerate() {
            let (v, f) = cube(*lo, *hi);
            text += &format!(
                "o {}\n",
                if k == 0 {
                    "top".into()
                } else {
                    format!("leg{k}")
                }
            );
            for p in v {
                text += &format!("v {} {} {}\n", p.x, p.y, p.z);
            }
            for t in f {
                let [a, b, c] = t.map(|i| i as usize + 1 + 8 * k);
                text += &format!("f {a} {b} {c}\n");
            }
        }
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/table.obj");
        if std::env::var_os("SCENEBAKE_WRITE_TABLE").is_some() {
            std::fs::write(&path, &text).unwrap();
        }
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    }
}
