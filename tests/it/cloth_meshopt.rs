//! `--compress meshopt`: the same bake with and without EXT_meshopt_compression. Every
//! compressed buffer view, decoded with meshoptimizer's decoders, must give back the bytes of the
//! uncompressed file's view (triangles up to a rotation of their corners, which the index codec
//! may apply); the file declares the extension as required, with a fallback buffer. (three.js's MeshoptDecoder playing it is checked in scripts/viewer_check.sh.)

use crate::common;

use std::path::Path;

use scenebake::bake::cloth::{bake_cloth, ClothJob, ClothSource};
use scenebake::export::{BasisSize, Compression, QuantizeMode};
use serde_json::{json, Value};

fn lab_job(out: &Path, frames: usize) -> ClothJob {
    let mut job = ClothJob::new(ClothSource::LabCloth { resolution: 10 }, out.to_path_buf());
    job.frames = Some(frames);
    job
}

fn read_glb(path: &Path) -> (Value, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let g = gltf::binary::Glb::from_slice(&bytes).unwrap();
    (
        serde_json::from_slice(&g.json).unwrap(),
        g.bin.map(|b| b.into_owned()).unwrap_or_default(),
    )
}

/// The bytes of view `v` of `doc`, decoding EXT_meshopt_compression where present.
fn view_bytes(doc: &Value, bin: &[u8], v: usize) -> Vec<u8> {
    let view = &doc["bufferViews"][v];
    let at = |x: &Value| x["byteOffset"].as_u64().unwrap_or(0) as usize;
    let len = |x: &Value| x["byteLength"].as_u64().unwrap() as usize;
    let Some(e) = view["extensions"].get("EXT_meshopt_compression") else {
        return bin[at(view)..at(view) + len(view)].to_vec();
    };
    assert_eq!(e["buffer"], json!(0), "bufferViews[{v}]");
    let data = &bin[at(e)..at(e) + len(e)];
    let count = e["count"].as_u64().unwrap() as usize;
    let stride = e["byteStride"].as_u64().unwrap() as usize;
    let out: Vec<u8> = match (e["mode"].as_str().unwrap(), stride) {
        ("TRIANGLES", 2) => meshopt::decode_index_buffer::<u16>(data, count)
            .unwrap()
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        ("TRIANGLES", 4) => meshopt::decode_index_buffer::<u32>(data, count)
            .unwrap()
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        ("ATTRIBUTES", 4) => meshopt::decode_vertex_buffer::<[u8; 4]>(data, count)
            .unwrap()
            .concat(),
        ("ATTRIBUTES", 8) => meshopt::decode_vertex_buffer::<[u8; 8]>(data, count)
            .unwrap()
            .concat(),
        ("ATTRIBUTES", 12) => meshopt::decode_vertex_buffer::<[u8; 12]>(data, count)
            .unwrap()
            .concat(),
        ("ATTRIBUTES", 16) => meshopt::decode_vertex_buffer::<[u8; 16]>(data, count)
            .unwrap()
            .concat(),
        other => panic!("bufferViews[{v}]: unexpected mode/stride {other:?}"),
    };
    assert_eq!(out.len(), len(view), "bufferViews[{v}] decoded length");
    out
}

/// Triangles of little-endian `size`-byte indices, each rotated to start at its smallest index.
fn triangles(bytes: &[u8], size: usize) -> Vec<[u32; 3]> {
    let index = |c: &[u8]| match size {
        2 => u16::from_le_bytes([c[0], c[1]]) as u32,
        _ => u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
    };
    let flat: Vec<u32> = bytes.chunks_exact(size).map(index).collect();
    flat.chunks_exact(3)
        .map(|t| {
            let k = (0..3).min_by_key(|&i| t[i]).unwrap_or(0);
            [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
        })
        .collect()
}

#[track_caller]
fn same_data_smaller(plain: &Path, packed: &Path, max_ratio: f64) -> usize {
    let (a, abin) = read_glb(plain);
    let (b, bbin) = read_glb(packed);
    // The plain file's extensions, and EXT_meshopt_compression, used and required.
    for key in ["extensionsUsed", "extensionsRequired"] {
        let mut want = a[key].as_array().cloned().unwrap_or_default();
        want.push(json!("EXT_meshopt_compression"));
        assert_eq!(b[key], json!(want), "{key}");
    }
    let fallback = &b["buffers"][1];
    assert_eq!(
        fallback["extensions"]["EXT_meshopt_compression"]["fallback"],
        json!(true)
    );
    assert!(fallback.get("uri").is_none());
    // Everything but the buffer layout is the same document.
    for key in [
        "accessors",
        "meshes",
        "nodes",
        "animations",
        "asset",
        "materials",
    ] {
        assert_eq!(a[key], b[key], "{key}");
    }
    let views = a["bufferViews"].as_array().unwrap().len();
    let mut compressed = 0;
    for v in 0..views {
        compressed += b["bufferViews"][v]["extensions"]
            .get("EXT_meshopt_compression")
            .is_some() as usize;
        let (got, want) = (view_bytes(&b, &bbin, v), view_bytes(&a, &abin, v));
        let mode = &b["bufferViews"][v]["extensions"]["EXT_meshopt_compression"]["mode"];
        if mode == "TRIANGLES" {
            // The index codec may rotate a triangle's corners (winding kept): same triangles,
            // in the same order.
            let size = b["bufferViews"][v]["extensions"]["EXT_meshopt_compression"]["byteStride"]
                .as_u64()
                .unwrap() as usize;
            assert_eq!(
                triangles(&got, size),
                triangles(&want, size),
                "bufferViews[{v}]"
            );
        } else {
            assert_eq!(got, want, "bufferViews[{v}]");
        }
    }
    let (sa, sb) = (
        std::fs::metadata(plain).unwrap().len(),
        std::fs::metadata(packed).unwrap().len(),
    );
    assert!(
        (sb as f64) < max_ratio * sa as f64,
        "{sb} bytes compressed, {sa} plain"
    );
    compressed
}

#[test]
fn meshopt_views_decode_to_the_uncompressed_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.glb");
    let packed = dir.path().join("packed.glb");
    bake_cloth(&lab_job(&plain, 20), &mut |_, _| {}).unwrap();
    let mut job = lab_job(&packed, 20);
    job.compress = Compression::Meshopt;
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(
        report.cache.gltf_bytes,
        std::fs::metadata(&packed).unwrap().len()
    );
    // POSITION, NORMAL, TEXCOORD_0, the indices, the 20 POSITION deltas and the weights; tiny
    // views (7 sparse NORMAL deltas, 21 key times) stay plain, as compressed they would be larger.
    assert!(same_data_smaller(&plain, &packed, 0.5) >= 25);

    // A quantised basis (int16 positions, int8 normals padded to 4 bytes) too.
    let mut basis = lab_job(&plain, 20);
    basis.basis = Some(BasisSize::Auto);
    basis.quantize = Some(QuantizeMode::On);
    bake_cloth(&basis, &mut |_, _| {}).unwrap();
    basis.output = packed.clone();
    basis.compress = Compression::Meshopt;
    bake_cloth(&basis, &mut |_, _| {}).unwrap();
    // (A small file, mostly JSON.)
    assert!(same_data_smaller(&plain, &packed, 0.8) >= 3);
}

/// A bake on a character (`--rig`) compresses its glTF too: skin, joints, weights and the
/// garment's morph cache decode to the uncompressed file's bytes, and `--max-targets` is held to.
#[test]
fn a_character_bake_is_compressed_and_keeps_its_target_limit() {
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.glb");
    let packed = dir.path().join("packed.glb");
    let job = common::rigged_sheet(plain.clone());
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    let targets = report.cache.stats.targets;
    assert!(targets > 10, "{targets} targets");
    let job = ClothJob {
        output: packed.clone(),
        compress: Compression::Meshopt,
        ..job
    };
    let report = bake_cloth(&job, &mut |_, _| {}).unwrap();
    assert_eq!(
        report.cache.gltf_bytes,
        std::fs::metadata(&packed).unwrap().len()
    );
    // (Mostly JSON: the skin, its joints and one accessor per morph target.)
    assert!(same_data_smaller(&plain, &packed, 0.95) >= 10);

    let job = ClothJob {
        max_targets: Some(targets - 1),
        output: dir.path().join("limited.glb"),
        ..job
    };
    let err = bake_cloth(&job, &mut |_, _| {}).unwrap_err().to_string();
    assert!(
        err.contains("max_targets")
            && err.contains(&format!("needs {targets} targets"))
            && err.contains("basis"),
        "{err}"
    );
    assert!(!job.output.exists());
}
