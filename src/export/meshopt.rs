//! `--compress meshopt`: EXT_meshopt_compression over an encoded glTF (engine-side compression;
//! three.js, Babylon.js and gltfpack-aware engines decode it, Blender's importer cannot).
//!
//! Works on the encoded files (a `.glb`, or a `.gltf` with its `.bin`): every buffer view that
//! holds exactly one accessor is compressed with meshoptimizer's codecs (the `meshopt` crate):
//! triangle indices in TRIANGLES mode, everything else (positions, normals, morph deltas, UVs,
//! weights, key times and values) in ATTRIBUTES mode when its stride is a multiple of 4 bytes
//! (at most 256), sparse values included; other views (2-byte sparse indices) stay as they are. As
//! the extension specifies, each compressed view keeps its place in a second, "fallback" buffer
//! that has no data (`extensions.EXT_meshopt_compression.fallback`), its compressed bytes are in
//! the first buffer, and the extension is listed in `extensionsUsed` and `extensionsRequired`.
//! Vertex data uses codec version 0, the one EXT_meshopt_compression defines. Decoding restores
//! the exact vertex bytes in the same vertex order (a VAT still addresses the same vertices); the
//! index codec may rotate a triangle's corners, keeping its winding.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{Error, Result};

/// The extension's name.
pub const EXTENSION: &str = "EXT_meshopt_compression";

/// `--compress`: engine-side compression of the glTF.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Compression {
    /// No compression: every glTF reader, Blender included.
    #[default]
    None,
    /// EXT_meshopt_compression (three.js, Babylon.js, engines with a meshopt decoder; Blender
    /// cannot read it).
    Meshopt,
}

/// Bytes per component of glTF component type `t`.
fn component_size(t: u64) -> Option<usize> {
    match t {
        5120 | 5121 => Some(1),
        5122 | 5123 => Some(2),
        5125 | 5126 => Some(4),
        _ => None,
    }
}

/// Components of accessor type `t`.
fn component_count(t: &str) -> Option<usize> {
    Some(match t {
        "SCALAR" => 1,
        "VEC2" => 2,
        "VEC3" => 3,
        "VEC4" | "MAT2" => 4,
        "MAT3" => 9,
        "MAT4" => 16,
        _ => return None,
    })
}

/// Meshoptimizer's vertex codec (version 0) over `bytes` cut into `stride`-byte elements.
fn encode_attributes(bytes: &[u8], stride: usize) -> Option<Vec<u8>> {
    macro_rules! by_stride {
        ($($n:literal)*) => {
            match stride {
                $($n => {
                    let v: Vec<[u8; $n]> = bytes
                        .chunks_exact($n)
                        .map(|c| c.try_into().unwrap_or([0; $n]))
                        .collect();
                    meshopt::encode_vertex_buffer_level(&v, 2, Some(0)).ok()
                })*
                _ => None,
            }
        };
    }
    by_stride!(4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64)
}

/// Meshoptimizer's index codec over little-endian indices of `size` bytes.
fn encode_triangles(bytes: &[u8], size: usize) -> Option<Vec<u8>> {
    let indices: Vec<u32> = match size {
        2 => bytes
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as u32)
            .collect(),
        4 => bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        _ => return None,
    };
    let vertices = indices.iter().max().map_or(0, |&m| m as usize + 1);
    meshopt::encode_index_buffer(&indices, vertices).ok()
}

fn export_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Export {
        path: path.into(),
        message: message.into().into(),
    }
}

/// Compresses the encoded glTF `files` (as [`super::GltfBuilder::encode`] returns them) for
/// `path`; other files pass through.
///
/// # Errors
/// [`Error::Export`] when the files are not a glTF this crate wrote (no GLB framing, no JSON, a
/// buffer view outside its buffer); [`Error::Json`].
pub fn compress_files(
    path: &Path,
    files: Vec<(PathBuf, Vec<u8>)>,
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    let glb = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    let mut others = Vec::new();
    let mut json_bytes = None;
    let mut bin = Vec::new();
    let mut bin_path = None;
    for (p, bytes) in files {
        if p == path {
            if glb {
                let g = gltf::binary::Glb::from_slice(&bytes)
                    .map_err(|e| export_error(path, format!("not a GLB: {e}")))?;
                json_bytes = Some(g.json.into_owned());
                bin = g.bin.map(|b| b.into_owned()).unwrap_or_default();
            } else {
                json_bytes = Some(bytes);
            }
        } else if !glb && p.extension().is_some_and(|e| e == "bin") && bin_path.is_none() {
            bin = bytes;
            bin_path = Some(p);
        } else {
            others.push((p, bytes));
        }
    }
    let json_bytes = json_bytes.ok_or_else(|| export_error(path, "no glTF among the files"))?;
    let mut doc: Value = serde_json::from_slice(&json_bytes).map_err(|source| Error::Json {
        path: path.into(),
        source,
    })?;
    let new_bin = compress_document(path, &mut doc, &bin)?;
    let json_out = serde_json::to_vec(&doc).map_err(|source| Error::Json {
        path: path.into(),
        source,
    })?;
    let mut out = Vec::new();
    if glb {
        let g = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: 0,
            },
            json: json_out.into(),
            bin: (!new_bin.is_empty()).then(|| new_bin.into()),
        };
        let bytes = g.to_vec().map_err(|e| export_error(path, e.to_string()))?;
        out.push((path.to_path_buf(), bytes));
    } else {
        if let Some(p) = bin_path {
            out.push((p, new_bin));
        }
        out.push((path.to_path_buf(), json_out));
    }
    out.extend(others);
    Ok(out)
}

/// One reader of a buffer view.
#[derive(Debug, Clone, Copy)]
struct Use {
    /// Bytes per component.
    size: usize,
    /// Components per element.
    n: usize,
    /// Elements.
    count: usize,
    /// Triangle indices of a primitive.
    index: bool,
    /// The reader's byteOffset into the view.
    offset: u64,
}

/// Rewrites `doc`'s buffer views over `bin` (buffer 0); returns the new buffer 0.
fn compress_document(path: &Path, doc: &mut Value, bin: &[u8]) -> Result<Vec<u8>> {
    let views = doc["bufferViews"].as_array().map_or(0, Vec::len);
    if views == 0 || doc["buffers"].as_array().map_or(0, Vec::len) != 1 {
        return Ok(bin.to_vec());
    }
    // What each view holds: one entry per accessor (or sparse value array) reading it.
    let mut users: Vec<Vec<Use>> = vec![Vec::new(); views];
    let index_accessors: Vec<u64> = doc["meshes"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|m| m["primitives"].as_array().into_iter().flatten())
        .filter(|p| p["mode"].as_u64().unwrap_or(4) == 4)
        .filter_map(|p| p["indices"].as_u64())
        .collect();
    for (i, a) in doc["accessors"]
        .as_array()
        .into_iter()
        .flatten()
        .enumerate()
    {
        let size = a["componentType"].as_u64().and_then(component_size);
        let n = a["type"].as_str().and_then(component_count);
        let (Some(size), Some(n)) = (size, n) else {
            continue;
        };
        let dense = a["bufferView"].as_u64().zip(a["count"].as_u64());
        let sparse = &a["sparse"];
        // Sparse values (e.g. the NORMAL deltas of a few vertices) are attribute data too.
        let values = sparse["values"]["bufferView"]
            .as_u64()
            .zip(sparse["count"].as_u64());
        for (view, count, offset, index) in [
            dense.map(|(v, c)| {
                (
                    v,
                    c,
                    &a["byteOffset"],
                    index_accessors.contains(&(i as u64)),
                )
            }),
            values.map(|(v, c)| (v, c, &sparse["values"]["byteOffset"], false)),
        ]
        .into_iter()
        .flatten()
        {
            if let Some(list) = users.get_mut(view as usize) {
                list.push(Use {
                    size,
                    n,
                    count: count as usize,
                    index,
                    offset: offset.as_u64().unwrap_or(0),
                });
            }
        }
    }
    let mut out = Vec::new();
    let mut fallback_len = 0usize;
    let mut compressed = 0usize;
    let pad = |b: &mut Vec<u8>| {
        while !b.len().is_multiple_of(4) {
            b.push(0);
        }
    };
    for (i, view) in doc["bufferViews"]
        .as_array_mut()
        .into_iter()
        .flatten()
        .enumerate()
    {
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let length = view["byteLength"].as_u64().unwrap_or(0) as usize;
        let bytes = bin.get(start..start + length).ok_or_else(|| {
            export_error(path, format!("bufferViews[{i}] lies outside the buffer"))
        })?;
        let encoded = match users[i].as_slice() {
            [u] if u.offset == 0 => {
                let stride = view["byteStride"]
                    .as_u64()
                    .map_or(u.size * u.n, |s| s as usize);
                if u.index && u.n * u.size == stride && u.count.is_multiple_of(3) {
                    encode_triangles(bytes, u.size).map(|e| (e, "TRIANGLES", stride, u.count))
                } else if !u.index
                    && stride.is_multiple_of(4)
                    && stride <= 256
                    && length == u.count * stride
                {
                    encode_attributes(bytes, stride).map(|e| (e, "ATTRIBUTES", stride, u.count))
                } else {
                    None
                }
            }
            _ => None,
        };
        match encoded.filter(|(e, ..)| e.len() < length) {
            Some((data, mode, stride, count)) => {
                pad(&mut out);
                let offset = out.len();
                out.extend_from_slice(&data);
                pad(&mut out);
                view["extensions"] = json!({ EXTENSION: {
                    "buffer": 0, "byteOffset": offset, "byteLength": data.len(),
                    "byteStride": stride, "mode": mode, "count": count,
                }});
                view["buffer"] = json!(1);
                view["byteOffset"] = json!(fallback_len);
                fallback_len += length.div_ceil(4) * 4;
                compressed += 1;
            }
            None => {
                pad(&mut out);
                view["byteOffset"] = json!(out.len());
                out.extend_from_slice(bytes);
            }
        }
    }
    pad(&mut out);
    if compressed == 0 {
        return Ok(bin.to_vec());
    }
    let uri = doc["buffers"][0].get("uri").cloned();
    let mut main = json!({ "byteLength": out.len() });
    if let Some(uri) = uri {
        main["uri"] = uri;
    }
    doc["buffers"] = json!([main, {
        "byteLength": fallback_len,
        "extensions": { EXTENSION: { "fallback": true } },
    }]);
    for key in ["extensionsUsed", "extensionsRequired"] {
        let list = doc
            .as_object_mut()
            .map(|o| o.entry(key).or_insert_with(|| json!([])));
        if let Some(Value::Array(list)) = list {
            if !list.iter().any(|e| e == EXTENSION) {
                list.push(json!(EXTENSION));
            }
        }
    }
    Ok(out)
}
