//! The size of a morph-target cache, estimated before baking, so an absurd `--frames` is refused
//! before any memory is spent on it.
//!
//! A bake holds every frame's positions and normals per render vertex in memory (24 bytes per
//! vertex per frame) and writes them as dense morph targets at most (the same 24 bytes, plus
//! the base). A GLB cannot exceed 4 GiB (its length field is 32 bits), and nothing that large
//! plays in a viewer, so larger estimates are errors; above [`WARN_BYTES`] the bake runs and
//! warns.

use crate::error::{Error, Result};
use crate::param::Param;
use crate::param::Text;
use crate::text;

/// Largest output accepted: a GLB's 32-bit length.
pub const LIMIT_BYTES: u64 = u32::MAX as u64;

/// Above this the bake warns that the output is large.
pub const WARN_BYTES: u64 = 1 << 30;

/// Bytes of a dense morph cache: the base and `frames - 1` targets over `vertices` render
/// vertices, POSITION (and NORMAL when `normals`) as 12-byte vectors.
pub fn morph_bytes(vertices: usize, frames: usize, normals: bool) -> u128 {
    let per_vertex = if normals { 24u128 } else { 12 };
    per_vertex * vertices as u128 * frames as u128
}

/// `1.2 GB`-style size (decimal units).
pub fn human(bytes: u128) -> String {
    const UNITS: [&str; 6] = ["B", "KB", "MB", "GB", "TB", "PB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < UNITS.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Checks a cloth bake of `frames` frames after the initial state over `vertices` render
/// vertices: an error naming `--frames` when the cache would exceed [`LIMIT_BYTES`], a warning
/// (returned) above [`WARN_BYTES`].
///
/// # Errors
/// [`Error::InvalidOption`] naming `--frames`.
pub fn check_frames(frames: usize, vertices: usize, normals: bool) -> Result<Option<Text>> {
    let bytes = morph_bytes(vertices, frames.saturating_add(1), normals);
    if bytes > u128::from(LIMIT_BYTES) {
        let most = u128::from(LIMIT_BYTES) / morph_bytes(vertices.max(1), 1, normals);
        return Err(Error::param_value(
            Param::Frames,
            text!(
                format!(
                    "{frames}: {frames} frames of {vertices} vertices need about {} in memory and \
                     in the output, over the 4.3 GB a GLB can hold; at most {} frames fit (",
                    human(bytes),
                    most.saturating_sub(1)
                ),
                Param::KeyframeTolerance,
                " shrinks the file, not the bake)"
            ),
        ));
    }
    Ok((bytes > u128::from(WARN_BYTES)).then(|| {
        text!(
            format!(
                "the output will be about {} ({frames} frames of {vertices} vertices); ",
                human(bytes)
            ),
            Param::KeyframeTolerance,
            " can shrink it"
        )
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limit_is_the_glb_length_field() {
        // 961 vertices with normals: 23,064 bytes a frame; 186,217 frames fit in 4 GiB.
        let fit = (u32::MAX as u64 / 23_064) as usize;
        assert!(check_frames(fit - 1, 961, true).is_ok());
        let e = check_frames(fit, 961, true).unwrap_err().to_string();
        assert!(e.starts_with("invalid value for `frames`: "), "{e}");
        assert!(
            e.contains(&format!("at most {} frames fit", fit - 1)),
            "{e}"
        );
        assert!(check_frames(1_000_000_000, 961, true).is_err());
        assert_eq!(check_frames(120, 961, true).unwrap(), None);
        assert!(check_frames(50_000, 961, true).unwrap().is_some());
    }

    /// The trial run's trap: `--frames 20000` on an 8k-vertex skirt wrote gigabytes silently.
    /// 20,001 frames × 8,121 vertices × 24 bytes = 3,898,274,904 bytes: under the GLB limit, over
    /// the warning threshold.
    #[test]
    fn twenty_thousand_frames_of_a_skirt_warn_with_the_size() {
        assert_eq!(morph_bytes(8121, 20_001, true), 3_898_274_904);
        let warning = check_frames(20_000, 8121, true).unwrap().unwrap();
        assert_eq!(
            warning.render(&|p| format!("--{}", p.key().replace('_', "-"))),
            "the output will be about 3.9 GB (20000 frames of 8121 vertices); \
             --keyframe-tolerance can shrink it"
        );
    }

    #[test]
    fn sizes_read_in_decimal_units() {
        assert_eq!(human(999), "999 B");
        assert_eq!(human(23_064_000_000_000), "23.1 TB");
    }
}
