//! Compact morph caches: keyframe reduction and sparse morph-target deltas.
//!
//! **Keyframe reduction** (`--keyframe-tolerance T`). A greedy forward scan over the baked frames:
//! starting from a kept frame `a`, the segment is extended to `b = a+2, a+3, ...` while every
//! skipped frame `a < k < b` is reproduced within `T` (the largest distance over all render
//! vertices, scene units) by what the player computes between the kept frames `a` and `b`. With
//! LINEAR weights that is the blend `base + (1-t)·Δa + t·Δb`, `t = (k-a)/(b-a)`, of the stored
//! deltas (frame 0 is the base, its delta zero); with STEP weights it is frame `a` held. The first
//! extension that fails ends the segment at the last good `b`, which is kept; the first and last
//! frames are always kept. Cost: O(N·L·V) for N frames, segments of L frames and V vertices.
//!
//! **Sparse deltas** (`--sparse auto`). A morph-target accessor whose vertices mostly do not move
//! (pinned regions, cloth at rest) is written as a glTF sparse accessor with no buffer view (the
//! base is zeros) plus the strictly increasing indices of the changed vertices and their values,
//! whenever that takes fewer bytes than the dense array. A vertex is unchanged when its delta is
//! exactly zero in `f32`.

use glam::{DVec3, Vec3};
use gltf_json as json;

use super::frames::RenderFrames;
use super::gltf_doc::GltfBuilder;
use super::morph::Interpolation;

/// Whether morph-target deltas may be written as sparse accessors (`--sparse`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SparseMode {
    /// Sparse where it is smaller than dense.
    #[default]
    Auto,
    /// Always dense (a basis cache then writes no normal targets; its `normal_offset`
    /// target's zero POSITION stays a one-entry sparse accessor).
    Off,
}

/// The frames a keyframe reduction keeps.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyframeSelection {
    /// Kept frame numbers, increasing, starting at 0 and ending at the last frame.
    pub kept: Vec<usize>,
    /// Largest distance (scene units) between a dropped frame as played back and as baked, over
    /// every render vertex and dropped frame; 0 when nothing was dropped.
    pub max_error: f64,
}

impl KeyframeSelection {
    /// Keeps every frame of a cache of `frames` frames.
    pub fn all(frames: usize) -> Self {
        KeyframeSelection {
            kept: (0..frames).collect(),
            max_error: 0.0,
        }
    }
}

/// Chooses the frames to keep so that playback with `interpolation` reproduces every frame of
/// `frames` within `tolerance` (scene units), by the greedy forward scan described in the module
/// documentation.
pub fn select_keyframes(
    frames: &RenderFrames,
    tolerance: f64,
    interpolation: Interpolation,
) -> KeyframeSelection {
    let last = frames.frame_count().saturating_sub(1);
    let mut kept = vec![0];
    let mut max_error = 0.0f64;
    let mut a = 0;
    while a < last {
        let (mut b, mut err) = (a + 1, 0.0);
        for candidate in a + 2..=last {
            match segment_error(frames, a, candidate, tolerance, interpolation) {
                Some(e) => (b, err) = (candidate, e),
                None => break,
            }
        }
        kept.push(b);
        max_error = max_error.max(err);
        a = b;
    }
    KeyframeSelection { kept, max_error }
}

/// The largest playback error over the frames strictly between `a` and `b` when only `a` and `b`
/// are kept, or `None` as soon as it exceeds `tolerance`.
fn segment_error(
    frames: &RenderFrames,
    a: usize,
    b: usize,
    tolerance: f64,
    interpolation: Interpolation,
) -> Option<f64> {
    let base = frames.positions(0);
    let (pa, pb) = (frames.positions(a), frames.positions(b));
    let mut worst = 0.0f64;
    for k in a + 1..b {
        let t = (k - a) as f64 / (b - a) as f64;
        for (v, want) in frames.positions(k).iter().enumerate() {
            let got = played_back(base[v], pa[v], pb[v], t, interpolation);
            let e = got.distance(want.as_dvec3());
            if e > tolerance {
                return None;
            }
            worst = worst.max(e);
        }
    }
    Some(worst)
}

/// What a player shows at fraction `t` between kept positions `pa` and `pb`, computed as the file
/// stores them: the base plus weighted `f32` deltas.
fn played_back(base: Vec3, pa: Vec3, pb: Vec3, t: f64, interpolation: Interpolation) -> DVec3 {
    let (da, db) = ((pa - base).as_dvec3(), (pb - base).as_dvec3());
    match interpolation {
        Interpolation::Linear => base.as_dvec3() + (1.0 - t) * da + t * db,
        Interpolation::Step => base.as_dvec3() + da,
    }
}

/// How one morph-target accessor was stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeltaEncoding {
    /// A plain array of one value per vertex.
    Dense,
    /// A sparse accessor listing the changed vertices.
    Sparse,
}

/// Bytes the JSON of a sparse accessor and its second buffer view add over a dense one (an
/// estimate, so that a sparse accessor must save more than it costs).
pub const SPARSE_JSON_OVERHEAD: usize = 160;

/// Indices of the vertices whose delta is not exactly zero, increasing.
pub fn changed_vertices(delta: &[Vec3]) -> Vec<u32> {
    delta
        .iter()
        .enumerate()
        .filter(|(_, d)| **d != Vec3::ZERO)
        .map(|(i, _)| i as u32)
        .collect()
}

/// Binary bytes of a sparse VEC3 float accessor with `changed` entries over `vertices` vertices:
/// indices (u16 when every index fits, else u32) and values, each padded to 4 bytes.
pub fn sparse_bytes(changed: usize, vertices: usize) -> usize {
    let index = if vertices <= 1 << 16 { 2 } else { 4 };
    (changed * index).next_multiple_of(4) + changed * 12
}

/// Binary bytes of a dense VEC3 float accessor.
pub fn dense_bytes(vertices: usize) -> usize {
    vertices * 12
}

/// Writes one morph-target delta accessor (VEC3 float), sparse when `mode` allows it and it is
/// smaller. `min_max` writes bounds, which for a sparse accessor cover the implicit zeros too.
pub fn delta_accessor(
    b: &mut GltfBuilder,
    delta: &[Vec3],
    mode: SparseMode,
    min_max: bool,
) -> (json::Index<json::Accessor>, DeltaEncoding) {
    let array = Some(json::buffer::Target::ArrayBuffer);
    if mode == SparseMode::Off {
        return (b.vec3(delta, array, min_max), DeltaEncoding::Dense);
    }
    let mut changed = changed_vertices(delta);
    // A sparse accessor lists at least one entry: an unmoved target lists vertex 0's zero.
    if changed.is_empty() && !delta.is_empty() {
        changed.push(0);
    }
    if sparse_bytes(changed.len(), delta.len()) + SPARSE_JSON_OVERHEAD < dense_bytes(delta.len()) {
        (
            b.sparse_vec3(delta, &changed, min_max),
            DeltaEncoding::Sparse,
        )
    } else {
        (b.vec3(delta, array, min_max), DeltaEncoding::Dense)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::FrameCache;
    use crate::mesh::Mesh;

    /// Two particles, one triangle's worth of render vertices, moving along x by `xs[k]`.
    fn frames_of(xs: &[f64]) -> RenderFrames {
        let positions = vec![glam::DVec3::ZERO, glam::DVec3::Y, glam::DVec3::Z];
        let mesh = Mesh::from_triangles("t".into(), positions.clone(), vec![[0, 1, 2]]);
        let mut cache = FrameCache::new(3);
        for x in xs {
            let f: Vec<_> = positions.iter().map(|p| *p + glam::DVec3::X * *x).collect();
            cache.push(&f);
        }
        RenderFrames::new(&mesh, &cache)
    }

    #[test]
    fn linear_motion_keeps_only_the_ends() {
        let f = frames_of(&[0.0, 1.0, 2.0, 3.0, 4.0]);
        let s = select_keyframes(&f, 1e-6, Interpolation::Linear);
        assert_eq!(s.kept, vec![0, 4]);
        assert!(s.max_error < 1e-6);
    }

    #[test]
    fn a_kink_is_kept_and_the_error_is_measured() {
        let f = frames_of(&[0.0, 1.0, 2.0, 2.0, 2.0]);
        let s = select_keyframes(&f, 1e-6, Interpolation::Linear);
        assert_eq!(s.kept, vec![0, 2, 4]);
        let loose = select_keyframes(&f, 1.0, Interpolation::Linear);
        assert_eq!(loose.kept, vec![0, 4]);
        // Frame 2 played back as the blend 2·(2/4) = 1 instead of 2.
        assert!((loose.max_error - 1.0).abs() < 1e-9, "{}", loose.max_error);
    }

    #[test]
    fn step_playback_holds_the_earlier_frame() {
        let f = frames_of(&[0.0, 0.0, 0.5, 0.5, 3.0]);
        assert_eq!(
            select_keyframes(&f, 0.0, Interpolation::Step).kept,
            vec![0, 2, 4]
        );
    }

    #[test]
    fn zero_tolerance_and_short_caches() {
        assert_eq!(
            select_keyframes(&frames_of(&[0.0]), 0.0, Interpolation::Linear).kept,
            vec![0]
        );
        assert_eq!(
            select_keyframes(&frames_of(&[0.0, 1.0]), 0.0, Interpolation::Linear).kept,
            vec![0, 1]
        );
    }

    #[test]
    fn sparse_sizes_and_changed_vertices() {
        let d = [Vec3::ZERO, Vec3::X, Vec3::new(-0.0, 0.0, 0.0), Vec3::Y];
        assert_eq!(changed_vertices(&d), vec![1, 3]);
        assert_eq!(sparse_bytes(3, 100), 8 + 36);
        assert_eq!(sparse_bytes(3, 70_000), 12 + 36);
        assert_eq!(dense_bytes(100), 1200);
    }
}
