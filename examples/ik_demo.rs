//! Bakes the three IK examples of issue #4 into `exports/` (or the folder given as the first
//! argument), the library equivalent of:
//!
//! ```text
//! scenebake ik --preset lab-arm --curve circle --solver fabrik -o exports/circle.glb
//! scenebake ik --preset lab-arm --text "HELLO" -o exports/hello.glb --report hello.json
//! scenebake ik --rig meshes/Fox.glb --chain b_Spine01_02..b_Head_05 --curve heart -o exports/fox.glb
//! ```

use std::path::PathBuf;

use scenebake::bake::{bake_ik, IkJob};
use scenebake::ik::SolverKind;
use scenebake::path::CurveKind;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "exports".into()));
    let lab = IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        ..Default::default()
    };
    let jobs = [
        IkJob {
            curve: Some(CurveKind::Circle),
            solver: SolverKind::Fabrik,
            output: out.join("circle.glb"),
            report: Some(out.join("circle.json")),
            ..lab.clone()
        },
        IkJob {
            curve: Some(CurveKind::Circle),
            solver: SolverKind::Ccd,
            output: out.join("circle_ccd.glb"),
            report: Some(out.join("circle_ccd.json")),
            ..lab.clone()
        },
        IkJob {
            text: Some("HELLO".into()),
            output: out.join("hello.glb"),
            report: Some(out.join("hello.json")),
            ..lab.clone()
        },
        IkJob {
            text: Some("HELLO, WORLD!".into()),
            output: out.join("hello_world.gltf"),
            ..lab.clone()
        },
        IkJob {
            preset: None,
            joints: Some(10),
            length: Some(3.0),
            curve: Some(CurveKind::Star),
            output: out.join("star10.glb"),
            ..lab.clone()
        },
        IkJob {
            preset: None,
            rig: Some("meshes/Fox.glb".into()),
            chain: Some("b_Spine01_02..b_Head_05".into()),
            curve: Some(CurveKind::Heart),
            output: out.join("fox.glb"),
            report: Some(out.join("fox.json")),
            ..lab.clone()
        },
        IkJob {
            preset: None,
            rig: Some("meshes/RiggedSimple.gltf".into()),
            chain: Some("Bone..Bone.001".into()),
            curve: Some(CurveKind::Circle),
            output: out.join("rigged_simple.gltf"),
            ..lab.clone()
        },
    ];
    for job in &jobs {
        let r = bake_ik(job, &mut |_, _| {})?;
        // The library returns the report; writing it is the caller's choice.
        if let Some(path) = &job.report {
            std::fs::write(path, serde_json::to_vec_pretty(&r)?)?;
        }
        println!(
            "{}: {} joints, {} frames, solver {}, reached {}, unreachable {}, mean iterations {:.2}, max error {:.2e}, {:.1} ms",
            job.output.display(),
            r.joints,
            r.frames,
            r.solver,
            r.reached,
            r.unreachable,
            r.mean_iterations,
            r.max_error,
            r.seconds_total * 1e3
        );
    }
    Ok(())
}
