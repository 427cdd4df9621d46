//! Cost of a garment on an animated character against the same garment without it.
//!
//! ```text
//! cargo bench --bench character
//! SWEEPS=0 cargo bench --bench character     # Newton without its Gauss–Seidel sweeps
//! ```
//!
//! The Fox cape (`meshes/garments/fox_cape.obj`, 315 particles, 15 pinned) baked three ways in
//! one process, one after another, with the same pins, fabric, fps and frame count:
//! 1. on Fox's walk (`--rig`: pins ride the neck, the skinned body is a moving collider);
//! 2. on Fox's walk without the body collider (pins ride the neck; nothing to collide with);
//! 3. without the rig (pins fixed, no collider: the same garment swinging on its own).
//!
//! Prints one markdown row per case: frames, ms per frame, median and largest Newton iterations
//! per step, the share of steps within the tolerance.

use std::path::PathBuf;
use std::time::Instant;

use scenebake::bake::cloth::{bake_cloth, ClothJob, Switch};
use scenebake::cloth::collide::ContactModel;
use scenebake::cloth::pins::PinSpec;

fn path(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn main() {
    let dir =
        std::env::temp_dir().join(format!("scenebake-bench-character-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let pin: PinSpec = "box:-1,0.69,0.235,1,0.71,0.245".parse().unwrap();
    // SWEEPS=N overrides the default (10 without self-contact).
    let sweeps = std::env::var("SWEEPS").ok().and_then(|s| s.parse().ok());
    let on_fox = ClothJob {
        sweeps,
        input: Some(path("meshes/garments/fox_cape.obj")),
        output: dir.join("rig.glb"),
        rig: Some(path("meshes/Fox.glb")),
        animation: Some("Walk".into()),
        rig_scale: 0.01,
        max_iterations: Some(100),
        pin: vec![pin],
        ..ClothJob::default()
    };
    let first = bake_cloth(&on_fox, &mut |_, _| {}).unwrap();
    let frames = first.frames;
    let cases = [
        ("on Fox's walk, body collider", on_fox.clone()),
        (
            "on Fox's walk, body collider, constraint",
            ClothJob {
                contact: Some(ContactModel::Constraint),
                output: dir.join("constraint.glb"),
                ..on_fox.clone()
            },
        ),
        (
            "on Fox's walk, no body collider",
            ClothJob {
                body_collider: Switch::Off,
                output: dir.join("pins.glb"),
                ..on_fox.clone()
            },
        ),
        (
            "no rig (fixed pins, no collider)",
            ClothJob {
                rig: None,
                animation: None,
                frames: Some(frames),
                fps: Some(first.fps),
                output: dir.join("plain.glb"),
                ..on_fox.clone()
            },
        ),
    ];
    println!(
        "| case | frames | ms/frame | Newton its/step (median, max) | steps within tolerance |"
    );
    println!("|---|---:|---:|---:|---:|");
    for (label, job) in cases {
        let start = Instant::now();
        let r = bake_cloth(&job, &mut |_, _| {}).unwrap();
        let seconds = start.elapsed().as_secs_f64();
        let mut its = r.iterations.clone();
        its.sort_unstable();
        println!(
            "| {label} | {} | {:.1} | {}, {} | {} of {} |",
            r.frames,
            1e3 * seconds / r.frames as f64,
            its[its.len() / 2],
            its[its.len() - 1],
            r.frames - r.unconverged_frames.len(),
            r.frames
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
