//! SVG drawings (`--svg`): what a browser would draw, flattened within the stated tolerance,
//! checked against closed-form positions; errors name the file, the line and the element.

use std::path::Path;

use glam::{DVec2, DVec3};
use scenebake::bake::ik::IkPreset;
use scenebake::bake::{bake_ik, IkJob};
use scenebake::error::Error;
use scenebake::io::drawing::read_svg;
use scenebake::path::svg::{parse_svg, Polyline, TOLERANCE};

const NS: &str = r#"xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink""#;

fn parse(svg: &str) -> Vec<Polyline> {
    parse_svg(svg, Path::new("test.svg")).unwrap()
}

/// Asserts that `shape` is a closed polygon with exactly the corners `expected` (any order).
#[track_caller]
fn assert_corners(shape: &Polyline, expected: &[DVec2], eps: f64) {
    assert!(shape.1, "closed");
    assert_eq!(shape.0.len(), expected.len(), "{:?}", shape.0);
    for e in expected {
        assert!(
            shape.0.iter().any(|p| p.distance(*e) < eps),
            "no corner at {e} in {:?}",
            shape.0
        );
    }
}

#[test]
fn use_of_a_rect_with_transforms_and_mm_units_lands_on_closed_form_corners() {
    // Canvas 50 mm wide showing user units 0..50: one user unit is one mm, k px on the canvas.
    // Inside, `10mm` is 10·k user units (absolute units convert at 96 px per inch).
    let k = 96.0 / 25.4;
    let svg = format!(
        r##"<svg {NS} width="50mm" height="50mm" viewBox="0 0 50 50">
  <defs><rect id="r" width="10mm" height="4mm"/></defs>
  <use href="#r" x="2" y="3" transform="translate(5 6) rotate(90)"/>
  <g transform="scale(0.5)"><use xlink:href="#r" x="1in"/></g>
</svg>"##
    );
    let shapes = parse(&svg);
    assert_eq!(shapes.len(), 2, "the <defs> rect itself is not drawn");
    let (w, h) = (10.0 * k, 4.0 * k);
    // translate(5,6)·rotate(90°)·translate(x=2,y=3): (u, v) ↦ (5 − (v + 3), 6 + (u + 2)).
    let first = |u: f64, v: f64| DVec2::new(2.0 - v, 8.0 + u) * k;
    assert_corners(
        &shapes[0],
        &[first(0.0, 0.0), first(w, 0.0), first(w, h), first(0.0, h)],
        1e-3,
    );
    // scale(½)·translate(1 in = 96 user units, 0).
    let second = |u: f64, v: f64| DVec2::new(0.5 * (u + 96.0), 0.5 * v) * k;
    assert_corners(
        &shapes[1],
        &[
            second(0.0, 0.0),
            second(w, 0.0),
            second(w, h),
            second(0.0, h),
        ],
        1e-3,
    );
}

#[test]
fn css_display_none_hides_and_css_stroke_shows() {
    let svg = format!(
        r##"<svg {NS} viewBox="0 0 10 10">
  <style>
    .hidden {{ display: none }}
    #shown {{ stroke: red }}
  </style>
  <path class="hidden" d="M0 0 L9 9"/>
  <g style="display:none"><path d="M0 9 L9 0"/></g>
  <path visibility="hidden" d="M0 5 L9 5"/>
  <symbol id="s"><path d="M5 0 L5 9"/></symbol>
  <path d="M0 1 L9 1" fill="none"/>
  <path id="shown" d="M1 1 L2 1" fill="none"/>
</svg>"##
    );
    let shapes = parse(&svg);
    // Hidden by a class, by an ancestor's style, by visibility, never used, neither filled nor
    // stroked: only the path the style sheet strokes is left.
    assert_eq!(
        shapes,
        vec![(vec![DVec2::new(1.0, 1.0), DVec2::new(2.0, 1.0)], false)]
    );
}

#[test]
fn circles_and_arcs_lie_on_the_circle_within_the_tolerance() {
    let (c, r) = (DVec2::new(100.0, 100.0), 80.0);
    let svg = format!(
        r#"<svg {NS} viewBox="0 0 200 200">
  <circle cx="100" cy="100" r="80"/>
  <path d="M 20 100 A 80 80 0 0 1 180 100" fill="none" stroke="black"/>
  <path d="M 20 100 a 80 80 0 1 0 160 0" fill="none" stroke="black"/>
</svg>"#
    );
    let shapes = parse(&svg);
    assert_eq!(shapes.len(), 3);
    // The drawing is 160 wide; the documented bound: flattening within TOLERANCE × 160 of the
    // cubics, which are within 2.8·10⁻⁴·r of the circle.
    let bound = TOLERANCE * 160.0 + 2.8e-4 * r;
    let mut spans = Vec::new();
    for (points, closed) in &shapes {
        let mut line = points.clone();
        if *closed {
            line.push(points[0]);
        }
        for p in &line {
            assert!(
                (p.distance(c) - r).abs() <= bound,
                "{p} off by {}",
                p.distance(c) - r
            );
        }
        // The chords: their midpoints too (a coarse polygon fails here).
        for w in line.windows(2) {
            let mid = (w[0] + w[1]) / 2.0;
            assert!((mid.distance(c) - r).abs() <= bound, "chord {w:?}");
        }
        let span: f64 = line.windows(2).map(|w| (w[0] - c).angle_to(w[1] - c)).sum();
        spans.push(span);
    }
    // A full turn for the circle; the upper half (y down: through y = 20) for the first arc,
    // the lower half for the second; `sweep` sets the direction.
    let pi = std::f64::consts::PI;
    assert!((spans[0].abs() - 2.0 * pi).abs() < 1e-9, "{spans:?}");
    assert!((spans[1] - pi).abs() < 1e-9, "{spans:?}");
    assert!((spans[2] + pi).abs() < 1e-9, "{spans:?}");
    assert!(shapes[1].0.iter().all(|p| p.y <= 100.0 + 1e-9));
    assert!(shapes[2].0.iter().all(|p| p.y >= 100.0 - 1e-9));
}

#[test]
fn malformed_xml_names_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("broken.svg");
    std::fs::write(
        &file,
        format!("<svg {NS}>\n  <g>\n    <path d=\"M0 0 L1 1\">\n  </g>\n</svg>\n"),
    )
    .unwrap();
    let e = read_svg(&file).unwrap_err();
    // The `<path>` opened on line 3 is closed by the `</g>` on line 4.
    match &e {
        Error::Parse { path, line, .. } => {
            assert_eq!(path, &file);
            assert_eq!(*line, Some(4), "{e}");
        }
        other => panic!("{other:?}"),
    }
    assert!(
        e.to_string()
            .starts_with(&format!("{}:4: ", file.display())),
        "{e}"
    );
}

#[test]
fn bad_path_data_names_the_element() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.svg");
    std::fs::write(
        &file,
        format!("<svg {NS}>\n<path id=\"ok\" d=\"M0 0 L1 1\"/>\n<path id=\"wing\" d=\"M0 0 L1 1 C 2\"/>\n</svg>"),
    )
    .unwrap();
    let e = read_svg(&file).unwrap_err();
    assert!(
        matches!(&e, Error::Parse { line: Some(3), message, .. } if message.to_string().contains("<path id=\"wing\">")),
        "{e}"
    );
    let missing = dir.path().join("missing.svg");
    assert!(matches!(read_svg(&missing), Err(Error::Io { path, .. }) if path == missing));
}

#[test]
fn svg_y_down_is_the_drawing_planes_down() {
    // An "L": down the page, then right. On the lab plane, x → world x and y (up) → world −z.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("l.svg");
    std::fs::write(
        &file,
        format!(r#"<svg {NS} viewBox="0 0 10 10"><path d="M0 0 L0 10 L5 10" fill="none" stroke="black"/></svg>"#),
    )
    .unwrap();
    let r = bake_ik(
        &IkJob {
            preset: Some(IkPreset::LabArm),
            svg: Some(file),
            output: dir.path().join("l.glb"),
            ..Default::default()
        },
        &mut |_, _| {},
    )
    .unwrap();
    let first = DVec3::from_array(r.targets[0]);
    let last = DVec3::from_array(*r.targets.last().unwrap());
    // Centred: the top-left start is at (−2.5, +5)·s on the plane, the end at (+2.5, −5)·s.
    assert!(first.x < 0.0 && first.z < 0.0, "{first}");
    assert!(last.x > 0.0 && last.z > 0.0, "{last}");
    assert!((first.x / first.z - 0.5).abs() < 1e-9, "{first}");
    assert!((last.x / last.z - 0.5).abs() < 1e-9, "{last}");
}
