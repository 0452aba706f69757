//! The window kernel for cores without vector units ([`super::window::Window`]): the template
//! interleaved `[I, Ix, Iy]` a pixel, rows exactly `win` wide.

use super::border::Pixels;
use super::patch::{Rows, block_of, block_rows, cached_patch, fetch_grad, fetch_patch};
use super::window::{PIX_SHIFT, Window};
use crate::gradient::scharr_window;
use crate::image::ImageView;
use crate::klt::arith::{Bilinear, W_BITS};
use crate::{Error, Result};

/// `i16` elements of scratch for `win x win` windows: `3 win²` for the template and its
/// derivatives, and before it the larger of `3 (win + 1)²` (derivatives and pixels at integer
/// positions) and [`sums_len`]`(win)` `i32` (with one `i16` to align them).
pub(super) const fn scratch_len(win: usize) -> usize {
    let n = win + 1;
    let (grid, sums) = (3 * n * n, 2 * sums_len(win) + 1);
    (if grid > sums { grid } else { sums }) + 3 * win * win
}

/// `i32` elements of [`template_inside`]'s sums: `(win + 2)²` bilinear sums and one row of
/// `win + 2` vertical Scharr pairs.
const fn sums_len(win: usize) -> usize {
    (win + 2) * (win + 2) + 2 * (win + 2)
}

/// `i16` elements of the template, [`Window::state`].
pub(super) const fn state_len(win: usize) -> usize {
    3 * win * win
}

/// The scratch split into its parts.
pub(in crate::klt) struct Packed<'s> {
    win: usize,
    /// Work space, used by one step at a time: while a template is made, its derivatives at
    /// integer positions (`(win + 1)²` `[Ix, Iy]` pairs) and the pixels of a block that leaves
    /// the image (reflected, `(win + 1)²`), or, when the block lies inside the image,
    /// [`template_inside`]'s `i32` sums; after it, the reflected window of `J` for the
    /// mismatch with its margin, `(win + 3)²` ([`cached_patch`]; each template clears
    /// `patch_at`).
    low: &'s mut [i16],
    /// The interpolated template: `[I, Ix, Iy]` a pixel, together so that the mismatch loop
    /// reads one run of memory (and keeps one pointer live).
    tmpl: &'s mut [[i16; 3]],
    /// The integer corner of the window of `J` in `patch`, if it holds one
    /// ([`cached_patch`]); cleared by [`Window::template`].
    patch_at: Option<(i32, i32)>,
}

impl<'s> Window<'s> for Packed<'s> {
    /// Not measured to pay on a board (a copy of the level-1 pair of 320x240 is 61 KB of
    /// RAM); reading the copies cost the M7 0.7 % a feature even when none was given.
    const BORDERED: bool = false;

    fn new(scratch: &'s mut [i16], win: usize) -> Result<Self> {
        let short = Error::BufferTooSmall("scratch");
        let (low, rest) = scratch
            .split_at_mut_checked(scratch_len(win) - state_len(win))
            .ok_or(short)?;
        let t = rest.get_mut(..state_len(win)).ok_or(short)?;
        let (tmpl, _) = t.as_chunks_mut::<3>();
        Ok(Self {
            win,
            low,
            tmpl,
            patch_at: None,
        })
    }

    fn template(
        &mut self,
        pixels: &Pixels<'_>,
        grad: Option<&ImageView<'_, [i16; 2]>>,
        b: &Bilinear,
    ) -> (i64, i64, i64) {
        let (win, n) = (self.win, self.win + 1);
        let i = &pixels.img;
        self.patch_at = None;
        if grad.is_none()
            && let Some(rows) = block_rows(
                i,
                (b.x.saturating_sub(1), b.y.saturating_sub(1)),
                n + 2,
                n + 2,
            )
        {
            let (_, sums, _) = bytemuck::pod_align_to_mut::<i16, i32>(self.low);
            return template_inside(rows, sums, self.tmpl, win, b.w);
        }
        let (gwin, patch) = self.low.split_at_mut((2 * n * n).min(self.low.len()));
        let (gwin, _) = gwin.as_chunks_mut::<2>();
        match grad {
            Some(g) => fetch_grad(g, (b.x, b.y), n, n, gwin),
            None => {
                let _ = scharr_window(i, b.x as isize, b.y as isize, n, n, gwin);
            }
        }
        let rows = match block_rows(i, (b.x, b.y), n, n) {
            Some(rows) => rows,
            None => {
                let patch = bytemuck::cast_slice_mut::<i16, u8>(patch);
                fetch_patch(i, (b.x, b.y), n, n, patch);
                block_of(patch, n, n)
            }
        };
        template(rows, gwin, self.tmpl, win, b.w)
    }

    fn mismatch(&mut self, j: &Pixels<'_>, b: &Bilinear, abs: bool) -> (i64, i64) {
        let (win, n) = (self.win, self.win + 1);
        let j = &j.img;
        match block_rows(j, (b.x, b.y), n, n) {
            Some(rows) => mismatch(rows, self.tmpl, win, b.w, abs),
            None => {
                // The template is made: the derivatives' part of the scratch is free.
                let at = (b.x, b.y);
                let rows = cached_patch(j, at, (n, n), self.low, &mut self.patch_at);
                mismatch(rows, self.tmpl, win, b.w, abs)
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

/// The template at weights `w` of a window whose Scharr taps lie inside the image (`rows`: the
/// `win + 3` rows, `win + 3` wide, of the block one pixel up and left of the window's corner),
/// with the same integers as [`template`] in fewer operations.
///
/// Scharr and the bilinear sum are both linear with integer coefficients, so they commute
/// exactly: the bilinear sum of the Scharr derivatives (what [`template`] descales) is the
/// Scharr derivative of the bilinear sums `P = w₀₀ p₀₀ + w₀₁ p₀₁ + w₁₀ p₁₀ + w₁₁ p₁₁` of the
/// pixels (`|P| < 2²²`, so `16 |P| < 2²⁶`, exact in `i32`). One bilinear pass over the
/// `(win + 2)²` positions then gives `I` (`P` descaled), `Ix` and `Iy` (Scharr of `P`: per row
/// the vertical `[3 10 3]` sum and `[-1 0 1]` difference, then the horizontal ones, descaled),
/// where [`template`] interpolates three planes from a `(win + 1)²` Scharr window: on the
/// Cortex-M7, about 69 instructions a template pixel become about 55. `sums` holds
/// [`sums_len`]`(win)`.
fn template_inside(
    rows: Rows<'_, u8>,
    sums: &mut [i32],
    tmpl: &mut [[i16; 3]],
    win: usize,
    w: [i32; 4],
) -> (i64, i64, i64) {
    // Checked, so the optimiser sees `m >= 2` (no zero-chunk panic below).
    let Some(m) = win.checked_add(2) else {
        return (0, 0, 0);
    };
    let Some((p, rest)) = sums.split_at_mut_checked(m * m) else {
        return (0, 0, 0);
    };
    let (vert, _) = rest.as_chunks_mut::<2>();
    let vert = vert.get_mut(..m).unwrap_or(&mut []);
    bilinear_sums(rows, p, m, &w);
    let (mut a11, mut a12, mut a22) = (0i64, 0i64, 0i64);
    let prows = p.chunks_exact(m);
    let triples = prows.clone().zip(prows.clone().skip(1)).zip(prows.skip(2));
    for (((top, mid), bot), out) in triples.zip(tmpl.chunks_exact_mut(win.max(1))) {
        for (((&a, &b), &c), v) in top.iter().zip(mid).zip(bot).zip(vert.iter_mut()) {
            *v = [3 * (a + c) + 10 * b, c - a];
        }
        let [s11, s12, s22] = inside_row(vert, mid.get(1..).unwrap_or(&[]), out);
        a11 += i64::from(s11);
        a12 += i64::from(s12);
        a22 += i64::from(s22);
    }
    (a11, a12, a22)
}

/// The bilinear sums `P` (undescaled) of the `m x m` positions of the `m + 1` rows `rows` into
/// `p`. A function of its own: inlined into [`template_inside`], whose `i64` sums and row
/// pointers stay live around it, the loop spilled its row pointers (18 instructions a
/// position on the Cortex-M7 instead of 11).
#[inline(never)]
fn bilinear_sums(rows: Rows<'_, u8>, p: &mut [i32], m: usize, w: &[i32; 4]) {
    for ((r0, r1), out) in rows.pairs().zip(p.chunks_exact_mut(m.max(1))) {
        let [p00, p01, p10, p11] = taps(r0, r1, m);
        let px = p00.iter().zip(p01).zip(p10).zip(p11);
        for ((((&a, &b), &c), &d), o) in px.zip(out.iter_mut()) {
            *o = lerp(a, b, c, d, w);
        }
    }
}

/// One row of [`template_inside`]: from the vertical Scharr pairs `vert` (`[3 10 3]` sum,
/// `[-1 0 1]` difference of `P`, `win + 2` of them) and the middle row of `P` from its second
/// column, the row's `[I, Ix, Iy]` into `out` and its `Σ Ix²`, `Σ Ix Iy`, `Σ Iy²` (as in
/// [`template_row`]).
#[inline(always)]
fn inside_row(vert: &[[i32; 2]], mid: &[i32], out: &mut [[i16; 3]]) -> [i32; 3] {
    let k = out.len();
    let (v0, v1, v2) = match (vert.get(..k), vert.get(1..k + 1), vert.get(2..k + 2)) {
        (Some(a), Some(b), Some(c)) => (a, b, c),
        _ => return [0; 3],
    };
    let (mut s11, mut s12, mut s22) = (0i32, 0i32, 0i32);
    let cols = v0.iter().zip(v1).zip(v2).zip(mid);
    for ((((&[s0, d0], &[_, d1]), &[s2, d2]), &pm), o) in cols.zip(out.iter_mut()) {
        let ix = descale(s2 - s0, W_BITS);
        let iy = descale(3 * (d0 + d2) + 10 * d1, W_BITS);
        *o = [descale(pm, PIX_SHIFT) as i16, ix as i16, iy as i16];
        s11 = s11.wrapping_add(ix * ix);
        s12 = s12.wrapping_add(ix * iy);
        s22 = s22.wrapping_add(iy * iy);
    }
    [s11, s12, s22]
}

/// `v / 2ⁿ` rounded half up.
#[inline(always)]
fn descale(v: i32, n: u32) -> i32 {
    (v + (1 << (n - 1))) >> n
}

/// The bilinear sample `p00 w0 + p01 w1 + p10 w2 + p11 w3` at one position.
#[inline(always)]
fn lerp<P: Copy + Into<i32>, W: Copy + Into<i32>>(
    p00: P,
    p01: P,
    p10: P,
    p11: P,
    w: &[W; 4],
) -> i32 {
    p00.into() * w[0].into()
        + p01.into() * w[1].into()
        + p10.into() * w[2].into()
        + p11.into() * w[3].into()
}

/// The four taps of `m` bilinear samples along two rows: `(r0[x], r0[x+1], r1[x], r1[x+1])`
/// for `x < m`, as four slices of exactly `m` (empty when a row is shorter than `m + 1`).
///
/// Exact lengths let the zips below run on one index with no per-element length tests, so
/// the loop bodies stay straight-line (the Cortex-M7 keeps the four weights and both sums in
/// registers; with unequal lengths it predicated every instruction and spilled the weights).
#[inline(always)]
fn taps<'a, P>(r0: &'a [P], r1: &'a [P], m: usize) -> [&'a [P]; 4] {
    match (r0.get(..m + 1), r1.get(..m + 1)) {
        (Some(a), Some(b)) => [
            a.get(..m).unwrap_or(&[]),
            a.get(1..).unwrap_or(&[]),
            b.get(..m).unwrap_or(&[]),
            b.get(1..).unwrap_or(&[]),
        ],
        _ => [&[]; 4],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For every window size the work space holds the mismatch's block with
    /// [`PATCH_MARGIN`](super::super::patch::PATCH_MARGIN) on every side.
    #[test]
    fn scratch_holds_the_margin_patch() {
        use super::super::patch::PATCH_MARGIN;
        for win in 3..=crate::klt::MAX_WIN {
            let mut scratch = std::vec![0i16; scratch_len(win)];
            let k = Packed::new(&mut scratch, win).unwrap();
            let n = win + 1 + 2 * PATCH_MARGIN;
            assert!(k.low.len() >= n * n, "win {win}");
        }
    }
}
