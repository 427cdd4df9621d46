//! Pin specifications: which particles are held fixed.
//!
//! Spellings (repeatable `--pin`):
//! - `index:I,J,...` zero-based particle indices in the file's order of positions;
//! - `box:X0,Y0,Z0,X1,Y1,Z1` every particle inside the axis-aligned box (bounds inclusive, in
//!   either order);
//! - `group:NAME` every particle of an OBJ group or object.

use std::str::FromStr;

use glam::DVec3;

use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::spec::parse_numbers;

/// One parsed `--pin` value.
#[derive(Debug, Clone, PartialEq)]
pub enum PinSpec {
    /// Particles by zero-based index in file order.
    Index(Vec<u32>),
    /// Particles inside an axis-aligned box (min, max corners, metres).
    Box(DVec3, DVec3),
    /// Particles of a named OBJ group or object.
    Group(String),
}

impl FromStr for PinSpec {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self> {
        let bad = |m: String| Error::value(format!("`{s}`: {m}"));
        let (kind, rest) = s.split_once(':').ok_or_else(|| {
            bad("expected index:I,J,..., box:X0,Y0,Z0,X1,Y1,Z1 or group:NAME".into())
        })?;
        match kind.trim() {
            "index" => {
                let indices = rest
                    .split(',')
                    .map(|w| {
                        w.trim()
                            .parse::<u32>()
                            .map_err(|_| bad(format!("`{}` is not a particle index", w.trim())))
                    })
                    .collect::<Result<Vec<u32>>>()?;
                Ok(PinSpec::Index(indices))
            }
            "box" => {
                let c = parse_numbers::<6>(rest, "box:X0,Y0,Z0,X1,Y1,Z1")?;
                let (a, b) = (DVec3::new(c[0], c[1], c[2]), DVec3::new(c[3], c[4], c[5]));
                Ok(PinSpec::Box(a.min(b), a.max(b)))
            }
            "group" if !rest.trim().is_empty() => Ok(PinSpec::Group(rest.trim().to_owned())),
            "group" => Err(bad("group name is empty".into())),
            other => Err(bad(format!(
                "unknown pin kind `{other}` (use index, box or group)"
            ))),
        }
    }
}

impl std::fmt::Display for PinSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PinSpec::Index(i) => write!(
                f,
                "index:{}",
                i.iter().map(u32::to_string).collect::<Vec<_>>().join(",")
            ),
            PinSpec::Box(a, b) => write!(f, "box:{},{},{},{},{},{}", a.x, a.y, a.z, b.x, b.y, b.z),
            PinSpec::Group(g) => write!(f, "group:{g}"),
        }
    }
}

impl PinSpec {
    /// The particles this spec selects on `mesh`, sorted and unique.
    ///
    /// # Errors
    /// [`Error::EmptyPin`] when nothing is selected; [`Error::Value`] for an index past the file's
    /// positions or a position no face uses, or an unknown group (the job names `--pin`).
    pub fn select(&self, mesh: &Mesh) -> Result<Vec<u32>> {
        let mut out: Vec<u32> = match self {
            PinSpec::Index(indices) => {
                let file_count = mesh.file_index.last().map_or(0, |&i| i as usize + 1);
                indices
                    .iter()
                    .map(|&i| {
                        mesh.file_index.binary_search(&i).map(|p| p as u32).map_err(|_| {
                            let why = if (i as usize) < file_count { "is used by no face" } else { "is out of range" };
                            Error::value(
                                format!("`{self}`: particle {i} {why} ({} has {} particles, indices from 0)", mesh.name, mesh.positions.len()),
                            )
                        })
                    })
                    .collect::<Result<_>>()?
            }
            PinSpec::Box(lo, hi) => (0..mesh.positions.len() as u32)
                .filter(|&i| {
                    let p = mesh.positions[i as usize];
                    p.cmpge(*lo).all() && p.cmple(*hi).all()
                })
                .collect(),
            PinSpec::Group(name) => mesh.groups.get(name).cloned().ok_or_else(|| {
                let known: Vec<&str> = mesh.groups.keys().map(String::as_str).collect();
                Error::value(format!(
                    "`{self}`: {} has no group `{name}` (groups: {})",
                    mesh.name,
                    if known.is_empty() {
                        "none".into()
                    } else {
                        known.join(", ")
                    }
                ))
            })?,
        };
        out.sort_unstable();
        out.dedup();
        if out.is_empty() {
            let (lo, hi) = mesh.bounds();
            return Err(Error::EmptyPin {
                spec: self.to_string(),
                hint: format!(
                    "; the mesh spans {:.4?} to {:.4?}",
                    lo.to_array(),
                    hi.to_array()
                ),
            });
        }
        Ok(out)
    }
}

/// Marks every particle selected by any of `specs`; returns one flag per particle.
pub fn pinned_flags(mesh: &Mesh, specs: &[PinSpec]) -> Result<Vec<bool>> {
    let mut pinned = vec![false; mesh.positions.len()];
    for spec in specs {
        for i in spec.select(mesh)? {
            pinned[i as usize] = true;
        }
    }
    Ok(pinned)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Mesh {
        Mesh::from_triangles(
            "sq".into(),
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        )
    }

    #[test]
    fn specs_parse_and_select() {
        let m = square();
        assert_eq!(
            "index:3,1,1"
                .parse::<PinSpec>()
                .unwrap()
                .select(&m)
                .unwrap(),
            vec![1, 3]
        );
        assert_eq!(
            "box:-1,0.5,-1,2,2,1"
                .parse::<PinSpec>()
                .unwrap()
                .select(&m)
                .unwrap(),
            vec![2, 3]
        );
    }

    #[test]
    fn bad_specs_are_clear_errors() {
        for (spec, words) in [
            ("corner", "expected index"),
            ("index:a", "not a particle index"),
            ("box:1,2,3", "6 comma-separated"),
            ("ring:1", "unknown pin kind"),
            ("group:", "empty"),
        ] {
            // A value error; the job (or clap, or the scene reader) names `--pin`.
            let e = spec.parse::<PinSpec>().unwrap_err();
            assert!(matches!(e, Error::Value { .. }), "{spec}: {e}");
            let e = e.detail();
            assert!(e.starts_with('`') && e.contains(words), "{spec}: {e}");
        }
        let m = square();
        let e = "index:7"
            .parse::<PinSpec>()
            .unwrap()
            .select(&m)
            .unwrap_err()
            .to_string();
        assert!(e.contains("out of range"), "{e}");
        let e = "box:5,5,5,6,6,6"
            .parse::<PinSpec>()
            .unwrap()
            .select(&m)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("selects no particle") && e.contains("spans"),
            "{e}"
        );
        let e = "group:top"
            .parse::<PinSpec>()
            .unwrap()
            .select(&m)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no group"), "{e}");
    }
}
