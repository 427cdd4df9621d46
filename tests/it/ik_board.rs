//! The drawing board: `--center` and `--normal` put the writing on any plane, for generated chains
//! and rigs, reading left to right for someone standing at the chain's root.

use crate::common;

use glam::DVec3;
use scenebake::bake::{bake_ik, IkJob, IkReport};

/// Pen-down runs (one per stroke) of a bake.
fn runs(r: &IkReport) -> Vec<Vec<DVec3>> {
    let mut out: Vec<Vec<DVec3>> = Vec::new();
    let mut down = false;
    for (t, &d) in r.targets.iter().zip(&r.pen_down) {
        if d {
            if !down {
                out.push(Vec::new());
            }
            out.last_mut().unwrap().push(DVec3::from_array(*t));
        }
        down = d;
    }
    out
}

fn mean(s: &[DVec3]) -> DVec3 {
    s.iter().copied().sum::<DVec3>() / s.len() as f64
}

/// The reader's right and up on a board through `c` with normal `n`, seen from `eye`: forward
/// into the board; up = world +Y made perpendicular to it, or on a level desk the horizontal
/// direction away from the reader; right = forward × up.
fn reader_axes(eye: DVec3, c: DVec3, n: DVec3) -> (DVec3, DVec3) {
    let n = n.normalize();
    let forward = if (c - eye).dot(n) > 0.0 { n } else { -n };
    let up = if n.y.abs() > 0.99 {
        DVec3::new(c.x - eye.x, 0.0, c.z - eye.z).normalize()
    } else {
        (DVec3::Y - DVec3::Y.dot(n) * n).normalize()
    };
    (forward.cross(up).normalize(), up)
}

#[test]
fn a_board_anywhere_reads_left_to_right_from_the_chain_root() {
    let dir = tempfile::tempdir().unwrap();
    // A 3-joint arm (shoulder at (0, 1.7, 0), two 1.3 bones) writing on boards around it.
    let root = DVec3::new(0.0, 1.7, 0.0);
    let boards = [
        (DVec3::new(0.0, 1.4, 1.0), DVec3::new(0.0, 0.0, -1.0)),
        (DVec3::new(0.9, 1.2, 0.4), DVec3::new(-1.0, 0.2, -0.3)),
        // The same board with the normal reversed: still read from the root's side.
        (DVec3::new(0.9, 1.2, 0.4), DVec3::new(1.0, -0.2, 0.3)),
        // A desk below the shoulder.
        (DVec3::new(0.3, 0.6, 0.5), DVec3::new(0.0, 1.0, 0.0)),
    ];
    let mut layouts = Vec::new();
    for (k, (c, n)) in boards.into_iter().enumerate() {
        let job = IkJob {
            joints: Some(3),
            text: Some("T-".into()),
            font: Some("grid".into()),
            size: Some(0.3),
            center: Some(c),
            normal: Some(n),
            output: dir.path().join(format!("b{k}.glb")),
            ..Default::default()
        };
        let r = bake_ik(&job, &mut |_, _| {}).unwrap();
        assert_eq!(r.reached, r.frames, "board {k}: max error {}", r.max_error);
        let nn = n.normalize();
        for p in runs(&r).iter().flatten() {
            assert!(
                (*p - c).dot(nn).abs() < 1e-9,
                "board {k}: target off the board"
            );
        }
        // Lifted targets are on the reader's side.
        for (t, d) in r.targets.iter().zip(&r.pen_down) {
            let side = (DVec3::from_array(*t) - c).dot(nn) * (root - c).dot(nn);
            assert!(
                *d || side > -1e-12,
                "board {k}: pen lifted through the board"
            );
        }
        // Grid `T-`: the bar, the stem, the dash. The bar is above the stem; the dash to the
        // right of the stem, for the reader at the root.
        let s = runs(&r);
        assert_eq!(s.len(), 3);
        let (right, up) = reader_axes(root, c, n);
        let (bar, stem, dash) = (mean(&s[0]), mean(&s[1]), mean(&s[2]));
        assert!((bar - stem).dot(up) > 0.05, "board {k}: upside down");
        assert!((dash - stem).dot(right) > 0.1, "board {k}: mirrored");
        assert!((bar - stem).dot(right).abs() < 1e-9);
        layouts.push(r.targets.clone());

        // The file's tip is on the board at every pen-down frame (independent FK).
        let l = common::load(&job.output);
        let tracks = l.animation("ik");
        let tip = l.node_by_name("joint_2");
        let (times, _) = tracks.rotation.values().next().unwrap();
        for (f, &t) in times.iter().enumerate() {
            if r.pen_down[f] {
                let p = l.world_pos(&tracks, tip, t);
                assert!((p - c).dot(nn).abs() < 1e-4 + 1e-5, "board {k} frame {f}");
            }
        }
    }
    assert_eq!(layouts[1], layouts[2], "the normal's sign changes nothing");
}

#[test]
fn a_rig_writes_on_a_board_given_by_center_and_normal() {
    let dir = tempfile::tempdir().unwrap();
    let fox = common::crate_dir().join("meshes/Fox.glb");
    // Fox's neck to head, writing on a wall in front of its nose (the fox looks along +Z).
    let job = IkJob {
        rig: Some(fox),
        chain: Some("b_Spine02_03..b_Head_05".into()),
        text: Some("ok".into()),
        size: Some(6.0),
        center: Some(DVec3::new(0.0, 58.0, 30.0)),
        normal: Some(DVec3::new(0.0, 0.0, -1.0)),
        output: dir.path().join("fox.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    for p in runs(&r).iter().flatten() {
        assert!((p.z - 30.0).abs() < 1e-9);
    }
    assert!(
        r.reached as f64 >= 0.95 * r.frames as f64,
        "{} of {}",
        r.reached,
        r.frames
    );
    // `o` then `k`: for the fox looking along +Z, its right is -X.
    let s = runs(&r);
    assert!(mean(&s[0]).x > mean(&s[s.len() - 1]).x);
}

#[test]
fn a_zero_normal_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let e = bake_ik(
        &IkJob {
            preset: Some(scenebake::bake::ik::IkPreset::LabArm),
            curve: Some(scenebake::path::CurveKind::Circle),
            normal: Some(DVec3::ZERO),
            output: dir.path().join("z.glb"),
            ..Default::default()
        },
        &mut |_, _| {},
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("`normal`"), "{e}");
}
