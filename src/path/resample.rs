//! Arc-length resampling: points spaced evenly along a polyline, whatever the spacing of the
//! input (points are inserted where the input is sparse and dropped where it is dense).

use glam::DVec3;

/// Resamples `points` to an even spacing as close to `spacing` as divides the length exactly.
/// An open polyline keeps both ends (m + 1 points for m intervals); a closed one includes the
/// closing segment and returns m points without repeating the first. A polyline of zero
/// length gives its first point. `spacing` must be positive.
pub fn resample(points: &[DVec3], closed: bool, spacing: f64) -> Vec<DVec3> {
    if points.is_empty() {
        return Vec::new();
    }
    let mut pts: Vec<DVec3> = points.to_vec();
    if closed {
        pts.push(points[0]);
    }
    let mut cum = Vec::with_capacity(pts.len());
    cum.push(0.0);
    for w in pts.windows(2) {
        cum.push(cum[cum.len() - 1] + w[0].distance(w[1]));
    }
    let total = cum[cum.len() - 1];
    if total <= 1e-12 || spacing.is_nan() || spacing <= 0.0 {
        return vec![points[0]];
    }
    let min_intervals = if closed { 3 } else { 1 };
    let m = ((total / spacing).round() as usize).max(min_intervals);
    let count = if closed { m } else { m + 1 };
    let mut out = Vec::with_capacity(count);
    let mut seg = 0;
    for k in 0..count {
        let s = total * k as f64 / m as f64;
        while seg + 2 < cum.len() && cum[seg + 1] < s {
            seg += 1;
        }
        let len = cum[seg + 1] - cum[seg];
        let t = if len > 0.0 {
            ((s - cum[seg]) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(pts[seg].lerp(pts[seg + 1], t));
    }
    out
}

/// Samples an open polyline (both ends kept) one point per frame for a pen that starts and ends
/// at rest: it speeds up uniformly for `ease_frames` frames to `step` scene units per frame,
/// cruises, and slows down the same way (a trapezoidal speed profile; a triangular one when the
/// polyline is too short to reach full speed). The motion takes `L/step + ease_frames` frames for
/// a polyline of length `L ≥ step·ease_frames`, rounded up to whole frames (the samples are then
/// spread over the rounded time so the last one lands on the end). `ease_frames = 0` is an even
/// spacing of about `step`. A polyline of zero length gives its first point.
pub fn resample_eased(points: &[DVec3], step: f64, ease_frames: f64) -> Vec<DVec3> {
    if points.is_empty() {
        return Vec::new();
    }
    let mut cum = Vec::with_capacity(points.len());
    cum.push(0.0);
    for w in points.windows(2) {
        cum.push(cum[cum.len() - 1] + w[0].distance(w[1]));
    }
    let total = cum[cum.len() - 1];
    if total <= 1e-12 || step.is_nan() || step <= 0.0 {
        return vec![points[0]];
    }
    let ease = ease_frames.max(0.0);
    // Distance covered while speeding up to `step` over `ease` frames.
    let ramp = step * ease / 2.0;
    let (peak, accel_frames, duration) = if ease <= 0.0 {
        (step, 0.0, total / step)
    } else if total >= 2.0 * ramp {
        (step, ease, total / step + ease)
    } else {
        let a = step / ease;
        let peak = (a * total).sqrt();
        (peak, peak / a, 2.0 * peak / a)
    };
    let distance_at = |t: f64| -> f64 {
        if accel_frames <= 0.0 {
            return peak * t;
        }
        let a = peak / accel_frames;
        if t <= accel_frames {
            0.5 * a * t * t
        } else if t <= duration - accel_frames {
            0.5 * peak * accel_frames + peak * (t - accel_frames)
        } else {
            let r = duration - t;
            total - 0.5 * a * r * r
        }
    };
    let m = (duration.ceil() as usize).max(1);
    let scale = duration / m as f64;
    let mut out = Vec::with_capacity(m + 1);
    let mut seg = 0;
    for k in 0..=m {
        let s = if k == m {
            total
        } else {
            distance_at(k as f64 * scale).clamp(0.0, total)
        };
        while seg + 2 < cum.len() && cum[seg + 1] < s {
            seg += 1;
        }
        let len = cum[seg + 1] - cum[seg];
        let t = if len > 0.0 {
            ((s - cum[seg]) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(points[seg].lerp(points[seg + 1], t));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn uneven_input_becomes_even() {
        // Parameter-uniform samples of y = x³ bunch up near 0: resampling evens them out.
        let pts: Vec<DVec3> = (0..=50)
            .map(|i| {
                let t = -1.0 + 2.0 * i as f64 / 50.0;
                DVec3::new(t, t * t * t, 0.0)
            })
            .collect();
        let out = resample(&pts, false, 0.05);
        assert_eq!(out[0], pts[0]);
        assert_abs_diff_eq!(out[out.len() - 1].distance(pts[50]), 0.0, epsilon = 1e-12);
        let d: Vec<f64> = out.windows(2).map(|w| w[0].distance(w[1])).collect();
        let (lo, hi) = d
            .iter()
            .fold((f64::MAX, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
        // Chords of an evenly arc-length-sampled smooth curve: all close to the spacing.
        assert!(hi <= 0.05 * 1.05 && lo >= 0.05 * 0.85, "{lo} {hi}");
        // The input's own spacing is far from even.
        let din: Vec<f64> = pts.windows(2).map(|w| w[0].distance(w[1])).collect();
        let ratio =
            din.iter().cloned().fold(0.0, f64::max) / din.iter().cloned().fold(f64::MAX, f64::min);
        assert!(ratio > 3.0);
    }

    #[test]
    fn closed_square_has_exact_spacing() {
        let sq = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let out = resample(&sq, true, 0.25);
        assert_eq!(out.len(), 16);
        for k in 0..16 {
            let next = out[(k + 1) % 16];
            assert_abs_diff_eq!(out[k].distance(next), 0.25, epsilon = 1e-12);
        }
    }

    #[test]
    fn eased_line_takes_length_over_speed_plus_the_ease_and_starts_at_rest() {
        let line = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
        // 0.02 per frame, 6 frames to full speed: 1/0.02 + 6 = 56 frames.
        let out = resample_eased(&line, 0.02, 6.0);
        assert_eq!(out.len(), 57);
        let d: Vec<f64> = out.windows(2).map(|w| w[1].x - w[0].x).collect();
        // Uniform acceleration from rest: steps grow as 1, 3, 5... times a/2.
        let a = 0.02 / 6.0;
        assert_abs_diff_eq!(d[0], 0.5 * a, epsilon = 1e-12);
        assert_abs_diff_eq!(d[1], 1.5 * a, epsilon = 1e-12);
        assert_abs_diff_eq!(d[28], 0.02, epsilon = 1e-12);
        assert_abs_diff_eq!(d[55], 0.5 * a, epsilon = 1e-12);
        assert!(d.iter().all(|&x| x > 0.0 && x <= 0.02 + 1e-12));
        assert_eq!(out[56], line[1]);
        // Too short to reach full speed: a triangle, symmetric, still from rest to rest.
        let short = resample_eased(&[DVec3::ZERO, DVec3::new(0.03, 0.0, 0.0)], 0.02, 6.0);
        let d: Vec<f64> = short.windows(2).map(|w| w[1].x - w[0].x).collect();
        assert!(d.iter().all(|&x| x < 0.02));
        assert_abs_diff_eq!(d[0], d[d.len() - 1], epsilon = 1e-12);
    }

    #[test]
    fn degenerate_inputs() {
        assert!(resample(&[], false, 0.1).is_empty());
        assert_eq!(
            resample(&[DVec3::ONE, DVec3::ONE], false, 0.1),
            vec![DVec3::ONE]
        );
        assert_eq!(resample(&[DVec3::ZERO, DVec3::X], false, 10.0).len(), 2);
    }
}
