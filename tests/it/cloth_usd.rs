//! USD export (`--usd FILE.usda`): the layer is read back by Pixar's USD (`pxr` from PyPI's
//! usd-core, scripts/usd_check.py) and compared with an independent numpy reading of the glTF
//! the same bake wrote (scripts/blender/gltf_eval.py): every mesh (cloth, colliders, a body
//! sequence) at every frame within 1e-6 m, the glTF's triangles mapped onto the USD points are the
//! USD faces, time codes / fps / extent agree, and USD's validators report no error.
//!
//! The python with `pxr` and numpy is `$SCENEBAKE_USD_PYTHON`, else `python3`; without it the
//! comparisons are skipped with a note, except under CI (`CI` set), where that fails.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::cli::fails_with;
use common::{crate_dir, fixture, mesh_path};
use scenebake::bake::cloth::{bake_cloth, ClothJob, UpAxis};
use scenebake::cloth::collide::ColliderSpec;
use scenebake::cloth::pins::PinSpec;
use scenebake::glam::DVec3;

/// The python that has `pxr` and numpy, or `None` (with a note) outside CI.
fn usd_python() -> Option<PathBuf> {
    let python = std::env::var_os("SCENEBAKE_USD_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("python3"));
    let have = Command::new(&python)
        .args(["-c", "import pxr.Usd, numpy"])
        .status()
        .is_ok_and(|s| s.success());
    if !have {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI needs a python with usd-core and numpy ({} has not; set SCENEBAKE_USD_PYTHON)",
            python.display()
        );
        eprintln!(
            "skipped: {} cannot import pxr and numpy (pip install usd-core numpy, or set \
             SCENEBAKE_USD_PYTHON)",
            python.display()
        );
        return None;
    }
    Some(python)
}

/// Runs scripts/usd_check.py on `usd` and `gltf` at `frames` (all when empty): its success and
/// figures.
fn usd_check(
    python: &Path,
    usd: &Path,
    gltf: &Path,
    frames: &[usize],
) -> (bool, serde_json::Value) {
    let json = usd.with_extension("check.json");
    let out = Command::new(python)
        .arg(crate_dir().join("scripts/usd_check.py"))
        .arg(usd)
        .arg(gltf)
        .arg("--frames")
        .args(frames.iter().map(|f| f.to_string()))
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    (out.status.success(), common::read_json(&json))
}

/// The fixture sheet (shuffled `v` lines, a UV seam, an unused position), Z-up, scaled and moved
/// above the table, pinned along one edge, with the table and a floor as colliders.
fn sheet_job(dir: &Path) -> ClothJob {
    ClothJob {
        input: Some(fixture("cache_sheet.obj")),
        output: dir.join("sheet.glb"),
        frames: Some(12),
        up: UpAxis::Z,
        scale: 0.5,
        translate: Some(DVec3::new(0.0, 1.0, 0.3)),
        // The top row (y = 1 in the file) is at z = 0.3 − 0.5 once placed.
        pin: vec!["box:-10,-10,-0.25,10,10,-0.15".parse::<PinSpec>().unwrap()],
        collider: vec![
            format!("mesh:{}", mesh_path("table.obj").display())
                .parse::<ColliderSpec>()
                .unwrap(),
            "plane:0,1,0,0".parse::<ColliderSpec>().unwrap(),
        ],
        usd: Some(dir.join("sheet.usda")),
        ..ClothJob::default()
    }
}

#[test]
fn the_usd_layer_plays_the_gltf_frames() {
    let dir = tempfile::tempdir().unwrap();
    let job = sheet_job(dir.path());
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let usd = job.usd.as_ref().unwrap();
    let r = report.usd.as_ref().expect("a usd section");
    assert_eq!(&r.file, usd);
    assert_eq!(r.bytes, std::fs::metadata(usd).unwrap().len());
    assert_eq!(
        r.prims,
        [
            "/World/cache_sheet",
            "/World/collider_1",
            "/World/collider_2"
        ]
    );
    assert_eq!((r.frames, r.time_codes, r.fps), (13, [0.0, 12.0], 30.0));
    assert!(report.output.iter().any(|o| o == usd), "listed as written");

    let Some(python) = usd_python() else { return };
    let (ok, figures) = usd_check(&python, usd, &job.output, &[0, 1, 6, 12]);
    assert!(ok, "{figures:#}");
    assert_eq!(figures["prims"].as_object().unwrap().len(), 3);
    let sheet = &figures["prims"]["/World/cache_sheet"];
    // One point per used position (36), the glTF's 42 vertices split at the seam.
    assert_eq!(
        (sheet["points"].as_u64(), sheet["gltf_vertices"].as_u64()),
        (Some(36), Some(42))
    );
    assert_eq!(sheet["animated"], true);
    assert_eq!(figures["prims"]["/World/collider_1"]["animated"], false);
    assert!(figures["max_distance_m"].as_f64().unwrap() <= 1e-6);
    eprintln!(
        "sheet: largest distance to the glTF {} m",
        figures["max_distance_m"]
    );

    // Another rate: time codes per second follow --fps.
    let job = ClothJob {
        fps: Some(24.0),
        frames: Some(4),
        output: dir.path().join("sheet24.gltf"),
        usd: Some(dir.path().join("sheet24.usda")),
        ..sheet_job(dir.path())
    };
    bake_cloth(&job, &mut |_, _| {}).unwrap();
    let (ok, figures) = usd_check(&python, job.usd.as_ref().unwrap(), &job.output, &[]);
    assert!(ok, "{figures:#}");
    assert_eq!(figures["timeCodesPerSecond"], 24.0);
    assert_eq!(figures["frames"].as_array().unwrap().len(), 5);
}

/// A box whose top rises, as an OBJ sequence `box%d.obj` (frames 0..6 at 10 fps).
fn write_box_sequence(dir: &Path) -> PathBuf {
    for i in 0..6 {
        let top = 0.02 * i as f64;
        let mut s = String::new();
        for (x, y, z) in [
            (-0.3, -0.2, -0.3),
            (0.3, -0.2, -0.3),
            (0.3, -0.2, 0.3),
            (-0.3, -0.2, 0.3),
            (-0.3, top, -0.3),
            (0.3, top, -0.3),
            (0.3, top, 0.3),
            (-0.3, top, 0.3),
        ] {
            s += &format!("v {x} {y} {z}\n");
        }
        s += "f 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\nf 1 5 6\nf 1 6 2\nf 2 6 7\nf 2 7 3\nf 3 7 8\n\
              f 3 8 4\nf 4 8 5\nf 4 5 1\n";
        std::fs::write(dir.join(format!("box{i}.obj")), s).unwrap();
    }
    dir.join("box%d.obj")
}

#[test]
fn a_body_sequence_is_a_mesh_with_time_sampled_points() {
    let dir = tempfile::tempdir().unwrap();
    let job = ClothJob {
        input: Some(fixture("cache_sheet.obj")),
        output: dir.path().join("body.glb"),
        up: UpAxis::Z,
        scale: 0.4,
        translate: Some(DVec3::new(0.0, 0.02, 0.2)),
        body: Some(write_box_sequence(dir.path())),
        body_fps: Some(10.0),
        thickness: Some(0.01),
        usd: Some(dir.path().join("body.usda")),
        ..ClothJob::default()
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let r = report.usd.as_ref().unwrap();
    assert_eq!(r.prims, ["/World/cache_sheet", "/World/cache_sheet_body"]);
    let Some(python) = usd_python() else { return };
    let (ok, figures) = usd_check(&python, job.usd.as_ref().unwrap(), &job.output, &[]);
    assert!(ok, "{figures:#}");
    eprintln!(
        "body bake: largest distance to the glTF {} m",
        figures["max_distance_m"]
    );
    let body = &figures["prims"]["/World/cache_sheet_body"];
    assert_eq!(
        (body["animated"].as_bool(), body["points"].as_u64()),
        (Some(true), Some(8))
    );
}

/// With `--rig` the layer holds the garment and the character's skinned mesh (its points at
/// every frame, as the glTF's skin plays them, read independently by usd_check.py), their frames
/// the written loops', keyed from the animation's start as the glTF is (time code = key time ×
/// fps).
#[test]
fn a_rig_bake_writes_the_garment_and_the_skinned_body() {
    let dir = tempfile::tempdir().unwrap();
    let job = ClothJob {
        usd: Some(dir.path().join("rig.usda")),
        cycles: 2,
        ..common::rigged_sheet(dir.path().join("rig.glb"))
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let r = report.usd.as_ref().unwrap();
    assert_eq!(r.prims, ["/World/cache_sheet", "/World/Cylinder"]);
    assert!(
        r.time_codes[0] > 0.0,
        "the loop starts after the animation's start"
    );
    let Some(python) = usd_python() else { return };
    let (ok, figures) = usd_check(&python, job.usd.as_ref().unwrap(), &job.output, &[]);
    assert!(ok, "{figures:#}");
    assert_eq!(figures["startTimeCode"].as_f64().unwrap(), r.time_codes[0]);
    let body = &figures["prims"]["/World/Cylinder"];
    assert_eq!(body["animated"].as_bool(), Some(true), "{figures:#}");
    // The garment-only file has no character, so the layer has none either.
    let job = ClothJob {
        garment_only: true,
        output: dir.path().join("garment.glb"),
        usd: Some(dir.path().join("garment.usda")),
        ..job
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(report.usd.as_ref().unwrap().prims, ["/World/cache_sheet"]);
}

#[test]
fn bad_usd_paths_are_refused_before_the_bake_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = |name: &str| dir.path().join(name).display().to_string();
    std::fs::write(dir.path().join("a_file"), b"x").unwrap();
    std::fs::create_dir(dir.path().join("a_folder")).unwrap();
    let obj = fixture("cache_sheet.obj").display().to_string();
    let run = |extra: &[&str], out: &str, words: &[&str]| {
        common::cli::cloth_refused(&obj, dir.path(), out, extra, words, &["a_file", "a_folder"])
    };
    let usdc = d("out.usdc");
    run(
        &["--usd", &usdc],
        "out.glb",
        &[
            "--usd",
            &format!(
                "{usdc}: binary .usdc is not written (the USD writer used makes .usdc files that \
                 Pixar's USD cannot open); give a .usda file (usdcat converts it: usdcat \
                 FILE.usda -o FILE.usdc)"
            ),
        ],
    );
    let txt = d("out.usd");
    run(
        &["--usd", &txt],
        "out.glb",
        &[
            "--usd",
            &format!("{txt}: unknown USD extension: expected .usda"),
        ],
    );
    let under_file = d("a_file/x.usda");
    run(
        &["--usd", &under_file],
        "out.glb",
        &["--usd", &under_file, "is a file, not a directory"],
    );
    run(
        &["--usd", &d("a_folder")],
        "out.glb",
        &["--usd", "is a directory, not a file"],
    );
    let pc2 = d("c.usda");
    run(
        &["--pc2", &pc2, "--usd", &pc2],
        "out.glb",
        &["--usd", "the same file as --pc2"],
    );
}

/// An existing read-only file is not replaced: the bake is refused before it starts.
#[test]
fn a_read_only_usd_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let usd = dir.path().join("x.usda");
    std::fs::write(&usd, b"kept").unwrap();
    let mut perms = std::fs::metadata(&usd).unwrap().permissions();
    perms.set_readonly(true);
    std::fs::set_permissions(&usd, perms).unwrap();
    let out = dir.path().join("out.glb").display().to_string();
    let obj = fixture("cache_sheet.obj").display().to_string();
    let usd_text = usd.display().to_string();
    fails_with(
        &["cloth", &obj, "-o", &out, "--usd", &usd_text],
        &[
            "--usd",
            &format!(
                "{usd_text}: exists and is read-only; make it writable or choose another file"
            ),
        ],
    );
    assert!(!Path::new(&out).exists());
    assert_eq!(std::fs::read(&usd).unwrap(), b"kept");
}
