//! Point lists (`--points FILE.csv`): one `x,y` or `x,y,z` per line; a blank line lifts the pen
//! (starts a new stroke); lines starting with `#` are comments.
//!
//! `x,y` points are drawing-plane coordinates (scene units, relative to the plane's centre);
//! `x,y,z` points are world positions used as given. A file uses one form throughout.

use std::path::Path;

use glam::DVec3;

use crate::error::{Error, Result};

/// The strokes of a point file.
#[derive(Debug, Clone, PartialEq)]
pub struct PointStrokes {
    /// Strokes in file order; 2-D points have z = 0.
    pub strokes: Vec<Vec<DVec3>>,
    /// Whether the points are 3-D world positions (`x,y,z`) rather than plane coordinates.
    pub world: bool,
}

/// Parses the text of a point file (`path` only names it in errors; [`crate::io::drawing`]
/// reads the file).
///
/// # Errors
/// [`Error::Parse`] with the line for a malformed or non-finite number or mixed 2-D/3-D lines;
/// [`Error::InvalidInput`] for a file without points.
pub fn parse_points(path: &Path, text: &str) -> Result<PointStrokes> {
    let mut strokes: Vec<Vec<DVec3>> = vec![Vec::new()];
    let mut dims: Option<usize> = None;
    for (idx, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.starts_with('#') {
            continue;
        }
        if line.is_empty() {
            if !strokes.last().is_some_and(Vec::is_empty) {
                strokes.push(Vec::new());
            }
            continue;
        }
        let parse_err = |message: String| Error::Parse {
            path: path.into(),
            line: Some(idx + 1),
            message: message.into(),
        };
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if !(2..=3).contains(&fields.len()) {
            return Err(parse_err(format!("`{line}`: expected x,y or x,y,z")));
        }
        match dims {
            None => dims = Some(fields.len()),
            Some(d) if d != fields.len() => {
                return Err(parse_err(format!(
                    "`{line}`: has {} numbers but earlier lines have {d}",
                    fields.len()
                )))
            }
            _ => {}
        }
        let mut v = [0.0; 3];
        for (slot, f) in v.iter_mut().zip(&fields) {
            *slot = f
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| parse_err(format!("`{f}` is not a finite number")))?;
        }
        strokes
            .last_mut()
            .expect("non-empty")
            .push(DVec3::from_array(v));
    }
    strokes.retain(|s| !s.is_empty());
    if strokes.is_empty() {
        return Err(Error::invalid(
            path,
            "no points (expected lines of x,y or x,y,z)",
        ));
    }
    Ok(PointStrokes {
        strokes,
        world: dims == Some(3),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blank_lines_split_strokes() {
        let p = parse_points(Path::new("p.csv"), "# a\n0,0\n1,0\n\n\n2, 0\n3,1\n").unwrap();
        assert_eq!(p.strokes.len(), 2);
        assert!(!p.world);
        assert_eq!(p.strokes[1][1], DVec3::new(3.0, 1.0, 0.0));
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_points(Path::new("p.csv"), "0,0\n1,x\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.csv:2"), "{e}");
        let e = parse_points(Path::new("p.csv"), "0,0\n1,1,1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.csv:2"), "{e}");
        assert!(parse_points(Path::new("p.csv"), "\n# nothing\n").is_err());
    }
}
