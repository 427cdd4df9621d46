//! The size of a morph-target cache, estimated before baking, so an absurd `--frames` is refused
//! before any memory is spent on it.
//!
//! A bake holds every frame's positions and normals per render vertex in memory (24 bytes per
//! vertex per frame) and writes them as dense morph targets at most (the same 24 bytes, plus
//! the base). A GLB cannot exceed 4 GiB (its length field is 32 bits), and nothing that large
//! plays in a viewer, so larger estimates are errors; above [`WARN_BYTES`] the bake runs and
//! warns.

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

/// How the cache of a bake compares with what a GLB holds (see [`cache_size`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CacheSize {
    /// Within [`WARN_BYTES`].
    Fits,
    /// Over [`WARN_BYTES`], within [`LIMIT_BYTES`]: the bake runs, with a warning.
    Large {
        /// The estimated bytes.
        bytes: u128,
    },
    /// Over [`LIMIT_BYTES`]: refused.
    TooLarge {
        /// The estimated bytes.
        bytes: u128,
        /// The most frames after the initial state that fit.
        most_frames: u128,
    },
}

/// The size of a cloth bake of `frames` frames after the initial state over `vertices` render
/// vertices, with NORMAL deltas when `normals`.
pub fn cache_size(frames: usize, vertices: usize, normals: bool) -> CacheSize {
    let bytes = morph_bytes(vertices, frames.saturating_add(1), normals);
    if bytes > u128::from(LIMIT_BYTES) {
        let most = u128::from(LIMIT_BYTES) / morph_bytes(vertices.max(1), 1, normals);
        CacheSize::TooLarge {
            bytes,
            most_frames: most.saturating_sub(1),
        }
    } else if bytes > u128::from(WARN_BYTES) {
        CacheSize::Large { bytes }
    } else {
        CacheSize::Fits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limit_is_the_glb_length_field() {
        // 961 vertices with normals: 23,064 bytes a frame; 186,217 frames fit in 4 GiB.
        let fit = (u32::MAX as u64 / 23_064) as usize;
        assert!(!matches!(
            cache_size(fit - 1, 961, true),
            CacheSize::TooLarge { .. }
        ));
        assert!(matches!(
            cache_size(fit, 961, true),
            CacheSize::TooLarge { most_frames, .. } if most_frames == fit as u128 - 1
        ));
        assert!(matches!(
            cache_size(1_000_000_000, 961, true),
            CacheSize::TooLarge { .. }
        ));
        assert_eq!(cache_size(120, 961, true), CacheSize::Fits);
        assert!(matches!(
            cache_size(50_000, 961, true),
            CacheSize::Large { .. }
        ));
    }

    /// The trial run's trap: `--frames 20000` on an 8k-vertex skirt wrote gigabytes silently.
    /// 20,001 frames × 8,121 vertices × 24 bytes = 3,898,274,904 bytes: under the GLB limit, over
    /// the warning threshold (the job's warning: `crate::bake::cloth`).
    #[test]
    fn twenty_thousand_frames_of_a_skirt_are_large() {
        assert_eq!(morph_bytes(8121, 20_001, true), 3_898_274_904);
        assert_eq!(
            cache_size(20_000, 8121, true),
            CacheSize::Large {
                bytes: 3_898_274_904
            }
        );
    }

    #[test]
    fn sizes_read_in_decimal_units() {
        assert_eq!(human(999), "999 B");
        assert_eq!(human(23_064_000_000_000), "23.1 TB");
    }
}
