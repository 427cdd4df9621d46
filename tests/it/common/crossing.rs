//! Crossing triangles by an exact test of every pair (no broad phase beyond bounding boxes),
//! independent of scenebake's own count (`src/measure`): edges of one triangle through the
//! other, with Shewchuk's exact orientation signs (the `robust` crate).

use std::collections::HashMap;
use std::path::Path;

use glam::{DVec3, Vec3};
use robust::{orient3d, Coord3D};

/// The `v` lines (in file order, as point caches hold them) and the triangles of the `f` lines
/// (corners `v`, `v/vt` or `v/vt/vn`, 1-based) of a triangulated OBJ: a soup for the exact tests
/// below, read without scenebake's loader.
pub fn obj_soup(path: &Path) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut points = Vec::new();
    let mut triangles = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let v: Vec<f32> = words.take(3).map(|w| w.parse().unwrap()).collect();
                points.push(Vec3::new(v[0], v[1], v[2]));
            }
            Some("f") => {
                let f: Vec<u32> = words
                    .map(|w| w.split('/').next().unwrap().parse::<u32>().unwrap() - 1)
                    .collect();
                assert_eq!(
                    f.len(),
                    3,
                    "{}: a face of {} corners",
                    path.display(),
                    f.len()
                );
                triangles.push([f[0], f[1], f[2]]);
            }
            _ => {}
        }
    }
    (points, triangles)
}

/// The welded triangles of a render surface: render vertices at bit-identical positions (UV
/// seams) become one vertex, so adjacency is the cloth's own.
pub fn weld(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut first: HashMap<[u32; 3], u32> = HashMap::new();
    let id: Vec<u32> = positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            *first
                .entry(p.to_array().map(f32::to_bits))
                .or_insert(i as u32)
        })
        .collect();
    triangles
        .iter()
        .map(|t| t.map(|i| id[i as usize]))
        .collect()
}

pub fn o3(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    let k = |p: DVec3| Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    };
    orient3d(k(a), k(b), k(c), k(d))
}

/// Triangles s and t meet: some edge of one passes through the other (Möller's formulation:
/// the edge's ends on opposite sides of, or on, the other's plane, and its line on the inner
/// side of the other's three edges).
pub fn meet(s: [DVec3; 3], t: [DVec3; 3]) -> bool {
    let edge_through = |p: DVec3, q: DVec3, [a, b, c]: [DVec3; 3]| {
        let (sp, sq) = (o3(a, b, c, p).signum(), o3(a, b, c, q).signum());
        let sp = if o3(a, b, c, p) == 0.0 { 0.0 } else { sp };
        let sq = if o3(a, b, c, q) == 0.0 { 0.0 } else { sq };
        if sp * sq > 0.0 || (sp == 0.0 && sq == 0.0) {
            return false;
        }
        let w = [o3(p, q, a, b), o3(p, q, b, c), o3(p, q, c, a)];
        let pos = w.iter().filter(|&&x| x > 0.0).count();
        let neg = w.iter().filter(|&&x| x < 0.0).count();
        (pos == 0 || neg == 0) && pos + neg > 0
    };
    (0..3).any(|k| edge_through(s[k], s[(k + 1) % 3], t))
        || (0..3).any(|k| edge_through(t[k], t[(k + 1) % 3], s))
}

pub fn bounds(t: &[DVec3; 3]) -> (DVec3, DVec3) {
    (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))
}

pub fn overlap(a: &(DVec3, DVec3), b: &(DVec3, DVec3)) -> bool {
    a.0.cmple(b.1).all() && b.0.cmple(a.1).all()
}

pub fn corners(p: &[Vec3], t: &[u32; 3]) -> [DVec3; 3] {
    t.map(|i| p[i as usize].as_dvec3())
}

/// Every pair of triangles of `tris` sharing no vertex that meet.
pub fn brute_self(p: &[Vec3], tris: &[[u32; 3]]) -> usize {
    let c: Vec<[DVec3; 3]> = tris.iter().map(|t| corners(p, t)).collect();
    let b: Vec<_> = c.iter().map(bounds).collect();
    let mut n = 0;
    for i in 0..tris.len() {
        for j in i + 1..tris.len() {
            if overlap(&b[i], &b[j])
                && !tris[i].iter().any(|v| tris[j].contains(v))
                && meet(c[i], c[j])
            {
                n += 1;
            }
        }
    }
    n
}

/// Every pair (triangle of a, triangle of b) that meet.
pub fn brute_between(pa: &[Vec3], ta: &[[u32; 3]], pb: &[Vec3], tb: &[[u32; 3]]) -> usize {
    let ca: Vec<[DVec3; 3]> = ta.iter().map(|t| corners(pa, t)).collect();
    let cb: Vec<[DVec3; 3]> = tb.iter().map(|t| corners(pb, t)).collect();
    let ba: Vec<_> = ca.iter().map(bounds).collect();
    let bb: Vec<_> = cb.iter().map(bounds).collect();
    let mut n = 0;
    for i in 0..ca.len() {
        for j in 0..cb.len() {
            if overlap(&ba[i], &bb[j]) && meet(ca[i], cb[j]) {
                n += 1;
            }
        }
    }
    n
}

pub fn cloth_triangles(path: &Path) -> Vec<[u32; 3]> {
    let (doc, buffers, _) = super::gltf_read::import(path).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let r = prim.reader(|b| Some(&buffers[b.index()]));
    let i: Vec<u32> = r.read_indices().unwrap().into_u32().collect();
    i.chunks(3).map(|c| [c[0], c[1], c[2]]).collect()
}
