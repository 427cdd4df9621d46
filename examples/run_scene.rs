//! Runs a scene file with the library alone: load it, run each job, write each report where the
//! scene asks, print one line per job.
//!
//! ```text
//! cargo run --release --example run_scene -- scenes/demo.toml
//! ```

use scenebake::scene::Scene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "scenes/demo.toml".into());
    let scene = Scene::load(path.as_ref())?;
    for job in &scene.jobs {
        let report = job.job.run(&mut |_done, _total| {})?;
        if let Some(path) = job.job.report_path() {
            std::fs::write(path, serde_json::to_vec_pretty(&report)?)?;
        }
        println!(
            "{} ({}): {} frames → {}",
            job.name,
            job.job.kind(),
            report.frames(),
            job.job.output().display()
        );
        for w in report.warnings() {
            println!("  warning: {w}");
        }
    }
    Ok(())
}
