//! Whole jobs, from options to written files and reports.

pub mod cloth;

pub use cloth::{bake_cloth, ClothJob, ClothReport, ClothSource};
