//! Whole jobs, from a typed config to written files and a returned report: [`cloth`] and
//! [`ik`]; [`outputs`] lists the files a job writes and checks them before it starts. Both configs deserialise from scene files ([`crate::scene`]) and, with the `cli`
//! feature, derive the `scenebake` command line.

pub mod cloth;
pub mod ik;
pub mod outputs;

pub use cloth::{bake_cloth, ClothJob, ClothReport, ClothSource};
pub use ik::{bake_ik, IkJob, IkReport};
