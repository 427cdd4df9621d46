//! Lab-arm bakes, checked through the written glTF with an independent FK sampler.

use crate::common;

use common::{load, vec3_of};
use glam::DVec3;
use scenebake::bake::{bake_ik, IkJob};
use scenebake::ik::SolverKind;
use scenebake::path::CurveKind;

const OFFSETS: [[f64; 3]; 5] = [
    [0.0, 1.7, 0.0],
    [0.0, -0.8, 0.0],
    [0.0, -0.4, 0.0],
    [0.0, -0.2, 0.0],
    [0.0, -1.2, 0.0],
];

fn lab_job(dir: &std::path::Path, name: &str) -> IkJob {
    IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        output: dir.join(format!("{name}.glb")),
        ..Default::default()
    }
}

/// Tip of the arm in the baked file at key `k`, plus all joint positions.
fn joint_positions(l: &common::Loaded, tracks: &common::Tracks, t: f32, n: usize) -> Vec<DVec3> {
    (0..n)
        .map(|i| l.world_pos(tracks, l.node_by_name(&format!("joint_{i}")), t))
        .collect()
}

/// How many keys of the baked file put the tip (`joint_4`, posed by our own FK) within
/// `tolerance` of that frame's target, plus f32 rounding of the keys: counted here from the
/// written file, not read from the report.
fn reached_in_file(path: &std::path::Path, targets: &[[f64; 3]], tolerance: f64) -> usize {
    let l = load(path);
    let tracks = l.animation("ik");
    let (times, _) = tracks.rotation.values().next().unwrap();
    assert_eq!(times.len(), targets.len(), "one key per target");
    let tip = l.node_by_name("joint_4");
    times
        .iter()
        .zip(targets)
        .filter(|(&t, target)| {
            l.world_pos(&tracks, tip, t)
                .distance(DVec3::from_array(**target))
                <= tolerance + 1e-5
        })
        .count()
}

#[track_caller]
fn assert_bones_kept(p: &[DVec3]) {
    for i in 1..p.len() {
        let want = DVec3::from_array(OFFSETS[i]).length();
        let got = p[i].distance(p[i - 1]);
        assert!((got - want).abs() < 1e-5, "bone {i}: {got} vs {want}");
    }
    assert!(
        p[0].distance(DVec3::new(0.0, 1.7, 0.0)) < 1e-6,
        "root moved: {}",
        p[0]
    );
}

#[test]
fn fabrik_circle_tip_follows_the_lab_circle() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        curve: Some(CurveKind::Circle),
        solver: SolverKind::Fabrik,
        ..lab_job(dir.path(), "circle")
    };
    let report = bake_ik(&job, &mut |_, _| {}).unwrap();
    assert_eq!(report.frames, 150);
    let l = load(&job.output);
    let tracks = l.animation("ik");
    let (times, _) = tracks.rotation.values().next().unwrap();
    assert_eq!(times.len(), 150);
    for (k, &t) in times.iter().enumerate() {
        let p = joint_positions(&l, &tracks, t, 5);
        assert_bones_kept(&p);
        let tip = p[4];
        // The lab circle: radius 0.6 about the origin in the y = 0 plane.
        assert!(
            tip.y.abs() < 1e-4 + 1e-5,
            "frame {k}: tip {tip} off the plane"
        );
        assert!(
            ((tip.x * tip.x + tip.z * tip.z).sqrt() - 0.6).abs() < 1e-4 + 1e-5,
            "frame {k}: tip {tip} off the circle"
        );
        let target = DVec3::from_array(report.targets[k]);
        assert!(
            tip.distance(target) <= 1e-4 + 1e-5,
            "frame {k}: |tip - target| = {}",
            tip.distance(target)
        );
    }
    // Targets go once around the circle, evenly.
    let d: Vec<f64> = report
        .targets
        .windows(2)
        .map(|w| DVec3::from_array(w[0]).distance(DVec3::from_array(w[1])))
        .collect();
    let (lo, hi) = d
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi - lo < 1e-9, "uneven circle targets {lo}..{hi}");
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["solver"], "fabrik");
    assert_eq!(json["frames"], 150);
    assert_eq!(json["joints"], 5);
    for key in [
        "targets",
        "iterations",
        "error",
        "reached",
        "unreachable",
        "mean_iterations",
        "seconds_total",
    ] {
        assert!(!json[key].is_null(), "report lacks {key}");
    }
}

#[test]
fn ccd_and_fabrik_both_reach_the_circle_and_fabrik_iterates_less() {
    let dir = tempfile::tempdir().unwrap();
    let mut means = Vec::new();
    for solver in [SolverKind::Ccd, SolverKind::Fabrik] {
        let job = IkJob {
            curve: Some(CurveKind::Circle),
            solver,
            ..lab_job(dir.path(), solver.as_str())
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        let reached = reached_in_file(&job.output, &r.targets, job.tolerance);
        assert_eq!(
            reached, r.frames,
            "{solver:?}: {reached} of {} frames reached in the file, max error {}",
            r.frames, r.max_error
        );
        assert_eq!(r.reached, reached, "{solver:?}: the report agrees");
        assert_eq!(r.unreachable, 0);
        let l = load(&job.output);
        let tracks = l.animation("ik");
        let (times, _) = tracks.rotation.values().next().unwrap();
        for (k, &t) in times.iter().enumerate() {
            let p = joint_positions(&l, &tracks, t, 5);
            assert_bones_kept(&p);
            assert!(
                p[4].distance(DVec3::from_array(r.targets[k])) <= 1e-4 + 1e-5,
                "{solver:?} frame {k}"
            );
        }
        means.push(r.mean_iterations);
    }
    assert!(
        means[1] < means[0],
        "FABRIK mean iterations {} not below CCD {}",
        means[1],
        means[0]
    );
}

#[test]
fn unreachable_targets_stretch_the_chain_straight_without_twitching() {
    let dir = tempfile::tempdir().unwrap();
    // World points (x,y,z) far outside the 2.6 reach of the root at (0, 1.7, 0).
    let csv = dir.path().join("far.csv");
    let pts: String = (0..20)
        .map(|k| format!("{},{},{}\n", 4.0, 1.7 + 0.05 * k as f64, 1.0))
        .collect();
    std::fs::write(&csv, pts).unwrap();
    for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
        let job = IkJob {
            points: Some(csv.clone()),
            solver,
            spacing: Some(0.05),
            ..lab_job(dir.path(), &format!("far_{}", solver.as_str()))
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert_eq!(r.unreachable, r.frames, "{solver:?}");
        assert_eq!(r.reached, 0);
        assert_eq!(reached_in_file(&job.output, &r.targets, job.tolerance), 0);
        let l = load(&job.output);
        let tracks = l.animation("ik");
        let (times, keys) = tracks.rotation.values().next().unwrap();
        for (k, &t) in times.iter().enumerate() {
            let p = joint_positions(&l, &tracks, t, 5);
            assert_bones_kept(&p);
            let target = DVec3::from_array(r.targets[k]);
            let dir_t = (target - p[0]).normalize();
            for q in &p[1..] {
                let along = (*q - p[0]).normalize().dot(dir_t);
                assert!(
                    along > 1.0 - 1e-9,
                    "{solver:?} frame {k}: joint not on the root→target line ({along})"
                );
            }
            assert!((r.error[k] - (target.distance(p[0]) - 2.6)).abs() < 1e-5);
        }
        // No twitching: consecutive keys of every joint differ by a small rotation.
        for w in keys.windows(2) {
            let dot: f32 = w[0].iter().zip(&w[1]).map(|(a, b)| a * b).sum();
            assert!(dot > 0.99, "{solver:?}: jump between frames (dot {dot})");
        }
    }
}

#[test]
fn text_bake_lifts_the_pen_and_reveals_the_trail() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        text: Some("HELLO".into()),
        ..lab_job(dir.path(), "hello")
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    let json = serde_json::to_value(&r).unwrap();
    let pen: Vec<bool> = json["pen_down"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_bool().unwrap())
        .collect();
    assert!(
        pen.iter().filter(|d| !**d).count() > 0,
        "the pen never lifted"
    );
    // Pen-down targets lie in the y = 0 drawing plane; lifted ones above it (towards the root).
    for (k, t) in json["targets"].as_array().unwrap().iter().enumerate() {
        let t = vec3_of(t);
        if pen[k] {
            assert!(t.y.abs() < 1e-12, "frame {k}: drawing off the plane");
        } else {
            assert!(t.y > -1e-12, "frame {k}: pen below the paper");
        }
    }
    assert_eq!(r.unreachable, 0);
    let reached = reached_in_file(&job.output, &r.targets, job.tolerance);
    assert_eq!(
        reached, r.frames,
        "{reached} of {} frames reached in the file, max error {}",
        r.frames, r.max_error
    );
    assert_eq!(r.reached, reached, "the report agrees");
    // The letters fit the arm's reach and span a sensible width in x.
    let xs: Vec<f64> = r.targets.iter().map(|t| t[0]).collect();
    let width =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(width > 1.0 && width < 4.0, "text width {width}");

    let l = load(&job.output);
    let tracks = l.animation("ik");
    // Tip follows the targets in the file.
    let (times, _) = tracks.rotation.values().next().unwrap();
    assert_eq!(times.len(), r.frames);
    for (k, &t) in times.iter().enumerate().step_by(7) {
        let tip = l.world_pos(&tracks, l.node_by_name("joint_4"), t);
        assert!(
            tip.distance(DVec3::from_array(r.targets[k])) < 1e-4 + 1e-5,
            "frame {k}"
        );
    }
    // Trail pieces: hidden at t = 0, full size by the end, revealed in order.
    let trail = l.node_by_name("trail");
    let pieces: Vec<usize> = l
        .doc
        .nodes()
        .nth(trail)
        .unwrap()
        .children()
        .map(|c| c.index())
        .collect();
    assert!(pieces.len() > 5);
    let mut last_reveal = 0.0;
    for &p in &pieces {
        let (ts, vals, step) = tracks.scale.get(&p).expect("piece animated");
        assert!(*step);
        assert!(vals[0][0] < 1e-3 && vals[vals.len() - 1][0] == 1.0);
        assert!(ts[ts.len() - 1] >= last_reveal);
        last_reveal = ts[ts.len() - 1];
    }
}

#[test]
fn generated_chain_has_armature_skin_and_meshes() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        preset: None,
        joints: Some(7),
        length: Some(3.0),
        curve: Some(CurveKind::Star),
        output: dir.path().join("star.gltf"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    assert_eq!(r.joints, 7);
    assert!(dir.path().join("star.bin").is_file());
    let l = load(&job.output);
    let parents = l.parents();
    for i in 0..7 {
        let n = l.node_by_name(&format!("joint_{i}"));
        if i > 0 {
            assert_eq!(
                parents[n],
                Some(l.node_by_name(&format!("joint_{}", i - 1)))
            );
            let (t, _, _) = l.doc.nodes().nth(n).unwrap().transform().decomposed();
            assert!(
                (DVec3::from_array(t.map(f64::from)) - DVec3::new(0.0, -0.5, 0.0)).length() < 1e-6
            );
        } else {
            assert_eq!(parents[n], None);
        }
    }
    let skin = l.doc.skins().next().unwrap();
    assert_eq!(skin.joints().count(), 7);
    let ibm: Vec<_> = skin
        .reader(|b| Some(&l.buffers[b.index()]))
        .read_inverse_bind_matrices()
        .unwrap()
        .collect();
    assert_eq!(ibm.len(), 7);
    let arm = l.doc.nodes().find(|n| n.skin().is_some()).unwrap();
    assert_eq!(parents[arm.index()], None);
    let prim = arm.mesh().unwrap().primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&l.buffers[b.index()]));
    let weights: Vec<[f32; 4]> = reader.read_weights(0).unwrap().into_f32().collect();
    assert!(weights
        .iter()
        .all(|w| (w.iter().sum::<f32>() - 1.0).abs() < 1e-6));
    let joints: Vec<[u16; 4]> = reader.read_joints(0).unwrap().into_u16().collect();
    assert!(joints.iter().all(|j| j[0] < 6));
    assert!(prim
        .get(&gltf::Semantic::Positions)
        .unwrap()
        .min()
        .is_some());
    let modes: Vec<_> = l
        .doc
        .meshes()
        .flat_map(|m| m.primitives().map(|p| p.mode()))
        .collect();
    // The target path is a guide of lines; the trail is tubes (triangles) that render.
    assert!(modes.contains(&gltf::mesh::Mode::Lines));
    assert!(!modes.contains(&gltf::mesh::Mode::LineStrip));
    let trail = l.doc.nodes().find(|n| n.name() == Some("trail")).unwrap();
    assert!(trail.children().all(|p| p
        .mesh()
        .unwrap()
        .primitives()
        .all(|q| q.mode() == gltf::mesh::Mode::Triangles)));
    assert!(l.doc.nodes().any(|n| n.name() == Some("pen_tip")));
}

#[test]
fn every_lab_curve_is_reached_by_both_solvers() {
    let dir = tempfile::tempdir().unwrap();
    for curve in CurveKind::ALL {
        for solver in [SolverKind::Fabrik, SolverKind::Ccd] {
            let job = IkJob {
                curve: Some(curve),
                solver,
                report: None,
                ..lab_job(
                    dir.path(),
                    &format!("{}_{}", curve.as_str(), solver.as_str()),
                )
            };
            let r = bake_ik(&job, &mut |_, _| {}).unwrap();
            assert_eq!(r.unreachable, 0, "{curve:?} {solver:?}");
            // Reached as the written file plays, counted here.
            let reached = reached_in_file(&job.output, &r.targets, job.tolerance);
            assert_eq!(
                reached, r.frames,
                "{curve:?} {solver:?}: {reached} of {} frames reached in the file, max error {}",
                r.frames, r.max_error
            );
            assert_eq!(
                r.reached, reached,
                "{curve:?} {solver:?}: the report agrees"
            );
            // Every target lies in the lab's y = 0 plane.
            assert!(r.targets.iter().all(|t| t[1].abs() < 1e-12), "{curve:?}");
        }
    }
}
