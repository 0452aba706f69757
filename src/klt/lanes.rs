//! The window kernel for targets with 128-bit SIMD ([`super::window`]): the template and the
//! window derivatives in planes, rows padded to whole vectors of [`L`] `i16`.
//!
//! Every loop is over whole vectors with products of two `i16` summed in `i32` lanes, the shape
//! LLVM turns into `pmaddwd` (SSE2) or `smlal` (NEON). Row sums are the same integers as
//! [`super::packed`]'s: the padding lanes carry `Ix = Iy = 0`, and the `Σ |J - I|` pass reads
//! only the `win` real columns.

use super::arith::{Bilinear, W_BITS};
use super::window::{
    PIX_SHIFT, Window, block_of, block_rows, cached_patch, descale, fetch_patch, lerp, taps,
};
use crate::gradient::scharr_window;
use crate::image::ImageView;
use crate::{Error, Result};
use wide::{i16x8, i32x4, i32x8};

/// Lanes of one vector of `i16` (128 bits).
const L: usize = 8;

/// Row stride of the template planes: `win` rounded up to whole vectors.
const fn stride(win: usize) -> usize {
    win.div_ceil(L) * L
}

/// `i16` elements of scratch for `win x win` windows, `s = stride(win)`:
/// `3 (win + 1)(s + 1)` (`Ix`, `Iy` and reflected pixels at integer positions, `s + 1`
/// columns for the right-hand taps of the last lane) and `3 win s` (the template planes).
pub(super) const fn scratch_len(win: usize) -> usize {
    let s = stride(win);
    3 * (win + 1) * (s + 1) + 3 * win * s
}

/// The scratch split into its parts.
pub(super) struct Lanes<'s> {
    win: usize,
    /// [`stride`]`(win)`.
    s: usize,
    /// `Ix` at integer positions, `(win + 1) x (s + 1)`.
    gx: &'s mut [i16],
    /// `Iy` at integer positions, `(win + 1) x (s + 1)`.
    gy: &'s mut [i16],
    /// Pixels of a block that leaves the image (reflected), `(win + 1) x (s + 1)`.
    patch: &'s mut [i16],
    /// The template planes `I` (1/32 grey levels), `Ix`, `Iy` at the window's weights,
    /// `win x s` each; `Ix` and `Iy` are zero beyond column `win`.
    tmpl: &'s mut [i16],
    /// The integer corner of the window of `J` in `patch`, if it holds one
    /// ([`cached_patch`]); cleared by [`Window::template`].
    patch_at: Option<(i32, i32)>,
}

impl<'s> Window<'s> for Lanes<'s> {
    fn new(scratch: &'s mut [i16], win: usize) -> Result<Self> {
        let s = stride(win);
        let block = (win + 1) * (s + 1);
        let short = Error::BufferTooSmall("scratch");
        let (gx, rest) = scratch.split_at_mut_checked(block).ok_or(short)?;
        let (gy, rest) = rest.split_at_mut_checked(block).ok_or(short)?;
        let (patch, rest) = rest.split_at_mut_checked(block).ok_or(short)?;
        let tmpl = rest.get_mut(..3 * win * s).ok_or(short)?;
        Ok(Self {
            win,
            s,
            gx,
            gy,
            patch,
            tmpl,
            patch_at: None,
        })
    }

    fn template(
        &mut self,
        i: &ImageView<'_, u8>,
        grad: Option<&ImageView<'_, [i16; 2]>>,
        b: &Bilinear,
    ) -> (i64, i64, i64) {
        let (n, c) = (self.win + 1, self.s + 1);
        match grad {
            Some(g) => fetch_grad(g, (b.x, b.y), c, n, self.gx, self.gy),
            None => {
                // Scharr writes `[Ix, Iy]` pairs, `win + 1` a row (the padding columns only
                // reach lanes that are zeroed after the interpolation): into the template
                // planes, free until the interpolation below (`2 (win + 1)² <= 3 win s` for
                // `win >= 3`), then split into the two planes.
                let (pairs, _) = self.tmpl.as_chunks_mut::<2>();
                if let Some(pairs) = pairs.get_mut(..n * n) {
                    let _ = scharr_window(i, b.x as isize, b.y as isize, n, n, pairs);
                    let rows = pairs.chunks_exact(n);
                    let planes = self.gx.chunks_exact_mut(c).zip(self.gy.chunks_exact_mut(c));
                    for (row, (rx, ry)) in rows.zip(planes) {
                        for (&[dx, dy], (x, y)) in row.iter().zip(rx.iter_mut().zip(ry)) {
                            (*x, *y) = (dx, dy);
                        }
                    }
                }
            }
        }
        self.patch_at = None;
        let w = weights(b);
        let (grads, tmpl) = ((&*self.gx, &*self.gy), &mut *self.tmpl);
        match block_rows(i, (b.x, b.y), c, n) {
            Some(rows) => template(rows, grads, tmpl, self.win, self.s, w),
            None => {
                fetch_patch(i, (b.x, b.y), c, n, self.patch);
                template(block_of(self.patch, c, n), grads, tmpl, self.win, self.s, w)
            }
        }
    }

    fn mismatch(&mut self, j: &ImageView<'_, u8>, b: &Bilinear, abs: bool) -> (i64, i64) {
        let (n, c) = (self.win + 1, self.s + 1);
        let w = weights(b);
        match block_rows(j, (b.x, b.y), c, n) {
            Some(rows) => mismatch(rows, self.tmpl, self.win, self.s, w, abs),
            None => {
                let at = (b.x, b.y);
                let patch = cached_patch(j, at, (c, n), self.patch, &mut self.patch_at);
                mismatch(block_of(patch, c, n), self.tmpl, self.win, self.s, w, abs)
            }
        }
    }
}

/// The Q14 weights as `i16`, so that every product is `i16 x i16`: each within one unit of
/// `0 ..= 2¹⁴` (`w11 = 2¹⁴ - w00 - w01 - w10` is `-1` where the other three round up at a
/// tiny `a b`; the packed kernel uses that `-1` too).
fn weights(b: &Bilinear) -> [i16; 4] {
    b.w.map(|v| v.clamp(-1, (1 << W_BITS) + 1) as i16)
}

/// Copies the `cols x rows` derivatives at `(x0, y0)` of a precomputed level into the planes
/// `gx`, `gy`, zero outside.
fn fetch_grad(
    g: &ImageView<'_, [i16; 2]>,
    (x0, y0): (i32, i32),
    cols: usize,
    rows: usize,
    gx: &mut [i16],
    gy: &mut [i16],
) {
    let planes = gx
        .chunks_exact_mut(cols.max(1))
        .zip(gy.chunks_exact_mut(cols.max(1)));
    for (j, (rx, ry)) in planes.take(rows).enumerate() {
        let y = y0 + j as i32;
        let src = if y >= 0 { g.row(y as usize) } else { None };
        for (i, (x, y)) in rx.iter_mut().zip(ry.iter_mut()).enumerate() {
            let c = x0 + i as i32;
            [*x, *y] = match src {
                Some(r) if c >= 0 => r.get(c as usize).copied().unwrap_or([0, 0]),
                _ => [0, 0],
            };
        }
    }
}

/// The `L + 1` taps of vector `k` along a row (`None` past its end).
#[inline(always)]
fn taps_of<P: Copy>(row: &[P], k: usize) -> Option<&[P; L + 1]> {
    row.get(k * L..k * L + L + 1)?.try_into().ok()
}

/// Lanes `off .. off + L` of `t` as a vector.
#[inline(always)]
fn load<P: Copy + Into<i16>>(t: &[P; L + 1], off: usize) -> i16x8 {
    i16x8::new(core::array::from_fn(|l| {
        t.get(l + off).map_or(0, |&p| p.into())
    }))
}

/// `⌊(Σ taps · w) / 2^shift⌉` for the `L` lanes of vector `k` of rows `r0`, `r1`: four
/// widening products `i16 x i16 -> i32`, exact (at most `255 · 2¹⁴` for pixels,
/// `16 · 255 · 2¹⁴` for derivatives), then packed back to `i16`, where every result fits
/// (pixels at most `255 · 32` in 1/32 grey levels, derivatives `16 · 255`).
#[inline(always)]
fn interpolate<P: Copy + Into<i16>>(
    a: &[P; L + 1],
    b: &[P; L + 1],
    w: &Weights,
    shift: u32,
) -> i16x8 {
    let j = load(a, 0).widening_mul(w[0])
        + load(a, 1).widening_mul(w[1])
        + load(b, 0).widening_mul(w[2])
        + load(b, 1).widening_mul(w[3]);
    let half = i32x8::splat(1 << (shift - 1));
    i16x8::from_i32x8_saturate((j + half) >> shift)
}

/// The four weights, each splat across a vector.
type Weights = [i16x8; 4];

/// One plane row of the template (`r0`, `r1` at least `out.len() + 1` long).
#[inline(always)]
fn interpolate_row<P: Copy + Into<i16>>(
    r0: &[P],
    r1: &[P],
    out: &mut [i16],
    w: &Weights,
    shift: u32,
) {
    let (out, _) = out.as_chunks_mut::<L>();
    for (k, o) in out.iter_mut().enumerate() {
        let (Some(a), Some(b)) = (taps_of(r0, k), taps_of(r1, k)) else {
            return;
        };
        *o = interpolate(a, b, w, shift).to_array();
    }
}

/// Interpolates the template planes (pixels from the `win + 1` rows `rows`, derivatives from
/// `gx`, `gy`) at weights `w`; returns `G`'s sums. Row sums in `i32` are exact: at most
/// `64 · (16 · 255)² < 2³¹`.
fn template<'p, P: Copy + Into<i16> + Into<i32> + 'p>(
    rows: impl Iterator<Item = &'p [P]> + Clone,
    (gx, gy): (&[i16], &[i16]),
    tmpl: &mut [i16],
    win: usize,
    s: usize,
    w: [i16; 4],
) -> (i64, i64, i64) {
    let (c, n) = (s + 1, win + 1);
    let (ti, rest) = tmpl.split_at_mut(win * s);
    let (tx, ty) = rest.split_at_mut(win * s);
    let planes = ti.chunks_exact_mut(s.max(L)).zip(
        tx.chunks_exact_mut(s.max(L))
            .zip(ty.chunks_exact_mut(s.max(L))),
    );
    let pairs = |b| block_of(b, c, n).zip(block_of(b, c, n).skip(1));
    let taps = rows.clone().zip(rows.skip(1)).zip(pairs(gx).zip(pairs(gy)));
    let vw = w.map(i16x8::splat);
    let (mut a11, mut a12, mut a22) = (0i64, 0i64, 0i64);
    for (((r0, r1), (x, y)), (oi, (ox, oy))) in taps.zip(planes) {
        interpolate_row(r0, r1, oi, &vw, PIX_SHIFT);
        interpolate_row(x.0, x.1, ox, &vw, W_BITS);
        interpolate_row(y.0, y.1, oy, &vw, W_BITS);
        // The padding: `Ix`, `Iy` zero beyond column `win`.
        for pad in [ox.get_mut(win..), oy.get_mut(win..)].into_iter().flatten() {
            pad.fill(0);
        }
        let (mut s11, mut s12, mut s22) = (i32x4::ZERO, i32x4::ZERO, i32x4::ZERO);
        let (vx, _) = ox.as_chunks::<L>();
        let (vy, _) = oy.as_chunks::<L>();
        for (&x, &y) in vx.iter().zip(vy) {
            let (x, y) = (i16x8::new(x), i16x8::new(y));
            s11 += x.dot(x);
            s12 += x.dot(y);
            s22 += y.dot(y);
        }
        a11 += sum(s11);
        a12 += sum(s12);
        a22 += sum(s22);
    }
    (a11, a12, a22)
}

/// The lanes of `v` added (exact in `i64`).
#[inline(always)]
fn sum(v: i32x4) -> i64 {
    v.to_array().iter().map(|&x| i64::from(x)).sum()
}

/// One row of [`mismatch`]: `Σ (J - I) Ix`, `Σ (J - I) Iy` over the template rows `ti`, `tx`,
/// `ty` (`s` long), `J` bilinear in rows `r0`, `r1` (at least `s + 1` long). `J - I` fits
/// `i16` (both in `0 ..= 255 · 32`); a lane of the `i32` sums adds two products of at most
/// `8160 · 4080` a vector, at most 8 vectors: below 2³¹.
#[inline(always)]
fn mismatch_row<P: Copy + Into<i16>>(
    (r0, r1): (&[P], &[P]),
    (ti, tx, ty): (&[i16], &[i16], &[i16]),
    w: &Weights,
) -> (i64, i64) {
    let (ti, _) = ti.as_chunks::<L>();
    let (tx, _) = tx.as_chunks::<L>();
    let (ty, _) = ty.as_chunks::<L>();
    let (mut s1, mut s2) = (i32x4::ZERO, i32x4::ZERO);
    for (k, ((&i, &x), &y)) in ti.iter().zip(tx).zip(ty).enumerate() {
        let (Some(a), Some(b)) = (taps_of(r0, k), taps_of(r1, k)) else {
            break;
        };
        let diff = interpolate(a, b, w, PIX_SHIFT) - i16x8::new(i);
        s1 += diff.dot(i16x8::new(x));
        s2 += diff.dot(i16x8::new(y));
    }
    (sum(s1), sum(s2))
}

/// One row of [`mismatch`]'s `Σ |J - I|` over the `win` real columns of `ti` (at most
/// `63 · 8160 < 2³¹`).
#[inline(always)]
fn abs_row<P: Copy + Into<i32>>(r0: &[P], r1: &[P], ti: &[i16], w: &[i16; 4]) -> u32 {
    let [p00, p01, p10, p11] = taps(r0, r1, ti.len());
    let mut s = 0u32;
    for ((((&a, &b), &c), &d), &i) in p00.iter().zip(p01).zip(p10).zip(p11).zip(ti) {
        let diff = descale(lerp(a, b, c, d, w), PIX_SHIFT) - i32::from(i);
        s = s.wrapping_add(diff.unsigned_abs());
    }
    s
}

/// `Σ (J - I) [Ix Iy]` over the window (or `Σ |J - I|` when `abs`), `J` bilinear in the
/// `win + 1` rows `rows` (image rows or the scratch patch, `s + 1` wide).
fn mismatch<'p, P: Copy + Into<i16> + Into<i32> + 'p>(
    rows: impl Iterator<Item = &'p [P]> + Clone,
    tmpl: &[i16],
    win: usize,
    s: usize,
    w: [i16; 4],
    abs: bool,
) -> (i64, i64) {
    let (ti, rest) = tmpl.split_at(win * s);
    let (tx, ty) = rest.split_at(win * s);
    let planes = ti
        .chunks_exact(s.max(L))
        .zip(tx.chunks_exact(s.max(L)).zip(ty.chunks_exact(s.max(L))));
    let vw = w.map(i16x8::splat);
    let (mut b1, mut b2) = (0i64, 0i64);
    for ((r0, r1), (i, (x, y))) in rows.clone().zip(rows.skip(1)).zip(planes) {
        if abs {
            b1 += i64::from(abs_row(r0, r1, i.get(..win).unwrap_or(&[]), &w));
        } else {
            let (s1, s2) = mismatch_row((r0, r1), (i, x, y), &vw);
            b1 += s1;
            b2 += s2;
        }
    }
    (b1, b2)
}
