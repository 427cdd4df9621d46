//! The integration tests, one module per topic, built as one test binary: as 33 binaries, each
//! linking the library, they took over half of a cold `cargo test --release` to build
//! (CHANGELOG.md, 2026-12-07 (3)).
//! Each module drives the public API or the `scenebake` binary and checks the result against
//! an independent expectation (see [`common`]).

mod common;

mod character;
mod cli;
mod cli_traps;
mod cli_vat;
mod cli_view;
mod cloth_basis;
mod cloth_body_sequence;
mod cloth_compact;
mod cloth_contact;
mod cloth_export;
mod cloth_material;
mod cloth_meshopt;
mod cloth_physics;
mod cloth_pointcache;
mod cloth_quality;
mod cloth_self_contact;
mod cloth_solvers;
mod cloth_usd;
mod cloth_vat;
mod corpus;
mod fuzz_loaders;
mod ik_board;
mod ik_fonts;
mod ik_humanoid;
mod ik_joints;
mod ik_lab_arm;
mod ik_paths;
mod ik_pen;
mod ik_rig;
mod ik_trail;
mod ik_validator;
mod static_meshes;
mod svg;
