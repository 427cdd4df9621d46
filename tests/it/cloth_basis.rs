//! Morph-basis caches (`--basis`, `--max-targets`, `--quantize`): the written file is reloaded
//! with the `gltf` crate, its accessors decoded here from the raw bytes (component type,
//! normalisation, stride, sparse), the frames played back with the node transform and compared
//! with a reference simulation run through the library directly.

use crate::common;

use std::path::Path;

use common::morph::{max_distance, reference, reference_positions};
use scenebake::bake::cloth::{bake_cloth, ClothJob, ClothSource};
use scenebake::export::{BasisSize, QuantizeMode};
use scenebake::glam::{Mat4, Vec3};

/// Slack for f32 rounding between the writer's measurement and this player.
const ROUNDING: f32 = 2e-6;

fn lab_job(out: &Path, frames: usize) -> ClothJob {
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 12 }, out.to_path_buf());
    job.frames = Some(frames);
    job
}

/// A basis cache decoded from the file.
struct Played {
    transform: Mat4,
    base: Vec<Vec3>,
    deltas: Vec<Vec<Vec3>>,
    times: Vec<f32>,
    weights: Vec<f32>,
    default_weights: Vec<f32>,
    extensions_required: Vec<String>,
    position_type: gltf::accessor::DataType,
    /// The base NORMAL and every target's NORMAL deltas (zero where a target has none).
    normal_base: Option<Vec<Vec3>>,
    normal_deltas: Vec<Vec<Vec3>>,
}

impl Played {
    fn k(&self) -> usize {
        self.deltas.len()
    }

    /// The weights at time `t`, sampled linearly.
    fn weights_at(&self, t: f32) -> Vec<f32> {
        let k = self.k();
        let row = |i: usize| &self.weights[i * k..(i + 1) * k];
        let i = self.times.partition_point(|&x| x <= t).max(1) - 1;
        if i + 1 >= self.times.len() {
            row(i).to_vec()
        } else {
            let s = ((t - self.times[i]) / (self.times[i + 1] - self.times[i])).clamp(0.0, 1.0);
            row(i)
                .iter()
                .zip(row(i + 1))
                .map(|(a, b)| a + s * (b - a))
                .collect()
        }
    }

    /// Unit normals at time `t`: base NORMAL + Σ w·ΔNORMAL, renormalised (the node transform
    /// is a uniform scale and a translation, which leave normals as they are).
    fn normals_at(&self, t: f32) -> Vec<Vec3> {
        let w = self.weights_at(t);
        let base = self.normal_base.as_ref().expect("a NORMAL attribute");
        base.iter()
            .enumerate()
            .map(|(v, b)| {
                let mut n = *b;
                for (d, wk) in self.normal_deltas.iter().zip(&w) {
                    n += *wk * d[v];
                }
                n.normalize()
            })
            .collect()
    }

    /// World positions at time `t`: weights sampled linearly, base + Σ w·Δ, node transform.
    fn positions_at(&self, t: f32) -> Vec<Vec3> {
        let w = self.weights_at(t);
        self.base
            .iter()
            .enumerate()
            .map(|(v, b)| {
                let mut p = *b;
                for (d, wk) in self.deltas.iter().zip(&w) {
                    p += *wk * d[v];
                }
                self.transform.transform_point3(p)
            })
            .collect()
    }
}

/// Decodes a VEC3 accessor from the raw bytes: float, or (normalised) integers, with stride and
/// sparse substitution.
fn read_vec3(a: &gltf::Accessor<'_>, buffers: &[common::gltf_read::Data]) -> Vec<Vec3> {
    use gltf::accessor::DataType;
    assert_eq!(a.dimensions(), gltf::accessor::Dimensions::Vec3);
    let size = a.data_type().size();
    let decode = |bytes: &[u8]| -> f32 {
        let raw = match a.data_type() {
            DataType::F32 => return f32::from_le_bytes(bytes[..4].try_into().unwrap()),
            DataType::I16 => i16::from_le_bytes([bytes[0], bytes[1]]) as f32,
            DataType::U16 => u16::from_le_bytes([bytes[0], bytes[1]]) as f32,
            DataType::I8 => bytes[0] as i8 as f32,
            DataType::U8 => bytes[0] as f32,
            DataType::U32 => panic!("u32 is not a vertex attribute type"),
        };
        if !a.normalized() {
            return raw;
        }
        match a.data_type() {
            DataType::I16 => (raw / 32767.0).max(-1.0),
            DataType::U16 => raw / 65535.0,
            DataType::I8 => (raw / 127.0).max(-1.0),
            DataType::U8 => raw / 255.0,
            _ => unreachable!(),
        }
    };
    let element = |data: &[u8], at: usize| -> Vec3 {
        Vec3::new(
            decode(&data[at..]),
            decode(&data[at + size..]),
            decode(&data[at + 2 * size..]),
        )
    };
    let mut out = vec![Vec3::ZERO; a.count()];
    if let Some(view) = a.view() {
        let data = &buffers[view.buffer().index()].0;
        let stride = view.stride().unwrap_or(3 * size);
        let start = view.offset() + a.offset();
        for (i, o) in out.iter_mut().enumerate() {
            *o = element(data, start + i * stride);
        }
    }
    if let Some(sparse) = a.sparse() {
        let iv = sparse.indices().view();
        let idata = &buffers[iv.buffer().index()].0;
        let istart = iv.offset() + sparse.indices().offset();
        let vv = sparse.values().view();
        let vdata = &buffers[vv.buffer().index()].0;
        let vstart = vv.offset() + sparse.values().offset();
        for n in 0..sparse.count() {
            let index = match sparse.indices().index_type() {
                gltf::accessor::sparse::IndexType::U8 => idata[istart + n] as usize,
                gltf::accessor::sparse::IndexType::U16 => {
                    u16::from_le_bytes([idata[istart + 2 * n], idata[istart + 2 * n + 1]]) as usize
                }
                gltf::accessor::sparse::IndexType::U32 => u32::from_le_bytes(
                    idata[istart + 4 * n..istart + 4 * n + 4]
                        .try_into()
                        .unwrap(),
                ) as usize,
            };
            out[index] = element(vdata, vstart + n * 3 * size);
        }
    }
    out
}

/// The document and buffers of `path`. The gltf crate validates extensionsRequired against the
/// extensions it implements, which do not include KHR_mesh_quantization: parse without that
/// check (the accessors are decoded here, by `read_vec3`).
fn open(path: &Path) -> (gltf::Document, Vec<common::gltf_read::Data>) {
    let bytes = std::fs::read(path).unwrap();
    let gltf =
        gltf::Gltf::from_slice_without_validation(&bytes).expect("parse with the gltf crate");
    let buffers =
        common::gltf_read::import_buffers(&gltf.document, path.parent(), gltf.blob.clone())
            .unwrap();
    (gltf.document, buffers)
}

/// The first primitive of the first mesh.
fn first_primitive(doc: &gltf::Document) -> gltf::Primitive<'_> {
    doc.meshes().next().unwrap().primitives().next().unwrap()
}

fn load(path: &Path) -> Played {
    load_node(path, None)
}

/// The morph cache of the node named `name` (the first node when `None`), played by the
/// channel of the first animation that animates its weights.
fn load_node(path: &Path, name: Option<&str>) -> Played {
    let (doc, buffers) = open(path);
    let node = match name {
        Some(name) => doc.nodes().find(|n| n.name() == Some(name)).unwrap(),
        None => doc.nodes().next().unwrap(),
    };
    let mesh = node.mesh().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let pos = prim.get(&gltf::Semantic::Positions).unwrap();
    let base = read_vec3(&pos, &buffers);
    let deltas = prim
        .morph_targets()
        .map(|t| read_vec3(&t.positions().unwrap(), &buffers))
        .collect();
    let normal_base = prim
        .get(&gltf::Semantic::Normals)
        .map(|n| read_vec3(&n, &buffers));
    let normal_deltas = prim
        .morph_targets()
        .map(|t| match t.normals() {
            Some(n) => read_vec3(&n, &buffers),
            None => vec![Vec3::ZERO; base.len()],
        })
        .collect();
    let anim = doc.animations().next().unwrap();
    let channel = anim
        .channels()
        .find(|c| {
            c.target().node().index() == node.index()
                && c.target().property() == gltf::animation::Property::MorphTargetWeights
        })
        .unwrap();
    assert_eq!(
        channel.sampler().interpolation(),
        gltf::animation::Interpolation::Linear
    );
    let r = channel.reader(|b| Some(&buffers[b.index()]));
    let times: Vec<f32> = r.read_inputs().unwrap().collect();
    let weights: Vec<f32> = match r.read_outputs().unwrap() {
        gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
        _ => panic!("weights output"),
    };
    Played {
        transform: Mat4::from_cols_array_2d(&node.transform().matrix()),
        base,
        deltas,
        times,
        weights,
        default_weights: mesh.weights().unwrap_or_default().to_vec(),
        extensions_required: doc.extensions_required().map(str::to_owned).collect(),
        position_type: pos.data_type(),
        normal_base,
        normal_deltas,
    }
}

/// Largest distance between the file played at every baked frame and the reference.
fn worst_error(job: &ClothJob, played: &Played, fps: f64) -> (f32, usize) {
    let (mesh, sim) = reference(job);
    let mut worst = (0.0f32, 0);
    for k in 0..sim.frame_count() {
        let got = played.positions_at((k as f64 / fps) as f32);
        let want = reference_positions(&mesh, &sim, k);
        let d = got
            .iter()
            .zip(&want)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max);
        if d > worst.0 {
            worst = (d, k);
        }
    }
    worst
}

#[test]
fn auto_basis_plays_every_frame_within_the_tolerance_with_few_targets() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let frames = 120;
    let tolerance = 1e-3;
    let mut job = lab_job(&out, frames);
    job.basis = Some(BasisSize::Auto);
    job.basis_tolerance = Some(tolerance);
    job.quantize = Some(QuantizeMode::Off);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let basis = report.cache.basis.as_ref().expect("basis stats");
    let played = load(&out);
    // The K basis targets, and the NORMAL offset target when written.
    let written = basis.targets + usize::from(basis.normal_offset_target) + basis.normal_targets;
    assert_eq!(played.k(), written);
    assert_eq!(report.cache.stats.targets, written);
    assert!(
        basis.targets >= 2 && basis.targets < frames / 4,
        "a slow cloth needs few basis shapes: K = {}",
        basis.targets
    );
    assert_eq!(played.times.len(), frames + 1, "one key per frame");
    assert!(played.extensions_required.is_empty());
    assert_eq!(played.position_type, gltf::accessor::DataType::F32);
    // Blender clamps shape-key values to [0, 1] unless told otherwise: every weight is inside.
    assert!(played.weights.iter().all(|w| (0.0..=1.0).contains(w)));
    // The default weights are frame 0's: a player without animation shows the initial pose.
    assert_eq!(
        played.default_weights,
        played.weights[..played.k()].to_vec()
    );

    let (worst, _) = worst_error(&job, &played, report.fps);
    assert!(worst <= tolerance as f32 + ROUNDING, "{worst} m off");
    assert!(
        (worst - basis.max_error as f32).abs() < 1e-5,
        "the report's error is the one measured: {worst} vs {}",
        basis.max_error
    );
    // One target fewer is not enough (auto picks the smallest K).
    assert!(basis.projection_error <= tolerance);
    let mut fewer = job.clone();
    fewer.basis = Some(BasisSize::Fixed(basis.targets - 1));
    fewer.output = dir.path().join("fewer.glb");
    let r = bake_cloth(&fewer, &mut |_, _| {}).unwrap();
    let e = worst_error(&fewer, &load(&fewer.output), r.fps).0;
    assert!(e > tolerance as f32, "K-1 targets: {e}");

    // Much smaller than one target per frame.
    let mut full = lab_job(&dir.path().join("full.glb"), frames);
    full.normals = scenebake::bake::cloth::Switch::On;
    let rf = bake_cloth(&full, &mut |_, _| {}).unwrap();
    assert!(
        report.output_bytes * 5 < rf.output_bytes,
        "{} vs {}",
        report.output_bytes,
        rf.output_bytes
    );
}

#[test]
fn quantized_basis_uses_int16_and_stays_within_the_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.gltf");
    let tolerance = 1e-3;
    let mut job = lab_job(&out, 60);
    job.basis = Some(BasisSize::Auto);
    job.basis_tolerance = Some(tolerance);
    job.quantize = Some(QuantizeMode::Auto);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let basis = report.cache.basis.as_ref().unwrap();
    assert_eq!(basis.quantization.positions, "int16");
    let played = load(&out);
    assert_eq!(played.position_type, gltf::accessor::DataType::I16);
    assert_eq!(played.extensions_required, vec!["KHR_mesh_quantization"]);
    let (worst, frame) = worst_error(&job, &played, report.fps);
    assert!(
        worst <= tolerance as f32 + ROUNDING,
        "{worst} m off at frame {frame}"
    );
    assert!((worst - basis.max_error as f32).abs() < 1e-5);

    // inspect reads the quantised file and names its encoding.
    let info = scenebake::inspect::inspect(&out).unwrap();
    assert_eq!(info.failures().count(), 0);
    let e = &info.meshes[0].encoding;
    assert_eq!(e.kind, "basis");
    assert!(e.quantized);
    assert_eq!(e.positions, "i16 normalized");
    let stored: usize = e.target_positions.iter().map(|(_, n)| n).sum();
    assert_eq!(
        stored,
        basis.targets + usize::from(basis.normal_offset_target) + basis.normal_targets
    );
    assert_eq!(
        basis.quantization.int8_targets + basis.quantization.int16_targets,
        basis.targets
    );

    let mut float = job.clone();
    float.quantize = Some(QuantizeMode::Off);
    float.output = dir.path().join("float.gltf");
    let rf = bake_cloth(&float, &mut |_, _| {}).unwrap();
    assert!(report.output_bytes < rf.output_bytes);

    // Texture coordinates (within [0, 1]) as normalised u16, the float file's to half a step.
    let uvs = |path: &Path, want: gltf::accessor::DataType| -> Vec<[f32; 2]> {
        let (doc, buffers) = open(path);
        let a = first_primitive(&doc)
            .get(&gltf::Semantic::TexCoords(0))
            .unwrap();
        assert_eq!(a.data_type(), want);
        assert_eq!(a.normalized(), want == gltf::accessor::DataType::U16);
        let view = a.view().unwrap();
        let data = &buffers[view.buffer().index()].0[view.offset() + a.offset()..];
        let size = a.data_type().size();
        let stride = view.stride().unwrap_or(2 * size);
        (0..a.count())
            .map(|i| {
                [0, 1].map(|c| {
                    let at = i * stride + c * size;
                    match a.data_type() {
                        gltf::accessor::DataType::U16 => {
                            u16::from_le_bytes([data[at], data[at + 1]]) as f32 / 65535.0
                        }
                        _ => f32::from_le_bytes(data[at..at + 4].try_into().unwrap()),
                    }
                })
            })
            .collect()
    };
    let (q, f) = (
        uvs(&out, gltf::accessor::DataType::U16),
        uvs(&float.output, gltf::accessor::DataType::F32),
    );
    assert_eq!(q.len(), f.len());
    for (a, b) in q.iter().zip(&f) {
        for c in 0..2 {
            assert!(
                (a[c] - b[c]).abs() <= 0.5 / 65535.0 + 1e-7,
                "{a:?} vs {b:?}"
            );
        }
    }
}

#[test]
fn keyframe_tolerance_drops_weight_keys_within_the_bound() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let frames = 90;
    let mut job = lab_job(&out, frames);
    job.basis = Some(BasisSize::Auto);
    job.keyframe_tolerance = Some(2e-3);
    job.quantize = Some(QuantizeMode::Off);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let basis = report.cache.basis.as_ref().unwrap();
    // The basis tolerance defaults to the keyframe tolerance.
    assert_eq!(basis.tolerance, 2e-3);
    let played = load(&out);
    assert!(
        played.times.len() < frames / 2,
        "{} keys",
        played.times.len()
    );
    assert_eq!(played.times.len(), report.cache.stats.kept_frames.len());
    let (worst, frame) = worst_error(&job, &played, report.fps);
    assert!(worst <= 2e-3 + ROUNDING, "{worst} at frame {frame}");
}

#[test]
fn max_targets_too_small_is_an_error_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let mut job = lab_job(&out, 60);
    job.basis = Some(BasisSize::Auto);
    job.basis_tolerance = Some(1e-5);
    job.max_targets = Some(2);
    let e = bake_cloth(&job, &mut |_, _| {}).unwrap_err();
    assert_eq!(e.param(), Some(scenebake::Param::MaxTargets), "{e}");
    assert!(!out.exists(), "nothing written");

    // Without --basis, a cache with more targets than allowed is refused too.
    let mut plain = lab_job(&out, 20);
    plain.max_targets = Some(10);
    let e = bake_cloth(&plain, &mut |_, _| {}).unwrap_err().to_string();
    assert!(e.contains("`max_targets`"), "{e}");

    // Within the cap, it is respected.
    job.basis_tolerance = Some(1e-3);
    job.max_targets = Some(40);
    let r = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert!(r.cache.stats.targets <= 40);
}

#[test]
fn fixed_basis_writes_k_targets_and_more_targets_are_closer() {
    let dir = tempfile::tempdir().unwrap();
    let mut errors = Vec::new();
    for k in [1, 4, 12] {
        let out = dir.path().join(format!("k{k}.glb"));
        let mut job = lab_job(&out, 60);
        job.basis = Some(BasisSize::Fixed(k));
        job.quantize = Some(QuantizeMode::Off);
        let r = bake_cloth(&job, &mut |_, _| {}).unwrap();
        let played = load(&out);
        let b = r.cache.basis.as_ref().unwrap();
        assert_eq!(
            played.k(),
            k + usize::from(b.normal_offset_target) + b.normal_targets
        );
        let (e, _) = worst_error(&job, &played, r.fps);
        assert!((e - r.cache.basis.as_ref().unwrap().max_error as f32).abs() < 1e-5);
        errors.push(e);
    }
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    let mut job = lab_job(&dir.path().join("x.glb"), 10);
    job.basis = Some(BasisSize::Fixed(11));
    let e = bake_cloth(&job, &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(
            e,
            scenebake::Error::Param {
                param: scenebake::Param::Basis,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn a_cache_that_never_moves_gets_one_zero_target() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("still.glb");
    let mut job = ClothJob::new(
        ClothSource::File(common::mesh_path("plane_30x30.obj")),
        out.clone(),
    );
    job.frames = Some(5);
    // No gravity, no wind, springs at rest: nothing moves.
    job.gravity = Some(scenebake::glam::DVec3::ZERO);
    job.basis = Some(BasisSize::Auto);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let basis = report.cache.basis.as_ref().unwrap();
    assert_eq!(basis.targets, 1);
    let played = load(&out);
    let (worst, _) = worst_error(&job, &played, report.fps);
    assert!(worst <= 1e-3, "{worst}");
}

/// Corner-angle-weighted unit vertex normals of `triangles` over `positions` (Blender's smooth
/// vertex normals), written here independently of the exporter.
fn angle_weighted(positions: &[Vec3], triangles: &[[usize; 3]]) -> Vec<Vec3> {
    let mut sum = vec![scenebake::glam::DVec3::ZERO; positions.len()];
    for t in triangles {
        let p = t.map(|i| positions[i].as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        for c in 0..3 {
            let a = (p[(c + 1) % 3] - p[c]).normalize();
            let b = (p[(c + 2) % 3] - p[c]).normalize();
            sum[t[c]] += n * a.dot(b).clamp(-1.0, 1.0).acos();
        }
    }
    sum.iter().map(|n| n.normalize().as_vec3()).collect()
}

#[test]
fn base_normals_are_the_base_shapes_own_and_every_face_imports_smooth() {
    // Blender keeps the base NORMAL as custom normals relative to the imported base shape and
    // guesses a face flat when every stored corner normal (not renormalised) has a dot product
    // above 0.9999999 with the face normal. The lab cloth starts as a flat sheet.
    let dir = tempfile::tempdir().unwrap();
    for quantize in [QuantizeMode::Auto, QuantizeMode::Off] {
        let out = dir.path().join(format!("lab_{quantize:?}.glb"));
        // 40×40 over 120 frames: large enough that the quantised file is smaller with the NORMAL
        // offset target (the demo's lab_cloth_basis).
        let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 40 }, out.clone());
        job.frames = Some(120);
        job.basis = Some(BasisSize::Auto);
        job.basis_tolerance = Some(1e-3);
        job.quantize = Some(quantize);
        let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
        let basis = report.cache.basis.as_ref().unwrap();
        if quantize == QuantizeMode::Auto {
            assert!(basis.normal_offset_target);
        }
        // The NORMAL offset target, when written, moves nothing and plays at weight 1.
        let played = load(&out);
        if basis.normal_offset_target {
            let k = played.k();
            assert_eq!(k, basis.targets + 1 + basis.normal_targets);
            let offset = basis.targets;
            assert!(played.deltas[offset].iter().all(|d| *d == Vec3::ZERO));
            assert!(played.weights.chunks(k).all(|w| w[offset] == 1.0));
        }
        let info = scenebake::inspect::inspect(&out).unwrap();
        assert_eq!(info.failures().count(), 0);
        let (doc, buffers) = open(&out);
        let prim = first_primitive(&doc);
        let base = read_vec3(&prim.get(&gltf::Semantic::Positions).unwrap(), &buffers);
        let normals = prim.get(&gltf::Semantic::Normals).unwrap();
        if quantize == QuantizeMode::Auto {
            assert_eq!(normals.data_type(), gltf::accessor::DataType::I16);
        }
        let stored = read_vec3(&normals, &buffers);
        let indices: Vec<usize> = prim
            .reader(|b| Some(&buffers[b.index()]))
            .read_indices()
            .unwrap()
            .into_u32()
            .map(|i| i as usize)
            .collect();
        let triangles: Vec<[usize; 3]> = indices.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
        let want = angle_weighted(&base, &triangles);
        // Within the lean given to flat vertices (0.25°) and the int16 step.
        let mut worst = 0.0f32;
        for (n, w) in stored.iter().zip(&want) {
            assert!(n.length() <= 1.0 + 1e-6, "{n} longer than 1");
            worst = worst.max(n.normalize().dot(*w).min(1.0).acos().to_degrees());
        }
        assert!(
            worst <= 0.26,
            "{quantize:?}: {worst}° from the base shape's normals"
        );
        let flat = triangles
            .iter()
            .filter(|t| {
                let p = t.map(|i| base[i]);
                let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
                t.iter().all(|&i| stored[i].dot(face) > 0.999_999_9)
            })
            .count();
        assert_eq!(flat, 0, "{quantize:?}: faces Blender would import flat");
    }
}

#[test]
fn normal_targets_play_the_baked_normals_and_move_nothing() {
    // The demo's lab_cloth_basis (40×40, 120 frames): small-amplitude basis targets have tiny
    // weights, so normal deltas shared with them would need f32; normal targets of their own
    // (zero POSITION, weights of their own) store the normals as int8.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab.glb");
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 40 }, out.clone());
    job.frames = Some(120);
    job.basis = Some(BasisSize::Auto);
    job.basis_tolerance = Some(1e-3);
    job.quantize = Some(QuantizeMode::Auto);
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let basis = report.cache.basis.as_ref().unwrap();
    let j = basis.normal_targets;
    assert!(j > 0, "normal targets written");
    assert!(basis.normal_offset_target);
    let played = load(&out);
    let k = basis.targets;
    assert_eq!(played.k(), k + 1 + j);
    // Position targets carry no normal deltas; the offset and normal targets move nothing.
    for t in 0..k {
        assert!(played.normal_deltas[t].iter().all(|d| *d == Vec3::ZERO));
    }
    for t in k..k + 1 + j {
        assert!(played.deltas[t].iter().all(|d| *d == Vec3::ZERO));
    }
    // Only the position targets' weights need Blender's [0, 1] slider range.
    assert!(played
        .weights
        .chunks(played.k())
        .all(|w| w[..k].iter().all(|x| (0.0..=1.0).contains(x))));
    // Positions still within the tolerance.
    let (worst, _) = worst_error(&job, &played, report.fps);
    assert!(worst <= 1e-3 + ROUNDING, "{worst} m off");

    // The played normals against the baked shape's own normals, computed here from the
    // reference simulation: the angles the report gives, and small on average.
    let (mesh, sim) = reference(&job);
    let triangles: Vec<[usize; 3]> = mesh
        .render_triangles
        .iter()
        .map(|t| t.map(|i| i as usize))
        .collect();
    let (mut largest, mut sum, mut n) = (0.0f64, 0.0f64, 0usize);
    for f in 0..sim.frame_count() {
        let want = angle_weighted(&reference_positions(&mesh, &sim, f), &triangles);
        let got = played.normals_at((f as f64 / report.fps) as f32);
        for (a, b) in got.iter().zip(&want) {
            let angle = (a.dot(*b).clamp(-1.0, 1.0) as f64).acos().to_degrees();
            largest = largest.max(angle);
            sum += angle;
            n += 1;
        }
    }
    let mean = sum / n as f64;
    assert!(
        (largest - basis.max_normal_error_degrees).abs() < 0.05
            && (mean - basis.mean_normal_error_degrees).abs() < 0.005,
        "played normals {largest}° / {mean}° against the report's {}° / {}°",
        basis.max_normal_error_degrees,
        basis.mean_normal_error_degrees
    );
    assert!(mean < 0.2, "mean normal error {mean}°");
}

/// A garment on a character (`--rig`) gets a basis cache too: in the character's document, its
/// node scaled to the document's units over the basis's own dequantisation, played on the
/// animation's time axis, every written frame within the basis tolerance of the per-frame cache
/// of the same bake (itself checked against the skinned body elsewhere), with fewer targets.
#[test]
fn a_garment_on_a_character_gets_a_basis_cache() {
    let dir = tempfile::tempdir().unwrap();
    let job = ClothJob {
        rig_scale: 0.5,
        ..common::rigged_sheet(dir.path().join("frames.glb"))
    };
    let frames = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let tolerance = 1e-3;
    for quantize in [QuantizeMode::Off, QuantizeMode::On] {
        let basis_job = ClothJob {
            output: dir.path().join("basis.glb"),
            basis: Some(BasisSize::Auto),
            basis_tolerance: Some(tolerance),
            quantize: Some(quantize),
            ..job.clone()
        };
        let report = bake_cloth(&basis_job, &mut |_, _| {}).unwrap();
        let basis = report.cache.basis.as_ref().unwrap();
        assert!(
            basis.targets < frames.cache.stats.targets,
            "{} targets",
            basis.targets
        );
        let want = load_node(&job.output, Some("cache_sheet"));
        let got = load_node(&basis_job.output, Some("cache_sheet"));
        assert_eq!(
            got.position_type == gltf::accessor::DataType::I16,
            quantize == QuantizeMode::On
        );
        assert!(want.times[0] > 0.0, "keyed on the animation's times");
        let mut worst = 0.0f32;
        for &t in &want.times {
            // Document units: the tolerance (metres) over the rig scale.
            let d = max_distance(&got.positions_at(t), &want.positions_at(t));
            worst = worst.max(d * 0.5);
        }
        assert!(
            worst <= tolerance as f32 + ROUNDING,
            "{quantize:?}: {worst} m"
        );
        // The character is there and plays: its skin and the driving animation's channels.
        let (doc, _) = open(&basis_job.output);
        assert_eq!(doc.skins().count(), 1);
        assert!(doc.animations().next().unwrap().channels().count() > 1);
    }
}
