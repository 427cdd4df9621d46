//! Characters that write while they walk (issue 17's must-show): a humanoid (the Quaternius
//! robot, `meshes/humanoid/RobotExpressive.glb`) writes a lower-case word in the script font on a
//! board in front of its chest while its Walking animation plays, and Fox's head draws a heart
//! while it walks.
//!
//! Everything is checked on the exported file with the gltf crate, the independent FK of
//! tests/it/common and a spherical-linear sampler of the *input* file's animation written below;
//! none of scenebake's chain, solver or animation code is used for the expectations.

use crate::common;

use common::{load, Loaded, Tracks};
use glam::{DQuat, DVec3};
use scenebake::bake::{bake_ik, IkJob, IkReport};
use scenebake::ik::SolverKind;

const ROBOT: &str = "meshes/humanoid/RobotExpressive.glb";
const POLE: DVec3 = DVec3::new(-2.0, 0.5, 0.0);
/// 1 mm, in the robot's scene units (it is 4.1 units tall; taken as metres).
const MM: f64 = 1e-3;

fn robot_job(dir: &std::path::Path, solver: SolverKind) -> IkJob {
    IkJob {
        rig: Some(common::crate_dir().join(ROBOT)),
        chain: Some("UpperArmR..Palm2R".into()),
        base_animation: Some("Walking".into()),
        text: Some("hello".into()),
        font: Some("script".into()),
        size: Some(0.2),
        center: Some(DVec3::new(-0.45, 1.85, 1.2)),
        normal: Some(DVec3::new(0.0, 0.0, -1.0)),
        pole: Some(POLE),
        limit: vec![
            "LowerArmR:hinge:-120..0".into(),
            "UpperArmR:cone:100".into(),
            "UpperArmR:twist:0..75".into(),
        ],
        tip_axis: Some(DVec3::Z),
        solver,
        output: dir.join(format!("robot_{}.glb", solver.as_str())),
        ..Default::default()
    }
}

/// One animation of a document as raw tracks: (node, path) → (times, values).
struct Anim {
    rotation: Vec<(usize, Vec<f32>, Vec<[f32; 4]>)>,
    translation: Vec<(usize, Vec<f32>, Vec<[f32; 3]>)>,
    end: f32,
}

fn read_anim(l: &Loaded, name: &str) -> Anim {
    let a = l
        .doc
        .animations()
        .find(|a| a.name() == Some(name))
        .unwrap_or_else(|| panic!("no animation {name}"));
    let mut out = Anim {
        rotation: Vec::new(),
        translation: Vec::new(),
        end: 0.0,
    };
    for ch in a.channels() {
        // The drawn trail's pieces are revealed by STEP scale keys; the rest is LINEAR.
        if ch
            .target()
            .node()
            .name()
            .is_some_and(|n| n.starts_with("trail_"))
        {
            assert_eq!(ch.target().property(), gltf::animation::Property::Scale);
            assert_eq!(
                ch.sampler().interpolation(),
                gltf::animation::Interpolation::Step
            );
            continue;
        }
        assert_eq!(
            ch.sampler().interpolation(),
            gltf::animation::Interpolation::Linear
        );
        let reader = ch.reader(|b| Some(&l.buffers[b.index()]));
        let times: Vec<f32> = reader.read_inputs().unwrap().collect();
        out.end = out.end.max(*times.last().unwrap());
        let node = ch.target().node().index();
        match reader.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::Rotations(r) => {
                out.rotation.push((node, times, r.into_f32().collect()))
            }
            gltf::animation::util::ReadOutputs::Translations(v) => {
                out.translation.push((node, times, v.collect()))
            }
            _ => {}
        }
    }
    out
}

/// Key interval and fraction for time `t` (clamped to the keys).
fn bracket(times: &[f32], t: f64) -> (usize, usize, f64) {
    let last = times.len() - 1;
    if t <= times[0] as f64 {
        return (0, 0, 0.0);
    }
    if t >= times[last] as f64 {
        return (last, last, 0.0);
    }
    let k = times.partition_point(|&x| (x as f64) <= t) - 1;
    let u = (t - times[k] as f64) / (times[k + 1] - times[k]) as f64;
    (k, k + 1, u)
}

/// glTF LINEAR rotation sampling: slerp on the shorter arc (spec, Appendix C).
fn slerp_at(times: &[f32], vals: &[[f32; 4]], t: f64) -> DQuat {
    let (a, b, u) = bracket(times, t);
    let qa = DQuat::from_array(vals[a].map(f64::from)).normalize();
    let mut qb = DQuat::from_array(vals[b].map(f64::from)).normalize();
    let mut d = qa.dot(qb);
    if d < 0.0 {
        qb = -qb;
        d = -d;
    }
    if d > 1.0 - 1e-12 {
        return qa;
    }
    let th = d.acos();
    (qa * ((1.0 - u) * th).sin() + qb * (u * th).sin()) * (1.0 / th.sin())
}

fn lerp_at(times: &[f32], vals: &[[f32; 3]], t: f64) -> DVec3 {
    let (a, b, u) = bracket(times, t);
    let va = DVec3::from_array(vals[a].map(f64::from));
    va.lerp(DVec3::from_array(vals[b].map(f64::from)), u)
}

fn same_rotation(a: DQuat, b: DQuat) -> f64 {
    // Angle between two rotations, radians (atan2 of the relative rotation: exact near 0,
    // where acos of the dot product loses half the digits).
    let d = a.inverse() * b;
    2.0 * DVec3::new(d.x, d.y, d.z).length().atan2(d.w.abs())
}

/// Asserts that every node of `nodes` has, in the export's first animation, exactly the base
/// animation's rotation (and translation, where keyed) at every frame time, looped.
#[track_caller]
fn assert_keeps_base(out: &Loaded, input: &Loaded, base: &str, nodes: &[&str], fps: f64) {
    let first = out.doc.animations().next().unwrap();
    assert_eq!(first.name(), Some("ik"), "the bake is the first animation");
    let baked = read_anim(out, "ik");
    let src = read_anim(input, base);
    assert!(src.end > 0.0);
    let (mut worst_angle, mut checked) = (0f64, 0);
    for name in nodes {
        let node = input.node_by_name(name);
        assert_eq!(out.node_by_name(name), node);
        let (_, src_t, src_q) = src
            .rotation
            .iter()
            .find(|(n, _, _)| *n == node)
            .unwrap_or_else(|| panic!("{base} does not animate {name}"));
        let (_, times, keys) = baked
            .rotation
            .iter()
            .find(|(n, _, _)| *n == node)
            .unwrap_or_else(|| panic!("the bake does not key {name}"));
        for (k, (t, q)) in times.iter().zip(keys).enumerate() {
            assert!((*t as f64 - k as f64 / fps).abs() < 1e-5);
            let want = slerp_at(src_t, src_q, (k as f64 / fps) % src.end as f64);
            let got = DQuat::from_array(q.map(f64::from));
            assert!(
                same_rotation(want, got) < 1e-5,
                "{name} frame {k}: {}° from the base animation ({want} vs {got})",
                same_rotation(want, got).to_degrees()
            );
            worst_angle = worst_angle.max(same_rotation(want, got));
            checked += 1;
        }
        if let Some((_, src_t, src_v)) = src.translation.iter().find(|(n, _, _)| *n == node) {
            let (_, _, _, vals) = baked
                .translation
                .iter()
                .find(|(n, _, _)| *n == node)
                .map(|(n, t, v)| (n, t, 0, v))
                .unwrap();
            for (k, v) in vals.iter().enumerate() {
                let want = lerp_at(src_t, src_v, (k as f64 / fps) % src.end as f64);
                let d = DVec3::from_array(v.map(f64::from)).distance(want);
                assert!(d < 1e-6 * want.length().max(1.0), "{name} frame {k}: {d}");
            }
        }
    }
    eprintln!(
        "{} nodes keep {base}: {checked} rotation keys, ≤ {:.1e}° from it",
        nodes.len(),
        worst_angle.to_degrees()
    );
}

/// Twist of the local rotation change `d` about the unit bone axis `b0`, measured geometrically:
/// a reference vector across the bone, turned by `d`, then carried back by the shortest arc
/// from the bone's new direction to `b0`, ends up turned about `b0` by the twist.
fn twist_of(d: DQuat, b0: DVec3) -> f64 {
    let p0 = b0.any_orthonormal_vector();
    let p2 = DQuat::from_rotation_arc(d * b0, b0) * (d * p0);
    p0.cross(p2).dot(b0).atan2(p0.dot(p2))
}

struct Baked {
    r: IkReport,
    out: Loaded,
    tracks: Tracks,
}

fn bake(job: &IkJob) -> Baked {
    let r = bake_ik(job, &mut |_, _| {}).unwrap();
    let out = load(&job.output);
    let tracks = out.animation("ik");
    Baked { r, out, tracks }
}

impl Baked {
    fn pos(&self, name: &str, k: usize) -> DVec3 {
        let t = (k as f64 / self.r.fps) as f32;
        self.out
            .world_pos(&self.tracks, self.out.node_by_name(name), t)
    }

    fn local_rotation(&self, name: &str, k: usize) -> DQuat {
        let (times, keys) = &self.tracks.rotation[&self.out.node_by_name(name)];
        common::sample_quat(times, keys, times[k])
    }
}

#[test]
fn a_walking_humanoid_writes_a_cursive_word_on_a_board_in_front_of_its_chest() {
    let dir = tempfile::tempdir().unwrap();
    let input = load(&common::crate_dir().join(ROBOT));
    let rest = |name: &str| {
        let (_, r, s) = input
            .doc
            .nodes()
            .nth(input.node_by_name(name))
            .unwrap()
            .transform()
            .decomposed();
        (
            DQuat::from_array(r.map(f64::from)),
            DVec3::from_array(s.map(f64::from)),
        )
    };
    let offset = |name: &str| {
        let (t, _, _) = input
            .doc
            .nodes()
            .nth(input.node_by_name(name))
            .unwrap()
            .transform()
            .decomposed();
        DVec3::from_array(t.map(f64::from))
    };
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = robot_job(dir.path(), solver);
        let b = bake(&job);
        let r = &b.r;
        assert_eq!(r.reached, r.frames, "{solver:?}: max error {}", r.max_error);

        // The hand on every pen-down target, by the file's own FK.
        let mut down = 0;
        let mut worst_hand = 0f64;
        for k in 0..r.frames {
            if !r.pen_down[k] {
                continue;
            }
            down += 1;
            let d = b.pos("Palm2R", k).distance(DVec3::from_array(r.targets[k]));
            assert!(d < MM, "{solver:?} frame {k}: hand {d} from the target");
            worst_hand = worst_hand.max(d);
        }
        assert!(down > 100, "{solver:?}: {down} pen-down frames");

        // The board is in front of the chest, and the shoulder really moves (walking).
        let s0 = b.pos("UpperArmR", 0);
        let shoulder_path: f64 = (1..r.frames)
            .map(|k| b.pos("UpperArmR", k).distance(b.pos("UpperArmR", k - 1)))
            .sum();
        assert!(
            shoulder_path > 0.2,
            "{solver:?}: shoulder moved {shoulder_path}"
        );
        for t in &r.targets {
            assert!(t[2] > s0.z + 0.5 && t[1] > 1.5 && t[1] < s0.y, "{t:?}");
        }

        let (hinge_rest, _) = rest("LowerArmR");
        let (upper_rest, upper_scale) = rest("UpperArmR");
        let b0 = (upper_rest * (upper_scale * offset("LowerArmR"))).normalize();
        let mut hinge_axis: Option<DVec3> = None;
        // Figures for the closing note (printed with --nocapture): the smallest margins found.
        let (mut elbow_side, mut elbow_below) = (f64::MAX, f64::MAX);
        let (mut max_hinge, mut max_swing, mut max_pen) = (0f64, 0f64, 0f64);
        let (mut twist_lo, mut twist_hi) = (f64::MAX, f64::MIN);
        let pen = offset("Middle1R").normalize();
        for k in 0..r.frames {
            let (s, e, h) = (
                b.pos("UpperArmR", k),
                b.pos("LowerArmR", k),
                b.pos("Palm2R", k),
            );
            // The elbow never flips across the shoulder–hand line and stays below the shoulder.
            let line = (h - s).normalize();
            let off = (e - s).reject_from(line);
            let side = off.dot((POLE - s).reject_from(line).normalize());
            assert!(side > 0.0, "{solver:?} frame {k}: the elbow flipped");
            assert!(e.y < s.y, "{solver:?} frame {k}: elbow above the shoulder");
            elbow_side = elbow_side.min(side);
            elbow_below = elbow_below.min(s.y - e.y);

            // Hinge: one fixed axis, one side of the rest angle, at most 120°.
            let d = b.local_rotation("LowerArmR", k) * hinge_rest.inverse();
            let (axis, angle) = d.to_axis_angle();
            let (axis, angle) = if angle < 0.0 {
                (-axis, -angle)
            } else {
                (axis, angle)
            };
            let angle = if angle > std::f64::consts::PI {
                std::f64::consts::TAU - angle
            } else {
                angle
            };
            assert!(angle <= 120f64.to_radians() + 1e-4, "{solver:?} frame {k}");
            max_hinge = max_hinge.max(angle);
            if angle > 0.05 {
                let fixed = *hinge_axis.get_or_insert(axis);
                assert!(
                    axis.dot(fixed) > 1.0 - 1e-6,
                    "{solver:?} frame {k}: the elbow left its hinge (or crossed its rest angle)"
                );
            }
            // Cone and twist on the shoulder, from its exported rotation.
            let d = b.local_rotation("UpperArmR", k) * upper_rest.inverse();
            let swing = (d * b0).angle_between(b0);
            assert!(swing <= 100f64.to_radians() + 1e-4, "{solver:?} frame {k}");
            max_swing = max_swing.max(swing);
            let twist = twist_of(d, b0).to_degrees();
            twist_lo = twist_lo.min(twist);
            twist_hi = twist_hi.max(twist);
            assert!(
                (-1e-3..=75.0 + 1e-3).contains(&twist),
                "{solver:?} frame {k}: shoulder twist {twist}°"
            );
            // The pen (the hand's bone, towards the fingers) points into the board.
            let w = b.out.world(
                &b.tracks,
                b.out.node_by_name("Palm2R"),
                (k as f64 / r.fps) as f32,
            );
            let a = w.transform_vector3(pen).angle_between(DVec3::Z);
            assert!(
                a < 0.05f64.to_radians(),
                "{solver:?} frame {k}: pen {}° off",
                a.to_degrees()
            );
            max_pen = max_pen.max(a);
        }
        eprintln!(
            "{solver:?}: {down} pen-down of {} frames, hand ≤ {:.2e} from its target (file FK); \
             elbow ≥ {:.3} towards the pole side, ≥ {:.3} below the shoulder; hinge ≤ {:.1}°, \
             cone ≤ {:.1}°, twist {:.1}..{:.1}°, pen ≤ {:.4}° off +Z; shoulder path {:.2}",
            r.frames,
            worst_hand,
            elbow_side,
            elbow_below,
            max_hinge.to_degrees(),
            max_swing.to_degrees(),
            twist_lo,
            twist_hi,
            max_pen.to_degrees(),
            shoulder_path,
        );

        // The legs (and the body and the other arm) keep the walk exactly.
        assert_keeps_base(
            &b.out,
            &input,
            "Walking",
            &[
                "UpperLegL",
                "LowerLegL",
                "UpperLegR",
                "LowerLegR",
                "FootL",
                "FootR",
                "Body",
                "ShoulderR",
                "UpperArmL",
                "LowerArmL",
            ],
            r.fps,
        );
        // The whole skeleton is keyed: every joint of every skin.
        for skin in b.out.doc.skins() {
            for j in skin.joints() {
                assert!(
                    b.tracks.rotation.contains_key(&j.index())
                        && b.tracks.translation.contains_key(&j.index())
                        && b.tracks.scale.contains_key(&j.index()),
                    "{solver:?}: joint {:?} not keyed",
                    j.name()
                );
            }
        }
    }
}

#[test]
fn fox_draws_a_heart_with_its_head_while_it_walks() {
    let dir = tempfile::tempdir().unwrap();
    let fox = common::crate_dir().join("meshes/Fox.glb");
    let input = load(&fox);
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = IkJob {
            rig: Some(fox.clone()),
            chain: Some("b_Spine02_03..b_Head_05".into()),
            base_animation: Some("Walk".into()),
            curve: Some(scenebake::path::CurveKind::Heart),
            radius: Some(6.0),
            center: Some(DVec3::new(0.0, 56.0, 36.0)),
            normal: Some(DVec3::new(0.0, 0.0, -1.0)),
            solver,
            output: dir.path().join(format!("fox_{}.glb", solver.as_str())),
            ..Default::default()
        };
        let b = bake(&job);
        assert_eq!(b.r.reached, b.r.frames, "{solver:?}");
        // Fox is in centimetre-like units: 1 mm = 0.1.
        for k in 0..b.r.frames {
            let d = b
                .pos("b_Head_05", k)
                .distance(DVec3::from_array(b.r.targets[k]));
            assert!(d < 0.1, "{solver:?} frame {k}: head {d} from the heart");
        }
        // The heart is drawn in the fixed world plane z = 36 while the spine below moves.
        assert!(b.r.targets.iter().all(|t| (t[2] - 36.0).abs() < 1e-9));
        assert_keeps_base(
            &b.out,
            &input,
            "Walk",
            &[
                "b_LeftLeg01_015",
                "b_LeftLeg02_016",
                "b_RightLeg01_019",
                "b_RightFoot01_021",
                "b_Tail02_013",
                "b_Spine01_02",
                "b_RightUpperArm_06",
            ],
            b.r.fps,
        );
    }
}

#[test]
fn a_base_animation_needs_a_rig_and_a_name_it_has() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        base_animation: Some("Strut".into()),
        ..robot_job(dir.path(), SolverKind::Fabrik)
    };
    let e = bake_ik(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(
        e.contains("`base_animation`") && e.contains("Strut") && e.contains("#10 `Walking`"),
        "{e}"
    );
    assert!(!job.output.exists());
    let by_index = IkJob {
        base_animation: Some("#10".into()),
        ..robot_job(dir.path(), SolverKind::Fabrik)
    };
    let r = bake_ik(&by_index, &mut |_, _| {}).unwrap();
    assert_eq!(r.reached, r.frames);
    let e = bake_ik(
        &IkJob {
            joints: Some(3),
            curve: Some(scenebake::path::CurveKind::Circle),
            base_animation: Some("Walk".into()),
            output: dir.path().join("x.glb"),
            ..Default::default()
        },
        &mut |_, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("`base_animation`") && e.contains("`rig`"), "{e}");
}
