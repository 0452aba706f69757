//! The AVX2 sampler of the vector window kernel ([`super`]), for x86-64 CPUs that have
//! AVX2 (found at run time with the `std` feature, at compile time without it).
//!
//! The same integers as [`PairWeights`]: each row's eight pixel tap pairs `(p[x], p[x + 1])`
//! widened into one 256-bit vector (`vpmovzxbw`) and weighed by one dot product
//! (`vpmaddwd`) instead of two, the two rows' sums added and descaled in one vector of eight
//! `i32`. Two consecutive samples of a column are packed to `i16` with saturation by one
//! `vpackssdw` into one vector of sixteen lanes, in its own order ([`pair_lanes`]); the
//! template planes keep that order, so the kernels' differences and dot products work on
//! 256 bits with no reordering. The derivatives' eight tap pairs come from two 256-bit loads
//! of `[Ix, Iy]` pairs, split by masks and shifts. The AVX2 instructions are reached through
//! [`pulp`]'s `V3` token, which proves the CPU has them, so the crate stays free of `unsafe`;
//! the kernel that uses the sampler is inlined into [`pulp::x86::V3::vectorize`], where AVX2
//! is enabled.

use super::sampler::{L, PairWeights, Sampler, byte_pairs};
use crate::klt::arith::W_BITS;
use crate::klt::kernel::patch::Column;
use crate::klt::kernel::window::PIX_SHIFT;
use core::arch::x86_64::{__m128i, __m256i};
use pulp::x86::V3;
use wide::i16x8;

/// The AVX2 sampler: the weights of each row's tap pairs in 256-bit vectors.
#[derive(Clone, Copy)]
pub(super) struct Avx2 {
    v3: V3,
    /// `[w00, w01]` in every pair of lanes: the upper row's.
    upper: __m256i,
    /// `[w10, w11]`: the lower row's.
    lower: __m256i,
}

impl Avx2 {
    /// The sampler for the Q14 weights `w = [w00, w01, w10, w11]`.
    #[inline(always)]
    pub(super) fn new(v3: V3, w: &[i16; 4]) -> Self {
        let narrow = PairWeights::new(w);
        let wide = |h: i16x8| -> __m256i { bytemuck::cast([h, h]) };
        Self {
            v3,
            upper: wide(narrow.upper),
            lower: wide(narrow.lower),
        }
    }

    /// `⌊(a · upper + b · lower) / 2^S⌉` in eight `i32` lanes: the rows' tap pairs `a`
    /// (upper) and `b` weighed by one dot product each.
    #[inline(always)]
    fn weigh<const S: i32>(self, a: __m256i, b: __m256i) -> __m256i {
        let (avx, avx2) = (self.v3.avx, self.v3.avx2);
        let a = avx2._mm256_madd_epi16(a, self.upper);
        let b = avx2._mm256_madd_epi16(b, self.lower);
        let half = avx._mm256_set1_epi32(1 << (S - 1));
        avx2._mm256_srai_epi32::<S>(avx2._mm256_add_epi32(avx2._mm256_add_epi32(a, b), half))
    }
}

/// The order of the sixteen lanes of an AVX2 vector of two rows' samples, `vpackssdw`'s: lanes
/// 0-3 of the upper row, 0-3 of the lower, 4-7 of the upper, 4-7 of the lower.
pub(super) fn pair_lanes<T: Copy + Default>(upper: [T; L], lower: [T; L]) -> [T; 2 * L] {
    let mut out = [T::default(); 2 * L];
    let halves = upper.chunks(L / 2).zip(lower.chunks(L / 2));
    for (o, (u, l)) in out.chunks_mut(L).zip(halves) {
        let (a, b) = o.split_at_mut(L / 2);
        for (o, &v) in a.iter_mut().zip(u).chain(b.iter_mut().zip(l)) {
            *o = v;
        }
    }
    out
}

impl Sampler for Avx2 {
    /// The eight tap pairs of a row ([`byte_pairs`]) widened into sixteen `i16` at once.
    type Pixels = __m256i;
    /// `Ix`'s tap pairs and `Iy`'s of all eight lanes, each in one 256-bit vector.
    type Derivatives = (__m256i, __m256i);
    /// Two rows, in the order of [`pair_lanes`].
    type Vector = __m256i;
    type Sums = __m256i;
    type Stored = [i16; 2 * L];

    #[inline(always)]
    fn pixel_taps(self, r: &[u8; L + 1]) -> __m256i {
        let p: __m128i = bytemuck::cast(byte_pairs(r));
        self.v3.avx2._mm256_cvtepu8_epi16(p)
    }

    /// Eight `[Ix, Iy]` pairs at `x` and eight at `x + 1`, one load each, split as
    /// [`split_pairs`](super::sampler::split_pairs) does (x86-64 is little-endian).
    #[inline(always)]
    fn derivative_taps(self, r: &[[i16; 2]; L + 1]) -> (__m256i, __m256i) {
        let (avx, avx2) = (self.v3.avx, self.v3.avx2);
        let load = |p: Option<&[[i16; 2]; L]>| -> __m256i {
            p.map_or(avx._mm256_setzero_si256(), |p| bytemuck::cast(*p))
        };
        let (a, b) = (load(r.first_chunk()), load(r.last_chunk()));
        let (low, high) = (
            avx._mm256_set1_epi32(0xFFFF),
            avx._mm256_set1_epi32(-0x1_0000),
        );
        let ix = avx2._mm256_or_si256(
            avx2._mm256_and_si256(a, low),
            avx2._mm256_slli_epi32::<16>(b),
        );
        let iy = avx2._mm256_or_si256(
            avx2._mm256_srli_epi32::<16>(a),
            avx2._mm256_and_si256(b, high),
        );
        (ix, iy)
    }

    /// Two rows' samples, each row's two dot products added and descaled in eight `i32`,
    /// both rows packed to `i16` by one `vpackssdw` (no reordering: the planes keep its
    /// order). Below the last row of `taps`, zero.
    #[inline(always)]
    fn next_pixels(
        self,
        upper: &mut __m256i,
        taps: &mut Column<'_, u8, { L + 1 }>,
    ) -> Option<__m256i> {
        const S: i32 = PIX_SHIFT as i32;
        let (avx, avx2) = (self.v3.avx, self.v3.avx2);
        let mid = self.pixel_taps(taps.next()?);
        let (first, second) = match taps.next() {
            Some(t) => {
                let lower = self.pixel_taps(t);
                let top = core::mem::replace(upper, lower);
                (self.weigh::<S>(top, mid), self.weigh::<S>(mid, lower))
            }
            None => (self.weigh::<S>(*upper, mid), avx._mm256_setzero_si256()),
        };
        Some(avx2._mm256_packs_epi32(first, second))
    }

    /// [`Self::next_pixels`] for each derivative.
    #[inline(always)]
    fn next_derivatives(
        self,
        upper: &mut (__m256i, __m256i),
        taps: &mut Column<'_, [i16; 2], { L + 1 }>,
    ) -> Option<(__m256i, __m256i)> {
        const S: i32 = W_BITS as i32;
        let (avx, avx2) = (self.v3.avx, self.v3.avx2);
        let mid = self.derivative_taps(taps.next()?);
        let zero = avx._mm256_setzero_si256();
        let (ix, iy) = match taps.next() {
            Some(t) => {
                let lower = self.derivative_taps(t);
                let top = core::mem::replace(upper, lower);
                (
                    (
                        self.weigh::<S>(top.0, mid.0),
                        self.weigh::<S>(mid.0, lower.0),
                    ),
                    (
                        self.weigh::<S>(top.1, mid.1),
                        self.weigh::<S>(mid.1, lower.1),
                    ),
                )
            }
            None => (
                (self.weigh::<S>(upper.0, mid.0), zero),
                (self.weigh::<S>(upper.1, mid.1), zero),
            ),
        };
        Some((
            avx2._mm256_packs_epi32(ix.0, ix.1),
            avx2._mm256_packs_epi32(iy.0, iy.1),
        ))
    }

    #[inline(always)]
    fn lanes(self, row: i16x8) -> __m256i {
        let row = row.to_array();
        bytemuck::cast(pair_lanes(row, row))
    }
    #[inline(always)]
    fn load(self, v: &[i16; 2 * L]) -> __m256i {
        bytemuck::cast(*v)
    }
    #[inline(always)]
    fn store(self, v: __m256i) -> [i16; 2 * L] {
        bytemuck::cast(v)
    }
    #[inline(always)]
    fn and(self, a: __m256i, b: __m256i) -> __m256i {
        self.v3.avx2._mm256_and_si256(a, b)
    }
    #[inline(always)]
    fn sub(self, a: __m256i, b: __m256i) -> __m256i {
        self.v3.avx2._mm256_sub_epi16(a, b)
    }
    #[inline(always)]
    fn zero(self) -> __m256i {
        self.v3.avx._mm256_setzero_si256()
    }
    #[inline(always)]
    fn dot(self, acc: __m256i, a: __m256i, b: __m256i) -> __m256i {
        let avx2 = self.v3.avx2;
        avx2._mm256_add_epi32(acc, avx2._mm256_madd_epi16(a, b))
    }
    #[inline(always)]
    fn abs(self, acc: __m256i, a: __m256i) -> __m256i {
        let (avx, avx2) = (self.v3.avx, self.v3.avx2);
        let ones = avx._mm256_set1_epi16(1);
        avx2._mm256_add_epi32(acc, avx2._mm256_madd_epi16(avx2._mm256_abs_epi16(a), ones))
    }
    #[inline(always)]
    fn sum(self, acc: __m256i) -> i64 {
        let lanes: [i32; 8] = bytemuck::cast(acc);
        lanes.iter().map(|&x| i64::from(x)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::klt::kernel::patch::block_of;

    /// The vectors a sampler gives down the column of `rows` rows (`L + 1` wide) of `buf`:
    /// pixels, or `Ix` and `Iy` when `buf` holds `[Ix, Iy]` pairs; all of them, as arrays.
    fn pixels<K: Sampler>(k: K, buf: &[u8], rows: usize) -> std::vec::Vec<K::Stored> {
        let mut col = block_of(buf, L + 1, rows).column::<{ L + 1 }>(0);
        let mut upper = k.pixel_taps(col.next().unwrap());
        core::iter::from_fn(|| k.next_pixels(&mut upper, &mut col).map(|v| k.store(v))).collect()
    }
    fn derivatives<K: Sampler>(
        k: K,
        buf: &[[i16; 2]],
        rows: usize,
    ) -> std::vec::Vec<(K::Stored, K::Stored)> {
        let mut col = block_of(buf, L + 1, rows).column::<{ L + 1 }>(0);
        let mut upper = k.derivative_taps(col.next().unwrap());
        core::iter::from_fn(|| {
            let (x, y) = k.next_derivatives(&mut upper, &mut col)?;
            Some((k.store(x), k.store(y)))
        })
        .collect()
    }
    /// The 128-bit sampler's rows as the AVX2 sampler's vectors: two rows each in the order
    /// of [`pair_lanes`], a missing last row zero.
    fn paired(rows: &[[i16; L]]) -> std::vec::Vec<[i16; 2 * L]> {
        rows.chunks(2)
            .map(|p| pair_lanes(p[0], p.get(1).copied().unwrap_or([0; L])))
            .collect()
    }

    /// The AVX2 sampler gives the 128-bit one's pixels and derivatives, two rows a vector
    /// in the order of [`pair_lanes`] and a missing last row zero, for the weights the
    /// tracker makes ([`Fixed::bilinear`](crate::klt::FlowArith::bilinear) of random
    /// Q16 fractions, through the kernel's `weights`, so `w11 = -1` at tiny fractions too) on
    /// taps that reach both ends of their ranges (bytes; derivatives `±16 · 255`), down
    /// columns of two and three samples. Without AVX2 on this CPU there is nothing to
    /// compare, and the test says so.
    #[test]
    fn avx2_samples_as_the_128_bit_sampler() {
        use super::super::sampler::weights;
        use crate::klt::arith::{Fixed, FlowArith, Q16};
        let Some(v3) = V3::try_new() else {
            std::eprintln!("no AVX2 on this CPU: the AVX2 sampler is not run");
            return;
        };
        let mut rng = crate::rng::Pcg32::new(7);
        let mut next = move || u64::from(rng.next_u32());
        let mut negative = 0;
        for case in 0..20_000 {
            // Every fifth case fractions below 400 units, where `w11` can round to -1.
            let frac = |v: u64| {
                if case % 5 == 0 {
                    (v % 400) as i32
                } else {
                    (v & 0xFFFF) as i32
                }
            };
            let (x, y) = (Q16::from_bits(frac(next())), Q16::from_bits(frac(next())));
            let Some(b) = Fixed::bilinear(x, y) else {
                panic!("case {case}: no weights at ({x:?}, {y:?})");
            };
            let w = weights(&b);
            negative += usize::from(w[3] < 0);
            let (p, k) = (PairWeights::new(&w), Avx2::new(v3, &w));
            // Three or four rows of taps: two or three samples.
            let rows = 3 + case % 2;
            let px: std::vec::Vec<u8> = (0..rows * (L + 1))
                .map(|_| match next() % 4 {
                    0 => 0,
                    1 => 255,
                    _ => next() as u8,
                })
                .collect();
            let want = paired(&pixels(p, &px, rows));
            let got = v3.vectorize(|| pixels(k, &px, rows));
            assert_eq!(got, want, "case {case}: weights {w:?}, rows {px:?}");
            // Derivatives in `-16 · 255 ..= 16 · 255`, the ends as often as the rest.
            let grad: std::vec::Vec<[i16; 2]> = (0..rows * (L + 1))
                .map(|_| {
                    core::array::from_fn(|_| match next() % 4 {
                        0 => -4080,
                        1 => 4080,
                        _ => (next() % 8161) as i16 - 4080,
                    })
                })
                .collect();
            let (wx, wy): (std::vec::Vec<_>, std::vec::Vec<_>) =
                derivatives(p, &grad, rows).into_iter().unzip();
            let want: std::vec::Vec<_> = paired(&wx).into_iter().zip(paired(&wy)).collect();
            let got = v3.vectorize(|| derivatives(k, &grad, rows));
            assert_eq!(got, want, "case {case}: weights {w:?}, rows {grad:?}");
        }
        assert!(negative > 0, "no weight set with w11 = -1 was drawn");
    }
}
