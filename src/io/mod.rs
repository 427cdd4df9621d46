//! Readers for input files.

pub mod collider;
pub mod drawing;
pub mod gltf_import;
pub mod gltf_mesh;
pub mod obj;
pub mod rig;
pub mod sequence;
pub mod skin_weights;
pub mod tet;
