//! Target paths for the IK end effector: analytic curves, single-stroke text, point lists and
//! SVG drawings, placed on a drawing plane, resampled by arc length and joined into one pen path
//! (pen down along strokes, lifted between them).

pub mod curves;
pub mod font;
pub mod points;
pub mod resample;
pub mod svg;
pub mod text;

use glam::{DVec2, DVec3};

pub use curves::CurveKind;
pub use resample::{resample, resample_eased};

/// A polyline in world coordinates (scene units).
#[derive(Debug, Clone, PartialEq)]
pub struct Stroke {
    /// The points, in drawing order.
    pub points: Vec<DVec3>,
    /// Whether the last point joins back to the first.
    pub closed: bool,
}

/// A drawing plane: an origin and an orthonormal basis. Plane coordinates (x, y) map to
/// `center + x·right + y·up`; `normal = up × right` points away from the viewer, who looks
/// along it (for a chain, from the root side towards the plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// Plane origin (world).
    pub center: DVec3,
    /// Unit "right" direction of the drawing.
    pub right: DVec3,
    /// Unit "up" direction of the drawing.
    pub up: DVec3,
    /// Unit normal, the viewing direction (pointing away from the chain root).
    pub normal: DVec3,
}

impl Plane {
    /// The plane through `center` seen along `normal`: "up" is world +Y projected onto the
    /// plane, or -Z (+Z) when looking straight down (up); `right = normal × up`, so drawings
    /// read correctly for a viewer looking along `normal`.
    pub fn facing(center: DVec3, normal: DVec3) -> Plane {
        let n = normal.normalize_or(DVec3::NEG_Y);
        let reference = if n.y.abs() > 0.9 {
            DVec3::new(0.0, 0.0, n.y.signum())
        } else {
            DVec3::Y
        };
        let up = (reference - reference.dot(n) * n).normalize();
        let right = n.cross(up);
        Plane {
            center,
            right,
            up,
            normal: n,
        }
    }

    /// The plane through `center` seen along `normal` by a reader at `eye`: as [`Plane::facing`],
    /// except that on a level board (a desk or a ceiling, `|normal.y| > 0.9`) "up" points
    /// horizontally away from the reader, as on a sheet of paper on a table.
    pub fn facing_from(center: DVec3, normal: DVec3, eye: DVec3) -> Plane {
        let plane = Plane::facing(center, normal);
        let away = center - eye;
        let away = away - away.dot(plane.normal) * plane.normal;
        if plane.normal.y.abs() <= 0.9 || away.length() < 1e-9 * (1.0 + center.length()) {
            return plane;
        }
        let up = away.normalize();
        Plane {
            up,
            right: plane.normal.cross(up),
            ..plane
        }
    }

    /// World position of plane coordinates `p`.
    pub fn to_world(&self, p: DVec2) -> DVec3 {
        self.center + self.right * p.x + self.up * p.y
    }
}

/// One target of the pen path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenTarget {
    /// World position of the target.
    pub position: DVec3,
    /// The stroke being drawn (pen down), or `None` while the pen travels lifted.
    pub stroke: Option<usize>,
}

/// How the targets are spaced along the pen path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Timing {
    /// Even arc-length spacing (scene units between targets), pen speed constant.
    Even(f64),
    /// One target per frame for a pen moving `step` scene units per frame that starts and stops
    /// at rest at the ends of every stroke and every lift, taking `ease_frames` frames to speed
    /// up or slow down ([`resample_eased`]).
    Eased {
        /// Cruising distance per frame.
        step: f64,
        /// Frames to reach the cruising speed from rest.
        ease_frames: f64,
    },
}

/// [`pen_path`] with a choice of [`Timing`].
pub fn pen_path_timed(strokes: &[Stroke], timing: Timing, lift: DVec3) -> Vec<PenTarget> {
    let (step, ease_frames) = match timing {
        Timing::Even(spacing) => return pen_path(strokes, spacing, lift),
        Timing::Eased { step, ease_frames } => (step, ease_frames),
    };
    let mut out: Vec<PenTarget> = Vec::new();
    let mut last: Option<DVec3> = None;
    for (k, s) in strokes.iter().enumerate() {
        if s.points.is_empty() {
            continue;
        }
        let mut line = s.points.clone();
        if s.closed {
            line.push(s.points[0]);
        }
        let pts = resample_eased(&line, step, ease_frames);
        if let Some(end) = last {
            let start = pts[0];
            let moved = resample_eased(&[end, end + lift, start + lift, start], step, ease_frames);
            out.extend(
                moved[1..moved.len().saturating_sub(1)]
                    .iter()
                    .map(|&position| PenTarget {
                        position,
                        stroke: None,
                    }),
            );
        }
        out.extend(pts.iter().map(|&position| PenTarget {
            position,
            stroke: Some(k),
        }));
        last = Some(pts[pts.len() - 1]);
    }
    out
}

/// Joins strokes into one pen path. Each stroke is resampled to `spacing`; between strokes the
/// pen moves by `lift` (a world vector, usually towards the chain), travels to above the next
/// stroke's start and comes down, all at the same spacing. A closed stroke ends back on its
/// first point before the pen lifts.
pub fn pen_path(strokes: &[Stroke], spacing: f64, lift: DVec3) -> Vec<PenTarget> {
    let mut out: Vec<PenTarget> = Vec::new();
    let mut last: Option<DVec3> = None;
    for (k, s) in strokes.iter().enumerate() {
        if s.points.is_empty() {
            continue;
        }
        let pts = resample(&s.points, s.closed, spacing);
        if let Some(end) = last {
            let start = pts[0];
            let travel = [end, end + lift, start + lift, start];
            let moved = resample(&travel, false, spacing);
            // Skip the first (already drawn) and last (the stroke's own first point) samples.
            out.extend(
                moved[1..moved.len().saturating_sub(1)]
                    .iter()
                    .map(|&position| PenTarget {
                        position,
                        stroke: None,
                    }),
            );
        }
        out.extend(pts.iter().map(|&position| PenTarget {
            position,
            stroke: Some(k),
        }));
        let multi = strokes.len() > 1;
        if s.closed && multi {
            out.push(PenTarget {
                position: pts[0],
                stroke: Some(k),
            });
        }
        last = Some(if s.closed && multi {
            pts[0]
        } else {
            pts[pts.len() - 1]
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn lab_plane_is_y0_read_from_above() {
        let p = Plane::facing(DVec3::ZERO, DVec3::NEG_Y);
        assert_abs_diff_eq!(p.right.distance(DVec3::X), 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(p.up.distance(DVec3::NEG_Z), 0.0, epsilon = 1e-12);
        let q = Plane::facing(DVec3::ZERO, DVec3::Z);
        assert_abs_diff_eq!(q.up.distance(DVec3::Y), 0.0, epsilon = 1e-12);
        assert_abs_diff_eq!(q.up.cross(q.right).distance(q.normal), 0.0, epsilon = 1e-12);
    }

    #[test]
    fn pen_lifts_between_strokes() {
        let a = Stroke {
            points: vec![DVec3::ZERO, DVec3::X],
            closed: false,
        };
        let b = Stroke {
            points: vec![DVec3::new(2.0, 0.0, 0.0), DVec3::new(3.0, 0.0, 0.0)],
            closed: false,
        };
        let path = pen_path(&[a, b], 0.1, DVec3::Y * 0.5);
        let up: Vec<_> = path.iter().filter(|t| t.stroke.is_none()).collect();
        assert!(!up.is_empty());
        assert!(up.iter().any(|t| (t.position.y - 0.5).abs() < 1e-9));
        assert_eq!(path.first().unwrap().stroke, Some(0));
        assert_eq!(path.last().unwrap().stroke, Some(1));
        for w in path.windows(2) {
            assert!(w[0].position.distance(w[1].position) <= 0.1 + 1e-9);
        }
    }
}
