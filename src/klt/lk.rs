//! The Lucas-Kanade iteration of one point on one level, and the pyramid driver.

use super::arith::{Bilinear, Coordinate, FlowArith, W_BITS};
use super::{Flow, FlowStatus, Gradients, LkConfig, LkParams, scratch_len};
use crate::gradient::{reflect101, scharr_window};
use crate::image::{ImageMut, ImageView};
use crate::pyramid::Pyramid;
use crate::{Error, Result};

/// Shift from Q14-weighted pixels to the template's 1/32 grey levels.
const PIX_SHIFT: u32 = W_BITS - 5;

#[inline]
fn descale(v: i32, n: u32) -> i32 {
    (v + (1 << (n - 1))) >> n
}

/// Copies the `n x n` pixels at `(x0, y0)` of `img` into `out`, reflecting outside the image.
fn fetch_patch(img: &ImageView<'_, u8>, x0: i32, y0: i32, n: usize, out: &mut [i16]) {
    let (w, h) = (img.width() as i32, img.height() as i32);
    let inside = x0 >= 0 && y0 >= 0 && x0 + n as i32 <= w && y0 + n as i32 <= h;
    for (j, row) in out.chunks_exact_mut(n.max(1)).take(n).enumerate() {
        let y = y0 as isize + j as isize;
        let src = img.row_clamped(reflect101(y, img.height()) as isize);
        if inside {
            let seg = src.iter().skip(x0 as usize);
            for (o, &p) in row.iter_mut().zip(seg) {
                *o = i16::from(p);
            }
        } else {
            for (i, o) in row.iter_mut().enumerate() {
                let x = reflect101(x0 as isize + i as isize, img.width());
                *o = i16::from(src.get(x).copied().unwrap_or(0));
            }
        }
    }
}

/// Copies the `n x n` derivatives at `(x0, y0)` of a precomputed level, zero outside.
fn fetch_grad(g: &ImageView<'_, [i16; 2]>, x0: i32, y0: i32, n: usize, out: &mut [[i16; 2]]) {
    for (j, row) in out.chunks_exact_mut(n.max(1)).take(n).enumerate() {
        let y = y0 + j as i32;
        let src = if y >= 0 { g.row(y as usize) } else { None };
        for (i, o) in row.iter_mut().enumerate() {
            let x = x0 + i as i32;
            *o = match src {
                Some(r) if x >= 0 => r.get(x as usize).copied().unwrap_or([0, 0]),
                _ => [0, 0],
            };
        }
    }
}

/// `true` when the window at integer corner `(x, y)` still touches the image (OpenCV's test).
#[inline]
fn in_range(b: &Bilinear, win: usize, w: usize, h: usize) -> bool {
    let win = win as i32;
    b.x >= -win && b.x < w as i32 && b.y >= -win && b.y < h as i32
}

/// The per-call state shared by every point of a level.
struct Level<'a, 'g, A: FlowArith> {
    i: ImageView<'a, u8>,
    j: ImageView<'a, u8>,
    grad: Option<ImageView<'g, [i16; 2]>>,
    level: u32,
    top: bool,
    win: usize,
    max_iter: u32,
    use_initial: bool,
    compute_error: bool,
    params: A::Params,
}

/// The scratch split into its parts.
struct Scratch<'s> {
    gwin: &'s mut [[i16; 2]],
    patch: &'s mut [i16],
    /// The interpolated template: `[I, Ix, Iy]` a pixel, together so that the mismatch loop
    /// reads one run of memory (and keeps one pointer live).
    tmpl: &'s mut [[i16; 3]],
}

fn split_scratch(scratch: &mut [i16], win: usize) -> Result<Scratch<'_>> {
    let n2 = (win + 1) * (win + 1);
    let w2 = win * win;
    let (g, rest) = scratch
        .split_at_mut_checked(2 * n2)
        .ok_or(Error::BufferTooSmall("scratch"))?;
    let (patch, rest) = rest
        .split_at_mut_checked(n2)
        .ok_or(Error::BufferTooSmall("scratch"))?;
    let t = rest
        .get_mut(..3 * w2)
        .ok_or(Error::BufferTooSmall("scratch"))?;
    let (gwin, _) = g.as_chunks_mut::<2>();
    let (tmpl, _) = t.as_chunks_mut::<3>();
    Ok(Scratch { gwin, patch, tmpl })
}

/// The `n` rows of the `n x n` block at `(x0, y0)` of `img`, straight from the image, when
/// the block lies inside it (then no copy into the scratch patch is needed).
fn block_rows<'a>(
    img: &ImageView<'a, u8>,
    x0: i32,
    y0: i32,
    n: usize,
) -> Option<impl Iterator<Item = &'a [u8]> + Clone> {
    let (x0, y0) = (usize::try_from(x0).ok()?, usize::try_from(y0).ok()?);
    if x0 + n > img.width() || y0 + n > img.height() {
        return None;
    }
    let img = *img;
    Some((y0..y0 + n).map(move |y| img.row(y).and_then(|r| r.get(x0..x0 + n)).unwrap_or(&[])))
}

/// The `n` rows of the `n x n` scratch patch (as `patch.chunks_exact(n)`, whose length the
/// zips above would compute with a division the optimiser cannot prove non-zero).
fn patch_rows(patch: &[i16], n: usize) -> impl Iterator<Item = &[i16]> + Clone {
    (0..n).map(move |r| patch.get(r * n..(r + 1) * n).unwrap_or(&[]))
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

/// The bilinear sample `p00 w0 + p01 w1 + p10 w2 + p11 w3` at one position.
#[inline(always)]
fn lerp<P: Copy + Into<i32>>(p00: P, p01: P, p10: P, p11: P, w: &[i32; 4]) -> i32 {
    p00.into() * w[0] + p01.into() * w[1] + p10.into() * w[2] + p11.into() * w[3]
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
fn mismatch<'p, P: Copy + Into<i32> + 'p>(
    rows: impl Iterator<Item = &'p [P]> + Clone,
    tmpl: &[[i16; 3]],
    win: usize,
    w: [i32; 4],
    abs: bool,
) -> (i64, i64) {
    let (mut b1, mut b2) = (0i64, 0i64);
    let pairs = rows.clone().zip(rows.skip(1));
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
fn template<'p, P: Copy + Into<i32> + 'p>(
    rows: impl Iterator<Item = &'p [P]> + Clone,
    gwin: &[[i16; 2]],
    tmpl: &mut [[i16; 3]],
    win: usize,
    w: [i32; 4],
) -> (i64, i64, i64) {
    let n = win + 1;
    let (mut a11, mut a12, mut a22) = (0i64, 0i64, 0i64);
    let grows = gwin.chunks_exact(n.max(1));
    let pairs = rows
        .clone()
        .zip(rows.skip(1))
        .zip(grows.clone().zip(grows.skip(1)));
    for ((r, g), out) in pairs.zip(tmpl.chunks_exact_mut(win.max(1))) {
        let [s11, s12, s22] = template_row(r, g, out, &w);
        a11 += i64::from(s11);
        a12 += i64::from(s12);
        a22 += i64::from(s22);
    }
    (a11, a12, a22)
}

/// [`mismatch`] of the window of `J` at integer corner `(x, y)`: straight from the image
/// when inside it, else through the reflected scratch patch.
fn mismatch_at(
    j: &ImageView<'_, u8>,
    s: &mut Scratch<'_>,
    (x, y): (i32, i32),
    win: usize,
    w: [i32; 4],
    abs: bool,
) -> (i64, i64) {
    let n = win + 1;
    match block_rows(j, x, y, n) {
        Some(rows) => mismatch(rows, s.tmpl, win, w, abs),
        None => {
            fetch_patch(j, x, y, n, s.patch);
            mismatch(patch_rows(s.patch, n), s.tmpl, win, w, abs)
        }
    }
}

/// One point on one level (OpenCV's `LKTrackerInvoker` body).
fn track_point<A: FlowArith>(
    lv: &Level<'_, '_, A>,
    s: &mut Scratch<'_>,
    prev_pt: [A::Coord; 2],
    f: &mut Flow<A::Coord>,
) {
    let win = lv.win;
    let area = (win * win) as u32;
    let half = A::Coord::from_half_px(win as i32 - 1);
    let last = lv.level == 0;
    let p = prev_pt.map(|c| c.down(lv.level));
    let mut next = if lv.top {
        if lv.use_initial {
            [f.x.down(lv.level), f.y.down(lv.level)]
        } else {
            p
        }
    } else {
        [f.x.twice(), f.y.twice()]
    };
    f.x = next[0];
    f.y = next[1];
    let (iw, ih) = (lv.i.width(), lv.i.height());
    let Some(bi) = A::bilinear(p[0] - half, p[1] - half) else {
        f.status = FlowStatus::OutOfBounds;
        return;
    };
    if !in_range(&bi, win, iw, ih) {
        if last {
            f.status = FlowStatus::OutOfBounds;
            f.err = A::Coord::default();
        }
        return;
    }
    let n = win + 1;
    match &lv.grad {
        Some(g) => fetch_grad(g, bi.x, bi.y, n, s.gwin),
        None => {
            let _ = scharr_window(&lv.i, bi.x as isize, bi.y as isize, n, n, s.gwin);
        }
    }
    let (a11, a12, a22) = match block_rows(&lv.i, bi.x, bi.y, n) {
        Some(rows) => template(rows, s.gwin, s.tmpl, win, bi.w),
        None => {
            fetch_patch(&lv.i, bi.x, bi.y, n, s.patch);
            template(patch_rows(s.patch, n), s.gwin, s.tmpl, win, bi.w)
        }
    };
    let gram = match A::gram(a11, a12, a22, &lv.params) {
        Ok(g) => g,
        Err(status) => {
            if last {
                f.status = status;
            }
            return;
        }
    };
    next = next.map(|c| c - half);
    let mut prev_delta = [A::Coord::default(); 2];
    for it in 0..lv.max_iter {
        let Some(bj) = A::bilinear(next[0], next[1]) else {
            f.status = FlowStatus::OutOfBounds;
            return;
        };
        if !in_range(&bj, win, iw, ih) {
            if last {
                f.status = FlowStatus::OutOfBounds;
            }
            break;
        }
        let (b1, b2) = mismatch_at(&lv.j, s, (bj.x, bj.y), win, bj.w, false);
        let delta = A::step(&gram, b1, b2);
        next = [next[0] + delta[0], next[1] + delta[1]];
        f.x = next[0] + half;
        f.y = next[1] + half;
        if A::converged(delta, &lv.params) {
            break;
        }
        if it > 0 && A::oscillates(delta, prev_delta) {
            f.x = f.x - delta[0].half();
            f.y = f.y - delta[1].half();
            break;
        }
        prev_delta = delta;
    }
    if last && lv.compute_error && f.status == FlowStatus::Tracked {
        let Some(bj) = A::bilinear(f.x - half, f.y - half) else {
            f.status = FlowStatus::OutOfBounds;
            return;
        };
        if !in_range(&bj, win, iw, ih) {
            f.status = FlowStatus::OutOfBounds;
            return;
        }
        let (sum, _) = mismatch_at(&lv.j, s, (bj.x, bj.y), win, bj.w, true);
        f.err = A::error(sum.unsigned_abs(), area);
    }
}

/// The coarsest level OpenCV would use: `cfg.max_level`, capped by both pyramids and by the
/// rule that a level above 0 must be larger than the window in both directions.
fn usable_levels(prev: &Pyramid<'_>, next: &Pyramid<'_>, cfg: &LkConfig) -> usize {
    let mut top = 0;
    while top < cfg.max_level {
        let l = top + 1;
        match (prev.level(l), next.level(l)) {
            (Some(a), Some(_)) if a.width() > cfg.win && a.height() > cfg.win => top = l,
            _ => break,
        }
    }
    top
}

/// The driver: every level from the coarsest down, every point on each level.
fn run<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    pts: impl Fn(usize) -> Option<[A::Coord; 2]>,
    flows: &mut [Flow<A::Coord>],
    params: &LkParams,
    grads: &mut Gradients<'_>,
    scratch: &mut [i16],
) -> Result<()> {
    let cfg = params.config();
    if scratch.len() < scratch_len(cfg.win) {
        return Err(Error::BufferTooSmall("scratch"));
    }
    let mut s = split_scratch(scratch, cfg.win)?;
    let top = usable_levels(prev, next, cfg);
    let params = A::params(params, (cfg.win * cfg.win) as u32);
    for f in flows.iter_mut() {
        f.status = FlowStatus::Tracked;
        f.err = A::Coord::default();
    }
    for level in (0..=top).rev() {
        let (Some(i), Some(j)) = (prev.level(level), next.level(level)) else {
            return Err(Error::InvalidImage);
        };
        if (i.width(), i.height()) != (j.width(), j.height()) {
            return Err(Error::InvalidImage);
        }
        let grad = match grads {
            Gradients::PerWindow => None,
            Gradients::PerLevel(buf) => {
                let len = i.width() * i.height();
                let b = buf
                    .get_mut(..len)
                    .ok_or(Error::BufferTooSmall("gradients"))?;
                crate::gradient::scharr_level(
                    &i,
                    &mut ImageMut::packed(b, i.width(), i.height())?,
                )?;
                Some(ImageView::packed(&*b, i.width(), i.height())?)
            }
        };
        let lv = Level::<A> {
            i,
            j,
            grad,
            level: level as u32,
            top: level == top,
            win: cfg.win,
            max_iter: cfg.max_iter,
            use_initial: cfg.use_initial_flow,
            compute_error: cfg.compute_error,
            params,
        };
        for (k, f) in flows.iter_mut().enumerate() {
            match pts(k) {
                Some(p) => track_point(&lv, &mut s, p, f),
                None => f.status = FlowStatus::OutOfBounds,
            }
        }
    }
    Ok(())
}

/// Tracks `prev_pts` from `prev` to `next` (OpenCV's `calcOpticalFlowPyrLK`).
///
/// `flows[k]` receives the position of `prev_pts[k]` in `next` with its status and error
/// (with [`LkConfig::use_initial_flow`] it must hold the initial guesses on entry). Points are
/// full-resolution pixel coordinates, `(0, 0)` the centre of the top-left pixel.
///
/// Errors: [`Error::LengthMismatch`] when the slices differ in length,
/// [`Error::BufferTooSmall`] for scratch shorter than [`scratch_len`]`(win)` (or a
/// [`Gradients::PerLevel`] buffer too short), [`Error::InvalidImage`] when the pyramids'
/// levels differ in size. The configuration was checked once by [`LkConfig::check`].
pub fn calc_flow<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    prev_pts: &[[A::Coord; 2]],
    flows: &mut [Flow<A::Coord>],
    cfg: &LkParams,
    mut grads: Gradients<'_>,
    scratch: &mut [i16],
) -> Result<()> {
    if prev_pts.len() != flows.len() {
        return Err(Error::LengthMismatch);
    }
    run::<A>(
        prev,
        next,
        |k| prev_pts.get(k).copied(),
        flows,
        cfg,
        &mut grads,
        scratch,
    )
}

/// Forward-backward check: tracks the results `flows` back from `next` to `prev` into `back`
/// and marks [`FlowStatus::Inconsistent`] every tracked point that does not come back within
/// [`LkConfig::fb_threshold`] of `prev_pts` (`|back - prev| > t`). Does nothing when the
/// threshold is `None`. Same errors as [`calc_flow`].
#[allow(clippy::too_many_arguments)]
pub fn forward_backward<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    prev_pts: &[[A::Coord; 2]],
    flows: &mut [Flow<A::Coord>],
    back: &mut [Flow<A::Coord>],
    cfg: &LkParams,
    mut grads: Gradients<'_>,
    scratch: &mut [i16],
) -> Result<()> {
    if prev_pts.len() != flows.len() || back.len() != flows.len() {
        return Err(Error::LengthMismatch);
    }
    if cfg.config().fb_threshold.is_none() {
        return Ok(());
    }
    let bcfg = cfg.with_initial_flow(false);
    {
        let fw: &[Flow<A::Coord>] = flows;
        run::<A>(
            next,
            prev,
            |k| fw.get(k).map(|f| [f.x, f.y]),
            back,
            &bcfg,
            &mut grads,
            scratch,
        )?;
    }
    let win = cfg.config().win;
    let params = A::params(cfg, (win * win) as u32);
    for ((f, b), p) in flows.iter_mut().zip(back.iter()).zip(prev_pts) {
        if f.status == FlowStatus::Tracked
            && (b.status != FlowStatus::Tracked || A::beyond([b.x, b.y], *p, &params))
        {
            f.status = FlowStatus::Inconsistent;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::{Fixed, Q16};
    use super::*;
    use std::vec::Vec;

    /// A smooth textured image: sum of sinusoids, exact at sub-pixel shifts.
    fn scene(w: usize, h: usize, dx: f64, dy: f64) -> Vec<u8> {
        let mut v = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (u, t) = (x as f64 - dx, y as f64 - dy);
                let s = 128.0
                    + 50.0 * (u * 0.21).sin() * (t * 0.17).cos()
                    + 40.0 * (u * 0.07 + t * 0.11).sin()
                    + 20.0 * ((u - t) * 0.31).cos();
                v.push(s.round().clamp(0.0, 255.0) as u8);
            }
        }
        v
    }

    fn run_both(dx: f64, dy: f64) -> (Vec<Flow<f32>>, Vec<Flow<Q16>>) {
        let (w, h) = (160, 120);
        let a = scene(w, h, 0.0, 0.0);
        let b = scene(w, h, dx, dy);
        let mut ba = std::vec![0u8; crate::pyramid::buffer_len(w, h, 3)];
        let mut bb = std::vec![0u8; crate::pyramid::buffer_len(w, h, 3)];
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut ba, 3).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut bb, 3).unwrap();
        let cfg = LkConfig {
            max_level: 2,
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        let pts: Vec<[f32; 2]> = (0..5)
            .flat_map(|j| (0..5).map(move |i| [25.0 + 22.0 * i as f32, 20.0 + 20.0 * j as f32]))
            .collect();
        let mut scratch = std::vec![0i16; scratch_len(cfg.config().win)];
        let mut ff = std::vec![Flow::<f32>::default(); pts.len()];
        calc_flow::<f32>(
            &pa,
            &pb,
            &pts,
            &mut ff,
            &cfg,
            Gradients::PerWindow,
            &mut scratch,
        )
        .unwrap();
        let qpts: Vec<[Q16; 2]> = pts
            .iter()
            .map(|p| {
                [
                    Q16::saturating_from_f32(p[0]),
                    Q16::saturating_from_f32(p[1]),
                ]
            })
            .collect();
        let mut fq = std::vec![Flow::<Q16>::default(); pts.len()];
        let mut lvl = std::vec![[0i16; 2]; w * h];
        calc_flow::<Fixed>(
            &pa,
            &pb,
            &qpts,
            &mut fq,
            &cfg,
            Gradients::PerLevel(&mut lvl),
            &mut scratch,
        )
        .unwrap();
        for ((p, f), q) in pts.iter().zip(&ff).zip(&fq) {
            assert_eq!(f.status, FlowStatus::Tracked, "{p:?}");
            assert_eq!(q.status, FlowStatus::Tracked, "{p:?}");
            let e =
                |x: f32, y: f32| (x as f64 - p[0] as f64 - dx).hypot(y as f64 - p[1] as f64 - dy);
            assert!(e(f.x, f.y) < 0.15, "f32 {p:?} -> {f:?}");
            assert!(e(q.x.to_f32(), q.y.to_f32()) < 0.15, "fixed {p:?} -> {q:?}");
        }
        (ff, fq)
    }

    #[test]
    fn recovers_known_translations() {
        run_both(0.0, 0.0);
        run_both(1.3, -0.6);
        run_both(-4.7, 3.2);
        run_both(9.5, 7.25);
    }

    #[test]
    fn per_level_and_per_window_agree_bit_for_bit() {
        let (w, h) = (64, 48);
        let a = scene(w, h, 0.0, 0.0);
        let b = scene(w, h, 1.7, 0.4);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let cfg = LkConfig {
            win: 9,
            max_level: 0,
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        // Including points near and past the border.
        let pts = [
            [0, 0],
            [3 << 16, 40 << 16],
            [(63 << 16) + 5, 47 << 16],
            [30 << 16, (20 << 16) + 999],
        ]
        .map(|p| p.map(Q16::from_bits));
        let mut s = std::vec![0i16; scratch_len(9)];
        let mut f1 = [Flow::<Q16>::default(); 4];
        let mut f2 = [Flow::<Q16>::default(); 4];
        calc_flow::<Fixed>(&pa, &pb, &pts, &mut f1, &cfg, Gradients::PerWindow, &mut s).unwrap();
        let mut g = std::vec![[0i16; 2]; w * h];
        calc_flow::<Fixed>(
            &pa,
            &pb,
            &pts,
            &mut f2,
            &cfg,
            Gradients::PerLevel(&mut g),
            &mut s,
        )
        .unwrap();
        assert_eq!(f1, f2);
    }

    /// `compute_error: false` moves no point (same positions bit for bit), leaves `err` 0,
    /// and skips only the final range check: a point whose last step leaves the image stays
    /// `Tracked` without it.
    #[test]
    fn without_the_error_pass_the_positions_are_the_same() {
        let (w, h) = (64, 48);
        let a = scene(w, h, 0.0, 0.0);
        let b = scene(w, h, 2.6, -1.2);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let pts = [[20, 20], [40, 30], [10, 35], [62, 1], [1, 46]]
            .map(|p: [i32; 2]| p.map(|v| Q16::from_bits(v << 16)));
        let run = |compute_error: bool| {
            let cfg = LkConfig {
                win: 9,
                max_level: 0,
                compute_error,
                ..LkConfig::default()
            }
            .check()
            .unwrap();
            let mut s = std::vec![0i16; scratch_len(9)];
            let mut f = [Flow::<Q16>::default(); 5];
            calc_flow::<Fixed>(&pa, &pb, &pts, &mut f, &cfg, Gradients::PerWindow, &mut s).unwrap();
            f
        };
        let (with, without) = (run(true), run(false));
        let (mut tracked, mut with_err) = (0, 0);
        for (a, b) in with.iter().zip(&without) {
            assert_eq!((a.x, a.y), (b.x, b.y));
            assert_eq!(b.err, Q16::ZERO);
            if a.status == FlowStatus::Tracked {
                assert_eq!(b.status, FlowStatus::Tracked);
                tracked += 1;
                with_err += usize::from(a.err > Q16::ZERO);
            }
        }
        // The scene moved by a fraction of a pixel: the error pass sees a residual.
        assert!(tracked >= 3 && with_err >= 1, "{with:?}");
    }

    #[test]
    fn far_points_are_lost_and_bad_inputs_are_errors() {
        let (w, h) = (64, 48);
        let a = scene(w, h, 0.0, 0.0);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let cfg = LkConfig {
            win: 7,
            max_level: 0,
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        let pts = [[-50.0f32, 3.0], [f32::NAN, 1.0], [10.0, 1e30]];
        let mut f = [Flow::<f32>::default(); 3];
        let mut s = std::vec![0i16; scratch_len(7)];
        calc_flow::<f32>(&pa, &pa, &pts, &mut f, &cfg, Gradients::PerWindow, &mut s).unwrap();
        assert!(f.iter().all(|f| f.status == FlowStatus::OutOfBounds));
        let mut short = [0i16; 10];
        assert_eq!(
            calc_flow::<f32>(
                &pa,
                &pa,
                &pts,
                &mut f,
                &cfg,
                Gradients::PerWindow,
                &mut short
            ),
            Err(Error::BufferTooSmall("scratch"))
        );
        assert_eq!(
            calc_flow::<f32>(
                &pa,
                &pa,
                &pts[..2],
                &mut f,
                &cfg,
                Gradients::PerWindow,
                &mut s
            ),
            Err(Error::LengthMismatch)
        );
        let bad = LkConfig {
            win: 2,
            ..*cfg.config()
        };
        assert_eq!(bad.check(), Err(Error::InvalidParameter("lk.win")));
        // A flat image has no texture.
        let flat = [77u8; 64 * 48];
        let pf = Pyramid::build(ImageView::packed(&flat, w, h).unwrap(), &mut [], 1).unwrap();
        let mut g = [Flow::<f32>::default(); 1];
        calc_flow::<f32>(
            &pf,
            &pf,
            &[[30.0, 20.0]],
            &mut g,
            &cfg,
            Gradients::PerWindow,
            &mut s,
        )
        .unwrap();
        assert_eq!(g[0].status, FlowStatus::SmallEigenvalue);
    }

    #[test]
    fn forward_backward_flags_occlusion() {
        let (w, h) = (96, 72);
        let a = scene(w, h, 0.0, 0.0);
        let mut b = scene(w, h, 2.0, 1.0);
        // Paint a flat occluder over the second point in the next frame.
        for y in 40..72 {
            for x in 60..96 {
                b[y * w + x] = ((x * 37 + y * 91) % 256) as u8;
            }
        }
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let cfg = LkConfig {
            win: 11,
            max_level: 0,
            fb_threshold: Some(0.5),
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        let pts = [[30.0f32, 20.0], [78.0, 56.0]];
        let mut f = [Flow::<f32>::default(); 2];
        let mut back = [Flow::<f32>::default(); 2];
        let mut s = std::vec![0i16; scratch_len(11)];
        calc_flow::<f32>(&pa, &pb, &pts, &mut f, &cfg, Gradients::PerWindow, &mut s).unwrap();
        forward_backward::<f32>(
            &pa,
            &pb,
            &pts,
            &mut f,
            &mut back,
            &cfg,
            Gradients::PerWindow,
            &mut s,
        )
        .unwrap();
        assert_eq!(f[0].status, FlowStatus::Tracked);
        assert_ne!(f[1].status, FlowStatus::Tracked);
    }
}
