//! `scenebake ik`: the library's [`IkJob`] as command-line options.

use clap::Args;
use scenebake::bake::IkJob;

/// Bake an inverse-kinematics animation: a joint chain whose tip follows a curve, text or drawing.
#[derive(Debug, Args)]
#[command(
    allow_negative_numbers = true,
    after_help = "Examples:\n  scenebake ik --preset lab-arm --curve circle --solver fabrik -o exports/circle.glb\n  scenebake ik --preset lab-arm --text \"hello\" --font script -o exports/hello.glb --report hello.json\n  scenebake ik --rig meshes/Fox.glb --chain b_Spine01_02..b_Head_05 --curve heart -o exports/fox.glb"
)]
pub struct IkArgs {
    /// Every parameter of the bake (see `scenebake::bake::ik`).
    #[command(flatten)]
    pub job: IkJob,
}
