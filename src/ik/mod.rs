//! Inverse kinematics: joint chains, forward kinematics, the CCD and FABRIK solvers, chains
//! loaded from rigged glTF files, and the bake that turns a target path into an animation.

pub mod bake;
pub mod ccd;
pub mod chain;
pub mod fabrik;
pub mod rig;
pub mod solver;

pub use bake::{bake_ik, IkJob, IkReport, SolverKind};
pub use ccd::Ccd;
pub use chain::{Chain, Joint, Pose};
pub use fabrik::Fabrik;
pub use solver::{IkSolver, SolveReport, SolverConfig};
