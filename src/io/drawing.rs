//! Drawings and fonts the IK pen follows: point files, SVG files and font files, read here and
//! parsed by [`crate::path`].

use std::path::Path;

use crate::error::{Error, Result};
use crate::path::font::{Font, FontSource};
use crate::path::points::{parse_points, PointStrokes};
use crate::path::svg::{parse_svg, Polyline};

/// Reads a point file ([`parse_points`]).
///
/// # Errors
/// [`Error::Io`] when unreadable, then as [`parse_points`].
pub fn read_points(path: &Path) -> Result<PointStrokes> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_points(path, &text)
}

/// Reads an SVG file and flattens its visible shapes ([`parse_svg`]).
///
/// # Errors
/// [`Error::Io`] when unreadable, then as [`parse_svg`].
pub fn read_svg(path: &Path) -> Result<Vec<Polyline>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_svg(&text, path)
}

/// Loads a font by name ([`Font::load`]): a built-in font, or a TrueType/OpenType file read
/// here.
///
/// # Errors
/// As [`Font::load`]; [`Error::Io`] for an unreadable file; as [`Font::from_file_data`].
pub fn load_font(spec: &str) -> Result<Font> {
    match Font::load(spec)? {
        FontSource::Builtin(font) => Ok(font),
        FontSource::File(path) => {
            let data = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
            Font::from_file_data(&path, data)
        }
    }
}
