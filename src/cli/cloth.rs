//! `scenebake cloth`: the library's [`ClothJob`] as command-line options.

use clap::Args;
use scenebake::bake::ClothJob;

/// Simulate a cloth or soft body and write it as a morph-target glTF.
#[derive(Debug, Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:\n  scenebake cloth meshes/plane_30x30.obj -o exports/plane.glb --frames 120 --pin box:-1,-1,-1,1,1,-0.49\n  scenebake cloth --preset lab-cloth -o exports/lab_cloth.glb"
)]
pub struct ClothArgs {
    /// Every parameter of the bake (see `scenebake::bake::cloth::config`).
    #[command(flatten)]
    pub job: ClothJob,
}
