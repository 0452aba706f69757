//! Gaussian image pyramids into caller-provided buffers.
//!
//! One level down is OpenCV's `pyrDown`, bit for bit: a 5x5 Gaussian `g gᵀ / 256` with
//! `g = [1 4 6 4 1]`, evaluated at every second pixel, borders reflected without repeating the
//! edge pixel (`BORDER_REFLECT_101`: `-1 → 1`, `n → n - 2`), rounded as `(Σ + 128) >> 8`:
//!
//! `out(x, y) = (Σᵢⱼ gᵢ gⱼ in(2x + i - 2, 2y + j - 2) + 128) >> 8`, size `(⌈w/2⌉, ⌈h/2⌉)`.
//!
//! [`PyramidPair`] owns the two frames and two pyramid buffers of a frame loop (the previous
//! frame's pyramid is the template of the next flow) and swaps their roles frame by frame:
//! capture into the free frame, [`PyramidPair::advance`] for both pyramids,
//! [`PyramidPair::previous_mut`] to draw on the frame that is no template any more.
//!
//! Integer only. The work runs in tiles of [`TILE`] output pixels with the vertical sums in a
//! fixed stack array, so there is no scratch to provide and no size limit beyond
//! [`crate::image::MAX_DIM`].
//!
//! ```
//! use camgeom::image::ImageView;
//! use camgeom::pyramid::{Pyramid, buffer_len, level_size};
//!
//! // A single bright pixel at (10, 10): level 1 holds the kernel, (g gᵀ 255 + 128) >> 8.
//! let mut frame = [0u8; 40 * 30];
//! frame[10 * 40 + 10] = 255;
//! let mut buf = [0u8; buffer_len(40, 30, 3)];
//! let pyr = Pyramid::build(ImageView::packed(&frame, 40, 30)?, &mut buf, 3)?;
//! let l1 = pyr.level(1).ok_or(camgeom::Error::Degenerate)?;
//! assert_eq!((l1.width(), l1.height()), (20, 15));
//! assert_eq!(l1.get(5, 5), Some(36)); // (6·6·255 + 128) >> 8
//! assert_eq!(l1.get(4, 5), Some(6)); // (1·6·255 + 128) >> 8
//! assert_eq!(l1.get(4, 4), Some(1)); // (1·1·255 + 128) >> 8
//! assert_eq!(l1.get(3, 5), Some(0));
//! let l2 = pyr.level(2).ok_or(camgeom::Error::Degenerate)?;
//! assert_eq!((l2.width(), l2.height()), level_size(40, 30, 2)); // (10, 8): sizes round up
//! # Ok::<(), camgeom::Error>(())
//! ```

mod pair;

pub use pair::{PyramidPair, Pyramids};

use core::ops::Range;

use heapless::Vec;

use crate::image::{ImageMut, ImageView};
use crate::{Error, Result};

/// The most levels a [`Pyramid`] holds, the frame itself included.
pub const MAX_LEVELS: usize = 8;

/// Output pixels per tile of the horizontal pass (stack use: `2 TILE + 4` `u16`).
pub const TILE: usize = 64;

/// Size after one reduction: `(⌈w/2⌉, ⌈h/2⌉)`.
pub const fn down_size(width: usize, height: usize) -> (usize, usize) {
    (width.div_ceil(2), height.div_ceil(2))
}

/// Size of level `level` of a `width x height` frame (level 0 is the frame).
pub const fn level_size(width: usize, height: usize, level: usize) -> (usize, usize) {
    let (mut w, mut h, mut l) = (width, height, 0);
    while l < level {
        (w, h) = down_size(w, h);
        l += 1;
    }
    (w, h)
}

/// Bytes the caller's buffer needs for a `levels`-level pyramid of a `width x height` frame
/// (levels `1..levels`, tightly packed; level 0 is the caller's frame and is not copied).
pub const fn buffer_len(width: usize, height: usize, levels: usize) -> usize {
    let (mut total, mut l) = (0, 1);
    while l < levels {
        let (w, h) = level_size(width, height, l);
        total += w * h;
        l += 1;
    }
    total
}

/// `BORDER_REFLECT_101` index into `0..n` (`n >= 1`).
#[inline]
fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let mut i = i;
    // One reflection suffices for |i| < n, which holds for taps at most 2 outside (n >= 2:
    // -2 → 2 needs n >= 3; for n = 2 the reflected index is clamped below).
    if i < 0 {
        i = -i;
    }
    if i >= n {
        i = 2 * n - 2 - i;
    }
    i.max(0).min(n - 1) as usize
}

/// One level down: `dst` must be exactly [`down_size`] of `src`, else [`Error::InvalidImage`].
///
/// Per output row, per tile of at most [`TILE`] output pixels: the vertical `[1 4 6 4 1]` sums
/// of the source columns the tile reads go to two stack arrays, the even columns to one and
/// the odd ones to the other, so that the horizontal pass is a straight-line loop over
/// contiguous `u16` lanes (no stride-2 access, no reflection). Only the at most two source
/// columns per side that fall outside the image take the reflecting slow path.
#[doc(alias = "pyrDown")]
pub fn pyr_down(src: &ImageView<'_, u8>, dst: &mut ImageMut<'_, u8>) -> Result<()> {
    pyr_down_with(src, dst, SWAR)
}

/// [`pyr_down`] with the vertical pass chosen by `swar` (both are tested on every target).
fn pyr_down_with(src: &ImageView<'_, u8>, dst: &mut ImageMut<'_, u8>, swar: bool) -> Result<()> {
    let (w, h) = (src.width(), src.height());
    if (dst.width(), dst.height()) != down_size(w, h) {
        return Err(Error::InvalidImage);
    }
    // Vertical sums of source columns `first + 2k` (`even[k]`) and `first + 2k + 1` (`odd[k]`),
    // `first = 2 x0 - 2` for a tile starting at output column `x0`.
    let mut even = [0u16; TILE + 2];
    let mut odd = [0u16; TILE + 2];
    for y in 0..dst.height() {
        let cy = 2 * y as isize;
        let rows: [&[u8]; 5] =
            core::array::from_fn(|j| src.row(reflect101(cy + j as isize - 2, h)).unwrap_or(&[]));
        let Some(out) = dst.row_mut(y) else { break };
        let mut first = -2;
        for (tile, out_tile) in out.chunks_mut(TILE).enumerate() {
            // The last two pairs of the previous (full) tile are this tile's first two.
            let start = if tile == 0 {
                0
            } else {
                even.copy_within(TILE.., 0);
                odd.copy_within(TILE.., 0);
                2
            };
            let end = out_tile.len() + 2;
            // Fast path: every column of the tile inside the image (all tiles but the row's
            // first and last), one run of pairs with no reflection.
            let c = first + 2 * start as isize;
            let cols = 2 * (end - start);
            match (even.get_mut(start..end), odd.get_mut(start..end)) {
                (Some(ev), Some(od)) if c >= 0 && c as usize + cols <= w => {
                    let c = c as usize;
                    let rows_in =
                        rows.map(|r| r.get(c..c + cols).unwrap_or(&[]).as_chunks::<2>().0);
                    pair_run(rows_in, ev, od, swar);
                }
                _ => vertical(&rows, first, start..end, w, (&mut even, &mut odd), swar),
            }
            horizontal(&even, &odd, out_tile, swar);
            first += 2 * TILE as isize;
        }
    }
    Ok(())
}

/// `[1 4 6 4 1]` down the five `rows` for the column pairs `(first + 2k, first + 2k + 1)`,
/// `k` in `pairs`, into `even[k]` and `odd[k]`.
#[inline]
fn vertical(
    rows: &[&[u8]; 5],
    first: isize,
    pairs: Range<usize>,
    w: usize,
    (even, odd): (&mut [u16; TILE + 2], &mut [u16; TILE + 2]),
    swar: bool,
) {
    let (start, end) = (pairs.start, pairs.end.min(TILE + 2));
    // Pairs `k_lo..k_hi` lie inside the image: `first + 2k >= 0` and `first + 2k + 1 < w`.
    let k_lo = ((-first).max(0) as usize).div_ceil(2).clamp(start, end);
    let k_hi = (((w as isize - first).max(0) / 2) as usize).clamp(k_lo, end);
    let c0 = (first + 2 * k_lo as isize).max(0) as usize;
    let m = k_hi - k_lo;
    let rows_in = rows.map(|r| r.get(c0..c0 + 2 * m).unwrap_or(&[]).as_chunks::<2>().0);
    let ev = even.get_mut(k_lo..k_hi).unwrap_or(&mut []);
    let od = odd.get_mut(k_lo..k_hi).unwrap_or(&mut []);
    // Whole blocks of `LANES` pairs, then the last `LANES` pairs again for the rest
    // (overlapping): the vectorised loop never falls back to its scalar tail.
    let whole = m - m % LANES;
    let (ev_w, od_w) = (prefix(ev, whole), prefix(od, whole));
    pair_run(
        rows_in.map(|r| r.get(..whole).unwrap_or(&[])),
        ev_w,
        od_w,
        swar,
    );
    if whole != m {
        let from = if whole == 0 { 0 } else { m - LANES };
        let (ev_t, od_t) = (
            ev.get_mut(from..).unwrap_or(&mut []),
            od.get_mut(from..).unwrap_or(&mut []),
        );
        pair_run(
            rows_in.map(|r| r.get(from..).unwrap_or(&[])),
            ev_t,
            od_t,
            swar,
        );
    }
    // The pairs with a column outside the image (at most two per side), reflected.
    let slow = |c: isize| {
        let c = reflect101(c, w);
        let px = |r: &[u8]| u16::from(r.get(c).copied().unwrap_or(0));
        taps(
            px(rows[0]),
            px(rows[1]),
            px(rows[2]),
            px(rows[3]),
            px(rows[4]),
        )
    };
    for k in (start..k_lo).chain(k_hi..end) {
        let c = first + 2 * k as isize;
        if let (Some(e), Some(o)) = (even.get_mut(k), odd.get_mut(k)) {
            (*e, *o) = (slow(c), slow(c + 1));
        }
    }
}

/// Column pairs per block of the vertical pass: one SSE2 register of `u16` lanes.
const LANES: usize = 8;

/// `v[..n]`, or all of `v` when shorter.
#[inline]
fn prefix(v: &mut [u16], n: usize) -> &mut [u16] {
    let n = n.min(v.len());
    v.split_at_mut(n).0
}

/// Whether the passes take two outputs' worth at a time in the 16-bit lanes of one 32-bit word
/// (the vertical [`quad_run`]: four 8-bit columns, masked into two lanes each for the even and
/// the odd ones; the horizontal pass of [`horizontal`]: two outputs) rather than one step per
/// pair for the vectoriser. On Arm: its cores load an unaligned word in one instruction (and
/// the Cortex-M4/M7/M33 split bytes into lanes with `uxtb16`), and without SIMD the words
/// took the Cortex-M7 main job's pyramid from 1.35M to 0.98M instructions a frame at
/// 320x240. Elsewhere (SIMD, or RISC-V, where a word from bytes costs ten instructions) the
/// pair loops.
const SWAR: bool = cfg!(target_arch = "arm");

/// [`pair_taps`] over a run of column pairs, by [`quad_run`] or [`lane_run`] (see [`SWAR`]).
/// Not inlined: the arrays' `noalias` tells the vectoriser that the stores never hit the rows,
/// so the loop needs no run-time overlap checks.
#[inline(never)]
fn pair_run(rows: [&[[u8; 2]]; 5], even: &mut [u16], odd: &mut [u16], swar: bool) {
    if swar {
        quad_run(rows, even, odd);
    } else {
        lane_run(rows, even, odd);
    }
}

/// One pair a step (x86-64: five 16-byte loads, `pand`/`psrlw`, `paddw`/`psllw`/`pmullw`, two
/// stores per 8 pairs).
#[inline(always)]
fn lane_run(rows: [&[[u8; 2]]; 5], even: &mut [u16], odd: &mut [u16]) {
    let [r0, r1, r2, r3, r4] = rows;
    let lanes = even
        .iter_mut()
        .zip(odd.iter_mut())
        .zip(r0)
        .zip(r1)
        .zip(r2)
        .zip(r3)
        .zip(r4);
    for ((((((e, o), p0), p1), p2), p3), p4) in lanes {
        (*e, *o) = pair_taps([p0, p1, p2, p3, p4]);
    }
}

/// Two pairs a step, in a 32-bit word per row: the even columns `w & 0x00ff00ff` and the odd
/// ones `(w >> 8) & 0x00ff00ff` each hold two columns in 16-bit lanes, and
/// `a + 4 b + 6 c + 4 d + e <= 16 · 255` cannot carry from one lane into the other; then the
/// last pair alone when the run is odd.
#[inline(always)]
fn quad_run(rows: [&[[u8; 2]]; 5], even: &mut [u16], odd: &mut [u16]) {
    let m = rows.iter().map(|r| r.len()).min().unwrap_or(0);
    let m = m.min(even.len()).min(odd.len());
    let quads = m / 2;
    let [r0, r1, r2, r3, r4] = rows.map(|r| r.get(..2 * quads).unwrap_or(&[]).as_chunks::<2>().0);
    let ev = even
        .get_mut(..2 * quads)
        .unwrap_or(&mut [])
        .as_chunks_mut::<2>()
        .0;
    let od = odd
        .get_mut(..2 * quads)
        .unwrap_or(&mut [])
        .as_chunks_mut::<2>()
        .0;
    let lanes = ev
        .iter_mut()
        .zip(od.iter_mut())
        .zip(r0)
        .zip(r1)
        .zip(r2)
        .zip(r3)
        .zip(r4);
    for ((((((e, o), p0), p1), p2), p3), p4) in lanes {
        let word = |[[a, b], [c, d]]: [[u8; 2]; 2]| u32::from_le_bytes([a, b, c, d]);
        let w = [p0, p1, p2, p3, p4].map(|p| word(*p));
        let sum = |[a, b, c, d, e]: [u32; 5]| a + e + 4 * (b + d) + 6 * c;
        let lo = sum(w.map(|x| x & 0x00ff_00ff));
        let hi = sum(w.map(|x| (x >> 8) & 0x00ff_00ff));
        *e = [lo as u16, (lo >> 16) as u16];
        *o = [hi as u16, (hi >> 16) as u16];
    }
    if m % 2 == 1 {
        let k = m - 1;
        let p = rows.map(|r| r.get(k).unwrap_or(&[0, 0]));
        if let (Some(e), Some(o)) = (even.get_mut(k), odd.get_mut(k)) {
            (*e, *o) = pair_taps(p);
        }
    }
}

/// `[1 4 6 4 1]` down one column pair of the five rows: `(even column, odd column)`.
#[inline(always)]
fn pair_taps(p: [&[u8; 2]; 5]) -> (u16, u16) {
    // A column pair as one 16-bit lane, its even column the low byte: the vectoriser makes
    // this a load, `pand` and `psrlw` (SSE2), where two byte loads at stride 2 would not be
    // vectorised at all; targets without fast unaligned loads get two byte loads back.
    let [a, b, c, d, e] = p.map(|p| u16::from_le_bytes(*p));
    (
        taps(a & 0xff, b & 0xff, c & 0xff, d & 0xff, e & 0xff),
        taps(a >> 8, b >> 8, c >> 8, d >> 8, e >> 8),
    )
}

/// `out[i] = (even[i] + 4 odd[i] + 6 even[i + 1] + 4 odd[i + 1] + even[i + 2] + 128) >> 8`,
/// two outputs a step in the 16-bit lanes of a 32-bit word when `swar` (see [`SWAR`]; a lane
/// holds at most `256 · 255 + 128 < 2¹⁶`, so neither carries into the other).
#[inline]
fn horizontal(even: &[u16; TILE + 2], odd: &[u16; TILE + 2], out: &mut [u8], swar: bool) {
    let n = out.len().min(TILE);
    fn part(v: &[u16; TILE + 2], k: usize, n: usize) -> &[u16] {
        v.get(k..k + n).unwrap_or(&[])
    }
    let done = if swar {
        let pairs = n / 2;
        fn words(v: &[u16; TILE + 2], k: usize, n: usize) -> impl Iterator<Item = u32> + '_ {
            part(v, k, n)
                .as_chunks::<2>()
                .0
                .iter()
                .map(|&[a, b]| u32::from(a) | (u32::from(b) << 16))
        }
        let words = |v, k| words(v, k, 2 * pairs);
        let outs = out
            .get_mut(..2 * pairs)
            .unwrap_or(&mut [])
            .as_chunks_mut::<2>()
            .0;
        let taps = words(even, 0)
            .zip(words(odd, 0))
            .zip(words(even, 1))
            .zip(words(odd, 1))
            .zip(words(even, 2));
        for (o, ((((a, b), c), d), e)) in outs.iter_mut().zip(taps) {
            let sum = a + e + 4 * (b + d) + 6 * c + 0x0080_0080;
            *o = [(sum >> 8) as u8, (sum >> 24) as u8];
        }
        2 * pairs
    } else {
        0
    };
    let (e0, e1, e2) = (
        part(even, done, n - done),
        part(even, done + 1, n - done),
        part(even, done + 2, n - done),
    );
    let (o0, o1) = (part(odd, done, n - done), part(odd, done + 1, n - done));
    let rest = out.get_mut(done..n).unwrap_or(&mut []);
    for (((((o, &a), &b), &c), &d), &e) in rest.iter_mut().zip(e0).zip(o0).zip(e1).zip(o1).zip(e2) {
        // <= 256 * 255 + 128 < 2^16: u16 lanes, and the quotient fits u8.
        *o = ((taps(a, b, c, d, e) + 128) >> 8) as u8;
    }
}

/// `a + 4 b + 6 c + 4 d + e` (`<= 256 * 255` for the sums of sums here, so no overflow).
#[inline(always)]
fn taps(a: u16, b: u16, c: u16, d: u16, e: u16) -> u16 {
    a + e + 4 * (b + d) + 6 * c
}

/// A Gaussian pyramid: level 0 is the caller's frame, levels `1..` live in the caller's buffer.
#[derive(Debug, Clone)]
pub struct Pyramid<'a> {
    levels: Vec<ImageView<'a, u8>, MAX_LEVELS>,
}

impl<'a> Pyramid<'a> {
    /// Builds `levels` levels (1 to [`MAX_LEVELS`]) of `frame` into `buf`, which must hold at
    /// least [`buffer_len`] bytes. Errors: [`Error::InvalidParameter`] for a level count out of
    /// range, [`Error::InvalidImage`] when the buffer is too short.
    ///
    /// Never inlined: its tile buffers then live on the stack only while it runs, not under
    /// every later stage of a frame loop that calls it.
    #[inline(never)]
    #[doc(alias = "buildPyramid")]
    #[doc(alias = "buildOpticalFlowPyramid")]
    pub fn build(frame: ImageView<'a, u8>, buf: &'a mut [u8], levels: usize) -> Result<Self> {
        if levels == 0 || levels > MAX_LEVELS {
            return Err(Error::InvalidParameter("levels"));
        }
        if buf.len() < buffer_len(frame.width(), frame.height(), levels) {
            return Err(Error::InvalidImage);
        }
        let mut out = Vec::new();
        out.push(frame)
            .map_err(|_| Error::InvalidParameter("levels"))?;
        let mut prev = frame;
        let mut rest = buf;
        for _ in 1..levels {
            let (w, h) = down_size(prev.width(), prev.height());
            let (cur, tail) = rest
                .split_at_mut_checked(w * h)
                .ok_or(Error::InvalidImage)?;
            let mut dst = ImageMut::packed(cur, w, h)?;
            pyr_down(&prev, &mut dst)?;
            let done: &'a [u8] = cur;
            prev = ImageView::packed(done, w, h)?;
            out.push(prev)
                .map_err(|_| Error::InvalidParameter("levels"))?;
            rest = tail;
        }
        Ok(Self { levels: out })
    }

    /// Re-wraps a pyramid already built into `buf` by [`Pyramid::build`] with the same frame
    /// geometry and level count, without computing anything (for keeping the previous frame's
    /// pyramid while the next one is built into another buffer). Same errors as
    /// [`Pyramid::build`].
    pub fn from_buffer(frame: ImageView<'a, u8>, buf: &'a [u8], levels: usize) -> Result<Self> {
        if levels == 0 || levels > MAX_LEVELS {
            return Err(Error::InvalidParameter("levels"));
        }
        if buf.len() < buffer_len(frame.width(), frame.height(), levels) {
            return Err(Error::InvalidImage);
        }
        let mut out = Vec::new();
        out.push(frame)
            .map_err(|_| Error::InvalidParameter("levels"))?;
        let (mut w, mut h) = (frame.width(), frame.height());
        let mut rest = buf;
        for _ in 1..levels {
            (w, h) = down_size(w, h);
            let (cur, tail) = rest.split_at_checked(w * h).ok_or(Error::InvalidImage)?;
            out.push(ImageView::packed(cur, w, h)?)
                .map_err(|_| Error::InvalidParameter("levels"))?;
            rest = tail;
        }
        Ok(Self { levels: out })
    }

    /// Number of levels.
    pub fn len(&self) -> usize {
        self.levels.len()
    }

    /// Always `false`: a pyramid has at least its base level.
    pub fn is_empty(&self) -> bool {
        self.levels.is_empty()
    }

    /// Level `l` (0 = the frame), `None` beyond the last.
    pub fn level(&self, l: usize) -> Option<ImageView<'a, u8>> {
        self.levels.get(l).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Straight 5x5 evaluation of the definition, independent of the tiled code.
    fn reference(src: &[u8], w: usize, h: usize) -> std::vec::Vec<u8> {
        let g = [1u32, 4, 6, 4, 1];
        let (ow, oh) = down_size(w, h);
        let refl = |i: isize, n: usize| -> usize {
            let n = n as isize;
            if n == 1 {
                return 0;
            }
            let r = i.abs();
            let r = if r >= n { 2 * n - 2 - r } else { r };
            r.max(0).min(n - 1) as usize
        };
        let mut out = std::vec![0u8; ow * oh];
        for y in 0..oh {
            for x in 0..ow {
                let mut s = 0u32;
                for j in 0..5 {
                    for i in 0..5 {
                        let sx = refl(2 * x as isize + i as isize - 2, w);
                        let sy = refl(2 * y as isize + j as isize - 2, h);
                        s += g[i] * g[j] * src[sy * w + sx] as u32;
                    }
                }
                out[y * ow + x] = ((s + 128) >> 8) as u8;
            }
        }
        out
    }

    #[test]
    fn matches_direct_definition_on_odd_and_tiny_sizes() {
        let mut seed = 12345u32;
        for &(w, h) in &[
            (1, 1),
            (2, 1),
            (1, 2),
            (2, 2),
            (3, 3),
            (5, 7),
            (17, 9),
            (131, 67),
            (320, 240),
        ] {
            check_random(w, h, &mut seed);
        }
    }

    /// `pyr_down` of a `w x h` frame of pseudo-random pixels (an LCG from `seed`) equals the
    /// direct 5x5 definition.
    fn check_random(w: usize, h: usize, seed: &mut u32) {
        let src: std::vec::Vec<u8> = (0..w * h)
            .map(|_| {
                *seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (*seed >> 24) as u8
            })
            .collect();
        let (ow, oh) = down_size(w, h);
        let mut dst = std::vec![0u8; ow * oh];
        let view = ImageView::packed(&src, w, h).unwrap();
        // Both vertical passes (the word-at-a-time one of the Arm targets and the pair loop).
        for swar in [false, true] {
            dst.fill(0);
            pyr_down_with(
                &view,
                &mut ImageMut::packed(&mut dst, ow, oh).unwrap(),
                swar,
            )
            .unwrap();
            assert_eq!(dst, reference(&src, w, h), "{w}x{h} swar {swar}");
        }
    }

    #[test]
    fn matches_direct_definition_at_tile_and_block_edges() {
        // Widths around the tile size (full and partial last tiles, carried pairs), around the
        // vectorised block size (whole, overlapping and scalar runs) and odd/even.
        let mut seed = 777u32;
        let widths = (1..=40)
            .chain((2 * TILE - 4)..=(2 * TILE + 5))
            .chain([4 * TILE + 1, 4 * TILE + 18]);
        for w in widths {
            for h in [1, 2, 5, 6] {
                check_random(w, h, &mut seed);
            }
        }
    }

    #[test]
    fn pyramid_levels_and_sizes() {
        let src = [200u8; 320 * 240];
        let mut buf = [0u8; buffer_len(320, 240, 4)];
        assert_eq!(buf.len(), 160 * 120 + 80 * 60 + 40 * 30);
        let p = Pyramid::build(ImageView::packed(&src, 320, 240).unwrap(), &mut buf, 4).unwrap();
        assert_eq!(p.len(), 4);
        let l3 = p.level(3).unwrap();
        assert_eq!((l3.width(), l3.height()), (40, 30));
        // A constant image stays constant at every level (the kernel sums to 256).
        assert!(l3.rows().all(|r| r.iter().all(|&v| v == 200)));
        assert!(p.level(4).is_none());
        drop(p);
        let q = Pyramid::from_buffer(ImageView::packed(&src, 320, 240).unwrap(), &buf, 4).unwrap();
        assert_eq!(q.level(3).unwrap().get(5, 5), Some(200));
        assert_eq!(
            Pyramid::from_buffer(ImageView::packed(&src, 320, 240).unwrap(), &buf[..10], 4).err(),
            Some(Error::InvalidImage)
        );
        assert_eq!(level_size(641, 481, 2), (161, 121));
    }

    #[test]
    fn bad_sizes_are_errors() {
        let src = [0u8; 64];
        let v = ImageView::packed(&src, 8, 8).unwrap();
        let mut small = [0u8; 10];
        assert_eq!(
            Pyramid::build(v, &mut small, 3).err(),
            Some(Error::InvalidImage)
        );
        let mut buf = [0u8; 64];
        assert_eq!(
            Pyramid::build(v, &mut buf, 0).err(),
            Some(Error::InvalidParameter("levels"))
        );
        assert_eq!(
            Pyramid::build(v, &mut buf, MAX_LEVELS + 1).err(),
            Some(Error::InvalidParameter("levels"))
        );
        let mut d = [0u8; 25];
        let mut wrong = ImageMut::packed(&mut d, 5, 5).unwrap();
        assert_eq!(pyr_down(&v, &mut wrong), Err(Error::InvalidImage));
    }
}
