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
use super::window::Window;
use crate::gradient::{scharr_window, scharr8};
use crate::image::ImageView;
use crate::klt::arith::Bilinear;
use crate::{Error, Result};
use sampler::{L, PairWeights, Sampler, weights};
use wide::i16x8;

#[cfg(target_arch = "x86_64")]
mod avx2;
mod sampler;

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
}
