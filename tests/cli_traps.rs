//! The traps a new user hit in a trial run (issue 13), each closed with the exact message the
//! command line now prints.

mod common;

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
