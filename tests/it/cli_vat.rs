//! The VAT and compact-cache options through the binary: command line and scene-file keys share
//! one vocabulary (`vat`, `vat_mode`, `vat_max_width`, `keyframe_tolerance`, `sparse`).

use crate::common;

use common::cli::bin as scenebake;

#[test]
fn scene_file_keys_reach_the_vat_and_compact_writers() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        r#"
[[cloth]]
name = "lab"
preset = "lab-cloth"
output = "out/lab.gltf"
frames = 30
vat = "out/lab_vat.exr"
vat_mode = "offset"
vat_max_width = 50
keyframe_tolerance = 0.002
sparse = "off"
"#,
    )
    .unwrap();
    let report = dir.path().join("run.json");
    let status = scenebake()
        .arg("-q")
        .arg("run")
        .arg(&scene)
        .arg("--report")
        .arg(&report)
        .status()
        .unwrap();
    assert!(status.success());
    let out = dir.path().join("out");
    for f in [
        "lab.gltf",
        "lab.bin",
        "lab_vat.exr",
        "lab_vat.normals.exr",
        "lab_vat.json",
    ] {
        assert!(
            out.join(f).is_file(),
            "{f} written beside the scene's output"
        );
    }
    let vat: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("lab_vat.json")).unwrap()).unwrap();
    assert_eq!(vat["mode"], "offset");
    assert_eq!(vat["layout"]["width"], 50);
    assert_eq!(vat["layout"]["rows_per_frame"], 3);
    assert_eq!(vat["gltf"], "lab.gltf");
    let run: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let cache = &run["jobs"][0]["report"]["cache"];
    assert_eq!(cache["keyframe_tolerance"], 0.002);
    assert_eq!(cache["sparse_accessors"], 0);
    assert!(cache["targets"].as_u64().unwrap() < 30);
}

#[test]
fn bad_values_name_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("x.glb");
    for (args, option) in [
        (vec!["--vat", "x.png"], "--vat"),
        (vec!["--vat-max-width", "0"], "--vat-max-width"),
        (vec!["--keyframe-tolerance", "-0.5"], "--keyframe-tolerance"),
        (vec!["--sparse", "sometimes"], "--sparse"),
        (vec!["--vat-mode", "relative"], "--vat-mode"),
    ] {
        let out = scenebake()
            .args(["cloth", "--preset", "lab-cloth", "--frames", "2", "-o"])
            .arg(&glb)
            .args(&args)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(option), "{args:?}: {err}");
    }
    assert!(!glb.exists());
}
