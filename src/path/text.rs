//! The `grid` font (`--font grid`): our own small stroke font drawn on a 4 × 6 grid, scenebake's
//! only font before the Hershey fonts ([`super::font`]) came.
//!
//! Glyphs cover A–Z (lower case maps to upper case), 0–9, space and common punctuation
//! `. , ! ? - + : ; ' " / ( ) = _ * < > # %`. Coordinates are in grid units: the baseline is
//! y = 0, capitals are 6 high ([`CAP_HEIGHT`]) and 4 wide, advance 5 per character.

use glam::DVec2;

use crate::error::Result;

/// Height of a capital letter in grid units.
pub const CAP_HEIGHT: f64 = 6.0;
/// Horizontal advance per character, in grid units.
pub const ADVANCE: f64 = 5.0;
/// Distance between baselines of successive lines (`\n` in the text), in grid units.
pub const LINE_HEIGHT: f64 = 9.0;

/// Strokes of a glyph: `|` separates strokes, spaces separate `x,y` points.
pub(crate) fn grid_glyph(c: char) -> Option<&'static str> {
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

/// The strokes of a grid glyph, parsed.
pub(crate) fn parse_grid_glyph(spec: &str) -> Vec<Vec<DVec2>> {
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

/// Lays out `text` in the default font ([`super::font::DEFAULT`]); see [`super::font::layout`].
///
/// # Errors
/// As [`super::font::layout`].
pub fn layout(text: &str) -> Result<super::font::TextLayout> {
    super::font::layout(&super::font::Font::builtin(super::font::DEFAULT)?, text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::font::{self, Font};

    #[test]
    fn every_glyph_parses_inside_its_cell() {
        for c in ('A'..='Z')
            .chain('0'..='9')
            .chain(".,!?-+:;'\"/()=_*<>#%".chars())
        {
            let g = parse_grid_glyph(grid_glyph(c).unwrap());
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
    fn grid_layout_centres_and_rejects_unknown() {
        let grid = Font::builtin("grid").unwrap();
        let l = font::layout(&grid, "HELLO").unwrap();
        assert_eq!(l.extent, DVec2::new(24.0, 6.0));
        let xs = l.strokes.iter().flat_map(|(s, _)| s).map(|p| p.x);
        let (lo, hi) = xs.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
        assert!((lo + 12.0).abs() < 1e-12 && (hi - 12.0).abs() < 1e-12);
        let e = font::layout(&grid, "héllo").unwrap_err().to_string();
        assert!(
            e.contains("`text`") && e.contains("'é'") && e.contains("grid"),
            "{e}"
        );
        assert!(font::layout(&grid, "  ").is_err());
        assert!(font::layout(&grid, "hello world").is_ok());
    }
}
