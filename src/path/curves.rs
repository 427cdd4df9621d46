//! The labs' closed target curves, in drawing-plane coordinates around the origin.

use std::f64::consts::{FRAC_PI_2, TAU};
use std::str::FromStr;

use glam::DVec2;

use crate::error::Error;

/// A closed analytic curve (`--curve`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum CurveKind {
    /// Circle of radius R.
    Circle,
    /// Axis-aligned square of half-side R.
    Square,
    /// Cardioid `r = R (1 - sin θ)` about the centre (the lab's heart has R = 0.5).
    Heart,
    /// Equilateral triangle inscribed in the circle of radius R, a vertex up.
    Triangle,
    /// Five-pointed star, outer radius R, inner radius 0.382 R, a point up.
    Star,
}

impl CurveKind {
    /// Every curve, in option order.
    pub const ALL: [CurveKind; 5] = [
        CurveKind::Circle,
        CurveKind::Square,
        CurveKind::Heart,
        CurveKind::Triangle,
        CurveKind::Star,
    ];

    /// The option value (`circle`...).
    pub fn as_str(self) -> &'static str {
        match self {
            CurveKind::Circle => "circle",
            CurveKind::Square => "square",
            CurveKind::Heart => "heart",
            CurveKind::Triangle => "triangle",
            CurveKind::Star => "star",
        }
    }

    /// The curve as a closed polyline of size `radius`. Polygons give their corners (exact),
    /// the circle and heart `samples` points evenly spaced in θ (even in arc length for the
    /// circle).
    pub fn polyline(self, radius: f64, samples: usize) -> Vec<DVec2> {
        let samples = samples.max(3);
        let polar = |k: usize, n: usize, r: f64| {
            let t = FRAC_PI_2 + TAU * k as f64 / n as f64;
            DVec2::new(r * t.cos(), r * t.sin())
        };
        match self {
            CurveKind::Circle => (0..samples)
                .map(|k| {
                    let t = TAU * k as f64 / samples as f64;
                    DVec2::new(radius * t.cos(), radius * t.sin())
                })
                .collect(),
            CurveKind::Square => vec![
                DVec2::new(-radius, -radius),
                DVec2::new(radius, -radius),
                DVec2::new(radius, radius),
                DVec2::new(-radius, radius),
            ],
            CurveKind::Heart => (0..samples)
                .map(|k| {
                    // Start at the cusp (θ = π/2, r = 0) so the path begins at the heart's notch.
                    let t = FRAC_PI_2 + TAU * k as f64 / samples as f64;
                    let r = radius * (1.0 - t.sin());
                    DVec2::new(r * t.cos(), r * t.sin())
                })
                .collect(),
            CurveKind::Triangle => (0..3).map(|k| polar(k, 3, radius)).collect(),
            CurveKind::Star => (0..10)
                .map(|k| polar(k, 10, if k % 2 == 0 { radius } else { radius * 0.382 }))
                .collect(),
        }
    }
}

impl FromStr for CurveKind {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Error> {
        CurveKind::ALL
            .into_iter()
            .find(|c| c.as_str().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| {
                Error::value(format!(
                    "`{s}`: expected circle, square, heart, triangle or star"
                ))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn curves_parse_and_have_the_lab_sizes() {
        assert_eq!("Heart".parse::<CurveKind>().unwrap(), CurveKind::Heart);
        let e = "blob".parse::<CurveKind>().unwrap_err();
        assert!(matches!(e, Error::Value { .. }), "{e}");
        assert!(e.detail().starts_with("`blob`: expected circle"), "{e}");
        let c = CurveKind::Circle.polyline(0.6, 150);
        assert_eq!(c.len(), 150);
        assert!(c.iter().all(|p| (p.length() - 0.6).abs() < 1e-12));
        // Lab heart r = 0.5 (1 - sin θ): bottom point at distance 1.0.
        let h = CurveKind::Heart.polyline(0.5, 400);
        let lowest = h.iter().map(|p| p.y).fold(f64::MAX, f64::min);
        assert_abs_diff_eq!(lowest, -1.0, epsilon = 1e-3);
    }
}
