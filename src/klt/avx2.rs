//! The AVX2 sampler of the vector window kernel ([`super::lanes`]), for x86-64 CPUs that have
//! AVX2 (found at run time with the `std` feature, at compile time without it).
//!
//! The same integers as [`PairWeights`]: each row's eight pixel tap pairs `(p[x], p[x + 1])`
//! widened into one 256-bit vector (`vpmovzxbw`) and weighed by one dot product
//! (`vpmaddwd`) instead of two, the two rows' sums added and descaled in one vector of eight
//! `i32`, packed to `i16` with saturation (`packssdw`, as [`PairWeights`]). The derivatives'
//! eight tap pairs come from two 256-bit loads of `[Ix, Iy]` pairs, split by masks and shifts. The AVX2 instructions are reached through
//! [`pulp`]'s `V3` token, which proves the CPU has them, so the crate stays free of `unsafe`;
//! the kernel that uses the sampler is inlined into [`pulp::x86::V3::vectorize`], where AVX2
//! is enabled.

use super::arith::W_BITS;
use super::lanes::{L, PairWeights, Sampler, byte_pairs};
use super::window::PIX_SHIFT;
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

impl Sampler for Avx2 {
    /// The eight tap pairs of a row ([`byte_pairs`]) widened into sixteen `i16` at once.
    type Pixels = __m256i;
    /// `Ix`'s tap pairs and `Iy`'s of all eight lanes, each in one 256-bit vector.
    type Derivatives = (__m256i, __m256i);

    #[inline(always)]
    fn pixel_taps(self, r: &[u8; L + 1]) -> __m256i {
        let p: __m128i = bytemuck::cast(byte_pairs(r));
        self.v3.avx2._mm256_cvtepu8_epi16(p)
    }

    #[inline(always)]
    fn pixels(self, r0: __m256i, r1: __m256i) -> i16x8 {
        let (avx, avx2, sse2) = (self.v3.avx, self.v3.avx2, self.v3.sse2);
        let s = self.weigh::<{ PIX_SHIFT as i32 }>(r0, r1);
        let (lo, hi) = (
            avx._mm256_castsi256_si128(s),
            avx2._mm256_extracti128_si256::<1>(s),
        );
        bytemuck::cast(sse2._mm_packs_epi32(lo, hi))
    }

    /// Eight `[Ix, Iy]` pairs at `x` and eight at `x + 1`, one load each, split as
    /// [`split_pairs`](super::lanes::split_pairs) does (x86-64 is little-endian).
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

    /// Each derivative's two dot products, added and descaled in `i32`, both packed to `i16`
    /// in one `vpackssdw` and put in order by one `vpermq`.
    #[inline(always)]
    fn derivatives(self, r0: (__m256i, __m256i), r1: (__m256i, __m256i)) -> (i16x8, i16x8) {
        const S: i32 = W_BITS as i32;
        let (ix, iy) = (self.weigh::<S>(r0.0, r1.0), self.weigh::<S>(r0.1, r1.1));
        let avx2 = self.v3.avx2;
        // Lanes `[ix 0-3, iy 0-3 | ix 4-7, iy 4-7]`, then `[ix 0-7 | iy 0-7]`.
        let p = avx2._mm256_packs_epi32(ix, iy);
        let p = avx2._mm256_permute4x64_epi64::<0b11_01_10_00>(p);
        let [ix, iy]: [i16x8; 2] = bytemuck::cast(p);
        (ix, iy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 sampler gives the 128-bit one's pixels and derivatives for the weights the
    /// tracker makes ([`Fixed::bilinear`](super::super::arith::FlowArith::bilinear) of random
    /// Q16 fractions, through the kernel's `weights`, so `w11 = -1` at tiny fractions too) on
    /// taps that reach both ends of their ranges (bytes; derivatives `±16 · 255`). Without AVX2
    /// on this CPU there is nothing to compare, and the test says so.
    #[test]
    fn avx2_samples_as_the_128_bit_sampler() {
        use super::super::arith::{Fixed, FlowArith, Q16};
        use super::super::lanes::weights;
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
            let tap = |next: &mut dyn FnMut() -> u64| -> [u8; L + 1] {
                core::array::from_fn(|_| match next() % 4 {
                    0 => 0,
                    1 => 255,
                    _ => next() as u8,
                })
            };
            let (r0, r1) = (tap(&mut next), tap(&mut next));
            let (p, k) = (PairWeights::new(&w), Avx2::new(v3, &w));
            let want = p.pixels(p.pixel_taps(&r0), p.pixel_taps(&r1));
            let got = v3.vectorize(|| k.pixels(k.pixel_taps(&r0), k.pixel_taps(&r1)));
            assert_eq!(got, want, "case {case}: weights {w:?}, rows {r0:?} {r1:?}");
            // Derivatives in `-16 · 255 ..= 16 · 255`, the ends as often as the rest.
            let grad = |next: &mut dyn FnMut() -> u64| -> [[i16; 2]; L + 1] {
                core::array::from_fn(|_| {
                    core::array::from_fn(|_| match next() % 4 {
                        0 => -4080,
                        1 => 4080,
                        _ => (next() % 8161) as i16 - 4080,
                    })
                })
            };
            let (g0, g1) = (grad(&mut next), grad(&mut next));
            let want = p.derivatives(p.derivative_taps(&g0), p.derivative_taps(&g1));
            let got =
                v3.vectorize(|| k.derivatives(k.derivative_taps(&g0), k.derivative_taps(&g1)));
            assert_eq!(got, want, "case {case}: weights {w:?}, rows {g0:?} {g1:?}");
        }
        assert!(negative > 0, "no weight set with w11 = -1 was drawn");
    }
}
