//! Whole jobs, from a typed config to written files and a returned report: [`cloth`] and
//! [`ik`]. Both configs deserialise from scene files ([`crate::scene`]) and, with the `cli`
//! feature, derive the `scenebake` command line.

pub mod cloth;
pub mod ik;

pub use cloth::{bake_cloth, ClothJob, ClothReport, ClothSource};
pub use ik::{bake_ik, IkJob, IkReport};
