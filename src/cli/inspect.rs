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
            let joints: Vec<String> = s
                .joints
                .iter()
                .zip(&s.joint_nodes)
                .map(|(name, &i)| {
                    if name.starts_with('#') {
                        name.clone()
                    } else {
                        format!("{name} #{i}")
                    }
                })
                .collect();
            println!(
                "  skin {}: {} joints ({})",
                s.name,
                s.joints.len(),
                joints.join(", ")
            );
        }
        print_hierarchy(&info);
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

/// The node tree of each scene, one node a line: `#N name`, what it holds, joints marked.
/// Nodes no scene reaches (or caught in a cycle) are listed after.
fn print_hierarchy(info: &scenebake::inspect::Inspection) {
    if info.nodes.is_empty() {
        return;
    }
    println!("  nodes (`#N` as --chain accepts it; Blender names an unnamed node Node_N):");
    let mut shown = vec![false; info.nodes.len()];
    for (s, roots) in info.scenes.iter().enumerate() {
        println!("    scene {s}:");
        for &r in roots {
            print_node(info, r, 3, &mut shown);
        }
    }
    let rest: Vec<usize> = (0..info.nodes.len()).filter(|&i| !shown[i]).collect();
    if !rest.is_empty() {
        println!("    in no scene:");
        for i in rest {
            if !shown[i] {
                print_node(info, i, 3, &mut shown);
            }
        }
    }
}

fn print_node(info: &scenebake::inspect::Inspection, i: usize, depth: usize, shown: &mut [bool]) {
    let Some(n) = info.nodes.get(i) else {
        return;
    };
    let indent = "  ".repeat(depth);
    if std::mem::replace(&mut shown[i], true) {
        println!("{indent}#{i} (again: the hierarchy loops here)");
        return;
    }
    let mut what = Vec::new();
    if let Some(m) = n.mesh {
        what.push(format!(
            "mesh {}",
            info.meshes.get(m).map_or("?", |x| &x.name)
        ));
    }
    if let Some(sk) = n.skin {
        what.push(format!(
            "skin {}",
            info.skins.get(sk).map_or("?", |x| &x.name)
        ));
    }
    if !n.joint_of.is_empty() {
        what.push("joint".into());
    }
    let name = n.name.as_deref().unwrap_or("(unnamed)");
    let what = if what.is_empty() {
        String::new()
    } else {
        format!(" [{}]", what.join(", "))
    };
    println!("{indent}#{i} {name}{what}");
    for &c in &n.children {
        print_node(info, c, depth + 1, shown);
    }
}
