//! The bilinear sampler of the vector kernel: the [`Sampler`] trait, which both the 128-bit
//! sampler ([`PairWeights`], here) and the AVX2 one (`super::avx2`) implement, and the tap
//! pairs they share. A file of its own so that the kernel ([`super`]) and the AVX2 sampler both
//! import it and neither imports the other's items.

use crate::klt::arith::{Bilinear, W_BITS};
use crate::klt::kernel::patch::Column;
use crate::klt::kernel::window::PIX_SHIFT;
use crate::simd::low;
use wide::{i16x8, i32x4, i32x8, u8x16, u32x4};

/// Lanes of one vector of `i16` (128 bits).
pub(super) const L: usize = 8;

/// The Q14 weights as `i16`, so that every product is `i16 x i16`: each within one unit of
/// `0 ..= 2¹⁴` (`w11 = 2¹⁴ - w00 - w01 - w10` is `-1` where the other three round up at a
/// tiny `a b`; the packed kernel uses that `-1` too).
pub(super) fn weights(b: &Bilinear) -> [i16; 4] {
    b.w.map(|v| v.clamp(-1, (1 << W_BITS) + 1) as i16)
}

/// A bilinear sampler of eight pixels at a window's weights, and the vector arithmetic of the
/// kernels on its samples: [`PairWeights`] (128-bit, every SIMD target) or
/// `avx2::Avx2` (x86-64 CPUs with AVX2). Both compute the same integers:
/// `⌊(p₀₀ w₀₀ + p₀₁ w₀₁ + p₁₀ w₁₀ + p₁₁ w₁₁) / 2⁹⌉`, exact in `i32`, packed to `i16`.
///
/// A sample takes its taps from two rows; the kernels walk a window a column of vectors at a
/// time, so each row's taps are prepared once ([`Sampler::pixel_taps`]) and serve as the lower
/// row of one sample and the upper row of the next. A [`Sampler::Vector`] holds the samples of
/// one row (eight lanes) or of two consecutive rows, in an order of the sampler's own
/// ([`Sampler::lanes`]); the template planes are stored in that order, so the kernels never
/// reorder lanes. When `win` is not a whole number of vectors, the last vector's missing rows
/// are zero (pixels and derivatives both), so they add nothing to any sum.
pub(super) trait Sampler: Copy + 'static {
    /// A row's pixel taps `(p[x], p[x + 1])` of lanes `x = 0 .. 8`, ready for weighing.
    type Pixels: Copy + 'static;
    /// A row's derivative taps, `Ix`'s and `Iy`'s, the same way.
    type Derivatives: Copy + 'static;
    /// `i16` samples of one or two rows of eight lanes.
    type Vector: Copy + 'static;
    /// `i32` sums of products of [`Self::Vector`]s.
    type Sums: Copy + 'static;
    /// A [`Self::Vector`] in memory, as the template planes keep it.
    type Stored: bytemuck::Pod;

    /// The pixel taps of row `r`.
    fn pixel_taps(self, r: &[u8; L + 1]) -> Self::Pixels;
    /// The derivative taps of row `r` of `[Ix, Iy]` pairs.
    fn derivative_taps(self, r: &[[i16; 2]; L + 1]) -> Self::Derivatives;
    /// The next vector of pixels (1/32 grey levels) down a column whose previous row's taps
    /// are `upper`, the rows below from `taps`; `upper` becomes the last row's. `None` when
    /// `taps` has no row left.
    fn next_pixels(
        self,
        upper: &mut Self::Pixels,
        taps: &mut Column<'_, u8, { L + 1 }>,
    ) -> Option<Self::Vector>;
    /// [`Self::next_pixels`] for `Ix` and `Iy` (`⌊Σ / 2¹⁴⌉`, in the units of the Scharr
    /// derivatives).
    fn next_derivatives(
        self,
        upper: &mut Self::Derivatives,
        taps: &mut Column<'_, [i16; 2], { L + 1 }>,
    ) -> Option<(Self::Vector, Self::Vector)>;
    /// The vector whose every row is `row`, in the sampler's lane order.
    fn lanes(self, row: i16x8) -> Self::Vector;
    /// A vector read from the template planes.
    fn load(self, v: &Self::Stored) -> Self::Vector;
    /// A vector to keep in the template planes.
    fn store(self, v: Self::Vector) -> Self::Stored;
    /// `a & b`.
    fn and(self, a: Self::Vector, b: Self::Vector) -> Self::Vector;
    /// `a - b`, wrapping (the kernels' differences fit `i16`).
    fn sub(self, a: Self::Vector, b: Self::Vector) -> Self::Vector;
    /// Sums of nothing.
    fn zero(self) -> Self::Sums;
    /// `acc` plus the products `a · b`, each pair of adjacent lanes' into one `i32` lane.
    fn dot(self, acc: Self::Sums, a: Self::Vector, b: Self::Vector) -> Self::Sums;
    /// `acc` plus `|a|`, each pair of adjacent lanes' into one `i32` lane.
    fn abs(self, acc: Self::Sums, a: Self::Vector) -> Self::Sums;
    /// The lanes of `acc` added (exact in `i64`).
    fn sum(self, acc: Self::Sums) -> i64;
}

/// The weights of each row's pair of taps, alternating across the lanes: `[w00, w01, ...]`
/// for the upper row, `[w10, w11, ...]` for the lower.
#[derive(Clone, Copy)]
pub(super) struct PairWeights {
    pub(super) upper: i16x8,
    pub(super) lower: i16x8,
}

impl PairWeights {
    pub(super) fn new(w: &[i16; 4]) -> Self {
        let [w00, w01, w10, w11] = *w;
        let pair = |a: i16, b: i16| i16x8::new([a, b, a, b, a, b, a, b]);
        Self {
            upper: pair(w00, w01),
            lower: pair(w10, w11),
        }
    }
}

/// The taps `(p[x], p[x + 1])` of lanes `x = 0 .. 8` of `r` as sixteen interleaved bytes: two
/// 8-byte loads, one byte interleave (`punpcklbw`).
#[inline(always)]
pub(super) fn byte_pairs(r: &[u8; L + 1]) -> u8x16 {
    match (r.first_chunk::<L>(), r.last_chunk::<L>()) {
        (Some(left), Some(right)) => u8x16::unpack_low(low(left), low(right)),
        _ => u8x16::ZERO,
    }
}

/// The tap pairs of `Ix` and of `Iy` of four lanes from their `[Ix, Iy]` pairs at `x` (`a`)
/// and `x + 1` (`b`), each pair as a 32-bit lane: `Ix`'s are the first halves in memory of
/// `a`'s and `b`'s lanes, `Iy`'s the second halves, joined by masks and shifts (no shuffle).
#[inline(always)]
pub(super) fn split_pairs(a: u32x4, b: u32x4) -> (u32x4, u32x4) {
    let low = u32x4::splat(0xFFFF);
    if cfg!(target_endian = "little") {
        ((a & low) | (b << 16), (a >> 16) | (b & !low))
    } else {
        ((a & !low) | (b >> 16), (a << 16) | (b & low))
    }
}

/// The taps of row `r`'s `[Ix, Iy]` pairs: `Ix`'s pairs of lanes 0-3 and 4-7, then `Iy`'s.
#[inline(always)]
fn derivative_pairs(r: &[[i16; 2]; L + 1]) -> [i16x8; 4] {
    let words = |p: Option<&[[i16; 2]; 4]>| p.map_or(u32x4::ZERO, |p| bytemuck::cast(*p));
    let half = |r: &[[i16; 2]]| {
        (
            words(r.first_chunk()),
            words(r.get(1..).and_then(|r| r.first_chunk())),
        )
    };
    let ((a0, b0), (a1, b1)) = (half(r), half(r.get(L / 2..).unwrap_or(&[])));
    let (x0, y0) = split_pairs(a0, b0);
    let (x1, y1) = split_pairs(a1, b1);
    [x0, x1, y0, y1].map(bytemuck::cast)
}

/// `⌊Σ taps · w / 2^shift⌉` for the 8 lanes of the rows of tap pairs `a` (upper) and `b`
/// (lanes 0-3, then 4-7): each row's tap pairs weighed by one `i16` dot product, exact in
/// `i32` (at most `255 · 2¹⁴` for pixels, `16 · 255 · 2¹⁴` for derivatives), then packed back
/// to `i16`, where every result fits (pixels at most `255 · 32` in 1/32 grey levels,
/// derivatives `16 · 255`).
#[inline(always)]
fn interpolate(a: [i16x8; 2], b: [i16x8; 2], w: &PairWeights, shift: i32) -> i16x8 {
    let half = i32x4::splat(1 << (shift - 1));
    let lo = (a[0].dot(w.upper) + b[0].dot(w.lower) + half) >> shift;
    let hi = (a[1].dot(w.upper) + b[1].dot(w.lower) + half) >> shift;
    i16x8::from_i32x8_saturate(bytemuck::cast::<[i32x4; 2], i32x8>([lo, hi]))
}

impl Sampler for PairWeights {
    type Pixels = [i16x8; 2];
    type Derivatives = [i16x8; 4];
    /// One row.
    type Vector = i16x8;
    type Sums = i32x4;
    type Stored = [i16; L];

    /// [`byte_pairs`], widened.
    #[inline(always)]
    fn pixel_taps(self, r: &[u8; L + 1]) -> [i16x8; 2] {
        let p = byte_pairs(r);
        [i16x8::from_u8x16_low(p), i16x8::from_u8x16_high(p)]
    }

    /// [`derivative_pairs`].
    #[inline(always)]
    fn derivative_taps(self, r: &[[i16; 2]; L + 1]) -> [i16x8; 4] {
        derivative_pairs(r)
    }

    /// [`interpolate`] of pixels.
    #[inline(always)]
    fn next_pixels(
        self,
        upper: &mut [i16x8; 2],
        taps: &mut Column<'_, u8, { L + 1 }>,
    ) -> Option<i16x8> {
        let lower = self.pixel_taps(taps.next()?);
        let upper = core::mem::replace(upper, lower);
        Some(interpolate(upper, lower, &self, PIX_SHIFT as i32))
    }

    /// [`interpolate`] of each derivative.
    #[inline(always)]
    fn next_derivatives(
        self,
        upper: &mut [i16x8; 4],
        taps: &mut Column<'_, [i16; 2], { L + 1 }>,
    ) -> Option<(i16x8, i16x8)> {
        let lower = self.derivative_taps(taps.next()?);
        let [x0, x1, y0, y1] = core::mem::replace(upper, lower);
        let [u0, u1, v0, v1] = lower;
        let shift = W_BITS as i32;
        Some((
            interpolate([x0, x1], [u0, u1], &self, shift),
            interpolate([y0, y1], [v0, v1], &self, shift),
        ))
    }

    #[inline(always)]
    fn lanes(self, row: i16x8) -> i16x8 {
        row
    }
    #[inline(always)]
    fn load(self, v: &[i16; L]) -> i16x8 {
        i16x8::new(*v)
    }
    #[inline(always)]
    fn store(self, v: i16x8) -> [i16; L] {
        v.to_array()
    }
    #[inline(always)]
    fn and(self, a: i16x8, b: i16x8) -> i16x8 {
        a & b
    }
    #[inline(always)]
    fn sub(self, a: i16x8, b: i16x8) -> i16x8 {
        a - b
    }
    #[inline(always)]
    fn zero(self) -> i32x4 {
        i32x4::ZERO
    }
    #[inline(always)]
    fn dot(self, acc: i32x4, a: i16x8, b: i16x8) -> i32x4 {
        acc + a.dot(b)
    }
    #[inline(always)]
    fn abs(self, acc: i32x4, a: i16x8) -> i32x4 {
        acc + a.abs().dot(i16x8::ONE)
    }
    #[inline(always)]
    fn sum(self, acc: i32x4) -> i64 {
        acc.to_array().iter().map(|&x| i64::from(x)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tap pairs `(t[x], t[x + 1])` of lanes `0 .. 8`, in two vectors of four pairs.
    fn want_pairs(t: &dyn Fn(usize) -> i16) -> [i16x8; 2] {
        let pairs: [i16; 16] = core::array::from_fn(|l| t(l / 2 + l % 2));
        [
            i16x8::new(pairs.first_chunk::<8>().copied().unwrap()),
            i16x8::new(pairs.last_chunk::<8>().copied().unwrap()),
        ]
    }

    /// The pixel tap pairs and the derivatives' (split from `[Ix, Iy]` pairs by masks and
    /// shifts) against their definitions, on values at both ends of their ranges.
    #[test]
    fn tap_pairs_interleave() {
        let px: [u8; L + 1] = core::array::from_fn(|k| (k * 37 + 200) as u8);
        let k = PairWeights::new(&[0; 4]);
        assert_eq!(k.pixel_taps(&px), want_pairs(&|x| i16::from(px[x])));
        let d = |x: usize, m: i16| [-4080, 4080, -1, 0, 1, 2039, -2040, 7, 4080][x] * m;
        let dv: [[i16; 2]; L + 1] = core::array::from_fn(|x| [d(x, 1), d(x, -1)]);
        let [x0, x1, y0, y1] = derivative_pairs(&dv);
        assert_eq!([x0, x1], want_pairs(&|x| d(x, 1)));
        assert_eq!([y0, y1], want_pairs(&|x| d(x, -1)));
    }
}
