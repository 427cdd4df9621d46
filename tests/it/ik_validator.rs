//! Runs the Khronos glTF-Validator on IK bakes: `scripts/validate_gltf.mjs` once
//! `npm ci --prefix scripts` has installed the validator (`.ci/run` does, before the tests), or
//! the script named by `SCENEBAKE_GLTF_VALIDATOR`; zero errors and zero warnings are required.
//! Without the validator the test only bakes the files and says it skipped validation, except
//! under CI (`CI` set), where a missing validator is a failure.

use std::process::Command;

use scenebake::bake::{bake_ik, IkJob};
use scenebake::ik::SolverKind;
use scenebake::path::CurveKind;

#[test]
fn ik_bakes_are_validator_clean() {
    let dir = tempfile::tempdir().unwrap();
    let lab = IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        ..Default::default()
    };
    let meshes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    let jobs = [
        IkJob {
            curve: Some(CurveKind::Circle),
            solver: SolverKind::Ccd,
            output: dir.path().join("circle.glb"),
            ..lab.clone()
        },
        IkJob {
            text: Some("HELLO".into()),
            output: dir.path().join("hello.gltf"),
            ..lab.clone()
        },
        IkJob {
            preset: None,
            joints: Some(300),
            length: Some(3.0),
            curve: Some(CurveKind::Triangle),
            spacing: Some(0.2),
            max_iterations: 5,
            output: dir.path().join("u16.glb"),
            ..lab.clone()
        },
        IkJob {
            preset: None,
            rig: Some(meshes.join("Fox.glb")),
            chain: Some("b_Spine01_02..b_Head_05".into()),
            curve: Some(CurveKind::Heart),
            output: dir.path().join("fox.glb"),
            ..lab.clone()
        },
        IkJob {
            preset: None,
            rig: Some(meshes.join("RiggedSimple.gltf")),
            chain: Some("Bone..Bone.001".into()),
            curve: Some(CurveKind::Circle),
            output: dir.path().join("rs.gltf"),
            ..lab.clone()
        },
    ];
    for job in &jobs {
        bake_ik(job, &mut |_, _| {}).unwrap();
    }
    let crate_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let installed = crate_dir.join("scripts/node_modules/gltf-validator");
    let script = match std::env::var("SCENEBAKE_GLTF_VALIDATOR") {
        Ok(script) => std::path::PathBuf::from(script),
        Err(_) if installed.is_dir() => crate_dir.join("scripts/validate_gltf.mjs"),
        Err(_) => {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI must install the validator (npm ci --prefix scripts) before the tests"
            );
            eprintln!("the glTF validator is not installed (npm ci --prefix scripts): skipped");
            return;
        }
    };
    let out = Command::new("node")
        .arg(&script)
        .args(jobs.iter().map(|j| &j.output))
        .output()
        .expect("run node");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "validator reported problems:\n{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
