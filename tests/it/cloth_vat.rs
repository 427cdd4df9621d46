//! VAT export (`--vat`): the EXR images, read back with the `exr` crate, hold exactly what the
//! morph-target glTF (read back with the `gltf` crate) plays at every frame, a garment's in a
//! character's glTF (`--rig`) included.

use crate::common;

use std::path::Path;

use common::mesh_path;
use common::morph::{load_morph, Morph};
use exr::prelude::{read_first_rgba_layer_from_file, SampleType};
use scenebake::bake::cloth::{bake_cloth, ClothJob, ClothSource};
use scenebake::export::VatMode;
use scenebake::glam::Vec3;

/// An EXR image: width, height, RGB per pixel (row-major from the top row).
struct Exr {
    width: usize,
    height: usize,
    rgb: Vec<Vec3>,
}

impl Exr {
    fn at(&self, row: usize, column: usize) -> Vec3 {
        self.rgb[row * self.width + column]
    }
}

fn read_exr(path: &Path) -> Exr {
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| {
            (
                res.width(),
                res.height(),
                vec![Vec3::ZERO; res.width() * res.height()],
            )
        },
        |(w, _, px): &mut (usize, usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b)
        },
    )
    .expect("read back with the exr crate");
    let channels = &image.layer_data.channel_data.channels;
    for c in [&channels.0, &channels.1, &channels.2] {
        assert_eq!(c.sample_type, SampleType::F32, "32-bit float channels");
    }
    assert!(channels.3.is_none(), "RGB only");
    let (width, height, rgb) = image.layer_data.channel_data.pixels;
    Exr { width, height, rgb }
}

fn lab_job(dir: &Path, frames: usize) -> ClothJob {
    let mut job = ClothJob::new(
        ClothSource::LabCloth { resolution: 10 },
        dir.join("lab.glb"),
    );
    job.frames = Some(frames);
    job.vat = Some(dir.join("lab.exr"));
    job
}

/// Frame `f` of the glTF as a player shows it at weight 1 (frame 0 is the base).
fn gltf_frame(m: &Morph, f: usize) -> Vec<Vec3> {
    if f == 0 {
        m.base.clone()
    } else {
        m.target_positions(f - 1)
    }
}

fn gltf_normals(m: &Morph, f: usize) -> Vec<Vec3> {
    let base = m.base_normals.clone().expect("NORMAL");
    if f == 0 {
        return base;
    }
    base.iter()
        .zip(m.normal_deltas[f - 1].as_ref().expect("NORMAL delta"))
        .map(|(b, d)| *b + *d)
        .collect()
}

/// The VAT's normal agrees with the glTF's: to 1e-6 at baked frames, and within the documented
/// lean at frame 0 (whose glTF NORMAL is leaned so importers shade the cloth smooth, see
/// `scenebake::export::shading`) and where a normal is still exactly its frame-0 value.
fn normals_agree(frame: usize, vat: Vec3, gltf: Vec3, vat_frame0: Vec3) -> bool {
    if frame > 0 && vat != vat_frame0 {
        return (vat - gltf).abs().max_element() <= 1e-6;
    }
    // Frame 0, or a normal still exactly its frame-0 value (its NORMAL delta stays zero).
    let angle = vat
        .normalize()
        .dot(gltf.normalize())
        .min(1.0)
        .acos()
        .to_degrees();
    angle <= scenebake::export::shading::LEAN_DEGREES as f32 + 1e-3
}

#[test]
fn vat_pixels_match_the_gltf_morph_cache_at_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let frames = 12;
    let job = lab_job(dir.path(), frames);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let vat = report.vat.as_ref().expect("a VAT report");
    let names: Vec<String> = vat
        .files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["lab.exr", "lab.normals.exr", "lab.json"]);
    let on_disk: u64 = report
        .output
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!(report.output_bytes, on_disk, "every file counted");

    let m = load_morph(&dir.path().join("lab.glb"));
    let n = m.base.len();
    let img = read_exr(&dir.path().join("lab.exr"));
    let nrm = read_exr(&dir.path().join("lab.normals.exr"));
    assert_eq!(
        (img.width, img.height),
        (n, frames + 1),
        "one column per vertex, one row per frame"
    );
    assert_eq!((nrm.width, nrm.height), (n, frames + 1));
    let mut lo = Vec3::INFINITY;
    let mut hi = Vec3::NEG_INFINITY;
    for f in 0..=frames {
        let want = gltf_frame(&m, f);
        let want_n = gltf_normals(&m, f);
        for v in 0..n {
            let got = img.at(f, v);
            // base + (p − base) in f32 may differ from p in the last bit.
            assert!(
                (got - want[v]).abs().max_element() <= 1e-6 * (1.0 + want[v].abs().max_element()),
                "frame {f} vertex {v}: {got} vs {}",
                want[v]
            );
            assert!(
                normals_agree(f, nrm.at(f, v), want_n[v], nrm.at(0, v)),
                "normal frame {f} vertex {v}"
            );
            assert!((nrm.at(f, v).length() - 1.0).abs() < 1e-5, "unit normals");
            lo = lo.min(got);
            hi = hi.max(got);
        }
    }
    // Frame 0 is the top row and is the base exactly; the cloth moves afterwards.
    for v in 0..n {
        assert_eq!(img.at(0, v), m.base[v]);
    }
    assert!(
        img.at(frames, 0) != img.at(0, 0) || img.at(frames, n - 1) != img.at(0, n - 1),
        "the cloth moved"
    );

    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("lab.json")).unwrap()).unwrap();
    assert_eq!(json["frames"], frames + 1);
    assert_eq!(json["fps"], report.fps);
    assert_eq!(json["vertex_count"], n);
    assert_eq!(json["mode"], "absolute");
    assert_eq!(json["layout"]["width"], n);
    assert_eq!(json["layout"]["height"], frames + 1);
    assert_eq!(json["layout"]["rows_per_frame"], 1);
    assert_eq!(json["gltf"], "lab.glb");
    assert_eq!(json["positions"], "lab.exr");
    assert_eq!(json["normals"], "lab.normals.exr");
    let bound = |k: &str, i: usize| json["bounds"][k][i].as_f64().unwrap() as f32;
    for i in 0..3 {
        assert_eq!(bound("min", i), lo[i]);
        assert_eq!(bound("max", i), hi[i]);
    }
}

#[test]
fn offset_mode_stores_the_morph_deltas() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = lab_job(dir.path(), 6);
    job.vat_mode = VatMode::Offset;
    job.normals = scenebake::bake::cloth::Switch::Off;
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(
        report.vat.as_ref().unwrap().files.len(),
        2,
        "no normal image with --normals off"
    );
    assert!(!dir.path().join("lab.normals.exr").exists());
    let m = load_morph(&dir.path().join("lab.glb"));
    let img = read_exr(&dir.path().join("lab.exr"));
    for v in 0..m.base.len() {
        assert_eq!(img.at(0, v), Vec3::ZERO);
        for f in 1..=6 {
            assert_eq!(
                img.at(f, v),
                m.deltas[f - 1][v],
                "offset = the glTF's POSITION delta, bit for bit"
            );
        }
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("lab.json")).unwrap()).unwrap();
    assert_eq!(json["mode"], "offset");
    assert!(json["normals"].is_null());
}

#[test]
fn wide_meshes_wrap_into_several_rows_per_frame() {
    let dir = tempfile::tempdir().unwrap();
    let frames = 4;
    let mut job = lab_job(dir.path(), frames);
    job.vat_max_width = 50; // 121 vertices → 3 rows of 50
    bake_cloth(&job, &mut |_, _| {}).unwrap();
    let m = load_morph(&dir.path().join("lab.glb"));
    let n = m.base.len();
    assert_eq!(n, 121);
    let img = read_exr(&dir.path().join("lab.exr"));
    let nrm = read_exr(&dir.path().join("lab.normals.exr"));
    let rows = 3;
    assert_eq!((img.width, img.height), (50, (frames + 1) * rows));
    assert_eq!((nrm.width, nrm.height), (50, (frames + 1) * rows));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("lab.json")).unwrap()).unwrap();
    assert_eq!(json["layout"]["rows_per_frame"], rows);
    assert_eq!(json["layout"]["width"], 50);
    for f in 0..=frames {
        let want = gltf_frame(&m, f);
        let want_n = gltf_normals(&m, f);
        for v in 0..n {
            let (row, col) = (f * rows + v / 50, v % 50);
            assert!(
                (img.at(row, col) - want[v]).abs().max_element()
                    <= 1e-6 * (1.0 + want[v].abs().max_element()),
                "frame {f} vertex {v}"
            );
            assert!(normals_agree(
                f,
                nrm.at(row, col),
                want_n[v],
                nrm.at(v / 50, v % 50)
            ));
        }
        // The unused tail of each frame's last row is zero.
        for col in n % 50..50 {
            assert_eq!(img.at(f * rows + rows - 1, col), Vec3::ZERO);
        }
    }
}

#[test]
fn bad_vat_options_name_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = lab_job(dir.path(), 2);
    job.vat = Some(dir.path().join("lab.png"));
    let e = bake_cloth(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(e.contains("`vat`") && e.contains(".exr"), "{e}");
    let mut job = lab_job(dir.path(), 2);
    job.vat_max_width = 0;
    let e = bake_cloth(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(e.contains("`vat_max_width`"), "{e}");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "nothing written"
    );
}

#[test]
fn vat_follows_the_render_vertices_of_a_seamed_obj() {
    // cloth_z_up.obj has UVs: render vertices are the glTF's, not the particles.
    let dir = tempfile::tempdir().unwrap();
    let mut job = ClothJob::new(
        ClothSource::File(mesh_path("cloth_z_up.obj")),
        dir.path().join("c.gltf"),
    );
    job.frames = Some(3);
    job.gravity = Some(scenebake::glam::DVec3::new(0.0, 0.0, -9.81));
    job.pin = vec!["index:0".parse().unwrap()];
    job.vat = Some(dir.path().join("c.exr"));
    bake_cloth(&job, &mut |_, _| {}).unwrap();
    let m = load_morph(&dir.path().join("c.gltf"));
    let img = read_exr(&dir.path().join("c.exr"));
    assert_eq!(img.width, m.base.len());
    for f in 0..=3 {
        let want = gltf_frame(&m, f);
        for (v, w) in want.iter().enumerate() {
            assert!(
                (img.at(f, v) - *w).abs().max_element() <= 1e-6 * (1.0 + w.abs().max_element())
            );
        }
    }
}

#[test]
fn the_gltf_and_vat_are_replaced_together_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let job = lab_job(dir.path(), 3);
    std::fs::write(dir.path().join("lab.glb"), b"earlier export").unwrap();
    std::fs::write(dir.path().join("lab.exr"), b"earlier vat").unwrap();
    // The JSON's target is a directory: the set fails after the images are staged.
    std::fs::create_dir(dir.path().join("lab.json")).unwrap();
    let e = bake_cloth(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(e.contains("lab.json"), "{e}");
    assert_eq!(
        std::fs::read(dir.path().join("lab.glb")).unwrap(),
        b"earlier export"
    );
    assert_eq!(
        std::fs::read(dir.path().join("lab.exr")).unwrap(),
        b"earlier vat"
    );
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["lab.exr", "lab.glb", "lab.json"],
        "no temporary left behind"
    );
}

/// The garment of a character's glTF as the `gltf` crate reads it: its node's scale, its
/// morph cache (base, deltas, NORMAL base and deltas) and its weights channel in the first
/// animation (one key per written frame without `--keyframe-tolerance`).
struct Garment {
    scale: [f32; 3],
    base: Vec<Vec3>,
    deltas: Vec<Vec<Vec3>>,
    normals: Vec<Vec3>,
    normal_deltas: Vec<Vec<Vec3>>,
    times: Vec<f32>,
    weights: Vec<f32>,
}

impl Garment {
    fn load(path: &Path, name: &str) -> Garment {
        let (doc, buffers, _) = common::gltf_read::import(path).unwrap();
        let node = doc.nodes().find(|n| n.name() == Some(name)).unwrap();
        let (_, _, scale) = node.transform().decomposed();
        let prim = node.mesh().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let v3 = |it: &mut dyn Iterator<Item = [f32; 3]>| it.map(Vec3::from).collect::<Vec<_>>();
        let base = v3(&mut reader.read_positions().unwrap());
        let normals = v3(&mut reader.read_normals().expect("NORMAL"));
        let (mut deltas, mut normal_deltas) = (Vec::new(), Vec::new());
        for (p, n, _) in reader.read_morph_targets() {
            deltas.push(v3(&mut p.expect("POSITION delta")));
            normal_deltas.push(match n {
                Some(mut n) => v3(&mut n),
                None => vec![Vec3::ZERO; base.len()],
            });
        }
        let channel = doc
            .animations()
            .next()
            .unwrap()
            .channels()
            .find(|c| {
                c.target().node().index() == node.index()
                    && c.target().property() == gltf::animation::Property::MorphTargetWeights
            })
            .expect("the garment's weights in the first animation");
        let r = channel.reader(|b| Some(&buffers[b.index()]));
        let times: Vec<f32> = r.read_inputs().unwrap().collect();
        let weights = match r.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
            _ => panic!("weights output"),
        };
        Garment {
            scale,
            base,
            deltas,
            normals,
            normal_deltas,
            times,
            weights,
        }
    }

    /// Base + Σ wⱼ·Δⱼ at key `k`, for positions and (unnormalised) normals.
    fn at_key(&self, k: usize) -> (Vec<Vec3>, Vec<Vec3>) {
        let n = self.deltas.len();
        let w = &self.weights[k * n..(k + 1) * n];
        let (mut p, mut q) = (self.base.clone(), self.normals.clone());
        for (j, &wj) in w.iter().enumerate() {
            if wj != 0.0 {
                for v in 0..p.len() {
                    p[v] += wj * self.deltas[j][v];
                    q[v] += wj * self.normal_deltas[j][v];
                }
            }
        }
        (p, q)
    }
}

/// A garment on a character (`--rig`) gets a VAT of its written loops: row f of the EXR
/// (addressed by the manifest's layout, wrapped here) is what the character's glTF plays for the
/// garment at its f-th key (base + morph targets by the keyed weights, object space, metres;
/// the node scales by 1 / `--rig-scale`), every key a row, the manifest's fps and start the keys'
/// times, written in the same set as the glTF and reported.
#[test]
fn a_garment_on_a_character_gets_a_vat_of_its_written_loops() {
    let dir = tempfile::tempdir().unwrap();
    let job = ClothJob {
        rig_scale: 0.5,
        cycles: 2,
        vat: Some(dir.path().join("rig.exr")),
        vat_max_width: 16,
        ..common::rigged_sheet(dir.path().join("rig.glb"))
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let vat = report.vat.as_ref().expect("a VAT report");
    let names: Vec<String> = report
        .output
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["rig.glb", "rig.exr", "rig.normals.exr", "rig.json"]);
    assert_eq!(vat.files, report.output[1..]);
    let on_disk = |files: &[std::path::PathBuf]| -> u64 {
        files
            .iter()
            .map(|p| std::fs::metadata(p).unwrap().len())
            .sum()
    };
    assert_eq!(vat.bytes, on_disk(&vat.files));
    assert_eq!(report.output_bytes, on_disk(&report.output));

    let g = Garment::load(&job.output, "cache_sheet");
    assert_eq!(
        g.scale, [2.0; 3],
        "the node scales metres to the rig's units"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("rig.json")).unwrap()).unwrap();
    let character = report.character.as_ref().unwrap();
    let frames = job.cycles * character.frames_per_cycle + 1;
    assert_eq!(g.times.len(), frames, "a key per written frame");
    assert_eq!(json["frames"], frames);
    assert_eq!(json["fps"], report.fps);
    assert_eq!(json["gltf"], "rig.glb");
    assert_eq!(json["positions"], "rig.exr");
    assert_eq!(json["normals"], "rig.normals.exr");
    assert_eq!(json["mode"], "absolute");
    assert_eq!(json["vertex_count"], g.base.len());
    let fps = json["fps"].as_f64().unwrap();
    let start = json["start_time"].as_f64().unwrap();
    assert!(start > 0.0, "RiggedSimple's animation starts after 0");
    for (k, t) in g.times.iter().enumerate() {
        let want = start + k as f64 / fps;
        assert!(
            (f64::from(*t) - want).abs() < 1e-5,
            "key {k} at {t} s, the manifest's frame {k} at {want} s"
        );
    }

    let (width, rows) = (
        json["layout"]["width"].as_u64().unwrap() as usize,
        json["layout"]["rows_per_frame"].as_u64().unwrap() as usize,
    );
    let n = g.base.len();
    assert_eq!((width, rows), (16, n.div_ceil(16)));
    let img = read_exr(&dir.path().join("rig.exr"));
    let nrm = read_exr(&dir.path().join("rig.normals.exr"));
    assert_eq!((img.width, img.height), (width, frames * rows));
    assert_eq!((nrm.width, nrm.height), (width, frames * rows));
    let texel = |image: &Exr, f: usize, v: usize| image.at(f * rows + v / width, v % width);
    let bound = |k: &str| {
        Vec3::from_slice(
            &(0..3)
                .map(|i| json["bounds"][k][i].as_f64().unwrap() as f32)
                .collect::<Vec<_>>(),
        )
    };
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let mut moved = 0.0f32;
    for f in 0..frames {
        let (want, want_n) = g.at_key(f);
        for v in 0..n {
            let got = texel(&img, f, v);
            // base + (p − base) in f32 may differ from p in the last bit.
            assert!(
                (got - want[v]).abs().max_element() <= 1e-6 * (1.0 + want[v].abs().max_element()),
                "frame {f} vertex {v}: VAT {got} against the glTF's {}",
                want[v]
            );
            assert!(
                normals_agree(f, texel(&nrm, f, v), want_n[v], texel(&nrm, 0, v)),
                "normal frame {f} vertex {v}"
            );
            lo = lo.min(got);
            hi = hi.max(got);
            moved = moved.max(got.distance(texel(&img, 0, v)));
        }
    }
    assert_eq!((bound("min"), bound("max")), (lo, hi));
    assert!(moved > 0.01, "the garment moves with the bone: {moved} m");
}
