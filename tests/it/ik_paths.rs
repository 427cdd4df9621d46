//! Target paths through whole bakes: spacing, SVG and CSV inputs, the per-frame rotation limit
//! and frame-to-frame continuity of the baked rotations.

use crate::common;

use common::load;
use glam::{DQuat, DVec3};
use scenebake::bake::{bake_ik, IkJob};
use scenebake::ik::SolverKind;
use scenebake::path::CurveKind;

fn lab(dir: &std::path::Path, name: &str) -> IkJob {
    IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        output: dir.join(format!("{name}.glb")),
        ..Default::default()
    }
}

fn key_angles(keys: &[[f32; 4]]) -> Vec<f64> {
    keys.windows(2)
        .map(|w| {
            let a = DQuat::from_array(w[0].map(f64::from));
            let b = DQuat::from_array(w[1].map(f64::from));
            a.angle_between(b)
        })
        .collect()
}

#[test]
fn spacing_option_sets_the_distance_between_targets() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        curve: Some(CurveKind::Square),
        spacing: Some(0.05),
        ..lab(dir.path(), "sq")
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    // Square of half-side 0.6: perimeter 4.8 → 96 targets 0.05 apart (corners included).
    assert_eq!(r.frames, 96);
    for w in r.targets.windows(2) {
        let d = DVec3::from_array(w[0]).distance(DVec3::from_array(w[1]));
        assert!((d - 0.05).abs() < 1e-9, "{d}");
    }
    // Default spacing follows the frame rate: twice the fps, twice the targets.
    let slow = bake_ik(
        &IkJob {
            curve: Some(CurveKind::Circle),
            fps: 60.0,
            ..lab(dir.path(), "c60")
        },
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(slow.frames, 300);
}

#[test]
fn rotation_limit_caps_every_joint_per_frame_and_keys_are_continuous() {
    let dir = tempfile::tempdir().unwrap();
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let free = IkJob {
            curve: Some(CurveKind::Star),
            solver,
            ..lab(dir.path(), &format!("free_{}", solver.as_str()))
        };
        bake_ik(&free, &mut |_, _| {}).unwrap();
        let l = load(&free.output);
        let tracks = l.animation("ik");
        for (_, keys) in tracks.rotation.values() {
            // Warm-started solutions move smoothly: no joint turns more than 20° between frames
            // after the first frame (which starts from the straight rest pose).
            let worst = key_angles(&keys[1..]).into_iter().fold(0.0, f64::max);
            assert!(
                worst < 20f64.to_radians(),
                "{solver:?}: {}° between frames",
                worst.to_degrees()
            );
            for q in keys {
                assert!((q.iter().map(|x| x * x).sum::<f32>().sqrt() - 1.0).abs() < 1e-6);
            }
        }

        let limited = IkJob {
            max_angle: Some(1.0),
            ..IkJob {
                output: dir.path().join(format!("lim_{}.glb", solver.as_str())),
                ..free.clone()
            }
        };
        let r = bake_ik(&limited, &mut |_, _| {}).unwrap();
        let l = load(&limited.output);
        let tracks = l.animation("ik");
        for (_, keys) in tracks.rotation.values() {
            for a in key_angles(keys) {
                // f32 keys: the angle between two nearby f32 quaternions is good to ~3e-5 rad here.
                assert!(
                    a <= 1f64.to_radians() + 1e-4,
                    "{solver:?}: {}° > 1°",
                    a.to_degrees()
                );
            }
        }
        // Limited joints cannot keep up with the first jump: some frames miss, and say so.
        assert!(r.reached < r.frames);
    }
}

#[test]
fn svg_and_csv_paths_are_drawn_in_the_plane() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("d.svg");
    std::fs::write(&svg, r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100"><path d="M10 80 C 40 10, 65 10, 95 80 S 150 150, 180 80"/><circle cx="50" cy="50" r="20"/></svg>"#).unwrap();
    let r = bake_ik(
        &IkJob {
            svg: Some(svg),
            ..lab(dir.path(), "svg")
        },
        &mut |_, _| {},
    )
    .unwrap();
    assert!(r.frames > 50);
    assert_eq!(r.reached, r.frames);
    let json = serde_json::to_value(&r).unwrap();
    for (t, down) in json["targets"]
        .as_array()
        .unwrap()
        .iter()
        .zip(json["pen_down"].as_array().unwrap())
    {
        if down.as_bool().unwrap() {
            assert!(common::vec3_of(t).y.abs() < 1e-12);
        }
    }

    let csv = dir.path().join("p.csv");
    std::fs::write(&csv, "0,0\n0.3,0\n\n0.3,0.3\n0,0.3\n").unwrap();
    let r = bake_ik(
        &IkJob {
            points: Some(csv),
            spacing: Some(0.01),
            ..lab(dir.path(), "csv")
        },
        &mut |_, _| {},
    )
    .unwrap();
    // Plane coordinates of the lab plane: x → world x, y → world -z.
    assert_eq!(r.targets[0], [0.0, 0.0, 0.0]);
    let last = DVec3::from_array(*r.targets.last().unwrap());
    assert!(last.distance(DVec3::new(0.0, 0.0, -0.3)) < 1e-12, "{last}");
    assert_eq!(r.reached, r.frames);
}
