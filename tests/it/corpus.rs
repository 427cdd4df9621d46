//! Every shipped surface or volume mesh loads, agrees with an independent reader, and bakes.

use crate::common;

use std::path::{Path, PathBuf};

use scenebake::bake::cloth::{bake_cloth, load_body, ClothJob, ClothSource};

fn meshes() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("obj" | "tet" | "gltf" | "glb")
            )
        })
        .collect();
    files.sort();
    assert!(files.len() >= 10, "the corpus is shipped in meshes/");
    files
}

#[test]
fn every_mesh_bakes_a_few_frames() {
    let dir = tempfile::tempdir().unwrap();
    for path in meshes() {
        let out = dir.path().join(format!(
            "{}.glb",
            path.file_stem().unwrap().to_string_lossy()
        ));
        let mut job = ClothJob::new(ClothSource::File(path.clone()), out.clone());
        job.frames = Some(4);
        let report =
            bake_cloth(&job, &mut |_, _| {}).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (doc, _, _) = common::gltf_read::import(&out).unwrap();
        let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(prim.morph_targets().count(), 4, "{}", path.display());
        assert!(
            report.springs > 0 && report.particles > 0,
            "{}",
            path.display()
        );
    }
}

/// Our OBJ reader and `tobj` see the same triangles (as coordinate triples, order-free).
#[test]
fn obj_reader_agrees_with_tobj() {
    for path in meshes()
        .into_iter()
        .filter(|p| p.extension().unwrap() == "obj")
    {
        let ours = load_body(
            &path,
            &ClothJob::new(ClothSource::File(path.clone()), "x.glb".into()),
        )
        .unwrap();
        let key = |p: [f32; 3]| p.map(f32::to_bits);
        let mut a: Vec<[[u32; 3]; 3]> = ours
            .triangles
            .iter()
            .map(|t| t.map(|i| key(ours.positions[i as usize].as_vec3().to_array())))
            .collect();
        let (models, _) = tobj::load_obj(
            &path,
            &tobj::LoadOptions {
                triangulate: true,
                ..Default::default()
            },
        )
        .unwrap();
        let mut b: Vec<[[u32; 3]; 3]> = Vec::new();
        for m in &models {
            let p = &m.mesh.positions;
            for t in m.mesh.indices.chunks(3) {
                b.push([0, 1, 2].map(|k| {
                    let i = t[k] as usize * 3;
                    key([p[i], p[i + 1], p[i + 2]])
                }));
            }
        }
        // Drop tobj's degenerate triangles, which our reader skips with a warning.
        b.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        for t in a.iter_mut().chain(b.iter_mut()) {
            // Rotate each triangle to start at its smallest corner (same winding).
            let m = (0..3).min_by_key(|&k| t[k]).unwrap();
            t.rotate_left(m);
        }
        a.sort_unstable();
        b.sort_unstable();
        assert_eq!(a.len(), b.len(), "{}: triangle count", path.display());
        assert!(a == b, "{}: triangles differ", path.display());
    }
}

#[test]
fn groups_of_one_body_share_their_corners() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/cube_groups.obj");
    let m = load_body(
        &path,
        &ClothJob::new(ClothSource::File(path.clone()), "x.glb".into()),
    )
    .unwrap();
    assert_eq!(m.positions.len(), 8, "six quads over eight shared corners");
    assert_eq!(m.triangles.len(), 12);
    // Each `g` line names a face group and the shared group `cube`.
    let names: Vec<&str> = m.groups.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        ["back", "bottom", "cube", "front", "left", "right", "top"]
    );
    assert_eq!(m.groups["cube"].len(), 8);
    assert_eq!(m.groups["front"].len(), 4);
}
