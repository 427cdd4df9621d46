//! Property-based fuzzing of the loaders and option parsers: whatever the input, they return a
//! value that satisfies the model's invariants or an error, and never panic. Runs a bounded
//! number of cases in `cargo test`; raise PROPTEST_CASES to fuzz longer.

use std::path::Path;

use proptest::prelude::*;
use scenebake::cloth::pins::PinSpec;
use scenebake::io::obj::{parse_obj, ObjOptions};
use scenebake::io::tet::parse_tet;
use scenebake::mesh::Mesh;

fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        (-3.0f64..3.0).prop_map(|v| format!("{v}")),
        Just("0".to_string()),
        Just("-0.000000".to_string()),
        Just("nan".to_string()),
        Just("1e309".to_string()),
        Just("inf".to_string()),
        "[0-9a-z.+-]{0,6}",
    ]
}

fn index() -> impl Strategy<Value = String> {
    prop_oneof![
        (-12i64..12).prop_map(|i| i.to_string()),
        Just("".to_string()),
        "[0-9/]{1,5}",
        Just("99999999999".to_string())
    ]
}

fn obj_line() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (number(), number(), number()).prop_map(|(a, b, c)| format!("v {a} {b} {c}")),
        1 => (number(), number()).prop_map(|(a, b)| format!("vt {a} {b}")),
        1 => (number(), number(), number()).prop_map(|(a, b, c)| format!("vn {a} {b} {c}")),
        4 => prop::collection::vec((index(), index()), 0..6).prop_map(|c| {
            let corners: Vec<String> = c.into_iter().map(|(p, t)| if t.is_empty() { p } else { format!("{p}/{t}") }).collect();
            format!("f {}", corners.join(" "))
        }),
        1 => "[a-z ]{0,8}".prop_map(|n| format!("g {n}")),
        1 => "[a-z]{0,5}".prop_map(|n| format!("o {n}")),
        1 => "[ -~]{0,20}",
    ]
}

/// What every successfully loaded mesh must satisfy.
fn check_mesh(m: &Mesh) {
    let n = m.positions.len() as u32;
    assert!(m.positions.iter().all(|p| p.is_finite()));
    assert!(!m.triangles.is_empty());
    assert_eq!(m.triangles.len(), m.render_triangles.len());
    for (t, r) in m.triangles.iter().zip(&m.render_triangles) {
        assert!(t.iter().all(|&i| i < n));
        assert!(
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2],
            "degenerate triangle kept"
        );
        for (k, &rv) in r.iter().enumerate() {
            assert_eq!(m.render_vertices[rv as usize].particle, t[k]);
        }
    }
    assert!(m.tets.iter().flatten().all(|&i| i < n));
    assert_eq!(m.file_index.len(), m.positions.len());
}

/// `default` cases, or PROPTEST_CASES when set (for long fuzzing runs).
fn cases(default: u32) -> ProptestConfig {
    ProptestConfig::with_cases(
        std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default),
    )
}

proptest! {
    #![proptest_config(cases(512))]

    #[test]
    fn obj_reader_never_panics(lines in prop::collection::vec(obj_line(), 0..40)) {
        let text = lines.join("\n");
        if let Ok(m) = parse_obj(&text, Path::new("fuzz.obj"), &ObjOptions::default()) {
            check_mesh(&m);
        }
    }

    #[test]
    fn obj_reader_survives_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        if let Ok(m) = parse_obj(&text, Path::new("fuzz.obj"), &ObjOptions::default()) {
            check_mesh(&m);
        }
    }

    #[test]
    fn tet_reader_never_panics(n in 0usize..7, m in 0usize..4, body in prop::collection::vec(prop_oneof![number(), index()], 0..50), breaks in prop::collection::vec(0usize..6, 0..50)) {
        let mut text = format!("tet {n} {m}\n");
        for (w, b) in body.iter().zip(breaks.iter().chain(std::iter::repeat(&1))) {
            text.push_str(w);
            text.push(if *b == 0 { '\n' } else { ' ' });
        }
        if let Ok(mesh) = parse_tet(&text, Path::new("fuzz.tet")) {
            check_mesh(&mesh);
        }
    }

    #[test]
    fn svg_reader_never_panics(parts in prop::collection::vec(prop_oneof![
        Just("<g transform=\"translate(3,4) scale(2)\">".to_string()),
        Just("</g>".to_string()),
        Just("<defs>".to_string()),
        Just("</defs>".to_string()),
        Just("<symbol id=\"s\" viewBox=\"0 0 2 2\">".to_string()),
        Just("</symbol>".to_string()),
        Just("<use href=\"#s\" width=\"3mm\" height=\"1in\"/>".to_string()),
        Just("<rect id=\"r\" class=\"h\" width=\"2\" height=\"1\"/><use href=\"#r\" transform=\"skewX(30)\"/>".to_string()),
        (number(), number()).prop_map(|(a, b)| format!("<path d=\"M {a} {b} L 1 2 C 3 4 5 6 7 8 A 5 5 0 1 0 {b} {a} Z\"/>")),
        "[MLHVCSQTAZmlhvcsqtaz0-9 .,eE+-]{0,24}".prop_map(|d| format!("<path d=\"{d}\"/>")),
        "[a-z(),. 0-9-]{0,20}".prop_map(|t| format!("<line x1=\"0\" x2=\"1\" transform=\"{t}\"/>")),
        (number(), number()).prop_map(|(a, b)| format!("<circle cx=\"{a}\" cy=\"{b}\" r=\"2\"/>")),
        "[ -~]{0,12}",
    ], 0..12)) {
        // The property is that it answers (shapes or an error) without panicking, with and
        // without an SVG root around the fragments.
        let body = parts.concat();
        let _ = scenebake::path::svg::parse_svg(&body, Path::new("fuzz.svg"));
        let svg = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"0 0 9 9\"><style>.h{{display:none}}</style>{body}</svg>");
        let _ = scenebake::path::svg::parse_svg(&svg, Path::new("fuzz.svg"));
    }

    #[test]
    fn pin_and_vector_parsers_never_panic(s in "[ -~]{0,30}") {
        let _ = s.parse::<PinSpec>();
        let _ = scenebake::spec::parse_vec3(&s);
        let _ = scenebake::spec::parse_numbers::<6>(&s, "box");
    }

    #[test]
    fn collider_specs_never_panic(kind in prop_oneof![Just("plane:"), Just("sphere:"), Just("box:"), Just("mesh:"), Just("")], rest in "[ -~]{0,30}") {
        let _ = format!("{kind}{rest}").parse::<scenebake::cloth::collide::ColliderSpec>();
    }

    /// Random triangle soups (degenerate, duplicated, out-of-range indices): the mesh collider
    /// builds or refuses with an error, and every query answers with a finite distance and a
    /// unit normal.
    #[test]
    fn mesh_collider_answers_every_query(
        points in prop::collection::vec((-2i8..3, -2i8..3, -2i8..3), 0..12),
        tris in prop::collection::vec((0u32..14, 0u32..14, 0u32..14), 0..16),
        queries in prop::collection::vec((-30i16..30, -30i16..30, -30i16..30, -30i16..30, -30i16..30, -30i16..30), 1..8),
        reach in 0.0f64..3.0,
    ) {
        use scenebake::cloth::collide::MeshCollider;
        use scenebake::glam::DVec3;
        let positions: Vec<DVec3> = points.iter().map(|&(x, y, z)| DVec3::new(x as f64, y as f64, z as f64) * 0.5).collect();
        // Mostly valid indices (so most soups build), and now and then one past the end.
        let n = positions.len() as u32 + u32::from(tris.len() % 5 == 0);
        let triangles: Vec<[u32; 3]> = tris.iter().map(|&(a, b, c)| [a % n.max(1), b % n.max(1), c % n.max(1)]).collect();
        let Ok(mesh) = MeshCollider::new(positions, triangles) else { return Ok(()) };
        prop_assert!(!mesh.triangles().is_empty());
        for &(px, py, pz, fx, fy, fz) in &queries {
            let p = DVec3::new(px as f64, py as f64, pz as f64) * 0.1;
            let from = DVec3::new(fx as f64, fy as f64, fz as f64) * 0.1;
            if let Some(s) = mesh.contact(p, from, reach) {
                prop_assert!(s.distance.is_finite(), "{s:?}");
                prop_assert!((s.normal.length() - 1.0).abs() < 1e-9, "{s:?}");
            }
        }
    }

    #[test]
    fn valid_pin_specs_round_trip(kind in 0usize..3, nums in prop::collection::vec(-5.0f64..5.0, 6), idx in prop::collection::vec(0u32..1000, 1..5), name in "[a-z_]{1,8}") {
        let spec = match kind {
            0 => format!("index:{}", idx.iter().map(u32::to_string).collect::<Vec<_>>().join(",")),
            1 => format!("box:{}", nums.iter().map(f64::to_string).collect::<Vec<_>>().join(",")),
            _ => format!("group:{name}"),
        };
        let parsed: PinSpec = spec.parse().unwrap();
        let again: PinSpec = parsed.to_string().parse().unwrap();
        prop_assert_eq!(parsed, again);
    }
}

/// Random corruptions of a real GLB: the glTF mesh loader errors or loads, never panics.
#[test]
fn gltf_loader_survives_corrupted_files() {
    let original =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/Fox.glb")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fuzz.glb");
    let mut runner = proptest::test_runner::TestRunner::new(cases(160));
    let strategy = (
        prop::collection::vec((0usize..original.len(), any::<u8>()), 1..8),
        prop::option::of(0usize..original.len()),
    );
    runner
        .run(&strategy, |(edits, truncate)| {
            let mut bytes = original.clone();
            for (at, value) in edits {
                // Bias edits towards the header and JSON chunk, where structure lives.
                let at = if value % 2 == 0 {
                    at % 4096.min(bytes.len())
                } else {
                    at
                };
                bytes[at] = value;
            }
            if let Some(t) = truncate.filter(|t| t % 3 == 0) {
                bytes.truncate(t);
            }
            std::fs::write(&path, &bytes).unwrap();
            if let Ok(m) = scenebake::io::gltf_mesh::load_gltf_mesh(&path, None) {
                check_mesh(&m);
            }
            Ok(())
        })
        .unwrap();
}
