//! SVG drawings (`--svg FILE`): every visible shape of the picture, flattened to polylines.
//!
//! The document is resolved by [`usvg`] the way a browser draws it: CSS (`<style>` sheets with
//! selectors, `style` attributes, presentation attributes), `<use>` (of elements or `<symbol>`s,
//! with their `x`/`y`), nested `transform`s, nested `<svg>` viewports, `viewBox` and
//! `preserveAspectRatio`, lengths in `px`, `mm`, `cm`, `in`, `pt`, `pc`, `em`, `%` (96 px per
//! inch), `display:none` and `visibility:hidden`, markers. Shapes inside `<defs>`, `<clipPath>`,
//! `<mask>`, `<pattern>`, `<marker>` definitions and `<symbol>` are drawn only where used. A shape
//! with neither fill nor stroke is invisible and not drawn. Text and raster images are not
//! drawn (convert text to paths, in Inkscape: Path ▸ Object to Path); nothing outside the file
//! is read.
//!
//! # Frame and units
//! Points are in CSS px of the SVG canvas (its `width` × `height`, at 96 px per inch), origin
//! at its top-left corner, **x to the right and y down**; when the root `<svg>` has no
//! `viewBox`, or its `viewBox` has the size of the canvas, these are the root's user units.
//! The IK bake (`scenebake ik --svg`) turns y down the page into the drawing plane's down,
//! centres the drawing and scales it (fit to reach, or `--size`), so only the shape matters.
//!
//! # Flattening tolerance
//! Béziers (and so every curve) are flattened into polylines whose distance to the curve is at
//! most [`TOLERANCE`] × the larger side of the drawing's bounding box, in the units above
//! (0.1 mm on a drawing 1 m tall). Arcs, circles and ellipses reach us as cubic Béziers: usvg
//! converts them within 0.1 of their own user unit (kurbo's arc bound; a full circle or
//! ellipse always uses at least one cubic per quarter, off by at most 2.8·10⁻⁴ × its radius).
//!
//! # Errors
//! Malformed XML, path data, `transform` lists, shape lengths and `points` lists are errors
//! that name the file, the line and the element, where a browser would draw the shape up to
//! the error: a drawing that comes out partly is the wrong drawing for a pen.

use std::path::Path;

use glam::DVec2;
use kurbo::{BezPath, PathEl, Shape};
use roxmltree::{Document, Node};

use crate::error::{Error, Result};

/// One flattened subpath: its points (canvas px, y down) and whether it is closed. A closed
/// subpath does not repeat its first point at the end.
pub type Polyline = (Vec<DVec2>, bool);

/// Flattening tolerance, as a fraction of the larger side of the drawing's bounding box (see
/// the module docs).
pub const TOLERANCE: f64 = 1e-4;

const SVG_NS: &str = "http://www.w3.org/2000/svg";

/// Parses SVG text and flattens every visible shape into polylines (see the module docs for the
/// frame, units and tolerance). `path` names the file in error messages only; nothing is read.
///
/// # Errors
/// [`Error::Parse`] (with the line) for malformed XML or an element with malformed path data,
/// `transform`, length or `points`; [`Error::InvalidInput`] when the SVG has no valid size or
/// no visible shape.
pub fn parse_svg(text: &str, path: &Path) -> Result<Vec<Polyline>> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: true, // Illustrator writes entity declarations
        ..Default::default()
    };
    let doc = Document::parse_with_options(text, options).map_err(|e| Error::Parse {
        path: path.into(),
        line: Some(e.pos().row as usize),
        message: format!("malformed XML: {e}").into(),
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "svg" || !is_svg(root) {
        return Err(Error::invalid(
            path,
            format!(
                "the root element is <{}>, not <svg xmlns=\"{SVG_NS}\">",
                root.tag_name().name()
            ),
        ));
    }
    validate(&doc, path)?;

    let usvg_options = usvg::Options {
        // Raster images are not drawn: never read their files or decode their data.
        image_href_resolver: usvg::ImageHrefResolver {
            resolve_data: Box::new(|_, _, _| None),
            resolve_string: Box::new(|_, _| None),
        },
        ..Default::default()
    };
    let tree = usvg::Tree::from_xmltree(&doc, &usvg_options).map_err(|e| match e {
        usvg::Error::InvalidSize => Error::invalid(
            path,
            "<svg>: width, height or viewBox is zero or negative, so nothing is drawn",
        ),
        other => Error::Parse {
            path: path.into(),
            line: None,
            message: other.to_string().into(),
        },
    })?;

    let mut curves = Vec::new();
    collect(tree.root(), &mut curves);
    let bounds = curves
        .iter()
        .map(Shape::bounding_box)
        .reduce(|a, b| a.union(b));
    let extent = bounds.map_or(0.0, |b| b.width().max(b.height()));
    let tolerance = if extent > 0.0 {
        TOLERANCE * extent
    } else {
        1.0
    };
    let shapes: Vec<Polyline> = curves
        .iter()
        .flat_map(|c| flatten(c, tolerance))
        .filter(|(p, _)| p.len() >= 2)
        .collect();
    if shapes.is_empty() {
        return Err(Error::invalid(path, nothing_drawn(&doc)));
    }
    Ok(shapes)
}

/// Every visible path of `group` and its descendants, in canvas coordinates (f64).
fn collect(group: &usvg::Group, out: &mut Vec<BezPath>) {
    for node in group.children() {
        match node {
            usvg::Node::Group(g) => collect(g, out),
            usvg::Node::Path(p) if p.is_visible() => {
                let t = p.abs_transform();
                let m = kurbo::Affine::new([t.sx, t.ky, t.kx, t.sy, t.tx, t.ty].map(f64::from));
                let pt = |q: usvg::tiny_skia_path::Point| {
                    m * kurbo::Point::new(f64::from(q.x), f64::from(q.y))
                };
                let mut b = BezPath::new();
                for seg in p.data().segments() {
                    use usvg::tiny_skia_path::PathSegment as S;
                    match seg {
                        S::MoveTo(a) => b.move_to(pt(a)),
                        S::LineTo(a) => b.line_to(pt(a)),
                        S::QuadTo(c, a) => b.quad_to(pt(c), pt(a)),
                        S::CubicTo(c1, c2, a) => b.curve_to(pt(c1), pt(c2), pt(a)),
                        S::Close => b.close_path(),
                    }
                }
                out.push(b);
            }
            _ => {}
        }
    }
}

/// Splits a path into flattened subpaths within `tolerance`.
fn flatten(curve: &BezPath, tolerance: f64) -> Vec<Polyline> {
    let mut out: Vec<Polyline> = Vec::new();
    let mut cur: Vec<DVec2> = Vec::new();
    let mut finish = |cur: &mut Vec<DVec2>, closed: bool| {
        let mut pts = std::mem::take(cur);
        // A closing point back on the start (within the tolerance) is the start.
        if closed && pts.len() > 2 && pts[0].distance(pts[pts.len() - 1]) <= tolerance {
            pts.pop();
        }
        out.push((pts, closed));
    };
    kurbo::flatten(curve, tolerance, |el| match el {
        PathEl::MoveTo(p) => {
            if !cur.is_empty() {
                finish(&mut cur, false);
            }
            cur.push(DVec2::new(p.x, p.y));
        }
        PathEl::LineTo(p) => cur.push(DVec2::new(p.x, p.y)),
        PathEl::ClosePath => finish(&mut cur, true),
        // `flatten` emits only the three above.
        PathEl::QuadTo(..) | PathEl::CurveTo(..) => {}
    });
    if !cur.is_empty() {
        finish(&mut cur, false);
    }
    out
}

/// Checks the attributes a browser would silently cut short, naming the element and its line.
fn validate(doc: &Document<'_>, path: &Path) -> Result<()> {
    for node in doc.descendants().filter(|n| n.is_element()) {
        if !is_svg(node) {
            continue;
        }
        let fail = |attr: &str, value: &str, what: String| {
            let shown: String = value.chars().take(40).collect();
            let more = if shown.len() < value.len() { "…" } else { "" };
            Err(Error::Parse {
                path: path.into(),
                line: Some(doc.text_pos_at(node.range().start).row as usize),
                message: format!("{}: {attr}=\"{shown}{more}\": {what}", describe(&node)).into(),
            })
        };
        if let Some(t) = node.attribute("transform") {
            if let Err(e) = t.parse::<svgtypes::Transform>() {
                return fail("transform", t, e.to_string());
            }
        }
        let name = node.tag_name().name();
        let lengths: &[&str] = match name {
            "rect" => &["x", "y", "width", "height", "rx", "ry"],
            "circle" => &["cx", "cy", "r"],
            "ellipse" => &["cx", "cy", "rx", "ry"],
            "line" => &["x1", "y1", "x2", "y2"],
            _ => &[],
        };
        for &attr in lengths {
            if let Some(v) = node.attribute(attr) {
                if v.trim() != "auto" {
                    if let Err(e) = v.parse::<svgtypes::Length>() {
                        return fail(attr, v, format!("not a length ({e})"));
                    }
                }
            }
        }
        if name == "path" {
            if let Some(d) = node.attribute("d") {
                if let Some(Err(e)) = svgtypes::PathParser::from(d).find(|s| s.is_err()) {
                    return fail("d", d, format!("bad path data ({e})"));
                }
            }
        }
        if name == "polyline" || name == "polygon" {
            if let Some(v) = node.attribute("points") {
                let mut count = 0;
                for n in svgtypes::NumberListParser::from(v) {
                    if let Err(e) = n {
                        return fail("points", v, format!("bad number list ({e})"));
                    }
                    count += 1;
                }
                if count % 2 == 1 {
                    return fail("points", v, format!("{count} numbers, not x,y pairs"));
                }
            }
        }
    }
    Ok(())
}

/// Whether an element is in the SVG namespace (or in none, as usvg also accepts).
fn is_svg(node: Node<'_, '_>) -> bool {
    matches!(node.tag_name().namespace(), None | Some(SVG_NS))
}

/// `<path id="a">`, or `<path>` without an id.
fn describe(node: &Node<'_, '_>) -> String {
    match node.attribute("id") {
        Some(id) => format!("<{} id=\"{id}\">", node.tag_name().name()),
        None => format!("<{}>", node.tag_name().name()),
    }
}

/// Why a parsed document drew nothing, with the likely fix.
fn nothing_drawn(doc: &Document<'_>) -> String {
    let texts = doc
        .descendants()
        .filter(|n| is_svg(*n) && n.tag_name().name() == "text")
        .count();
    let hint = if texts > 0 {
        format!(" ({texts} <text> element(s) are not drawn: convert text to paths)")
    } else {
        String::new()
    };
    format!("no visible path, line, polyline, polygon, rect, circle or ellipse{hint}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(svg: &str) -> Result<Vec<Polyline>> {
        parse_svg(svg, Path::new("t.svg"))
    }

    #[test]
    fn shapes_and_path_commands() {
        let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100"><!-- c -->
            <path d="M10,10 L20,10 h5 v5 Z m1 1 c0,10 10,10 10,0 s10,-10 10,0 q5,5 10,0 t10,0 A5 5 0 0 1 60 20"/>
            <line x1="0" y1="0" x2="3" y2="4" stroke="black"/><polygon points="0,0 1,0 1,1"/><rect x="1" y="1" width="2" height="3"/>
            <circle cx="5" cy="5" r="2"/></svg>"#;
        let s = parse(svg).unwrap();
        assert_eq!(s.len(), 6);
        // M10,10 L20,10 h5 v5 Z: four corners, closed.
        assert!(s[0].1);
        assert_eq!(
            s[0].0,
            [(10.0, 10.0), (20.0, 10.0), (25.0, 10.0), (25.0, 15.0)].map(DVec2::from)
        );
        // `m1 1` after Z is relative to the subpath start (10,10).
        assert_eq!(s[1].0[0], DVec2::new(11.0, 11.0));
        assert!(s[1].0.last().unwrap().distance(DVec2::new(60.0, 20.0)) < 1e-4);
        assert_eq!(s[2].0, [DVec2::ZERO, DVec2::new(3.0, 4.0)]);
        assert_eq!(s[4].0.len(), 4);
        assert!(s[4].1);
    }

    #[test]
    fn transforms_nest_and_end_with_their_group() {
        let svg = r#"<?xml version="1.0"?>
<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100" stroke="black">
  <defs><path d="M 0 0 L 100 100"/></defs>
  <g transform="translate(10, 20)">
    <g transform="scale(2)">
      <line x1="0" y1="0" x2="1" y2="0"/>
    </g>
    <path transform="rotate(90)" d="M 1 0 L 2 0"/>
  </g>
  <line x1="5" y1="5" x2="6" y2="5" transform="matrix(1 0 0 1 -5 -5)"/>
</svg>"#;
        let shapes = parse(svg).unwrap();
        assert_eq!(shapes.len(), 3, "the <defs> path is not drawn");
        let at = |k: usize, a: (f64, f64), b: (f64, f64)| {
            let (p, q) = (shapes[k].0[0], shapes[k].0[1]);
            assert!(
                p.distance(a.into()) < 1e-6 && q.distance(b.into()) < 1e-6,
                "{p} {q}"
            );
        };
        // translate(10,20)·scale(2): (0,0)→(10,20), (1,0)→(12,20).
        at(0, (10.0, 20.0), (12.0, 20.0));
        // translate(10,20)·rotate(90): (1,0)→(10,21), (2,0)→(10,22); the scale ended with its </g>.
        at(1, (10.0, 21.0), (10.0, 22.0));
        at(2, (0.0, 0.0), (1.0, 0.0));
    }

    #[test]
    fn malformed_attributes_name_the_element_and_line() {
        for (body, needle) in [
            (
                r#"<path id="p" d="M0,0 L1"/>"#,
                r#"<path id="p">: d="M0,0 L1""#,
            ),
            (
                r#"<g transform="frobnicate(1)"><line x2="1"/></g>"#,
                "<g>: transform=",
            ),
            (
                r#"<rect width="ten"/>"#,
                "<rect>: width=\"ten\": not a length",
            ),
            (r#"<polygon points="0,0 1"/>"#, "3 numbers"),
        ] {
            let svg = format!("<svg xmlns=\"{SVG_NS}\">\n\n{body}</svg>");
            let e = parse(&svg).unwrap_err();
            assert!(
                matches!(&e, Error::Parse { line: Some(3), message, .. } if message.to_string().contains(needle)),
                "{e}"
            );
            assert!(e.to_string().starts_with("t.svg:3: "), "{e}");
        }
    }

    #[test]
    fn nothing_visible_says_why() {
        // Without the SVG namespace it is drawn all the same; another root element is not SVG.
        assert_eq!(
            parse(r#"<svg><path d="M0 0 L1 1"/></svg>"#).unwrap().len(),
            1
        );
        let html = parse(r#"<html><path d="M0 0 L1 1"/></html>"#).unwrap_err();
        assert!(html.to_string().contains("<html>"), "{html}");
        let text = parse(&format!("<svg xmlns=\"{SVG_NS}\"><text>hi</text></svg>")).unwrap_err();
        assert!(text.to_string().contains("1 <text>"), "{text}");
    }
}
