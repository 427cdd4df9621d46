//! The command line as a user meets it: every bad input gets a clear error naming the file (or
//! option, or scene job) and exits with a failure code, never a panic.

use crate::common;

use std::path::Path;
use std::process::Command;

use common::cli::{fails_with, scenebake};
use common::{fixture, mesh_path as mesh, names_in};

fn out_path(dir: &tempfile::TempDir) -> String {
    dir.path().join("out.glb").to_string_lossy().into_owned()
}

#[test]
fn unreadable_inputs_name_the_file_and_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let out = out_path(&dir);
    let f = |n: &str| fixture(n).to_string_lossy().into_owned();
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            "/nonexistent/cloth.obj".into(),
            vec!["/nonexistent/cloth.obj", "No such file"],
        ),
        (
            dir.path().join("adir.obj").to_string_lossy().into_owned(),
            vec!["adir.obj", "directory"],
        ),
        (f("empty.obj"), vec!["empty.obj", "no faces"]),
        (f("garbage.obj"), vec!["garbage.obj", "not a text file"]),
        (
            f("index_out_of_range.obj"),
            vec!["index_out_of_range.obj:4", "out of range"],
        ),
        (f("index_zero.obj"), vec!["index_zero.obj:4", "index 0"]),
        (f("nan.obj"), vec!["nan.obj:2", "non-finite"]),
        (f("inf.obj"), vec!["inf.obj:2", "non-finite"]),
        (f("no_faces.obj"), vec!["no_faces.obj", "no faces"]),
        (f("truncated.glb"), vec!["truncated.glb"]),
        (
            f("missing_bin.gltf"),
            vec!["missing_bin.gltf", "missing.bin"],
        ),
        (f("invalid_json.gltf"), vec!["invalid_json.gltf", "EOF"]),
        // Found by fuzzing: the gltf crate's validator panicked on this one.
        (f("position_accessor_out_of_range.gltf"), vec!["position_accessor_out_of_range.gltf", "meshes[0].primitives[0].attributes.POSITION refers to accessor 0, but the file has 0 accessors"]),
        // Found by fuzzing: an image with a bufferView but no mimeType panicked the pre-check.
        (f("image_view_without_mime.gltf"), vec!["image_view_without_mime.gltf", "images[0] has a bufferView but no mimeType"]),
        // Found by a longer fuzzing run: this one passes the gltf crate's validation, then its
        // image loader unwrapped the missing mimeType.
        (f("image_view_without_mime_valid_view.gltf"), vec!["image_view_without_mime_valid_view.gltf", "images[0] has a bufferView but no mimeType"]),
        (f("short.tet"), vec!["short.tet:4", "3 of the 10 points"]),
        (
            f("tet_bad_index.tet"),
            vec!["tet_bad_index.tet:6", "out of range"],
        ),
        (
            mesh("cube.mtl").to_string_lossy().into_owned(),
            vec!["cube.mtl", "unknown mesh format"],
        ),
    ];
    std::fs::create_dir(dir.path().join("adir.obj")).unwrap();
    for (input, words) in cases {
        fails_with(&["cloth", &input, "-o", &out, "--frames", "2"], &words);
    }
    assert!(!Path::new(&out).exists(), "no output from failed bakes");
}

#[test]
fn degenerate_faces_and_zero_length_edges_are_skipped_with_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    for (file, warning) in [
        ("degenerate.obj", "degenerate"),
        ("zero_length.obj", "zero-length"),
    ] {
        let (code, err) = scenebake([
            "cloth",
            fixture(file).to_str().unwrap(),
            "-o",
            &out_path(&dir),
            "--frames",
            "3",
            "--pin",
            "index:0",
            // The labs' springs: a bending spring joins the two coincident opposite vertices.
            "--stiffness",
            "1000",
            "--report",
            report.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{file}: {err}");
        let r: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
        let warnings = r["warnings"].to_string();
        assert!(warnings.contains(warning), "{file}: {warnings}");
    }
}

#[test]
fn bad_option_values_name_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = out_path(&dir);
    let plane = mesh("plane_30x30.obj");
    let plane = plane.to_str().unwrap();
    let cases: &[(&[&str], &[&str])] = &[
        (&["--pin", "corner"], &["--pin", "expected index"]),
        (&["--pin", "box:1,2"], &["--pin", "6 comma-separated"]),
        (
            &["--pin", "box:5,5,5,6,6,6"],
            &["--pin box:5,5,5,6,6,6", "selects no particle", "spans"],
        ),
        (&["--pin", "index:99999"], &["--pin", "out of range"]),
        (&["--pin", "group:nope"], &["--pin", "no group `nope`"]),
        (&["--frames", "0"], &["--frames", "at least 1"]),
        (&["--frames", "-3"], &["--frames"]),
        (&["--fps", "0"], &["--fps", "positive"]),
        (&["--fps", "-30"], &["--fps", "positive"]),
        (&["--stiffness", "-1"], &["--stiffness", "positive"]),
        (&["--stiffness", "nan"], &["--stiffness", "positive"]),
        (&["--mass", "0"], &["--mass", "positive"]),
        (&["--density", "-2"], &["--density", "positive"]),
        (&["--mass", "1", "--density", "1"], &["--mass", "not both"]),
        (&["--iterations", "0"], &["--iterations", "at least 1"]),
        (&["--substeps", "0"], &["--substeps", "at least 1"]),
        (
            &["--gravity", "0,-9.81"],
            &["--gravity", "3 comma-separated"],
        ),
        (
            &["--gravity", "a,b,c"],
            &["--gravity", "not a finite number"],
        ),
        (&["--solver", "magic"], &["--solver", "magic"]),
        (
            &["--collider", "cone:1,2,3"],
            &["--collider", "unknown collider kind `cone`"],
        ),
        (
            &["--collider", "plane:0,1,0"],
            &["--collider", "4 comma-separated"],
        ),
        (
            &["--collider", "plane:0,0,0,1"],
            &["--collider", "normal is zero"],
        ),
        (
            &["--collider", "sphere:0,0,0,-1"],
            &["--collider", "radius -1 must be positive"],
        ),
        (&["--collider", "box:0,0,0,1,0,1"], &["--collider", "flat"]),
        (
            &["--collider", "mesh:"],
            &["--collider", "file name is empty"],
        ),
        (
            &["--collider", "mesh:/nonexistent/table.obj"],
            &["/nonexistent/table.obj"],
        ),
        (
            &["--collider", "plane:0,1,0,-1", "--thickness", "0"],
            &["--thickness", "positive"],
        ),
        (
            &["--collider", "plane:0,1,0,-1", "--friction", "-0.5"],
            &["--friction", "zero or a positive"],
        ),
        (
            &[
                "--collider",
                "plane:0,1,0,-1",
                "--contact",
                "barrier",
                "--solver",
                "fast",
            ],
            &["--contact", "the fast solver"],
        ),
        (
            &["--self-contact", "on", "--solver", "fast"],
            &["--self-contact", "the fast solver has none"],
        ),
        (
            &["--self-contact", "on", "--self-thickness", "-1"],
            &["--self-thickness", "positive"],
        ),
        (&["--contact", "sticky"], &["--contact", "sticky"]),
        (&["--wind", "1,2"], &["--wind", "3 comma-separated"]),
        (
            &["--wind", "5,0,0", "--drag", "-1"],
            &["--drag", "zero or a positive"],
        ),
        (&["--turbulence", "0.3"], &["--turbulence", "give --wind"]),
        (&["--scale", "0"], &["--scale", "positive"]),
        (
            &["--translate", "1,nan,0"],
            &["--translate", "not a finite number"],
        ),
        (
            &["--object", "nope"],
            &["--object", "no object or group named `nope`"],
        ),
    ];
    for (extra, words) in cases {
        let mut args = vec!["cloth", plane, "-o", &out, "--frames", "2"];
        if extra.contains(&"--frames") {
            args.truncate(4);
        }
        args.extend_from_slice(extra);
        fails_with(&args, words);
    }
    fails_with(
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "-o",
            &out,
            "--translate",
            "0,1,0",
        ],
        &["--translate", "lab-cloth preset"],
    );
}

#[test]
fn unwritable_outputs_are_errors_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("file");
    std::fs::write(&blocker, b"x").unwrap();
    let inside_a_file = blocker.join("out.glb");
    fails_with(
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--frames",
            "2",
            "-o",
            inside_a_file.to_str().unwrap(),
        ],
        &["file"],
    );
    let a_dir = dir.path().join("d.glb");
    std::fs::create_dir(&a_dir).unwrap();
    fails_with(
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--frames",
            "2",
            "-o",
            a_dir.to_str().unwrap(),
        ],
        &["d.glb", "directory"],
    );
    fails_with(
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--frames",
            "2",
            "-o",
            dir.path().join("x.fbx").to_str().unwrap(),
        ],
        &["x.fbx", ".glb or .gltf"],
    );
}

#[test]
fn scene_file_errors_name_the_file_the_job_and_the_key() {
    let cases: &[(&str, &[&str])] = &[
        (
            "scene_unknown_key.toml",
            &[
                "scene_unknown_key.toml",
                "[[cloth]] job 1",
                "unknown key `framez`",
            ],
        ),
        (
            "scene_wrong_type.toml",
            &["scene_wrong_type.toml", "job 1", "ten", "frames", "line 4"],
        ),
        (
            "scene_missing_output.toml",
            &["scene_missing_output.toml", "job 1", "`output` is required"],
        ),
        ("scene_bad_toml.toml", &["scene_bad_toml.toml", "line 6"]),
        (
            "scene_unknown_table.toml",
            &["scene_unknown_table.toml", "unknown table `cloths`"],
        ),
    ];
    for (file, words) in cases {
        fails_with(&["run", fixture(file).to_str().unwrap()], words);
    }
    fails_with(
        &["run", "/nonexistent/scene.toml"],
        &["/nonexistent/scene.toml"],
    );
}

/// Writes `text` to the scene file `scene`, runs it with `--report` beside it and returns the
/// report (the run must succeed).
fn run_scene(scene: &Path, text: &str) -> serde_json::Value {
    std::fs::write(scene, text).unwrap();
    let report = scene.with_extension("json");
    let (code, err) = scenebake([
        "run",
        scene.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap()
}

#[test]
fn a_scene_runs_its_jobs_and_reports() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    let r = run_scene(
        &scene,
        &format!(
            "[[cloth]]\nname = \"lab\"\npreset = \"lab-cloth\"\nframes = 5\noutput = \"out/lab.glb\"\n\n[[cloth]]\nname = \"plane\"\ninput = \"{}\"\nframes = 3\npin = [\"box:-1,-1,-1,1,1,-0.49\"]\nbend_stiffness = 0\noutput = \"out/plane.gltf\"\n",
            mesh("plane_30x30.obj").display()
        ),
    );
    assert!(
        dir.path().join("out/lab.glb").exists()
            && dir.path().join("out/plane.gltf").exists()
            && dir.path().join("out/plane.bin").exists()
    );
    let jobs = r["jobs"].as_array().unwrap();
    assert_eq!(jobs.len(), 2);
    assert_eq!(jobs[1]["report"]["frames"], 3);
    assert_eq!(
        jobs[1]["report"]["springs_by_kind"]["bend"], 0,
        "bend_stiffness = 0 is honoured"
    );
    // A collider mesh in a scene is found relative to the scene file, like every other path.
    std::fs::copy(mesh("cube_5.obj"), dir.path().join("block.obj")).unwrap();
    let r = run_scene(
        &dir.path().join("drape.toml"),
        &format!(
            "[[cloth]]\nname = \"drape\"\ninput = \"{}\"\nframes = 3\ncollider = [\"mesh:block.obj\", \"plane:0,1,0,-2\"]\ncontact = \"barrier\"\nwind = \"1,0,0\"\noutput = \"out/drape.glb\"\n",
            mesh("plane_30x30.obj").display()
        ),
    );
    let env = &r["jobs"][0]["report"]["environment"];
    assert_eq!(env["colliders"].as_array().unwrap().len(), 2, "{env}");
    assert!(
        env["colliders"][0].as_str().unwrap().starts_with("mesh"),
        "{env}"
    );
    assert_eq!(env["wind"]["velocity"][0], 1.0, "{env}");
    assert_eq!(env["contact"], "barrier", "{env}");

    // --only runs one job.
    std::fs::remove_file(dir.path().join("out/lab.glb")).unwrap();
    let (code, err) = scenebake(["run", scene.to_str().unwrap(), "--only", "lab"]);
    assert_eq!(code, 0, "{err}");
    assert!(dir.path().join("out/lab.glb").exists());
    fails_with(
        &["run", scene.to_str().unwrap(), "--only", "nope"],
        &["no job named `nope`", "lab, plane"],
    );
}

#[test]
fn inspect_describes_a_bake_and_flags_broken_invariants() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let (code, err) = scenebake([
        "-q",
        "cloth",
        "--preset",
        "lab-cloth",
        "--frames",
        "6",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let o = Command::new(env!("CARGO_BIN_EXE_scenebake"))
        .args(["inspect", "--json", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["meshes"][0]["vertices"], 121);
    assert_eq!(v["meshes"][0]["triangles"], 200);
    assert_eq!(v["meshes"][0]["morph_targets"], 6);
    assert_eq!(v["animations"][0]["channels"][0]["keys"], 7);
    assert_eq!(v["animations"][0]["channels"][0]["path"], "weights");
    assert_eq!(v["bytes"], std::fs::metadata(&out).unwrap().len());
    assert!(v["checks"]
        .as_array()
        .unwrap()
        .iter()
        .all(|c| c["ok"] == true));

    let broken = fixture("broken_invariants.gltf");
    fails_with(
        &["inspect", broken.to_str().unwrap()],
        &[
            "broken_invariants.gltf",
            "3 invariant check(s) failed",
            "morph POSITION has min/max",
            "targetNames count (2)",
            "weights: 1 values = 2 keys × 1 targets",
        ],
    );
}

/// Scene files built from random keys and values: `run` answers with an error or a bake, never a
/// panic.
#[test]
fn random_scene_files_never_panic() {
    use proptest::prelude::*;
    let dir = tempfile::tempdir().unwrap();
    let keys = [
        "pin",
        "gravity",
        "stiffness",
        "damping",
        "fps",
        "solver",
        "interpolation",
        "normals",
        "mass",
        "density",
        "substeps",
        "iterations",
        "object",
        "bogus",
        "resolution",
        "input",
    ];
    let value = prop_oneof![
        Just("\"box:-1,-1,-1,1,1,1\"".to_string()),
        Just("[\"index:0\", \"index:3\"]".to_string()),
        Just("\"0,-9.81,0\"".to_string()),
        (-5i64..50).prop_map(|i| i.to_string()),
        (-2.0f64..100.0).prop_map(|f| format!("{f:.3}")),
        Just("true".to_string()),
        Just("{ a = 1 }".to_string()),
        Just("\"off\"".to_string()),
        "\"[ -~&&[^\"\\\\]]{0,12}\"",
    ];
    let strategy = prop::collection::vec((0..keys.len(), value), 0..4);
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig::with_cases(48));
    let scene = dir.path().join("s.toml");
    runner
        .run(&strategy, |entries| {
            let mut text =
                String::from("[[cloth]]\npreset = \"lab-cloth\"\nframes = 2\noutput = \"o.glb\"\n");
            let mut seen = std::collections::HashSet::new();
            for (k, v) in entries {
                let key = keys[k];
                if seen.insert(key) {
                    // Keep bakes tiny: a random resolution could ask for millions of particles.
                    let v = if key == "resolution" {
                        "4".to_string()
                    } else {
                        v
                    };
                    text.push_str(&format!("{key} = {v}\n"));
                }
            }
            std::fs::write(&scene, &text).unwrap();
            let (code, err) = scenebake(["-q", "run", scene.to_str().unwrap()]);
            prop_assert!(
                code == 0 || code == 1 || code == 2,
                "exit {code} for\n{text}\n{err}"
            );
            prop_assert!(!err.contains("panicked"), "panic for\n{text}\n{err}");
            if code != 0 {
                prop_assert!(
                    err.contains("s.toml"),
                    "error does not name the scene file:\n{text}\n{err}"
                );
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn inspect_rejects_a_file_the_gltf_crate_would_panic_on() {
    fails_with(
        &[
            "inspect",
            fixture("position_accessor_out_of_range.gltf")
                .to_str()
                .unwrap(),
        ],
        &["refers to accessor 0, but the file has 0 accessors"],
    );
}

#[test]
fn bad_ik_options_name_the_option_or_joint() {
    let dir = tempfile::tempdir().unwrap();
    let out = out_path(&dir);
    let fox = mesh("Fox.glb");
    let fox = fox.to_str().unwrap();
    let cases: &[(&[&str], &[&str])] = &[
        (
            &["--preset", "lab-arm", "--curve", "spiral"],
            &["--curve", "spiral", "circle"],
        ),
        (
            &["--preset", "lab-arm", "--text", ""],
            &["--text", "nothing to draw"],
        ),
        (&["--preset", "lab-arm"], &["--curve"]),
        (
            &["--preset", "lab-arm", "--curve", "circle", "--text", "HI"],
            &["--curve", "--text"],
        ),
        (&["--curve", "circle"], &["--preset"]),
        (
            &["--preset", "lab-arm", "--curve", "circle", "--fps", "0"],
            &["--fps", "positive"],
        ),
        (
            &[
                "--preset", "lab-arm", "--curve", "circle", "--center", "1,2",
            ],
            &["--center", "3 comma-separated"],
        ),
        (
            &["--preset", "lab-arm", "--text", "café", "--font", "script"],
            &["font `script`", "'é'"],
        ),
        (
            &["--preset", "lab-arm", "--text", "hi", "--font", "comic"],
            &["--font", "comic", "cursive"],
        ),
        (
            &[
                "--joints",
                "3",
                "--curve",
                "circle",
                "--limit",
                "elbow:cone:30",
            ],
            &["--limit", "elbow", "joint_1"],
        ),
        (
            &[
                "--preset", "lab-arm", "--curve", "circle", "--normal", "0,0,0",
            ],
            &["--normal", "non-zero"],
        ),
        (
            &[
                "--preset",
                "lab-arm",
                "--curve",
                "circle",
                "--trail-radius",
                "0",
            ],
            &["error: invalid value for --trail-radius: 0: must be a positive number"],
        ),
        (
            &[
                "--preset",
                "lab-arm",
                "--curve",
                "circle",
                "--trail-radius",
                "-0.5",
            ],
            &["error: invalid value for --trail-radius: -0.5: must be a positive number"],
        ),
        (
            &[
                "--preset",
                "lab-arm",
                "--curve",
                "circle",
                "--trail-radius",
                "inf",
            ],
            &["error: invalid value for --trail-radius: inf: must be a positive number"],
        ),
        (
            &[
                "--rig",
                fox,
                "--chain",
                "b_Spine01_02..b_Nope",
                "--curve",
                "heart",
            ],
            &["Fox.glb", "b_Nope"],
        ),
        (
            &[
                "--rig",
                fox,
                "--chain",
                "b_Head_05..b_Spine01_02",
                "--curve",
                "heart",
            ],
            &["Fox.glb", "not below"],
        ),
        (
            &[
                "--rig",
                "/nonexistent/rig.glb",
                "--chain",
                "a..b",
                "--curve",
                "heart",
            ],
            &["/nonexistent/rig.glb"],
        ),
    ];
    for (extra, words) in cases {
        let mut args = vec!["ik", "-o", &out];
        args.extend_from_slice(extra);
        fails_with(&args, words);
    }
}

/// Ctrl-C while the output is being written: the bake is stopped (SIGSTOP) as soon as its
/// temporary appears beside the earlier export, interrupted, and let go. Exit status 130, the
/// earlier export intact, the temporary gone. The bake is cheap to simulate (one local/global
/// iteration per step) but its output is large (about 140 MB without sparse accessors), so the
/// temporary is written for long enough to be caught.
#[cfg(unix)]
#[test]
fn an_interrupted_bake_loses_nothing() {
    use common::cli::signal;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.glb");
    std::fs::write(&out, b"earlier export").unwrap();
    let mut child = common::cli::bin()
        .args([
            "-q",
            "cloth",
            "--preset",
            "lab-cloth",
            "--resolution",
            "120",
            "--frames",
            "400",
            "--solver",
            "fast",
            "--iterations",
            "1",
            "--sparse",
            "off",
            "-o",
            out.to_str().unwrap(),
        ])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let is_temporary = |n: &str| n.starts_with(".keep.glb.") && n.ends_with(".tmp");
    let temporary = loop {
        if let Some(n) = names_in(dir.path()).into_iter().find(|n| is_temporary(n)) {
            break dir.path().join(n);
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the bake ended ({status}) before a temporary was seen");
        }
        std::thread::sleep(std::time::Duration::from_micros(500));
    };
    signal(child.id(), "STOP");
    // Stopped mid-write: the temporary is there and the earlier export not yet replaced.
    assert!(
        temporary.exists(),
        "the temporary was renamed before the bake could be stopped"
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"earlier export");
    signal(child.id(), "INT");
    signal(child.id(), "CONT");
    let done = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&done.stderr);
    assert_eq!(
        done.status.code(),
        Some(130),
        "the handler exits with 130: {err}"
    );
    assert!(err.contains("nothing was written"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"earlier export");
    assert_eq!(
        names_in(dir.path()),
        ["keep.glb"],
        "the temporary is removed"
    );
}

/// A write failing midway, without any hook in the program: the file-size limit (RLIMIT_FSIZE,
/// `ulimit -f`, with SIGXFSZ ignored so that write(2) returns EFBIG) stops the output after 64
/// KiB of about 1 MB. The error names the file, the earlier `.gltf` and `.bin` are untouched and
/// no temporary is left.
#[cfg(unix)]
#[test]
fn a_write_failing_midway_keeps_the_earlier_export() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.gltf");
    std::fs::write(&out, b"earlier export").unwrap();
    std::fs::write(dir.path().join("keep.bin"), b"earlier buffer").unwrap();
    let run = |limit_kib: u32| {
        // POSIX sh counts `ulimit -f` in 512-byte blocks.
        let script = format!(
            "trap '' XFSZ; ulimit -f {}; exec \"$0\" \"$@\"",
            limit_kib * 2
        );
        Command::new("sh")
            .args(["-c", &script, env!("CARGO_BIN_EXE_scenebake")])
            .args(["-q", "cloth", "--preset", "lab-cloth", "--resolution", "30"])
            .args([
                "--frames",
                "40",
                "--sparse",
                "off",
                "-o",
                out.to_str().unwrap(),
            ])
            .output()
            .unwrap()
    };
    let failed = run(64);
    let err = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(1), "{err}");
    assert!(
        err.contains("keep.") && err.contains("File too large"),
        "the error names the file and the cause: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"earlier export");
    assert_eq!(
        std::fs::read(dir.path().join("keep.bin")).unwrap(),
        b"earlier buffer"
    );
    assert_eq!(names_in(dir.path()), ["keep.bin", "keep.gltf"]);
    // The same bake under a limit it fits in replaces both files: the failure was the limit.
    let done = run(64 * 1024);
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    assert!(
        std::fs::metadata(dir.path().join("keep.bin"))
            .unwrap()
            .len()
            > 64 * 1024
    );
    common::load(&out);
}

/// A scene of independent jobs of both kinds (paths relative to the scene's folder).
fn parallel_scene(dir: &Path) -> std::path::PathBuf {
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "[[cloth]]\nname = \"lab\"\npreset = \"lab-cloth\"\nframes = 30\noutput = \"out/lab.glb\"\n\n\
             [[cloth]]\nname = \"plane\"\ninput = \"{}\"\nframes = 10\npin = \"box:-1,-1,-1,1,1,-0.49\"\noutput = \"out/plane.glb\"\n\n\
             [[cloth]]\nname = \"fast\"\npreset = \"lab-cloth\"\nsolver = \"fast\"\nframes = 20\noutput = \"out/fast.gltf\"\n\n\
             [[ik]]\nname = \"circle\"\npreset = \"lab-arm\"\ncurve = \"circle\"\noutput = \"out/circle.glb\"\n",
            mesh("plane_30x30.obj").display()
        ),
    )
    .unwrap();
    scene
}

#[test]
fn jobs_in_parallel_write_the_same_bytes_and_shards_split_the_jobs() {
    let one = tempfile::tempdir().unwrap();
    let two = tempfile::tempdir().unwrap();
    for (dir, jobs) in [(one.path(), "1"), (two.path(), "2")] {
        let scene = parallel_scene(dir);
        let (code, err) = scenebake(["run", scene.to_str().unwrap(), "--jobs", jobs]);
        assert_eq!(code, 0, "{err}");
        // Each job's summary line reaches a non-terminal stderr too, numbered in file order.
        assert!(err.contains("[1/4] lab: baked 30 frames"), "{err}");
        assert!(err.contains("[4/4] circle: baked 150 frames"), "{err}");
    }
    let files = names_in(&one.path().join("out"));
    assert_eq!(files.len(), 5, "{files:?}"); // four outputs and the .bin of the .gltf
    assert_eq!(files, names_in(&two.path().join("out")));
    for f in &files {
        let a = std::fs::read(one.path().join("out").join(f)).unwrap();
        let b = std::fs::read(two.path().join("out").join(f)).unwrap();
        assert!(a == b, "{f} differs between --jobs 1 and --jobs 2");
    }

    // --shard I/N: jobs I, I+N, ... in file order.
    let sharded = tempfile::tempdir().unwrap();
    let scene = parallel_scene(sharded.path());
    let (code, err) = scenebake(["run", scene.to_str().unwrap(), "--shard", "2/3"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(names_in(&sharded.path().join("out")), vec!["plane.glb"]);
    let (code, err) = scenebake(["run", scene.to_str().unwrap(), "--shard", "1/3"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        names_in(&sharded.path().join("out")),
        vec!["circle.glb", "lab.glb", "plane.glb"]
    );
    fails_with(
        &["run", scene.to_str().unwrap(), "--shard", "4/3"],
        &["--shard", "1 ≤ I ≤ N"],
    );
}
