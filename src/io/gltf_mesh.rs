//! Reads a triangle mesh from a glTF 2.0 file (`.gltf` or `.glb`) as a cloth body.
//!
//! The chosen mesh's triangle primitives are merged into one body. glTF splits vertices at UV and
//! normal seams; vertices with bit-identical positions become one particle, so seams stay sewn.
//! Positions are placed in the scene's world frame with the transform of the first node that
//! instantiates the mesh (glTF units: metres, +Y up).

use std::collections::HashMap;
use std::path::Path;

use glam::{DMat4, DVec3, Mat4};

use super::gltf_import::import_gltf;
use crate::error::{Error, Result};
use crate::mesh::{drop_degenerate, Mesh, RenderVertex};

/// Reads mesh `name` (or the first mesh) of a glTF file.
///
/// # Errors
/// [`Error::Gltf`] when the file cannot be loaded; [`Error::Value`] naming the file and its
/// meshes when `name` names none (the job names `--mesh`); [`Error::InvalidInput`] when the mesh
/// is missing, has no triangles, or holds non-finite positions.
pub fn load_gltf_mesh(path: &Path, name: Option<&str>) -> Result<Mesh> {
    let (doc, buffers) = import_gltf(path)?;
    let gmesh = match name {
        Some(name) => doc
            .meshes()
            .find(|m| m.name() == Some(name))
            .ok_or_else(|| {
                let known: Vec<String> = doc
                    .meshes()
                    .map(|m| {
                        m.name()
                            .map(str::to_owned)
                            .unwrap_or_else(|| format!("#{}", m.index()))
                    })
                    .collect();
                Error::value(format!(
                    "{}: no mesh named `{name}` (meshes: {})",
                    path.display(),
                    known.join(", ")
                ))
            })?,
        None => doc
            .meshes()
            .next()
            .ok_or_else(|| Error::invalid(path, "the file contains no mesh"))?,
    };
    let transform = world_transform_of_mesh(&doc, gmesh.index());
    read_mesh(path, &buffers, gmesh, transform)
}

/// Mesh `gmesh`'s triangle primitives as one body, placed by `transform`.
pub(crate) fn read_mesh(
    path: &Path,
    buffers: &[Vec<u8>],
    gmesh: gltf::Mesh<'_>,
    transform: DMat4,
) -> Result<Mesh> {
    let mut mesh = Mesh {
        name: path.display().to_string(),
        ..Default::default()
    };
    let mut particle_of_bits: HashMap<[u64; 3], u32> = HashMap::new();
    let mut skipped_primitives = 0;
    for prim in gmesh.primitives() {
        if prim.mode() != gltf::mesh::Mode::Triangles {
            skipped_primitives += 1;
            continue;
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
        let Some(positions) = reader.read_positions() else {
            skipped_primitives += 1;
            continue;
        };
        let base = mesh.render_vertices.len() as u32;
        let uvs: Option<Vec<[f32; 2]>> = reader.read_tex_coords(0).map(|t| t.into_f32().collect());
        for (k, p) in positions.enumerate() {
            let p = transform.transform_point3(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            if !p.is_finite() {
                return Err(Error::invalid(
                    path,
                    format!(
                        "mesh {}: vertex {k} has a non-finite position",
                        gmesh.index()
                    ),
                ));
            }
            let key = p.to_array().map(f64::to_bits);
            let next = mesh.positions.len() as u32;
            let particle = *particle_of_bits.entry(key).or_insert_with(|| {
                mesh.positions.push(p);
                next
            });
            mesh.render_vertices.push(RenderVertex {
                particle,
                // glTF's v points down; the mesh model keeps OBJ's v-up convention.
                uv: uvs
                    .as_ref()
                    .and_then(|t| t.get(k))
                    .map(|&[u, v]| [u, 1.0 - v]),
            });
        }
        let count = mesh.render_vertices.len() as u32 - base;
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..count).collect(),
        };
        if let Some(bad) = indices.iter().find(|&&i| i >= count) {
            return Err(Error::invalid(
                path,
                format!(
                    "mesh {}: index {bad} out of range ({count} vertices)",
                    gmesh.index()
                ),
            ));
        }
        for t in indices.chunks_exact(3) {
            let r = [t[0] + base, t[1] + base, t[2] + base];
            mesh.render_triangles.push(r);
            mesh.triangles
                .push(r.map(|i| mesh.render_vertices[i as usize].particle));
        }
    }
    if skipped_primitives > 0 {
        mesh.warnings.push(format!(
            "{skipped_primitives} non-triangle primitives skipped"
        ));
    }
    mesh.file_index = (0..mesh.positions.len() as u32).collect();
    let dropped = drop_degenerate(
        &mesh.positions,
        &mut mesh.triangles,
        Some(&mut mesh.render_triangles),
    );
    if dropped > 0 {
        mesh.warnings
            .push(format!("{dropped} degenerate triangles skipped"));
    }
    if mesh.triangles.is_empty() {
        return Err(Error::invalid(
            path,
            format!("mesh {} has no usable triangles", gmesh.index()),
        ));
    }
    Ok(mesh)
}

/// Reads the triangles of a glTF file as a mesh collider (`--collider mesh:FILE.glb[#NAME]`), in
/// world space (each mesh placed by the node that instantiates it).
///
/// With `part`, only the node of that name (when it has a mesh), else the mesh of that name;
/// without, every mesh node of the default scene (or of the first scene), merged into one
/// triangle set, as an OBJ collider takes every object.
///
/// # Errors
/// As [`load_gltf_mesh`]; [`Error::Value`] naming the file and the names it holds when `part`
/// names nothing (the job names `--collider`).
pub fn load_gltf_collider(path: &Path, part: Option<&str>) -> Result<Mesh> {
    let (doc, buffers) = import_gltf(path)?;
    let placed = mesh_nodes(&doc);
    let chosen: Vec<(gltf::Mesh<'_>, DMat4)> = match part {
        Some(name) => {
            if let Some((_, m, t)) = placed.iter().find(|(n, _, _)| n.name() == Some(name)) {
                vec![(m.clone(), *t)]
            } else if let Some(m) = doc.meshes().find(|m| m.name() == Some(name)) {
                let t = world_transform_of_mesh(&doc, m.index());
                vec![(m, t)]
            } else {
                let named = |names: Vec<Option<&str>>| {
                    let mut v: Vec<String> =
                        names.into_iter().flatten().map(str::to_owned).collect();
                    v.dedup();
                    if v.is_empty() {
                        "none named".to_owned()
                    } else {
                        v.join(", ")
                    }
                };
                return Err(Error::value(format!(
                    "{}: no mesh or mesh node named `{name}` (meshes: {}; nodes with a mesh: {})",
                    path.display(),
                    named(doc.meshes().map(|m| m.name()).collect()),
                    named(placed.iter().map(|(n, _, _)| n.name()).collect()),
                )));
            }
        }
        None if !placed.is_empty() => placed.into_iter().map(|(_, m, t)| (m, t)).collect(),
        None => doc.meshes().map(|m| (m, DMat4::IDENTITY)).collect(),
    };
    if chosen.is_empty() {
        return Err(Error::invalid(path, "the file contains no mesh"));
    }
    let mut all = Mesh {
        name: path.display().to_string(),
        ..Default::default()
    };
    for (gmesh, transform) in chosen {
        let mesh = read_mesh(path, &buffers, gmesh, transform)?;
        let base = all.positions.len() as u32;
        all.positions.extend(mesh.positions);
        all.triangles
            .extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
        all.warnings.extend(mesh.warnings);
    }
    all.file_index = (0..all.positions.len() as u32).collect();
    Ok(all)
}

/// Every node of the default scene (else the first scene) that has a mesh, with its world
/// transform, in depth-first order.
fn mesh_nodes(doc: &gltf::Document) -> Vec<(gltf::Node<'_>, gltf::Mesh<'_>, DMat4)> {
    fn visit<'a>(
        node: gltf::Node<'a>,
        parent: DMat4,
        seen: &mut [bool],
        out: &mut Vec<(gltf::Node<'a>, gltf::Mesh<'a>, DMat4)>,
    ) {
        // The gltf crate checks indices, not cycles or shared children: each node once.
        if std::mem::replace(&mut seen[node.index()], true) {
            return;
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4();
        if let Some(m) = node.mesh() {
            out.push((node.clone(), m, world));
        }
        for c in node.children() {
            visit(c, world, seen, out);
        }
    }
    let mut out = Vec::new();
    let mut seen = vec![false; doc.nodes().len()];
    if let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next()) {
        for n in scene.nodes() {
            visit(n, DMat4::IDENTITY, &mut seen, &mut out);
        }
    }
    out
}

/// World transform of the first node (in any scene) that instantiates mesh `mesh_index`;
/// identity when no node does.
pub(crate) fn world_transform_of_mesh(doc: &gltf::Document, mesh_index: usize) -> DMat4 {
    fn visit(node: gltf::Node<'_>, parent: Mat4, mesh_index: usize) -> Option<Mat4> {
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if node.mesh().map(|m| m.index()) == Some(mesh_index) {
            return Some(world);
        }
        node.children().find_map(|c| visit(c, world, mesh_index))
    }
    let roots: Vec<gltf::Node<'_>> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => Vec::new(),
    };
    roots
        .into_iter()
        .find_map(|n| visit(n, Mat4::IDENTITY, mesh_index))
        .map(|m| m.as_dmat4())
        .unwrap_or(DMat4::IDENTITY)
}
