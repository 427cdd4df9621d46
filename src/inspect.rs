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
    /// Invariant checks, passed and failed.
    pub checks: Vec<Check>,
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
    /// Target POSITION component types and how many targets use each.
    pub target_positions: Vec<(String, usize)>,
    /// Target NORMAL component types and how many targets use each.
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
                tally(counts, component(&a));
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
    let (doc, buffers, _) = crate::io::gltf_import::import_gltf_for_inspection(path)?;
    let quantized = doc
        .extensions_required()
        .any(|e| e == crate::export::basis::KHR_MESH_QUANTIZATION);
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
    let data = |b: gltf::Buffer<'_>| buffers.get(b.index()).map(|d| &d.0[..]);
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
    Ok(Inspection {
        file: path.display().to_string(),
        bytes: meta.len() + external,
        meshes,
        skins,
        animations,
        checks,
    })
}
