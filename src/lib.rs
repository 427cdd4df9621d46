//! scenebake: bake cloth simulations and inverse-kinematics animations offline into glTF 2.0
//! files that play back in Blender and game engines.
//!
//! Data flows one way:
//!
//! ```text
//!  scene / config ──► io (load) ──► mesh, cloth, ik (model, solve) ──► data ──► export (write) ──► report
//!  scene.rs, bake    obj, tet,      springs, materials, Newton,         frame     glTF morph/basis,
//!  (ClothJob, IkJob) glTF, rigs     local/global, FABRIK, CCD, paths    caches,   skins, VAT, statics
//!                                                                        chains
//! ```
//!
//! - [`bake`] holds the jobs: typed configs ([`ClothJob`], [`IkJob`]) with their defaults, run
//!   into returned reports; [`scene`] reads scene files into them.
//! - [`data`] is what solvers produce and writers consume ([`FrameCache`], [`StaticMesh`],
//!   [`data::Chain`] and its poses); `export` imports neither `cloth` nor `ik`, and neither of them
//!   imports `export`.
//! - Errors ([`Error`]) name the file, element and [`Param`]eter; a front end words them with
//!   [`Error::render`]. Only the job layer ([`bake`], [`scene`], the binary) speaks [`Param`]:
//!   the layers below report a bad value as [`Error::Value`] (or an error of their own kind) and
//!   the job, which knows where the value came from, names it ([`Error::for_param`]).
//!
//! Units are SI (metres, seconds, kilograms); glTF's frame is +Y up, right-handed.
#![warn(missing_docs)]
// Printing is the binary's job.
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod bake;
pub mod cloth;
pub mod cores;
pub mod data;
pub mod error;
pub mod export;
pub mod ik;
pub mod inspect;
pub mod io;
pub mod measure;
pub mod mesh;
pub mod param;
pub mod path;
pub mod scene;
pub mod spec;

pub use bake::{bake_cloth, bake_ik, ClothJob, ClothReport, IkJob, IkReport};
pub use data::{FrameCache, StaticMesh};
pub use error::{Error, Result};
pub use glam;
pub use param::{Param, Text};
pub use scene::Scene;
