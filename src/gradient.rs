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

use crate::image::{ImageMut, ImageView};
use crate::{Error, Result};

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
    let period = 2 * (n - 1);
    let mut r = i.rem_euclid(period);
    if r >= n {
        r = period - r;
    }
    r.clamp(0, n - 1) as usize
}

/// Scharr derivatives `(Ix, Iy)` of row `y` of `img` at columns `x0 .. x0 + out.len()`
/// (all inside the image; columns beyond the width are written as zero).
pub fn scharr_row(img: &ImageView<'_, u8>, y: usize, x0: usize, out: &mut [[i16; 2]]) {
    let (w, h) = (img.width(), img.height());
    let yi = y as isize;
    let r0 = img.row_clamped(reflect101(yi - 1, h) as isize);
    let r1 = img.row_clamped(yi);
    let r2 = img.row_clamped(reflect101(yi + 1, h) as isize);
    // Vertical pass at column c: (t0, t1) = (3 (r0 + r2) + 10 r1, r2 - r0).
    let vert = |c: usize| -> (i32, i32) {
        let p = |r: &[u8]| i32::from(r.get(c).copied().unwrap_or(0));
        (3 * (p(r0) + p(r2)) + 10 * p(r1), p(r2) - p(r0))
    };
    let mut prev = vert(reflect101(x0 as isize - 1, w));
    let mut cur = vert(x0.min(w.saturating_sub(1)));
    for (k, o) in out.iter_mut().enumerate() {
        let x = x0 + k;
        if x >= w {
            *o = [0, 0];
            continue;
        }
        let next = vert(reflect101(x as isize + 1, w));
        // |dx| <= 16 * 255 and |dy| <= 16 * 255: both fit i16.
        *o = [
            (next.0 - prev.0) as i16,
            (3 * (next.1 + prev.1) + 10 * cur.1) as i16,
        ];
        prev = cur;
        cur = next;
    }
}

/// Derivatives of a whole level into `dst` (interleaved `[Ix, Iy]`, same size as `img`, else
/// [`Error::InvalidImage`]).
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
/// [`Error::InvalidParameter`] when `out` is shorter than `w h`.
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
        .ok_or(Error::InvalidParameter)?;
    if w == 0 {
        return Ok(());
    }
    let (iw, ih) = (img.width() as isize, img.height() as isize);
    // Columns of the grid that fall inside the image.
    let cx0 = x0.clamp(0, iw);
    let cx1 = (x0 + w as isize).clamp(0, iw);
    for (j, row) in out.chunks_exact_mut(w).enumerate() {
        let y = y0 + j as isize;
        if y < 0 || y >= ih || cx1 <= cx0 {
            row.fill([0, 0]);
            continue;
        }
        let lead = (cx0 - x0) as usize;
        let inner = (cx1 - cx0) as usize;
        let (left, rest) = row.split_at_mut(lead.min(w));
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
        assert_eq!(
            scharr_window(&v, 0, 0, 8, 7, &mut win),
            Err(Error::InvalidParameter)
        );
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
