//! Pen timing: `--pen-speed` with easing at stroke ends, and lifts at `--lift` height.

use glam::DVec3;
use scenebake::bake::{bake_ik, IkJob};

fn lab(dir: &std::path::Path, name: &str) -> IkJob {
    IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        output: dir.join(format!("{name}.glb")),
        ..Default::default()
    }
}

#[test]
fn a_straight_stroke_follows_a_trapezoidal_speed_profile() {
    // One 1 m stroke at 0.5 m/s, 0.2 s to speed up and to stop, 30 fps: it takes
    // 1/0.5 + 0.2 = 2.2 s = 66 frames (67 targets); the first frame covers a·t²/2 with
    // a = 0.5/0.2 m/s², t = 1/30 s; the middle ones 0.5/30 m each.
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("line.csv");
    std::fs::write(&csv, "-0.5,0\n0.5,0\n").unwrap();
    let r = bake_ik(
        &IkJob {
            points: Some(csv),
            pen_speed: Some(0.5),
            ease: Some(0.2),
            ..lab(dir.path(), "line")
        },
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(r.frames, 67);
    let steps: Vec<f64> = r
        .targets
        .windows(2)
        .map(|w| DVec3::from_array(w[0]).distance(DVec3::from_array(w[1])))
        .collect();
    let (a, t) = (0.5 / 0.2, 1.0 / 30.0);
    assert!((steps[0] - 0.5 * a * t * t).abs() < 1e-12, "{}", steps[0]);
    assert!((steps[65] - 0.5 * a * t * t).abs() < 1e-12);
    assert!((steps[33] - 0.5 / 30.0).abs() < 1e-12);
    assert!(steps.iter().all(|&s| s <= 0.5 / 30.0 + 1e-12));
    // Speeding up, then steady, then slowing down.
    assert!(steps[..6].windows(2).all(|w| w[1] > w[0]));
    assert!(steps[60..].windows(2).all(|w| w[1] < w[0]));
    assert_eq!(r.reached, r.frames);
}

#[test]
fn every_stroke_and_lift_starts_and_ends_at_rest_at_the_lift_height() {
    let dir = tempfile::tempdir().unwrap();
    let speed = 0.6;
    let r = bake_ik(
        &IkJob {
            text: Some("hi".into()),
            size: Some(0.4),
            lift: Some(0.1),
            pen_speed: Some(speed),
            ..lab(dir.path(), "hi")
        },
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(r.reached, r.frames);
    let cruise = speed / 30.0;
    let p: Vec<DVec3> = r.targets.iter().map(|t| DVec3::from_array(*t)).collect();
    // Lab board: y = 0, the reader (and the lift) above it.
    let mut top: f64 = 0.0;
    for (k, q) in p.iter().enumerate() {
        if r.pen_down[k] {
            assert!(q.y.abs() < 1e-12);
        } else {
            assert!(q.y > 0.0 && q.y <= 0.1 + 1e-12, "frame {k}: {}", q.y);
            top = top.max(q.y);
        }
    }
    assert!((top - 0.1).abs() < 0.02, "the pen lifts to {top}, not 0.1");
    // At each pen-down/pen-up switch the pen is nearly still.
    let mut switches = 0;
    for k in 1..p.len() - 1 {
        if r.pen_down[k] != r.pen_down[k + 1] || r.pen_down[k] != r.pen_down[k - 1] {
            switches += 1;
            let slow = p[k].distance(p[k - 1]).min(p[k].distance(p[k + 1]));
            assert!(slow < 0.25 * cruise, "frame {k}: {slow} vs cruise {cruise}");
        }
    }
    assert!(switches >= 4);
    let fastest = p
        .windows(2)
        .map(|w| w[0].distance(w[1]))
        .fold(0.0, f64::max);
    assert!(fastest <= cruise + 1e-12 && fastest > 0.9 * cruise);
}

#[test]
fn pen_speed_options_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let base = IkJob {
        text: Some("hi".into()),
        ..lab(dir.path(), "x")
    };
    let err = |job: IkJob| bake_ik(&job, &mut |_, _| {}).unwrap_err().to_string();
    let e = err(IkJob {
        pen_speed: Some(0.5),
        spacing: Some(0.01),
        ..base.clone()
    });
    assert!(e.contains("`pen_speed`") && e.contains("`spacing`"), "{e}");
    let e = err(IkJob {
        ease: Some(0.1),
        ..base.clone()
    });
    assert!(e.contains("`ease`"), "{e}");
    let e = err(IkJob {
        pen_speed: Some(-1.0),
        ..base.clone()
    });
    assert!(e.contains("`pen_speed`"), "{e}");
}
