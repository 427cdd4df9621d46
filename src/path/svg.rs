//! SVG drawings (`--svg FILE`): every `path`, `line`, `polyline`, `polygon`, `rect`, `circle`
//! and `ellipse` element, flattened to polylines in SVG user units (y pointing down).
//!
//! A small built-in reader (no dependency): path data supports all commands (M L H V C S Q T A
//! Z, absolute and relative); Béziers are flattened into 16 segments, arcs into segments of at
//! most 10°. Not supported: `transform` attributes, `<use>`, CSS, text; such drawings are read
//! without them.

use std::f64::consts::{PI, TAU};
use std::path::Path;

use glam::DVec2;

use crate::error::{Error, Result};

/// One flattened subpath: its points and whether it is closed.
pub type Polyline = (Vec<DVec2>, bool);

/// Reads every shape of an SVG file as polylines in user units.
///
/// # Errors
/// [`Error::Io`] when unreadable; [`Error::Parse`] for malformed path data;
/// [`Error::InvalidInput`] when the file has no drawable shape.
pub fn read_svg(path: &Path) -> Result<Vec<Polyline>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let shapes = parse_svg(&text).map_err(|message| Error::Parse {
        path: path.into(),
        line: None,
        message,
    })?;
    if shapes.iter().all(|(p, _)| p.len() < 2) {
        return Err(Error::invalid(
            path,
            "no drawable path, line, polyline, polygon, rect, circle or ellipse",
        ));
    }
    Ok(shapes.into_iter().filter(|(p, _)| p.len() >= 2).collect())
}

/// Parses SVG text (see the module docs for what is supported).
///
/// # Errors
/// A message naming the element or path command that could not be read.
pub fn parse_svg(text: &str) -> std::result::Result<Vec<Polyline>, String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find('<') {
        rest = &rest[start + 1..];
        if rest.starts_with("!--") {
            rest = rest.find("-->").map_or("", |e| &rest[e + 3..]);
            continue;
        }
        let end = rest.find('>').ok_or("unterminated tag")?;
        let tag = &rest[..end];
        rest = &rest[end + 1..];
        let name: String = tag
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == ':')
            .collect();
        let attrs = |key: &str| attribute(tag, key);
        let num = |key: &str| -> std::result::Result<f64, String> {
            attrs(key).map_or(Ok(0.0), |v| {
                v.trim()
                    .trim_end_matches("px")
                    .parse::<f64>()
                    .map_err(|_| format!("<{name}> {key}=\"{v}\": not a number"))
            })
        };
        match name.as_str() {
            "path" => {
                if let Some(d) = attrs("d") {
                    out.extend(parse_path_data(&d)?);
                }
            }
            "line" => out.push((
                vec![
                    DVec2::new(num("x1")?, num("y1")?),
                    DVec2::new(num("x2")?, num("y2")?),
                ],
                false,
            )),
            "polyline" | "polygon" => {
                let nums = numbers(&attrs("points").unwrap_or_default())?;
                let pts: Vec<DVec2> = nums
                    .chunks_exact(2)
                    .map(|c| DVec2::new(c[0], c[1]))
                    .collect();
                out.push((pts, name == "polygon"));
            }
            "rect" => {
                let (x, y, w, h) = (num("x")?, num("y")?, num("width")?, num("height")?);
                out.push((
                    vec![
                        DVec2::new(x, y),
                        DVec2::new(x + w, y),
                        DVec2::new(x + w, y + h),
                        DVec2::new(x, y + h),
                    ],
                    true,
                ));
            }
            "circle" | "ellipse" => {
                let (cx, cy) = (num("cx")?, num("cy")?);
                let (rx, ry) = if name == "circle" {
                    (num("r")?, num("r")?)
                } else {
                    (num("rx")?, num("ry")?)
                };
                let pts = (0..72)
                    .map(|k| {
                        let t = TAU * k as f64 / 72.0;
                        DVec2::new(cx + rx * t.cos(), cy + ry * t.sin())
                    })
                    .collect();
                out.push((pts, true));
            }
            _ => {}
        }
    }
    Ok(out)
}

fn attribute(tag: &str, key: &str) -> Option<String> {
    let mut search = tag;
    while let Some(i) = search.find(key) {
        let before_ok = i == 0 || search[..i].ends_with(|c: char| c.is_whitespace());
        let after = search[i + key.len()..].trim_start();
        if before_ok {
            if let Some(v) = after.strip_prefix('=') {
                let v = v.trim_start();
                let quote = v.chars().next()?;
                if quote == '"' || quote == '\'' {
                    let body = &v[1..];
                    return body.find(quote).map(|e| body[..e].to_string());
                }
            }
        }
        search = &search[i + key.len()..];
    }
    None
}

/// All numbers in a list (commas and whitespace separate; `1-2` and `.5.5` split as in SVG).
fn numbers(s: &str) -> std::result::Result<Vec<f64>, String> {
    let mut lex = Lexer {
        s: s.as_bytes(),
        i: 0,
    };
    let mut out = Vec::new();
    while lex.skip_sep() {
        out.push(
            lex.number()
                .ok_or_else(|| format!("bad number list `{s}`"))?,
        );
    }
    Ok(out)
}

struct Lexer<'a> {
    s: &'a [u8],
    i: usize,
}

impl Lexer<'_> {
    /// Skips separators; false at the end.
    fn skip_sep(&mut self) -> bool {
        while self.i < self.s.len()
            && (self.s[self.i].is_ascii_whitespace() || self.s[self.i] == b',')
        {
            self.i += 1;
        }
        self.i < self.s.len()
    }

    fn peek_number(&mut self) -> bool {
        self.skip_sep() && matches!(self.s[self.i], b'0'..=b'9' | b'.' | b'-' | b'+')
    }

    fn number(&mut self) -> Option<f64> {
        self.skip_sep();
        let start = self.i;
        let s = self.s;
        if self.i < s.len() && (s[self.i] == b'-' || s[self.i] == b'+') {
            self.i += 1;
        }
        let mut dot = false;
        while self.i < s.len() && (s[self.i].is_ascii_digit() || (s[self.i] == b'.' && !dot)) {
            dot |= s[self.i] == b'.';
            self.i += 1;
        }
        if self.i < s.len() && (s[self.i] == b'e' || s[self.i] == b'E') {
            let save = self.i;
            self.i += 1;
            if self.i < s.len() && (s[self.i] == b'-' || s[self.i] == b'+') {
                self.i += 1;
            }
            let digits = self.i;
            while self.i < s.len() && s[self.i].is_ascii_digit() {
                self.i += 1;
            }
            if digits == self.i {
                self.i = save;
            }
        }
        std::str::from_utf8(&s[start..self.i])
            .ok()?
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
    }

    fn flag(&mut self) -> Option<bool> {
        self.skip_sep();
        let c = *self.s.get(self.i)?;
        self.i += 1;
        match c {
            b'0' => Some(false),
            b'1' => Some(true),
            _ => None,
        }
    }
}

/// Flattens SVG path data into subpaths.
///
/// # Errors
/// A message naming the offending command.
pub fn parse_path_data(d: &str) -> std::result::Result<Vec<Polyline>, String> {
    let mut lex = Lexer {
        s: d.as_bytes(),
        i: 0,
    };
    let mut out: Vec<Polyline> = Vec::new();
    let mut cur: Vec<DVec2> = Vec::new();
    let (mut p, mut start) = (DVec2::ZERO, DVec2::ZERO);
    let mut last_ctrl: Option<(u8, DVec2)> = None;
    let mut cmd = 0u8;
    let err = |c: u8| {
        format!(
            "path data `{}`: bad arguments for `{}`",
            d.chars().take(40).collect::<String>(),
            c as char
        )
    };
    loop {
        if !lex.skip_sep() {
            break;
        }
        let c = lex.s[lex.i];
        if c.is_ascii_alphabetic() {
            cmd = c;
            lex.i += 1;
        } else if cmd == 0 {
            return Err(err(c));
        } else if cmd == b'M' {
            cmd = b'L';
        } else if cmd == b'm' {
            cmd = b'l';
        }
        let rel = cmd.is_ascii_lowercase();
        let base = if rel { p } else { DVec2::ZERO };
        let pt = |lex: &mut Lexer<'_>| -> std::result::Result<DVec2, String> {
            let x = lex.number().ok_or_else(|| err(cmd))?;
            let y = lex.number().ok_or_else(|| err(cmd))?;
            Ok(base + DVec2::new(x, y))
        };
        let upper = cmd.to_ascii_uppercase();
        match upper {
            b'M' => {
                if cur.len() >= 2 {
                    out.push((std::mem::take(&mut cur), false));
                }
                cur.clear();
                p = pt(&mut lex)?;
                start = p;
                cur.push(p);
            }
            b'L' => {
                p = pt(&mut lex)?;
                cur.push(p);
            }
            b'H' => {
                let x = lex.number().ok_or_else(|| err(cmd))?;
                p.x = if rel { p.x + x } else { x };
                cur.push(p);
            }
            b'V' => {
                let y = lex.number().ok_or_else(|| err(cmd))?;
                p.y = if rel { p.y + y } else { y };
                cur.push(p);
            }
            b'C' | b'S' => {
                let c1 = if upper == b'C' {
                    pt(&mut lex)?
                } else {
                    match last_ctrl {
                        Some((b'C', c)) => 2.0 * p - c,
                        _ => p,
                    }
                };
                let c2 = pt(&mut lex)?;
                let e = pt(&mut lex)?;
                for k in 1..=16 {
                    let t = k as f64 / 16.0;
                    let u = 1.0 - t;
                    cur.push(
                        p * (u * u * u)
                            + c1 * (3.0 * u * u * t)
                            + c2 * (3.0 * u * t * t)
                            + e * (t * t * t),
                    );
                }
                last_ctrl = Some((b'C', c2));
                p = e;
                continue;
            }
            b'Q' | b'T' => {
                let c1 = if upper == b'Q' {
                    pt(&mut lex)?
                } else {
                    match last_ctrl {
                        Some((b'Q', c)) => 2.0 * p - c,
                        _ => p,
                    }
                };
                let e = pt(&mut lex)?;
                for k in 1..=16 {
                    let t = k as f64 / 16.0;
                    let u = 1.0 - t;
                    cur.push(p * (u * u) + c1 * (2.0 * u * t) + e * (t * t));
                }
                last_ctrl = Some((b'Q', c1));
                p = e;
                continue;
            }
            b'A' => {
                let rx = lex.number().ok_or_else(|| err(cmd))?.abs();
                let ry = lex.number().ok_or_else(|| err(cmd))?.abs();
                let rot = lex.number().ok_or_else(|| err(cmd))?.to_radians();
                let large = lex.flag().ok_or_else(|| err(cmd))?;
                let sweep = lex.flag().ok_or_else(|| err(cmd))?;
                let e = pt(&mut lex)?;
                arc(&mut cur, p, e, rx, ry, rot, large, sweep);
                p = e;
            }
            b'Z' => {
                if cur.len() >= 2 {
                    out.push((std::mem::take(&mut cur), true));
                }
                p = start;
                cur.clear();
                cur.push(p);
                // `Z` takes no arguments; a following number would repeat the last command.
                if lex.peek_number() {
                    return Err(err(cmd));
                }
            }
            _ => return Err(format!("unknown path command `{}`", cmd as char)),
        }
        last_ctrl = None;
    }
    if cur.len() >= 2 {
        out.push((cur, false));
    }
    Ok(out)
}

/// Appends an elliptical arc from `a` to `b` (SVG endpoint parameterisation, spec F.6.5).
#[allow(clippy::too_many_arguments, reason = "the SVG arc's parameters")]
fn arc(
    out: &mut Vec<DVec2>,
    a: DVec2,
    b: DVec2,
    mut rx: f64,
    mut ry: f64,
    phi: f64,
    large: bool,
    sweep: bool,
) {
    if rx < 1e-12 || ry < 1e-12 || a.distance(b) < 1e-12 {
        out.push(b);
        return;
    }
    let (s, c) = phi.sin_cos();
    let h = (a - b) / 2.0;
    let x1 = DVec2::new(c * h.x + s * h.y, -s * h.x + c * h.y);
    let lambda = (x1.x * x1.x) / (rx * rx) + (x1.y * x1.y) / (ry * ry);
    if lambda > 1.0 {
        rx *= lambda.sqrt();
        ry *= lambda.sqrt();
    }
    let num = (rx * rx * ry * ry - rx * rx * x1.y * x1.y - ry * ry * x1.x * x1.x).max(0.0);
    let den = rx * rx * x1.y * x1.y + ry * ry * x1.x * x1.x;
    let mut k = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
    if large == sweep {
        k = -k;
    }
    let cp = DVec2::new(k * rx * x1.y / ry, -k * ry * x1.x / rx);
    let mid = (a + b) / 2.0;
    let center = DVec2::new(c * cp.x - s * cp.y, s * cp.x + c * cp.y) + mid;
    let angle = |u: DVec2, v: DVec2| {
        let a = u.angle_to(v);
        if a.is_finite() {
            a
        } else {
            0.0
        }
    };
    let u = DVec2::new((x1.x - cp.x) / rx, (x1.y - cp.y) / ry);
    let v = DVec2::new((-x1.x - cp.x) / rx, (-x1.y - cp.y) / ry);
    let theta1 = angle(DVec2::X, u);
    let mut dtheta = angle(u, v) % TAU;
    if !sweep && dtheta > 0.0 {
        dtheta -= TAU;
    } else if sweep && dtheta < 0.0 {
        dtheta += TAU;
    }
    let n = ((dtheta.abs() / (PI / 18.0)).ceil() as usize).max(1);
    for i in 1..=n {
        let t = theta1 + dtheta * i as f64 / n as f64;
        let (st, ct) = t.sin_cos();
        let q = DVec2::new(rx * ct, ry * st);
        out.push(center + DVec2::new(c * q.x - s * q.y, s * q.x + c * q.y));
    }
    if let Some(last) = out.last_mut() {
        *last = b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_and_path_commands() {
        let svg = r#"<svg xmlns="http://www.w3.org/2000/svg"><!-- c -->
            <path d="M10,10 L20,10 h5 v5 Z m1 1 c0,10 10,10 10,0 s10,-10 10,0 q5,5 10,0 t10,0 A5 5 0 0 1 60 20"/>
            <line x1="0" y1="0" x2="3" y2="4"/><polygon points="0,0 1,0 1,1"/><rect x="1" y="1" width="2" height="3"/>
            <circle cx="5" cy="5" r="2"/></svg>"#;
        let s = parse_svg(svg).unwrap();
        assert_eq!(s.len(), 6);
        assert!(s[0].1 && s[0].0.len() == 4);
        assert_eq!(s[1].0[0], DVec2::new(11.0, 11.0));
        assert_eq!(*s[1].0.last().unwrap(), DVec2::new(60.0, 20.0));
        assert!(s[5]
            .0
            .iter()
            .all(|p| (p.distance(DVec2::splat(5.0)) - 2.0).abs() < 1e-9));
    }

    #[test]
    fn half_circle_arc_stays_on_the_circle() {
        let s = parse_path_data("M0,0 A1,1 0 0 1 2,0").unwrap();
        let pts = &s[0].0;
        assert!(pts.len() > 10);
        assert!(pts
            .iter()
            .all(|p| (p.distance(DVec2::new(1.0, 0.0)) - 1.0).abs() < 1e-9));
        assert!(parse_path_data("M0,0 L1").is_err());
        assert!(parse_path_data("X1,2").is_err());
    }
}
