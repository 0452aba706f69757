//! Scharr image derivatives in `i16`, exactly as OpenCV's optical flow computes them.
//!
//! `Ix = S ⋆ I`, `Iy = Sᵀ ⋆ I` with `S = [3 10 3]ᵀ [-1 0 1]` (no normalisation, so
//! `Ix ≈ 32 ∂I/∂x` and `|Ix| ≤ 16 · 255 = 4080` fits `i16`). Image borders are reflected
//! without repeating the edge pixel (`BORDER_REFLECT_101`), as OpenCV's `calcSharrDeriv`.
//! Outside the image the derivative is zero (OpenCV pads its derivative images with zeros).
//!
//! Two ways to feed the tracker, with the same numbers:
//!
//! * per level ([`scharr_level`]): one pass over a whole pyramid level into a caller buffer of
//!   `2 w h` `i16` — 300 KB for 320x240, too much next to the frames on a 512 KB board, and most
//!   of it is never read when only a few hundred windows are tracked;
//! * per window ([`scharr_window`]): only the `(win + 1)²` pixels a tracked window reads, into a
//!   few KB of scratch. Each window costs `(win + 1)²` derivative evaluations, so this is cheaper
//!   than a whole level as long as `N (win + 1)² < w h` (for 21x21 windows on 320x240: fewer
//!   than ~160 features per level). The board default.
//!
//! [`crate::klt::Gradients::Auto`] takes whichever is cheaper level by level (with a buffer for
//! the levels it computes whole: the coarse ones, usually).
//!
//! ```
//! use camgeom::gradient::scharr_level;
//! use camgeom::image::{ImageMut, ImageView};
//!
//! // The ramp I = 3x + 2y: ∂I/∂x = 3, ∂I/∂y = 2, so (Ix, Iy) = 32 (3, 2) = (96, 64).
//! let (w, h) = (16, 12);
//! let mut img = [0u8; 16 * 12];
//! for (i, p) in img.iter_mut().enumerate() {
//!     *p = (3 * (i % w) + 2 * (i / w)) as u8;
//! }
//! let mut d = [[0i16; 2]; 16 * 12];
//! scharr_level(&ImageView::packed(&img, w, h)?, &mut ImageMut::packed(&mut d, w, h)?)?;
//! for y in 1..h - 1 {
//!     for x in 1..w - 1 {
//!         assert_eq!(d[y * w + x], [96, 64]);
//!     }
//! }
//! // The border reflects (-1 → 1): the first column sees no x slope.
//! assert_eq!(d[5 * w], [0, 64]);
//! # Ok::<(), camgeom::Error>(())
//! ```

use crate::image::{ImageMut, ImageView};
use crate::simd::{interleave, low};
use crate::{Error, Result};
use wide::i16x8;

/// `BORDER_REFLECT_101` index into `0..n` for any `i` (`n >= 1`): `-1 → 1`, `n → n - 2`.
#[inline]
pub(crate) fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if i >= 0 && i < n {
        return i as usize;
    }
    if n <= 1 {
        return 0;
    }
    // Within one image width of it, the period's fold without a division.
    if i < 0 && -i < n {
        return (-i) as usize;
    }
    if i >= n && i < 2 * n - 1 {
        return (2 * n - 2 - i) as usize;
    }
    let period = 2 * (n - 1);
    let mut r = i.rem_euclid(period);
    if r >= n {
        r = period - r;
    }
    r.max(0).min(n - 1) as usize
}

/// Scharr derivatives `(Ix, Iy)` of row `y` of `img` at columns `x0 .. x0 + out.len()`
/// (all inside the image; columns beyond the width are written as zero).
pub fn scharr_row(img: &ImageView<'_, u8>, y: usize, x0: usize, out: &mut [[i16; 2]]) {
    let (w, h) = (img.width(), img.height());
    let yi = y as isize;
    let r0 = img.row_clamped(reflect101(yi - 1, h) as isize);
    let r1 = img.row_clamped(yi);
    let r2 = img.row_clamped(reflect101(yi + 1, h) as isize);
    // Columns at or beyond the width are zero.
    let valid = w.saturating_sub(x0).min(out.len());
    let (vals, beyond) = out.split_at_mut(valid.min(out.len()));
    beyond.fill([0, 0]);
    // The first and last image columns, whose two neighbours reflect to one column `n`
    // (`x ± 1` to column 1 at `x = 0`, to `w - 2` at `x = w - 1`; the column itself when
    // `w = 1`): `Ix = 0` and `Iy = 6 d(n) + 10 d(x)`, `d = r2 - r0`.
    let edge = |x: usize| -> [i16; 2] {
        let n = reflect101(x as isize + 1, w);
        let d = |c: usize| {
            let p = |r: &[u8]| i32::from(r.get(c).copied().unwrap_or(0));
            p(r2) - p(r0)
        };
        // |Iy| <= 16 * 255: fits i16.
        [0, (6 * d(n) + 10 * d(x)) as i16]
    };
    // Interior columns `lo .. hi` (within 1 .. w - 1) by the sliding loop; at most the first
    // and the last image column reflect.
    let lo = x0.max(1).min(x0 + valid);
    let hi = (x0 + valid).min(w.saturating_sub(1)).max(lo);
    let (head, rest) = vals.split_at_mut((lo - x0).min(vals.len()));
    let (inner, tail) = rest.split_at_mut((hi - lo).min(rest.len()));
    for (k, o) in head.iter_mut().enumerate() {
        *o = edge(x0 + k);
    }
    for (k, o) in tail.iter_mut().enumerate() {
        *o = edge(hi + k);
    }
    scharr_interior(r0, r1, r2, lo - 1, inner);
}

/// Scharr derivatives at columns `start + 1 .. start + 1 + out.len()` of the rows `r0`
/// (above), `r1`, `r2` (below), every tap inside the rows.
///
/// Separable: each column `x` is reduced once to its vertical smoothing
/// `s(x) = 3 r0 + 10 r1 + 3 r2` and difference `d(x) = r2 - r0`; then
/// `Ix(x) = s(x + 1) - s(x - 1)` and `Iy(x) = 3 d(x - 1) + 10 d(x) + 3 d(x + 1)`. The sliding
/// loop carries two columns, so a pixel costs three loads (the 3x3 form read eight).
///
/// A column is one word, `v = 2¹⁶ s + d` (`0 <= s <= 16 · 255`, `|d| <= 255`), so the loop
/// carries two values instead of four: `v(x + 1) - v(x - 1) + 2¹⁵` is
/// `2¹⁶ Ix + (d(x + 1) - d(x - 1) + 2¹⁵)` with the second term in `0 .. 2¹⁶`, so its
/// arithmetic shift by 16 is `Ix`; `3 (v(x - 1) + v(x + 1)) + 10 v(x)` is `Iy` plus a multiple
/// of `2¹⁶` (wrapping), and `|Iy| <= 16 · 255` is its low half.
///
/// On targets with 128-bit SIMD ([`crate::SIMD`]) eight columns go at a time ([`scharr8`])
/// and the sliding loop takes the last few.
fn scharr_interior(r0: &[u8], r1: &[u8], r2: &[u8], start: usize, out: &mut [[i16; 2]]) {
    let done = if crate::SIMD {
        scharr_interior_lanes(r0, r1, r2, start, out)
    } else {
        0
    };
    let (start, Some(out)) = (start + done, out.get_mut(done..)) else {
        return;
    };
    // Column x + 1 of every output x: the loop's one new column a step.
    let ahead = start + 2..start + 2 + out.len();
    let (Some(a2), Some(b2), Some(c2)) =
        (r0.get(ahead.clone()), r1.get(ahead.clone()), r2.get(ahead))
    else {
        return;
    };
    let column = |a: u8, b: u8, c: u8| {
        let (a, b, c) = (i32::from(a), i32::from(b), i32::from(c));
        ((3 * (a + c) + 10 * b) << 16) + (c - a)
    };
    let at = |k: usize| {
        let [a, b, c] = [r0, r1, r2].map(|r| r.get(start + k).copied().unwrap_or(0));
        column(a, b, c)
    };
    let (mut v0, mut v1) = (at(0), at(1));
    for (o, ((&a, &b), &c)) in out.iter_mut().zip(a2.iter().zip(b2).zip(c2)) {
        let v2 = column(a, b, c);
        let ix = (v2 - v0 + (1 << 15)) >> 16;
        let iy = (3 * (v0 + v2)).wrapping_add(v1.wrapping_mul(10));
        // |Ix| <= 16 · 255 and |Iy| <= 16 · 255: both fit i16 (`Iy` is the low half).
        *o = [ix as i16, iy as i16];
        (v0, v1) = (v1, v2);
    }
}

/// [`scharr_interior`] eight columns a step while every tap is inside the rows; returns the
/// columns done (a multiple of eight).
fn scharr_interior_lanes(
    r0: &[u8],
    r1: &[u8],
    r2: &[u8],
    start: usize,
    out: &mut [[i16; 2]],
) -> usize {
    let (chunks, _) = out.as_chunks_mut::<8>();
    let mut done = 0;
    for o in chunks {
        let at = start + done;
        let taps = [r0, r1, r2].map(|r| r.get(at..).and_then(|t| t.first_chunk::<10>()));
        let [Some(a), Some(b), Some(c)] = taps else {
            break;
        };
        *o = scharr8(a, b, c);
        done += 8;
    }
    done
}

/// The Scharr derivatives of eight columns from ten bytes of each of the rows above (`a`),
/// at (`b`) and below (`c`), the columns and one either side: `Ix = 3 (a₊ - a₋) +
/// 10 (b₊ - b₋) + 3 (c₊ - c₋)`, `Iy = 3 (c₋ - a₋) + 10 (c - a) + 3 (c₊ - a₊)`; at most
/// `16 · 255` in magnitude, so `i16` lanes hold every step. As `[Ix, Iy]` pairs (the two
/// vectors interleaved).
#[inline(always)]
pub(crate) fn scharr8(a: &[u8; 10], b: &[u8; 10], c: &[u8; 10]) -> [[i16; 2]; 8] {
    let widen = |h: Option<&[u8; 8]>| h.map_or(i16x8::ZERO, |h| i16x8::from_u8x16_low(low(h)));
    // Columns `x - 1`, `x`, `x + 1` of the eight outputs.
    let three = |t: &[u8; 10]| {
        let mid = t.first_chunk::<9>().and_then(|m| m.last_chunk::<8>());
        [
            widen(t.first_chunk::<8>()),
            widen(mid),
            widen(t.last_chunk::<8>()),
        ]
    };
    let ([a0, a1, a2], [b0, _, b2], [c0, c1, c2]) = (three(a), three(b), three(c));
    let (k3, k10) = (i16x8::splat(3), i16x8::splat(10));
    let ix = k3 * (a2 - a0 + c2 - c0) + k10 * (b2 - b0);
    let iy = k3 * (c0 - a0 + c2 - a2) + k10 * (c1 - a1);
    let (lo, hi) = interleave(ix, iy);
    bytemuck::cast([lo.to_array(), hi.to_array()])
}

/// Derivatives of a whole level into `dst` (interleaved `[Ix, Iy]`, same size as `img`, else
/// [`Error::InvalidImage`]).
#[doc(alias = "Scharr")]
#[doc(alias = "spatialGradient")]
pub fn scharr_level(img: &ImageView<'_, u8>, dst: &mut ImageMut<'_, [i16; 2]>) -> Result<()> {
    if (dst.width(), dst.height()) != (img.width(), img.height()) {
        return Err(Error::InvalidImage);
    }
    for y in 0..img.height() {
        if let Some(row) = dst.row_mut(y) {
            scharr_row(img, y, 0, row);
        }
    }
    Ok(())
}

/// Derivatives on the `w x h` grid of integer pixels starting at `(x0, y0)` (which may stick
/// out of the image: those pixels get `[0, 0]`), row-major into `out[.. w h]`.
/// [`Error::BufferTooSmall`]`("out")` when `out` is shorter than `w h`.
pub fn scharr_window(
    img: &ImageView<'_, u8>,
    x0: isize,
    y0: isize,
    w: usize,
    h: usize,
    out: &mut [[i16; 2]],
) -> Result<()> {
    let out = out
        .get_mut(..w.saturating_mul(h))
        .ok_or(Error::BufferTooSmall("out"))?;
    if w == 0 {
        return Ok(());
    }
    let (iw, ih) = (img.width() as isize, img.height() as isize);
    // The common case (a tracking window away from the border): every 3x3 neighbourhood
    // inside the image, so no row or column reflects and each row is one sliding pass.
    if x0 >= 1 && y0 >= 1 && x0 + (w as isize) < iw && y0 + (h as isize) < ih {
        let (x0, y0) = (x0 as usize, y0 as usize);
        for (j, row) in out.chunks_exact_mut(w).enumerate() {
            let y = y0 + j;
            if let (Some(r0), Some(r1), Some(r2)) = (img.row(y - 1), img.row(y), img.row(y + 1)) {
                scharr_interior(r0, r1, r2, x0 - 1, row);
            }
        }
        return Ok(());
    }
    // Columns of the grid that fall inside the image.
    let cx0 = x0.max(0).min(iw);
    let cx1 = (x0 + w as isize).max(0).min(iw);
    for (j, row) in out.chunks_exact_mut(w.max(1)).enumerate() {
        let y = y0 + j as isize;
        if y < 0 || y >= ih || cx1 <= cx0 {
            row.fill([0, 0]);
            continue;
        }
        let lead = (cx0 - x0) as usize;
        let inner = (cx1 - cx0) as usize;
        let (left, rest) = row.split_at_mut(lead.min(row.len()));
        left.fill([0, 0]);
        let (mid, right) = rest.split_at_mut(inner.min(rest.len()));
        scharr_row(img, y as usize, cx0 as usize, mid);
        right.fill([0, 0]);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn direct(img: &[u8], w: usize, h: usize, x: usize, y: usize) -> [i16; 2] {
        let p = |xx: isize, yy: isize| i32::from(img[reflect101(yy, h) * w + reflect101(xx, w)]);
        let (x, y) = (x as isize, y as isize);
        let dx = 3 * (p(x + 1, y - 1) - p(x - 1, y - 1))
            + 10 * (p(x + 1, y) - p(x - 1, y))
            + 3 * (p(x + 1, y + 1) - p(x - 1, y + 1));
        let dy = 3 * (p(x - 1, y + 1) - p(x - 1, y - 1))
            + 10 * (p(x, y + 1) - p(x, y - 1))
            + 3 * (p(x + 1, y + 1) - p(x + 1, y - 1));
        [dx as i16, dy as i16]
    }

    #[test]
    fn reflect() {
        assert_eq!(reflect101(-1, 5), 1);
        assert_eq!(reflect101(5, 5), 3);
        assert_eq!(reflect101(-6, 5), 2);
        assert_eq!(reflect101(9, 5), 1);
        assert_eq!(reflect101(3, 1), 0);
    }

    /// Narrow windows (the sliding interior loop starts with two carried columns) at every
    /// column, against the 3x3 definition.
    #[test]
    fn narrow_windows_agree_with_the_definition() {
        let (w, h) = (9usize, 5usize);
        let img: std::vec::Vec<u8> = (0..w * h).map(|i| (i * 97 % 251) as u8).collect();
        let v = ImageView::packed(&img, w, h).unwrap();
        for width in 1..=4usize {
            for x0 in 0..=w - width {
                let mut win = [[0i16; 2]; 4 * 2];
                scharr_window(&v, x0 as isize, 2, width, 2, &mut win).unwrap();
                for j in 0..2 {
                    for i in 0..width {
                        let got = win[j * width + i];
                        assert_eq!(got, direct(&img, w, h, x0 + i, 2 + j), "{width} {x0} {i}");
                    }
                }
            }
        }
    }

    #[test]
    fn level_window_and_direct_agree() {
        let (w, h) = (23usize, 17usize);
        let mut s = 7u32;
        let img: std::vec::Vec<u8> = (0..w * h)
            .map(|_| {
                s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (s >> 23) as u8
            })
            .collect();
        let v = ImageView::packed(&img, w, h).unwrap();
        let mut lvl = std::vec![[0i16; 2]; w * h];
        scharr_level(&v, &mut ImageMut::packed(&mut lvl, w, h).unwrap()).unwrap();
        for y in 0..h {
            for x in 0..w {
                assert_eq!(lvl[y * w + x], direct(&img, w, h, x, y), "{x},{y}");
            }
        }
        let mut win = [[0i16; 2]; 8 * 6];
        scharr_window(&v, -3, 13, 8, 6, &mut win).unwrap();
        for j in 0..6isize {
            for i in 0..8isize {
                let (x, y) = (i - 3, j + 13);
                let want = if x < 0 || y >= h as isize {
                    [0, 0]
                } else {
                    lvl[y as usize * w + x as usize]
                };
                assert_eq!(win[(j * 8 + i) as usize], want);
            }
        }
        // Across the right and bottom edges: the last column reflects, beyond it is zero.
        scharr_window(&v, 18, 12, 8, 6, &mut win).unwrap();
        for j in 0..6usize {
            for i in 0..8usize {
                let (x, y) = (18 + i, 12 + j);
                let want = if x >= w || y >= h {
                    [0, 0]
                } else {
                    lvl[y * w + x]
                };
                assert_eq!(win[j * 8 + i], want, "{x},{y}");
            }
        }
        assert_eq!(
            scharr_window(&v, 0, 0, 8, 7, &mut win),
            Err(Error::BufferTooSmall("out"))
        );
    }

    /// Images one to three pixels wide and high (the first and last columns reflect onto
    /// one neighbour, or onto themselves): the level against the 3x3 definition.
    #[test]
    fn tiny_images_agree_with_the_definition() {
        for (w, h) in (1..=3usize).flat_map(|w| (1..=3usize).map(move |h| (w, h))) {
            let img: std::vec::Vec<u8> = (0..w * h).map(|i| (i * 97 % 251) as u8).collect();
            let v = ImageView::packed(&img, w, h).unwrap();
            let mut lvl = std::vec![[0i16; 2]; w * h];
            scharr_level(&v, &mut ImageMut::packed(&mut lvl, w, h).unwrap()).unwrap();
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        lvl[y * w + x],
                        direct(&img, w, h, x, y),
                        "{w}x{h} at {x},{y}"
                    );
                }
            }
        }
    }

    /// Rows of every width up to 40 and every span within them (the vector form takes eight
    /// columns a step, the sliding loop the rest; the split moves with the span), on pixels
    /// that are mostly 0 or 255 (the largest derivatives), against the 3x3 definition.
    #[test]
    fn every_span_agrees_with_the_definition() {
        let mut s = 11u32;
        for w in 1..=40usize {
            let h = 3;
            let img: std::vec::Vec<u8> = (0..w * h)
                .map(|_| {
                    s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
                    match s >> 29 {
                        0..=2 => 0,
                        3..=5 => 255,
                        _ => (s >> 21) as u8,
                    }
                })
                .collect();
            let v = ImageView::packed(&img, w, h).unwrap();
            let mut row = std::vec![[0i16; 2]; w];
            for x0 in 0..w {
                for len in 1..=w - x0 {
                    scharr_row(&v, 1, x0, &mut row[..len]);
                    for (i, &got) in row[..len].iter().enumerate() {
                        assert_eq!(got, direct(&img, w, h, x0 + i, 1), "w {w}, x0 {x0}, {i}");
                    }
                }
            }
        }
    }

    #[test]
    fn extreme_step_fits_i16() {
        let mut img = [0u8; 9 * 9];
        for (i, p) in img.iter_mut().enumerate() {
            if i % 9 >= 4 {
                *p = 255;
            }
        }
        let v = ImageView::packed(&img, 9, 9).unwrap();
        let mut row = [[0i16; 2]; 9];
        scharr_row(&v, 4, 0, &mut row);
        assert_eq!(row[4], [4080, 0]);
    }
}
