//! Test support shared by the integration tests (each test module reaches it as `crate::common`).
//!
//! Everything here is an independent expectation, never scenebake's own code under test:
//! - [`fk`]: node animations reloaded with the `gltf` crate and posed by our own sampler and
//!   4×4 matrices (the IK tests' forward kinematics);
//! - [`morph`]: morph-target files reloaded with the `gltf` crate, and the reference simulation
//!   run without any writer;
//! - [`geometry`]: analytic signed distances to planes, spheres and boxes, and a brute-force
//!   point–triangle distance with a winding-number inside test for meshes;
//! - [`gltf_read`]: a glTF's buffers read by the specification (the `gltf` crate parses);
//! - [`crossing`]: crossing triangle pairs by an exact test of every pair;
//! - [`cli`]: running the binary, signalling it, and listing what it left in a folder;
//! - [`strain`]: the largest stretch and compression of a bake's edges, from its frames.
#![allow(dead_code, reason = "each test file uses a subset")]

pub mod cli;
pub mod crossing;
pub mod fk;
pub mod geometry;
pub mod gltf_read;
pub mod morph;
pub mod strain;

use std::path::{Path, PathBuf};

use glam::DVec3;

#[allow(unused_imports, reason = "each test file uses a subset")]
pub use fk::{load, sample_quat, sample_vec3, Loaded, Tracks, Vec3Track};

/// Root of the crate.
pub fn crate_dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A file of `meshes/`.
pub fn mesh_path(name: &str) -> PathBuf {
    crate_dir().join("meshes").join(name)
}

/// A file of `tests/fixtures/`.
pub fn fixture(name: &str) -> PathBuf {
    crate_dir().join("tests/fixtures").join(name)
}

/// The cache test sheet hanging from RiggedSimple's upper bone (pins bound to `Bone.001`, no
/// body collider), written to `output`: the small character bake of the cache tests.
pub fn rigged_sheet(output: PathBuf) -> scenebake::bake::cloth::ClothJob {
    use scenebake::bake::cloth::{ClothJob, Switch};
    ClothJob {
        input: Some(fixture("cache_sheet.obj")),
        output,
        rig: Some(mesh_path("RiggedSimple.gltf")),
        pin_to: Some("Bone.001".into()),
        body_collider: Switch::Off,
        translate: Some(DVec3::new(3.0, 3.0, 0.0)),
        pin: vec!["box:-10,3.9,-10,10,4.1,10".parse().unwrap()],
        ..ClothJob::default()
    }
}

/// Reads a report JSON as a generic value.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// A JSON array of counts.
pub fn counts_of(v: &serde_json::Value) -> Vec<usize> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_u64().unwrap() as usize)
        .collect()
}

/// A JSON `[x, y, z]` array.
pub fn vec3_of(v: &serde_json::Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

/// The names in `dir`, sorted (to check that a failed or interrupted write left nothing behind).
pub fn names_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Writes `dir/NAME.obj`: a 0.4 m square sheet, 9 × 9 vertices, centred on the y axis, for each
/// `(height, [dx, dz])` of `layers`, one above the other, each at that height (m) and shifted
/// by that offset in x and z (m).
pub fn write_layers(dir: &Path, name: &str, layers: &[(f64, [f64; 2])]) -> PathBuf {
    let n = 9;
    let mut s = String::new();
    for &(y, [dx, dz]) in layers {
        for j in 0..n {
            for i in 0..n {
                let (x, z) = (
                    -0.2 + 0.4 * i as f64 / (n - 1) as f64 + dx,
                    -0.2 + 0.4 * j as f64 / (n - 1) as f64 + dz,
                );
                s += &format!("v {x} {y} {z}\n");
            }
        }
    }
    for layer in 0..layers.len() {
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = layer * n * n + j * n + i + 1;
                s += &format!(
                    "f {a} {} {}\nf {a} {} {}\n",
                    a + n,
                    a + n + 1,
                    a + n + 1,
                    a + 1
                );
            }
        }
    }
    let path = dir.join(format!("{name}.obj"));
    std::fs::write(&path, s).unwrap();
    path
}
