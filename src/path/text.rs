//! Single-stroke lettering: a small built-in stroke font (our own, drawn on a 4 × 6 grid) and
//! the layout of a string into pen strokes.
//!
//! Glyphs cover A–Z (lower case maps to upper case), 0–9, space and common punctuation
//! `. , ! ? - + : ; ' " / ( ) = _ * < > # %`. Coordinates are in grid units: the baseline is
//! y = 0, capitals are 6 high ([`CAP_HEIGHT`]) and 4 wide, advance 5 per character.

use glam::DVec2;

use crate::error::{Error, Result};

/// Height of a capital letter in grid units.
pub const CAP_HEIGHT: f64 = 6.0;
/// Horizontal advance per character, in grid units.
pub const ADVANCE: f64 = 5.0;
/// Distance between baselines of successive lines (`\n` in the text), in grid units.
pub const LINE_HEIGHT: f64 = 9.0;

/// Strokes of a glyph: `|` separates strokes, spaces separate `x,y` points.
fn glyph(c: char) -> Option<&'static str> {
    Some(match c {
        'A' => "0,0 2,6 4,0|1,2 3,2",
        'B' => "0,0 0,6 3,6 4,5 4,4 3,3 0,3|3,3 4,2 4,1 3,0 0,0",
        'C' => "4,5 3,6 1,6 0,5 0,1 1,0 3,0 4,1",
        'D' => "0,0 0,6 2,6 4,4 4,2 2,0 0,0",
        'E' => "4,6 0,6 0,0 4,0|0,3 3,3",
        'F' => "4,6 0,6 0,0|0,3 3,3",
        'G' => "4,5 3,6 1,6 0,5 0,1 1,0 3,0 4,1 4,3 2,3",
        'H' => "0,6 0,0|4,6 4,0|0,3 4,3",
        'I' => "1,6 3,6|2,6 2,0|1,0 3,0",
        'J' => "4,6 4,1 3,0 1,0 0,1",
        'K' => "0,6 0,0|4,6 0,2|1,3 4,0",
        'L' => "0,6 0,0 4,0",
        'M' => "0,0 0,6 2,3 4,6 4,0",
        'N' => "0,0 0,6 4,0 4,6",
        'O' => "1,0 0,1 0,5 1,6 3,6 4,5 4,1 3,0 1,0",
        'P' => "0,0 0,6 3,6 4,5 4,4 3,3 0,3",
        'Q' => "1,0 0,1 0,5 1,6 3,6 4,5 4,1 3,0 1,0|2,2 4,0",
        'R' => "0,0 0,6 3,6 4,5 4,4 3,3 0,3|2,3 4,0",
        'S' => "4,5 3,6 1,6 0,5 0,4 1,3 3,3 4,2 4,1 3,0 1,0 0,1",
        'T' => "0,6 4,6|2,6 2,0",
        'U' => "0,6 0,1 1,0 3,0 4,1 4,6",
        'V' => "0,6 2,0 4,6",
        'W' => "0,6 1,0 2,4 3,0 4,6",
        'X' => "0,6 4,0|4,6 0,0",
        'Y' => "0,6 2,3 4,6|2,3 2,0",
        'Z' => "0,6 4,6 0,0 4,0",
        '0' => "1,0 0,1 0,5 1,6 3,6 4,5 4,1 3,0 1,0|1,1 3,5",
        '1' => "1,5 2,6 2,0|1,0 3,0",
        '2' => "0,5 1,6 3,6 4,5 4,4 0,0 4,0",
        '3' => "0,5 1,6 3,6 4,5 4,4 3,3 1,3|3,3 4,2 4,1 3,0 1,0 0,1",
        '4' => "3,0 3,6 0,2 4,2",
        '5' => "4,6 0,6 0,3 3,3 4,2 4,1 3,0 0,0",
        '6' => "4,5 3,6 1,6 0,5 0,1 1,0 3,0 4,1 4,2 3,3 0,3",
        '7' => "0,6 4,6 1,0",
        '8' => "1,3 0,4 0,5 1,6 3,6 4,5 4,4 3,3 1,3 0,2 0,1 1,0 3,0 4,1 4,2 3,3",
        '9' => "4,3 1,3 0,4 0,5 1,6 3,6 4,5 4,1 3,0 1,0 0,1",
        '.' => "2,0.5 2,0",
        ',' => "2,0.5 2,0 1.5,-1",
        '!' => "2,6 2,2|2,0.5 2,0",
        '?' => "0,5 1,6 3,6 4,5 4,4 2,3 2,2|2,0.5 2,0",
        '-' => "1,3 3,3",
        '+' => "0,3 4,3|2,1 2,5",
        ':' => "2,4.5 2,4|2,1.5 2,1",
        ';' => "2,4.5 2,4|2,1.5 2,1 1.5,0",
        '\'' => "2,6 2,4.5",
        '"' => "1,6 1,4.5|3,6 3,4.5",
        '/' => "0,0 4,6",
        '(' => "3,6 2,5 1.5,3 2,1 3,0",
        ')' => "1,6 2,5 2.5,3 2,1 1,0",
        '=' => "0,4 4,4|0,2 4,2",
        '_' => "0,-0.5 4,-0.5",
        '*' => "2,5 2,1|0.3,4 3.7,2|0.3,2 3.7,4",
        '<' => "4,5 0,3 4,1",
        '>' => "0,5 4,3 0,1",
        '#' => "1,0 1.5,6|2.5,0 3,6|0,2 4,2|0,4 4,4",
        '%' => "0,0 4,6|0.5,6 0,5.5 0.5,5 1,5.5 0.5,6|3.5,1 3,0.5 3.5,0 4,0.5 3.5,1",
        ' ' => "",
        _ => return None,
    })
}

fn parse_glyph(spec: &str) -> Vec<Vec<DVec2>> {
    spec.split('|')
        .filter(|s| !s.trim().is_empty())
        .map(|stroke| {
            stroke
                .split_whitespace()
                .map(|pt| {
                    let (x, y) = pt.split_once(',').expect("glyph table point");
                    DVec2::new(x.parse().expect("glyph x"), y.parse().expect("glyph y"))
                })
                .collect()
        })
        .collect()
}

/// Whether the font has a glyph for `c` (after upper-casing).
pub fn has_glyph(c: char) -> bool {
    c == '\n' || glyph(c.to_ascii_uppercase()).is_some()
}

/// Lays out `text` as open strokes in grid units, the block centred on the origin (lines
/// separated by `\n`, each line centred). Returns the strokes and the block's size (width,
/// height) in grid units.
///
/// # Errors
/// [`Error::InvalidOption`] (`--text`) naming the first character without a glyph, or for a text
/// with nothing to draw.
pub fn layout(text: &str) -> Result<(Vec<Vec<DVec2>>, DVec2)> {
    if let Some(bad) = text.chars().find(|&c| !has_glyph(c)) {
        return Err(Error::option("--text", format!("no glyph for {bad:?}; available: A-Z, 0-9, space and . , ! ? - + : ; ' \" / ( ) = _ * < > # %")));
    }
    let lines: Vec<&str> = text.lines().collect();
    let widest = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0);
    let width = (widest as f64 * ADVANCE - (ADVANCE - 4.0)).max(0.0);
    let height = CAP_HEIGHT + LINE_HEIGHT * (lines.len().max(1) - 1) as f64;
    let mut strokes = Vec::new();
    for (row, line) in lines.iter().enumerate() {
        let count = line.chars().count();
        let line_width = (count as f64 * ADVANCE - (ADVANCE - 4.0)).max(0.0);
        let x0 = -line_width / 2.0;
        let y0 = height / 2.0 - CAP_HEIGHT - LINE_HEIGHT * row as f64;
        for (col, c) in line.chars().enumerate() {
            let offset = DVec2::new(x0 + ADVANCE * col as f64, y0);
            for s in parse_glyph(glyph(c.to_ascii_uppercase()).unwrap_or("")) {
                strokes.push(s.into_iter().map(|p| p + offset).collect());
            }
        }
    }
    if strokes.is_empty() {
        return Err(Error::option(
            "--text",
            "nothing to draw (the text is empty or only spaces)",
        ));
    }
    Ok((strokes, DVec2::new(width, height)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_glyph_parses_inside_its_cell() {
        for c in ('A'..='Z')
            .chain('0'..='9')
            .chain(".,!?-+:;'\"/()=_*<>#%".chars())
        {
            let g = parse_glyph(glyph(c).unwrap());
            assert!(!g.is_empty(), "{c}");
            for s in &g {
                assert!(s.len() >= 2, "{c}: stroke of one point");
                assert!(
                    s.iter()
                        .all(|p| (0.0..=4.0).contains(&p.x) && (-1.0..=6.0).contains(&p.y)),
                    "{c}"
                );
            }
        }
    }

    #[test]
    fn layout_centres_and_rejects_unknown() {
        let (strokes, size) = layout("HELLO").unwrap();
        assert_eq!(size, DVec2::new(24.0, 6.0));
        let xs = strokes.iter().flatten().map(|p| p.x);
        let (lo, hi) = xs.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
        assert!((lo + 12.0).abs() < 1e-12 && (hi - 12.0).abs() < 1e-12);
        assert!(layout("héllo").unwrap_err().to_string().contains("--text"));
        assert!(layout("  ").is_err());
        assert!(layout("hello world").is_ok());
    }
}
