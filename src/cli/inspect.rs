//! `scenebake inspect FILE`: what a glTF holds, and whether our export invariants hold.

use std::path::PathBuf;

use anyhow::bail;
use clap::Args;

use super::progress::bytes;

/// Describe a glTF/GLB file and check the invariants scenebake's exports promise.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// The .glb or .gltf file.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Prints the inspection; fails when a check fails.
pub fn run(args: &InspectArgs) -> anyhow::Result<()> {
    let info = scenebake::inspect::inspect(&args.file)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        println!("{} ({})", info.file, bytes(info.bytes));
        for m in &info.meshes {
            println!(
                "  mesh {}: {} vertices, {} triangles, {} morph targets",
                m.name, m.vertices, m.triangles, m.morph_targets
            );
            let e = &m.encoding;
            if m.morph_targets > 0 {
                let list = |v: &[(String, usize)]| {
                    v.iter()
                        .map(|(t, n)| format!("{n}× {t}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                println!(
                    "    encoding: {}{}; POSITION {}, NORMAL {}; target POSITION {}; target NORMAL {}; {} sparse",
                    e.kind,
                    if e.quantized { ", KHR_mesh_quantization" } else { "" },
                    e.positions,
                    e.normals.as_deref().unwrap_or("none"),
                    list(&e.target_positions),
                    if e.target_normals.is_empty() { "none".into() } else { list(&e.target_normals) },
                    e.sparse_accessors
                );
                println!(
                    "    bytes: base {}, indices {}, target POSITION {}, target NORMAL {}",
                    bytes(e.bytes.base),
                    bytes(e.bytes.indices),
                    bytes(e.bytes.target_positions),
                    bytes(e.bytes.target_normals)
                );
            }
        }
        for s in &info.skins {
            println!(
                "  skin {}: {} joints ({})",
                s.name,
                s.joints.len(),
                s.joints.join(", ")
            );
        }
        for a in &info.animations {
            println!(
                "  animation {}: {:.3} s, {} channels",
                a.name,
                a.duration,
                a.channels.len()
            );
            for c in &a.channels {
                println!(
                    "    {} {}: {} keys, {}",
                    c.node, c.path, c.keys, c.interpolation
                );
            }
        }
        let failed = info.failures().count();
        println!(
            "  checks: {} passed, {failed} failed",
            info.checks.len() - failed
        );
        for c in info.failures() {
            println!("    FAILED: {}", c.what);
        }
    }
    let failed: Vec<&str> = info.failures().map(|c| c.what.as_str()).collect();
    if !failed.is_empty() {
        bail!(
            "{}: {} invariant check(s) failed: {}",
            args.file.display(),
            failed.len(),
            failed.join("; ")
        );
    }
    Ok(())
}
