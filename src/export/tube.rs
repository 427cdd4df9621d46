//! Tubes around polylines: the drawn trail of an IK bake as a triangle mesh that renders.
//!
//! A [`Tube`] sweeps a ring of [`SIDES`] vertices along a polyline with rotation-minimising
//! frames (the double-reflection method of Wang, Jüttler, Zheng and Liu 2008), so the rings do
//! not twist. Every vertex lies at the radius from the polyline:
//! - samples closer than the radius to the last kept one are skipped (they lie inside the tube);
//! - at a bend the ring lies in the bisecting plane; its outer half is a circle of the radius
//!   about the bend point (nearest to the bend point, beyond both segments' ends), its inner half
//!   is stretched by 1/cos(θ/2) towards the inside (the mitre), so it lies at the radius from
//!   both segments' lines, within both segments;
//! - where a bend turns by more than 90° or its mitre would reach past a neighbouring segment, the
//!   tube is split into two runs;
//! - each run ends in hemispherical caps ([`CAP_RINGS`] rings and a pole), so its surface is
//!   closed.
//!
//! [`Tube::mesh`] cuts the tube into pieces by sample index: consecutive pieces share a ring, so
//! pieces revealed one after another draw one continuous tube. Normals point out from the axis
//! (the ring's unit direction; on caps, from the cap's centre), for smooth shading.

use glam::{DVec3, Vec3};

/// Vertices per ring.
pub const SIDES: usize = 8;
/// Latitude steps of a hemispherical cap: `CAP_RINGS - 1` rings, then the pole.
pub const CAP_RINGS: usize = 2;

/// One cross-section of a tube.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Section {
    centre: DVec3,
    /// Unit tangent (the bisector of the segments at a bend).
    tangent: DVec3,
    /// Unit ring axes, perpendicular to `tangent` and to each other (rotation-minimising).
    normal: DVec3,
    binormal: DVec3,
    /// Unit direction into the bend (zero on a straight run or a run's end).
    bend: DVec3,
    /// Mitre stretch of the inner half: 1/cos(θ/2) for a turn by θ.
    stretch: f64,
    /// Index of the input point at the centre.
    sample: usize,
}

/// A triangle mesh: positions, unit normals, counter-clockwise triangles seen from outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TubeMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
    /// Triangle corners, three per triangle.
    pub indices: Vec<u32>,
}

impl TubeMesh {
    /// Number of triangles.
    pub fn triangles(&self) -> usize {
        self.indices.len() / 3
    }
}

/// A tube of a given radius around a polyline, split into runs (see the module docs).
#[derive(Debug, Clone)]
pub struct Tube {
    radius: f64,
    runs: Vec<Vec<Section>>,
}

impl Tube {
    /// The tube of `radius` (> 0) around `points` (an empty polyline gives an empty tube; points
    /// all within `radius` of the first give a sphere).
    pub fn new(points: &[DVec3], radius: f64) -> Tube {
        let kept = thin(points, radius);
        let mut runs = Vec::new();
        if kept.is_empty() {
            return Tube { radius, runs };
        }
        let q = |i: usize| points[kept[i]];
        let end_section = |i: usize, tangent: DVec3| Section {
            centre: q(i),
            tangent,
            normal: DVec3::ZERO,
            binormal: DVec3::ZERO,
            bend: DVec3::ZERO,
            stretch: 1.0,
            sample: kept[i],
        };
        if kept.len() == 1 {
            runs.push(vec![end_section(0, DVec3::X)]);
        } else {
            let dirs: Vec<DVec3> = kept
                .windows(2)
                .map(|w| (points[w[1]] - points[w[0]]).normalize())
                .collect();
            let lens: Vec<f64> = kept
                .windows(2)
                .map(|w| points[w[0]].distance(points[w[1]]))
                .collect();
            let mut run = vec![end_section(0, dirs[0])];
            for i in 1..kept.len() - 1 {
                let (d0, d1) = (dirs[i - 1], dirs[i]);
                let cos = d0.dot(d1).clamp(-1.0, 1.0);
                let half_cos = ((1.0 + cos) / 2.0).sqrt();
                let half_tan = ((1.0 - cos) / 2.0).sqrt() / half_cos.max(1e-300);
                if cos < 0.0 || radius * half_tan > lens[i - 1].min(lens[i]) {
                    run.push(end_section(i, d0));
                    runs.push(std::mem::take(&mut run));
                    run.push(end_section(i, d1));
                    continue;
                }
                let turn = d1 - d0;
                let straight = turn.length() < 1e-12;
                run.push(Section {
                    tangent: (d0 + d1).normalize(),
                    bend: if straight {
                        DVec3::ZERO
                    } else {
                        turn.normalize()
                    },
                    stretch: if straight { 1.0 } else { 1.0 / half_cos },
                    ..end_section(i, d0)
                });
            }
            run.push(end_section(kept.len() - 1, dirs[dirs.len() - 1]));
            runs.push(run);
        }
        for run in &mut runs {
            frame(run);
        }
        Tube { radius, runs }
    }

    /// Number of runs (closed tubes) the polyline was split into.
    pub fn runs(&self) -> usize {
        self.runs.len()
    }

    /// The piece of the tube through the samples `from..=to`, positions relative to `origin`:
    /// in each run, the rings at those samples, joined to the ring before them (so a piece
    /// continues the previous one), with a cap where a run starts or ends among them. Empty when
    /// no ring lies at those samples.
    pub fn mesh(&self, from: usize, to: usize, origin: DVec3) -> TubeMesh {
        let mut out = TubeMesh::default();
        for run in &self.runs {
            let Some(first) = run.iter().position(|s| (from..=to).contains(&s.sample)) else {
                continue;
            };
            let last = run
                .iter()
                .rposition(|s| (from..=to).contains(&s.sample))
                .expect("one lies in range");
            let start = first.saturating_sub(1);
            self.append(
                &run[start..=last],
                first == 0,
                last == run.len() - 1,
                origin,
                &mut out,
            );
        }
        out
    }

    /// Appends the rings of `sections` (and caps) to `out`.
    fn append(
        &self,
        sections: &[Section],
        start_cap: bool,
        end_cap: bool,
        origin: DVec3,
        out: &mut TubeMesh,
    ) {
        let r = self.radius;
        let base = out.positions.len() as u32;
        let push = |p: DVec3, n: DVec3, out: &mut TubeMesh| {
            out.positions.push((p - origin).as_vec3());
            out.normals.push(n.normalize().as_vec3());
        };
        // Rings in order along the tube, then the poles.
        let cap = |s: &Section, sign: f64, k: usize, out: &mut TubeMesh| {
            let a = k as f64 * std::f64::consts::FRAC_PI_2 / CAP_RINGS as f64;
            let c = s.centre + s.tangent * (sign * r * a.sin());
            for u in ring_dirs(s) {
                push(
                    c + u * (r * a.cos()),
                    u * a.cos() + s.tangent * (sign * a.sin()),
                    out,
                );
            }
        };
        let mut rings = 0;
        if start_cap {
            for k in (1..CAP_RINGS).rev() {
                cap(&sections[0], -1.0, k, out);
                rings += 1;
            }
        }
        for s in sections {
            for u in ring_dirs(s) {
                let inward = u.dot(s.bend).max(0.0);
                push(
                    s.centre + (u + s.bend * (inward * (s.stretch - 1.0))) * r,
                    u,
                    out,
                );
            }
            rings += 1;
        }
        if end_cap {
            for k in 1..CAP_RINGS {
                cap(&sections[sections.len() - 1], 1.0, k, out);
                rings += 1;
            }
        }
        let n = SIDES as u32;
        let at = |ring: u32, j: u32| base + ring * n + j % n;
        for ring in 0..rings as u32 - 1 {
            for j in 0..n {
                let (a, b, c, d) = (
                    at(ring, j),
                    at(ring, j + 1),
                    at(ring + 1, j + 1),
                    at(ring + 1, j),
                );
                out.indices.extend_from_slice(&[a, b, c, a, c, d]);
            }
        }
        if start_cap {
            let s = &sections[0];
            let pole = out.positions.len() as u32;
            push(s.centre - s.tangent * r, -s.tangent, out);
            for j in 0..n {
                out.indices
                    .extend_from_slice(&[pole, at(0, j + 1), at(0, j)]);
            }
        }
        if end_cap {
            let s = &sections[sections.len() - 1];
            let pole = out.positions.len() as u32;
            push(s.centre + s.tangent * r, s.tangent, out);
            let last = rings as u32 - 1;
            for j in 0..n {
                out.indices
                    .extend_from_slice(&[at(last, j), at(last, j + 1), pole]);
            }
        }
    }
}

/// Indices of the points kept: the first, then each one at least `radius` from the last kept;
/// the last point always ends the line (replacing the last kept one when it is nearer).
fn thin(points: &[DVec3], radius: f64) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    for (i, p) in points.iter().enumerate() {
        match kept.last() {
            Some(&k) if points[k].distance(*p) < radius => {}
            _ => kept.push(i),
        }
    }
    let last = points.len().wrapping_sub(1);
    if let Some(&k) = kept.last() {
        if k != last && points[k].distance(points[last]) > 0.0 {
            if kept.len() > 1 {
                kept.pop();
            }
            let before = kept[kept.len() - 1];
            if points[before].distance(points[last]) > radius * 1e-6 {
                kept.push(last);
            }
        }
    }
    kept
}

/// Rotation-minimising ring axes along a run (double reflection); the first is any unit vector
/// perpendicular to the first tangent.
fn frame(run: &mut [Section]) {
    let mut r = run[0].tangent.any_orthonormal_vector();
    for i in 0..run.len() {
        if i > 0 {
            let (prev, cur) = (&run[i - 1], &run[i]);
            let v1 = cur.centre - prev.centre;
            let c1 = v1.dot(v1);
            if c1 > 0.0 {
                let r_l = r - v1 * (2.0 / c1 * v1.dot(r));
                let t_l = prev.tangent - v1 * (2.0 / c1 * v1.dot(prev.tangent));
                let v2 = cur.tangent - t_l;
                let c2 = v2.dot(v2);
                r = if c2 > 1e-24 {
                    r_l - v2 * (2.0 / c2 * v2.dot(r_l))
                } else {
                    r_l
                };
            }
            // Remove round-off: r stays unit and perpendicular to the tangent.
            r = (r - cur.tangent * cur.tangent.dot(r)).normalize();
        }
        run[i].normal = r;
        run[i].binormal = run[i].tangent.cross(r);
    }
}

/// The unit directions of a ring's vertices: `normal` turned towards `binormal` by 2πj/SIDES.
fn ring_dirs(s: &Section) -> impl Iterator<Item = DVec3> + '_ {
    (0..SIDES).map(move |j| {
        let a = std::f64::consts::TAU * j as f64 / SIDES as f64;
        s.normal * a.cos() + s.binormal * a.sin()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance from `p` to the segment `a`–`b`.
    fn seg_dist(p: DVec3, a: DVec3, b: DVec3) -> f64 {
        let d = b - a;
        let t = ((p - a).dot(d) / d.dot(d)).clamp(0.0, 1.0);
        p.distance(a + d * t)
    }

    fn line_dist(p: DVec3, line: &[DVec3]) -> f64 {
        if line.len() == 1 {
            return p.distance(line[0]);
        }
        line.windows(2)
            .map(|w| seg_dist(p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
    }

    /// Every edge of the mesh is shared by exactly two triangles, in opposite directions.
    fn closed(m: &TubeMesh) -> bool {
        let mut edges = std::collections::HashMap::new();
        for t in m.indices.chunks(3) {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
    }

    /// Signed volume (divergence theorem): positive when the triangles face outwards.
    fn volume(m: &TubeMesh) -> f64 {
        m.indices
            .chunks(3)
            .map(|t| {
                let p = |i: u32| m.positions[i as usize].as_dvec3();
                p(t[0]).dot(p(t[1]).cross(p(t[2]))) / 6.0
            })
            .sum()
    }

    #[test]
    fn a_bent_line_is_a_closed_tube_at_the_radius() {
        // A helix-like bent polyline: turns of 30°, no twist needed to follow it.
        let pts: Vec<DVec3> = (0..20)
            .map(|i| {
                let a = i as f64 * 0.5;
                DVec3::new(a.cos(), 0.1 * i as f64, a.sin())
            })
            .collect();
        let r = 0.05;
        let tube = Tube::new(&pts, r);
        assert_eq!(tube.runs(), 1);
        let m = tube.mesh(0, pts.len() - 1, DVec3::ZERO);
        let rings = pts.len() + 2 * (CAP_RINGS - 1);
        assert_eq!(m.positions.len(), rings * SIDES + 2);
        assert_eq!(m.triangles(), 2 * SIDES * (rings - 1) + 2 * SIDES);
        assert!(closed(&m));
        for p in &m.positions {
            let d = line_dist(p.as_dvec3(), &pts);
            assert!((d - r).abs() < 1e-6, "{d}");
        }
        // Outward faces: the volume is a bit under π r² × length + 4/3 π r³ (polygonal rings).
        let length: f64 = pts.windows(2).map(|w| w[0].distance(w[1])).sum();
        let round =
            std::f64::consts::PI * r * r * length + 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        let v = volume(&m);
        assert!(v > 0.8 * round && v < round, "{v} vs {round}");
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((n.length() - 1.0).abs() < 1e-5);
            // Normals point away from the axis.
            let p = p.as_dvec3();
            let nearest = pts
                .windows(2)
                .map(|w| {
                    let d = w[1] - w[0];
                    let t = ((p - w[0]).dot(d) / d.dot(d)).clamp(0.0, 1.0);
                    w[0] + d * t
                })
                .min_by(|a, b| a.distance(p).total_cmp(&b.distance(p)))
                .unwrap();
            assert!(n.as_dvec3().dot(p - nearest) > 0.5 * r);
        }
    }

    #[test]
    fn rings_do_not_twist_along_a_planar_curve() {
        // In a plane the rotation-minimising normal stays perpendicular to or in the plane.
        let pts: Vec<DVec3> = (0..40)
            .map(|i| {
                let a = i as f64 * 0.15;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let tube = Tube::new(&pts, 0.01);
        let run = &tube.runs[0];
        let z0 = run[0].normal.z;
        for s in run {
            assert!((s.normal.z - z0).abs() < 1e-9);
            assert!(s.normal.dot(s.tangent).abs() < 1e-12);
        }
    }

    #[test]
    fn sharp_corners_split_the_tube_and_pieces_join_ring_to_ring() {
        // A V: 150° turn at (1, 0, 0).
        let mut pts: Vec<DVec3> = (0..=10)
            .map(|i| DVec3::new(i as f64 * 0.1, 0.0, 0.0))
            .collect();
        let back = DVec3::new(-(150f64.to_radians().cos()), 150f64.to_radians().sin(), 0.0);
        pts.extend((1..=10).map(|i| DVec3::new(1.0, 0.0, 0.0) - back * (i as f64 * 0.1)));
        let r = 0.02;
        let tube = Tube::new(&pts, r);
        assert_eq!(tube.runs(), 2);
        for (run, line) in tube.runs.iter().zip([&pts[..=10], &pts[10..]]) {
            let m = {
                let mut out = TubeMesh::default();
                tube.append(run, true, true, DVec3::ZERO, &mut out);
                out
            };
            assert!(closed(&m));
            for p in &m.positions {
                assert!((line_dist(p.as_dvec3(), line) - r).abs() < 1e-6);
            }
        }
        // Pieces 0..=4, 5..=14, 15..=20: the first starts with a cap, the second starts on the
        // first's last ring; together they hold every ring once more per join.
        let a = tube.mesh(0, 4, DVec3::ZERO);
        let b = tube.mesh(5, 14, DVec3::ZERO);
        let c = tube.mesh(15, 20, DVec3::ZERO);
        let ring = |m: &TubeMesh, k: usize| m.positions[k * SIDES..(k + 1) * SIDES].to_vec();
        // a: start cap ring, rings 0..=4; b: ring 4 first.
        assert_eq!(ring(&a, CAP_RINGS - 1 + 4), ring(&b, 0));
        assert!(!c.positions.is_empty());
        let whole = tube.mesh(0, 20, DVec3::ZERO);
        assert_eq!(
            a.triangles() + b.triangles() + c.triangles(),
            whole.triangles()
        );
    }

    #[test]
    fn close_samples_are_skipped_and_a_dot_is_a_sphere() {
        // A dot: the pen wanders less than the radius and comes back.
        let pts = [
            DVec3::ZERO,
            DVec3::new(1e-3, 0.0, 0.0),
            DVec3::new(0.0, 2e-3, 0.0),
            DVec3::ZERO,
        ];
        let tube = Tube::new(&pts, 0.01);
        assert_eq!(tube.runs(), 1);
        let m = tube.mesh(0, 3, DVec3::new(1.0, 0.0, 0.0));
        assert!(closed(&m));
        assert_eq!(m.positions.len(), (2 * CAP_RINGS - 1) * SIDES + 2);
        for p in &m.positions {
            assert!(((p.as_dvec3() + DVec3::X).length() - 0.01).abs() < 1e-6);
        }
        // Repeated points (a stuck tip) give no degenerate segment.
        let stuck = [
            DVec3::ZERO,
            DVec3::X,
            DVec3::X,
            DVec3::X,
            DVec3::new(2.0, 0.0, 0.0),
        ];
        let m = Tube::new(&stuck, 0.1).mesh(0, 4, DVec3::ZERO);
        assert!(m.positions.iter().all(|p| p.is_finite()));
        assert!(closed(&m));
        assert!(Tube::new(&[], 0.1)
            .mesh(0, 0, DVec3::ZERO)
            .positions
            .is_empty());
    }
}
