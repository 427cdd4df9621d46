//! The labs' `.tet` tetrahedral mesh format.
//!
//! ```text
//! tet N M          header: N points, M tetrahedra
//! x y z            N lines of point coordinates
//! a b c d          M lines of four zero-based point indices
//! ```
//! Springs go on the tetrahedra's edges; the boundary (faces used by one tetrahedron only,
//! oriented outwards) is the exported surface.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// Reads a `.tet` file.
///
/// # Errors
/// [`Error::Io`] when unreadable; [`Error::Parse`] with the line for a bad header, a short file,
/// non-finite coordinates or out-of-range indices.
pub fn load_tet(path: &Path) -> Result<Mesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8_lossy(&bytes);
    parse_tet(&text, path)
}

/// Parses `.tet` text; `path` is only used in messages.
pub fn parse_tet(text: &str, path: &Path) -> Result<Mesh> {
    let err = |line: usize, message: String| Error::Parse {
        path: path.into(),
        line: Some(line),
        message: message.into(),
    };
    // Non-empty lines with their one-based numbers.
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (header_line, header) = lines
        .next()
        .ok_or_else(|| err(1, "empty file: expected a `tet N M` header".into()))?;
    let words: Vec<&str> = header.split_whitespace().collect();
    let (n, m) = match words.as_slice() {
        ["tet", n, m] => match (n.parse::<usize>(), m.parse::<usize>()) {
            (Ok(n), Ok(m)) => (n, m),
            _ => {
                return Err(err(
                    header_line,
                    format!("bad header `{header}`: counts must be whole numbers"),
                ))
            }
        },
        _ => {
            return Err(err(
                header_line,
                format!("bad header `{header}`: expected `tet N M`"),
            ))
        }
    };
    if n < 4 || m == 0 {
        return Err(err(
            header_line,
            format!("header announces {n} points and {m} tetrahedra: nothing to simulate"),
        ));
    }
    let mut rows = Rows {
        lines,
        last_line: header_line,
        path,
    };
    let mut positions = Vec::with_capacity(n);
    for k in 0..n {
        let (line, c) = rows.next::<f64, 3>(k, n, ("point", "points"), "numbers")?;
        if c.iter().any(|v| !v.is_finite()) {
            return Err(err(line, format!("point {k}: non-finite coordinate")));
        }
        positions.push(DVec3::from_array(c));
    }
    let mut tets = Vec::with_capacity(m);
    for k in 0..m {
        let (line, idx) = rows.next::<usize, 4>(k, m, ("tetrahedron", "tetrahedra"), "indices")?;
        if let Some(bad) = idx.iter().find(|&&i| i >= n) {
            return Err(err(
                line,
                format!("tetrahedron {k}: index {bad} out of range (0..{n})"),
            ));
        }
        tets.push(idx.map(|i| i as u32));
    }
    let triangles = boundary(&positions, &tets);
    let mut mesh = Mesh::from_triangles(path.display().to_string(), positions, triangles);
    mesh.tets = tets;
    Ok(mesh)
}

/// The data lines of a `.tet` file, read one fixed-width row at a time.
struct Rows<'a, I> {
    lines: I,
    last_line: usize,
    path: &'a Path,
}

impl<'a, 'l, I: Iterator<Item = (usize, &'l str)>> Rows<'a, I> {
    /// Row `k` of `count` elements named `what` (plural `plural`), holding exactly `N` values
    /// (`unit` names them in errors). Returns the row's line number and values.
    fn next<T: std::str::FromStr, const N: usize>(
        &mut self,
        k: usize,
        count: usize,
        (what, plural): (&str, &str),
        unit: &str,
    ) -> Result<(usize, [T; N])> {
        let err = |line: usize, message: String| Error::Parse {
            path: self.path.into(),
            line: Some(line),
            message: message.into(),
        };
        let (line, l) = self.lines.next().ok_or_else(|| {
            err(
                self.last_line,
                format!("file ends after {k} of the {count} {plural} the header announces"),
            )
        })?;
        self.last_line = line;
        let values: Vec<T> = l
            .split_whitespace()
            .map(str::parse)
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| {
                err(
                    line,
                    format!("{what} {k}: expected {N} {unit}, found `{l}`"),
                )
            })?;
        let found = values.len();
        let row: [T; N] = values.try_into().map_err(|_| {
            err(
                line,
                format!("{what} {k}: expected {N} {unit}, found {found}"),
            )
        })?;
        Ok((line, row))
    }
}

/// Faces used by exactly one tetrahedron, wound so their normal points away from the fourth
/// vertex (outwards).
fn boundary(positions: &[DVec3], tets: &[[u32; 4]]) -> Vec<[u32; 3]> {
    let mut count: HashMap<[u32; 3], (usize, [u32; 3])> = HashMap::new();
    for t in tets {
        for (face, opposite) in [
            ([t[0], t[1], t[2]], t[3]),
            ([t[0], t[1], t[3]], t[2]),
            ([t[0], t[2], t[3]], t[1]),
            ([t[1], t[2], t[3]], t[0]),
        ] {
            let [a, b, c] = face.map(|i| positions[i as usize]);
            let d = positions[opposite as usize];
            let outward = if (b - a).cross(c - a).dot(d - a) > 0.0 {
                [face[0], face[2], face[1]]
            } else {
                face
            };
            let mut key = face;
            key.sort_unstable();
            count.entry(key).or_insert((0, outward)).0 += 1;
        }
    }
    let mut faces: Vec<[u32; 3]> = count
        .into_values()
        .filter(|(n, _)| *n == 1)
        .map(|(_, f)| f)
        .collect();
    faces.sort_unstable(); // deterministic order
    faces
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_tet_has_four_outward_faces() {
        let m = parse_tet(
            "tet 4 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 1 2 3\n",
            Path::new("a.tet"),
        )
        .unwrap();
        assert_eq!(m.triangles.len(), 4);
        let centre = DVec3::splat(0.25);
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            assert!(
                (b - a).cross(c - a).dot(a - centre) > 0.0,
                "face {t:?} points inwards"
            );
        }
    }

    #[test]
    fn short_file_names_what_is_missing() {
        let e = parse_tet("tet 4 1\n0 0 0\n1 0 0\n", Path::new("a.tet"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a.tet:3") && e.contains("2 of the 4 points"),
            "{e}"
        );
        let e = parse_tet(
            "tet 4 1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n0 1 2 9\n",
            Path::new("a.tet"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("out of range"), "{e}");
    }
}
