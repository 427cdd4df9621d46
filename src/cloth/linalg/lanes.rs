//! The right-hand sides the triangular sweeps run over (`DVec3`, and padded [`Lanes4`] and
//! [`Lanes4f`] of four unknowns' coordinates), and the row kernels of the sweeps.

use glam::DVec3;

/// Right-hand-side element types of the triangular sweeps over factor values of type `V`:
/// small vectors of f64 or f32.
pub(crate) trait Lanes<V>:
    Copy
    + std::ops::Sub<Output = Self>
    + std::ops::Neg<Output = Self>
    + std::ops::AddAssign
    + std::ops::SubAssign
{
    const ZERO: Self;
    /// self + a·l
    fn mul_add(self, a: Self, l: V) -> Self;
    /// self·l
    fn scale(self, l: V) -> Self;
    /// Self with negligible components set to zero (f32 lanes: |v| < [`FLUSH_BELOW`]), applied
    /// to every solved unknown, so that decaying solutions do not go subnormal.
    #[inline(always)]
    fn flush(self) -> Self {
        self
    }
}

/// [`Cholesky::solve4f`] sets solved components below this magnitude to zero: far below f32's
/// resolution of an order-1 right-hand side, and far enough above f32's smallest normal number
/// (1.2e-38) that products with the factor's values stay normal (subnormal operands and results
/// cost a microcode assist per multiply-add on x86).
pub const FLUSH_BELOW: f32 = 1e-25;

impl Lanes<f64> for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    #[inline(always)]
    fn mul_add(self, a: Self, l: f64) -> Self {
        self + a * l
    }
    #[inline(always)]
    fn scale(self, l: f64) -> Self {
        self * l
    }
}

impl Lanes<f32> for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    #[inline(always)]
    fn mul_add(self, a: Self, l: f32) -> Self {
        self + a * f64::from(l)
    }
    #[inline(always)]
    fn scale(self, l: f32) -> Self {
        self * f64::from(l)
    }
}

/// Four f64 lanes aligned to 32 bytes: a right-hand side of [`Cholesky::solve4`] (x, y, z and a
/// spare lane).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Lanes4(pub [f64; 4]);

impl Lanes4 {
    /// (x, y, z, 0).
    #[inline(always)]
    pub fn from_vec3(v: DVec3) -> Self {
        Lanes4([v.x, v.y, v.z, 0.0])
    }

    /// The first three lanes.
    #[inline(always)]
    pub fn xyz(self) -> DVec3 {
        DVec3::new(self.0[0], self.0[1], self.0[2])
    }
}

impl Lanes<f64> for Lanes4 {
    const ZERO: Self = Lanes4([0.0; 4]);
    #[inline(always)]
    fn mul_add(self, a: Self, l: f64) -> Self {
        // `mul_add` becomes one fused instruction where FMA is enabled (and is exact either way).
        Lanes4(std::array::from_fn(|k| a.0[k].mul_add(l, self.0[k])))
    }
    #[inline(always)]
    fn scale(self, l: f64) -> Self {
        self * l
    }
}

/// f64 right-hand sides over f32 factor values (each value widened once per use).
impl Lanes<f32> for Lanes4 {
    const ZERO: Self = Lanes4([0.0; 4]);
    #[inline(always)]
    fn mul_add(self, a: Self, l: f32) -> Self {
        let l = f64::from(l);
        Lanes4(std::array::from_fn(|k| a.0[k].mul_add(l, self.0[k])))
    }
    #[inline(always)]
    fn scale(self, l: f32) -> Self {
        self * f64::from(l)
    }
}

/// Four f32 lanes aligned to 16 bytes (one 128-bit vector): a right-hand side of
/// [`Cholesky::solve4f`] (x, y, z and a spare lane).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(16))]
pub struct Lanes4f(pub [f32; 4]);

impl Lanes4f {
    /// The first three lanes of `v`, rounded to f32 (the fourth is 0).
    #[inline(always)]
    pub fn from_lanes4(v: Lanes4) -> Self {
        Lanes4f([v.0[0] as f32, v.0[1] as f32, v.0[2] as f32, 0.0])
    }

    /// The four lanes widened to f64.
    #[inline(always)]
    pub fn to_lanes4(self) -> Lanes4 {
        Lanes4(self.0.map(f64::from))
    }
}

impl Lanes<f32> for Lanes4f {
    const ZERO: Self = Lanes4f([0.0; 4]);
    #[inline(always)]
    fn mul_add(self, a: Self, l: f32) -> Self {
        Lanes4f(std::array::from_fn(|k| a.0[k].mul_add(l, self.0[k])))
    }
    #[inline(always)]
    fn scale(self, l: f32) -> Self {
        self * l
    }
    #[inline(always)]
    fn flush(self) -> Self {
        Lanes4f(self.0.map(|v| if v.abs() < FLUSH_BELOW { 0.0 } else { v }))
    }
}

/// The forward update of a supernode of width W: tail[r − c1] −= Σ_j L[r, j]·y[j] per pattern row.
#[inline(always)]
pub(crate) fn forward_rows<V: Copy, T: Lanes<V>, const W: usize>(
    rows: &[u32],
    below: &[V],
    y: &[T],
    tail: &mut [T],
    c1: usize,
) {
    let y: &[T; W] = y.try_into().expect("supernode width");
    for (&r, l) in rows.iter().zip(below.chunks_exact(W)) {
        let mut acc = <T as Lanes<V>>::ZERO;
        for j in 0..W {
            acc = acc.mul_add(y[j], l[j]);
        }
        tail[r as usize - c1] -= acc;
    }
}

/// The backward update of a supernode of width W: x[j] −= Σ_r L[r, j]·x[r].
#[inline(always)]
pub(crate) fn backward_rows<V: Copy, T: Lanes<V>, const W: usize>(
    rows: &[u32],
    below: &[V],
    x: &mut [T],
    tail: &[T],
    c1: usize,
) {
    let x: &mut [T; W] = x.try_into().expect("supernode width");
    let mut acc = *x;
    for (&r, l) in rows.iter().zip(below.chunks_exact(W)) {
        let xr = tail[r as usize - c1];
        for j in 0..W {
            acc[j] = acc[j].mul_add(-xr, l[j]);
        }
    }
    *x = acc;
}

/// Σ l[j]·y[j], four accumulators to hide the multiply-add latency.
#[inline(always)]
pub(crate) fn dot<V: Copy, T: Lanes<V>>(l: &[V], y: &[T]) -> T {
    let mut acc = [<T as Lanes<V>>::ZERO; 4];
    let (l4, y4) = (l.chunks_exact(4), y.chunks_exact(4));
    let (lr, yr) = (l4.remainder(), y4.remainder());
    for (l, y) in l4.zip(y4) {
        for k in 0..4 {
            acc[k] = acc[k].mul_add(y[k], l[k]);
        }
    }
    for (l, y) in lr.iter().zip(yr) {
        acc[0] = acc[0].mul_add(*y, *l);
    }
    acc[0] += acc[1];
    acc[2] += acc[3];
    acc[0] += acc[2];
    acc[0]
}
