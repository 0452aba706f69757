//! The window kernel for targets with 128-bit SIMD ([`super::window::Window`]): the template in
//! planes, rows padded to whole vectors of [`L`] `i16`; the window's derivatives as `[Ix, Iy]`
//! pairs, the level's own rows when the window lies inside it.
//!
//! Every loop is over whole vectors of eight lanes, down a column of vectors of the window
//! (so that each row's taps are prepared once, for the samples above and below it). A
//! bilinear sample interleaves each row's taps `(p[x], p[x + 1])` and weighs a pair with one
//! `i16` dot product (`pmaddwd` on SSE2, OpenCV's shape); the derivatives' tap pairs are split
//! from the `[Ix, Iy]` pairs by masks and shifts. The mismatch's products are dot products
//! too, summed in `i32` lanes over as many vectors as cannot overflow them. Row sums are the
//! same integers as [`super::packed`]'s: the padding lanes carry `Ix = Iy = 0`, and the
//! `Σ |J - I|` pass masks them off. With AVX2 a vector holds two rows' samples
//! ([`Sampler::Vector`]; a window of odd height ends with one padding row, zero).

use super::border::Pixels;
use super::patch::{Column, Rows, block_of, block_rows, cached_patch, fetch_grad, fetch_patch};
use super::window::{PIX_SHIFT, Window};
use crate::gradient::{scharr_window, scharr8};
use crate::image::ImageView;
use crate::klt::arith::{Bilinear, W_BITS};
use crate::simd::low;
use crate::{Error, Result};
use wide::{i16x8, i32x4, i32x8, u8x16, u32x4};

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Lanes of one vector of `i16` (128 bits).
pub(super) const L: usize = 8;

/// Row stride of the template planes: `win` rounded up to whole vectors.
const fn stride(win: usize) -> usize {
    win.div_ceil(L) * L
}

/// Rows of a column of the template planes: `win` rounded up to whole pairs (the AVX2
/// sampler's vectors hold two rows; the padding row is zero).
const fn plane_rows(win: usize) -> usize {
    win.next_multiple_of(2)
}

/// `i16` elements of one template plane.
const fn plane_len(win: usize) -> usize {
    plane_rows(win) * stride(win)
}

/// `i16` elements of scratch for `win x win` windows, `s = stride(win)`:
/// `3 (win + 1)(s + 1)` (`[Ix, Iy]` pairs and reflected pixels at integer positions, `s + 1`
/// columns for the right-hand taps of the last lane) and the three template planes
/// ([`state_len`]).
pub(super) const fn scratch_len(win: usize) -> usize {
    let s = stride(win);
    3 * (win + 1) * (s + 1) + state_len(win)
}

/// `i16` elements of the template planes, [`Window::state`]: three of `win` rounded up to
/// even rows by `stride(win)` columns.
pub(super) const fn state_len(win: usize) -> usize {
    3 * plane_len(win)
}

/// The scratch split into its parts.
pub(in crate::klt) struct Lanes<'s> {
    win: usize,
    /// [`stride`]`(win)`.
    s: usize,
    /// `[Ix, Iy]` at integer positions, `(win + 1) x (s + 1)`, for a window whose
    /// derivatives are not read straight from a level's ([`Window::template`]).
    grad: &'s mut [[i16; 2]],
    /// Pixels of a block that leaves the image (reflected): the template's,
    /// `(win + 1) x (s + 1)` bytes, or the mismatch's with its margin ([`cached_patch`]),
    /// `(win + 3) x (s + 3)`; both fit the `2 (win + 1)(s + 1)` bytes of its `i16` part of
    /// the scratch (tested for every window size).
    patch: &'s mut [u8],
    /// The template planes `I` (1/32 grey levels), `Ix`, `Iy` at the window's weights,
    /// [`plane_len`] each, a column of vectors after another in the sampler's order
    /// ([`columns`]); `Ix` and `Iy` are zero beyond column `win`, and all three in the padding
    /// row of an odd `win` as the AVX2 sampler keeps it (the 128-bit sampler never reads it).
    tmpl: &'s mut [i16],
    /// The integer corner of the window of `J` in `patch`, if it holds one
    /// ([`cached_patch`]); cleared by [`Window::template`].
    patch_at: Option<(i32, i32)>,
    /// AVX2, when this CPU has it ([`avx2`]).
    #[cfg(target_arch = "x86_64")]
    v3: Option<pulp::x86::V3>,
}

impl<'s> Window<'s> for Lanes<'s> {
    const BORDERED: bool = true;

    fn new(scratch: &'s mut [i16], win: usize) -> Result<Self> {
        let s = stride(win);
        let block = (win + 1) * (s + 1);
        let short = Error::BufferTooSmall("scratch");
        let (grad, rest) = scratch.split_at_mut_checked(2 * block).ok_or(short)?;
        let grad = bytemuck::cast_slice_mut::<i16, [i16; 2]>(grad);
        let (patch, rest) = rest.split_at_mut_checked(block).ok_or(short)?;
        let patch = bytemuck::cast_slice_mut::<i16, u8>(patch);
        let tmpl = rest.get_mut(..state_len(win)).ok_or(short)?;
        Ok(Self {
            win,
            s,
            grad,
            patch,
            tmpl,
            patch_at: None,
            #[cfg(target_arch = "x86_64")]
            v3: pulp::x86::V3::try_new(),
        })
    }

    fn template(
        &mut self,
        pixels: &Pixels<'_>,
        grad: Option<&ImageView<'_, [i16; 2]>>,
        b: &Bilinear,
    ) -> (i64, i64, i64) {
        let (n, c) = (self.win + 1, self.s + 1);
        let i = &pixels.img;
        // The derivatives: straight from the level's when the block lies inside it, else
        // copied (zero outside) or computed into `grad`.
        let grads = match grad {
            Some(g) => match block_rows(g, (b.x, b.y), c, n) {
                Some(rows) => rows,
                None => {
                    fetch_grad(g, (b.x, b.y), c, n, self.grad);
                    block_of(self.grad, c, n)
                }
            },
            None => {
                if !scharr_pairs(i, (b.x, b.y), n, c, self.grad) {
                    // Reflected, by the scalar Scharr (`c` columns a row: the padding
                    // columns only reach lanes that are zeroed after the interpolation).
                    let _ = scharr_window(i, b.x as isize, b.y as isize, c, n, self.grad);
                }
                block_of(self.grad, c, n)
            }
        };
        self.patch_at = None;
        let w = weights(b);
        let tmpl = &mut *self.tmpl;
        let rows = match pixels.block((b.x, b.y), c, n) {
            Some(rows) => rows,
            None => {
                fetch_patch(i, (b.x, b.y), c, n, self.patch);
                block_of(self.patch, c, n)
            }
        };
        let win = self.win;
        #[cfg(target_arch = "x86_64")]
        if let Some(v3) = self.v3 {
            let k = avx2::Avx2::new(v3, &w);
            return v3.vectorize(move || template(k, rows, grads, tmpl, win));
        }
        template(PairWeights::new(&w), rows, grads, tmpl, win)
    }

    fn mismatch(&mut self, j: &Pixels<'_>, b: &Bilinear, abs: bool) -> (i64, i64) {
        let (n, c) = (self.win + 1, self.s + 1);
        let w = weights(b);
        let rows = match j.block((b.x, b.y), c, n) {
            Some(rows) => rows,
            None => cached_patch(&j.img, (b.x, b.y), (c, n), self.patch, &mut self.patch_at),
        };
        let (tmpl, win) = (&*self.tmpl, self.win);
        #[cfg(target_arch = "x86_64")]
        if let Some(v3) = self.v3 {
            let k = avx2::Avx2::new(v3, &w);
            return v3.vectorize(move || mismatch(k, rows, tmpl, win, abs));
        }
        mismatch(PairWeights::new(&w), rows, tmpl, win, abs)
    }

    fn state(&self) -> &[i16] {
        self.tmpl
    }

    fn restore(&mut self, state: &[i16]) {
        for (t, &s) in self.tmpl.iter_mut().zip(state) {
            *t = s;
        }
        self.patch_at = None;
    }
}

/// The derivatives of the `n x n` pixels at `(x0, y0)` of `img` into `grad` as `[Ix, Iy]`
/// pairs (rows `c` apart), eight columns a step ([`scharr8`]), when the block and its
/// one-pixel ring lie inside the image (then no pixel reflects; `false` and nothing written
/// otherwise): the same integers as [`scharr_window`]. Columns from `n` to the end of a whole
/// vector are written too; only the masked padding lanes read them.
fn scharr_pairs(
    img: &ImageView<'_, u8>,
    (x0, y0): (i32, i32),
    n: usize,
    c: usize,
    grad: &mut [[i16; 2]],
) -> bool {
    let vectors = n.div_ceil(L);
    // Columns x0 - 1 .. x0 + 8 vectors + 1 of rows y0 - 1 .. y0 + n + 1.
    let cols = L * vectors + 2;
    let Some(mut rows) = block_rows(img, (x0 - 1, y0 - 1), cols, n + 2) else {
        return false;
    };
    let (Some(mut a), Some(mut b)) = (rows.next(), rows.next()) else {
        return false;
    };
    if c < L * vectors {
        return false;
    }
    for (out, cc) in grad.chunks_exact_mut(c).take(n).zip(rows) {
        let (out, _) = out.as_chunks_mut::<L>();
        let [ta, tb, tc] = [a, b, cc].map(|p| p.windows(L + 2).step_by(L));
        for (o, ((a, b), cc)) in out.iter_mut().zip(ta.zip(tb).zip(tc)) {
            let [Some(a), Some(b), Some(cc)] = [a, b, cc].map(|t| t.first_chunk::<{ L + 2 }>())
            else {
                break;
            };
            *o = scharr8(a, b, cc);
        }
        (a, b) = (b, cc);
    }
    true
}

/// The Q14 weights as `i16`, so that every product is `i16 x i16`: each within one unit of
/// `0 ..= 2¹⁴` (`w11 = 2¹⁴ - w00 - w01 - w10` is `-1` where the other three round up at a
/// tiny `a b`; the packed kernel uses that `-1` too).
pub(super) fn weights(b: &Bilinear) -> [i16; 4] {
    b.w.map(|v| v.clamp(-1, (1 << W_BITS) + 1) as i16)
}

/// A bilinear sampler of eight pixels at a window's weights, and the vector arithmetic of the
/// kernels on its samples: [`PairWeights`] (128-bit, every SIMD target) or
/// [`avx2::Avx2`] (x86-64 CPUs with AVX2). Both compute the same integers:
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

/// Column `v` of vectors of each of the template planes, as the sampler's vectors: the planes are kept a column of vectors after another
/// ([`plane_rows`] rows each), the order the kernels walk them in.
#[inline(always)]
fn columns<K: Sampler>(plane: &[i16], win: usize) -> impl Iterator<Item = &[K::Stored]> {
    plane
        .chunks_exact((plane_rows(win) * L).max(L))
        .map(|c| bytemuck::try_cast_slice(c).unwrap_or(&[]))
}

/// [`columns`], to write.
#[inline(always)]
fn columns_mut<K: Sampler>(
    plane: &mut [i16],
    win: usize,
) -> impl Iterator<Item = &mut [K::Stored]> {
    plane
        .chunks_exact_mut((plane_rows(win) * L).max(L))
        .map(|c| bytemuck::try_cast_slice_mut(c).unwrap_or(&mut []))
}

/// The samples of vector `v` of a block's pixels down the block ([`Sampler::next_pixels`]),
/// each row's taps prepared once. A hand-written iterator, not adapters over closures:
/// everything inside [`pulp::x86::V3::vectorize`] must inline, or the AVX2 intrinsics become
/// calls.
struct Samples<'a, K: Sampler> {
    k: K,
    taps: Column<'a, u8, { L + 1 }>,
    upper: K::Pixels,
}

impl<'a, K: Sampler> Samples<'a, K> {
    /// `None` when the block has no row.
    #[inline(always)]
    fn new(k: K, rows: Rows<'a, u8>, v: usize) -> Option<Self> {
        let mut taps = rows.column(v * L);
        let upper = k.pixel_taps(taps.next()?);
        Some(Self { k, taps, upper })
    }
}

impl<K: Sampler> Iterator for Samples<'_, K> {
    type Item = K::Vector;

    #[inline(always)]
    fn next(&mut self) -> Option<K::Vector> {
        self.k.next_pixels(&mut self.upper, &mut self.taps)
    }
}

/// Interpolates the template planes (pixels from the `win + 1` rows `rows`, derivatives from
/// the `win + 1` rows of `[Ix, Iy]` pairs `grads`) with sampler `k`, a column of vectors at a
/// time ([`columns`]); returns `G`'s sums, exact (in `i32` lanes over a column, at most 63
/// vectors of [`G_VECTOR_BOUND`], then in `i64`). Inlined into each caller, as [`mismatch`].
#[inline(always)]
fn template<K: Sampler>(
    k: K,
    rows: Rows<'_, u8>,
    grads: Rows<'_, [i16; 2]>,
    tmpl: &mut [i16],
    win: usize,
) -> (i64, i64, i64) {
    const _: () = assert!(crate::klt::MAX_WIN as i64 * G_VECTOR_BOUND <= i32::MAX as i64);
    let (ti, rest) = tmpl.split_at_mut(plane_len(win).min(tmpl.len()));
    let (tx, ty) = rest.split_at_mut(plane_len(win).min(rest.len()));
    for (v, oi) in columns_mut::<K>(ti, win).enumerate() {
        let Some(samples) = Samples::new(k, rows.clone(), v) else {
            break;
        };
        for (o, p) in oi.iter_mut().zip(samples) {
            *o = k.store(p);
        }
    }
    let planes = columns_mut::<K>(tx, win).zip(columns_mut::<K>(ty, win));
    let real = real_lanes(win);
    let (mut a11, mut a12, mut a22) = (0i64, 0i64, 0i64);
    for (v, ((ox, oy), &real)) in planes.zip(&real).enumerate() {
        // The derivatives' taps of column `v`, each row's prepared once.
        let mut taps = grads.clone().column::<{ L + 1 }>(v * L);
        let Some(t) = taps.next() else {
            break;
        };
        let mut upper = k.derivative_taps(t);
        let real = k.lanes(real);
        let (mut s11, mut s12, mut s22) = (k.zero(), k.zero(), k.zero());
        for (ox, oy) in ox.iter_mut().zip(oy) {
            let Some((ix, iy)) = k.next_derivatives(&mut upper, &mut taps) else {
                break;
            };
            // The derivatives, zero beyond column `win` (the padding), and `G`'s sums from
            // the same vectors.
            let (ix, iy) = (k.and(ix, real), k.and(iy, real));
            (*ox, *oy) = (k.store(ix), k.store(iy));
            s11 = k.dot(s11, ix, ix);
            s12 = k.dot(s12, ix, iy);
            s22 = k.dot(s22, iy, iy);
        }
        a11 += k.sum(s11);
        a12 += k.sum(s12);
        a22 += k.sum(s22);
    }
    (a11, a12, a22)
}

/// Vectors of the widest template row: [`stride`]`(MAX_WIN)` / [`L`].
const MAX_VECTORS: usize = stride(crate::klt::MAX_WIN) / L;

/// For each vector of a `win`-wide row, the lanes that are real columns (all ones; the
/// padding beyond `win` zero).
#[inline(always)]
fn real_lanes(win: usize) -> [i16x8; MAX_VECTORS] {
    let lane = i16x8::new([0, 1, 2, 3, 4, 5, 6, 7]);
    core::array::from_fn(|v| lane.simd_lt(i16x8::splat(win.saturating_sub(v * L).min(L) as i16)))
}

/// The most one vector adds to a lane of `G`'s sums: two products of at most `(16 · 255)²`.
const G_VECTOR_BOUND: i64 = 2 * 4080 * 4080;

/// The most one vector adds to a lane of [`mismatch`]'s sums: two products of `J - I` (it fits
/// `i16`: both in `0 ..= 255 · 32`) and a derivative, at most `2 · 8160 · 4080`.
const VECTOR_BOUND: i64 = 2 * 8160 * 4080;

/// Vectors of [`mismatch`] whose sums an `i32` lane holds (32).
const BATCH: usize = (i32::MAX as i64 / VECTOR_BOUND) as usize;
const _: () = assert!(BATCH > 0);

/// `Σ (J - I) [Ix Iy]` over the window (or `Σ |J - I|` when `abs`), `J` bilinear in the
/// `win + 1` rows `rows` (image rows or the scratch patch, `s + 1` wide), a column of vectors
/// at a time ([`columns`]). The products are summed in `i32` lanes over as many vectors as
/// cannot overflow them, then in `i64`. Inlined into each caller, so that the AVX2 sampler's
/// instructions are compiled where AVX2 is on.
#[inline(always)]
fn mismatch<K: Sampler>(
    k: K,
    rows: Rows<'_, u8>,
    tmpl: &[i16],
    win: usize,
    abs: bool,
) -> (i64, i64) {
    let (ti, rest) = tmpl.split_at(plane_len(win).min(tmpl.len()));
    let (tx, ty) = rest.split_at(plane_len(win).min(rest.len()));
    if abs {
        // The padding lanes masked off (the padding rows are zero in `J` and `I`); a lane
        // gains at most `2 · 8160` a vector, at most `63 · 8 · 2 · 8160 < 2³¹` in all.
        let real = real_lanes(win);
        let mut acc = k.zero();
        for (v, (ti, &real)) in columns::<K>(ti, win).zip(&real).enumerate() {
            let Some(samples) = Samples::new(k, rows.clone(), v) else {
                break;
            };
            let real = k.lanes(real);
            for (j, i) in samples.zip(ti) {
                acc = k.abs(acc, k.and(k.sub(j, k.load(i)), real));
            }
        }
        return (k.sum(acc), 0);
    }
    let (mut b1, mut b2) = (0i64, 0i64);
    let planes = columns::<K>(ti, win).zip(columns::<K>(tx, win).zip(columns::<K>(ty, win)));
    for (v, (ti, (tx, ty))) in planes.enumerate() {
        let Some(mut samples) = Samples::new(k, rows.clone(), v) else {
            break;
        };
        // The column in batches of vectors, each summed in `i32` lanes.
        let parts = ti.chunks(BATCH).zip(tx.chunks(BATCH).zip(ty.chunks(BATCH)));
        for (ti, (tx, ty)) in parts {
            let (mut s1, mut s2) = (k.zero(), k.zero());
            for ((i, (x, y)), j) in ti.iter().zip(tx.iter().zip(ty)).zip(&mut samples) {
                let diff = k.sub(j, k.load(i));
                s1 = k.dot(s1, diff, k.load(x));
                s2 = k.dot(s2, diff, k.load(y));
            }
            b1 += k.sum(s1);
            b2 += k.sum(s2);
        }
    }
    (b1, b2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For every window size the patch part of the scratch holds the mismatch's block with
    /// [`PATCH_MARGIN`](super::super::patch::PATCH_MARGIN) on every side (and the
    /// template's block, which is smaller).
    #[test]
    fn scratch_holds_the_margin_patch() {
        use super::super::patch::PATCH_MARGIN;
        for win in 3..=crate::klt::MAX_WIN {
            let mut scratch = std::vec![0i16; scratch_len(win)];
            let k = Lanes::new(&mut scratch, win).unwrap();
            let (c, n) = (stride(win) + 1, win + 1);
            let need = (c + 2 * PATCH_MARGIN) * (n + 2 * PATCH_MARGIN);
            assert!(k.patch.len() >= need.max(c * n), "win {win}");
        }
    }

    /// The vector Scharr equals the scalar one on every block it accepts, and accepts the
    /// blocks whose one-pixel ring lies inside the image.
    #[test]
    fn vector_scharr_matches_scalar() {
        let (w, h) = (53usize, 37usize);
        let img: std::vec::Vec<u8> = (0..w * h)
            .map(|i| ((i * 97 % 251) ^ (i / 7)) as u8)
            .collect();
        let view = ImageView::packed(&img, w, h).unwrap();
        for n in [4usize, 10, 22] {
            let c = stride(n - 1) + 1;
            let mut got = std::vec![[0i16; 2]; c * n];
            let mut want = std::vec![[0i16; 2]; n * n];
            for y0 in -2..h as i32 {
                for x0 in -2..w as i32 {
                    let took = scharr_pairs(&view, (x0, y0), n, c, &mut got);
                    let inside = x0 >= 1
                        && y0 >= 1
                        && x0 as usize + n.div_ceil(L) * L < w
                        && y0 as usize + n < h;
                    assert_eq!(took, inside, "n {n} at ({x0}, {y0})");
                    if !took {
                        continue;
                    }
                    scharr_window(&view, x0 as isize, y0 as isize, n, n, &mut want).unwrap();
                    for (k, &d) in want.iter().enumerate() {
                        let at = (k / n) * c + k % n;
                        assert_eq!(got[at], d, "n {n} at ({x0}, {y0}), {k}");
                    }
                }
            }
        }
    }

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
