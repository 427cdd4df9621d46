//! Point caches (`--pc2`, `--mdd`): read back by readers written here from the formats'
//! definitions, every frame equals the glTF (read with the `gltf` crate) mapped back onto the
//! input OBJ's `v` lines, and frame 0 is those lines as placed.
//!
//! The fixture's `v` lines are shuffled (not in the order faces use them), a UV seam splits
//! positions into several glTF vertices, and one position in the middle of the file is used by
//! no face: the cache holds the used positions in file order (the mesh Blender's OBJ importer
//! makes), so a cache in the glTF's order, in first-use order, or one that keeps the unused
//! position, fails here.

use crate::common;

use std::path::Path;

use common::morph::load_morph;
use common::{fixture, mesh_path};
use scenebake::bake::cloth::{bake_cloth, ClothJob, ClothReport, UpAxis};
use scenebake::cloth::pins::PinSpec;
use scenebake::glam::{DVec3, Vec3};

/// The fixture's position used by no face: its 11th `v` line, so the cache's points after it are
/// the file's positions one further on.
const UNUSED: usize = 10;

/// A PC2 file: start frame, sample rate, and each sample's points.
pub(crate) struct Pc2 {
    pub start: f32,
    pub sampling: f32,
    pub samples: Vec<Vec<Vec3>>,
}

fn le_i32(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn le_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn be_i32(b: &[u8], at: usize) -> i32 {
    i32::from_be_bytes(b[at..at + 4].try_into().unwrap())
}

fn be_f32(b: &[u8], at: usize) -> f32 {
    f32::from_be_bytes(b[at..at + 4].try_into().unwrap())
}

/// PC2: "POINTCACHE2\0", int32 version 1, int32 points, float32 start frame, float32 sample
/// rate, int32 samples, then float32 x, y, z per point per sample; little-endian.
pub(crate) fn read_pc2(path: &Path) -> Pc2 {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..12], b"POINTCACHE2\0", "signature");
    assert_eq!(le_i32(&b, 12), 1, "version");
    let points = le_i32(&b, 16) as usize;
    let samples = le_i32(&b, 28) as usize;
    assert_eq!(
        b.len(),
        32 + samples * points * 12,
        "size of {points} × {samples}"
    );
    let at = |s: usize, p: usize| {
        let o = 32 + (s * points + p) * 12;
        Vec3::new(le_f32(&b, o), le_f32(&b, o + 4), le_f32(&b, o + 8))
    };
    Pc2 {
        start: le_f32(&b, 20),
        sampling: le_f32(&b, 24),
        samples: (0..samples)
            .map(|s| (0..points).map(|p| at(s, p)).collect())
            .collect(),
    }
}

/// MDD: int32 frames, int32 points, float32 time of each frame, then float32 x, y, z per point
/// per frame; big-endian. Returns (times, frames).
fn read_mdd(path: &Path) -> (Vec<f32>, Vec<Vec<Vec3>>) {
    let b = std::fs::read(path).unwrap();
    let frames = be_i32(&b, 0) as usize;
    let points = be_i32(&b, 4) as usize;
    let data = 8 + 4 * frames;
    assert_eq!(
        b.len(),
        data + frames * points * 12,
        "size of {points} × {frames}"
    );
    let times = (0..frames).map(|k| be_f32(&b, 8 + 4 * k)).collect();
    let at = |f: usize, p: usize| {
        let o = data + (f * points + p) * 12;
        Vec3::new(be_f32(&b, o), be_f32(&b, o + 4), be_f32(&b, o + 8))
    };
    let frames = (0..frames)
        .map(|f| (0..points).map(|p| at(f, p)).collect())
        .collect();
    (times, frames)
}

/// The OBJ's `v` lines, in file order.
fn obj_positions(path: &Path) -> Vec<DVec3> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            DVec3::new(c[0], c[1], c[2])
        })
        .collect()
}

/// `--up`, `--scale` and `--translate` as the docs define them: (x, y, z) → (x, z, −y) for a
/// Z-up file, then scaled about the origin, then moved.
fn placed(p: DVec3, up_z: bool, scale: f64, translate: DVec3) -> Vec3 {
    let p = if up_z { DVec3::new(p.x, p.z, -p.y) } else { p };
    (p * scale + translate).as_vec3()
}

/// Every frame of the glTF's first mesh as a player shows it (frame 0 the base, frame f its
/// target f − 1 at weight 1), and its animation's key times.
fn gltf_frames(path: &Path) -> (Vec<Vec<Vec3>>, Vec<f32>) {
    let m = load_morph(path);
    let mut frames = vec![m.base.clone()];
    frames.extend((0..m.targets()).map(|j| m.target_positions(j)));
    (frames, m.times)
}

/// Checks both caches against the glTF and the OBJ; returns the number of frames.
fn check_caches(
    obj: &Path,
    gltf: &Path,
    pc2: &Path,
    mdd: &Path,
    place: &dyn Fn(DVec3) -> Vec3,
    fps: f32,
) -> usize {
    let rest: Vec<Vec3> = obj_positions(obj).into_iter().map(place).collect();
    let (frames, times) = gltf_frames(gltf);
    assert_eq!(times.len(), frames.len(), "one key per frame");
    // Each glTF vertex is the OBJ position it starts at (the fixture's positions are distinct).
    let position_of: Vec<usize> = frames[0]
        .iter()
        .map(|v| {
            let hits: Vec<usize> = (0..rest.len())
                .filter(|&i| rest[i].distance(*v) < 1e-6)
                .collect();
            assert_eq!(
                hits.len(),
                1,
                "glTF vertex at {v} matches OBJ positions {hits:?}"
            );
            hits[0]
        })
        .collect();
    let used: Vec<bool> = (0..rest.len()).map(|i| position_of.contains(&i)).collect();
    assert_eq!(
        (0..rest.len()).filter(|&i| !used[i]).collect::<Vec<_>>(),
        vec![UNUSED],
        "the fixture's one unused position"
    );
    assert!(
        frames[0].len() > rest.len() - 1,
        "the seam splits positions into several glTF vertices"
    );
    // The cache's points: the used `v` lines in file order.
    let lines: Vec<usize> = (0..rest.len()).filter(|&i| used[i]).collect();
    let point_of = |line: usize| lines.binary_search(&line).unwrap();

    let c = read_pc2(pc2);
    let (mdd_times, mdd) = read_mdd(mdd);
    assert_eq!(c.samples.len(), frames.len(), "PC2 samples");
    assert_eq!(mdd.len(), frames.len(), "MDD frames");
    assert_eq!(c.sampling, 1.0, "one PC2 sample per frame");
    assert!(
        (c.start - times[0] * fps).abs() < 1e-4,
        "PC2 start frame {} for a first key at {} s",
        c.start,
        times[0]
    );
    for (k, (a, b)) in mdd_times.iter().zip(&times).enumerate() {
        assert!(
            (a - b).abs() < 1e-5,
            "MDD time of frame {k}: {a} against the glTF's {b}"
        );
        assert!(
            (a - (times[0] + k as f32 / fps)).abs() < 1e-5,
            "frame {k} at {a} s"
        );
    }
    let mut worst = 0.0f32;
    for (f, gltf) in frames.iter().enumerate() {
        let (pc2, mdd) = (&c.samples[f], &mdd[f]);
        assert_eq!(pc2.len(), lines.len(), "one point per used `v` line");
        assert_eq!(mdd, pc2, "MDD frame {f} equals PC2's");
        for (v, p) in gltf.iter().enumerate() {
            let d = pc2[point_of(position_of[v])].distance(*p);
            worst = worst.max(d);
            assert!(d < 1e-6, "frame {f}, glTF vertex {v}: {d} m off");
        }
    }
    for (k, &i) in lines.iter().enumerate() {
        assert!(
            c.samples[0][k].distance(rest[i]) < 1e-6,
            "frame 0, `v` line {}: {} against {}",
            i + 1,
            c.samples[0][k],
            rest[i]
        );
    }
    let moved = c.samples[frames.len() - 1]
        .iter()
        .zip(&c.samples[0])
        .map(|(a, b)| a.distance(*b))
        .fold(0.0f32, f32::max);
    assert!(moved > 0.05, "the cloth moves ({moved} m)");
    eprintln!(
        "{} frames; worst distance to the glTF {worst:e} m",
        frames.len()
    );
    frames.len()
}

fn check_report(report: &ClothReport, pc2: &Path, mdd: &Path, frames: usize) {
    assert_eq!(report.point_caches.len(), 2);
    for (r, path, format) in [
        (&report.point_caches[0], pc2, "pc2"),
        (&report.point_caches[1], mdd, "mdd"),
    ] {
        assert_eq!(r.file, path);
        assert_eq!(r.bytes, std::fs::metadata(path).unwrap().len());
        assert_eq!(r.frames, frames);
        assert_eq!(r.points, 36, "the used positions");
        assert_eq!(serde_json::to_value(r.format).unwrap(), format);
        assert!(report.output.iter().any(|o| o == path), "{path:?} listed");
    }
    let on_disk: u64 = report
        .output
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!(report.output_bytes, on_disk);
}

#[test]
fn caches_hold_the_gltf_frames_in_the_obj_order() {
    let dir = tempfile::tempdir().unwrap();
    let obj = fixture("cache_sheet.obj");
    let (scale, translate) = (2.0, DVec3::new(1.0, 0.5, 0.0));
    let mut job = ClothJob {
        input: Some(obj.clone()),
        output: dir.path().join("sheet.gltf"),
        frames: Some(20),
        up: UpAxis::Z,
        scale,
        translate: Some(translate),
        // The top row (y = 1 in the file) is at z = −2 once placed.
        pin: vec!["box:-10,-10,-2.1,10,10,-1.9".parse::<PinSpec>().unwrap()],
        pc2: Some(dir.path().join("sheet.pc2")),
        mdd: Some(dir.path().join("sheet.mdd")),
        ..ClothJob::default()
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let place = |p| placed(p, true, scale, translate);
    let frames = check_caches(
        &obj,
        &job.output,
        job.pc2.as_ref().unwrap(),
        job.mdd.as_ref().unwrap(),
        &place,
        30.0,
    );
    assert_eq!(frames, 21, "frame 0 and 20 baked frames");
    check_report(
        &report,
        job.pc2.as_ref().unwrap(),
        job.mdd.as_ref().unwrap(),
        frames,
    );

    // Another rate, a .glb, and an --object pick: the same file numbering.
    job.object = Some("Sheet".into());
    job.fps = Some(24.0);
    job.output = dir.path().join("sheet24.glb");
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    check_caches(
        &obj,
        &job.output,
        job.pc2.as_ref().unwrap(),
        job.mdd.as_ref().unwrap(),
        &place,
        24.0,
    );
    assert_eq!(report.point_caches[0].fps, 24.0);
}

/// With `--rig`, the caches hold the written loops as the glTF's garment does, keyed on the
/// animation's times.
#[test]
fn rig_bakes_write_the_garments_frames() {
    let dir = tempfile::tempdir().unwrap();
    let obj = fixture("cache_sheet.obj");
    let translate = DVec3::new(3.0, 3.0, 0.0);
    for garment_only in [true, false] {
        let job = ClothJob {
            input: Some(obj.clone()),
            output: dir.path().join(format!("rig_{garment_only}.glb")),
            rig: Some(mesh_path("RiggedSimple.gltf")),
            pin_to: Some("Bone.001".into()),
            body_collider: scenebake::bake::cloth::Switch::Off,
            garment_only,
            translate: Some(translate),
            pin: vec!["box:-10,3.9,-10,10,4.1,10".parse::<PinSpec>().unwrap()],
            pc2: Some(dir.path().join(format!("rig_{garment_only}.pc2"))),
            mdd: Some(dir.path().join(format!("rig_{garment_only}.mdd"))),
            ..ClothJob::default()
        };
        let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
        let fps = report.fps as f32;
        // The written loops start in motion (frame 0 is the glTF's first frame, not the rest
        // pose), so glTF vertices are matched to cache points at frame 0. The garment is the
        // first mesh with --garment-only; in the character's document the same simulation must
        // give the same caches byte for byte.
        if garment_only {
            let rest = obj_positions(&obj);
            let (frames, times) = gltf_frames(&job.output);
            let c = read_pc2(job.pc2.as_ref().unwrap());
            let (mdd_times, mdd) = read_mdd(job.mdd.as_ref().unwrap());
            assert_eq!(c.samples.len(), frames.len());
            assert_eq!(mdd, c.samples);
            assert!((c.start - times[0] * fps).abs() < 1e-3);
            for (a, b) in mdd_times.iter().zip(&times) {
                assert!((a - b).abs() < 1e-5, "MDD time {a} against the glTF's {b}");
            }
            // Map glTF vertices to cache points by frame 0 (distinct positions in the sheet).
            for (f, g) in frames.iter().enumerate() {
                for (v, p) in g.iter().enumerate() {
                    let i = (0..c.samples[0].len())
                        .min_by(|&a, &b| {
                            c.samples[0][a]
                                .distance(frames[0][v])
                                .total_cmp(&c.samples[0][b].distance(frames[0][v]))
                        })
                        .unwrap();
                    assert!(c.samples[0][i].distance(frames[0][v]) < 1e-6);
                    assert!(c.samples[f][i].distance(*p) < 1e-6, "frame {f}, vertex {v}");
                }
            }
            assert_eq!(c.samples[0].len(), rest.len() - 1, "the used positions");
            assert_eq!(report.point_caches.len(), 2);
        } else {
            // The character's document: the same simulation, so the same caches byte for byte.
            for ext in ["pc2", "mdd"] {
                assert_eq!(
                    std::fs::read(dir.path().join(format!("rig_false.{ext}"))).unwrap(),
                    std::fs::read(dir.path().join(format!("rig_true.{ext}"))).unwrap(),
                    "{ext} with and without --garment-only"
                );
            }
        }
    }
}

#[test]
fn bad_cache_paths_are_refused_before_the_bake_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).display().to_string();
    std::fs::write(dir.path().join("a_file"), b"x").unwrap();
    std::fs::create_dir(dir.path().join("a_folder")).unwrap();
    let obj = fixture("cache_sheet.obj").display().to_string();
    let run = |extra: &[&str], out: &str, words: &[&str]| {
        common::cli::cloth_refused(&obj, dir.path(), out, extra, words, &["a_file", "a_folder"])
    };
    let under_file = d("a_file/x.pc2");
    run(
        &["--pc2", &under_file],
        "out.glb",
        &["--pc2", &under_file, "is a file, not a directory"],
    );
    let folder = d("a_folder");
    run(
        &["--mdd", &folder],
        "out.glb",
        &["--mdd", "is a directory, not a file"],
    );
    let out = d("out.glb");
    run(
        &["--pc2", &out],
        "out.glb",
        &["--pc2", "the same file as --output", "writes"],
    );
    let bin = d("sub/../out.bin");
    run(
        &["--mdd", &bin],
        "out.gltf",
        &["--mdd", "the same file as --output", "out.bin"],
    );
    let pc2 = d("c.cache");
    run(
        &["--pc2", &pc2, "--mdd", &pc2],
        "out.glb",
        &["--mdd", "the same file as --pc2"],
    );
    let report = d("r.json");
    run(
        &["--report", &report, "--pc2", &report],
        "out.glb",
        &["--pc2", "the same file as --report"],
    );
    // A rig bake checks them too, before loading the rig.
    run(
        &[
            "--rig",
            &mesh_path("RiggedSimple.gltf").display().to_string(),
            "--pc2",
            &under_file,
        ],
        "rig.glb",
        &["--pc2", "is a file, not a directory"],
    );
}
