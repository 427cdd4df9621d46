//! Fonts for `--text`: the Hershey single-stroke fonts shipped in `fonts/hershey/`, the old 4 × 6
//! grid font, and any TrueType/OpenType file (outlines flattened into closed strokes).
//!
//! A [`Font`] hands out [`Glyph`]s in its own units with y up and the baseline at y = 0; its
//! [`Font::cap_height`] (the height of `H`) is what `--size` sets. Text is not shaped: one glyph
//! per character, advanced by the glyph's own advance width, no kerning or ligatures.
//!
//! The Hershey data are Dr. A. V. Hershey's fonts (U.S. National Bureau of Standards) in James
//! Hurt's `.jhf` format, as distributed in Debian's `hershey-fonts-data` 0.1-1.1; see
//! `fonts/hershey/README.md` for the source and the terms of use.

use std::path::Path;

use glam::DVec2;

use crate::error::{Error, Result};

/// The built-in Hershey fonts: option name, file, description.
pub const HERSHEY_FONTS: [(&str, &str, &str); 8] = [
    (
        "simplex",
        "rowmans.jhf",
        "Roman simplex, single stroke (the default)",
    ),
    ("duplex", "rowmand.jhf", "Roman duplex, double stroke"),
    (
        "triplex",
        "rowmant.jhf",
        "Roman triplex, triple stroke with serifs",
    ),
    (
        "script",
        "scripts.jhf",
        "script simplex, single-stroke handwriting",
    ),
    (
        "script-complex",
        "scriptc.jhf",
        "script complex, double stroke",
    ),
    (
        "cursive",
        "cursive.jhf",
        "joined cursive handwriting, single stroke",
    ),
    ("sans", "futural.jhf", "Futura light, single stroke"),
    (
        "greek",
        "greek.jhf",
        "Greek simplex: Unicode Greek letters, digits, punctuation",
    ),
];

/// The old built-in font: capitals on a 4 × 6 grid (lower case drawn as upper case).
pub const GRID: &str = "grid";
/// The font used when `--font` is not given.
pub const DEFAULT: &str = "simplex";

fn hershey_data(file: &str) -> &'static str {
    match file {
        "rowmans.jhf" => include_str!("../../fonts/hershey/rowmans.jhf"),
        "rowmand.jhf" => include_str!("../../fonts/hershey/rowmand.jhf"),
        "rowmant.jhf" => include_str!("../../fonts/hershey/rowmant.jhf"),
        "scripts.jhf" => include_str!("../../fonts/hershey/scripts.jhf"),
        "scriptc.jhf" => include_str!("../../fonts/hershey/scriptc.jhf"),
        "cursive.jhf" => include_str!("../../fonts/hershey/cursive.jhf"),
        "futural.jhf" => include_str!("../../fonts/hershey/futural.jhf"),
        "greek.jhf" => include_str!("../../fonts/hershey/greek.jhf"),
        _ => "",
    }
}

/// One glyph: strokes (each a polyline, with whether it closes on itself) and the advance
/// width, in font units, y up, baseline at y = 0, pen start at x = 0.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Glyph {
    /// The strokes, in drawing order.
    pub strokes: Vec<(Vec<DVec2>, bool)>,
    /// Horizontal advance to the next glyph.
    pub advance: f64,
}

/// A loaded font.
#[derive(Debug, Clone)]
pub struct Font {
    name: String,
    kind: Kind,
    cap_height: f64,
    line_height: f64,
}

#[derive(Debug, Clone)]
enum Kind {
    Grid,
    /// Glyphs for ASCII 32..=127 in the file's order (only 32..=126 are looked up).
    Hershey {
        glyphs: Vec<Glyph>,
        greek: bool,
    },
    Outline {
        data: Vec<u8>,
        units_per_em: f64,
    },
}

/// What a font name refers to: a built-in font, or a font file still to be read.
#[derive(Debug)]
pub enum FontSource {
    /// A built-in font, ready.
    Builtin(Font),
    /// A TrueType/OpenType file.
    File(std::path::PathBuf),
}

impl Font {
    /// Resolves a font name: a built-in name ([`GRID`] or a [`HERSHEY_FONTS`] name) or a path to
    /// a `.ttf`/`.otf`/`.ttc` file (its first face).
    ///
    /// # Errors
    /// [`Error::Value`] for a name that is neither built in nor an existing file (the job names
    /// `--font`); [`Error::Io`] for an unreadable file; [`Error::InvalidInput`] naming the file when
    /// it is not a font with outlines.
    pub fn load(spec: &str) -> Result<FontSource> {
        let key = spec.trim();
        if key.eq_ignore_ascii_case(GRID) {
            return Ok(FontSource::Builtin(Font {
                name: GRID.into(),
                kind: Kind::Grid,
                cap_height: super::text::CAP_HEIGHT,
                line_height: super::text::LINE_HEIGHT,
            }));
        }
        if let Some((name, file, _)) = HERSHEY_FONTS
            .iter()
            .find(|(n, _, _)| n.eq_ignore_ascii_case(key))
        {
            return Font::hershey(name, hershey_data(file)).map(FontSource::Builtin);
        }
        let path = Path::new(key);
        let looks_like_file = path.extension().is_some_and(|e| {
            ["ttf", "otf", "ttc", "otc"]
                .iter()
                .any(|x| e.eq_ignore_ascii_case(x))
        }) || path.components().count() > 1;
        if !looks_like_file && !path.is_file() {
            let names: Vec<&str> = std::iter::once(GRID)
                .chain(HERSHEY_FONTS.iter().map(|(n, _, _)| *n))
                .collect();
            return Err(Error::value(format!(
                "`{spec}`: not a built-in font ({}) nor a .ttf/.otf file",
                names.join(", ")
            )));
        }
        Ok(FontSource::File(path.to_path_buf()))
    }

    /// A built-in font by name ([`GRID`] or a [`HERSHEY_FONTS`] name).
    ///
    /// # Errors
    /// As [`Font::load`], and [`Error::Value`] when the name is a file.
    pub fn builtin(name: &str) -> Result<Font> {
        match Font::load(name)? {
            FontSource::Builtin(font) => Ok(font),
            FontSource::File(path) => Err(Error::value(format!(
                "`{}` is a font file, not a built-in font",
                path.display()
            ))),
        }
    }

    /// A TrueType/OpenType font from the bytes of its file (`path` names it in errors;
    /// [`crate::io::drawing::load_font`] reads it).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the file when it is not a font with outlines.
    pub fn from_file_data(path: &Path, data: Vec<u8>) -> Result<Font> {
        Font::outline(path, data)
    }

    /// Parses Hershey `.jhf` text (one glyph per record, ASCII 32 upwards).
    fn hershey(name: &str, text: &str) -> Result<Font> {
        let glyphs = parse_jhf(text).map_err(|m| Error::invalid(format!("{name} font"), m))?;
        if glyphs.len() < 95 {
            return Err(Error::invalid(
                format!("{name} font"),
                format!("{} glyphs, expected 95", glyphs.len()),
            ));
        }
        // Cap height and baseline from `H` (Hershey y points down).
        let h = &glyphs[usize::from(b'H' - 32)];
        let (top, bottom) = h
            .strokes
            .iter()
            .flat_map(|(s, _)| s)
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
        let cap_height = bottom - top;
        let glyphs = glyphs
            .into_iter()
            .map(|g| Glyph {
                strokes: g
                    .strokes
                    .into_iter()
                    .map(|(s, c)| {
                        (
                            s.into_iter()
                                .map(|p| DVec2::new(p.x, bottom - p.y))
                                .collect(),
                            c,
                        )
                    })
                    .collect(),
                advance: g.advance,
            })
            .collect();
        Ok(Font {
            name: name.into(),
            kind: Kind::Hershey {
                glyphs,
                greek: name == "greek",
            },
            cap_height,
            line_height: 1.6 * cap_height,
        })
    }

    fn outline(path: &Path, data: Vec<u8>) -> Result<Font> {
        let face = ttf_parser::Face::parse(&data, 0)
            .map_err(|e| Error::invalid(path, format!("not a TrueType/OpenType font: {e}")))?;
        let units_per_em = f64::from(face.units_per_em());
        let cap = face
            .capital_height()
            .filter(|&h| h > 0)
            .map(f64::from)
            .or_else(|| {
                let g = face.glyph_index('H')?;
                face.glyph_bounding_box(g).map(|b| f64::from(b.y_max))
            })
            .unwrap_or(0.7 * units_per_em);
        let line =
            f64::from(face.ascender()) - f64::from(face.descender()) + f64::from(face.line_gap());
        let line_height = if line > 0.0 { line } else { 1.2 * units_per_em };
        Ok(Font {
            name: path.display().to_string(),
            kind: Kind::Outline { data, units_per_em },
            cap_height: cap,
            line_height,
        })
    }

    /// The font's name: the built-in name or the file's path.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Height of a capital `H` in font units.
    pub fn cap_height(&self) -> f64 {
        self.cap_height
    }

    /// Distance between baselines in font units.
    pub fn line_height(&self) -> f64 {
        self.line_height
    }

    /// The glyph for `c`.
    ///
    /// # Errors
    /// [`Error::UnknownGlyph`] naming the character and the font.
    pub fn glyph(&self, c: char) -> Result<Glyph> {
        let unknown = || Error::UnknownGlyph {
            font: self.name.clone(),
            glyph: c,
        };
        match &self.kind {
            Kind::Grid => {
                let spec = super::text::grid_glyph(c.to_ascii_uppercase()).ok_or_else(unknown)?;
                Ok(Glyph {
                    strokes: super::text::parse_grid_glyph(spec)
                        .into_iter()
                        .map(|s| (s, false))
                        .collect(),
                    advance: super::text::ADVANCE,
                })
            }
            Kind::Hershey { glyphs, greek } => {
                let slot = if *greek { greek_slot(c) } else { ascii_slot(c) };
                slot.and_then(|i| glyphs.get(i))
                    .cloned()
                    .ok_or_else(unknown)
            }
            Kind::Outline { data, units_per_em } => {
                let face = ttf_parser::Face::parse(data, 0).map_err(|e| {
                    Error::invalid(&self.name, format!("not a TrueType/OpenType font: {e}"))
                })?;
                let id = face
                    .glyph_index(c)
                    .filter(|g| g.0 != 0)
                    .ok_or_else(unknown)?;
                let advance = face.glyph_hor_advance(id).map_or(0.0, f64::from);
                let mut sink = Flatten {
                    tolerance: units_per_em / 1000.0,
                    strokes: Vec::new(),
                    current: Vec::new(),
                };
                let _ = face.outline_glyph(id, &mut sink);
                sink.finish_contour();
                if sink.strokes.is_empty() && !c.is_whitespace() && advance <= 0.0 {
                    return Err(unknown());
                }
                Ok(Glyph {
                    strokes: sink.strokes,
                    advance,
                })
            }
        }
    }
}

/// The record index of a printable ASCII character.
fn ascii_slot(c: char) -> Option<usize> {
    (' '..='~').contains(&c).then(|| c as usize - 32)
}

/// The record index of a character in the Greek file: its letters sit on Latin keys (the
/// Symbol-font convention: A = Alpha, C = Chi, F = Phi, Q = Theta, W = Omega, ...), so Greek
/// letters map to those keys, and the Latin letters (whose slots hold Greek) are refused. The
/// keys J and V hold no letter.
fn greek_slot(c: char) -> Option<usize> {
    const UPPER: &str = "ΑΒΧΔΕΦΓΗΙ?ΚΛΜΝΟΠΘΡΣΤΥ?ΩΞΨΖ";
    const LOWER: &str = "αβχδεφγηι?κλμνοπθρστυ?ωξψζ";
    if c.is_ascii_alphabetic() {
        return None;
    }
    if let Some(i) = UPPER.chars().position(|g| g == c && g != '?') {
        return Some(usize::from(b'A' - 32) + i);
    }
    if let Some(i) = LOWER.chars().position(|g| g == c && g != '?') {
        return Some(usize::from(b'a' - 32) + i);
    }
    if c == 'ϑ' {
        return Some(usize::from(b'q' - 32));
    }
    ascii_slot(c)
}

/// Parses `.jhf` records: a 5-character glyph number, a 3-character vertex count, then that
/// many coordinate pairs (each coordinate a character, value = code − `R`; the first pair the
/// left and right bearings; ` R` lifts the pen). A record may continue on following lines.
fn parse_jhf(text: &str) -> std::result::Result<Vec<Glyph>, String> {
    let mut glyphs = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((no, line)) = lines.next() {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |m: &str| format!("line {}: {m}", no + 1);
        let count: usize = line
            .get(5..8)
            .and_then(|s| s.trim().parse().ok())
            .ok_or_else(|| bad("no vertex count in columns 6-8"))?;
        let mut data: Vec<u8> = line.as_bytes().get(8..).unwrap_or(&[]).to_vec();
        while data.len() < 2 * count {
            let (_, more) = lines.next().ok_or_else(|| bad("record ends early"))?;
            data.extend_from_slice(more.as_bytes());
        }
        if count == 0 {
            return Err(bad("a record needs its bearings"));
        }
        let val = |b: u8| f64::from(b) - f64::from(b'R');
        let (left, right) = (val(data[0]), val(data[1]));
        let mut strokes: Vec<(Vec<DVec2>, bool)> = vec![(Vec::new(), false)];
        for k in 1..count {
            let (a, b) = (data[2 * k], data[2 * k + 1]);
            if a == b' ' && b == b'R' {
                strokes.push((Vec::new(), false));
                continue;
            }
            let p = DVec2::new(val(a) - left, val(b));
            strokes.last_mut().expect("non-empty").0.push(p);
        }
        // A single-point stroke is a dot: draw it as a tiny tick so the pen touches down.
        for (s, _) in &mut strokes {
            if s.len() == 1 {
                s.push(s[0] + DVec2::new(0.0, 0.5));
            }
        }
        strokes.retain(|(s, _)| !s.is_empty());
        glyphs.push(Glyph {
            strokes,
            advance: right - left,
        });
    }
    Ok(glyphs)
}

/// Collects a glyph outline as closed polylines, flattening quadratic and cubic Béziers so the
/// chords stay within `tolerance` font units of the curve.
struct Flatten {
    tolerance: f64,
    strokes: Vec<(Vec<DVec2>, bool)>,
    current: Vec<DVec2>,
}

impl Flatten {
    fn finish_contour(&mut self) {
        let mut c = std::mem::take(&mut self.current);
        if c.len() > 1 && c[0].distance(c[c.len() - 1]) < 1e-9 {
            c.pop();
        }
        if c.len() >= 2 {
            self.strokes.push((c, true));
        }
    }

    fn last(&self) -> DVec2 {
        self.current.last().copied().unwrap_or(DVec2::ZERO)
    }

    fn segments(&self, second_difference: f64) -> usize {
        // Uniform subdivision into n chords deviates at most M / (8 n²) · k from the curve
        // (k = 2 for quadratics, 6 for cubics with M the largest second difference).
        ((second_difference / (8.0 * self.tolerance)).sqrt().ceil() as usize).clamp(1, 256)
    }
}

impl ttf_parser::OutlineBuilder for Flatten {
    fn move_to(&mut self, x: f32, y: f32) {
        self.finish_contour();
        self.current.push(DVec2::new(f64::from(x), f64::from(y)));
    }

    fn line_to(&mut self, x: f32, y: f32) {
        self.current.push(DVec2::new(f64::from(x), f64::from(y)));
    }

    fn quad_to(&mut self, x1: f32, y1: f32, x: f32, y: f32) {
        let p0 = self.last();
        let p1 = DVec2::new(f64::from(x1), f64::from(y1));
        let p2 = DVec2::new(f64::from(x), f64::from(y));
        let n = self.segments(2.0 * (p0 - 2.0 * p1 + p2).length());
        for k in 1..=n {
            let t = k as f64 / n as f64;
            let u = 1.0 - t;
            self.current
                .push(p0 * (u * u) + p1 * (2.0 * u * t) + p2 * (t * t));
        }
    }

    fn curve_to(&mut self, x1: f32, y1: f32, x2: f32, y2: f32, x: f32, y: f32) {
        let p0 = self.last();
        let p1 = DVec2::new(f64::from(x1), f64::from(y1));
        let p2 = DVec2::new(f64::from(x2), f64::from(y2));
        let p3 = DVec2::new(f64::from(x), f64::from(y));
        let m = (p0 - 2.0 * p1 + p2)
            .length()
            .max((p1 - 2.0 * p2 + p3).length());
        let n = self.segments(6.0 * m);
        for k in 1..=n {
            let t = k as f64 / n as f64;
            let u = 1.0 - t;
            self.current.push(
                p0 * (u * u * u)
                    + p1 * (3.0 * u * u * t)
                    + p2 * (3.0 * u * t * t)
                    + p3 * (t * t * t),
            );
        }
    }

    fn close(&mut self) {
        self.finish_contour();
    }
}

/// A laid-out text: strokes in font units (y up), the block centred on the origin.
#[derive(Debug, Clone, PartialEq)]
pub struct TextLayout {
    /// Strokes with whether each closes on itself.
    pub strokes: Vec<(Vec<DVec2>, bool)>,
    /// Width and height of the block's ink, in font units.
    pub extent: DVec2,
}

/// Lays out `text` in `font`: lines split at `\n`, each line centred horizontally, the block's
/// ink centred on the origin.
///
/// # Errors
/// [`Error::UnknownGlyph`] for the first character the font lacks; [`Error::Value`] when there
/// is nothing to draw (the job names `--text`).
pub fn layout(font: &Font, text: &str) -> Result<TextLayout> {
    let mut all: Vec<(Vec<DVec2>, bool)> = Vec::new();
    for (row, line) in text.lines().enumerate() {
        let first = all.len();
        let mut x = 0.0;
        let baseline = -font.line_height() * row as f64;
        for c in line.chars() {
            let g = font.glyph(c)?;
            for (s, closed) in g.strokes {
                let moved = s.into_iter().map(|p| p + DVec2::new(x, baseline));
                all.push((moved.collect(), closed));
            }
            x += g.advance;
        }
        // Centre the line on its advance width.
        for (s, _) in &mut all[first..] {
            for p in s {
                p.x -= x / 2.0;
            }
        }
    }
    if all.is_empty() {
        return Err(Error::value(
            "nothing to draw (the text is empty or only spaces)",
        ));
    }
    let (mut lo, mut hi) = (DVec2::splat(f64::MAX), DVec2::splat(f64::MIN));
    for p in all.iter().flat_map(|(s, _)| s) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let mid = (lo + hi) / 2.0;
    for (s, _) in &mut all {
        for p in s {
            *p -= mid;
        }
    }
    Ok(TextLayout {
        strokes: all,
        extent: hi - lo,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_hershey_font_parses_95_glyphs_with_a_cap_height() {
        for (name, _, _) in HERSHEY_FONTS {
            let f = Font::builtin(name).unwrap();
            assert!(f.cap_height() > 15.0 && f.cap_height() < 30.0, "{name}");
            if let Kind::Hershey { glyphs, .. } = &f.kind {
                assert_eq!(glyphs.len(), 96, "{name}: ASCII 32..=127");
                assert!(glyphs[0].strokes.is_empty(), "{name}: space has ink");
            }
        }
    }

    #[test]
    fn continued_records_parse_like_one_line() {
        let one = " 2010  9MWRMNV RRMVV RPSTS";
        let two = " 2010  9MWRMNV RR\nMVV RPSTS";
        assert_eq!(parse_jhf(one).unwrap(), parse_jhf(two).unwrap());
        // `A` in Roman simplex: bearings -5..5 (advance 10), three strokes after `MW`... here 3.
        let g = &parse_jhf(one).unwrap()[0];
        assert_eq!(g.advance, 10.0);
        assert_eq!(g.strokes.len(), 3);
        assert!(parse_jhf(" 2010  9MWRM").is_err());
    }

    #[test]
    fn greek_letters_map_to_their_keys_and_latin_is_refused() {
        let g = Font::builtin("greek").unwrap();
        let simplex = Font::builtin("simplex").unwrap();
        assert_eq!(g.glyph('Ω').unwrap(), {
            let Kind::Hershey { glyphs, .. } = &g.kind else {
                unreachable!()
            };
            glyphs[usize::from(b'W' - 32)].clone()
        });
        assert!(g.glyph('α').is_ok() && g.glyph('ϑ').is_ok() && g.glyph('1').is_ok());
        let e = g.glyph('a').unwrap_err().to_string();
        assert!(e.contains("greek") && e.contains("'a'"), "{e}");
        assert!(simplex.glyph('α').is_err());
    }
}
