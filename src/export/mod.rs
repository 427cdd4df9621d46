//! Writers for output files.

pub mod atomic;
pub mod basis;
pub mod character;
pub mod compact;
pub mod estimate;
pub mod frames;
pub mod gltf_doc;
pub mod meshopt;
pub mod morph;
pub mod playback;
pub mod pointcache;
pub mod shading;
pub mod skin;
pub mod statics;
pub mod tube;
pub mod usd;
pub mod vat;

pub use basis::{BasisOptions, BasisSize, BasisStats, QuantizeMode};
pub use compact::SparseMode;
pub use frames::RenderFrames;
pub use gltf_doc::{GltfBuilder, Written};
pub use meshopt::Compression;
pub use morph::{write_morph_gltf, AnimatedBody, CacheStats, Interpolation, MorphOptions};
pub use statics::StaticMesh;
pub use vat::{VatMode, VatOptions};
