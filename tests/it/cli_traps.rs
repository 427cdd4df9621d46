//! The traps a new user hit in a trial run (issue 13), each closed with the exact message the
//! command line now prints.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn crate_path(rel: &str) -> PathBuf {
    common::crate_dir().join(rel)
}

fn s(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// Runs scenebake in `dir`; returns (exit code, stdout, stderr).
fn run(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let out = common::cli::bin()
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Asserts a failure (exit 1) whose stderr is exactly `message` plus a newline, nothing written.
#[track_caller]
fn fails_exactly(dir: &Path, args: &[&str], message: &str) {
    let before: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    let (code, _, err) = run(dir, args);
    assert_eq!(code, 1, "{args:?}: {err}");
    assert_eq!(err, format!("{message}\n"), "{args:?}");
    let after: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(before, after, "{args:?} wrote something");
}

#[test]
fn options_that_do_not_apply_to_the_input_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let obj = s(&crate_path("meshes/plane_30x30.obj"));
    let glb = s(&crate_path("meshes/Fox.glb"));
    fails_exactly(
        dir.path(),
        &["cloth", &obj, "--mesh", "cloth", "-o", "x.glb"],
        &format!("error: invalid value for --mesh: picks a mesh of a .gltf/.glb input, and {obj} is not one (for an OBJ, --object NAME picks an object or group)"),
    );
    fails_exactly(
        dir.path(),
        &["cloth", &glb, "--object", "cloth", "-o", "x.glb"],
        &format!("error: invalid value for --object: picks an object or group of an .obj input, and {glb} is not one (for a glTF, --mesh NAME picks a mesh)"),
    );
    fails_exactly(
        dir.path(),
        &["cloth", "--preset", "lab-cloth", "--object", "cloth", "-o", "x.glb"],
        "error: invalid value for --object: picks part of an input file; the lab-cloth preset has none",
    );
    fails_exactly(
        dir.path(),
        &["cloth", &obj, "--solver", "fast", "--linear-solver", "multigrid", "-o", "x.glb"],
        "error: invalid value for --linear-solver: how Newton solves for its directions; the fast solver has one prefactored matrix (choose the newton solver, or leave the linear solver out)",
    );
}

/// `--pin-smooth` is a distance: a negative or non-finite one is refused, naming the option,
/// before the rig is read or anything written.
#[test]
fn a_pin_smoothing_radius_must_be_a_distance() {
    let dir = tempfile::tempdir().unwrap();
    let obj = s(&crate_path("meshes/garments/fox_cape.obj"));
    let glb = s(&crate_path("meshes/Fox.glb"));
    for (bad, shown) in [("-0.1", "-0.1"), ("nan", "NaN"), ("inf", "inf")] {
        fails_exactly(
            dir.path(),
            &["cloth", &obj, "--rig", &glb, &format!("--pin-smooth={bad}"), "-o", "x.glb"],
            &format!("error: invalid value for --pin-smooth: {shown}: must be zero or a positive number of metres"),
        );
    }
}

/// `--loop-blend` is a duration within the loops: a negative or non-finite one, one longer than
/// the written loops, or one reaching back before the warm-up loops is refused, naming the
/// option (and the warm-up loops where more would do), before anything is simulated or written.
#[test]
fn a_loop_blend_must_fit_the_loops() {
    let dir = tempfile::tempdir().unwrap();
    let obj = s(&crate_path("meshes/garments/fox_cape.obj"));
    let glb = s(&crate_path("meshes/Fox.glb"));
    let fox = [
        "cloth",
        &obj,
        "--rig",
        &glb,
        "--animation",
        "Walk",
        "--rig-scale",
        "0.01",
        "-o",
        "x.glb",
    ];
    for (bad, shown) in [("-0.1", "-0.1"), ("nan", "NaN"), ("inf", "inf")] {
        fails_exactly(
            dir.path(),
            &[&fox[..], &[&format!("--loop-blend={bad}")]].concat(),
            &format!("error: invalid value for --loop-blend: {shown}: must be zero or a positive number of seconds"),
        );
    }
    // Fox's Walk is 0.708 s: 21 frames a loop at 30 fps.
    fails_exactly(
        dir.path(),
        &[&fox[..], &["--loop-blend", "2"]].concat(),
        "error: invalid value for --loop-blend: 2 s: 59 frames at 29.647 fps, longer than the written loops (21 frames)",
    );
    fails_exactly(
        dir.path(),
        &[&fox[..], &["--loop-blend", "0.2", "--warmup-cycles", "0"]].concat(),
        "error: invalid value for --loop-blend: 0.2 s: the last 6 written frames are steered onto the 6 frames before the written loops, but only 0 warm-up frames precede them; raise --warmup-cycles",
    );
}

/// The triangle membrane is a fabric model of Newton's: with the fast solver, the labs'
/// springs or their preset it is an error naming the option, before anything is written.
#[test]
fn the_triangle_membrane_is_refused_where_it_does_not_apply() {
    let dir = tempfile::tempdir().unwrap();
    let obj = s(&crate_path("meshes/plane_30x30.obj"));
    fails_exactly(
        dir.path(),
        &["cloth", &obj, "--membrane", "triangles", "--solver", "fast", "-o", "x.glb"],
        "error: invalid value for --membrane: triangles: the triangle membrane is part of Newton's solve; the fast solver has springs only (choose the newton solver)",
    );
    fails_exactly(
        dir.path(),
        &["cloth", &obj, "--membrane", "triangles", "--stiffness", "100", "-o", "x.glb"],
        "error: invalid value for --membrane: --stiffness sets the labs' symmetric springs (N/m per spring); --membrane sets a fabric mapped onto the mesh: give one or the other",
    );
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--membrane",
            "triangles",
            "-o",
            "x.glb",
        ],
    );
    assert_eq!(code, 1);
    assert!(
        err.starts_with("error: invalid value for --membrane: the lab-cloth preset"),
        "{err}"
    );
}

#[test]
fn an_absurd_frame_count_is_refused_before_baking() {
    let dir = tempfile::tempdir().unwrap();
    let obj = s(&crate_path("meshes/plane_30x30.obj"));
    // 961 vertices × 24 bytes (position and normal) a frame: 4 GiB hold 186,219 frames.
    fails_exactly(
        dir.path(),
        &["cloth", &obj, "--frames", "1000000000", "-o", "x.glb"],
        "error: invalid value for --frames: 1000000000: 1000000000 frames of 961 vertices need about 23.1 TB in memory and in the output, over the 4.3 GB a GLB can hold; at most 186218 frames fit (--keyframe-tolerance shrinks the file, not the bake)",
    );
    assert_eq!(4_294_967_295u64 / (961 * 24), 186_219);
}

#[test]
fn scene_files_empty_or_misspelt_are_errors_with_a_suggestion() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("empty.toml"), "# nothing yet\n").unwrap();
    fails_exactly(
        dir.path(),
        &["run", "empty.toml"],
        "error: empty.toml: no jobs: a scene lists [[cloth]] and [[ik]] tables (see scenes/demo.toml)",
    );
    std::fs::write(
        dir.path().join("typo.toml"),
        "[[cloth]]\nname = \"lab\"\npreset = \"lab-cloth\"\nstifness = 3\noutput = \"a.glb\"\n",
    )
    .unwrap();
    let (code, _, err) = run(dir.path(), &["run", "typo.toml"]);
    assert_eq!(code, 1);
    assert!(
        err.starts_with("error: typo.toml: [[cloth]] job 1 (`lab`): unknown key `stifness` (did you mean `stiffness`? keys: ")
            && err.ends_with(")\n")
            && err.lines().count() == 1,
        "{err}"
    );
    // The keys are listed in order, the scene keys of `scenebake cloth`'s options among them
    // (the list grows with new options, so no fixed slice of it is asserted).
    let keys: Vec<&str> = err
        .trim_end()
        .trim_end_matches(')')
        .split("keys: ")
        .nth(1)
        .unwrap()
        .split(", ")
        .collect();
    assert!(keys.windows(2).all(|w| w[0] < w[1]), "{keys:?}");
    for key in [
        "bend_stiffness",
        "collider",
        "frames",
        "output",
        "stiffness",
        "up",
    ] {
        assert!(keys.contains(&key), "{key} missing from {keys:?}");
    }
    std::fs::write(
        dir.path().join("kind.toml"),
        "[[clth]]\npreset = \"lab-cloth\"\n",
    )
    .unwrap();
    fails_exactly(
        dir.path(),
        &["run", "kind.toml"],
        "error: kind.toml: unknown table `clth` (did you mean [[cloth]]? jobs are [[cloth]], [[ik]])",
    );
    // Far from every key: no suggestion.
    std::fs::write(
        dir.path().join("far.toml"),
        "[[cloth]]\npreset = \"lab-cloth\"\nzzzzzz = 1\noutput = \"a.glb\"\n",
    )
    .unwrap();
    let (_, _, err) = run(dir.path(), &["run", "far.toml"]);
    assert!(err.contains("unknown key `zzzzzz` (keys: "), "{err}");
}

#[test]
fn warnings_and_each_file_size_are_printed() {
    let dir = tempfile::tempdir().unwrap();
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--frames",
            "3",
            "--solver",
            "newton",
            "--max-newton",
            "1",
            "--tolerance",
            "1e-15",
            "-o",
            "w.glb",
            "--vat",
            "w.exr",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "{err}");
    let size = |f: &str| {
        let n = std::fs::metadata(dir.path().join(f)).unwrap().len();
        match n {
            n if n >= 1 << 20 => format!("{:.1} MiB", n as f64 / (1u64 << 20) as f64),
            n if n >= 1 << 10 => format!("{:.1} KiB", n as f64 / 1024.0),
            n => format!("{n} B"),
        }
    };
    assert!(
        lines[0].ends_with(&format!(
            "; wrote w.glb ({}), w.exr ({}), w.normals.exr ({}), w.json ({})",
            size("w.glb"),
            size("w.exr"),
            size("w.normals.exr"),
            size("w.json")
        )),
        "{}",
        lines[0]
    );
    assert!(
        lines[1].starts_with(
            "warning: lab_cloth: 3 of 3 frames ended above the tolerance \
             0.000000000000001 (worst "
        ) && lines[1]
            .ends_with("); raise --max-iterations or --substeps, or see unconverged_frames"),
        "{}",
        lines[1]
    );
}

/// RiggedSimple with 40 vertices' weights halved, in `dir` as `halved.gltf`.
fn halved_rig(dir: &Path) -> PathBuf {
    let src = crate_path("meshes/RiggedSimple.gltf");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    let acc = &json["accessors"][json["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"]
        .as_u64()
        .unwrap() as usize];
    let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    let offset = view["byteOffset"].as_u64().unwrap() as usize
        + acc["byteOffset"].as_u64().unwrap_or(0) as usize;
    let stride = view["byteStride"].as_u64().unwrap_or(16) as usize;
    let mut bin = std::fs::read(crate_path("meshes/RiggedSimple0.bin")).unwrap();
    for v in 0..40 {
        for c in 0..4 {
            let at = offset + v * stride + c * 4;
            let w = f32::from_le_bytes(bin[at..at + 4].try_into().unwrap()) * 0.5;
            bin[at..at + 4].copy_from_slice(&w.to_le_bytes());
        }
    }
    std::fs::write(dir.join("RiggedSimple0.bin"), bin).unwrap();
    std::fs::copy(&src, dir.join("halved.gltf")).unwrap();
    dir.join("halved.gltf")
}

#[test]
fn inspect_reports_weight_sums_and_a_node_cycle() {
    let dir = tempfile::tempdir().unwrap();
    halved_rig(dir.path());
    let (code, out, err) = run(dir.path(), &["inspect", "halved.gltf"]);
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("    FAILED: meshes[0].primitives[0] skin weights sum to 1 (40 of 160 vertices sum to 0.500–0.500; an IK bake with this file as its rig renormalises them)\n"),
        "{out}"
    );
    assert!(
        err.starts_with("error: halved.gltf: 1 invariant check(s) failed: "),
        "{err}"
    );

    // The rig baked: renormalised, with a warning on the terminal; the output inspects clean.
    let (code, _, err) = run(
        dir.path(),
        &[
            "ik",
            "--rig",
            "halved.gltf",
            "--chain",
            "Bone..Bone.001",
            "--curve",
            "circle",
            "-o",
            "out.glb",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.ends_with("warning: out: halved.gltf: renormalised the skin weights of 40 vertices (they summed to 0.500–0.500, glTF requires 1)\n"),
        "{err}"
    );
    let (code, out, _) = run(dir.path(), &["inspect", "out.glb"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("  checks: "), "{out}");

    let cycle = s(&crate_path("tests/fixtures/node_cycle.gltf"));
    let (code, out, err) = run(dir.path(), &["inspect", &cycle]);
    assert_eq!(code, 1);
    assert!(
        out.contains(
            "      #0 hip\n        #1 knee\n          #2 (unnamed)\n            #1 (again: the hierarchy loops here)\n"
        ),
        "{out}"
    );
    assert!(
        out.contains("    FAILED: nodes: the hierarchy has no cycle (found #1 → #2 → #1)\n"),
        "{out}"
    );
    assert_eq!(
        err,
        format!("error: {cycle}: 2 invariant check(s) failed: nodes: every node has at most one parent (#1 is a child of #0 and #2); nodes: the hierarchy has no cycle (found #1 → #2 → #1)\n")
    );
}

#[test]
fn rig_joints_are_listed_with_their_index_and_blenders_names_work() {
    let dir = tempfile::tempdir().unwrap();
    let fox = s(&crate_path("meshes/Fox.glb"));
    let (code, out, _) = run(dir.path(), &["inspect", &fox]);
    assert_eq!(code, 0);
    assert!(
        out.contains("  skin #0: 24 joints (_rootJoint #2, b_Root_00 #3, b_Hip_01 #4,"),
        "{out}"
    );
    assert!(
        out.contains(
            "              #5 b_Spine01_02 [joint]\n                #6 b_Spine02_03 [joint]\n"
        ),
        "{out}"
    );
    // SimpleSkin's nodes have no names: Blender shows them as Node_N, which --chain accepts.
    let simple = s(&crate_path("meshes/SimpleSkin.gltf"));
    let (_, _, err) = run(
        dir.path(),
        &[
            "ik",
            "--rig",
            &simple,
            "--chain",
            "Node_1..Node_2",
            "--curve",
            "square",
            "-o",
            "s.glb",
        ],
    );
    // The chain is found (and then refused for its zero-length bone, as with #1..#2).
    assert!(err.contains("#2") && err.contains("length 0"), "{err}");
    let (_, _, err) = run(
        dir.path(),
        &[
            "ik",
            "--rig",
            &fox,
            "--chain",
            "Node_5..b_Head_05",
            "--curve",
            "square",
            "-o",
            "s.glb",
        ],
    );
    assert_eq!(
        err,
        format!("error: {fox}: --chain: no node named `Node_5` (use a node name, `#N` for node N, quoted in a shell as in '#13..#15', or Blender's `Node_N`; `scenebake inspect {fox}` lists them)\n")
    );
}

#[test]
fn open_says_when_blender_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.glb"), b"glTF").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_scenebake"))
        .args(["open", "a.glb"])
        .current_dir(dir.path())
        .env("PATH", dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "error: blender is not on PATH: install Blender 3.4 or later (https://www.blender.org/download/, or `apt install blender`), or give its executable with --blender PATH\n"
    );
    let (code, _, err) = run(
        dir.path(),
        &["open", "a.glb", "--blender", "/no/such/blender"],
    );
    assert_eq!(code, 1);
    assert_eq!(
        err,
        "error: invalid value for --blender: /no/such/blender: no such file (give the path of the Blender executable)\n"
    );
    let (_, _, err) = run(dir.path(), &["open", "missing.glb"]);
    assert_eq!(err, "error: missing.glb: no such file\n");
}

/// A Z-up OBJ (Bullet's cloth_z_up, a sheet in z = 0) with `--up z` arrives lying in y = 0:
/// the glTF's base positions are the file's `v` lines turned (x, y, z) → (x, z, −y).
#[test]
fn up_z_turns_a_z_up_input_to_y_up() {
    let dir = tempfile::tempdir().unwrap();
    let obj = crate_path("meshes/cloth_z_up.obj");
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth",
            &s(&obj),
            "--up",
            "z",
            "--frames",
            "2",
            "-o",
            "up.glb",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let (doc, buffers, _) = common::gltf_read::import(dir.path().join("up.glb")).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    let got: Vec<[f32; 3]> = prim
        .reader(|b| Some(&buffers[b.index()]))
        .read_positions()
        .unwrap()
        .collect();
    let key = |p: [f64; 3]| p.map(|c| (c * 1e5).round() as i64);
    let mut want: Vec<[i64; 3]> = std::fs::read_to_string(&obj)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            key([v[0], v[2], -v[1]])
        })
        .collect();
    want.sort();
    want.dedup();
    let mut got_keys: Vec<[i64; 3]> = got.iter().map(|p| key(p.map(f64::from))).collect();
    got_keys.sort();
    got_keys.dedup();
    assert_eq!(got_keys, want);
    assert!(
        got.iter().all(|p| p[1].abs() < 1e-6),
        "the sheet lies in y = 0"
    );
    fails_exactly(
        dir.path(),
        &["cloth", "--preset", "lab-cloth", "--up", "z", "-o", "x.glb"],
        "error: invalid value for --up: places an input file; the lab-cloth preset keeps the labs' coordinates",
    );
}

/// Ctrl-C in `run` after a job finished: the message names the file that job replaced.
#[cfg(unix)]
#[test]
fn an_interrupted_run_names_the_outputs_it_already_replaced() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("two.toml"),
        "[[cloth]]\nname = \"quick\"\npreset = \"lab-cloth\"\nframes = 2\noutput = \"quick.glb\"\n\n[[cloth]]\nname = \"long\"\npreset = \"lab-cloth\"\nresolution = 150\nframes = 1500\noutput = \"long.glb\"\n",
    )
    .unwrap();
    let child = common::cli::bin()
        .args(["-q", "run", "two.toml"])
        .current_dir(dir.path())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    common::cli::signal(child.id(), "INT");
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(130));
    assert_eq!(
        String::from_utf8_lossy(&out.stderr),
        "\ninterrupted: the job being baked wrote nothing, but finished jobs of this run replaced 1 file: quick.glb\n"
    );
    assert!(!dir.path().join("long.glb").exists());
}

/// The OBJ's `v` lines of object `object` (every object when `None`), read here independently.
fn obj_object_positions(path: &Path, object: Option<&str>) -> Vec<[f64; 3]> {
    let mut current = String::new();
    let mut out = Vec::new();
    for line in std::fs::read_to_string(path).unwrap().lines() {
        if let Some(name) = line.strip_prefix("o ") {
            current = name.trim().to_owned();
        } else if let Some(v) = line.strip_prefix("v ") {
            if object.is_none_or(|o| o == current) {
                let c: Vec<f64> = v.split_whitespace().map(|x| x.parse().unwrap()).collect();
                out.push([c[0], c[1], c[2]]);
            }
        }
    }
    out
}

/// Mesh `name` of a written glTF: its distinct positions (rounded to 0.01 mm) and triangle count.
fn written_mesh(path: &Path, name: &str) -> (Vec<[i64; 3]>, usize) {
    let (doc, buffers, _) = common::gltf_read::import(path).unwrap();
    let mesh = doc
        .meshes()
        .find(|m| m.name() == Some(name))
        .unwrap_or_else(|| panic!("{}: no mesh {name}", path.display()));
    let (mut keys, mut triangles) = (Vec::new(), 0);
    for prim in mesh.primitives() {
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let p: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        triangles += reader
            .read_indices()
            .map_or(p.len(), |i| i.into_u32().count())
            / 3;
        keys.extend(
            p.iter()
                .map(|p| p.map(|c| (f64::from(c) * 1e5).round() as i64)),
        );
    }
    keys.sort();
    keys.dedup();
    (keys, triangles)
}

fn keys(points: &[[f64; 3]]) -> Vec<[i64; 3]> {
    let mut k: Vec<[i64; 3]> = points
        .iter()
        .map(|p| p.map(|c| (c * 1e5).round() as i64))
        .collect();
    k.sort();
    k.dedup();
    k
}

/// `mesh:FILE.obj#OBJECT` takes that object only, `mesh:FILE.glb[#NAME]` reads a glTF (it was
/// refused as "not a text file"), `--up z` turns a collider file like the input, and a missing
/// object is an error naming the file and listing what it holds. What each bake used is read
/// back from the collider it writes into its glTF and compared with the OBJ's `v` lines.
#[test]
fn a_mesh_collider_takes_one_object_and_reads_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let table = crate_path("meshes/table.obj");
    let bake = |collider: &str, out: &str| {
        let (code, _, err) = run(
            dir.path(),
            &[
                "cloth",
                "--preset",
                "lab-cloth",
                "--frames",
                "2",
                "--collider",
                collider,
                "-o",
                out,
            ],
        );
        assert_eq!(code, 0, "{collider}: {err}");
        dir.path().join(out)
    };

    // The whole table (5 objects, 12 triangles each), then its top only.
    let all = bake(&format!("mesh:{}", s(&table)), "all.glb");
    let (got, triangles) = written_mesh(&all, "collider_1");
    assert_eq!(
        (got, triangles),
        (keys(&obj_object_positions(&table, None)), 60)
    );
    let top = bake(&format!("mesh:{}#top", s(&table)), "top.glb");
    let (top_keys, triangles) = written_mesh(&top, "collider_1");
    assert_eq!(
        (&top_keys, triangles),
        (&keys(&obj_object_positions(&table, Some("top"))), 12)
    );

    // A glTF collider: the top as the previous bake wrote it, by node name; and without a name,
    // every mesh node of the file (the lab cloth's 200 triangles and the top's 12).
    let again = bake("mesh:top.glb#collider_1", "again.glb");
    assert_eq!(written_mesh(&again, "collider_1"), (top_keys.clone(), 12));
    let every = bake("mesh:top.glb", "every.glb");
    assert_eq!(written_mesh(&every, "collider_1").1, 212);

    // --up z turns the collider file as it turns the input.
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth",
            &s(&crate_path("meshes/cloth_z_up.obj")),
            "--up",
            "z",
            "--frames",
            "1",
            "--collider",
            &format!("mesh:{}#top", s(&table)),
            "-o",
            "up.glb",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let turned: Vec<[f64; 3]> = obj_object_positions(&table, Some("top"))
        .iter()
        .map(|p| [p[0], p[2], -p[1]])
        .collect();
    assert_eq!(
        written_mesh(&dir.path().join("up.glb"), "collider_1").0,
        keys(&turned)
    );

    // Missing objects: the file, the name and what there is.
    fails_exactly(
        dir.path(),
        &["cloth", "--preset", "lab-cloth", "--collider", &format!("mesh:{}#lid", s(&table)), "-o", "x.glb"],
        &format!("error: invalid value for --collider: {}: no object or group named `lid` with faces (known: leg1, leg2, leg3, leg4, top)", s(&table)),
    );
    fails_exactly(
        dir.path(),
        &["cloth", "--preset", "lab-cloth", "--collider", "mesh:top.glb#lid", "-o", "x.glb"],
        "error: invalid value for --collider: top.glb: no mesh or mesh node named `lid` (meshes: lab_cloth, collider_1; nodes with a mesh: lab_cloth, collider_1)",
    );
    fails_exactly(
        dir.path(),
        &["cloth", "--preset", "lab-cloth", "--collider", "mesh:body.tet", "-o", "x.glb"],
        "error: invalid value for --collider: mesh:body.tet: a mesh collider is an .obj, .gltf or .glb file",
    );
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--collider",
            "mesh:top.glb#",
            "-o",
            "x.glb",
        ],
    );
    assert_eq!(code, 2);
    assert!(
        err.contains("`mesh:top.glb#`: the object name after `#` is empty (mesh:top.glb#NAME, or mesh:top.glb for every object)"),
        "{err}"
    );
}

/// Every file a README example writes (`-o`, `--report`, `--vat` and the files beside them),
/// with the command line that writes it.
fn readme_outputs(readme: &str) -> Vec<(String, String)> {
    let mut commands = Vec::new();
    let mut current = String::new();
    for line in readme.lines() {
        let line = line.split(" # ").next().unwrap_or("").trim();
        if current.is_empty() && !line.starts_with("scenebake ") {
            continue;
        }
        current.push_str(line.trim_end_matches('\\'));
        current.push(' ');
        if !line.ends_with('\\') {
            commands.push(std::mem::take(&mut current));
        }
    }
    let mut out = Vec::new();
    for cmd in commands {
        let words: Vec<&str> = cmd.split_whitespace().collect();
        for pair in words.windows(2) {
            let file = pair[1].to_owned();
            match pair[0] {
                "-o" | "--output" | "--report" => {
                    if let Some(stem) = file.strip_suffix(".gltf") {
                        out.push((format!("{stem}.bin"), cmd.clone()));
                    }
                    out.push((file, cmd.clone()));
                }
                "--vat" => {
                    let stem = file.trim_end_matches(".exr");
                    out.push((format!("{stem}.normals.exr"), cmd.clone()));
                    out.push((format!("{stem}.json"), cmd.clone()));
                    out.push((file, cmd.clone()));
                }
                _ => {}
            }
        }
    }
    out
}

/// No two README examples write the same file (they overwrote each other's outputs).
#[test]
fn readme_examples_write_distinct_files() {
    let readme = std::fs::read_to_string(crate_path("README.md")).unwrap();
    let outputs = readme_outputs(&readme);
    assert!(outputs.len() >= 15, "{outputs:?}");
    let mut seen = std::collections::HashMap::new();
    for (file, cmd) in &outputs {
        if let Some(first) = seen.insert(file.clone(), cmd.clone()) {
            panic!("README examples both write {file}:\n  {first}\n  {cmd}");
        }
    }
}

/// Every cloth encoding records the bake's fps and frame range in asset.extras (Blender keeps its
/// scene at 24 fps and frames 1–250 otherwise; `--basis` exports had no record), and the record
/// agrees with the animation it names: the first, whose last key is at frame_end / fps.
#[test]
fn every_cloth_encoding_records_fps_and_frame_range() {
    let dir = tempfile::tempdir().unwrap();
    for (out, extra) in [
        ("plain.glb", &[][..]),
        ("compact.glb", &["--keyframe-tolerance", "0.001"][..]),
        ("basis.glb", &["--basis", "auto", "--quantize", "off"][..]),
        ("step.gltf", &["--interpolation", "step"][..]),
    ] {
        let mut args = vec![
            "cloth",
            "--preset",
            "lab-cloth",
            "--fps",
            "60",
            "--frames",
            "12",
            "--name",
            "sheet",
            "-o",
            out,
        ];
        args.extend_from_slice(extra);
        let (code, _, err) = run(dir.path(), &args);
        assert_eq!(code, 0, "{out}: {err}");
        let (doc, buffers, _) = common::gltf_read::import(dir.path().join(out)).unwrap();
        let extras: serde_json::Value =
            serde_json::from_str(doc.as_json().asset.extras.as_ref().expect(out).get()).unwrap();
        assert_eq!(
            extras["scenebake"],
            serde_json::json!({"fps": 60.0, "frame_start": 0, "frame_end": 12, "animation": "sheet"}),
            "{out}"
        );
        let anim = doc.animations().next().unwrap();
        assert_eq!(anim.name(), Some("sheet"), "{out}");
        let times: Vec<f32> = anim
            .channels()
            .next()
            .unwrap()
            .reader(|b| Some(&buffers[b.index()]))
            .read_inputs()
            .unwrap()
            .collect();
        assert!(
            (f64::from(*times.last().unwrap()) - 12.0 / 60.0).abs() < 1e-6,
            "{out}: {times:?}"
        );
    }
}

/// Blender's names for unnamed nodes work in --chain: RiggedSimple with every node name removed,
/// baked with `Node_3..Node_4` (and `#3..#4`), animates the same nodes with the same keys as the
/// named original baked with `Bone..Bone.001`.
#[test]
fn blenders_node_n_names_bake_an_unnamed_rig() {
    let dir = tempfile::tempdir().unwrap();
    let src = crate_path("meshes/RiggedSimple.gltf");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&src).unwrap()).unwrap();
    for node in json["nodes"].as_array_mut().unwrap() {
        node.as_object_mut().unwrap().remove("name");
    }
    std::fs::write(dir.path().join("unnamed.gltf"), json.to_string()).unwrap();
    std::fs::copy(
        crate_path("meshes/RiggedSimple0.bin"),
        dir.path().join("RiggedSimple0.bin"),
    )
    .unwrap();
    let bake = |rig: &str, chain: &str, out: &str| {
        let (code, _, err) = run(
            dir.path(),
            &[
                "ik", "--rig", rig, "--chain", chain, "--curve", "circle", "-o", out,
            ],
        );
        assert_eq!(code, 0, "{chain}: {err}");
        let (doc, buffers, _) = common::gltf_read::import(dir.path().join(out)).unwrap();
        let anim = doc.animations().next().unwrap();
        let mut channels: Vec<(usize, String, Vec<f32>)> = anim
            .channels()
            .map(|c| {
                let r = c.reader(|b| Some(&buffers[b.index()]));
                let values: Vec<f32> = match r.read_outputs().unwrap() {
                    gltf::animation::util::ReadOutputs::Rotations(q) => {
                        q.into_f32().flatten().collect()
                    }
                    gltf::animation::util::ReadOutputs::Translations(t) => t.flatten().collect(),
                    gltf::animation::util::ReadOutputs::Scales(s) => s.flatten().collect(),
                    gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => {
                        w.into_f32().collect()
                    }
                };
                (
                    c.target().node().index(),
                    format!("{:?}", c.target().property()),
                    values,
                )
            })
            .collect();
        channels.sort_by(|a, b| (a.0, &a.1).cmp(&(b.0, &b.1)));
        channels
    };
    let named = bake(&s(&src), "Bone..Bone.001", "named.glb");
    assert!(named.iter().any(|c| c.0 == 4), "{named:?}");
    assert_eq!(bake("unnamed.gltf", "Node_3..Node_4", "blender.glb"), named);
    assert_eq!(bake("unnamed.gltf", "#3..#4", "index.glb"), named);
}

/// A bake whose output will be large says so before it starts (it used to be silent until the
/// end, hours later): the first line on stderr, while the bake runs; Ctrl-C then leaves nothing.
/// 1001² vertices × 24 bytes × 51 frames = 1,226,449,224 bytes, over the 1 GiB threshold.
#[cfg(unix)]
#[test]
fn a_large_output_is_announced_before_the_bake() {
    use std::io::BufRead;
    assert_eq!(1001u64 * 1001 * 24 * 51, 1_226_449_224);
    let dir = tempfile::tempdir().unwrap();
    let mut child = common::cli::bin()
        .args([
            "cloth",
            "--preset",
            "lab-cloth",
            "--resolution",
            "1000",
            "--frames",
            "50",
            "-o",
            "big.glb",
        ])
        .current_dir(dir.path())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    stderr.read_line(&mut first).unwrap();
    assert_eq!(
        first,
        "warning: lab_cloth: the output will be about 1.2 GB (50 frames of 1002001 vertices); \
         --keyframe-tolerance can shrink it\n"
    );
    assert!(child.try_wait().unwrap().is_none(), "the bake goes on");
    common::cli::signal(child.id(), "INT");
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    assert!(!dir.path().join("big.glb").exists());
}

/// A loader's warning reaches the terminal (it was only in the JSON report): an OBJ with two
/// positions no face uses says so after the summary, and the bake holds the four used ones only.
#[test]
fn unused_positions_are_reported_on_the_terminal() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("stray.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 0 1\nv 1 0 1\nv 5 5 5\nv 6 6 6\nf 1 2 3\nf 2 4 3\n",
    )
    .unwrap();
    let (code, _, err) = run(
        dir.path(),
        &["cloth", "stray.obj", "--frames", "2", "-o", "stray.glb"],
    );
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 2, "{err}");
    assert!(
        lines[0].starts_with("stray: baked 2 frames (4 particles,"),
        "{err}"
    );
    assert_eq!(
        lines[1],
        "warning: stray: 2 positions are used by no face and were left out"
    );
    let (doc, _, _) = common::gltf_read::import(dir.path().join("stray.glb")).unwrap();
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert_eq!(prim.get(&gltf::Semantic::Positions).unwrap().count(), 4);
}

/// `#N` in --chain is documented with its shell quoting in `ik --help` (an unquoted `#13..#15`
/// is a shell comment, and clap then only says a value is missing).
#[test]
fn chain_help_shows_how_to_quote_node_indices() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, _) = run(dir.path(), &["ik", "--help"]);
    assert_eq!(code, 0);
    let help: String = out.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        help.contains("#N for node N (quote it: a shell drops everything after an unquoted #, so write --chain '#13..#15'), or Node_N as Blender names unnamed nodes"),
        "{out}"
    );
}

/// Every file a bake writes is checked before the bake starts (an unwritable folder was reported
/// after the bake, a failing `--report` left the GLB written behind an exit 1): the glTF, its
/// `.bin`, the VAT files and the report, each named with its option; nothing is written.
#[test]
fn outputs_that_cannot_be_written_are_refused_before_the_bake() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "a file, not a folder\n").unwrap();
    std::fs::create_dir(dir.path().join("exports")).unwrap();
    let lab = ["cloth", "--preset", "lab-cloth", "--frames", "2"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        lab.iter().chain(extra).copied().collect()
    };
    fails_exactly(
        dir.path(),
        &with(&["-o", "notes.txt/cloth.glb"]),
        "error: invalid value for --output: notes.txt/cloth.glb: notes.txt is a file, not a directory",
    );
    // A missing folder below a file cannot be created either.
    fails_exactly(
        dir.path(),
        &with(&["-o", "notes.txt/new/cloth.gltf"]),
        "error: invalid value for --output: notes.txt/new/cloth.gltf: notes.txt is a file, not a directory",
    );
    fails_exactly(
        dir.path(),
        &with(&["-o", "exports"]),
        "error: invalid value for --output: exports: is a directory, not a file",
    );
    fails_exactly(
        dir.path(),
        &with(&["-o", "cloth.glb", "--vat", "notes.txt/cloth.exr"]),
        "error: invalid value for --vat: notes.txt/cloth.exr: notes.txt is a file, not a directory",
    );
    // The report is checked with the rest: no GLB is left behind a failing --report.
    fails_exactly(
        dir.path(),
        &with(&["-o", "cloth.glb", "--report", "notes.txt/report.json"]),
        "error: invalid value for --report: notes.txt/report.json: notes.txt is a file, not a directory",
    );
    fails_exactly(
        dir.path(),
        &[
            "ik", "--curve", "circle", "-o", "pen.glb", "--report", "exports",
        ],
        "error: invalid value for --report: exports: is a directory, not a file",
    );
    // A missing folder is created when the bake writes.
    let (code, _, err) = run(dir.path(), &with(&["-o", "new/deeper/cloth.glb"]));
    assert_eq!(code, 0, "{err}");
    assert!(dir.path().join("new/deeper/cloth.glb").is_file());

    // A folder the user may not write in (not testable as root, who may write anywhere).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let locked = dir.path().join("locked");
        std::fs::create_dir(&locked).unwrap();
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::write(locked.join("probe"), b"").is_err() {
            fails_exactly(
                dir.path(),
                &with(&["-o", "locked/cloth.glb"]),
                "error: invalid value for --output: locked/cloth.glb: cannot write in the directory locked (permission denied)",
            );
        } else {
            eprintln!("running as root: the unwritable-folder case is skipped");
        }
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// An existing read-only export is an error naming the file (it was silently replaced), the
/// `.bin` of a `.gltf` too; the file keeps its bytes.
#[test]
fn a_read_only_export_is_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let args = |out: &'static str| ["cloth", "--preset", "lab-cloth", "--frames", "2", "-o", out];
    for out in ["sheet.glb", "sheet.gltf"] {
        let (code, _, err) = run(dir.path(), &args(out));
        assert_eq!(code, 0, "{err}");
    }
    let protect = |name: &str| {
        let path = dir.path().join(name);
        let mut p = std::fs::metadata(&path).unwrap().permissions();
        p.set_readonly(true);
        std::fs::set_permissions(&path, p).unwrap();
        std::fs::read(&path).unwrap()
    };
    let glb = protect("sheet.glb");
    fails_exactly(
        dir.path(),
        &args("sheet.glb"),
        "error: invalid value for --output: sheet.glb: exists and is read-only; make it writable or choose another file",
    );
    assert_eq!(std::fs::read(dir.path().join("sheet.glb")).unwrap(), glb);
    let bin = protect("sheet.bin");
    fails_exactly(
        dir.path(),
        &args("sheet.gltf"),
        "error: invalid value for --output: sheet.bin: exists and is read-only; make it writable or choose another file",
    );
    assert_eq!(std::fs::read(dir.path().join("sheet.bin")).unwrap(), bin);
}

/// Two jobs of a scene that write one file (it was overwritten by whichever ended last) are an
/// error naming both before any job runs; so is one job writing a file twice, and a file of a
/// later job that cannot be written.
#[test]
fn scene_jobs_writing_one_file_are_refused_before_running() {
    let dir = tempfile::tempdir().unwrap();
    let job = |name: &str, rest: &str| {
        format!("[[cloth]]\nname = \"{name}\"\npreset = \"lab-cloth\"\nframes = 2\n{rest}\n")
    };
    let scene = |file: &str, jobs: &[String]| {
        std::fs::write(dir.path().join(file), jobs.concat()).unwrap();
    };
    scene(
        "same.toml",
        &[
            job("first", "output = \"out/a.glb\""),
            job("second", "output = \"out/../out/a.glb\""),
        ],
    );
    fails_exactly(
        dir.path(),
        &["run", "--jobs", "2", "same.toml"],
        "error: same.toml: jobs `first` and `second` both write out/a.glb (as their `output` and `output`); give each job its own files",
    );
    // A .gltf's .bin against another job's report.
    scene(
        "bin.toml",
        &[
            job("sheet", "output = \"sheet.gltf\""),
            job("notes", "output = \"notes.glb\"\nreport = \"sheet.bin\""),
        ],
    );
    fails_exactly(
        dir.path(),
        &["run", "bin.toml"],
        "error: bin.toml: jobs `sheet` and `notes` both write sheet.bin (as their `output` and `report`); give each job its own files",
    );
    // A VAT's JSON against another job's report; and one job's VAT JSON as its own report.
    scene(
        "vat.toml",
        &[
            job("a", "output = \"a.glb\"\nvat = \"a.exr\""),
            job("b", "output = \"b.glb\"\nreport = \"a.json\""),
        ],
    );
    fails_exactly(
        dir.path(),
        &["run", "vat.toml"],
        "error: vat.toml: jobs `a` and `b` both write a.json (as their `vat` and `report`); give each job its own files",
    );
    scene(
        "self.toml",
        &[job(
            "a",
            "output = \"a.glb\"\nvat = \"a.exr\"\nreport = \"a.json\"",
        )],
    );
    fails_exactly(
        dir.path(),
        &["run", "self.toml"],
        "error: self.toml: job `a` writes a.json twice (as its `vat` and its `report`); give each its own file",
    );
    // The second job's folder is a file: refused before the first job runs.
    std::fs::write(dir.path().join("notes.txt"), "").unwrap();
    scene(
        "late.toml",
        &[
            job("ok", "output = \"ok.glb\""),
            job("late", "output = \"notes.txt/late.glb\""),
        ],
    );
    fails_exactly(
        dir.path(),
        &["run", "--jobs", "1", "late.toml"],
        "error: late.toml: job `late` (cloth): invalid value for `output`: notes.txt/late.glb: notes.txt is a file, not a directory",
    );
    // So is the run's own --report.
    scene("fine.toml", &[job("ok", "output = \"ok.glb\"")]);
    fails_exactly(
        dir.path(),
        &["run", "fine.toml", "--report", "notes.txt/run.json"],
        "error: invalid value for --report: notes.txt/run.json: notes.txt is a file, not a directory",
    );
}

/// An OBJ of several objects read whole says which objects it merged and names `--object`
/// (`torus_with_plane.obj` fell as one body without a word); with `--object`, the positions of
/// the other objects are left out as asked, and only a position no face of the file uses is
/// reported (it read as a broken file: "5 positions are used by no face").
#[test]
fn merged_obj_objects_are_named_and_picking_one_is_not_a_fault() {
    let dir = tempfile::tempdir().unwrap();
    let obj = crate_path("tests/fixtures/two_objects.obj");
    std::fs::copy(&obj, dir.path().join("two.obj")).unwrap();
    // Objects and their used positions, read here from the file's `o` and `f` lines.
    let text = std::fs::read_to_string(&obj).unwrap();
    let objects: Vec<&str> = text.lines().filter_map(|l| l.strip_prefix("o ")).collect();
    let positions = text.lines().filter(|l| l.starts_with("v ")).count();
    let used: std::collections::BTreeSet<&str> = text
        .lines()
        .filter_map(|l| l.strip_prefix("f "))
        .flat_map(str::split_whitespace)
        .collect();
    assert_eq!((objects.len(), positions, used.len()), (2, 9, 8));
    let bake = |extra: &[&str]| {
        let mut args = vec!["cloth", "two.obj", "--frames", "2", "-o", "two.glb"];
        args.extend_from_slice(extra);
        let (code, _, err) = run(dir.path(), &args);
        assert_eq!(code, 0, "{err}");
        err.lines().map(str::to_owned).collect::<Vec<_>>()
    };
    let lines = bake(&[]);
    assert_eq!(lines.len(), 3, "{lines:?}");
    assert!(
        lines[0].starts_with("two: baked 2 frames (8 particles,"),
        "{lines:?}"
    );
    assert_eq!(
        lines[1..],
        [
            "warning: two: 1 position is used by no face and was left out".to_owned(),
            format!(
                "warning: two: two.obj holds 2 objects ({}), merged into one body; --object NAME bakes one of them",
                objects.join(", ")
            ),
        ]
    );
    let lines = bake(&["--object", objects[0]]);
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert!(
        lines[0].starts_with("two: baked 2 frames (4 particles,"),
        "{lines:?}"
    );
    assert_eq!(
        lines[1],
        "warning: two: 1 position is used by no face and was left out"
    );
    // The report lists the merge warning in the scene keys' words.
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth", "two.obj", "--frames", "1", "-o", "r.glb", "--report", "r.json",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("r.json")).unwrap()).unwrap();
    assert_eq!(
        report["warnings"][1],
        "two.obj holds 2 objects (Cloth, Floor), merged into one body; `object` NAME bakes one of them"
    );
}

/// A scene-file typo in a vector names the key, its line and the expected form (it printed
/// serde's `data did not match any variant of untagged enum Vec3Repr`).
#[test]
fn a_mistyped_scene_vector_names_the_key_and_the_form() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "gravity = [0, \"x\", 0]",
            "`gravity`: expected three numbers, [X, Y, Z] or \"X,Y,Z\"; value 2 is \"x\", not a number",
        ),
        (
            "gravity = [0, -9.81]",
            "`gravity`: expected three numbers, [X, Y, Z] or \"X,Y,Z\"; found 2 values",
        ),
        (
            "wind = 3",
            "`wind`: invalid type: integer `3`, expected three numbers, [X, Y, Z] or \"X,Y,Z\"",
        ),
        (
            "translate = \"0,1\"",
            "`translate`: `0,1`: expected 3 comma-separated numbers (X,Y,Z)",
        ),
    ];
    for (line, message) in cases {
        std::fs::write(
            dir.path().join("typo.toml"),
            format!(
                "[[cloth]]\nname = \"sheet\"\npreset = \"lab-cloth\"\n{line}\noutput = \"a.glb\"\n"
            ),
        )
        .unwrap();
        fails_exactly(
            dir.path(),
            &["run", "typo.toml"],
            &format!("error: typo.toml: [[cloth]] job 1 (`sheet`): line 4: {message}"),
        );
    }
    // Both forms still read.
    std::fs::write(
        dir.path().join("ok.toml"),
        "[[cloth]]\npreset = \"lab-cloth\"\nframes = 1\ngravity = [0, -9.81, 0]\nwind = \"1,0,0\"\noutput = \"a.glb\"\n",
    )
    .unwrap();
    let (code, _, err) = run(dir.path(), &["run", "ok.toml"]);
    assert_eq!(code, 0, "{err}");
}

/// Fox's Walk: its duration read here with the gltf crate.
fn fox_walk_seconds() -> f64 {
    let (doc, buffers, _) = common::gltf_read::import(crate_path("meshes/Fox.glb")).unwrap();
    let walk = doc.animations().find(|a| a.name() == Some("Walk")).unwrap();
    let times: Vec<f32> = walk
        .channels()
        .flat_map(|c| {
            c.reader(|b| Some(&buffers[b.index()]))
                .read_inputs()
                .unwrap()
                .collect::<Vec<_>>()
        })
        .collect();
    let (lo, hi) = times
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    f64::from(hi - lo)
}

/// The cape of `meshes/garments/fox_cape.obj` on Fox's walk, `--scale` times its size, pinned at
/// the neck (the pin box scaled alike).
fn cape_args(scale: &str, rig_scale: &str, out: &str) -> Vec<String> {
    let s: f64 = scale.parse().unwrap();
    let pin = [-1.0, 0.69, 0.235, 1.0, 0.71, 0.245].map(|c| (c * s).to_string());
    [
        "cloth",
        &s_(&crate_path("meshes/garments/fox_cape.obj")),
        "--rig",
        &s_(&crate_path("meshes/Fox.glb")),
        "--animation",
        "Walk",
        "--rig-scale",
        rig_scale,
        "--scale",
        scale,
        "--thickness",
        "0.003",
        "--max-iterations",
        "100",
        "--pin",
        &format!("box:{}", pin.join(",")),
        "-o",
        out,
    ]
    .map(str::to_owned)
    .to_vec()
}

fn s_(p: &Path) -> String {
    s(p)
}

/// A bake on a character says frames simulated and frames written apart (it said "baked 57
/// frames" for a 21-frame file): the blend-in and warm-up frames follow from Walk's duration,
/// read here, and the written count is the file's morph-weight keys less the first pose.
#[test]
fn a_character_bake_says_frames_simulated_and_written() {
    let dir = tempfile::tempdir().unwrap();
    let args = cape_args("1", "0.01", "cape.glb");
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let (code, _, err) = run(dir.path(), &args);
    assert_eq!(code, 0, "{err}");
    // Defaults: 30 fps rounded to whole frames a loop, 0.5 s blend-in, one warm-up loop, one
    // written loop.
    let cycle = fox_walk_seconds();
    let per_cycle = (cycle * 30.0).round() as usize;
    let fps = per_cycle as f64 / cycle;
    let blend = (0.5 * fps).ceil() as usize;
    let total = blend + 2 * per_cycle;
    assert_eq!((per_cycle, blend, total), (21, 15, 57));
    let first = err.lines().next().unwrap();
    assert!(
        first.starts_with(&format!(
            "fox_cape: baked {per_cycle} frames ({total} simulated: {blend} blending in, \
             {per_cycle} warming up, {per_cycle} written; 315 particles,"
        )) && first.contains(&format!("; {total} of {total} frames within tolerance")),
        "{err}"
    );
    let (doc, buffers, _) = common::gltf_read::import(dir.path().join("cape.glb")).unwrap();
    let keys = doc
        .animations()
        .flat_map(|a| a.channels().collect::<Vec<_>>())
        .find(|c| c.target().property() == gltf::animation::Property::MorphTargetWeights)
        .unwrap()
        .reader(|b| Some(&buffers[b.index()]))
        .read_inputs()
        .unwrap()
        .count();
    assert_eq!(keys, per_cycle + 1);
    // A plain bake simulates what it writes and says nothing more.
    let (code, _, err) = run(
        dir.path(),
        &[
            "cloth",
            "--preset",
            "lab-cloth",
            "--frames",
            "3",
            "-o",
            "lab.glb",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.starts_with("lab_cloth: baked 3 frames (121 particles,"),
        "{err}"
    );
}

/// A garment in other units than its character (a cape in centimetres on the metre-scale Fox
/// "succeeded" with an 8.8 m loop-seam warning) is refused before the bake with the `--scale`
/// (or `--rig-scale`) that fixes it; a cloth of implausible size alone is a warning. The
/// garment's size is computed here from the OBJ's `v` lines.
#[test]
fn garment_and_character_in_different_units_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let cape = obj_object_positions(&crate_path("meshes/garments/fox_cape.obj"), None);
    let diagonal = {
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for p in &cape {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt()
    };
    assert_eq!(format!("{:.1}", diagonal * 100.0), "48.8");
    // Fox at rest is 175.55 units across (its file is in centimetres: --rig-scale 0.01).
    let fails = |scale: &str, rig_scale: &str, message: String| {
        let args = cape_args(scale, rig_scale, "cape.glb");
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails_exactly(dir.path(), &args, &message);
    };
    fails(
        "100",
        "0.01",
        format!(
            "error: invalid value for --scale: 100: the garment ({:.2} m across) is {:.0} times \
             the size of the character (1.76 m across, with --rig-scale 0.01): are they in \
             different units? try --scale 1 for the garment, or --rig-scale 1 for the character",
            diagonal * 100.0,
            diagonal * 100.0 / 1.7555
        ),
    );
    fails(
        "1000",
        "0.01",
        format!(
            "error: invalid value for --scale: 1000: the garment ({:.2} m across) is {:.0} times \
             the size of the character (1.76 m across, with --rig-scale 0.01): are they in \
             different units? try --scale 1 for the garment, or --rig-scale 10 for the character",
            diagonal * 1000.0,
            diagonal * 1000.0 / 1.7555
        ),
    );
    // The rig's centimetres taken as metres: the character is 100 times too large.
    fails(
        "1",
        "1",
        format!(
            "error: invalid value for --scale: 1: the garment ({:.1} cm across) is 1/{:.0} of \
             the size of the character (175.55 m across, with --rig-scale 1): are they in \
             different units? try --scale 100 for the garment, or --rig-scale 0.01 for the \
             character",
            diagonal * 100.0,
            175.55 / diagonal
        ),
    );
    // Implausible cloth sizes alone: a warning with the scale that brings it near 1 m.
    let plane = s(&crate_path("meshes/plane_30x30.obj"));
    for (scale, message) in [
        (
            "0.001",
            "the cloth is 1.41 mm across (its bounding box's diagonal, scaled by 0.001), not a \
             plausible size in metres (0.01 to 100 m); if the input is in other units, --scale 1 \
             makes it 1.41 m",
        ),
        (
            "100",
            "the cloth is 141.42 m across (its bounding box's diagonal, scaled by 100), not a \
             plausible size in metres (0.01 to 100 m); if the input is in other units, --scale 1 \
             makes it 1.41 m",
        ),
    ] {
        let (code, _, err) = run(
            dir.path(),
            &[
                "cloth", &plane, "--scale", scale, "--frames", "1", "-o", "p.glb",
            ],
        );
        assert_eq!(code, 0, "{err}");
        assert_eq!(
            err.lines().nth(1),
            Some(format!("warning: plane_30x30: {message}").as_str()),
            "{err}"
        );
    }
    // The 1 m plane itself, and at 2 cm, say nothing.
    for scale in ["1", "0.02"] {
        let (code, _, err) = run(
            dir.path(),
            &[
                "cloth", &plane, "--scale", scale, "--frames", "1", "-o", "p.glb",
            ],
        );
        assert_eq!((code, err.lines().count()), (0, 1), "{err}");
    }
}
