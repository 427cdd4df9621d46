//! The drawn trail as tubes: read back from the file, every vertex at the trail radius from the
//! polyline the tip drew (tip positions from the file's own animation by independent forward
//! kinematics), every drawn point inside the tube, and pieces revealed no earlier than drawn.

mod common;

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

    // Every vertex at the radius from the polyline of its own stroke (the pen-down frames
    // around the frame that reveals its piece), never farther than that from the drawing.
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
    let mut worst: f64 = 0.0;
    for p in &pieces {
        let end = (p.reveal as f64 * fps + 0.5).round() as usize;
        let (a, b) = stroke_of(end.min(last));
        let mask: Vec<bool> = (0..r.frames).map(|k| k >= a && k <= b).collect();
        for v in &p.vertices {
            let d = drawn_distance(*v, &tips, &mask, last);
            worst = worst.max((d - radius).abs());
            let all = drawn_distance(*v, &tips, down, last);
            assert!(all <= radius + tol, "a vertex is {all} from the drawing");
        }
    }
    assert!(
        worst <= tol,
        "a vertex is {worst} off the radius {radius} from its stroke (tolerance {tol})"
    );
    // Every drawn point inside the closed tube surface.
    let all = Triangles {
        triangles: pieces.iter().flat_map(|p| p.triangles.clone()).collect(),
    };
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
