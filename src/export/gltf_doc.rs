//! A small typed builder over `gltf-json`: one binary buffer, one buffer view per accessor
//! (4-byte aligned), POSITION-style min/max computed from the exact `f32` data written, and one
//! writer for both `.glb` and `.gltf` + `.bin`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::Vec3;
use gltf_json as json;
use json::validation::{Checked::Valid, USize64};

use super::atomic::write_all_atomically;
use crate::error::{Error, Result};

/// Accumulates a glTF document and its binary buffer.
#[derive(Debug)]
pub struct GltfBuilder {
    /// The document; push meshes, nodes, animations... into it directly.
    pub root: json::Root,
    bin: Vec<u8>,
}

/// What a write produced.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Written {
    /// The files written (the `.gltf` and its `.bin`, or one `.glb`).
    pub files: Vec<PathBuf>,
    /// Their total size in bytes.
    pub bytes: u64,
}

impl Written {
    /// Writes a set of (path, bytes) files atomically (see [`write_all_atomically`]).
    ///
    /// # Errors
    /// [`Error::Io`] naming the file that could not be written; nothing is replaced then.
    pub fn write_all(files: Vec<(PathBuf, Vec<u8>)>) -> Result<Written> {
        let bytes = files.iter().map(|(_, b)| b.len() as u64).sum();
        write_all_atomically(&files)?;
        Ok(Written {
            files: files.into_iter().map(|(p, _)| p).collect(),
            bytes,
        })
    }
}

impl Default for GltfBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl GltfBuilder {
    /// An empty glTF 2.0 document whose generator names scenebake.
    pub fn new() -> Self {
        let mut root = json::Root::default();
        root.asset.generator = Some(format!("scenebake {}", env!("CARGO_PKG_VERSION")));
        GltfBuilder {
            root,
            bin: Vec::new(),
        }
    }

    /// Continues an existing document whose single binary buffer (buffer 0) holds `bin`; new
    /// views are appended after it and the document's asset and content are kept.
    pub fn from_parts(root: json::Root, bin: Vec<u8>) -> Self {
        GltfBuilder { root, bin }
    }

    /// Bytes in the binary buffer so far.
    pub fn buffer_len(&self) -> usize {
        self.bin.len()
    }

    /// Appends raw bytes as a buffer view.
    pub fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    /// Appends an accessor over `bytes` (tightly packed elements of `type_`/`component`).
    #[allow(clippy::too_many_arguments, reason = "mirrors the accessor's fields")]
    pub fn accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        type_: json::accessor::Type,
        component: json::accessor::ComponentType,
        target: Option<json::buffer::Target>,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
        normalized: bool,
    ) -> json::Index<json::Accessor> {
        let view = self.view(bytes, target);
        let (min, max) = match min_max {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized,
            sparse: None,
        })
    }

    /// A VEC3 float accessor; `min_max` writes per-axis bounds (required for POSITION).
    pub fn vec3(
        &mut self,
        data: &[Vec3],
        target: Option<json::buffer::Target>,
        min_max: bool,
    ) -> json::Index<json::Accessor> {
        let bounds = min_max.then(|| bounds_f32(data.iter().map(|v| v.to_array())));
        let bytes = f32_bytes(data.iter().flat_map(|v| v.to_array()));
        self.accessor(
            &bytes,
            data.len(),
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            target,
            bounds,
            false,
        )
    }

    /// A VEC3 float accessor stored sparsely: no buffer view (zeros) plus the values of `data`
    /// at `changed` (strictly increasing vertex indices, at least one). `min_max` writes bounds of
    /// the effective values, implicit zeros included. The index and value views carry no target
    /// and no stride, as the specification requires.
    ///
    /// # Panics
    /// When `changed` is empty (glTF requires at least one sparse entry).
    pub fn sparse_vec3(
        &mut self,
        data: &[Vec3],
        changed: &[u32],
        min_max: bool,
    ) -> json::Index<json::Accessor> {
        let bounds = min_max.then(|| bounds_f32(data.iter().map(|v| v.to_array())));
        let (min, max) = match bounds {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        let values = f32_bytes(changed.iter().flat_map(|&i| data[i as usize].to_array()));
        self.sparse_accessor(
            data.len(),
            changed,
            &values,
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            false,
            (min, max),
        )
    }

    /// An accessor of `count` elements stored sparsely: no buffer view (zeros) plus `values`
    /// (tightly packed elements of `type_`/`component`, one per entry of `changed`, strictly
    /// increasing indices, at least one). The index and value views carry no target and no
    /// stride, as the specification requires; indices are u16 when they fit.
    ///
    /// # Panics
    /// When `changed` is empty (glTF requires at least one sparse entry).
    #[allow(clippy::too_many_arguments, reason = "mirrors the accessor's fields")]
    pub fn sparse_accessor(
        &mut self,
        count: usize,
        changed: &[u32],
        values: &[u8],
        type_: json::accessor::Type,
        component: json::accessor::ComponentType,
        normalized: bool,
        (min, max): (Option<json::Value>, Option<json::Value>),
    ) -> json::Index<json::Accessor> {
        assert!(
            !changed.is_empty(),
            "a sparse accessor lists at least one entry"
        );
        let max_index = changed.iter().copied().max().unwrap_or(0);
        let (index_bytes, index_type) = if max_index <= u16::MAX as u32 {
            (
                changed
                    .iter()
                    .flat_map(|&i| (i as u16).to_le_bytes())
                    .collect::<Vec<u8>>(),
                json::accessor::ComponentType::U16,
            )
        } else {
            (
                changed.iter().flat_map(|&i| i.to_le_bytes()).collect(),
                json::accessor::ComponentType::U32,
            )
        };
        let indices_view = self.view(&index_bytes, None);
        let values_view = self.view(values, None);
        self.root.push(json::Accessor {
            buffer_view: None,
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized,
            sparse: Some(json::accessor::sparse::Sparse {
                count: USize64::from(changed.len()),
                indices: json::accessor::sparse::Indices {
                    buffer_view: indices_view,
                    byte_offset: USize64(0),
                    component_type: Valid(json::accessor::IndexComponentType(index_type)),
                    extensions: None,
                    extras: Default::default(),
                },
                values: json::accessor::sparse::Values {
                    buffer_view: values_view,
                    byte_offset: USize64(0),
                    extensions: None,
                    extras: Default::default(),
                },
                extensions: None,
                extras: Default::default(),
            }),
        })
    }

    /// A VEC2 float accessor (texture coordinates).
    pub fn vec2(&mut self, data: &[[f32; 2]]) -> json::Index<json::Accessor> {
        let bytes = f32_bytes(data.iter().flatten().copied());
        self.accessor(
            &bytes,
            data.len(),
            json::accessor::Type::Vec2,
            json::accessor::ComponentType::F32,
            Some(json::buffer::Target::ArrayBuffer),
            None,
            false,
        )
    }

    /// A VEC4 float accessor (rotations, weights); `target` for vertex attributes.
    pub fn vec4(
        &mut self,
        data: &[[f32; 4]],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::Accessor> {
        let bytes = f32_bytes(data.iter().flatten().copied());
        self.accessor(
            &bytes,
            data.len(),
            json::accessor::Type::Vec4,
            json::accessor::ComponentType::F32,
            target,
            None,
            false,
        )
    }

    /// A SCALAR float accessor; animation inputs need `min_max`.
    pub fn scalars(&mut self, data: &[f32], min_max: bool) -> json::Index<json::Accessor> {
        let bounds = min_max.then(|| bounds_f32(data.iter().map(|v| [*v])));
        self.accessor(
            &f32_bytes(data.iter().copied()),
            data.len(),
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::F32,
            None,
            bounds,
            false,
        )
    }

    /// A MAT4 float accessor (inverse bind matrices, column-major).
    pub fn mat4(&mut self, data: &[[f32; 16]]) -> json::Index<json::Accessor> {
        let bytes = f32_bytes(data.iter().flatten().copied());
        self.accessor(
            &bytes,
            data.len(),
            json::accessor::Type::Mat4,
            json::accessor::ComponentType::F32,
            None,
            None,
            false,
        )
    }

    /// Triangle indices, as u16 when they fit, else u32.
    pub fn indices(&mut self, data: &[u32]) -> json::Index<json::Accessor> {
        let max = data.iter().copied().max().unwrap_or(0);
        let target = Some(json::buffer::Target::ElementArrayBuffer);
        if max < u16::MAX as u32 {
            let bytes: Vec<u8> = data
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect();
            self.accessor(
                &bytes,
                data.len(),
                json::accessor::Type::Scalar,
                json::accessor::ComponentType::U16,
                target,
                None,
                false,
            )
        } else {
            let bytes: Vec<u8> = data.iter().flat_map(|&i| i.to_le_bytes()).collect();
            self.accessor(
                &bytes,
                data.len(),
                json::accessor::Type::Scalar,
                json::accessor::ComponentType::U32,
                target,
                None,
                false,
            )
        }
    }

    /// Writes the document: a `.glb` (one file) or a `.gltf` with `<stem>.bin` beside it, chosen
    /// by `path`'s extension. Files are written to temporaries in the target folder and renamed
    /// into place only when complete.
    ///
    /// # Errors
    /// [`Error::Export`] for an unknown extension or an oversized GLB; [`Error::Io`] when writing
    /// fails (any earlier file at `path` is then left untouched).
    pub fn write(self, path: &Path) -> Result<Written> {
        Written::write_all(self.encode(path)?)
    }

    /// The files [`GltfBuilder::write`] would write, as (path, bytes) pairs in rename order, so
    /// that callers can write them atomically together with other files.
    ///
    /// # Errors
    /// [`Error::Export`] for an unknown extension or an oversized GLB; [`Error::Json`].
    pub fn encode(mut self, path: &Path) -> Result<Vec<(PathBuf, Vec<u8>)>> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let glb = match ext.as_deref() {
            Some("glb") => true,
            Some("gltf") => false,
            _ => {
                return Err(Error::Export {
                    path: path.into(),
                    message: "output must end in .glb or .gltf".into(),
                })
            }
        };
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let bin_name = format!(
            "{}.bin",
            path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene")
        );
        if !self.bin.is_empty() {
            self.root.buffers = vec![json::Buffer {
                byte_length: USize64::from(self.bin.len()),
                name: None,
                uri: (!glb).then(|| bin_name.clone()),
                extensions: None,
                extras: Default::default(),
            }];
        }
        let json_bytes = json::serialize::to_vec(&self.root).map_err(|error| Error::Json {
            path: path.into(),
            source: error,
        })?;
        let files: Vec<(PathBuf, Vec<u8>)> = if glb {
            if json_bytes.len() + self.bin.len() + 28 > u32::MAX as usize {
                return Err(Error::Export {
                    path: path.into(),
                    message: "larger than the 4 GiB a GLB can hold; write .gltf instead".into(),
                });
            }
            let glb = gltf::binary::Glb {
                header: gltf::binary::Header {
                    magic: *b"glTF",
                    version: 2,
                    length: 0,
                },
                json: json_bytes.into(),
                bin: (!self.bin.is_empty()).then(|| self.bin.into()),
            };
            let bytes = glb.to_vec().map_err(|e| Error::Export {
                path: path.into(),
                message: e.to_string().into(),
            })?;
            vec![(path.to_path_buf(), bytes)]
        } else {
            // The .bin first: the .gltf that refers to it is renamed into place last.
            let bin_path = path.with_file_name(&bin_name);
            let mut files = Vec::new();
            if !self.bin.is_empty() {
                files.push((bin_path, self.bin));
            }
            files.push((path.to_path_buf(), json_bytes));
            files
        };
        Ok(files)
    }
}

/// An animation channel: sampler `sampler` (its index within the animation) drives `path` of
/// `node`.
pub fn channel(
    sampler: usize,
    node: json::Index<json::Node>,
    path: json::animation::Property,
) -> json::animation::Channel {
    json::animation::Channel {
        sampler: json::Index::new(sampler as u32),
        target: json::animation::Target {
            node,
            path: Valid(path),
            extensions: None,
            extras: Default::default(),
        },
        extensions: None,
        extras: Default::default(),
    }
}

/// An animation sampler from key times `input` to values `output`.
pub fn sampler(
    input: json::Index<json::Accessor>,
    output: json::Index<json::Accessor>,
    interpolation: json::animation::Interpolation,
) -> json::animation::Sampler {
    json::animation::Sampler {
        input,
        output,
        interpolation: Valid(interpolation),
        extensions: None,
        extras: Default::default(),
    }
}

/// A primitive without morph targets (add them with struct update syntax).
pub fn primitive(
    attributes: BTreeMap<
        json::validation::Checked<json::mesh::Semantic>,
        json::Index<json::Accessor>,
    >,
    indices: Option<json::Index<json::Accessor>>,
    material: json::Index<json::Material>,
    mode: json::mesh::Mode,
) -> json::mesh::Primitive {
    json::mesh::Primitive {
        attributes,
        indices,
        material: Some(material),
        mode: Valid(mode),
        targets: None,
        extensions: None,
        extras: Default::default(),
    }
}

/// Little-endian bytes of a float sequence.
pub fn f32_bytes(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// Per-component (min, max) of a sequence of N-vectors, as written in accessors.
pub fn bounds_f32<const N: usize>(values: impl Iterator<Item = [f32; N]>) -> (Vec<f32>, Vec<f32>) {
    let mut lo = [f32::INFINITY; N];
    let mut hi = [f32::NEG_INFINITY; N];
    let mut any = false;
    for v in values {
        any = true;
        for i in 0..N {
            lo[i] = lo[i].min(v[i]);
            hi[i] = hi[i].max(v[i]);
        }
    }
    if !any {
        return (vec![0.0; N], vec![0.0; N]);
    }
    (lo.to_vec(), hi.to_vec())
}
