//! The window kernel for cores without vector units ([`super::window`]): the template
//! interleaved `[I, Ix, Iy]` a pixel, rows exactly `win` wide.

use super::arith::{Bilinear, W_BITS};
use super::window::{
    PIX_SHIFT, Rows, Window, block_of, block_rows, cached_patch, descale, fetch_patch, grad_row,
    inside_span, lerp, taps,
};
use crate::gradient::scharr_window;
use crate::image::ImageView;
use crate::{Error, Result};

/// `i16` elements of scratch for `win x win` windows: `3 (win + 1)² + 3 win²` (derivatives
/// and pixels at integer positions, the interpolated template and its derivatives).
pub(super) const fn scratch_len(win: usize) -> usize {
    3 * (win + 1) * (win + 1) + 3 * win * win
}

/// `i16` elements of the template, [`Window::state`].
pub(super) const fn state_len(win: usize) -> usize {
    3 * win * win
}

/// The scratch split into its parts.
pub(super) struct Packed<'s> {
    win: usize,
    gwin: &'s mut [[i16; 2]],
    patch: &'s mut [i16],
    /// The interpolated template: `[I, Ix, Iy]` a pixel, together so that the mismatch loop
    /// reads one run of memory (and keeps one pointer live).
    tmpl: &'s mut [[i16; 3]],
    /// The integer corner of the window of `J` in `patch`, if it holds one
    /// ([`cached_patch`]); cleared by [`Window::template`].
    patch_at: Option<(i32, i32)>,
}

impl<'s> Window<'s> for Packed<'s> {
    fn new(scratch: &'s mut [i16], win: usize) -> Result<Self> {
        let n2 = (win + 1) * (win + 1);
        let (g, rest) = scratch
            .split_at_mut_checked(2 * n2)
            .ok_or(Error::BufferTooSmall("scratch"))?;
        let (patch, rest) = rest
            .split_at_mut_checked(n2)
            .ok_or(Error::BufferTooSmall("scratch"))?;
        let t = rest
            .get_mut(..state_len(win))
            .ok_or(Error::BufferTooSmall("scratch"))?;
        let (gwin, _) = g.as_chunks_mut::<2>();
        let (tmpl, _) = t.as_chunks_mut::<3>();
        Ok(Self {
            win,
            gwin,
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
        let (win, n) = (self.win, self.win + 1);
        match grad {
            Some(g) => fetch_grad(g, b.x, b.y, n, self.gwin),
            None => {
                let _ = scharr_window(i, b.x as isize, b.y as isize, n, n, self.gwin);
            }
        }
        self.patch_at = None;
        match block_rows(i, (b.x, b.y), n, n) {
            Some(rows) => template(rows, self.gwin, self.tmpl, win, b.w),
            None => {
                fetch_patch(i, (b.x, b.y), n, n, self.patch);
                template(block_of(self.patch, n, n), self.gwin, self.tmpl, win, b.w)
            }
        }
    }

    fn mismatch(&mut self, j: &ImageView<'_, u8>, b: &Bilinear, abs: bool) -> (i64, i64) {
        let (win, n) = (self.win, self.win + 1);
        match block_rows(j, (b.x, b.y), n, n) {
            Some(rows) => mismatch(rows, self.tmpl, win, b.w, abs),
            None => {
                let at = (b.x, b.y);
                let patch = cached_patch(j, at, (n, n), self.patch, &mut self.patch_at);
                mismatch(block_of(patch, n, n), self.tmpl, win, b.w, abs)
            }
        }
    }

    fn state(&self) -> &[i16] {
        self.tmpl.as_flattened()
    }

    fn restore(&mut self, state: &[i16]) {
        for (t, &s) in self.tmpl.as_flattened_mut().iter_mut().zip(state) {
            *t = s;
        }
        self.patch_at = None;
    }
}

/// Copies the `n x n` derivatives at `(x0, y0)` of a precomputed level, zero outside: each
/// row's span inside the level in one copy.
fn fetch_grad(g: &ImageView<'_, [i16; 2]>, x0: i32, y0: i32, n: usize, out: &mut [[i16; 2]]) {
    let (inner, span) = inside_span(g, x0, n);
    for (j, row) in out.chunks_exact_mut(n.max(1)).take(n).enumerate() {
        row.fill([0, 0]);
        let seg = grad_row(g, y0, j, span.clone());
        if let (Some(seg), Some(o)) = (seg, row.get_mut(inner.clone())) {
            for (o, &d) in o.iter_mut().zip(seg) {
                *o = d;
            }
        }
    }
}

/// One row of [`mismatch`]: `Σ (J - I) Ix`, `Σ (J - I) Iy` over the template row `t`, `J`
/// bilinear in rows `r0`, `r1`. Row sums in `i32` are exact: `|J - I| <= 255 · 32` and
/// `|Ix| <= 16 · 255`, so a row of at most `MAX_WIN = 63` products is below
/// `63 · 8160 · 4080 < 2³¹`. One loop (here, unlike [`template_row`], two passes through a
/// row buffer measured 15 % slower on the Cortex-M7).
#[inline(always)]
fn mismatch_row<P: Copy + Into<i32>>(r0: &[P], r1: &[P], t: &[[i16; 3]], w: &[i32; 4]) -> [i32; 2] {
    let [p00, p01, p10, p11] = taps(r0, r1, t.len());
    let (mut s1, mut s2) = (0i32, 0i32);
    for ((((&a, &b), &c), &d), &[iv, dx, dy]) in p00.iter().zip(p01).zip(p10).zip(p11).zip(t) {
        let diff = descale(lerp(a, b, c, d, w), PIX_SHIFT) - i32::from(iv);
        s1 = s1.wrapping_add(diff * i32::from(dx));
        s2 = s2.wrapping_add(diff * i32::from(dy));
    }
    [s1, s2]
}

/// One row of [`mismatch`]'s `Σ |J - I|` (at most `63 · 8160 < 2³¹`).
#[inline(always)]
fn abs_row<P: Copy + Into<i32>>(r0: &[P], r1: &[P], t: &[[i16; 3]], w: &[i32; 4]) -> u32 {
    let [p00, p01, p10, p11] = taps(r0, r1, t.len());
    let mut s = 0u32;
    for ((((&a, &b), &c), &d), &[iv, _, _]) in p00.iter().zip(p01).zip(p10).zip(p11).zip(t) {
        let diff = descale(lerp(a, b, c, d, w), PIX_SHIFT) - i32::from(iv);
        s = s.wrapping_add(diff.unsigned_abs());
    }
    s
}

/// `Σ (J - I) [Ix Iy]` over the window (or `Σ |J - I|` when `abs`), `J` bilinear in the
/// `win + 1` rows `rows` (image rows or the scratch patch).
fn mismatch<P: Copy + Into<i32>>(
    rows: Rows<'_, P>,
    tmpl: &[[i16; 3]],
    win: usize,
    w: [i32; 4],
    abs: bool,
) -> (i64, i64) {
    let (mut b1, mut b2) = (0i64, 0i64);
    let pairs = rows.pairs();
    for ((r0, r1), t) in pairs.zip(tmpl.chunks_exact(win.max(1))) {
        if abs {
            b1 += i64::from(abs_row(r0, r1, t, &w));
        } else {
            let [s1, s2] = mismatch_row(r0, r1, t, &w);
            b1 += i64::from(s1);
            b2 += i64::from(s2);
        }
    }
    (b1, b2)
}

/// One row of [`template`]: the template and its derivatives at weights `w` into `out`;
/// returns the row's `Σ Ix²`, `Σ Ix Iy`, `Σ Iy²` (exact in `i32`: `|Ix| <= 16 · 255`, so 63
/// squares stay below 2³¹). Three passes, the pixels, `Ix`, then `Iy`: one loop over all
/// three ran out of registers on the Cortex-M7 (about 60 instructions a pixel with the
/// weights reloaded from the stack).
#[inline(always)]
fn template_row<P: Copy + Into<i32>>(
    (r0, r1): (&[P], &[P]),
    (g0, g1): (&[[i16; 2]], &[[i16; 2]]),
    out: &mut [[i16; 3]],
    w: &[i32; 4],
) -> [i32; 3] {
    let m = out.len();
    let [p00, p01, p10, p11] = taps(r0, r1, m);
    let px = p00.iter().zip(p01).zip(p10).zip(p11);
    for ((((&a, &b), &c), &d), o) in px.zip(out.iter_mut()) {
        o[0] = descale(lerp(a, b, c, d, w), PIX_SHIFT) as i16;
    }
    let [q00, q01, q10, q11] = taps(g0, g1, m);
    let gr = || q00.iter().zip(q01).zip(q10).zip(q11);
    let mut s11 = 0i32;
    for ((((g00, g01), g10), g11), o) in gr().zip(out.iter_mut()) {
        let ix = descale(lerp(g00[0], g01[0], g10[0], g11[0], w), W_BITS);
        o[1] = ix as i16;
        s11 = s11.wrapping_add(ix * ix);
    }
    let (mut s12, mut s22) = (0i32, 0i32);
    for ((((g00, g01), g10), g11), o) in gr().zip(out.iter_mut()) {
        let iy = descale(lerp(g00[1], g01[1], g10[1], g11[1], w), W_BITS);
        o[2] = iy as i16;
        s12 = s12.wrapping_add(i32::from(o[1]) * iy);
        s22 = s22.wrapping_add(iy * iy);
    }
    [s11, s12, s22]
}

/// Interpolates the template (from the `win + 1` rows `rows` of `I`) and its derivatives
/// (from `gwin`) at weights `w` into `tmpl`; returns `G`'s sums.
fn template<P: Copy + Into<i32>>(
    rows: Rows<'_, P>,
    gwin: &[[i16; 2]],
    tmpl: &mut [[i16; 3]],
    win: usize,
    w: [i32; 4],
) -> (i64, i64, i64) {
    let n = win + 1;
    let (mut a11, mut a12, mut a22) = (0i64, 0i64, 0i64);
    let pairs = rows.pairs().zip(block_of(gwin, n, n).pairs());
    for ((r, g), out) in pairs.zip(tmpl.chunks_exact_mut(win.max(1))) {
        let [s11, s12, s22] = template_row(r, g, out, &w);
        a11 += i64::from(s11);
        a12 += i64::from(s12);
        a22 += i64::from(s22);
    }
    (a11, a12, a22)
}
