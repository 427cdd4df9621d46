//! Static meshes (the colliders) written beside the cloth: their own nodes after the cloth's,
//! checked with an independent reader (the `gltf` crate), and the cloth's cache unchanged.

use crate::common;

use common::morph::load_morph;
use scenebake::bake::cloth::{ClothJob, ClothSource};
use scenebake::export::{write_morph_gltf, MorphOptions, StaticMesh};
use scenebake::glam::{DVec3, Vec3};

/// One static node as reloaded (after checking it has no morph targets, no weights, POSITION
/// min/max and a grey non-metallic material).
struct Loaded {
    name: String,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

fn load_statics(path: &std::path::Path) -> Vec<Loaded> {
    let (doc, buffers, _) = common::gltf_read::import(path).expect("reload with the gltf crate");
    let scene = doc.default_scene().expect("a default scene");
    let nodes: Vec<gltf::Node> = scene.nodes().collect();
    // The cloth stays mesh 0 and the scene's first node, with its animation.
    assert_eq!(nodes[0].mesh().unwrap().index(), 0);
    assert!(
        nodes[0]
            .mesh()
            .unwrap()
            .primitives()
            .next()
            .unwrap()
            .morph_targets()
            .len()
            > 0
    );
    assert_eq!(doc.animations().count(), 1);
    for ch in doc.animations().next().unwrap().channels() {
        assert_eq!(ch.target().node().index(), nodes[0].index());
    }
    nodes[1..]
        .iter()
        .map(|node| {
            let mesh = node.mesh().expect("a static node has a mesh");
            assert_eq!(mesh.name(), node.name());
            assert!(mesh.weights().is_none());
            let prim = mesh.primitives().next().unwrap();
            assert_eq!(prim.morph_targets().len(), 0);
            let pbr = prim.material().pbr_metallic_roughness();
            assert_eq!(pbr.metallic_factor(), 0.0);
            let [r, g, b, _] = pbr.base_color_factor();
            assert!(r == g && g == b, "neutral grey");
            let pos = prim.get(&gltf::Semantic::Positions).unwrap();
            assert!(
                pos.min().is_some() && pos.max().is_some(),
                "POSITION min/max"
            );
            let reader = prim.reader(|b| Some(&buffers[b.index()]));
            let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            Loaded {
                name: node.name().unwrap().to_owned(),
                positions: reader.read_positions().unwrap().map(Vec3::from).collect(),
                normals: reader.read_normals().unwrap().map(Vec3::from).collect(),
                triangles: indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
            }
        })
        .collect()
}

impl Loaded {
    /// Each triangle's geometric normal (unit), and its centroid.
    fn faces(&self) -> impl Iterator<Item = (Vec3, Vec3)> + '_ {
        self.triangles.iter().map(|t| {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            ((b - a).cross(c - a).normalize(), (a + b + c) / 3.0)
        })
    }
}

#[test]
fn plane_sphere_and_cuboid_are_written_beside_the_cloth() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = ClothJob::new(
        ClothSource::LabCloth { resolution: 8 },
        dir.path().join("x.glb"),
    );
    job.frames = Some(3);
    let (mesh, cache) = common::morph::reference(&job);

    let plain = dir.path().join("plain.glb");
    let options = MorphOptions::new("cloth", 24.0);
    write_morph_gltf(&plain, &mesh, &cache, &options).unwrap();

    let n = DVec3::new(0.0, 2.0, 0.0);
    let (ball_c, ball_r) = (DVec3::new(0.1, -0.4, 0.2), 0.25);
    let (lo, hi) = (DVec3::new(-0.6, -1.0, -0.4), DVec3::new(0.6, -0.96, 0.4));
    let with = MorphOptions {
        static_meshes: vec![
            StaticMesh::plane(n, -3.0, DVec3::new(0.5, 7.0, -0.5), 4.0, "ground"),
            StaticMesh::sphere(ball_c, ball_r, "ball"),
            StaticMesh::cuboid(lo, hi, "table"),
        ],
        ..options
    };
    for ext in ["glb", "gltf"] {
        let out = dir.path().join(format!("with.{ext}"));
        write_morph_gltf(&out, &mesh, &cache, &with).unwrap();

        // The cloth's cache reads back exactly as without statics.
        let (a, b) = (load_morph(&plain), load_morph(&out));
        assert_eq!(a.base, b.base);
        assert_eq!(a.base_normals, b.base_normals);
        assert_eq!(a.deltas, b.deltas);
        assert_eq!(a.normal_deltas, b.normal_deltas);
        assert_eq!((a.times, a.weights), (b.times, b.weights));

        // `scenebake inspect` accepts meshes without morph targets.
        let inspection = scenebake::inspect::inspect(&out).unwrap();
        let failed: Vec<_> = inspection.failures().map(|c| c.what.clone()).collect();
        assert!(failed.is_empty(), "{failed:?}");
        assert_eq!(inspection.meshes.len(), 4);

        let statics = load_statics(&out);
        let names: Vec<&str> = statics.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["ground", "ball", "table"]);

        // Ground: y = -1.5 (n·x = d with n = 2y, d = -3), centred under (0.5, _, -0.5), facing +y.
        let ground = &statics[0];
        assert_eq!(ground.triangles.len(), 2);
        for p in &ground.positions {
            approx::assert_abs_diff_eq!(p.y, -1.5, epsilon = 1e-6);
            approx::assert_abs_diff_eq!(
                (*p - Vec3::new(0.5, -1.5, -0.5)).length(),
                2.0 * 2f32.sqrt(),
                epsilon = 1e-5
            );
        }
        for (normal, _) in ground.faces() {
            approx::assert_abs_diff_eq!(normal.y, 1.0, epsilon = 1e-6);
        }
        assert!(ground.normals.iter().all(|n| *n == Vec3::Y));

        // Ball: every vertex at the radius, every face and vertex normal outward.
        let ball = &statics[1];
        let c = ball_c.as_vec3();
        for (p, vn) in ball.positions.iter().zip(&ball.normals) {
            approx::assert_abs_diff_eq!(p.distance(c), ball_r as f32, epsilon = 1e-6);
            approx::assert_abs_diff_eq!(vn.dot((*p - c).normalize()), 1.0, epsilon = 1e-5);
        }
        for (normal, centroid) in ball.faces() {
            assert!(normal.dot(centroid - c) > 0.0);
        }

        // Table: 12 triangles, vertices on the box's faces, normals outward.
        let table = &statics[2];
        assert_eq!(table.triangles.len(), 12);
        let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
        for p in &table.positions {
            assert!(
                p.cmpge(lo).all() && p.cmple(hi).all(),
                "{p} inside the bounds"
            );
            assert!(
                (0..3).all(|k| p[k] == lo[k] || p[k] == hi[k]),
                "{p} is a corner"
            );
        }
        let centre = (lo + hi) * 0.5;
        for (normal, centroid) in table.faces() {
            let axis = normal.abs().max_position();
            approx::assert_abs_diff_eq!(normal[axis].abs(), 1.0, epsilon = 1e-6);
            // On the face the normal names, and pointing away from the centre.
            let face = if normal[axis] > 0.0 {
                hi[axis]
            } else {
                lo[axis]
            };
            approx::assert_abs_diff_eq!(centroid[axis], face, epsilon = 1e-6);
            assert!(normal.dot(centroid - centre) > 0.0);
        }
    }
}

#[test]
fn unusable_static_meshes_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = ClothJob::new(
        ClothSource::LabCloth { resolution: 4 },
        dir.path().join("x.glb"),
    );
    job.frames = Some(1);
    let (mesh, cache) = common::morph::reference(&job);
    let out = dir.path().join("bad.glb");
    let mut options = MorphOptions::new("cloth", 24.0);
    options.static_meshes = vec![StaticMesh::from_triangles(
        &[DVec3::ZERO, DVec3::X, DVec3::X * 2.0],
        &[[0, 1, 2]],
        "flat",
    )];
    let e = write_morph_gltf(&out, &mesh, &cache, &options).unwrap_err();
    assert!(
        e.to_string().contains("static mesh `flat` has no triangle"),
        "{e}"
    );
    let mut nan = StaticMesh::cuboid(DVec3::ZERO, DVec3::ONE, "nan");
    nan.positions[3].x = f32::NAN;
    options.static_meshes = vec![nan];
    let e = write_morph_gltf(&out, &mesh, &cache, &options).unwrap_err();
    assert!(
        e.to_string()
            .contains("static mesh `nan` position 3 is not finite"),
        "{e}"
    );
    assert!(!out.exists());
}
