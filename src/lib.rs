//! scenebake: bake cloth simulations and inverse-kinematics animations offline into glTF 2.0
//! files that play back in Blender and game engines.
//!
//! Data flows one way: load ([`io`]) → model ([`mesh`], [`cloth`]) → solve → cache → write
//! ([`export`]). Units are SI (metres, seconds, kilograms); glTF's frame is +Y up, right-handed.
#![warn(missing_docs)]

pub mod bake;
pub mod cloth;
pub mod data;
pub mod error;
pub mod export;
pub mod ik;
pub mod inspect;
pub mod io;
pub mod mesh;
pub mod param;
pub mod path;
pub mod scene;
pub mod spec;

pub use error::{Error, Result};
pub use glam;
pub use param::{Param, Text};
