//! Natural joints: a pole keeps the elbow on its side, hinge and cone limits hold in every frame.
//! Everything is checked on the exported file with an independent FK (tests/it/common).

use crate::common;

use common::{load, Loaded, Tracks};
use glam::{DQuat, DVec3};
use scenebake::bake::{bake_ik, IkJob, IkReport};
use scenebake::ik::SolverKind;

/// A 3-joint arm (shoulder joint_0 at (0, 0.785, 0), elbow joint_1, hand joint_2; two 0.6 m
/// bones hanging down) writing a cursive word on a board in front of its chest.
fn arm_job(dir: &std::path::Path, name: &str, solver: SolverKind) -> IkJob {
    IkJob {
        joints: Some(3),
        length: Some(1.2),
        text: Some("hello".into()),
        font: Some("cursive".into()),
        size: Some(0.08),
        center: Some(DVec3::new(0.15, 0.45, 0.45)),
        normal: Some(DVec3::new(0.0, 0.0, -1.0)),
        solver,
        output: dir.join(format!("{name}.glb")),
        ..Default::default()
    }
}

const POLE: DVec3 = DVec3::new(0.6, -0.5, 0.0);

struct Frames {
    l: Loaded,
    tracks: Tracks,
    times: Vec<f32>,
}

/// The baked file with the key times of `root`'s rotation (one key per frame).
fn frames(job: &IkJob, root: &str) -> Frames {
    let l = load(&job.output);
    let tracks = l.animation("ik");
    let times = tracks.rotation[&l.node_by_name(root)].0.clone();
    Frames { l, tracks, times }
}

impl Frames {
    fn pos(&self, joint: &str, t: f32) -> DVec3 {
        self.l
            .world_pos(&self.tracks, self.l.node_by_name(joint), t)
    }

    fn local_rotation(&self, joint: &str, t: f32) -> DQuat {
        let node = self.l.node_by_name(joint);
        let (times, keys) = self.tracks.rotation.get(&node).unwrap();
        common::sample_quat(times, keys, t)
    }
}

fn assert_tip_on_targets(f: &Frames, r: &IkReport, tip: &str) {
    for (k, &t) in f.times.iter().enumerate() {
        let d = f.pos(tip, t).distance(DVec3::from_array(r.targets[k]));
        if r.error[k] <= 1e-4 {
            assert!(d < 1e-4 + 2e-5, "frame {k}: file tip {d} from the target");
        }
    }
}

#[test]
fn with_a_pole_the_elbow_stays_on_its_side_and_the_hinge_holds() {
    let dir = tempfile::tempdir().unwrap();
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = IkJob {
            pole: Some(POLE),
            limit: vec!["joint_1:hinge:0..150".into(), "joint_0:cone:100".into()],
            ..arm_job(dir.path(), &format!("pole_{}", solver.as_str()), solver)
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert!(
            r.reached as f64 >= 0.97 * r.frames as f64,
            "{solver:?}: {} of {} reached",
            r.reached,
            r.frames
        );
        let f = frames(&job, "joint_0");
        assert_tip_on_targets(&f, &r, "joint_2");
        // The hinge axis the pole implies: perpendicular to the rest forearm (-Y) and to the
        // pole's offset from the rest elbow (+X side), oriented so a positive turn carries the
        // forearm away from the pole, i.e. the elbow out towards it: (+X) × (-Y) = -Z.
        let axis = DVec3::X.cross(DVec3::NEG_Y);
        for (k, &t) in f.times.iter().enumerate() {
            let (s, e, h) = (
                f.pos("joint_0", t),
                f.pos("joint_1", t),
                f.pos("joint_2", t),
            );
            let line = (h - s).normalize();
            let elbow_off = (e - s).reject_from(line);
            let pole_off = (POLE - s).reject_from(line);
            assert!(
                elbow_off.dot(pole_off) > 0.0 || elbow_off.length() < 1e-4,
                "{solver:?} frame {k}: the elbow flipped across the shoulder-hand line"
            );
            assert!(e.y < s.y, "{solver:?} frame {k}: elbow above the shoulder");
            // Hinge: the elbow's rotation (rest = identity, parent = upper arm) is a turn about
            // the axis by 0..150 degrees.
            let q = f.local_rotation("joint_1", t);
            let q = if q.w < 0.0 { -q } else { q };
            let v = DVec3::new(q.x, q.y, q.z);
            assert!(
                v.cross(axis).length() < 2e-5,
                "{solver:?} frame {k}: elbow swings off its hinge ({})",
                v.cross(axis).length()
            );
            let angle = 2.0 * v.dot(axis).atan2(q.w);
            assert!(
                (-1e-4..=150f64.to_radians() + 1e-4).contains(&angle),
                "{solver:?} frame {k}: hinge angle {}°",
                angle.to_degrees()
            );
            // Cone on the shoulder: the upper arm within 100° of hanging straight down.
            let up = (e - s).normalize();
            assert!(up.angle_between(DVec3::NEG_Y) <= 100f64.to_radians() + 1e-4);
        }
    }
}

#[test]
fn binding_limits_hold_and_missed_targets_are_reported() {
    // A shoulder cone of 25° cannot reach most of the word: the limit wins, frames say so.
    let dir = tempfile::tempdir().unwrap();
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = IkJob {
            limit: vec![
                "joint_0:cone:25".into(),
                "joint_1:hinge:-90..90:1,0,0".into(),
            ],
            ..arm_job(dir.path(), &format!("tight_{}", solver.as_str()), solver)
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert!(r.reached < r.frames, "{solver:?}: every target reached?");
        let f = frames(&job, "joint_0");
        for (k, &t) in f.times.iter().enumerate() {
            let (s, e) = (f.pos("joint_0", t), f.pos("joint_1", t));
            let a = (e - s).normalize().angle_between(DVec3::NEG_Y);
            assert!(
                a <= 25f64.to_radians() + 1e-4,
                "{solver:?} frame {k}: shoulder at {}°",
                a.to_degrees()
            );
            let q = f.local_rotation("joint_1", t);
            let v = DVec3::new(q.x, q.y, q.z);
            assert!(v.cross(DVec3::X).length() < 2e-5, "{solver:?} frame {k}");
            let d = f
                .pos("joint_2", t)
                .distance(DVec3::from_array(r.targets[k]));
            assert!(
                (d - r.error[k]).abs() < 1e-4,
                "{solver:?} frame {k}: reported error"
            );
        }
    }
}

#[test]
fn bad_limits_are_errors_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        limit: vec!["elbow:hinge:0..150".into()],
        ..arm_job(dir.path(), "bad", SolverKind::Fabrik)
    };
    let e = bake_ik(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(
        e.contains("`limit`") && e.contains("elbow") && e.contains("joint_1"),
        "{e}"
    );
    assert!(!job.output.exists());
}

#[test]
fn a_rig_leg_writes_with_a_pole_a_hinged_elbow_and_a_shoulder_cone() {
    // Fox's right foreleg (shoulder, elbow, paw; rig frames with rest rotations) writing on the
    // ground in front of it, the elbow pointing back at the pole.
    let dir = tempfile::tempdir().unwrap();
    let pole = DVec3::new(-7.0, 30.0, -20.0);
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = IkJob {
            rig: Some(common::crate_dir().join("meshes/Fox.glb")),
            chain: Some("b_RightUpperArm_06..b_RightHand_08".into()),
            text: Some("hi".into()),
            font: Some("script".into()),
            size: Some(8.0),
            center: Some(DVec3::new(-7.0, 12.0, 25.0)),
            normal: Some(DVec3::Y),
            pole: Some(pole),
            limit: vec![
                "b_RightForeArm_07:hinge:0..150".into(),
                "b_RightUpperArm_06:cone:70".into(),
            ],
            solver,
            output: dir.path().join(format!("leg_{}.glb", solver.as_str())),
            ..Default::default()
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert_eq!(r.reached, r.frames, "{solver:?}: max error {}", r.max_error);
        let f = frames(&job, "b_RightUpperArm_06");
        // f32 keys on a ~40-unit leg.
        for (k, &t) in f.times.iter().enumerate() {
            let d = f
                .pos("b_RightHand_08", t)
                .distance(DVec3::from_array(r.targets[k]));
            assert!(d < 1e-4 + 1e-3, "{solver:?} frame {k}: {d}");
        }
        let node = |n: &str| f.l.doc.nodes().nth(f.l.node_by_name(n)).unwrap();
        let rest_q = |n: &str| DQuat::from_array(node(n).transform().decomposed().1.map(f64::from));
        let (s0, e0) = (
            f.l.world_pos(
                &Tracks::default(),
                f.l.node_by_name("b_RightUpperArm_06"),
                0.0,
            ),
            f.l.world_pos(
                &Tracks::default(),
                f.l.node_by_name("b_RightForeArm_07"),
                0.0,
            ),
        );
        let mut hinge_axis: Option<DVec3> = None;
        for (k, &t) in f.times.iter().enumerate() {
            let (s, e, h) = (
                f.pos("b_RightUpperArm_06", t),
                f.pos("b_RightForeArm_07", t),
                f.pos("b_RightHand_08", t),
            );
            let line = (h - s).normalize();
            let off = (e - s).reject_from(line);
            assert!(
                off.dot((pole - s).reject_from(line)) > 0.0,
                "{solver:?} frame {k}: elbow flipped"
            );
            // Cone: the upper arm within 70° of its rest direction (its parent does not move).
            let a = (e - s).angle_between(e0 - s0);
            assert!(
                a <= 70f64.to_radians() + 1e-3,
                "{solver:?} frame {k}: {}°",
                a.to_degrees()
            );
            // Hinge: the elbow turns from rest about one fixed axis in every frame.
            let d =
                f.local_rotation("b_RightForeArm_07", t) * rest_q("b_RightForeArm_07").inverse();
            let (axis, angle) = d.to_axis_angle();
            if angle.abs() > 0.05 {
                let axis = if angle < 0.0 { -axis } else { axis };
                let fixed = *hinge_axis.get_or_insert(axis);
                assert!(
                    axis.cross(fixed).length() < 1e-3,
                    "{solver:?} frame {k}: the elbow swings off its hinge"
                );
            }
        }
    }
}

/// Twist of a local rotation `q` (rest = identity) about the rest bone direction `b0`, measured
/// geometrically: a reference vector across the bone, turned by `q`, then carried back by the
/// shortest arc from the bone's new direction to `b0`, ends up turned about `b0` by the twist.
fn twist_of(q: DQuat, b0: DVec3) -> f64 {
    let p0 = b0.any_orthonormal_vector();
    let b = q * b0;
    let p2 = DQuat::from_rotation_arc(b, b0) * (q * p0);
    p0.cross(p2).dot(b0).atan2(p0.dot(p2))
}

#[test]
fn twist_limits_hold_in_every_frame_and_keep_the_hand_on_the_word() {
    // The hinged elbow makes the shoulder roll about the upper arm (so the hinge can bend the
    // right way); a twist limit on the shoulder bounds that roll.
    let dir = tempfile::tempdir().unwrap();
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let free = IkJob {
            pole: Some(POLE),
            limit: vec!["joint_1:hinge:0..150".into()],
            ..arm_job(dir.path(), &format!("free_{}", solver.as_str()), solver)
        };
        let limited = IkJob {
            limit: vec![
                "joint_1:hinge:0..150".into(),
                "joint_0:twist:-20..20".into(),
                "joint_0:cone:120".into(),
            ],
            ..free.clone()
        };
        let limited = IkJob {
            output: dir.path().join(format!("twist_{}.glb", solver.as_str())),
            ..limited
        };
        let worst = |job: &IkJob| {
            let r = bake_ik(job, &mut |_, _| {}).unwrap();
            let f = frames(job, "joint_0");
            let w = f
                .times
                .iter()
                .map(|&t| twist_of(f.local_rotation("joint_0", t), DVec3::NEG_Y).abs())
                .fold(0.0, f64::max);
            (r, f, w)
        };
        let (_, _, w_free) = worst(&free);
        assert!(
            w_free > 25f64.to_radians(),
            "{solver:?}: the free shoulder rolls only {}°, the limit would not bind",
            w_free.to_degrees()
        );
        let (r, f, w) = worst(&limited);
        assert!(
            w <= 20f64.to_radians() + 1e-4,
            "{solver:?}: shoulder twist {}°",
            w.to_degrees()
        );
        for (k, &t) in f.times.iter().enumerate() {
            let d = f
                .pos("joint_2", t)
                .distance(DVec3::from_array(r.targets[k]));
            assert!(
                (d - r.error[k]).abs() < 1e-4,
                "{solver:?} frame {k}: reported error"
            );
        }
        assert!(
            r.reached as f64 >= 0.9 * r.frames as f64,
            "{solver:?}: {} of {} reached",
            r.reached,
            r.frames
        );
    }
}

#[test]
fn the_tip_axis_holds_the_pen_into_the_board_without_moving_the_tip() {
    let dir = tempfile::tempdir().unwrap();
    // The board faces -Z (towards the arm); the pen points into it, +Z.
    let axis = DVec3::new(0.0, 0.0, 1.0);
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let base = IkJob {
            pole: Some(POLE),
            limit: vec!["joint_1:hinge:0..150".into()],
            ..arm_job(dir.path(), &format!("pen_free_{}", solver.as_str()), solver)
        };
        let held = IkJob {
            tip_axis: Some(axis),
            output: dir.path().join(format!("pen_{}.glb", solver.as_str())),
            ..base.clone()
        };
        let pen_angles = |job: &IkJob| {
            let r = bake_ik(job, &mut |_, _| {}).unwrap();
            let f = frames(job, "joint_0");
            let tip = f.l.node_by_name("joint_2");
            // The pen continues the last bone: -Y in the tip's frame (rest rotation identity).
            let angles: Vec<f64> = f
                .times
                .iter()
                .map(|&t| {
                    let w = f.l.world(&f.tracks, tip, t);
                    w.transform_vector3(DVec3::NEG_Y).angle_between(axis)
                })
                .collect();
            (r, f, angles)
        };
        let (_, _, free) = pen_angles(&base);
        assert!(
            free.iter().any(|a| *a > 10f64.to_radians()),
            "{solver:?}: the free pen already points into the board"
        );
        let (r, f, held_angles) = pen_angles(&held);
        for (k, a) in held_angles.iter().enumerate() {
            assert!(
                *a < 0.01f64.to_radians(),
                "{solver:?} frame {k}: pen {}° off the axis",
                a.to_degrees()
            );
        }
        assert!(r.reached as f64 >= 0.97 * r.frames as f64, "{solver:?}");
        assert_tip_on_targets(&f, &r, "joint_2");
    }
}
