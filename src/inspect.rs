//! Reads a glTF/GLB back and describes it: meshes, skins, animations, and whether the invariants
//! scenebake's exports promise hold.

use std::path::Path;

use serde::Serialize;

use crate::error::{Error, Result};

/// What a glTF file contains.
#[derive(Debug, Clone, Serialize)]
pub struct Inspection {
    /// The file.
    pub file: String,
    /// Total size on disk in bytes (the `.gltf` plus external buffers and images).
    pub bytes: u64,
    /// Meshes.
    pub meshes: Vec<MeshInfo>,
    /// Skins.
    pub skins: Vec<SkinInfo>,
    /// Animations.
    pub animations: Vec<AnimationInfo>,
    /// Every node, in file order (the hierarchy: children, and what each node holds).
    pub nodes: Vec<NodeInfo>,
    /// The root nodes of each scene.
    pub scenes: Vec<Vec<usize>>,
    /// Invariant checks, passed and failed.
    pub checks: Vec<Check>,
}

/// One node of the hierarchy.
#[derive(Debug, Clone, Serialize)]
pub struct NodeInfo {
    /// Its index (`#N` on the command line, `Node_N` in Blender when it has no name).
    pub index: usize,
    /// Its name, when it has one.
    pub name: Option<String>,
    /// Child node indices.
    pub children: Vec<usize>,
    /// Its mesh, when any.
    pub mesh: Option<usize>,
    /// Its skin, when any.
    pub skin: Option<usize>,
    /// The skins listing it as a joint.
    pub joint_of: Vec<usize>,
}

/// One mesh.
#[derive(Debug, Clone, Serialize)]
pub struct MeshInfo {
    /// Its name, or `#index`.
    pub name: String,
    /// Vertices over all primitives.
    pub vertices: usize,
    /// Triangles over all triangle primitives.
    pub triangles: usize,
    /// Morph targets (of the first primitive).
    pub morph_targets: usize,
    /// How the vertex data are stored: component types, sparse targets, basis, bytes per part.
    pub encoding: Encoding,
}

/// How a mesh's vertex data are stored (first primitive).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Encoding {
    /// `basis` when the targets are a morph basis (named `basis_NN`, see
    /// [`crate::export::basis`]), `frames` when they are frames (`frame_NNNN`), else `targets`
    /// (or `none` without targets).
    pub kind: String,
    /// Component type of POSITION (`f32`, `i16 normalized`...).
    pub positions: String,
    /// Component type of NORMAL, if any.
    pub normals: Option<String>,
    /// Target POSITION component types (`zero` for a one-entry sparse accessor of zeros) and
    /// how many targets use each.
    pub target_positions: Vec<(String, usize)>,
    /// Target NORMAL component types (`zero` as for POSITION) and how many targets use each.
    pub target_normals: Vec<(String, usize)>,
    /// Target accessors stored sparse.
    pub sparse_accessors: usize,
    /// Whether the file requires KHR_mesh_quantization.
    pub quantized: bool,
    /// Bytes of buffer data per part: base attributes, indices, target positions, target
    /// normals.
    pub bytes: PartSizes,
}

/// Bytes of the buffer views an accessor group uses.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PartSizes {
    /// Base attributes (POSITION, NORMAL, TEXCOORD...).
    pub base: u64,
    /// Triangle indices.
    pub indices: u64,
    /// Morph-target POSITION deltas.
    pub target_positions: u64,
    /// Morph-target NORMAL deltas.
    pub target_normals: u64,
}

/// The component type of an accessor, e.g. `i16 normalized`.
fn component(a: &gltf::Accessor<'_>) -> String {
    let t = match a.data_type() {
        gltf::accessor::DataType::I8 => "i8",
        gltf::accessor::DataType::U8 => "u8",
        gltf::accessor::DataType::I16 => "i16",
        gltf::accessor::DataType::U16 => "u16",
        gltf::accessor::DataType::U32 => "u32",
        gltf::accessor::DataType::F32 => "f32",
    };
    if a.normalized() {
        format!("{t} normalized")
    } else {
        t.to_owned()
    }
}

/// Bytes of the buffer data behind an accessor (its view, or a sparse accessor's index and
/// value views).
fn accessor_bytes(a: &gltf::Accessor<'_>) -> u64 {
    let dense = a.view().map_or(0, |v| v.length() as u64);
    let sparse = a.sparse().map_or(0, |s| {
        (s.indices().view().length() + s.values().view().length()) as u64
    });
    dense + sparse
}

/// Whether `a` is all zeros by construction: no buffer view and one sparse entry, with bounds
/// of zero (the zero POSITION of a target that only carries normals, or the zero NORMAL of a
/// target that only moves positions).
fn is_zero(a: &gltf::Accessor<'_>) -> bool {
    let zero = |b: Option<serde_json::Value>| {
        b.and_then(|v| v.as_array().cloned())
            .is_some_and(|v| v.iter().all(|x| x.as_f64() == Some(0.0)))
    };
    a.view().is_none()
        && a.sparse().is_some_and(|s| s.count() == 1)
        && zero(a.min())
        && zero(a.max())
}

/// Adds one to the count of `key`.
fn tally(counts: &mut Vec<(String, usize)>, key: String) {
    match counts.iter_mut().find(|(k, _)| *k == key) {
        Some((_, n)) => *n += 1,
        None => counts.push((key, 1)),
    }
}

/// The encoding of `mesh`'s first primitive.
fn encoding(mesh: &gltf::Mesh<'_>, quantized: bool) -> Encoding {
    let mut e = Encoding {
        quantized,
        kind: "none".into(),
        ..Default::default()
    };
    let Some(prim) = mesh.primitives().next() else {
        return e;
    };
    for (semantic, a) in prim.attributes() {
        e.bytes.base += accessor_bytes(&a);
        match semantic {
            gltf::Semantic::Positions => e.positions = component(&a),
            gltf::Semantic::Normals => e.normals = Some(component(&a)),
            _ => {}
        }
    }
    e.bytes.indices = prim.indices().map_or(0, |a| accessor_bytes(&a));
    for t in prim.morph_targets() {
        for (a, counts, bytes) in [
            (
                t.positions(),
                &mut e.target_positions,
                &mut e.bytes.target_positions,
            ),
            (
                t.normals(),
                &mut e.target_normals,
                &mut e.bytes.target_normals,
            ),
        ] {
            if let Some(a) = a {
                tally(
                    counts,
                    if is_zero(&a) {
                        "zero".into()
                    } else {
                        component(&a)
                    },
                );
                *bytes += accessor_bytes(&a);
                e.sparse_accessors += usize::from(a.sparse().is_some());
            }
        }
    }
    let names = mesh
        .extras()
        .as_ref()
        .and_then(|x| serde_json::from_str::<serde_json::Value>(x.get()).ok())
        .and_then(|v| v.get("targetNames").cloned());
    let first = names
        .as_ref()
        .and_then(|n| n.get(0))
        .and_then(|n| n.as_str())
        .unwrap_or("");
    e.kind = if prim.morph_targets().len() == 0 {
        "none"
    } else if first.starts_with("basis_") {
        "basis"
    } else if first.starts_with("frame_") {
        "frames"
    } else {
        "targets"
    }
    .into();
    e
}

/// One skin.
#[derive(Debug, Clone, Serialize)]
pub struct SkinInfo {
    /// Its name, or `#index`.
    pub name: String,
    /// Joint node names (or `#index`), in skin order.
    pub joints: Vec<String>,
    /// Joint node indices, in skin order.
    pub joint_nodes: Vec<usize>,
}

/// One animation.
#[derive(Debug, Clone, Serialize)]
pub struct AnimationInfo {
    /// Its name, or `#index`.
    pub name: String,
    /// Duration in seconds (last key time).
    pub duration: f32,
    /// Channels.
    pub channels: Vec<ChannelInfo>,
}

/// One animation channel.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelInfo {
    /// Target node name, or `#index`.
    pub node: String,
    /// `translation`, `rotation`, `scale` or `weights`.
    pub path: String,
    /// Keyframes.
    pub keys: usize,
    /// `LINEAR`, `STEP` or `CUBICSPLINE`.
    pub interpolation: String,
}

/// One invariant check.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// What is checked, with the element (e.g. `meshes[0] targets[3] POSITION has min/max`).
    pub what: String,
    /// Whether it holds.
    pub ok: bool,
}

impl Inspection {
    /// The checks that failed.
    pub fn failures(&self) -> impl Iterator<Item = &Check> {
        self.checks.iter().filter(|c| !c.ok)
    }
}

fn name_or_index(name: Option<&str>, index: usize) -> String {
    name.map(str::to_owned)
        .unwrap_or_else(|| format!("#{index}"))
}

/// Loads and inspects a glTF or GLB file.
///
/// # Errors
/// [`Error::Io`] or [`Error::Gltf`] when the file cannot be loaded.
pub fn inspect(path: &Path) -> Result<Inspection> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let (doc, buffers) = crate::io::gltf_import::import_gltf_for_inspection(path)?;
    let quantized = doc
        .extensions_required()
        .any(|e| e == crate::data::KHR_MESH_QUANTIZATION);
    let dir = path.parent().unwrap_or(Path::new(""));
    let external: u64 = doc
        .buffers()
        .filter_map(|b| match b.source() {
            gltf::buffer::Source::Uri(u) if !u.starts_with("data:") => {
                std::fs::metadata(dir.join(u)).ok().map(|m| m.len())
            }
            _ => None,
        })
        .sum();
    let data = |b: gltf::Buffer<'_>| buffers.get(b.index()).map(|d| &d[..]);
    let mut checks = Vec::new();

    let mut meshes = Vec::new();
    for mesh in doc.meshes() {
        let (mut vertices, mut triangles, mut morph_targets) = (0, 0, None);
        for (p, prim) in mesh.primitives().enumerate() {
            let count = prim
                .get(&gltf::Semantic::Positions)
                .map_or(0, |a| a.count());
            vertices += count;
            if prim.mode() == gltf::mesh::Mode::Triangles {
                triangles += prim.indices().map_or(count, |i| i.count()) / 3;
            }
            morph_targets.get_or_insert(prim.morph_targets().count());
            if let Some(a) = prim.get(&gltf::Semantic::Positions) {
                checks.push(Check {
                    what: format!(
                        "meshes[{}].primitives[{p}] POSITION has min/max",
                        mesh.index()
                    ),
                    ok: a.min().is_some() && a.max().is_some(),
                });
            }
            let missing: Vec<usize> = prim
                .morph_targets()
                .enumerate()
                .filter(|(_, t)| {
                    t.positions()
                        .is_some_and(|a| a.min().is_none() || a.max().is_none())
                })
                .map(|(i, _)| i)
                .collect();
            if prim.morph_targets().len() > 0 {
                checks.push(Check {
                    what: format!(
                        "meshes[{}].primitives[{p}] every morph POSITION has min/max{}",
                        mesh.index(),
                        if missing.is_empty() {
                            String::new()
                        } else {
                            format!(" (missing: targets {missing:?})")
                        }
                    ),
                    ok: missing.is_empty(),
                });
            }
        }
        let targets = morph_targets.unwrap_or(0);
        if let Some(extras) = mesh.extras() {
            if let Ok(v) = serde_json::from_str::<serde_json::Value>(extras.get()) {
                if let Some(names) = v.get("targetNames").and_then(|n| n.as_array()) {
                    checks.push(Check {
                        what: format!(
                            "meshes[{}] targetNames count ({}) matches morph targets ({targets})",
                            mesh.index(),
                            names.len()
                        ),
                        ok: names.len() == targets,
                    });
                }
            }
        }
        meshes.push(MeshInfo {
            name: name_or_index(mesh.name(), mesh.index()),
            vertices,
            triangles,
            morph_targets: targets,
            encoding: encoding(&mesh, quantized),
        });
    }

    let skins = doc
        .skins()
        .map(|s| SkinInfo {
            name: name_or_index(s.name(), s.index()),
            joints: s
                .joints()
                .map(|j| name_or_index(j.name(), j.index()))
                .collect(),
            joint_nodes: s.joints().map(|j| j.index()).collect(),
        })
        .collect();

    let mut animations = Vec::new();
    for anim in doc.animations() {
        let mut channels = Vec::new();
        let mut duration = 0.0f32;
        for (c, ch) in anim.channels().enumerate() {
            let reader = ch.reader(data);
            let times: Vec<f32> = reader
                .read_inputs()
                .map(|i| i.collect())
                .unwrap_or_default();
            duration = duration.max(times.last().copied().unwrap_or(0.0));
            let place = format!("animations[{}].channels[{c}]", anim.index());
            checks.push(Check {
                what: format!("{place} key times strictly increase"),
                ok: times.windows(2).all(|w| w[1] > w[0]),
            });
            let node = ch.target().node();
            let path = match ch.target().property() {
                gltf::animation::Property::Translation => "translation",
                gltf::animation::Property::Rotation => "rotation",
                gltf::animation::Property::Scale => "scale",
                gltf::animation::Property::MorphTargetWeights => "weights",
            };
            match reader.read_outputs() {
                Some(gltf::animation::util::ReadOutputs::Rotations(r)) => {
                    let worst = r
                        .into_f32()
                        .map(|q| (q.iter().map(|x| x * x).sum::<f32>().sqrt() - 1.0).abs())
                        .fold(0.0f32, f32::max);
                    checks.push(Check {
                        what: format!(
                            "{place} rotations are unit quaternions (worst |q| - 1 = {worst:.1e})"
                        ),
                        ok: worst < 1e-3,
                    });
                }
                Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(w)) => {
                    let values = w.into_f32().count();
                    let targets = node
                        .mesh()
                        .and_then(|m| m.primitives().next())
                        .map_or(0, |p| p.morph_targets().count());
                    let per_key = if ch.sampler().interpolation()
                        == gltf::animation::Interpolation::CubicSpline
                    {
                        3
                    } else {
                        1
                    };
                    checks.push(Check {
                        what: format!(
                            "{place} weights: {values} values = {} keys × {targets} targets{}",
                            times.len(),
                            if per_key == 3 { " × 3" } else { "" }
                        ),
                        ok: targets > 0 && values == times.len() * targets * per_key,
                    });
                }
                _ => {}
            }
            channels.push(ChannelInfo {
                node: name_or_index(node.name(), node.index()),
                path: path.into(),
                keys: times.len(),
                interpolation: match ch.sampler().interpolation() {
                    gltf::animation::Interpolation::Linear => "LINEAR",
                    gltf::animation::Interpolation::Step => "STEP",
                    gltf::animation::Interpolation::CubicSpline => "CUBICSPLINE",
                }
                .into(),
            });
        }
        animations.push(AnimationInfo {
            name: name_or_index(anim.name(), anim.index()),
            duration,
            channels,
        });
    }
    for mesh in doc.meshes() {
        for (p, prim) in mesh.primitives().enumerate() {
            if let Some(check) = weight_check(mesh.index(), p, &prim, data) {
                checks.push(check);
            }
        }
    }
    let nodes: Vec<NodeInfo> = doc
        .nodes()
        .map(|n| NodeInfo {
            index: n.index(),
            name: n.name().map(str::to_owned),
            children: n.children().map(|c| c.index()).collect(),
            mesh: n.mesh().map(|m| m.index()),
            skin: n.skin().map(|s| s.index()),
            joint_of: doc
                .skins()
                .filter(|s| s.joints().any(|j| j.index() == n.index()))
                .map(|s| s.index())
                .collect(),
        })
        .collect();
    let scenes: Vec<Vec<usize>> = doc
        .scenes()
        .map(|s| s.nodes().map(|n| n.index()).collect())
        .collect();
    checks.extend(hierarchy_checks(&nodes, &scenes));
    Ok(Inspection {
        file: path.display().to_string(),
        bytes: meta.len() + external,
        meshes,
        skins,
        animations,
        nodes,
        scenes,
        checks,
    })
}

/// Skin weights of a primitive sum to 1 (over every WEIGHTS_n set), within
/// [`crate::io::skin_weights::SUM_TOLERANCE`].
fn weight_check<'a, 's, F>(
    mesh: usize,
    p: usize,
    prim: &'a gltf::Primitive<'a>,
    data: F,
) -> Option<Check>
where
    F: Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
{
    let reader = prim.reader(data);
    let mut sums: Vec<f32> = Vec::new();
    let mut set = 0;
    while let Some(weights) = reader.read_weights(set) {
        for (v, w) in weights.into_f32().enumerate() {
            if v == sums.len() {
                sums.push(0.0);
            }
            sums[v] += w.iter().sum::<f32>();
        }
        set += 1;
    }
    if set == 0 {
        return None;
    }
    let tol = crate::io::skin_weights::SUM_TOLERANCE;
    let off: Vec<f32> = sums
        .iter()
        .copied()
        .filter(|s| (s - 1.0).abs() > tol)
        .collect();
    let detail = if off.is_empty() {
        String::new()
    } else {
        let lo = off.iter().copied().fold(f32::MAX, f32::min);
        let hi = off.iter().copied().fold(f32::MIN, f32::max);
        format!(
            " ({} of {} vertices sum to {lo:.3}–{hi:.3}; an IK bake with this file as its rig renormalises them)",
            off.len(),
            sums.len()
        )
    };
    Some(Check {
        what: format!("meshes[{mesh}].primitives[{p}] skin weights sum to 1{detail}"),
        ok: off.is_empty(),
    })
}

/// The node hierarchy is a forest: no node has two parents, no node is its own ancestor, and
/// scene roots have no parent.
fn hierarchy_checks(nodes: &[NodeInfo], scenes: &[Vec<usize>]) -> Vec<Check> {
    let mut checks = Vec::new();
    let mut parents: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    for n in nodes {
        for &c in &n.children {
            if let Some(p) = parents.get_mut(c) {
                p.push(n.index);
            }
        }
    }
    let shared: Vec<String> = parents
        .iter()
        .enumerate()
        .filter(|(_, p)| p.len() > 1)
        .map(|(i, p)| {
            format!(
                "#{i} is a child of {}",
                p.iter()
                    .map(|x| format!("#{x}"))
                    .collect::<Vec<_>>()
                    .join(" and ")
            )
        })
        .collect();
    checks.push(Check {
        what: format!(
            "nodes: every node has at most one parent{}",
            if shared.is_empty() {
                String::new()
            } else {
                format!(" ({})", shared.join("; "))
            }
        ),
        ok: shared.is_empty(),
    });
    // A cycle: following children from a node comes back to it.
    let mut cycle = None;
    let mut state = vec![0u8; nodes.len()]; // 0 new, 1 on the path, 2 done
    for start in 0..nodes.len() {
        if cycle.is_some() {
            break;
        }
        let mut stack: Vec<(usize, usize)> = vec![(start, 0)];
        let mut path = vec![start];
        if state[start] != 0 {
            continue;
        }
        state[start] = 1;
        while let Some(&mut (node, ref mut next)) = stack.last_mut() {
            if let Some(&child) = nodes[node].children.get(*next) {
                *next += 1;
                match state.get(child) {
                    Some(0) => {
                        state[child] = 1;
                        stack.push((child, 0));
                        path.push(child);
                    }
                    Some(1) => {
                        let from = path.iter().position(|&x| x == child).unwrap_or(0);
                        let mut c: Vec<String> =
                            path[from..].iter().map(|x| format!("#{x}")).collect();
                        c.push(format!("#{child}"));
                        cycle = Some(c.join(" → "));
                        break;
                    }
                    _ => {}
                }
            } else {
                state[node] = 2;
                stack.pop();
                path.pop();
            }
        }
    }
    checks.push(Check {
        what: format!(
            "nodes: the hierarchy has no cycle{}",
            cycle
                .as_ref()
                .map(|c| format!(" (found {c})"))
                .unwrap_or_default()
        ),
        ok: cycle.is_none(),
    });
    let child_roots: Vec<String> = scenes
        .iter()
        .enumerate()
        .flat_map(|(s, roots)| {
            roots
                .iter()
                .filter(|&&r| parents.get(r).is_some_and(|p| !p.is_empty()))
                .map(move |r| format!("scenes[{s}] lists #{r}"))
        })
        .collect();
    checks.push(Check {
        what: format!(
            "scenes: root nodes have no parent{}",
            if child_roots.is_empty() {
                String::new()
            } else {
                format!(" ({})", child_roots.join("; "))
            }
        ),
        ok: child_roots.is_empty(),
    });
    checks
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(index: usize, children: &[usize]) -> NodeInfo {
        NodeInfo {
            index,
            name: None,
            children: children.to_vec(),
            mesh: None,
            skin: None,
            joint_of: Vec::new(),
        }
    }

    #[test]
    fn a_cycle_and_a_shared_child_are_reported_with_their_nodes() {
        let nodes = vec![node(0, &[1]), node(1, &[2]), node(2, &[1]), node(3, &[2])];
        let checks = hierarchy_checks(&nodes, &[vec![0, 2]]);
        let failed: Vec<&str> = checks
            .iter()
            .filter(|c| !c.ok)
            .map(|c| c.what.as_str())
            .collect();
        assert_eq!(
            failed,
            [
                "nodes: every node has at most one parent (#1 is a child of #0 and #2; #2 is a child of #1 and #3)",
                "nodes: the hierarchy has no cycle (found #1 → #2 → #1)",
                "scenes: root nodes have no parent (scenes[0] lists #2)",
            ]
        );
        let tree = vec![node(0, &[1, 2]), node(1, &[]), node(2, &[3]), node(3, &[])];
        assert!(hierarchy_checks(&tree, &[vec![0]]).iter().all(|c| c.ok));
    }
}
