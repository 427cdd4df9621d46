//! USD export (`--usd FILE.usda`): the bake as a USD layer, for Blender's USD import (File ›
//! Import › Universal Scene Description), Houdini, Omniverse, usdview...
//!
//! One `Xform` prim `/World` (the layer's `defaultPrim`) holds a `Mesh` prim per body: the cloth
//! (time-sampled `points`, `normals` and `extent`), each collider as a static mesh, and a body
//! sequence (`--body`) with time-sampled points. Frame k is at time code `start + k` where `start`
//! is the first frame's time × fps (0 for a cloth bake); the layer's `timeCodesPerSecond` and
//! `framesPerSecond` are the bake's fps, `startTimeCode`/`endTimeCode` its first and last frame,
//! `upAxis` Y and `metersPerUnit` 1 (positions are the bake's: metres, +Y up, as the glTF's).
//!
//! Meshes are triangles (`faceVertexCounts` all 3), counter-clockwise seen from the front (USD's
//! default `rightHanded` orientation), not subdivided (`subdivisionScheme = "none"`); normals
//! are per point (`interpolation = "vertex"`), the corner-angle-weighted normals the glTF holds.
//! The cloth's points are its particles in the input's order, as the point caches
//! ([`super::pointcache`]) hold them; its positions are the baked frames, which the glTF plays
//! unless it was reduced (`--keyframe-tolerance`, `--basis`, `--quantize`).
//!
//! The layer is built as Pixar's Sdf data (specs and fields) with the `openusd` crate and written
//! by its text writer. Binary `.usdc` is refused: openusd 0.6 (the newest release for our
//! rust-version) writes a prim's children as a `token[]` where Pixar's reader wants a
//! `TfTokenVector`, so USD itself refuses any file with a nested prim; openusd 0.8 fixes that but
//! needs Rust 1.96.

use std::path::{Path, PathBuf};

use glam::Vec3;
use openusd::gf::Vec3f;
use openusd::sdf::{self, ChildrenKey, FieldKey, SpecType, Specifier, Value, Variability};

use crate::error::{Error, Result};
use crate::export::pointcache::check_point_cache_path;

/// The root prim, the layer's default prim.
pub const ROOT: &str = "World";

/// A USD file format, by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UsdFormat {
    /// `.usda`: text.
    Text,
    /// `.usdc`: Pixar's binary crate format (not written; see the module's notes).
    Crate,
}

/// The format `path`'s extension names (case-insensitive), if any.
pub fn usd_format(path: &Path) -> Option<UsdFormat> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "usda" => Some(UsdFormat::Text),
        "usdc" => Some(UsdFormat::Crate),
        _ => None,
    }
}

/// Checks before a bake that `--usd` names a `.usda` file (a file name as every cache's:
/// [`check_point_cache_path`]). Whether it can be written is checked with every other output of
/// the job (`crate::bake::outputs`).
///
/// # Errors
/// [`Error::Value`] saying what is wrong (the job names `--usd`).
pub fn check_usd_path(path: &Path) -> Result<()> {
    check_point_cache_path(path)?;
    let refuse = |what: String| Err(Error::value(what));
    match usd_format(path) {
        Some(UsdFormat::Text) => Ok(()),
        Some(UsdFormat::Crate) => refuse(format!(
            "{}: binary .usdc is not written (the USD writer used makes .usdc files that Pixar's \
             USD cannot open); give a .usda file (usdcat converts it: usdcat FILE.usda -o \
             FILE.usdc)",
            path.display()
        )),
        None => refuse(format!(
            "{}: unknown USD extension: expected .usda",
            path.display()
        )),
    }
}

/// Where a mesh's points come from.
#[derive(Debug, Clone, PartialEq)]
pub enum UsdPoints {
    /// One shape for the whole layer: positions and unit normals.
    Static {
        /// Positions, metres.
        positions: Vec<Vec3>,
        /// Unit normals, parallel to `positions`.
        normals: Vec<Vec3>,
    },
    /// One shape per frame: `positions[k]` and `normals[k]` at frame k, every frame the same
    /// number of points.
    Animated {
        /// Positions per frame, metres.
        positions: Vec<Vec<Vec3>>,
        /// Unit normals per frame.
        normals: Vec<Vec<Vec3>>,
    },
}

/// One mesh of the layer.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdMesh {
    /// Its name (made a valid prim name: other characters become `_`).
    pub name: String,
    /// Triangles as point indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Its points.
    pub points: UsdPoints,
    /// Whether renderers show its back faces (cloth: yes).
    pub double_sided: bool,
}

/// The layer's timing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UsdOptions {
    /// Frames (time codes) per second.
    pub fps: f64,
    /// Time of frame 0 in seconds: frame k is at time code `start_time × fps + k`.
    pub start_time: f64,
    /// Frames, frame 0 included (the animated meshes' sample count).
    pub frames: usize,
}

/// A USD layer encoded but not written.
#[derive(Debug, Clone)]
pub struct EncodedUsd {
    /// The file.
    pub path: PathBuf,
    /// Its bytes.
    pub bytes: Vec<u8>,
    /// The meshes' prim paths, in the layer's order.
    pub prims: Vec<String>,
    /// The first and last frames' time codes.
    pub time_codes: [f64; 2],
}

/// A valid prim name for `name`: characters other than ASCII letters, digits and `_` become `_`,
/// and a leading digit (or an empty name) gets a `_` before it.
pub fn prim_name(name: &str) -> String {
    let mut out: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if out.chars().next().is_none_or(|c| c.is_ascii_digit()) {
        out.insert(0, '_');
    }
    out
}

/// Encodes `meshes` as a USD text layer for `path` (the extension is checked first:
/// [`check_usd_path`]).
///
/// # Errors
/// [`Error::Value`] for a path [`check_usd_path`] refuses; [`Error::Export`] naming `path` when a
/// mesh's frames do not match `options.frames`, its normals its positions, or a triangle indexes
/// past its points.
pub fn encode_usd(path: &Path, meshes: &[UsdMesh], options: &UsdOptions) -> Result<EncodedUsd> {
    check_usd_path(path)?;
    let export_error = |message: String| Error::Export {
        path: path.into(),
        message: message.into(),
    };
    let start = options.start_time * options.fps;
    let end = start + options.frames.saturating_sub(1) as f64;
    let mut data = sdf::Data::new();
    let mut names: Vec<String> = Vec::with_capacity(meshes.len());
    for mesh in meshes {
        // Sibling prims need distinct names.
        let base = prim_name(&mesh.name);
        let mut name = base.clone();
        let mut n = 1;
        while names.contains(&name) {
            n += 1;
            name = format!("{base}_{n}");
        }
        names.push(name);
    }

    let root = data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot);
    root.add(
        ChildrenKey::PrimChildren,
        Value::TokenVec(vec![ROOT.into()]),
    );
    root.add(FieldKey::DefaultPrim, Value::Token(ROOT.into()));
    root.add(FieldKey::TimeCodesPerSecond, Value::Double(options.fps));
    root.add(FieldKey::FramesPerSecond, Value::Double(options.fps));
    root.add(FieldKey::StartTimeCode, Value::Double(start));
    root.add(FieldKey::EndTimeCode, Value::Double(end));
    root.add("upAxis", Value::Token("Y".into()));
    root.add("metersPerUnit", Value::Double(1.0));
    root.add(
        FieldKey::Documentation,
        Value::String("Baked by scenebake".into()),
    );

    let world = prim_path(&format!("/{ROOT}"))?;
    let spec = data.create_spec(world.clone(), SpecType::Prim);
    spec.add(FieldKey::Specifier, Value::Specifier(Specifier::Def));
    spec.add(FieldKey::TypeName, Value::Token("Xform".into()));
    spec.add(
        ChildrenKey::PrimChildren,
        Value::TokenVec(names.iter().map(|n| n.as_str().into()).collect()),
    );

    let mut prims = Vec::with_capacity(meshes.len());
    for (mesh, name) in meshes.iter().zip(&names) {
        let at = prim_path(&format!("/{ROOT}/{name}"))?;
        let points = match &mesh.points {
            UsdPoints::Static { positions, .. } => positions.len(),
            UsdPoints::Animated { positions, .. } => positions.first().map_or(0, Vec::len),
        };
        check_mesh(mesh, points, options.frames)
            .map_err(|m| export_error(format!("{name}: {m}")))?;
        write_mesh(&mut data, &at, mesh, start)?;
        prims.push(at.as_str().to_owned());
    }

    let text = openusd::usda::TextWriter::write_to_string(&data)
        .map_err(|e| export_error(format!("writing USD text: {e}")))?;
    Ok(EncodedUsd {
        path: path.to_path_buf(),
        bytes: text.into_bytes(),
        prims,
        time_codes: [start, end],
    })
}

/// Whether `mesh` is consistent: every frame `points` points with as many normals, `frames`
/// frames when animated, triangles within the points.
fn check_mesh(mesh: &UsdMesh, points: usize, frames: usize) -> std::result::Result<(), String> {
    match &mesh.points {
        UsdPoints::Static { positions, normals } => {
            if normals.len() != positions.len() {
                return Err(format!(
                    "{} normals for {} points",
                    normals.len(),
                    positions.len()
                ));
            }
        }
        UsdPoints::Animated { positions, normals } => {
            if positions.len() != frames || normals.len() != frames {
                return Err(format!(
                    "{} frames of positions and {} of normals, expected {frames}",
                    positions.len(),
                    normals.len()
                ));
            }
            if let Some(k) =
                (0..frames).find(|&k| positions[k].len() != points || normals[k].len() != points)
            {
                return Err(format!(
                    "frame {k} has {} positions and {} normals, frame 0 {points} points",
                    positions[k].len(),
                    normals[k].len()
                ));
            }
        }
    }
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= points))
    {
        return Err(format!("triangle {t:?} indexes past its {points} points"));
    }
    if i32::try_from(3 * mesh.triangles.len()).is_err() {
        return Err("more triangle corners than a USD int index holds".into());
    }
    Ok(())
}

fn prim_path(text: &str) -> Result<sdf::Path> {
    sdf::path(text).map_err(|e| Error::Export {
        path: PathBuf::from(text),
        message: format!("not a USD prim path: {e}").into(),
    })
}

/// An attribute of `prim`: its type and fields.
fn attribute(data: &mut sdf::Data, prim: &sdf::Path, name: &str, type_name: &str) -> Result<()> {
    let path = prim.append_property(name).map_err(|e| Error::Export {
        path: PathBuf::from(prim.as_str()),
        message: format!("attribute {name}: {e}").into(),
    })?;
    let spec = data.create_spec(path, SpecType::Attribute);
    spec.add(FieldKey::TypeName, Value::Token(type_name.into()));
    Ok(())
}

fn vec3f(v: &[Vec3]) -> Value {
    Value::Vec3fVec(v.iter().map(|p| Vec3f::from(p.to_array())).collect())
}

/// The extent (bounds) of `points`: `[min, max]`; zeros for none.
fn extent(points: &[Vec3]) -> Value {
    let (lo, hi) = if points.is_empty() {
        (Vec3::ZERO, Vec3::ZERO)
    } else {
        points.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    };
    vec3f(&[lo, hi])
}

/// Writes `mesh` as a `Mesh` prim at `at`, its frame k at time code `start + k`.
fn write_mesh(data: &mut sdf::Data, at: &sdf::Path, mesh: &UsdMesh, start: f64) -> Result<()> {
    const PROPERTIES: [(&str, &str); 7] = [
        ("doubleSided", "bool"),
        ("extent", "float3[]"),
        ("faceVertexCounts", "int[]"),
        ("faceVertexIndices", "int[]"),
        ("normals", "normal3f[]"),
        ("points", "point3f[]"),
        ("subdivisionScheme", "token"),
    ];
    let spec = data.create_spec(at.clone(), SpecType::Prim);
    spec.add(FieldKey::Specifier, Value::Specifier(Specifier::Def));
    spec.add(FieldKey::TypeName, Value::Token("Mesh".into()));
    spec.add(
        ChildrenKey::PropertyChildren,
        Value::TokenVec(PROPERTIES.iter().map(|(n, _)| (*n).into()).collect()),
    );
    for (name, type_name) in PROPERTIES {
        attribute(data, at, name, type_name)?;
    }
    let mut set = |name: &str, key: &str, value: Value| {
        let path = at.append_property(name).expect("attribute created above");
        data.spec_mut(&path)
            .expect("attribute created above")
            .add(key, value);
    };
    let default = FieldKey::Default.as_str();
    let uniform = Value::Variability(Variability::Uniform);
    set("doubleSided", default, Value::Bool(mesh.double_sided));
    set(
        "doubleSided",
        FieldKey::Variability.as_str(),
        uniform.clone(),
    );
    set("subdivisionScheme", default, Value::Token("none".into()));
    set("subdivisionScheme", FieldKey::Variability.as_str(), uniform);
    set(
        "faceVertexCounts",
        default,
        Value::IntVec(vec![3; mesh.triangles.len()]),
    );
    set(
        "faceVertexIndices",
        default,
        Value::IntVec(mesh.triangles.iter().flatten().map(|&i| i as i32).collect()),
    );
    set("normals", "interpolation", Value::Token("vertex".into()));
    match &mesh.points {
        UsdPoints::Static { positions, normals } => {
            set("points", default, vec3f(positions));
            set("normals", default, vec3f(normals));
            set("extent", default, extent(positions));
        }
        UsdPoints::Animated { positions, normals } => {
            let samples = |of: &dyn Fn(usize) -> Value| {
                Value::TimeSamples(
                    (0..positions.len())
                        .map(|k| (start + k as f64, of(k)))
                        .collect(),
                )
            };
            let key = FieldKey::TimeSamples.as_str();
            set("points", key, samples(&|k| vec3f(&positions[k])));
            set("normals", key, samples(&|k| vec3f(&normals[k])));
            set("extent", key, samples(&|k| extent(&positions[k])));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_names_are_identifiers() {
        assert_eq!(prim_name("lab-cloth 2"), "lab_cloth_2");
        assert_eq!(prim_name("2sheets"), "_2sheets");
        assert_eq!(prim_name(""), "_");
        assert_eq!(prim_name("Fox_cape"), "Fox_cape");
    }

    #[test]
    fn only_usda_is_accepted() {
        assert!(check_usd_path(Path::new("a/b.USDA")).is_ok());
        for bad in ["b.usdc", "b.usd", "b.usdz", "b", ""] {
            assert!(check_usd_path(Path::new(bad)).is_err(), "{bad}");
        }
    }
}
