//! Inverse kinematics: joint chains, forward kinematics, the CCD and FABRIK solvers, chains
//! loaded from rigged glTF files, and the bake that turns a target path into an animation.
//!
//! Pipeline of [`crate::bake::bake_ik`]: build a [`Chain`] (the lab arm, a straight chain, or a `ROOT..TIP`
//! path in a rig via [`crate::io::rig::RigDocument`]) → place the target path on a drawing plane
//! ([`crate::path`]) and resample it to one target per frame → solve every frame with an
//! [`IkSolver`] under the job's [`Constraints`] (pole, joint limits), warm-started from the
//! previous frame → write the glTF
//! (the bake hands them to `export::skin`) and the [`crate::bake::IkReport`].
//!
//! Conventions: world coordinates are glTF's (+Y up, right-handed, scene units); rotations are
//! unit quaternions (x, y, z, w) local to the joint's parent frame; a chain's base frame carries
//! everything above the chain root (rig parents, node matrices, scales).
//!
//! ```
//! use scenebake::glam::DVec3;
//! use scenebake::ik::{Chain, Fabrik, IkSolver};
//! let arm = Chain::lab_arm();
//! let mut pose = arm.rest_pose();
//! let report = Fabrik::default().solve(&arm, &mut pose, DVec3::new(0.6, 0.0, 0.0)).unwrap();
//! assert!(report.reached && pose.tip().distance(DVec3::new(0.6, 0.0, 0.0)) <= 1e-4);
//! ```

pub mod ccd;
pub use crate::data::chain;
pub mod constraints;
pub mod fabrik;
pub mod solver;

pub use ccd::Ccd;
pub use chain::{Chain, Joint, Pose};
pub use constraints::{Constraints, Limit, TipAxis};
pub use fabrik::Fabrik;
pub use solver::{IkSolver, SolveReport, SolverConfig, SolverKind};
