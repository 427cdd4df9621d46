//! Point caches (`--pc2 FILE`, `--mdd FILE`): every frame's vertex positions in the input's
//! vertex order, for Blender's Mesh Cache modifier (and 3ds Max, LightWave, Houdini...) on the
//! user's own mesh.
//!
//! One point per particle, in the input's order: an OBJ's positions that a face uses (with
//! `--object`, that object's faces), in file order, which is the mesh Blender's OBJ importer
//! makes (it leaves unused positions out too); a `.tet`'s nodes; the lab-cloth grid's particles;
//! a glTF input's distinct positions (its vertices split at seams count once). Positions are the
//! bake's: metres, +Y up, after `--up`, `--scale` and `--translate` (as the glTF's); one sample
//! per frame, frame 0 the initial state.
//!
//! - PC2 (little-endian): the 12 bytes `POINTCACHE2\0`, int32 version 1, int32 points, float32
//!   start frame (the glTF's first key time × fps: 0 for a cloth bake), float32 sample rate 1
//!   (frames per sample), int32 samples, then float32 x, y, z per point per sample.
//! - MDD (big-endian): int32 frames, int32 points, float32 time in seconds of each frame (the
//!   glTF's key times: start + k / fps), then float32 x, y, z per point per frame.
//!
//! Blender's Mesh Cache modifier in its default Frame time mode shows sample `f - frame_start`
//! at scene frame `f`, linearly interpolated between samples, whatever the scene's fps.

use std::path::{Path, PathBuf};

use crate::data::FrameCache;
use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// Which point-cache format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PointCacheFormat {
    /// 3ds Max's Point Cache 2, little-endian.
    Pc2,
    /// LightWave's MDD, big-endian.
    Mdd,
}

/// The timing of a cache.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointCacheOptions {
    /// Frames per second: frame k is at `start_time + k / fps` seconds.
    pub fps: f64,
    /// Time of frame 0 in seconds (the glTF's first key).
    pub start_time: f64,
}

/// A point cache encoded but not written.
#[derive(Debug, Clone)]
pub struct EncodedPointCache {
    /// The file.
    pub path: PathBuf,
    /// Its bytes.
    pub bytes: Vec<u8>,
    /// Points per frame.
    pub points: usize,
    /// Frames (samples), frame 0 included.
    pub frames: usize,
}

/// Encodes `cache` (every frame of `mesh`'s particles, frame 0 the initial state) as a point
/// cache for `path`, without writing it.
///
/// # Errors
/// [`Error::Export`] naming `path` when the cache does not fit the mesh or holds more points or
/// frames than the format's 32-bit counts.
pub fn encode_point_cache(
    format: PointCacheFormat,
    path: &Path,
    mesh: &Mesh,
    cache: &FrameCache,
    options: &PointCacheOptions,
) -> Result<EncodedPointCache> {
    let export_error = |message: String| Error::Export {
        path: path.into(),
        message: message.into(),
    };
    if cache.particle_count() != mesh.particle_count() || cache.frame_count() == 0 {
        return Err(export_error(format!(
            "cache of {} frames × {} particles does not fit a mesh of {} particles",
            cache.frame_count(),
            cache.particle_count(),
            mesh.particle_count()
        )));
    }
    let (points, frames) = (cache.particle_count(), cache.frame_count());
    let count = |what: &str, n: usize| {
        i32::try_from(n).map_err(|_| {
            export_error(format!(
                "{n} {what}: more than a point cache's 32-bit count holds"
            ))
        })
    };
    let (points_i32, frames_i32) = (count("points", points)?, count("frames", frames)?);
    let header = match format {
        PointCacheFormat::Pc2 => 32,
        PointCacheFormat::Mdd => 8 + 4 * frames,
    };
    let mut bytes = Vec::with_capacity(header + 12 * points * frames);
    let put = |bytes: &mut Vec<u8>, v: f32| match format {
        PointCacheFormat::Pc2 => bytes.extend_from_slice(&v.to_le_bytes()),
        PointCacheFormat::Mdd => bytes.extend_from_slice(&v.to_be_bytes()),
    };
    match format {
        PointCacheFormat::Pc2 => {
            bytes.extend_from_slice(b"POINTCACHE2\0");
            bytes.extend_from_slice(&1i32.to_le_bytes());
            bytes.extend_from_slice(&points_i32.to_le_bytes());
            bytes.extend_from_slice(&((options.start_time * options.fps) as f32).to_le_bytes());
            bytes.extend_from_slice(&1f32.to_le_bytes());
            bytes.extend_from_slice(&frames_i32.to_le_bytes());
        }
        PointCacheFormat::Mdd => {
            bytes.extend_from_slice(&frames_i32.to_be_bytes());
            bytes.extend_from_slice(&points_i32.to_be_bytes());
            for k in 0..frames {
                put(
                    &mut bytes,
                    (options.start_time + k as f64 / options.fps) as f32,
                );
            }
        }
    }
    for k in 0..frames {
        for c in cache.frame(k).iter().flat_map(|p| p.to_array()) {
            put(&mut bytes, c);
        }
    }
    Ok(EncodedPointCache {
        path: path.to_path_buf(),
        bytes,
        points,
        frames,
    })
}

/// Checks before a bake that `path` names a file. Whether it can be written is checked with
/// every other output of the job (`crate::bake::outputs`).
///
/// # Errors
/// [`Error::Value`] naming the path (the job names the option).
pub fn check_point_cache_path(path: &Path) -> Result<()> {
    let refuse = |what: String| Err(Error::value(what));
    if path.as_os_str().is_empty() {
        return refuse("an empty path: give the cache's file name".into());
    }
    if path.file_name().is_none() {
        return refuse(format!(
            "{} names a directory: give the cache's file name",
            path.display()
        ));
    }
    Ok(())
}
