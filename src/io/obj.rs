//! Wavefront OBJ reader for cloth and shells.
//!
//! A small line-oriented reader rather than `tobj`: `tobj` renumbers positions per object in
//! first-use order, which loses both the file order that `--pin index:` promises and the positions
//! that several groups share (one body made of many `g` blocks), and its errors carry no line
//! number. The tests cross-check this reader against `tobj` on the real corpus.
//!
//! Particles are the file's `v` positions (those used by a face), in file order. Render vertices
//! are the distinct (position, texture coordinate) pairs used by faces. Polygons are split into
//! triangle fans. `vn` normals are read past: normals are recomputed from the simulated surface.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::mesh::{drop_degenerate, Mesh, RenderVertex};

/// Options for reading an OBJ file.
#[derive(Debug, Clone, Default)]
pub struct ObjOptions {
    /// Keep only the faces of this `o` object or `g` group (default: every face, one body).
    pub object: Option<String>,
}

/// Reads an OBJ file into one body.
///
/// # Errors
/// [`Error::Io`] when the file cannot be read, [`Error::Parse`] with the line number for malformed
/// or out-of-range data, [`Error::InvalidInput`] when no usable face remains; [`Error::Value`]
/// naming the file and its objects when `options.object` names none with faces (the job names
/// the option).
pub fn load_obj(path: &Path, options: &ObjOptions) -> Result<Mesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8(bytes).map_err(|e| Error::Parse {
        path: path.into(),
        line: None,
        message: format!(
            "not a text file (invalid UTF-8 at byte {})",
            e.utf8_error().valid_up_to()
        )
        .into(),
    })?;
    parse_obj(&text, path, options)
}

struct Face {
    corners: Vec<(u32, Option<u32>)>,
    groups: Vec<String>,
    object: Option<String>,
}

/// Parses OBJ text; `path` is only used in messages.
pub fn parse_obj(text: &str, path: &Path, options: &ObjOptions) -> Result<Mesh> {
    let mut positions: Vec<DVec3> = Vec::new();
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    let mut normal_count = 0usize;
    let mut faces: Vec<Face> = Vec::new();
    let mut current_groups: Vec<String> = Vec::new();
    let mut current_object: Option<String> = None;
    let mut known_names: Vec<String> = Vec::new();

    for (line_index, raw) in text.lines().enumerate() {
        let line_no = line_index + 1;
        let err = |message: String| Error::Parse {
            path: path.into(),
            line: Some(line_no),
            message: message.into(),
        };
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let xyz = parse_floats::<3>(&mut words)
                    .ok_or_else(|| err(format!("`v` needs three numbers, found `{line}`")))?;
                if xyz.iter().any(|c| !c.is_finite()) {
                    return Err(err(format!("non-finite coordinate in `{line}`")));
                }
                positions.push(DVec3::from_array(xyz));
            }
            "vt" => {
                let mut rest = words.clone();
                let u = parse_floats::<1>(&mut rest)
                    .ok_or_else(|| err(format!("`vt` needs a number, found `{line}`")))?[0];
                let v = match rest.next() {
                    None => 0.0,
                    Some(w) => w
                        .parse::<f64>()
                        .map_err(|_| err(format!("bad texture coordinate `{w}`")))?,
                };
                if !u.is_finite() || !v.is_finite() {
                    return Err(err(format!("non-finite texture coordinate in `{line}`")));
                }
                uvs.push([u as f32, v as f32]);
            }
            "vn" => normal_count += 1,
            "f" => {
                let mut corners = Vec::new();
                for word in words {
                    corners.push(
                        parse_corner(word, positions.len(), uvs.len(), normal_count)
                            .map_err(&err)?,
                    );
                }
                if corners.len() < 3 {
                    return Err(err(format!(
                        "a face needs at least 3 corners, found {}",
                        corners.len()
                    )));
                }
                let mut groups = current_groups.clone();
                if let Some(o) = &current_object {
                    groups.push(o.clone());
                }
                faces.push(Face {
                    corners,
                    groups,
                    object: current_object.clone(),
                });
            }
            "g" => {
                current_groups = words.map(str::to_owned).collect();
                known_names.extend(current_groups.iter().cloned());
            }
            "o" => {
                let name = words.collect::<Vec<_>>().join(" ");
                current_object = (!name.is_empty()).then_some(name.clone());
                known_names.push(name);
            }
            // Materials, smoothing groups, lines and points do not affect the body.
            "mtllib" | "usemtl" | "s" | "l" | "p" | "vp" | "cstype" | "deg" | "curv" | "surf"
            | "parm" | "end" | "bmat" | "step" | "curv2" | "trim" | "hole" | "scrv" | "sp"
            | "con" | "mg" | "lod" | "usemap" | "maplib" | "shadow_obj" | "trace_obj" | "ctech"
            | "stech" | "bevel" | "c_interp" | "d_interp" => {}
            other => {
                return Err(err(format!(
                    "unknown statement `{other}` (is this an OBJ file?)"
                )))
            }
        }
    }

    // Positions used by a face of the file, before an object is picked: those of the other
    // objects are left out by choice, not unused.
    let mut used_in_file = vec![false; positions.len()];
    for f in &faces {
        for &(p, _) in &f.corners {
            used_in_file[p as usize] = true;
        }
    }
    if let Some(object) = &options.object {
        faces.retain(|f| f.groups.iter().any(|g| g == object));
        if faces.is_empty() {
            known_names.sort();
            known_names.dedup();
            known_names.retain(|n| !n.is_empty());
            return Err(Error::value(format!(
                "{}: no object or group named `{object}` with faces (known: {})",
                path.display(),
                if known_names.is_empty() {
                    "none".into()
                } else {
                    known_names.join(", ")
                }
            )));
        }
    }
    if faces.is_empty() {
        return Err(Error::invalid(
            path,
            "no faces: a cloth needs triangles or polygons (`f` lines)",
        ));
    }
    let mut mesh = build_mesh(path, &positions, &uvs, &faces, &used_in_file)?;
    for f in &faces {
        if let Some(o) = &f.object {
            if !mesh.objects.contains(o) {
                mesh.objects.push(o.clone());
            }
        }
    }
    Ok(mesh)
}

fn build_mesh(
    path: &Path,
    positions: &[DVec3],
    uvs: &[[f32; 2]],
    faces: &[Face],
    used_in_file: &[bool],
) -> Result<Mesh> {
    // Particles: used positions in file order.
    let mut used = vec![false; positions.len()];
    for f in faces {
        for &(p, _) in &f.corners {
            used[p as usize] = true;
        }
    }
    let mut particle_of_position = vec![u32::MAX; positions.len()];
    let mut mesh = Mesh {
        name: path.display().to_string(),
        ..Default::default()
    };
    for (i, p) in positions.iter().enumerate() {
        if used[i] {
            particle_of_position[i] = mesh.positions.len() as u32;
            mesh.positions.push(*p);
            mesh.file_index.push(i as u32);
        }
    }
    // Positions no face of the file uses (those of objects not picked are not reported).
    let unused = (0..positions.len())
        .filter(|&i| !used[i] && !used_in_file[i])
        .count();
    if unused > 0 {
        mesh.warnings.push(if unused == 1 {
            "1 position is used by no face and was left out".to_owned()
        } else {
            format!("{unused} positions are used by no face and were left out")
        });
    }

    let mut render_index: HashMap<(u32, Option<u32>), u32> = HashMap::new();
    let mut groups: BTreeMap<String, Vec<u32>> = BTreeMap::new();
    for f in faces {
        let corner_ids: Vec<(u32, u32)> = f
            .corners
            .iter()
            .map(|&(p, t)| {
                let particle = particle_of_position[p as usize];
                let next = mesh.render_vertices.len() as u32;
                let r = *render_index.entry((particle, t)).or_insert_with(|| {
                    mesh.render_vertices.push(RenderVertex {
                        particle,
                        uv: t.map(|t| uvs[t as usize]),
                    });
                    next
                });
                (particle, r)
            })
            .collect();
        for k in 1..corner_ids.len() - 1 {
            let tri = [corner_ids[0], corner_ids[k], corner_ids[k + 1]];
            mesh.triangles.push(tri.map(|c| c.0));
            mesh.render_triangles.push(tri.map(|c| c.1));
        }
        for g in &f.groups {
            groups
                .entry(g.clone())
                .or_default()
                .extend(corner_ids.iter().map(|c| c.0));
        }
    }
    for set in groups.values_mut() {
        set.sort_unstable();
        set.dedup();
    }
    mesh.groups = groups;

    let dropped = drop_degenerate(
        &mesh.positions,
        &mut mesh.triangles,
        Some(&mut mesh.render_triangles),
    );
    if dropped > 0 {
        mesh.warnings.push(format!(
            "{dropped} degenerate triangles (zero area or repeated corner) skipped"
        ));
    }
    if mesh.triangles.is_empty() {
        return Err(Error::invalid(
            path,
            "every face is degenerate (zero area): nothing to simulate",
        ));
    }
    Ok(mesh)
}

fn parse_floats<'a, const N: usize>(words: &mut impl Iterator<Item = &'a str>) -> Option<[f64; N]> {
    let mut out = [0.0; N];
    for slot in &mut out {
        *slot = words.next()?.parse().ok()?;
    }
    Some(out)
}

/// Parses one `f` corner (`v`, `v/vt`, `v//vn`, `v/vt/vn`; negative = relative) into zero-based
/// (position, texture coordinate) indices.
fn parse_corner(
    word: &str,
    n_pos: usize,
    n_uv: usize,
    n_normal: usize,
) -> Result<(u32, Option<u32>), String> {
    let mut parts = word.split('/');
    let resolve = |s: &str, count: usize, what: &str| -> Result<u32, String> {
        let i: i64 = s
            .parse()
            .map_err(|_| format!("bad {what} index `{s}` in face corner `{word}`"))?;
        let zero_based = match i {
            0 => {
                return Err(format!(
                    "{what} index 0 in face corner `{word}` (OBJ indices start at 1)"
                ))
            }
            i if i > 0 => i - 1,
            i => count as i64 + i,
        };
        if zero_based < 0 || zero_based >= count as i64 {
            return Err(format!(
                "{what} index {i} in face corner `{word}` is out of range (the file has {count} so far)"
            ));
        }
        Ok(zero_based as u32)
    };
    let p = resolve(parts.next().unwrap_or(""), n_pos, "position")?;
    let t = match parts.next() {
        None | Some("") => None,
        Some(s) => Some(resolve(s, n_uv, "texture")?),
    };
    if let Some(s) = parts.next().filter(|s| !s.is_empty()) {
        resolve(s, n_normal, "normal")?;
    }
    Ok((p, t))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Mesh> {
        parse_obj(text, Path::new("t.obj"), &ObjOptions::default())
    }

    #[test]
    fn quads_become_two_triangles_and_seams_split_render_vertices() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 9 9\nf 1/1 2/2 3/3 4/4\nf 1/5 3/3 2/2\n").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(
            m.render_vertices.len(),
            5,
            "position 1 with two UVs is two render vertices"
        );
        assert!(m.has_uvs());
    }

    #[test]
    fn groups_share_positions_and_are_recorded() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ng a\nf 1 2 3\ng b\nf 2 4 3\n").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.groups["a"], vec![0, 1, 2]);
        assert_eq!(m.groups["b"], vec![1, 2, 3]);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.obj:3") && e.contains("out of range"), "{e}");
        let e = parse("v 0 0 nan\n").unwrap_err().to_string();
        assert!(e.contains(":1") && e.contains("non-finite"), "{e}");
        let e = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("index 0"), "{e}");
        assert!(parse("v 0 0 0\n")
            .unwrap_err()
            .to_string()
            .contains("no faces"));
    }

    #[test]
    fn negative_indices_are_relative() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n").unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }
}
