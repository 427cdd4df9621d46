//! Cloth bakes reloaded with an independent reader (the `gltf` crate): what the file says must be
//! what the simulator computed.

use crate::common;

use std::path::Path;

use common::morph::reference_with_pins as reference;
use common::{mesh_path, names_in};
use scenebake::bake::cloth::{bake_cloth, ClothJob, ClothSource};
use scenebake::cloth::collide::{ColliderSpec, ContactModel};
use scenebake::glam::{DVec3, Vec3};

struct Loaded {
    base: Vec<[f32; 3]>,
    deltas: Vec<Vec<[f32; 3]>>,
    uvs: Option<Vec<[f32; 2]>>,
    times: Vec<f32>,
    weights: Vec<f32>,
    target_names: Vec<String>,
}

fn load(path: &Path) -> Loaded {
    let (doc, buffers, _) = common::gltf_read::import(path).expect("reload with the gltf crate");
    assert_eq!(doc.meshes().count(), 1);
    let mesh = doc.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let reader = prim.reader(|b| Some(&buffers[b.index()]));
    let base: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let deltas: Vec<Vec<[f32; 3]>> = reader
        .read_morph_targets()
        .map(|(p, _, _)| p.expect("POSITION delta").collect())
        .collect();
    for t in prim.morph_targets() {
        let acc = t.positions().unwrap();
        assert!(
            acc.min().is_some() && acc.max().is_some(),
            "morph POSITION accessors carry min/max"
        );
    }
    assert!(prim
        .get(&gltf::Semantic::Positions)
        .unwrap()
        .min()
        .is_some());
    let uvs = reader.read_tex_coords(0).map(|t| t.into_f32().collect());
    let anim = doc.animations().next().expect("an animation");
    let channel = anim.channels().next().unwrap();
    assert_eq!(
        channel.target().property(),
        gltf::animation::Property::MorphTargetWeights
    );
    assert_eq!(
        channel.target().node().mesh().unwrap().index(),
        mesh.index(),
        "the animated node holds the mesh"
    );
    assert!(channel.target().node().skin().is_none());
    let r = channel.reader(|b| Some(&buffers[b.index()]));
    let times: Vec<f32> = r.read_inputs().unwrap().collect();
    let weights: Vec<f32> = match r.read_outputs().unwrap() {
        gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
        _ => panic!("weights output"),
    };
    let extras: serde_json::Value =
        serde_json::from_str(mesh.extras().as_ref().unwrap().get()).unwrap();
    let target_names = extras["targetNames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_owned())
        .collect();
    Loaded {
        base,
        deltas,
        uvs,
        times,
        weights,
        target_names,
    }
}

#[test]
fn plane_export_reproduces_the_simulation_frame_by_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plane.glb");
    let mut job = ClothJob::new(ClothSource::File(mesh_path("plane_30x30.obj")), out.clone());
    job.frames = Some(24);
    job.pin = vec!["box:-1,-1,-1,1,1,-0.49".parse().unwrap()];
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(report.frames, 24);
    assert_eq!(report.pinned, 31, "one edge of the 31×31 grid");
    assert_eq!(report.output_bytes, std::fs::metadata(&out).unwrap().len());

    let (mesh, cache, pinned) = reference(&job);
    let f = load(&out);
    let n = 24;
    assert_eq!(f.deltas.len(), n, "one morph target per baked frame");
    assert_eq!(f.target_names.len(), n);
    assert_eq!(f.target_names[0], "frame_0001");
    assert_eq!(f.times.len(), n + 1, "a key at every frame 0..N");
    for (k, t) in f.times.iter().enumerate() {
        assert!((t - k as f32 / 30.0).abs() < 1e-6, "key {k} at {t}");
    }
    // One-hot weights, all zero at frame 0.
    assert_eq!(f.weights.len(), (n + 1) * n);
    for k in 0..=n {
        let row = &f.weights[k * n..(k + 1) * n];
        for (j, w) in row.iter().enumerate() {
            let expected = if k >= 1 && j == k - 1 { 1.0 } else { 0.0 };
            assert_eq!(*w, expected, "weight of target {j} at frame {k}");
        }
    }
    assert_eq!(f.base.len(), mesh.render_vertices.len());
    for frame in [0, 1, 7, 24] {
        let particles = cache.frame(frame);
        for (v, rv) in mesh.render_vertices.iter().enumerate() {
            let mut p = Vec3::from(f.base[v]);
            if frame > 0 {
                p += Vec3::from(f.deltas[frame - 1][v]);
            }
            let want = particles[rv.particle as usize];
            assert!(
                (p - want).length() < 1e-5,
                "frame {frame} vertex {v}: {p} vs {want}"
            );
            if pinned[rv.particle as usize] && frame > 0 {
                assert_eq!(
                    f.deltas[frame - 1][v],
                    [0.0; 3],
                    "pinned vertex {v} moved at frame {frame}"
                );
            }
        }
    }
    // The cloth did fall: the free corner is lower at the end.
    let lowest_end = (0..f.base.len())
        .map(|v| f.base[v][1] + f.deltas[n - 1][v][1])
        .fold(f32::INFINITY, f32::min);
    assert!(lowest_end < -0.2, "lowest point {lowest_end}");
}

#[test]
fn uvs_are_carried_over_from_the_obj() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cloth.gltf");
    let mut job = ClothJob::new(ClothSource::File(mesh_path("cloth_z_up.obj")), out.clone());
    job.frames = Some(3);
    job.gravity = Some(scenebake::glam::DVec3::new(0.0, 0.0, -9.81));
    job.pin = vec!["index:0".parse().unwrap()];
    bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert!(
        dir.path().join("cloth.bin").exists(),
        ".gltf gets its .bin beside it"
    );
    let f = load(&out);
    let mut got: Vec<[u32; 2]> = f
        .uvs
        .expect("TEXCOORD_0")
        .iter()
        .map(|[u, v]| [u.to_bits(), (1.0 - v).to_bits()])
        .collect();
    // Independent reader: tobj's texture coordinates (glTF flips v).
    let (models, _) = tobj::load_obj(
        mesh_path("cloth_z_up.obj"),
        &tobj::LoadOptions {
            triangulate: true,
            ..Default::default()
        },
    )
    .unwrap();
    let mut want: Vec<[u32; 2]> = models[0]
        .mesh
        .texcoords
        .chunks(2)
        .map(|t| [t[0].to_bits(), t[1].to_bits()])
        .collect();
    got.sort_unstable();
    got.dedup();
    want.sort_unstable();
    want.dedup();
    // 1 - (1 - v) may differ from v in the last bit; compare as floats.
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g[0], w[0]);
        assert!((f32::from_bits(g[1]) - f32::from_bits(w[1])).abs() < 1e-6);
    }
}

#[test]
fn step_interpolation_and_no_normals_are_honoured() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 10 }, out.clone());
    job.frames = Some(5);
    job.interpolation = scenebake::export::Interpolation::Step;
    job.normals = scenebake::bake::cloth::Switch::Off;
    bake_cloth(&job, &mut |_, _| {}).unwrap();
    let (doc, _, _) = common::gltf_read::import(&out).unwrap();
    let sampler = doc.animations().next().unwrap().samplers().next().unwrap();
    assert_eq!(
        sampler.interpolation(),
        gltf::animation::Interpolation::Step
    );
    let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert!(prim.get(&gltf::Semantic::Normals).is_none());
    assert!(prim.morph_targets().all(|t| t.normals().is_none()));
}

/// Cloth that starts where the barrier cannot hold it (inside one of two solid half-spaces
/// 1 mm apart, closer than the 3 mm thickness, so pushing a particle out of one puts it behind
/// the other) is an error naming the time step, and nothing is written.
#[test]
fn cloth_starting_behind_a_barrier_is_an_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("squeezed.glb");
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 4 }, out.clone());
    job.frames = Some(2);
    // The lab grid lies in the plane y = 1.5: solid below 1.5005 and above 1.5015.
    job.collider = vec![
        ColliderSpec::Plane(DVec3::Y, 1.5005),
        ColliderSpec::Plane(-DVec3::Y, -1.5015),
    ];
    job.thickness = Some(0.003);
    job.contact = Some(ContactModel::Barrier);
    let err = bake_cloth(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(err.contains("diverged at frame 1"), "{err}");
    assert!(
        err.contains("start time step 1 behind a collider's surface"),
        "{err}"
    );
    // Newton's advice: a shorter step, not the local/global method's iterations.
    assert!(
        err.contains("substeps") && !err.contains("iterations"),
        "{err}"
    );
    assert!(names_in(dir.path()).is_empty(), "nothing written");
}

/// A step that ends with its forces unbalanced by millions of times the cloth's weight solved
/// nothing: the bake is an error and writes nothing, even though every position is finite and
/// near the start. The lab cloth with one Newton iteration a step and no sweeps, its particles
/// made so light that the springs the first iteration leaves unbalanced outweigh them: at
/// 1e-20 kg a particle the steps end near ρ = 9e6, past the 1e6 limit; at 1e-12 kg near 1e5,
/// which is exported with its frames flagged.
#[test]
fn a_step_ending_a_million_times_off_balance_is_a_divergence_not_an_export() {
    let dir = tempfile::tempdir().unwrap();
    let bake = |mass: f64, name: &str| {
        let mut job = ClothJob::new(
            ClothSource::LabCloth { resolution: 10 },
            dir.path().join(name),
        );
        job.frames = Some(2);
        job.mass = Some(mass);
        job.max_newton = 1;
        job.sweeps = Some(0);
        bake_cloth(&job, &mut |_, _| {})
    };
    let flagged = bake(1e-12, "flagged.glb").unwrap();
    let worst = flagged.residuals.iter().copied().fold(0.0, f64::max);
    assert!((1e3..1e6).contains(&worst), "worst rho {worst}");
    assert_eq!(flagged.unconverged_frames.len(), 2);
    let err = bake(1e-20, "noise.glb").unwrap_err().to_string();
    assert!(err.contains("diverged at frame 1"), "{err}");
    assert!(err.contains("times the cloth's weight unbalanced"), "{err}");
    assert_eq!(names_in(dir.path()), ["flagged.glb"]);
}

/// A bake that runs for a while and then diverges writes nothing: the earlier export stays as it
/// was and no temporary is left. Gravity of 1e10 m/s² carries the cloth past the divergence
/// guard's 1e9 m bound after some 27 frames of 50 (x ≈ g·h²·k(k+1)/2 with h = 1/60 s).
#[test]
fn a_bake_diverging_after_some_frames_keeps_the_earlier_export() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.gltf");
    std::fs::write(&out, b"earlier export").unwrap();
    std::fs::write(dir.path().join("keep.bin"), b"earlier buffer").unwrap();
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 10 }, out.clone());
    job.frames = Some(50);
    job.gravity = Some(scenebake::glam::DVec3::new(0.0, -1e10, 0.0));
    let mut done = 0;
    let err = bake_cloth(&job, &mut |frame, _| done = frame)
        .unwrap_err()
        .to_string();
    assert!(
        (10..50).contains(&done),
        "{done} frames were simulated before the failure: {err}"
    );
    assert!(
        err.contains(&format!("diverged at frame {}", done + 1)),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"earlier export");
    assert_eq!(
        std::fs::read(dir.path().join("keep.bin")).unwrap(),
        b"earlier buffer"
    );
    assert_eq!(
        names_in(dir.path()),
        ["keep.bin", "keep.gltf"],
        "no temporary left behind"
    );
}
