//! The bake's frame rate and frame range, written into the glTF's `asset.extras`.
//!
//! glTF keys time in seconds and has no frame rate; importers place keys with their own scene's
//! rate (Blender: 24 fps and frames 1–250 in a new file). Every scenebake export records what was
//! baked so a helper (`scripts/blender/scenebake_import.py`, `scenebake open`) can set the scene
//! up:
//!
//! ```json
//! "asset": { "extras": { "scenebake": {
//!     "fps": 30.0, "frame_start": 0, "frame_end": 120, "animation": "plane" } } }
//! ```
//!
//! Frame f is at time f / fps seconds; `frame_start` and `frame_end` are the first and last baked
//! frames (inclusive); `animation` names the glTF animation that plays the bake (the first one).

use gltf_json as json;
use serde::{Deserialize, Serialize};

/// The key under `asset.extras`.
pub const EXTRAS_KEY: &str = "scenebake";

/// Frame rate and range of a bake.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Playback {
    /// Frames per second.
    pub fps: f64,
    /// First baked frame (at time frame_start / fps).
    pub frame_start: usize,
    /// Last baked frame, inclusive.
    pub frame_end: usize,
    /// Name of the glTF animation that plays the bake.
    pub animation: String,
}

impl Playback {
    /// `frames` frames (the initial state included) from frame 0, at `fps`.
    pub fn frames(fps: f64, frames: usize, animation: &str) -> Self {
        Playback {
            fps,
            frame_start: 0,
            frame_end: frames.saturating_sub(1),
            animation: animation.into(),
        }
    }

    /// Reads the record from a document's `asset.extras`, when there is one.
    pub fn read(root: &json::Root) -> Option<Self> {
        let extras = root.asset.extras.as_ref()?;
        let value: serde_json::Value = serde_json::from_str(extras.get()).ok()?;
        serde_json::from_value(value.get(EXTRAS_KEY)?.clone()).ok()
    }
}

/// Writes `playback` under `asset.extras.scenebake`, keeping any other keys the asset's extras
/// already hold (a rig's own extras survive; a previous bake's record is replaced).
pub fn stamp(root: &mut json::Root, playback: &Playback) {
    let mut extras = root
        .asset
        .extras
        .as_ref()
        .and_then(|e| serde_json::from_str::<serde_json::Value>(e.get()).ok())
        .filter(serde_json::Value::is_object)
        .unwrap_or_else(|| serde_json::json!({}));
    extras[EXTRAS_KEY] = serde_json::to_value(playback).expect("plain numbers and a string");
    root.asset.extras =
        Some(serde_json::value::to_raw_value(&extras).expect("a JSON object serialises"));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamp_keeps_other_extras_and_reads_back() {
        let mut root = json::Root::default();
        root.asset.extras =
            Some(serde_json::value::to_raw_value(&serde_json::json!({"author": "x"})).unwrap());
        let p = Playback::frames(60.0, 121, "lab_cloth");
        stamp(&mut root, &p);
        assert_eq!(Playback::read(&root), Some(p.clone()));
        let v: serde_json::Value =
            serde_json::from_str(root.asset.extras.as_ref().unwrap().get()).unwrap();
        assert_eq!(v["author"], "x");
        assert_eq!(v["scenebake"]["frame_end"], 120);
        assert_eq!(v["scenebake"]["fps"], 60.0);
    }
}
