//! The drawn trail as tubes: read back from the file, every vertex at the trail radius from the
//! polyline the tip drew (tip positions from the file's own animation by independent forward
//! kinematics), every drawn point inside the tube, and pieces revealed no earlier than drawn.

use crate::common;

use common::geometry::Triangles;
use common::{load, mesh_path, Loaded, Tracks};
use glam::DVec3;
use scenebake::bake::{bake_ik, IkJob, IkReport};

/// Distance from `p` to the segment `a`–`b`.
fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let d = b - a;
    let len2 = d.dot(d);
    let t = if len2 > 0.0 {
        ((p - a).dot(d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + d * t)
}

/// Distance from `p` to the drawn polylines: consecutive pen-down frames, up to frame `upto`.
fn drawn_distance(p: DVec3, tips: &[DVec3], down: &[bool], upto: usize) -> f64 {
    let mut best = f64::INFINITY;
    for k in 0..=upto.min(tips.len() - 1) {
        if !down[k] {
            continue;
        }
        let d = if k < upto && k + 1 < tips.len() && down[k + 1] {
            segment_distance(p, tips[k], tips[k + 1])
        } else {
            p.distance(tips[k])
        };
        best = best.min(d);
    }
    best
}

/// How near `p` comes to lying at `radius` from one segment (or point) of the drawn polylines
/// selected by `down`: the least |distance − radius| over them.
fn radius_gap(p: DVec3, tips: &[DVec3], down: &[bool], radius: f64) -> f64 {
    let mut best = f64::INFINITY;
    for k in (0..tips.len()).filter(|&k| down[k]) {
        let d = if k + 1 < tips.len() && down[k + 1] {
            segment_distance(p, tips[k], tips[k + 1])
        } else {
            p.distance(tips[k])
        };
        best = best.min((d - radius).abs());
    }
    best
}

/// A trail piece read back: its reveal time, and its triangles and vertices in world space once
/// revealed (scale 1 about the node's translation; the trail sits at the scene root).
struct Piece {
    reveal: f32,
    vertices: Vec<DVec3>,
    triangles: Vec<[DVec3; 3]>,
}

fn pieces(l: &Loaded, tracks: &Tracks) -> Vec<Piece> {
    let trail = l.doc.nodes().nth(l.node_by_name("trail")).unwrap();
    assert!(
        l.doc
            .scenes()
            .all(|s| s.nodes().any(|n| n.index() == trail.index())),
        "the trail is a scene root"
    );
    trail
        .children()
        .map(|node| {
            let (t, r, _) = node.transform().decomposed();
            assert_eq!(r, [0.0, 0.0, 0.0, 1.0]);
            let origin = DVec3::from_array(t.map(f64::from));
            let (times, vals, step) = tracks.scale.get(&node.index()).expect("revealed by a key");
            assert!(*step, "STEP reveal");
            assert!(vals[0][0] < 1e-3 && vals.last().unwrap() == &[1.0; 3]);
            let prim = node.mesh().unwrap().primitives().next().unwrap();
            assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles);
            let reader = prim.reader(|b| Some(&l.buffers[b.index()]));
            let vertices: Vec<DVec3> = reader
                .read_positions()
                .unwrap()
                .map(|p| origin + DVec3::from_array(p.map(f64::from)))
                .collect();
            let normals: Vec<[f32; 3]> = reader.read_normals().expect("normals").collect();
            assert_eq!(normals.len(), vertices.len());
            let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            let triangles = idx
                .chunks(3)
                .map(|t| [0, 1, 2].map(|k| vertices[t[k] as usize]))
                .collect();
            Piece {
                reveal: *times.last().unwrap(),
                vertices,
                triangles,
            }
        })
        .collect()
}

/// Checks the trail of a bake against the tip positions of the file's animation (`tip` node).
/// Returns the trail's triangle count.
fn check_trail(r: &IkReport, path: &std::path::Path, tip: usize, radius: f64) -> usize {
    let l = load(path);
    let tracks = l.animation("ik");
    let fps = r.fps;
    let tips: Vec<DVec3> = (0..r.frames)
        .map(|k| l.world_pos(&tracks, tip, (k as f64 / fps) as f32))
        .collect();
    let down = &r.pen_down;
    let last = r.frames - 1;
    let pieces = pieces(&l, &tracks);
    assert!(pieces.len() > 5);
    // f32 positions and keys of a metre-sized scene.
    let tol = 2e-6 + 1e-4 * radius;

    let all = Triangles {
        triangles: pieces.iter().flat_map(|p| p.triangles.clone()).collect(),
    };

    // Every vertex lies at the radius from a segment its stroke drew (its own), and no nearer to
    // the rest of the stroke unless it is buried inside another pass of the tube where the
    // stroke comes back near itself (a cursive loop closing): the winding number of the whole
    // trail there above 1 (about 1/2 from its own surface, 1 more from the tube around it), or it
    // grazes that pass within the depth of the tube's flat faces (8-sided rings, caps of two
    // latitude steps: every face lies beyond the radius times cos² 22.5° from the line). Never
    // farther than the radius from the whole drawing.
    let stroke_of = |f: usize| {
        let (mut a, mut b) = (f, f);
        while a > 0 && down[a - 1] {
            a -= 1;
        }
        while b < last && down[b + 1] {
            b += 1;
        }
        (a, b)
    };
    let flat = radius * (std::f64::consts::PI / 8.0).cos().powi(2);
    let mut worst: f64 = 0.0;
    let (mut buried, mut vertices) = (0, 0);
    for p in &pieces {
        // The piece's stroke: the pen-down frames around the frame that reveals it.
        let end = ((p.reveal as f64 * fps + 0.5).round() as usize).min(last);
        let (a, b) = stroke_of(end);
        let stroke: Vec<bool> = (0..r.frames).map(|k| (a..=b).contains(&k)).collect();
        for v in &p.vertices {
            vertices += 1;
            let from_drawing = drawn_distance(*v, &tips, down, last);
            assert!(
                from_drawing <= radius + tol,
                "a vertex is {from_drawing} from the drawing (radius {radius})"
            );
            let gap = radius_gap(*v, &tips, &stroke, radius);
            worst = worst.max(gap);
            let d = drawn_distance(*v, &tips, &stroke, last);
            if d < radius - tol {
                let w = all.winding_number(*v);
                assert!(
                    w > 1.0 || d >= flat - tol,
                    "a vertex {} inside the radius {radius} of its stroke is not buried in the tube (winding {w})",
                    radius - d
                );
                buried += 1;
            }
        }
    }
    assert!(
        worst <= tol,
        "a vertex is {worst} off the radius {radius} from every segment of its stroke (tolerance {tol})"
    );
    println!("every vertex within {worst:.2e} of the radius from its stroke; {buried} of {vertices} inside another pass of it");

    // Every drawn point inside the closed tube surface.
    for k in (0..r.frames).filter(|&k| down[k]) {
        let w = all.winding_number(tips[k]);
        assert!(
            w > 0.5,
            "frame {k}: the tip is outside the tube (winding {w})"
        );
    }

    // In step with the animation: at frame f, the pieces shown lie within the radius of what the
    // tip has drawn by then, and they cover it all but the last piece's frames (12).
    for f in (0..r.frames).step_by(37) {
        let t = (f as f64 / fps) as f32;
        let shown: Vec<&Piece> = pieces.iter().filter(|p| p.reveal <= t).collect();
        for p in &shown {
            for v in &p.vertices {
                let d = drawn_distance(*v, &tips, down, f);
                assert!(d <= radius + tol, "frame {f}: shown before drawn ({d})");
            }
        }
        let shown = Triangles {
            triangles: shown.iter().flat_map(|p| p.triangles.clone()).collect(),
        };
        for k in (0..f.saturating_sub(12)).filter(|&k| down[k]) {
            assert!(
                shown.winding_number(tips[k]) > 0.5,
                "frame {f}: frame {k}'s ink is not shown yet"
            );
        }
    }
    all.triangles.len()
}

#[test]
fn a_chain_writes_its_trail_as_tubes_at_the_radius() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        text: Some("Ada".into()),
        trail_radius: Some(0.01),
        output: dir.path().join("ada.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    assert_eq!(r.trail_radius, 0.01);
    let l = load(&job.output);
    let tip = l.node_by_name(r.joint_names.last().unwrap());
    let triangles = check_trail(&r, &job.output, tip, 0.01);
    println!("chain: {} frames, {triangles} trail triangles", r.frames);
}

#[test]
fn a_rig_writes_its_trail_in_world_space() {
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        rig: Some(mesh_path("CesiumMan.glb")),
        chain: Some("#13..#15".into()),
        text: Some("Ada".into()),
        output: dir.path().join("cesium_ada.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    // The default: 0.5 % of the diagonal of the pen-down targets' bounding box.
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for (t, &down) in r.targets.iter().zip(&r.pen_down) {
        if down {
            lo = lo.min(DVec3::from_array(*t));
            hi = hi.max(DVec3::from_array(*t));
        }
    }
    let radius = 0.005 * (hi - lo).length();
    assert!((r.trail_radius - radius).abs() < 1e-12 * radius);
    let triangles = check_trail(&r, &job.output, 15, r.trail_radius);
    println!("rig: {} frames, {triangles} trail triangles", r.frames);
}

#[test]
fn a_walking_rig_leaves_its_trail_where_the_pen_drew() {
    // The demo's robot_writing: the hand writes on a board while the body walks; the trail stays
    // on the board in the world, not on the moving body.
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        rig: Some(mesh_path("humanoid/RobotExpressive.glb")),
        chain: Some("UpperArmR..Palm2R".into()),
        base_animation: Some("Walking".into()),
        text: Some("hello".into()),
        font: Some("script".into()),
        size: Some(0.2),
        pen_speed: Some(0.5),
        center: Some(DVec3::new(-0.45, 1.85, 1.2)),
        normal: Some(DVec3::new(0.0, 0.0, -1.0)),
        pole: Some(DVec3::new(-2.0, 0.5, 0.0)),
        limit: vec![
            "LowerArmR:hinge:-120..0".into(),
            "UpperArmR:cone:100".into(),
            "UpperArmR:twist:0..75".into(),
        ],
        tip_axis: Some(DVec3::Z),
        fps: 24.0,
        output: dir.path().join("robot.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    let l = load(&job.output);
    let tip = l.node_by_name("Palm2R");
    let triangles = check_trail(&r, &job.output, tip, r.trail_radius);
    println!(
        "walking rig: {} frames, {triangles} trail triangles",
        r.frames
    );
}
