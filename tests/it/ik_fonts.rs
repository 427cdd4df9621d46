//! Text through whole bakes in real fonts: the Hershey fonts shipped with scenebake and a
//! TrueType font installed on the machine (Debian's fonts-dejavu-core, which CI installs).
//!
//! Expectations come from typography, not from our code: lower case is shorter than capitals,
//! `A` is drawn with three strokes, an accented letter is its base letter plus one more contour
//! above it.

use crate::common;

use std::path::{Path, PathBuf};

use glam::DVec3;
use scenebake::bake::{bake_ik, IkJob, IkReport};
use scenebake::Error;

const DEJAVU: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

fn dejavu() -> PathBuf {
    let p = PathBuf::from(DEJAVU);
    assert!(
        p.is_file(),
        "{DEJAVU} is missing: install Debian's fonts-dejavu-core (.ci/run does)"
    );
    p
}

fn write(dir: &Path, name: &str, text: &str, font: &str) -> IkReport {
    let job = IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        text: Some(text.into()),
        font: Some(font.into()),
        size: Some(0.3),
        spacing: Some(0.005),
        output: dir.join(format!("{name}.glb")),
        ..Default::default()
    };
    bake_ik(&job, &mut |_, _| {}).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The pen-down runs of a bake (one per stroke), as world points.
fn strokes(r: &IkReport) -> Vec<Vec<DVec3>> {
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

/// Height of the ink in the lab's drawing plane (y = 0; drawing "up" is world -z).
fn ink_height(r: &IkReport) -> f64 {
    let zs = strokes(r).into_iter().flatten().map(|p| p.z);
    let (lo, hi) = zs.fold((f64::MAX, f64::MIN), |(a, b), z| (a.min(z), b.max(z)));
    hi - lo
}

#[test]
fn lower_case_draws_different_shorter_letters_than_capitals() {
    let dir = tempfile::tempdir().unwrap();
    for font in ["simplex", "script", "cursive", "duplex"] {
        let lower = write(dir.path(), "lo", "aceo", font);
        let upper = write(dir.path(), "up", "ACEO", font);
        let ratio = ink_height(&lower) / ink_height(&upper);
        // x-height over cap height: about 0.5-0.75 in any Latin font; 1 when lower case is
        // drawn with the capitals (as the grid font does).
        assert!(
            (0.4..0.85).contains(&ratio),
            "{font}: x-height / cap height = {ratio}"
        );
        assert_ne!(lower.targets.len(), upper.targets.len(), "{font}");
        assert_eq!(lower.reached, lower.frames, "{font}");
        // Pen-down targets lie on the lab's y = 0 board.
        for p in strokes(&lower).into_iter().flatten() {
            assert!(p.y.abs() < 1e-12);
        }
    }
    // The old grid font really has no lower case: the same height both ways.
    let lower = write(dir.path(), "glo", "aceo", "grid");
    let upper = write(dir.path(), "gup", "ACEO", "grid");
    assert!((ink_height(&lower) / ink_height(&upper) - 1.0).abs() < 1e-9);
}

#[test]
fn hershey_a_has_three_strokes_and_size_sets_the_cap_height() {
    let dir = tempfile::tempdir().unwrap();
    let r = write(dir.path(), "a", "A", "simplex");
    assert_eq!(strokes(&r).len(), 3, "two legs and a bar");
    // --size is the height of the capitals.
    let h = write(dir.path(), "h", "H", "simplex");
    assert!((ink_height(&h) - 0.3).abs() < 1e-9, "{}", ink_height(&h));
}

#[test]
fn a_truetype_font_draws_a_non_ascii_letter() {
    let dir = tempfile::tempdir().unwrap();
    let font = dejavu();
    let font = font.to_str().unwrap();
    let e = write(dir.path(), "e", "e", font);
    let e_acute = write(dir.path(), "eacute", "é", font);
    let (se, sa) = (strokes(&e), strokes(&e_acute));
    // `e` is an outer contour and a counter; `é` adds the acute accent.
    assert_eq!(se.len(), 2);
    assert_eq!(sa.len(), 3);
    // Outline contours are closed: each ends where it started.
    for s in &sa {
        assert!(s[0].distance(s[s.len() - 1]) < 1e-9);
    }
    // The extra contour is above the letter (drawing "up" is world -z on the lab board).
    let top_of = |s: &Vec<DVec3>| s.iter().map(|p| -p.z).fold(f64::MIN, f64::max);
    let bottom_of = |s: &Vec<DVec3>| s.iter().map(|p| -p.z).fold(f64::MAX, f64::min);
    let mut by_bottom: Vec<&Vec<DVec3>> = sa.iter().collect();
    by_bottom.sort_by(|a, b| bottom_of(a).total_cmp(&bottom_of(b)));
    let accent = by_bottom[2];
    assert!(bottom_of(accent) > top_of(by_bottom[0]).max(top_of(by_bottom[1])));
    assert_eq!(e_acute.reached, e_acute.frames);
    // Greek and accents in one line.
    let r = write(dir.path(), "greek", "Ωμέγα", font);
    assert!(strokes(&r).len() >= 6);
}

#[test]
fn a_glyph_the_font_lacks_is_an_error_naming_it_and_the_font() {
    let dir = tempfile::tempdir().unwrap();
    let job = |text: &str, font: &str| IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        text: Some(text.into()),
        font: Some(font.into()),
        output: dir.path().join("x.glb"),
        ..Default::default()
    };
    let e = bake_ik(&job("café", "script"), &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(&e, Error::UnknownGlyph { font, glyph: 'é' } if font == "script"),
        "{e}"
    );
    let dv = dejavu();
    let e = bake_ik(&job("漢字", dv.to_str().unwrap()), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains('漢') && e.contains("DejaVuSans.ttf"), "{e}");
    let e = bake_ik(&job("hi", "comic"), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("`font`") && e.contains("comic"), "{e}");
    let e = bake_ik(&job("hi", "/nonexistent/font.ttf"), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/font.ttf"), "{e}");
    let not_a_font = dir.path().join("fake.ttf");
    std::fs::write(&not_a_font, b"not a font at all").unwrap();
    let e = bake_ik(&job("hi", not_a_font.to_str().unwrap()), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("fake.ttf") && e.contains("not a TrueType"),
        "{e}"
    );
    assert!(!dir.path().join("x.glb").exists(), "no output on error");
}

#[test]
fn a_cursive_word_is_written_by_the_file_tip() {
    // The baked file, read back with an independent FK, puts the tip on every pen-down target.
    let dir = tempfile::tempdir().unwrap();
    let job = IkJob {
        preset: Some(scenebake::bake::ik::IkPreset::LabArm),
        text: Some("writing".into()),
        font: Some("cursive".into()),
        output: dir.path().join("w.glb"),
        ..Default::default()
    };
    let r = bake_ik(&job, &mut |_, _| {}).unwrap();
    assert_eq!(r.reached, r.frames);
    let l = common::load(&job.output);
    let tracks = l.animation("ik");
    let tip = l.node_by_name("joint_4");
    let (times, _) = tracks.rotation.values().next().unwrap();
    for (k, &t) in times.iter().enumerate() {
        if r.pen_down[k] {
            let p = l.world_pos(&tracks, tip, t);
            assert!(p.distance(DVec3::from_array(r.targets[k])) < 1e-4 + 1e-5);
        }
    }
}
