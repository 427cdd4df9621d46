//! The base NORMAL of a morph-target cache, chosen so importers shade the cloth smooth.
//!
//! Importers that turn morph targets into shape keys (Blender's, 3.4 to 5.x) ignore the targets'
//! NORMAL deltas: they shade the deformed surface with normals they recompute, smooth or flat per
//! face. Blender decides per face from the base NORMAL: a face all of whose corner normals equal
//! its own face normal (dot product above 0.9999999) is imported flat. A cloth that starts as a
//! flat sheet has exactly such normals, so every face would stay flat (faceted) through the whole
//! animation.
//!
//! [`base_normals`] therefore leans the frame-0 normal of each such vertex by [`LEAN_DEGREES`]
//! (towards the side its normal turns to during the bake, if it turns), so every face imports
//! smooth and Blender's recomputed normals follow the baked shape. The targets' NORMAL deltas
//! ([`normal_deltas`]) are taken from these base normals, so viewers that apply them (three.js,
//! game engines) get each baked frame's exact normals, except where a vertex's normal is still
//! exactly its frame-0 normal: there the delta stays zero (so still regions stay sparse) and the
//! viewer shows the lean, far below what shading can show.

use glam::{DVec3, Vec3};

use super::frames::RenderFrames;
use crate::mesh::Mesh;

/// How far a flat vertex's base normal is leaned, degrees (Blender's flat test needs > 0.026°).
pub const LEAN_DEGREES: f64 = 0.25;

/// A vertex whose normal is within this angle of every adjacent face normal is "flat", degrees.
const FLAT_DEGREES: f64 = 0.1;

/// The base (frame 0) NORMAL for a morph cache of `frames` over `mesh`'s render surface: the
/// frame-0 normals, with the vertices that would make their faces import flat (see the module
/// docs) leaned by [`LEAN_DEGREES`]. Unit vectors, one per render vertex.
pub fn base_normals(mesh: &Mesh, frames: &RenderFrames) -> Vec<Vec3> {
    // The sum of each vertex's normals over the bake (frame by frame, in memory order).
    let count = frames.vertex_count();
    let mut turns = vec![DVec3::ZERO; count];
    for k in 1..frames.frame_count() {
        for (t, n) in turns.iter_mut().zip(frames.normals(k)) {
            *t += n.as_dvec3();
        }
    }
    lean_flat_normals(
        &mesh.render_triangles,
        frames.positions(0),
        frames.normals(0),
        &turns,
        frames.frame_count(),
    )
}

/// `normals` (unit, one per vertex of `positions`) with the vertices that would make their faces
/// import flat in Blender leaned by [`LEAN_DEGREES`]: every vertex within [`FLAT_DEGREES`] of all
/// its faces' normals, then any vertex of a face that Blender's test (every corner's dot product
/// with the face normal above [`BLENDER_FLAT_DOT`]) would still find flat, with a tenfold margin
/// for rounding. Each lean goes towards the
/// tangent part of the vertex's `turns` (a sum of `samples` unit normals over the bake: where
/// the normal turns to), or any tangent direction when that is about zero. Face normals come
/// from the f32 `positions` an importer reads (any uniform scale and translation).
pub fn lean_flat_normals(
    triangles: &[[u32; 3]],
    positions: &[Vec3],
    normals: &[Vec3],
    turns: &[DVec3],
    samples: usize,
) -> Vec<Vec3> {
    let count = normals.len();
    let face = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| positions[i as usize].as_dvec3());
        (b - a).cross(c - a).try_normalize()
    };
    // Largest angle (as the smallest cosine) between each vertex normal and its faces' normals.
    let mut min_cos = vec![1.0f64; count];
    let mut touched = vec![false; count];
    for t in triangles {
        let Some(face) = face(t) else {
            continue;
        };
        for &i in t {
            let i = i as usize;
            touched[i] = true;
            min_cos[i] = min_cos[i].min(face.dot(normals[i].as_dvec3()));
        }
    }
    let flat_cos = FLAT_DEGREES.to_radians().cos();
    let lean = LEAN_DEGREES.to_radians().tan();
    let leaned = |v: usize| {
        let n = normals[v].as_dvec3();
        // The direction the normal turns to over the bake, in the tangent plane.
        let turn = turns.get(v).copied().unwrap_or(DVec3::ZERO);
        let mut tangent = turn - n * turn.dot(n);
        if tangent.length() < 1e-9 * (samples.max(1) as f64) {
            // Never turns: any direction will do (the face shades the same either way).
            tangent = n.any_orthonormal_vector();
        }
        (n + tangent.normalize() * lean).normalize().as_vec3()
    };
    let mut out: Vec<Vec3> = (0..count)
        .map(|v| {
            if !touched[v] || min_cos[v] < flat_cos {
                normals[v]
            } else {
                leaned(v)
            }
        })
        .collect();
    let mut done: Vec<bool> = (0..count).map(|v| out[v] != normals[v]).collect();
    for t in triangles {
        let Some(face) = face(t) else {
            continue;
        };
        if t.iter()
            .all(|&i| out[i as usize].as_dvec3().dot(face) > 1.0 - 10.0 * (1.0 - BLENDER_FLAT_DOT))
        {
            for &i in t {
                let i = i as usize;
                if !done[i] {
                    out[i] = leaned(i);
                    done[i] = true;
                }
            }
        }
    }
    out
}

/// Blender's importer (io_scene_gltf2 `set_poly_smoothing`) imports a face flat when every
/// corner normal's dot product with the face normal is above this.
pub const BLENDER_FLAT_DOT: f64 = 0.999_999_9;

/// Corner-angle-weighted unit vertex normals of a triangle soup over `positions` (+Y where a
/// vertex touches no triangle of non-zero area): each triangle's unit normal counts with the
/// angle of its corner at the vertex. This is how Blender (3.4 to 5.x) computes the normals it
/// shades with, and it does not depend on how a surface is triangulated; writing the same
/// normals makes every viewer shade a baked frame alike.
pub fn angle_weighted_normals(positions: &[DVec3], triangles: &[[u32; 3]], out: &mut Vec<DVec3>) {
    out.clear();
    out.resize(positions.len(), DVec3::ZERO);
    for t in triangles {
        let p = t.map(|i| positions[i as usize]);
        // Edges e[c] = p[c+1] − p[c], normalised once; the corner angles sum to π, so two acos
        // give all three.
        let e = [p[1] - p[0], p[2] - p[1], p[0] - p[2]];
        let Some(n) = e[0].cross(-e[2]).try_normalize() else {
            continue;
        };
        let (Some(u0), Some(u1), Some(u2)) = (
            e[0].try_normalize(),
            e[1].try_normalize(),
            e[2].try_normalize(),
        ) else {
            continue;
        };
        let a0 = (-u2.dot(u0)).clamp(-1.0, 1.0).acos();
        let a1 = (-u0.dot(u1)).clamp(-1.0, 1.0).acos();
        let a2 = (std::f64::consts::PI - a0 - a1).max(0.0);
        out[t[0] as usize] += n * a0;
        out[t[1] as usize] += n * a1;
        out[t[2] as usize] += n * a2;
    }
    for n in out.iter_mut() {
        *n = n.try_normalize().unwrap_or(DVec3::Y);
    }
}

/// The NORMAL deltas of a target: `normals - base` per vertex, except 0 where `normals` equals
/// `frame0` exactly (the vertex keeps its base normal, leaned by at most [`LEAN_DEGREES`]).
pub fn normal_deltas(normals: &[Vec3], frame0: &[Vec3], base: &[Vec3]) -> Vec<Vec3> {
    normals
        .iter()
        .zip(frame0)
        .zip(base)
        .map(|((n, n0), b)| if n == n0 { Vec3::ZERO } else { *n - *b })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::FrameCache;

    /// A 3×3-vertex sheet in y = 0 whose middle row rises by `lift` from frame 1 on.
    fn sheet(lift: f32) -> (Mesh, RenderFrames) {
        let mut positions = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                positions.push(DVec3::new(i as f64, 0.0, j as f64));
            }
        }
        let mut triangles = Vec::new();
        for i in 0..2u32 {
            for j in 0..2u32 {
                let a = i * 3 + j;
                triangles.push([a, a + 1, a + 3]);
                triangles.push([a + 1, a + 4, a + 3]);
            }
        }
        let mesh = Mesh::from_triangles("s".into(), positions.clone(), triangles);
        let mut cache = FrameCache::new(9);
        let f0: Vec<DVec3> = positions.clone();
        cache.push(&f0);
        let f1: Vec<DVec3> = positions
            .iter()
            .map(|p| *p + DVec3::Y * f64::from(lift) * f64::from(u8::from(p.x == 1.0)))
            .collect();
        cache.push(&f1);
        let frames = RenderFrames::new(&mesh, &cache);
        (mesh, frames)
    }

    /// Blender's test (io_scene_gltf2 `set_poly_smoothing`): a face is smooth when some corner
    /// normal's dot product with the face normal is at most 0.9999999.
    fn smooth_faces(mesh: &Mesh, positions: &[Vec3], normals: &[Vec3]) -> usize {
        mesh.render_triangles
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|i| positions[i as usize]);
                let face = (b - a).cross(c - a).normalize();
                t.iter()
                    .any(|&i| normals[i as usize].dot(face) <= 0.999_999_9)
            })
            .count()
    }

    #[test]
    fn a_flat_sheet_that_bends_imports_smooth_and_leans_by_the_stated_angle() {
        let (mesh, frames) = sheet(0.5);
        assert_eq!(
            smooth_faces(&mesh, frames.positions(0), frames.normals(0)),
            0
        );
        let base = base_normals(&mesh, &frames);
        assert_eq!(
            smooth_faces(&mesh, frames.positions(0), &base),
            mesh.render_triangles.len()
        );
        for (b, n) in base.iter().zip(frames.normals(0)) {
            let angle = f64::from(b.dot(*n).min(1.0)).acos().to_degrees();
            assert!(angle < LEAN_DEGREES + 0.01, "{angle}");
            assert!((b.length() - 1.0).abs() < 1e-6);
        }
        // Leaned towards where the normal turns: the sheet's edge rows tilt towards ±x as the
        // middle row rises, so their base normals gain the same sign of x.
        for (v, rv) in mesh.render_vertices.iter().enumerate() {
            let turned = frames.normals(1)[v].x;
            if mesh.positions[rv.particle as usize].x != 1.0 && turned.abs() > 1e-3 {
                assert_eq!(base[v].x.signum(), turned.signum());
            }
        }
    }

    #[test]
    fn angle_weights_ignore_how_a_face_is_split() {
        // A unit cube's corner: three faces, one of them split into two triangles at the
        // corner. Area weighting tilts the normal towards the split face; angle weighting gives
        // the symmetric (1,1,1)/√3 whatever the split.
        let p = vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::new(1.0, 1.0, 0.0),
        ];
        // Faces with outward normals -z (split at the corner into two), -x, -y.
        let tris = [[0, 2, 4], [0, 4, 1], [0, 3, 2], [0, 1, 3]];
        let mut out = Vec::new();
        angle_weighted_normals(&p, &tris, &mut out);
        let want = -DVec3::ONE.normalize();
        assert!(out[0].distance(want) < 1e-12, "{}", out[0]);
    }

    #[test]
    fn a_sheet_that_never_deforms_still_imports_smooth() {
        let (mesh, frames) = sheet(0.0);
        let base = base_normals(&mesh, &frames);
        assert_eq!(
            smooth_faces(&mesh, frames.positions(0), &base),
            mesh.render_triangles.len()
        );
    }
}
