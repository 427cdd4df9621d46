//! Compact caches: keyframe reduction (`--keyframe-tolerance`) and sparse morph targets
//! (`--sparse`), checked with an independent reader (the `gltf` crate) and our own weight sampler.

use crate::common;

use std::path::Path;

use common::mesh_path;
use common::morph::{load_morph, max_distance, reference, reference_positions};
use scenebake::bake::cloth::{bake_cloth, ClothJob, ClothSource};
use scenebake::cloth::FrameCache;
use scenebake::export::{write_morph_gltf, Interpolation, MorphOptions, SparseMode};
use scenebake::glam::{DVec3, Vec3};
use scenebake::mesh::Mesh;

/// Slack for f32 rounding between the writer's error measure (f64 over f32 deltas) and a
/// player's f32 blend; far below any tolerance a user would ask for.
const ROUNDING: f32 = 2e-6;

fn lab_job(out: &Path, frames: usize) -> ClothJob {
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 10 }, out.to_path_buf());
    job.frames = Some(frames);
    job
}

/// Plane 30×30 (961 vertices, y = 0, 1 m square) with the half z ≤ 0 pinned: half of every
/// position delta is exactly zero.
fn half_pinned_plane(out: &Path, frames: usize) -> ClothJob {
    let mut job = ClothJob::new(
        ClothSource::File(mesh_path("plane_30x30.obj")),
        out.to_path_buf(),
    );
    job.frames = Some(frames);
    job.pin = vec!["box:-1,-1,-1,1,1,0.0".parse().unwrap()];
    job
}

#[test]
fn keyframe_reduction_stays_within_tolerance_at_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let frames = 120;
    let tolerance = 1e-3;
    let mut job = lab_job(&out, frames);
    job.keyframe_tolerance = Some(tolerance);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let cache = &report.cache;
    let kept = &cache.stats.kept_frames;
    assert_eq!(kept[0], 0, "frame 0 kept");
    assert_eq!(*kept.last().unwrap(), frames, "last frame kept");
    assert!(kept.windows(2).all(|w| w[0] < w[1]));
    assert!(
        kept.len() < frames / 2,
        "a slow cloth compresses: kept {kept:?}"
    );
    assert_eq!(cache.stats.targets, kept.len() - 1);
    assert!(
        cache.stats.max_interpolation_error <= tolerance
            && cache.stats.max_interpolation_error > 0.0
    );
    assert_eq!(cache.keyframe_tolerance, Some(tolerance));

    let (mesh, sim) = reference(&job);
    let m = load_morph(&out);
    assert_eq!(m.targets(), kept.len() - 1);
    let fps = report.fps;
    // Keys sit at the kept frames' true times.
    assert_eq!(m.times.len(), kept.len());
    for (t, k) in m.times.iter().zip(kept) {
        assert_eq!(*t, (*k as f64 / fps) as f32);
    }
    let mut worst = 0.0f32;
    for k in 0..=frames {
        let t = (k as f64 / fps) as f32;
        let got = m.positions_at(t);
        let want = reference_positions(&mesh, &sim, k);
        let d = max_distance(&got, &want);
        assert!(d <= tolerance as f32 + ROUNDING, "frame {k}: {d} m off");
        worst = worst.max(d);
    }
    // The report's figure is the error actually measured.
    assert!(
        (worst - cache.stats.max_interpolation_error as f32).abs() < 1e-5,
        "{worst} vs {}",
        cache.stats.max_interpolation_error
    );
}

#[test]
fn step_interpolation_reduction_holds_frames_within_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let frames = 40;
    let tolerance = 2e-3;
    let mut job = lab_job(&out, frames);
    job.keyframe_tolerance = Some(tolerance);
    job.interpolation = Interpolation::Step;
    job.normals = scenebake::bake::cloth::Switch::Off;
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert!(report.cache.stats.kept_frames.len() < frames + 1);
    let (mesh, sim) = reference(&job);
    let m = load_morph(&out);
    assert!(!m.linear);
    for k in 0..=frames {
        let got = m.positions_at((k as f64 / report.fps) as f32);
        let d = max_distance(&got, &reference_positions(&mesh, &sim, k));
        assert!(d <= tolerance as f32 + ROUNDING, "frame {k}: {d}");
    }
}

#[test]
fn without_tolerance_every_frame_is_a_target() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let report = bake_cloth(&lab_job(&out, 10), &mut |_, _| {}).unwrap();
    assert_eq!(report.cache.stats.kept_frames, (0..=10).collect::<Vec<_>>());
    assert_eq!(report.cache.stats.targets, 10);
    assert_eq!(report.cache.stats.max_interpolation_error, 0.0);
    assert_eq!(
        report.cache.gltf_bytes,
        std::fs::metadata(&out).unwrap().len()
    );
}

#[test]
fn sparse_and_dense_files_give_identical_positions_and_sparse_is_smaller() {
    let dir = tempfile::tempdir().unwrap();
    let dense_out = dir.path().join("dense.glb");
    let sparse_out = dir.path().join("sparse.glb");
    let mut dense = half_pinned_plane(&dense_out, 20);
    dense.sparse = SparseMode::Off;
    let sparse = half_pinned_plane(&sparse_out, 20);
    let rd = bake_cloth(&dense, &mut |_, _| {}).unwrap();
    let rs = bake_cloth(&sparse, &mut |_, _| {}).unwrap();
    assert_eq!(rd.cache.stats.sparse_accessors, 0);
    assert!(
        rs.cache.stats.sparse_accessors >= 20,
        "every POSITION delta is half zeros: {:?}",
        rs.cache.stats
    );

    let d = load_morph(&dense_out);
    let s = load_morph(&sparse_out);
    assert_eq!(d.base, s.base);
    assert_eq!(d.targets(), s.targets());
    for j in 0..d.targets() {
        assert_eq!(d.deltas[j], s.deltas[j], "POSITION delta of target {j}");
        assert_eq!(
            d.normal_deltas[j], s.normal_deltas[j],
            "NORMAL delta of target {j}"
        );
    }
    assert_eq!(
        (d.times.clone(), d.weights.clone()),
        (s.times.clone(), s.weights.clone())
    );

    let dense_bytes = std::fs::metadata(&dense_out).unwrap().len();
    let sparse_bytes = std::fs::metadata(&sparse_out).unwrap().len();
    assert!(
        sparse_bytes * 10 < dense_bytes * 8,
        "sparse {sparse_bytes} B vs dense {dense_bytes} B"
    );
    assert!(rs.cache.stats.target_bytes < rd.cache.stats.target_bytes);
}

#[test]
fn sparse_accessors_follow_the_spec() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sparse.gltf");
    bake_cloth(&half_pinned_plane(&out, 8), &mut |_, _| {}).unwrap();
    let (doc, buffers, _) = common::gltf_read::import(&out).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let deltas: Vec<Vec<[f32; 3]>> = reader
        .read_morph_targets()
        .map(|(p, _, _)| p.unwrap().collect())
        .collect();
    let mut seen = 0;
    for (target, delta) in prim.morph_targets().zip(&deltas) {
        let acc = target.positions().unwrap();
        // min/max cover the effective values, implicit zeros included.
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for v in delta {
            for i in 0..3 {
                lo[i] = lo[i].min(v[i]);
                hi[i] = hi[i].max(v[i]);
            }
        }
        let as_f32 = |v: serde_json::Value| -> Vec<f32> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap() as f32)
                .collect()
        };
        assert_eq!(as_f32(acc.min().unwrap()), lo.to_vec());
        assert_eq!(as_f32(acc.max().unwrap()), hi.to_vec());
        let Some(sparse) = acc.sparse() else { continue };
        seen += 1;
        assert!(acc.view().is_none(), "zeros base: no buffer view");
        let idx = sparse.indices();
        assert!(matches!(
            idx.index_type(),
            gltf::accessor::sparse::IndexType::U16
        ));
        for view in [idx.view(), sparse.values().view()] {
            assert!(view.target().is_none(), "sparse views have no target");
            assert!(view.stride().is_none(), "sparse views have no byteStride");
        }
        let data = &buffers[idx.view().buffer().index()];
        let start = idx.view().offset() + idx.offset();
        let indices: Vec<u16> = data[start..start + 2 * sparse.count()]
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        assert!(
            indices.windows(2).all(|w| w[0] < w[1]),
            "strictly increasing"
        );
        // Exactly the changed vertices are listed.
        let changed: Vec<u16> = delta
            .iter()
            .enumerate()
            .filter(|(_, d)| **d != [0.0; 3])
            .map(|(i, _)| i as u16)
            .collect();
        assert_eq!(indices, changed);
        assert!(
            lo.iter().zip(&hi).all(|(l, h)| *l <= 0.0 && *h >= 0.0),
            "zeros inside the bounds"
        );
    }
    assert!(seen > 0);
}

#[test]
fn a_resting_target_is_one_explicit_zero() {
    // A cache that never moves: every delta is zero, stored as a one-entry sparse accessor, and a
    // zero tolerance keeps only the two end frames.
    let n = 10u32;
    let positions: Vec<DVec3> = (0..n * n)
        .map(|i| DVec3::new((i % n) as f64, 0.0, (i / n) as f64))
        .collect();
    let triangles: Vec<[u32; 3]> = (0..(n - 1) * (n - 1))
        .flat_map(|c| {
            let i = c / (n - 1) * n + c % (n - 1);
            [[i, i + n, i + 1], [i + 1, i + n, i + n + 1]]
        })
        .collect();
    let mesh = Mesh::from_triangles("still".into(), positions.clone(), triangles);
    let mut cache = FrameCache::new(positions.len());
    for _ in 0..4 {
        cache.push(&positions);
    }
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("still.glb");
    let options = MorphOptions::new("still", 30.0);
    write_morph_gltf(&out, &mesh, &cache, &options).unwrap();
    let m = load_morph(&out);
    assert_eq!(m.targets(), 3);
    for j in 0..3 {
        assert!(m.deltas[j].iter().all(|v| *v == Vec3::ZERO));
        assert!(m.normal_deltas[j]
            .as_ref()
            .unwrap()
            .iter()
            .all(|v| *v == Vec3::ZERO));
    }
    let (doc, _, _) = common::gltf_read::import(&out).unwrap();
    for acc in doc.accessors().filter(|a| a.sparse().is_some()) {
        assert_eq!(acc.sparse().unwrap().count(), 1);
        assert!(acc.view().is_none());
    }
    assert_eq!(
        doc.accessors().filter(|a| a.sparse().is_some()).count(),
        6,
        "3 POSITION + 3 NORMAL"
    );

    let reduced = MorphOptions {
        keyframe_tolerance: Some(0.0),
        ..options
    };
    write_morph_gltf(&out, &mesh, &cache, &reduced).unwrap();
    let m = load_morph(&out);
    assert_eq!(m.targets(), 1);
    assert_eq!(m.times, vec![0.0, 0.1]);
}

#[test]
fn negative_tolerance_is_rejected_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = lab_job(&dir.path().join("x.glb"), 2);
    job.keyframe_tolerance = Some(-1.0);
    let e = bake_cloth(&job, &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(
            e,
            scenebake::Error::Param {
                param: scenebake::Param::KeyframeTolerance,
                ..
            }
        ),
        "{e}"
    );
    job.keyframe_tolerance = Some(f64::NAN);
    assert!(bake_cloth(&job, &mut |_, _| {})
        .unwrap_err()
        .to_string()
        .contains("`keyframe_tolerance`"));
}
