//! Vertex-animation textures (VAT): the baked frames as 32-bit float OpenEXR images for shaders
//! that move vertices by texture look-ups (`--vat FILE.exr`).
//!
//! Three files are written together, atomically:
//! - `FILE.exr`: RGB = object-space position x, y, z of each render vertex (`--vat-mode absolute`,
//!   the default), or its offset from the base mesh (frame 0) (`--vat-mode offset`). One row per
//!   frame 0..=N, row 0 (frame 0) at the top of the image; one column per render vertex in the
//!   exported glTF's vertex order.
//! - `FILE.normals.exr`: RGB = the unit vertex normal x, y, z in the same layout, absolute in
//!   both modes (skipped with `--normals off`).
//! - `FILE.json`: the layout ([`VatManifest`]).
//!
//! A mesh wider than `--vat-max-width` (default 8192) wraps: frame `f`, vertex `v` is at row
//! `f * rows_per_frame + v / width`, column `v % width`; the unused pixels of a frame's last row
//! are zero. Images are ZIP-compressed scan lines (lossless), written with the `exr` crate.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use exr::prelude::{Encoding, Image, SpecificChannels, WritableImage};
use glam::Vec3;

use super::frames::RenderFrames;
use crate::error::{Error, Result};

/// Default `--vat-max-width`: pixels per image row.
pub const DEFAULT_MAX_WIDTH: usize = 8192;

/// What the position image stores (`--vat-mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum VatMode {
    /// Object-space positions, scene units.
    #[default]
    Absolute,
    /// Positions minus the base mesh's (frame 0), scene units.
    Offset,
}

/// Options of the VAT export.
#[derive(Debug, Clone, PartialEq)]
pub struct VatOptions {
    /// `--vat-mode`.
    pub mode: VatMode,
    /// `--vat-max-width`: most pixels per row (at least 1, the job checks it; 0 is taken as 1).
    pub max_width: usize,
    /// Frames per second: frame f is at f / fps seconds.
    pub fps: f64,
    /// Time of frame 0 on the glTF's animation, seconds (frame f is keyed there at
    /// `start_time + f / fps`): 0, or the driving animation's first key for a bake on a
    /// character.
    pub start_time: f64,
    /// Write `FILE.normals.exr`.
    pub normals: bool,
    /// File name of the glTF whose vertex order the images follow.
    pub gltf: String,
}

/// Where each vertex of each frame sits in the images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct VatLayout {
    /// Image width in pixels: the vertex count, or the maximum width for wider meshes.
    pub width: usize,
    /// Image height in pixels: frames × rows per frame.
    pub height: usize,
    /// Rows per frame: ⌈vertices / width⌉.
    pub rows_per_frame: usize,
}

impl VatLayout {
    /// The layout of `frames` frames of `vertices` vertices with at most `max_width` pixels per
    /// row (`max_width` ≥ 1).
    pub fn new(vertices: usize, frames: usize, max_width: usize) -> Self {
        let width = vertices.clamp(1, max_width.max(1));
        let rows_per_frame = vertices.div_ceil(width).max(1);
        VatLayout {
            width,
            height: frames * rows_per_frame,
            rows_per_frame,
        }
    }

    /// The (row, column) of vertex `v` in frame `f`; row 0 is the top of the image.
    pub fn pixel(&self, frame: usize, vertex: usize) -> (usize, usize) {
        (
            frame * self.rows_per_frame + vertex / self.width,
            vertex % self.width,
        )
    }
}

/// Per-axis bounds of the stored values.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct VatBounds {
    /// Smallest x, y, z stored.
    pub min: [f32; 3],
    /// Largest x, y, z stored.
    pub max: [f32; 3],
}

/// The `FILE.json` written beside the images.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct VatManifest {
    /// Always `scenebake-vat`.
    pub format: &'static str,
    /// Version of this layout description.
    pub version: u32,
    /// Frames stored (0..=N, the initial state included).
    pub frames: usize,
    /// Frames per second: frame f plays at f / fps seconds.
    pub fps: f64,
    /// Where frame 0 sits on the glTF's animation, seconds: the glTF keys frame f at
    /// `start_time + f / fps` (0 but for a bake on a character whose animation starts later).
    pub start_time: f64,
    /// Render vertices per frame.
    pub vertex_count: usize,
    /// What RGB holds in the position image.
    pub mode: VatMode,
    /// Bounds of the stored positions (or offsets), scene units.
    pub bounds: VatBounds,
    /// Image size and rows per frame.
    pub layout: VatLayout,
    /// How to find a vertex.
    pub addressing: &'static str,
    /// The position image's file name.
    pub positions: String,
    /// The normal image's file name, when written.
    pub normals: Option<String>,
    /// The glTF whose vertex order the columns follow.
    pub gltf: String,
}

/// The VAT files encoded in memory.
#[derive(Debug, Clone)]
pub struct EncodedVat {
    /// (path, bytes): positions, normals (when written), then the JSON.
    pub files: Vec<(PathBuf, Vec<u8>)>,
    /// What the JSON says.
    pub manifest: VatManifest,
}

/// The normal image and JSON paths for position image `path`: `x.exr` → `x.normals.exr`,
/// `x.json`.
///
/// # Errors
/// [`Error::Value`] when `path` does not end in `.exr` (the job names `--vat`).
pub fn vat_paths(path: &Path) -> Result<(PathBuf, PathBuf)> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if ext.as_deref() != Some("exr") || path.file_stem().is_none_or(|s| s.is_empty()) {
        return Err(Error::value(format!(
            "{}: the vertex-animation texture must be a file ending in .exr",
            path.display()
        )));
    }
    Ok((
        path.with_extension("normals.exr"),
        path.with_extension("json"),
    ))
}

/// Encodes the VAT of `frames` for position image `path` without writing it.
///
/// # Errors
/// As [`vat_paths`]; [`Error::Export`] when the `exr` crate fails.
pub fn encode_vat(path: &Path, frames: &RenderFrames, options: &VatOptions) -> Result<EncodedVat> {
    let (normals_path, json_path) = vat_paths(path)?;
    let layout = VatLayout::new(
        frames.vertex_count(),
        frames.frame_count(),
        options.max_width,
    );
    let positions = stored_positions(frames, options.mode);
    let mut files = vec![(
        path.to_path_buf(),
        exr_bytes(path, &positions, frames.vertex_count(), layout)?,
    )];
    let normals_name = if options.normals {
        let normals: Vec<Vec3> = (0..frames.frame_count())
            .flat_map(|k| frames.normals(k).iter().copied())
            .collect();
        files.push((
            normals_path.clone(),
            exr_bytes(&normals_path, &normals, frames.vertex_count(), layout)?,
        ));
        Some(file_name(&normals_path))
    } else {
        None
    };
    let manifest = VatManifest {
        format: "scenebake-vat",
        version: 1,
        frames: frames.frame_count(),
        fps: options.fps,
        start_time: options.start_time,
        vertex_count: frames.vertex_count(),
        mode: options.mode,
        bounds: bounds(&positions),
        layout,
        addressing: "frame f, vertex v -> row f * rows_per_frame + v / width, column v % width; row 0 at the top",
        positions: file_name(path),
        normals: normals_name,
        gltf: options.gltf.clone(),
    };
    let json = serde_json::to_vec_pretty(&manifest).map_err(|error| Error::Json {
        path: json_path.clone(),
        source: error,
    })?;
    files.push((json_path, json));
    Ok(EncodedVat { files, manifest })
}

/// The values the position image stores, frame-major.
fn stored_positions(frames: &RenderFrames, mode: VatMode) -> Vec<Vec3> {
    let base = frames.positions(0);
    (0..frames.frame_count())
        .flat_map(|k| {
            frames
                .positions(k)
                .iter()
                .zip(base)
                .map(move |(p, b)| match mode {
                    VatMode::Absolute => *p,
                    VatMode::Offset => *p - *b,
                })
        })
        .collect()
}

/// A 32-bit float RGB EXR of `values` (frame-major, `vertices` per frame) laid out by `layout`.
fn exr_bytes(path: &Path, values: &[Vec3], vertices: usize, layout: VatLayout) -> Result<Vec<u8>> {
    let pixel = |pos: exr::math::Vec2<usize>| {
        let (column, row) = (pos.x(), pos.y());
        let (frame, row_in_frame) = (row / layout.rows_per_frame, row % layout.rows_per_frame);
        let vertex = row_in_frame * layout.width + column;
        let v = if vertex < vertices {
            values[frame * vertices + vertex]
        } else {
            Vec3::ZERO
        };
        (v.x, v.y, v.z)
    };
    let image = Image::from_encoded_channels(
        (layout.width, layout.height),
        Encoding::SMALL_LOSSLESS,
        SpecificChannels::rgb(pixel),
    );
    let mut bytes = Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| Error::Export {
            path: path.into(),
            message: format!("cannot encode the EXR image: {e}").into(),
        })?;
    Ok(bytes.into_inner())
}

/// Per-axis bounds; zeros when empty.
fn bounds(values: &[Vec3]) -> VatBounds {
    if values.is_empty() {
        return VatBounds {
            min: [0.0; 3],
            max: [0.0; 3],
        };
    }
    let (lo, hi) = values
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    VatBounds {
        min: lo.to_array(),
        max: hi.to_array(),
    }
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_wraps_wide_meshes() {
        let l = VatLayout::new(10, 3, 4);
        assert_eq!((l.width, l.rows_per_frame, l.height), (4, 3, 9));
        assert_eq!(l.pixel(0, 0), (0, 0));
        assert_eq!(l.pixel(0, 9), (2, 1));
        assert_eq!(l.pixel(2, 5), (7, 1));
        let narrow = VatLayout::new(10, 3, 8192);
        assert_eq!(
            (narrow.width, narrow.rows_per_frame, narrow.height),
            (10, 1, 3)
        );
        let exact = VatLayout::new(8, 2, 4);
        assert_eq!((exact.width, exact.rows_per_frame), (4, 2));
    }

    #[test]
    fn paths_need_exr() {
        let (n, j) = vat_paths(Path::new("out/cloth.exr")).unwrap();
        assert_eq!(n, Path::new("out/cloth.normals.exr"));
        assert_eq!(j, Path::new("out/cloth.json"));
        assert!(vat_paths(Path::new("out/CLOTH.EXR")).is_ok());
        for bad in ["cloth.png", "cloth", "out/.exr"] {
            let e = vat_paths(Path::new(bad)).unwrap_err();
            assert!(matches!(e, Error::Value { .. }), "{e}");
            assert!(e.to_string().contains(".exr"), "{e}");
        }
    }
}
