//! The per-frame strain and crossing counts a bake reports, against an independent reading of
//! the file it wrote: every pair of triangles tested (no broad phase), each with exact
//! orientation signs, on the positions a player computes from the glTF.

use crate::common;

use std::path::Path;

use glam::Vec3;

use common::cli::scenebake;
use common::crossing::{brute_between, brute_self, cloth_triangles, weld};
use common::morph::load_morph;

/// The first primitive's indices of mesh `index`, and the positions of the node named `node`.
fn mesh_of(path: &Path, node: &str) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (doc, buffers, _) = common::gltf_read::import(path).unwrap();
    let node = doc
        .nodes()
        .find(|n| n.name() == Some(node))
        .unwrap_or_else(|| panic!("no node {node}"));
    let prim = node.mesh().unwrap().primitives().next().unwrap();
    let r = prim.reader(|b| Some(&buffers[b.index()]));
    let p: Vec<Vec3> = r.read_positions().unwrap().map(Vec3::from).collect();
    let i: Vec<u32> = r.read_indices().unwrap().into_u32().collect();
    // Node transforms of the written colliders are the identity (checked, not assumed).
    assert_eq!(
        node.transform().matrix(),
        glam::Mat4::IDENTITY.to_cols_array_2d()
    );
    (p, i.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
}

#[test]
fn the_dress_on_its_mannequin_reports_the_crossings_its_file_has() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dress.glb");
    let report = dir.path().join("dress.json");
    let (code, err) = scenebake([
        "cloth",
        common::mesh_path("garments/dress_draped.obj")
            .to_str()
            .unwrap(),
        "--collider",
        &format!(
            "mesh:{}",
            common::mesh_path("garments/mannequin.obj").display()
        ),
        "--frames",
        "2",
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r = common::read_json(&report);
    let q = &r["quality"];
    let list = |k: &str| common::counts_of(&q[k]);
    let morph = load_morph(&out);
    let tris = weld(&morph.base, &cloth_triangles(&out));
    let (body, body_tris) = mesh_of(&out, "collider_1");
    let fps = r["fps"].as_f64().unwrap() as f32;
    let (own, with_body) = (list("self_crossings"), list("body_crossings"));
    assert_eq!(own.len(), 3);
    for k in [0usize, 2] {
        let p = morph.positions_at(k as f32 / fps);
        assert_eq!(
            own[k],
            brute_self(&p, &tris),
            "cloth–cloth pairs, frame {k}"
        );
        assert_eq!(
            with_body[k],
            brute_between(&p, &tris, &body, &body_tris),
            "cloth–body pairs, frame {k}"
        );
    }
    // The draped input crosses itself (a property of the published file, not of the bake).
    assert!(own[0] > 100, "{own:?}");
    // Flagged: exactly the simulated frames with a crossing, and the terminal says so.
    let expected: Vec<usize> = (1..3).filter(|&k| own[k] + with_body[k] > 0).collect();
    assert_eq!(list("intersecting_frames"), expected);
    if !expected.is_empty() {
        assert!(
            err.contains("written frames have crossing triangles"),
            "{err}"
        );
    }
}

/// The largest edge stretch of each frame, from the file: welded edges, rest lengths from
/// frame 0.
fn strain_from_file(path: &Path, fps: f32, frames: usize) -> Vec<f64> {
    let morph = load_morph(path);
    let tris = weld(&morph.base, &cloth_triangles(path));
    let mut edges: Vec<[u32; 2]> = tris
        .iter()
        .flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]])
        .map(|[a, b]| [a.min(b), a.max(b)])
        .collect();
    edges.sort_unstable();
    edges.dedup();
    let len =
        |p: &[Vec3], [a, b]: [u32; 2]| p[a as usize].as_dvec3().distance(p[b as usize].as_dvec3());
    (0..=frames)
        .map(|k| {
            let p = morph.positions_at(k as f32 / fps);
            edges
                .iter()
                .map(|&e| len(&p, e) / len(&morph.base, e) - 1.0)
                .fold(0.0, f64::max)
        })
        .collect()
}

#[test]
fn a_cloth_stretched_past_the_strain_limit_is_flagged_in_the_report_and_on_the_terminal() {
    // The labs' grid with springs two thousand times too soft: it sags past 20 % stretch.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("soft.glb");
    let report = dir.path().join("soft.json");
    let (code, err) = scenebake([
        "cloth",
        "--preset",
        "lab-cloth",
        "--resolution",
        "10",
        "--stiffness",
        "0.5",
        "--frames",
        "60",
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let r = common::read_json(&report);
    let q = &r["quality"];
    let reported: Vec<f64> = q["max_strain"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let fps = r["fps"].as_f64().unwrap() as f32;
    let file = strain_from_file(&out, fps, 60);
    for (k, (a, b)) in reported.iter().zip(&file).enumerate() {
        assert!((a - b).abs() < 1e-4, "frame {k}: report {a}, file {b}");
    }
    let limit = q["strain_limit"].as_f64().unwrap();
    assert_eq!(limit, 0.2);
    let expected: Vec<u64> = (1..=60u64)
        .filter(|&k| file[k as usize] > limit + 1e-4)
        .collect();
    assert!(!expected.is_empty(), "the soft cloth should tear: {file:?}");
    let flagged: Vec<u64> = q["overstrained_frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert!(
        expected.iter().all(|k| flagged.contains(k)),
        "{expected:?} ⊄ {flagged:?}"
    );
    assert!(err.contains("past the strain limit 20 %"), "{err}");
    assert!(err.contains("--strain-limit"), "{err}");
}
