//! The blocks of pixels and derivatives a window reads: copied out reflected ([`fetch_patch`],
//! [`cached_patch`]) or zero-filled ([`fetch_grad`]) where the block leaves the level, read in
//! place otherwise ([`block_rows`]), and walked as rows ([`Rows`]) or as a column of taps
//! ([`Column`]).

use crate::gradient::reflect101;
use crate::image::ImageView;

/// Copies the `cols x rows` pixels at `(x0, y0)` of `img` into `out` (row-major), reflecting
/// outside the image. When no column reaches past the first reflection (the block is less
/// than an image width beyond either edge), each row is three straight copies: the columns
/// left of the image (backwards from column `-x0`), those inside, and those right of it
/// (backwards from column `2w - 2 - x0 - hi`); otherwise every pixel is reflected on its own.
/// Never inlined: a copy made once a template, or once a new integer corner, is not worth its
/// register pressure inside the kernels' loops' functions.
#[inline(never)]
pub(super) fn fetch_patch<T: Copy + From<u8>>(
    img: &ImageView<'_, u8>,
    (x0, y0): (i32, i32),
    cols: usize,
    rows: usize,
    out: &mut [T],
) {
    let (width, height) = (img.width(), img.height());
    // Columns `lo .. hi` of the patch lie inside the image: its columns `span`.
    let (inner, span) = inside_span(img, x0, cols);
    let (lo, hi) = (inner.start, inner.end);
    // The reflected columns' sources, when each is within the first reflection: column
    // `x < 0` is `-x`, column `x >= w` is `2w - 2 - x`, so the head (`x0 .. x0 + lo`) reads
    // `-x0 - lo + 1 ..= -x0` backwards and the tail (`x0 + hi .. x0 + cols`) reads
    // `2w - 1 - x0 - cols ..= 2w - 2 - x0 - hi` backwards.
    let (w, x, n, l, h) = (
        width as i64,
        i64::from(x0),
        cols as i64,
        lo as i64,
        hi as i64,
    );
    let range = |a: i64, b: i64| (a >= 0 && b < w).then(|| a as usize..(b + 1) as usize);
    let left = if lo > 0 {
        range(-x - l + 1, -x)
    } else {
        Some(0..0)
    };
    let right = if hi < cols {
        range(2 * w - 1 - x - n, 2 * w - 2 - x - h)
    } else {
        Some(0..0)
    };
    let folds = left.zip(right);
    let rows_out = out.chunks_exact_mut(cols.max(1)).take(rows);
    for (j, row) in rows_out.enumerate() {
        let src = img.row_clamped(reflect101(y0 as isize + j as isize, height) as isize);
        let sides = folds.as_ref().and_then(|(left, right)| {
            let mid = src.get(span.clone())?;
            Some((src.get(left.clone())?, mid, src.get(right.clone())?))
        });
        match sides {
            Some((left, mid, right)) => {
                let (o_head, rest) = row.split_at_mut(lo.min(row.len()));
                let (o_mid, o_tail) = rest.split_at_mut((hi - lo).min(rest.len()));
                for (o, &p) in o_head.iter_mut().zip(left.iter().rev()) {
                    *o = T::from(p);
                }
                for (o, &p) in o_mid.iter_mut().zip(mid) {
                    *o = T::from(p);
                }
                for (o, &p) in o_tail.iter_mut().zip(right.iter().rev()) {
                    *o = T::from(p);
                }
            }
            None => {
                for (i, o) in row.iter_mut().enumerate() {
                    let x = reflect101(x0 as isize + i as isize, width);
                    *o = T::from(src.get(x).copied().unwrap_or(0));
                }
            }
        }
    }
}

/// Copies the `cols x rows` derivatives at `(x0, y0)` of a precomputed level into `grad`,
/// zero outside: each row's span inside the level in one copy. Both kernels' copy.
pub(super) fn fetch_grad(
    g: &ImageView<'_, [i16; 2]>,
    (x0, y0): (i32, i32),
    cols: usize,
    rows: usize,
    grad: &mut [[i16; 2]],
) {
    let (inner, span) = inside_span(g, x0, cols);
    for (j, row) in grad.chunks_exact_mut(cols.max(1)).take(rows).enumerate() {
        let seg = grad_row(g, y0, j, span.clone()).unwrap_or(&[]);
        // Zero left of the span, the span, zero right of it (the fills only where there is
        // something to zero: each is a `memset` call).
        let (lo, hi) = (inner.start, inner.start + seg.len());
        let (head, rest) = row.split_at_mut(lo.min(row.len()));
        let (mid, tail) = rest.split_at_mut((hi - lo).min(rest.len()));
        for (m, &d) in mid.iter_mut().zip(seg) {
            *m = d;
        }
        for part in [head, tail] {
            if !part.is_empty() {
                part.fill([0; 2]);
            }
        }
    }
}

/// The columns of a `cols`-wide block at column `x0` of `g` that lie inside it: as columns of
/// the block, and as columns of `g` (equally long; empty when none).
fn inside_span<P: Copy>(
    g: &ImageView<'_, P>,
    x0: i32,
    cols: usize,
) -> (core::ops::Range<usize>, core::ops::Range<usize>) {
    let (w, x0) = (g.width() as i64, i64::from(x0));
    let cols = cols as i64;
    // `max` then `min`: `clamp` asserts its bounds are in order, a panic path the optimiser
    // cannot remove.
    let lo = (-x0).max(0).min(cols);
    let hi = (w - x0).min(cols).max(lo);
    let at = |c: i64| (x0 + c).max(0) as usize;
    (lo as usize..hi as usize, at(lo)..at(hi))
}

/// The columns `span` of row `y0 + j` of `g`, if that row is inside it.
#[inline(always)]
fn grad_row<'a, P: Copy>(
    g: &ImageView<'a, P>,
    y0: i32,
    j: usize,
    span: core::ops::Range<usize>,
) -> Option<&'a [P]> {
    let y = usize::try_from(i64::from(y0) + j as i64).ok()?;
    g.row(y)?.get(span)
}

/// `left` rows of `cols` elements, `stride` apart, from the start of `rest`: a block of an
/// image or of a row-major scratch buffer. Each row costs two slice bounds tests (the row,
/// then the rest of the block); [`Rows::pairs`] hands each row on to the next pair instead
/// of finding it twice.
#[derive(Clone)]
pub(in crate::klt) struct Rows<'a, P> {
    rest: &'a [P],
    stride: usize,
    cols: usize,
    left: usize,
}

impl<'a, P> Iterator for Rows<'a, P> {
    type Item = &'a [P];

    #[inline(always)]
    fn next(&mut self) -> Option<&'a [P]> {
        self.left = self.left.checked_sub(1)?;
        let row = self.rest.get(..self.cols)?;
        self.rest = self.rest.get(self.stride..).unwrap_or(&[]);
        Some(row)
    }
}

impl<'a, P> Rows<'a, P> {
    /// The `N` elements from column `at` of each row, down the block (none when they reach
    /// past its columns).
    #[inline(always)]
    pub(super) fn column<const N: usize>(self, at: usize) -> Column<'a, P, N> {
        // The block's elements, up to the end of its last row: each row's taps then cost one
        // bounds test.
        let end = self
            .left
            .checked_sub(1)
            .map(|l| l * self.stride + self.cols);
        let fits = at + N <= self.cols;
        let block = match end {
            Some(end) if fits => self.rest.get(..end).unwrap_or(&[]),
            _ => &[],
        };
        Column {
            block,
            at,
            stride: self.stride,
        }
    }

    /// Consecutive rows `(r, r + 1)`: `left - 1` pairs.
    #[inline(always)]
    pub(super) fn pairs(mut self) -> impl Iterator<Item = (&'a [P], &'a [P])> {
        let mut prev = self.next();
        core::iter::from_fn(move || {
            let r1 = self.next()?;
            let r0 = prev.replace(r1)?;
            Some((r0, r1))
        })
    }
}

/// [`Rows::column`]: `N` elements of each row, from one column down the block. Hand-written,
/// as [`Rows`], so that it inlines into the kernels (inside `V3::vectorize` a call left out of
/// line would take the AVX2 intrinsics with it).
pub(super) struct Column<'a, P, const N: usize> {
    block: &'a [P],
    /// The next row's first element in `block`.
    at: usize,
    stride: usize,
}

impl<'a, P, const N: usize> Iterator for Column<'a, P, N> {
    type Item = &'a [P; N];

    #[inline(always)]
    fn next(&mut self) -> Option<&'a [P; N]> {
        let t = self.block.get(self.at..)?.first_chunk::<N>()?;
        self.at += self.stride;
        Some(t)
    }
}

/// The `rows` rows, `cols` wide, of the block at `(x0, y0)` of `img`, straight from the image,
/// when the block lies inside it (then no copy into a scratch patch is needed).
pub(in crate::klt) fn block_rows<'a, P: Copy>(
    img: &ImageView<'a, P>,
    (x0, y0): (i32, i32),
    cols: usize,
    rows: usize,
) -> Option<Rows<'a, P>> {
    let (x0, y0) = (usize::try_from(x0).ok()?, usize::try_from(y0).ok()?);
    if x0 + cols > img.width() || y0 + rows > img.height() {
        return None;
    }
    let stride = img.stride();
    Some(Rows {
        rest: img.data().get(y0 * stride + x0..)?,
        stride,
        cols,
        left: rows,
    })
}

/// Pixels [`cached_patch`] fetches beyond the block on every side.
pub(super) const PATCH_MARGIN: usize = 1;

/// The `cols x rows` block of `j` at the integer corner `at`, reflected, as rows of `patch`:
/// the patch holds the block of a corner `c` widened by [`PATCH_MARGIN`] (`m`) on every side
/// (`(cols + 2m) x (rows + 2m)`, [`fetch_patch`]), and serves every corner within the margin
/// of `c` without a copy. A point near the border that settles across a pixel boundary
/// (its corner moving back and forth by one, as on a weakly textured coarse level) reuses
/// the copy. Reflection is per pixel, so a sub-block is the block fetched at its own corner.
/// A kernel clears `patch_at` (`c`) whenever `patch` gets anything else (a template's `I`);
/// `patch` must hold `(cols + 2m) (rows + 2m)` elements (shorter: fewer rows come back).
pub(super) fn cached_patch<'p, T: Copy + From<u8>>(
    j: &ImageView<'_, u8>,
    at: (i32, i32),
    (cols, rows): (usize, usize),
    patch: &'p mut [T],
    patch_at: &mut Option<(i32, i32)>,
) -> Rows<'p, T> {
    let m = PATCH_MARGIN as i32;
    let stride = cols + 2 * PATCH_MARGIN;
    let near = |c: (i32, i32)| (at.0 - c.0).abs() <= m && (at.1 - c.1).abs() <= m;
    let c = match *patch_at {
        Some(c) if near(c) => c,
        _ => {
            let corner = (at.0 - m, at.1 - m);
            fetch_patch(j, corner, stride, rows + 2 * PATCH_MARGIN, patch);
            *patch_at = Some(at);
            at
        }
    };
    // In `0 ..= 2 m` on both axes.
    let (dx, dy) = ((at.0 - c.0 + m) as usize, (at.1 - c.1 + m) as usize);
    Rows {
        rest: patch.get(dy * stride + dx..).unwrap_or(&[]),
        stride,
        cols,
        left: rows,
    }
}

/// The `rows` rows, `cols` wide, of a row-major scratch block.
pub(super) fn block_of<T>(buf: &[T], cols: usize, rows: usize) -> Rows<'_, T> {
    Rows {
        rest: buf,
        stride: cols,
        cols,
        left: rows,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every patch, inside, across each border and wholly outside, equals the per-pixel
    /// reflection of its definition.
    #[test]
    fn patches_reflect_outside_the_image() {
        let (w, h) = (13usize, 9usize);
        let img: std::vec::Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        let view = ImageView::packed(&img, w, h).unwrap();
        for (cols, rows) in [(1, 1), (4, 3), (10, 10), (25, 12)] {
            for y0 in -14..12 {
                for x0 in -30..16 {
                    let mut got = std::vec![-1i16; cols * rows];
                    fetch_patch(&view, (x0, y0), cols, rows, &mut got);
                    for (k, &g) in got.iter().enumerate() {
                        let (x, y) = (
                            x0 as isize + (k % cols) as isize,
                            y0 as isize + (k / cols) as isize,
                        );
                        let want = img[reflect101(y, h) * w + reflect101(x, w)];
                        assert_eq!(g, i16::from(want), "{cols}x{rows} at ({x0}, {y0}), {k}");
                    }
                }
            }
        }
    }

    /// A walk of corners, by steps of one and two pixels and jumps, inside, across each
    /// border and outside: every block [`cached_patch`] serves is the block fetched at its
    /// own corner, whether it came from the copy (a corner within the margin of the
    /// fetched one) or from a new fetch; and a step within the margin fetches nothing.
    #[test]
    fn cached_blocks_are_the_blocks_at_their_corners() {
        let (w, h) = (13usize, 9usize);
        let img: std::vec::Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        let view = ImageView::packed(&img, w, h).unwrap();
        let (cols, rows) = (6usize, 5usize);
        let mut patch = std::vec![0i16; (cols + 2 * PATCH_MARGIN) * (rows + 2 * PATCH_MARGIN)];
        let mut patch_at = None;
        let (mut at, mut fetched) = ((-9i32, -8i32), 0);
        let steps = [
            (1, 0),
            (0, 1),
            (-1, -1),
            (2, 0),
            (1, 1),
            (0, -2),
            (5, 3),
            (-1, 1),
        ];
        for k in 0..120 {
            let (dx, dy) = steps[k % steps.len()];
            at = (
                (at.0 + dx + 15).rem_euclid(30) - 15,
                (at.1 + dy + 12).rem_euclid(24) - 12,
            );
            let before = patch_at;
            let got: std::vec::Vec<i16> =
                cached_patch(&view, at, (cols, rows), &mut patch, &mut patch_at)
                    .flat_map(|r| r.iter().copied())
                    .collect();
            let mut want = std::vec![0i16; cols * rows];
            fetch_patch(&view, at, cols, rows, &mut want);
            assert_eq!(got, want, "corner {at:?}");
            let near = before.is_some_and(|c: (i32, i32)| {
                (at.0 - c.0).abs() <= PATCH_MARGIN as i32
                    && (at.1 - c.1).abs() <= PATCH_MARGIN as i32
            });
            assert_eq!(patch_at == before, near, "corner {at:?} after {before:?}");
            fetched += usize::from(!near);
        }
        assert!(fetched < 120, "every corner fetched");
    }
}
