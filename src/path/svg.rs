//! SVG drawings (`--svg FILE`): every `path`, `line`, `polyline`, `polygon`, `rect`, `circle`
//! and `ellipse` element, flattened to polylines in SVG user units (y pointing down).
//!
//! A small built-in reader (no dependency): path data supports all commands (M L H V C S Q T A
//! Z, absolute and relative); Béziers are flattened into 16 segments, arcs into segments of at
//! most 10°. `transform` attributes (matrix, translate, scale, rotate, skewX, skewY) apply to an
//! element and everything nested in it, as Inkscape's layer groups need; shapes inside `defs`,
//! `clipPath`, `mask`, `symbol`, `marker` and `pattern` are not drawn. Not supported: `<use>`,
//! CSS, text.

use std::f64::consts::{PI, TAU};
use std::path::Path;

use glam::{DAffine2, DVec2};

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
        message: message.into(),
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
    // The transform of each open element, and how many open elements are never rendered.
    let mut transforms = vec![DAffine2::IDENTITY];
    let mut hidden: Vec<bool> = vec![false];
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
        if tag.starts_with('/') {
            if transforms.len() > 1 {
                transforms.pop();
                hidden.pop();
            }
            continue;
        }
        if tag.starts_with('?') || tag.starts_with('!') {
            continue; // <?xml ...?>, <!DOCTYPE ...>
        }
        let name: String = tag
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == ':')
            .collect();
        let parent = *transforms.last().unwrap_or(&DAffine2::IDENTITY);
        let m = match attribute(tag, "transform") {
            Some(t) => {
                parent
                    * parse_transform(&t).map_err(|e| format!("<{name}> transform=\"{t}\": {e}"))?
            }
            None => parent,
        };
        let is_hidden = *hidden.last().unwrap_or(&false)
            || matches!(
                name.as_str(),
                "defs" | "clipPath" | "mask" | "symbol" | "marker" | "pattern"
            );
        if !tag.trim_end().ends_with('/') {
            transforms.push(m);
            hidden.push(is_hidden);
        }
        if is_hidden {
            continue;
        }
        let first_new = out.len();
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
        for (points, _) in &mut out[first_new..] {
            for p in points.iter_mut() {
                *p = m.transform_point2(*p);
            }
        }
    }
    Ok(out)
}

/// Parses an SVG `transform` list (`matrix(a b c d e f)`, `translate`, `scale`, `rotate(a [cx
/// cy])`, `skewX`, `skewY`; angles in degrees), composed left to right.
fn parse_transform(text: &str) -> std::result::Result<DAffine2, String> {
    let mut m = DAffine2::IDENTITY;
    let mut rest = text.trim();
    while !rest.is_empty() {
        let open = rest.find('(').ok_or("expected `name(...)`")?;
        let close = rest[open..].find(')').ok_or("missing `)`")? + open;
        let name = rest[..open].trim().trim_start_matches(',').trim();
        let a = numbers(&rest[open + 1..close])?;
        let arg = |i: usize| a.get(i).copied();
        let t = match (name, a.len()) {
            ("matrix", 6) => DAffine2::from_cols_array(&[a[0], a[1], a[2], a[3], a[4], a[5]]),
            ("translate", 1 | 2) => {
                DAffine2::from_translation(DVec2::new(a[0], arg(1).unwrap_or(0.0)))
            }
            ("scale", 1 | 2) => DAffine2::from_scale(DVec2::new(a[0], arg(1).unwrap_or(a[0]))),
            ("rotate", 1) => DAffine2::from_angle(a[0].to_radians()),
            ("rotate", 3) => {
                let c = DVec2::new(a[1], a[2]);
                DAffine2::from_translation(c)
                    * DAffine2::from_angle(a[0].to_radians())
                    * DAffine2::from_translation(-c)
            }
            ("skewX", 1) => {
                DAffine2::from_cols_array(&[1.0, 0.0, a[0].to_radians().tan(), 1.0, 0.0, 0.0])
            }
            ("skewY", 1) => {
                DAffine2::from_cols_array(&[1.0, a[0].to_radians().tan(), 0.0, 1.0, 0.0, 0.0])
            }
            _ => return Err(format!("unsupported `{name}` with {} numbers", a.len())),
        };
        m *= t;
        rest = rest[close + 1..].trim();
    }
    Ok(m)
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
    fn transforms_nest_and_hidden_containers_are_skipped() {
        let svg = r#"<?xml version="1.0"?>
<svg xmlns="http://www.w3.org/2000/svg">
  <defs><path d="M 0 0 L 100 100"/></defs>
  <g transform="translate(10, 20)">
    <g transform="scale(2)">
      <line x1="0" y1="0" x2="1" y2="0"/>
    </g>
    <path transform="rotate(90)" d="M 1 0 L 2 0"/>
  </g>
  <line x1="5" y1="5" x2="6" y2="5" transform="matrix(1 0 0 1 -5 -5)"/>
</svg>"#;
        let shapes = parse_svg(svg).unwrap();
        assert_eq!(shapes.len(), 3, "the <defs> path is not drawn");
        let close = |a: DVec2, b: DVec2| (a - b).length() < 1e-9;
        // translate(10,20)·scale(2): (0,0)→(10,20), (1,0)→(12,20).
        assert!(
            close(shapes[0].0[0], DVec2::new(10.0, 20.0))
                && close(shapes[0].0[1], DVec2::new(12.0, 20.0))
        );
        // translate(10,20)·rotate(90): (1,0)→(10,21), (2,0)→(10,22); the scale ended with its </g>.
        assert!(
            close(shapes[1].0[0], DVec2::new(10.0, 21.0))
                && close(shapes[1].0[1], DVec2::new(10.0, 22.0))
        );
        assert!(close(shapes[2].0[0], DVec2::ZERO) && close(shapes[2].0[1], DVec2::new(1.0, 0.0)));
        assert!(
            parse_svg(r#"<g transform="frobnicate(1)"><line x2="1"/></g>"#)
                .unwrap_err()
                .contains("frobnicate")
        );
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
