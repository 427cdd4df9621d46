//! Writers for output files.

pub mod atomic;
pub mod gltf_doc;
pub mod morph;
pub mod skin;

pub use gltf_doc::{GltfBuilder, Written};
pub use morph::{write_morph_gltf, Interpolation, MorphOptions};
