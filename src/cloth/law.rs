//! The fabric's one-dimensional law, written once: a spring's tension f(|r|) with its toe in
//! tension, its soft compression and its jamming ramp ([`spring_response`]), the energy it
//! derives from ([`spring_energy`]), its gradient and projected Hessian block
//! (`spring_terms`, and split for a particle's local step: `spring_local`), and the same law in the form the local/global method's residual
//! evaluates it, scalar and AVX2 side by side (`JamRamps`, `springs_scalar`, `springs_avx2`,
//! tested to give the same bits). The springs, the membrane's fibres and every solver take it
//! from here.

use glam::{DMat3, DVec3};

use super::linalg::Lanes4;

/// Half-width of the jamming ramp as a fraction of the jamming strain J: a spring softer in
/// compression than in tension stiffens from kc at a compression of (1 − JAM_RAMP)·J to kc + k
/// at (1 + JAM_RAMP)·J, as yarns pressed together jam gradually. With a sharp step the
/// tension's slope jumps from kc to kc + k (1000× for cotton), and Newton's quadratic model
/// overshoots into the jammed region and backtracks: on the 8k-vertex skirt over 30 frames a
/// sharp 9 % jam took 645 Newton iterations, a linear ramp of ±0.02 around it 467, and ±50 %
/// around the default 8 % 466 (`docs/performance.md`). The ramp is a smoothstep 3s² − 2s³ of
/// s = (compression − start)/width, so the slope's own derivative is continuous too.
pub const JAM_RAMP: f64 = 0.5;

/// The toe of a spring softer in compression than in tension, as a fraction of its rest
/// length: from the rest length to this stretch its stiffness rises linearly from kc to k, the
/// low-strain toe of woven fabric's J-shaped tensile curve (the yarns' crimp straightening).
/// Without it the tension's slope jumps from kc to k (1000× for cotton) at the rest length,
/// where many springs of a draping garment sit; with it and the smoothstep jamming ramp
/// ([`JAM_RAMP`]) the slope is continuous everywhere, and Newton on the 8k-vertex skirt hanging
/// for 30 frames took 404 iterations instead of 451 (`docs/performance.md`). A wider toe
/// converges sooner still (with the sweeps and the longer step: 1 % 137 iterations against 158)
/// but makes a garment sway longer: the robot skirt demo's loop seam grew from 2.1 mm to 7.0 mm,
/// and to 17 mm after six warm-up loops (`docs/performance.md`, "A longer step, and a wider toe
/// measured"). The toe lengthens a
/// spring under a given tension by half the toe, (k − kc)/k · TOE_STRAIN/2 of its rest length.
pub const TOE_STRAIN: f64 = 0.003;

/// A spring's tension f (N, positive when stretched) and its derivative df/d|r| (N/m) at length
/// `len`, with extension e = len − rest: f = k·e for e ≥ 0 and kc·e in compression, for
/// symmetric springs (kc = k: the labs' model). When kc < k the spring has a toe and jams:
/// - in tension its stiffness rises linearly from kc at the rest length to k at a stretch of
///   [`TOE_STRAIN`]·rest and stays k beyond: f = k·e − (k − kc)·τ(e), τ the toe's deficit
///   (e − e²/(2t) up to the toe t, t/2 past it);
/// - in compression, past (1 − [`JAM_RAMP`])·J·rest (J = `jam`, a fraction of the rest length),
///   the full tension stiffness k is added back along a smoothstep ramp that completes at
///   (1 + JAM_RAMP)·J·rest.
///
/// So df/d|r| is continuous for every length.
#[inline(always)]
pub fn spring_response(len: f64, rest: f64, k: f64, kc: f64, jam: f64) -> (f64, f64) {
    let e = len - rest;
    if kc >= k {
        let stiffness = if e >= 0.0 { k } else { kc };
        (stiffness * e, stiffness)
    } else if e >= 0.0 {
        let t = TOE_STRAIN * rest;
        let m = e.min(t);
        (
            k * e - (k - kc) * (m - m * m / (2.0 * t)),
            k - (k - kc) * (1.0 - m / t),
        )
    } else {
        let (lo, hi) = jam_ramp(rest, jam);
        (
            kc * e - k * ramp_integral(-e, lo, hi),
            kc + k * ramp(-e, lo, hi),
        )
    }
}

/// Energy of a spring of length `len` (J): the integral of [`spring_response`]'s tension.
#[inline]
pub fn spring_energy(len: f64, rest: f64, k: f64, kc: f64, jam: f64) -> f64 {
    let e = len - rest;
    if kc >= k {
        0.5 * (if e >= 0.0 { k } else { kc }) * e * e
    } else if e >= 0.0 {
        // ½k·e² less (k − kc)·∫τ, ∫τ = e²/2 − e³/(6t) up to the toe, t²/3 + t/2·(e − t) past it.
        let t = TOE_STRAIN * rest;
        let deficit = if e < t {
            e * e / 2.0 - e * e * e / (6.0 * t)
        } else {
            t * t / 3.0 + t / 2.0 * (e - t)
        };
        0.5 * k * e * e - (k - kc) * deficit
    } else {
        let (lo, hi) = jam_ramp(rest, jam);
        0.5 * kc * e * e + k * ramp_integral2(-e, lo, hi)
    }
}

/// The compressions (m) where the jamming ramp of a spring of rest length `rest` starts and ends.
#[inline(always)]
pub(crate) fn jam_ramp(rest: f64, jam: f64) -> (f64, f64) {
    ((1.0 - JAM_RAMP) * jam * rest, (1.0 + JAM_RAMP) * jam * rest)
}

/// The smoothstep ramp 3s² − 2s³ from 0 at `lo` to 1 at `hi`, s = (t − lo)/(hi − lo) clamped
/// to [0, 1].
#[inline(always)]
fn ramp(t: f64, lo: f64, hi: f64) -> f64 {
    let s = ((t - lo) / (hi - lo)).clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

/// ∫ ramp from −∞ to t: w·(s³ − s⁴/2) on the ramp (w = hi − lo), w/2 + (t − hi) past it.
#[inline(always)]
fn ramp_integral(t: f64, lo: f64, hi: f64) -> f64 {
    let w = hi - lo;
    if t <= lo {
        0.0
    } else if t < hi {
        let s = (t - lo) / w;
        w * s * s * s * (1.0 - 0.5 * s)
    } else {
        0.5 * w + (t - hi)
    }
}

/// ∫ [`ramp_integral`] from −∞ to t: w²·(s⁴/4 − s⁵/10) on the ramp, 3w²/20 + w/2·(t − hi) +
/// (t − hi)²/2 past it.
#[inline(always)]
fn ramp_integral2(t: f64, lo: f64, hi: f64) -> f64 {
    let w = hi - lo;
    if t <= lo {
        0.0
    } else if t < hi {
        let s = (t - lo) / w;
        w * w * s.powi(4) * (0.25 - 0.1 * s)
    } else {
        0.15 * w * w + 0.5 * w * (t - hi) + 0.5 * (t - hi) * (t - hi)
    }
}

/// One spring's part of the local step at its end a (r = xa − xb): the gradient f·u, and the
/// projected block of [`spring_terms`] split as t·I + p·u uᵀ (t = max(f/|r|, 0), p = df/d|r| − t),
/// returned as (f·u, t, p·u uᵀ) so that a particle's local block sums the isotropic parts of its
/// springs before adding them once. `None` for coincident ends (no force, no direction).
#[inline(always)]
pub(crate) fn spring_local(
    r: DVec3,
    rest: f64,
    k: f64,
    kc: f64,
    jam: f64,
) -> Option<(DVec3, f64, DMat3)> {
    let (f, u, t, p) = spring_parts(r, rest, k, kc, jam)?;
    Some((
        u * f,
        t,
        DMat3::from_cols(u * (u.x * p), u * (u.y * p), u * (u.z * p)),
    ))
}

/// A spring's tension f, direction u = r/|r|, transverse stiffness t = max(f/|r|, 0) and
/// p = df/d|r| − t, from which its gradient f·u and projected block t·I + p·u uᵀ are built;
/// `None` for coincident ends.
#[inline(always)]
fn spring_parts(r: DVec3, rest: f64, k: f64, kc: f64, jam: f64) -> Option<(f64, DVec3, f64, f64)> {
    let len = r.length();
    if len > 0.0 {
        let (f, along) = spring_response(len, rest, k, kc, jam);
        let t = (f / len).max(0.0);
        Some((f, r / len, t, along - t))
    } else {
        None
    }
}

/// The gradient f·u and the projected Hessian block of one spring, as rows: df/d|r| along u
/// and f/|r| across it, the latter clamped at zero for a compressed spring (whose exact
/// transverse term is negative), so every block is positive semi-definite.
#[inline(always)]
pub(crate) fn spring_terms(
    r: DVec3,
    rest: f64,
    k: f64,
    kc: f64,
    jam: f64,
) -> (DVec3, [[f64; 3]; 3]) {
    if let Some((f, u, t, p)) = spring_parts(r, rest, k, kc, jam) {
        let he = [
            [t + p * u.x * u.x, p * u.x * u.y, p * u.x * u.z],
            [p * u.y * u.x, t + p * u.y * u.y, p * u.y * u.z],
            [p * u.z * u.x, p * u.z * u.y, t + p * u.z * u.z],
        ];
        (u * f, he)
    } else {
        // Coincident ends: no force and no defined direction; the inertia keeps H definite.
        (DVec3::ZERO, [[0.0; 3]; 3])
    }
}

/// ∂/∂xa of a spring's energy with r = xa − xb: f·r/|r| with f from [`spring_response`] (zero
/// for coincident ends).
#[inline]
pub fn spring_gradient(r: DVec3, rest: f64, k: f64, kc: f64, jam: f64) -> DVec3 {
    let len = r.length();
    if len > 0.0 {
        r * (spring_response(len, rest, k, kc, jam).0 / len)
    } else {
        DVec3::ZERO
    }
}

/// The free springs' toes and jamming ramps in the form the spring kernels evaluate (see
/// [`spring_response`]). For a spring compressed by t = l − |d| (m), the
/// integral of its smoothstep ramp, `push` = m·s²·(1 − s/2) + (a − m) with a = max(t − lo, 0),
/// m = min(a, w) and s = m/w, so that its jammed push is h²k·push/|d|·d. For a spring stretched
/// by e = |d| − l, the toe's deficit `toe_push` = m − m²/(2τ) with m = min(max(e, 0), τ), τ the
/// toe, so that the toe's pull is less by h²(k − kc)·toe_push/|d|·d. A spring that never jams
/// (kc = k) has lo = ∞ and τ = 0 and pushes nothing.
#[derive(Debug, Clone)]
pub(crate) struct JamRamps {
    /// Rest length l, m.
    rest: Vec<f64>,
    /// Compression where the ramp starts, m (∞ for a spring that never jams).
    lo: Vec<f64>,
    /// The ramp's width w, m.
    width: Vec<f64>,
    /// 1/w, 1/m (0 for a spring that never jams).
    inv: Vec<f64>,
    /// The toe τ, m (0 for a spring that never jams).
    toe: Vec<f64>,
    /// 1/(2τ), 1/m (0 for a spring that never jams).
    toe_inv: Vec<f64>,
}

impl JamRamps {
    /// Ramps from a compression of (1 − [`JAM_RAMP`])·`jam`·l to
    /// (1 + JAM_RAMP)·`jam`·l and toes of `toe`·l for the springs softer in compression
    /// (kc < k).
    pub(crate) fn new(rest: &[f64], k: &[f64], kc: &[f64], jam: f64, toe: f64) -> Self {
        let n = rest.len();
        let mut r = JamRamps {
            rest: rest.to_vec(),
            lo: vec![f64::INFINITY; n],
            width: vec![0.0; n],
            inv: vec![0.0; n],
            toe: vec![0.0; n],
            toe_inv: vec![0.0; n],
        };
        for i in 0..n {
            if kc[i] < k[i] {
                let (lo, hi) = jam_ramp(rest[i], jam);
                r.lo[i] = lo;
                r.width[i] = hi - lo;
                r.inv[i] = 1.0 / (hi - lo);
                r.toe[i] = toe * rest[i];
                r.toe_inv[i] = 0.5 / (toe * rest[i]);
            }
        }
        r
    }

    /// ∫ ramp (m) of spring `i` at length `len` (m).
    #[inline(always)]
    pub(crate) fn push(&self, i: usize, len: f64) -> f64 {
        let a = (self.rest[i] - len - self.lo[i]).max(0.0);
        let m = a.min(self.width[i]);
        let s = m * self.inv[i];
        m * s * s * (1.0 - 0.5 * s) + (a - m)
    }

    /// The toe's deficit (m) of spring `i` at length `len` (m).
    #[inline(always)]
    pub(crate) fn toe_push(&self, i: usize, len: f64) -> f64 {
        let m = (len - self.rest[i]).max(0.0).min(self.toe[i]);
        m - m * m * self.toe_inv[i]
    }
}

/// The springs' part of [`FastSolver::residual_step`] from spring `first` on: h²k·(l/|d| − 1)·d
/// added to end a and subtracted from end b (d = xa − xb; coincident ends pull nothing), scaled
/// by `soft` = kc/k where the spring is compressed (l/|d| > 1), plus the jammed push
/// h²k·p/|d|·d with p = [`JamRamps::push`] at |d|; where it is stretched, plus the toe's
/// deficit h²k·(1 − soft)·p/|d|·d with p = [`JamRamps::toe_push`].
pub(crate) fn springs_scalar(
    x: &[Lanes4],
    r: &mut [Lanes4],
    (ends, hkl, hk): (&[[u32; 2]], &[f64], &[f64]),
    soft: &[f64],
    jam: &JamRamps,
    first: usize,
) {
    for i in first..ends.len() {
        let [a, b] = ends[i];
        let (a, b) = (a as usize, b as usize);
        let d = x[a] - x[b];
        let len2 = d.0[0] * d.0[0] + d.0[1] * d.0[1] + d.0[2] * d.0[2];
        if len2 > 0.0 {
            let len = len2.sqrt();
            let mut c = hkl[i] / len - hk[i];
            if c > 0.0 {
                c = c * soft[i] + hk[i] * jam.push(i, len) / len;
            } else {
                c += hk[i] * (1.0 - soft[i]) * jam.toe_push(i, len) / len;
            }
            let f = d * c;
            r[a] += f;
            r[b] -= f;
        }
    }
}

/// The springs' part of [`FastSolver::residual_step`], four springs at a time with AVX2: the
/// four square roots and divisions are one instruction each, the scatter stays in spring order,
/// and every operation is the scalar code's (no fusion), so the results are identical. Returns
/// how many springs were done (a multiple of four); the caller does the rest.
///
/// # Safety
/// The CPU supports AVX2; `x` and `r` have the same length and every end indexes them. (`x` must
/// also have a zero fourth lane for the results to be the scalar code's.)
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn springs_avx2(
    x: &[Lanes4],
    r: &mut [Lanes4],
    ends: &[[u32; 2]],
    hkl: &[f64],
    hk: &[f64],
    soft: &[f64],
    jam: &JamRamps,
) -> usize {
    use std::arch::x86_64::*;
    let quads = ends.len() / 4;
    let (ends, hkl, hk, soft) = (
        &ends[..4 * quads],
        &hkl[..4 * quads],
        &hk[..4 * quads],
        &soft[..4 * quads],
    );
    let (jam_rest, jam_lo, jam_width, jam_inv, toe, toe_inv) = (
        &jam.rest[..4 * quads],
        &jam.lo[..4 * quads],
        &jam.width[..4 * quads],
        &jam.inv[..4 * quads],
        &jam.toe[..4 * quads],
        &jam.toe_inv[..4 * quads],
    );
    debug_assert!(x.len() == r.len());
    debug_assert!(ends.iter().flatten().all(|&i| (i as usize) < x.len()));
    let (xp, rp) = (x.as_ptr() as *const f64, r.as_mut_ptr() as *mut f64);
    for q in 0..quads {
        let e: &[[u32; 2]; 4] = ends[4 * q..4 * q + 4].try_into().expect("4 springs");
        // SAFETY: indices in range (the caller's contract); `Lanes4` is an aligned [f64; 4].
        unsafe {
            let at = |i: u32| xp.add(4 * i as usize);
            let d: [__m256d; 4] = std::array::from_fn(|j| {
                _mm256_sub_pd(_mm256_load_pd(at(e[j][0])), _mm256_load_pd(at(e[j][1])))
            });
            let sq: [__m256d; 4] = std::array::from_fn(|j| _mm256_mul_pd(d[j], d[j]));
            // len2_j = (dx² + dy²) + (dz² + 0): the scalar code's sum (lane 3 is zero).
            let t01 = _mm256_hadd_pd(sq[0], sq[1]);
            let t23 = _mm256_hadd_pd(sq[2], sq[3]);
            let lo = _mm256_blend_pd(t01, t23, 0b1100);
            let hi = _mm256_permute2f128_pd(t01, t23, 0x21);
            let len2 = _mm256_add_pd(lo, hi);
            let len = _mm256_sqrt_pd(len2);
            let hkq = _mm256_loadu_pd(hk.as_ptr().add(4 * q));
            let c = _mm256_sub_pd(
                _mm256_div_pd(_mm256_loadu_pd(hkl.as_ptr().add(4 * q)), len),
                hkq,
            );
            // Compressed springs (c > 0) push with kc instead of k, c·(kc/k), plus the jammed
            // push h²k·JamRamps::push/|d|; stretched ones pull less by the toe's deficit
            // h²k·(1 − kc/k)·JamRamps::toe_push/|d|; in the scalar code's order.
            let compressed = _mm256_cmp_pd(c, _mm256_setzero_pd(), _CMP_GT_OQ);
            let load = |v: &[f64]| _mm256_loadu_pd(v.as_ptr().add(4 * q));
            let zero = _mm256_setzero_pd();
            let rest = load(jam_rest);
            let a = _mm256_max_pd(_mm256_sub_pd(_mm256_sub_pd(rest, len), load(jam_lo)), zero);
            let m = _mm256_min_pd(a, load(jam_width));
            let s = _mm256_mul_pd(m, load(jam_inv));
            let push = _mm256_add_pd(
                _mm256_mul_pd(
                    _mm256_mul_pd(_mm256_mul_pd(m, s), s),
                    _mm256_sub_pd(_mm256_set1_pd(1.0), _mm256_mul_pd(_mm256_set1_pd(0.5), s)),
                ),
                _mm256_sub_pd(a, m),
            );
            let jam = _mm256_div_pd(_mm256_mul_pd(hkq, push), len);
            let softq = load(soft);
            let t = _mm256_min_pd(_mm256_max_pd(_mm256_sub_pd(len, rest), zero), load(toe));
            let toe_push = _mm256_sub_pd(t, _mm256_mul_pd(_mm256_mul_pd(t, t), load(toe_inv)));
            let toe_pull = _mm256_div_pd(
                _mm256_mul_pd(
                    _mm256_mul_pd(hkq, _mm256_sub_pd(_mm256_set1_pd(1.0), softq)),
                    toe_push,
                ),
                len,
            );
            let c = _mm256_blendv_pd(
                _mm256_add_pd(c, toe_pull),
                _mm256_add_pd(_mm256_mul_pd(c, softq), jam),
                compressed,
            );
            // Coincident ends pull nothing (and l/0 is discarded).
            let c = _mm256_and_pd(c, _mm256_cmp_pd(len2, _mm256_setzero_pd(), _CMP_GT_OQ));
            let cs = [
                _mm256_permute4x64_pd(c, 0x00),
                _mm256_permute4x64_pd(c, 0x55),
                _mm256_permute4x64_pd(c, 0xaa),
                _mm256_permute4x64_pd(c, 0xff),
            ];
            for j in 0..4 {
                let f = _mm256_mul_pd(d[j], cs[j]);
                let (a, b) = (rp.add(4 * e[j][0] as usize), rp.add(4 * e[j][1] as usize));
                _mm256_store_pd(a, _mm256_add_pd(_mm256_load_pd(a), f));
                _mm256_store_pd(b, _mm256_sub_pd(_mm256_load_pd(b), f));
            }
        }
    }
    4 * quads
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tension is the derivative of the energy and its slope the derivative of the tension
    /// (central differences), from past the toe in tension through the toe, the soft
    /// compression, the jamming ramp and past it; the slope is continuous everywhere (between
    /// neighbouring samples it changes by no more than its steepest rise, (k − kc)/t in the toe
    /// and 1.5·k/w on the ramp, times their distance: the former jump of k − kc at the rest
    /// length is 45 times that), is kc at the rest length and k past the toe, and reaches kc + k
    /// past the ramp.
    #[test]
    fn spring_response_is_the_energys_derivative_through_the_toe_and_the_jamming_ramp() {
        let (rest, k, kc, jam) = (0.01, 1000.0, 1.0, 0.08);
        let (lo, hi) = jam_ramp(rest, jam);
        assert!(lo < jam * rest && hi > jam * rest);
        assert!(((lo + hi) / 2.0 - jam * rest).abs() < 1e-15);
        let toe = TOE_STRAIN * rest;
        let d = 1e-9;
        let (mut on_ramp, mut in_toe) = (0, 0);
        let samples = 3000;
        let spacing = 0.2 * rest / samples as f64;
        let steepest = ((k - kc) / toe).max(1.5 * k / (hi - lo));
        let mut last_slope: Option<f64> = None;
        for i in 0..=samples {
            let len = rest * 1.05 - spacing * i as f64;
            let (f, slope) = spring_response(len, rest, k, kc, jam);
            let fd_f = (spring_energy(len + d, rest, k, kc, jam)
                - spring_energy(len - d, rest, k, kc, jam))
                / (2.0 * d);
            let fd_slope = (spring_response(len + d, rest, k, kc, jam).0
                - spring_response(len - d, rest, k, kc, jam).0)
                / (2.0 * d);
            assert!((f - fd_f).abs() < 1e-6, "len {len}: f {f} vs {fd_f}");
            assert!(
                (slope - fd_slope).abs() < 1e-4 * k,
                "len {len}: slope {slope} vs {fd_slope}"
            );
            if let Some(last) = last_slope {
                assert!(
                    (slope - last).abs() <= steepest * spacing * 1.001,
                    "len {len}: slope {slope} after {last}"
                );
            }
            last_slope = Some(slope);
            let e = len - rest;
            if e > 0.0 && e < toe {
                in_toe += 1;
                assert!(slope >= kc && slope <= k);
            }
            if -e > lo && -e < hi {
                on_ramp += 1;
                assert!(slope >= kc && slope <= kc + k);
            }
        }
        assert!(on_ramp > 200 && in_toe > 20, "{on_ramp} {in_toe}");
        assert!(k - kc > 40.0 * steepest * spacing);
        assert_eq!(spring_response(rest, rest, k, kc, jam), (0.0, kc));
        let past = rest * (1.0 + 2.0 * TOE_STRAIN);
        let (f, slope) = spring_response(past, rest, k, kc, jam);
        assert_eq!(slope, k);
        assert!((f - (k * (past - rest) - (k - kc) * toe / 2.0)).abs() < 1e-12);
        assert_eq!(spring_response(rest - hi * 1.1, rest, k, kc, jam).1, kc + k);
        assert_eq!(spring_response(rest - lo * 0.9, rest, k, kc, jam).1, kc);
        // Symmetric springs never jam and have no toe.
        assert_eq!(
            spring_response(rest * 0.5, rest, k, k, jam),
            (-k * rest * 0.5, k)
        );
        let len = rest + 0.5 * toe;
        assert_eq!(spring_response(len, rest, k, k, jam), (k * (len - rest), k));
    }

    /// The AVX2 spring kernel gives exactly the scalar loop's residual (coincident ends and a
    /// count that is not a multiple of four included).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_springs_match_the_scalar_loop_exactly() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let n = 40;
        let x: Vec<Lanes4> = (0..n)
            .map(|i| {
                let t = i as f64;
                Lanes4::from_vec3(DVec3::new((t * 0.7).sin(), (t * 0.3).cos() * 2.0, t * 0.01))
            })
            .collect();
        let mut ends: Vec<[u32; 2]> = (0..n as u32 - 3)
            .flat_map(|i| [[i, i + 1], [i, i + 3], [i + 2, i]])
            .collect();
        ends.push([5, 5]); // coincident ends
        ends.push([7, 9]);
        let hkl: Vec<f64> = (0..ends.len()).map(|i| 0.1 + 0.01 * i as f64).collect();
        let hk: Vec<f64> = (0..ends.len()).map(|i| 0.3 + 0.02 * i as f64).collect();
        // Compression stiffness ratios from 0 to 1 (both branches of the blend are taken).
        let soft: Vec<f64> = (0..ends.len()).map(|i| (i % 5) as f64 / 4.0).collect();
        // Springs that jam (kc < k) at 30 % compression, with lengths before, on and past
        // their ramps, and toes of 50 % with stretches within and past them.
        let rest: Vec<f64> = hkl.iter().zip(&hk).map(|(a, b)| a / b).collect();
        let k = vec![1.0; ends.len()];
        let jam = JamRamps::new(&rest, &k, &soft, 0.3, 0.5);
        let regions = |lo: f64, hi: f64| {
            (0..ends.len())
                .filter(|&i| {
                    let [a, b] = ends[i];
                    let len = (x[a as usize] - x[b as usize]).xyz().length();
                    let t = (rest[i] - len) / rest[i];
                    soft[i] < 1.0 && t > lo && t < hi
                })
                .count()
        };
        assert!(regions(0.0, 0.225) > 0 && regions(0.225, 0.375) > 0 && regions(0.375, 1.0) > 0);
        assert!(regions(-0.5, 0.0) > 0 && regions(f64::NEG_INFINITY, -0.5) > 0);
        let mut want = vec![Lanes4::from_vec3(DVec3::new(0.5, -0.25, 1.0)); n];
        let mut got = want.clone();
        let springs = (&ends[..], &hkl[..], &hk[..]);
        springs_scalar(&x, &mut want, springs, &soft, &jam, 0);
        // SAFETY: AVX2 detected; every end is below n.
        let done = unsafe { springs_avx2(&x, &mut got, &ends, &hkl, &hk, &soft, &jam) };
        assert_eq!(done, ends.len() / 4 * 4);
        springs_scalar(&x, &mut got, springs, &soft, &jam, done);
        assert_eq!(got, want);
    }
}
