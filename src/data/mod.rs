//! The data that flows from solvers to writers, owned by neither: frame caches of simulated
//! positions, static meshes (colliders), and joint chains with their poses. `cloth` and `ik`
//! produce them, `export` writes them; neither side imports the other.

pub mod animation;
pub mod chain;
pub mod frames;
pub mod sequence;
pub mod statics;

pub use chain::{Chain, Joint, Pose};
pub use frames::FrameCache;
pub use sequence::MeshSequence;
pub use statics::StaticMesh;

/// Name of the glTF quantisation extension, which the basis writer uses and the readers accept.
pub const KHR_MESH_QUANTIZATION: &str = "KHR_mesh_quantization";
