//! Bilinear image resizing with pixel centres aligned, in integers.
//!
//! Destination pixel `(x, y)` samples the source at
//!
//! `x_s = (x + ½) w_s / w_d - ½`,  `y_s = (y + ½) h_s / h_d - ½`
//!
//! (clamped into the image), bilinearly with 8-bit weights:
//! `out = Σ w_ij I(x₀ + i, y₀ + j)` rounded, `w = (1 - f_x, f_x) ⊗ (1 - f_y, f_y)` with
//! `f = frac(x_s)` quantised to 1/256 — OpenCV's `resize(..., INTER_LINEAR)` up to that
//! quantisation (±1 grey level). No smoothing first: for reductions by more than about 1.5
//! use [`crate::pyramid`] instead.
//!
//! ```
//! use camgeom::image::{ImageMut, ImageView};
//! use camgeom::resize::resize_bilinear;
//!
//! // Up 2x: x_s = (x + ½)/2 - ½ = -¼ (clamped to 0), ¼, ¾, 1¼ (clamped to 1).
//! let src = [0u8, 200, 0, 200];
//! let mut up = [0u8; 4 * 2];
//! resize_bilinear(&ImageView::packed(&src, 2, 2)?, &mut ImageMut::packed(&mut up, 4, 2)?)?;
//! assert_eq!(up, [0, 50, 150, 200, 0, 50, 150, 200]);
//! // Down 2x of the ramp 10 x: x_s = 2x + ½, so the result is 20 x + 5.
//! let ramp: [u8; 8] = core::array::from_fn(|x| 10 * x as u8);
//! let mut down = [0u8; 4];
//! resize_bilinear(&ImageView::packed(&ramp, 8, 1)?, &mut ImageMut::packed(&mut down, 4, 1)?)?;
//! assert_eq!(down, [5, 25, 45, 65]);
//! # Ok::<(), camgeom::Error>(())
//! ```

use crate::image::{ImageMut, ImageView};
use crate::{Error, Result};

/// Source coordinate of destination index `i` in Q8 (`256 x_s`), clamped to `[0, n_s - 1]`:
/// `⌊(256 (2i + 1) n_s + n_d) / (2 n_d)⌋ - 128` (rounded `256 ((2i + 1) n_s / (2 n_d) - ½)`).
#[cfg(test)]
fn source_q8(i: usize, n_src: usize, n_dst: usize) -> u32 {
    // All in u64: n <= MAX_DIM = 2^13.
    let num = (2 * i as u64 + 1) * n_src as u64 * 256;
    let den = 2 * n_dst as u64;
    let v = (num + den / 2) / den;
    let v = v.saturating_sub(128);
    v.min((n_src as u64 - 1) * 256) as u32
}

/// The source coordinates of destination indices `0, 1, 2, ..` in Q8, as `source_q8` (tests)
/// gives them, by one division and then a quotient and remainder carried from index to index:
/// the numerator grows by `512 n_s` a step (a division per pixel is a library call on a
/// Cortex-M).
fn source_q8s(n_src: usize, n_dst: usize) -> impl Iterator<Item = u32> {
    let (ns, den) = (n_src as u64, 2 * (n_dst as u64).max(1));
    let step = 512 * ns;
    let (dq, dr) = (step / den, step % den);
    let start = 256 * ns + den / 2;
    let (mut q, mut r) = (start / den, start % den);
    let max = ns.saturating_sub(1) * 256;
    core::iter::from_fn(move || {
        let v = q.saturating_sub(128).min(max) as u32;
        q += dq;
        r += dr;
        if r >= den {
            r -= den;
            q += 1;
        }
        Some(v)
    })
}

/// Destination columns handled at a time: their source columns and weights are worked out
/// once for every row.
const STRIP: usize = 64;

/// Source columns a strip may read (a power of two: a column index masked by `SPAN - 1` is
/// provably in bounds, so the gather needs no checks). Strips are narrowed so that their
/// span fits ([`strip_width`]).
const SPAN: usize = 256;

/// Destination columns of a strip whose source columns span at most `SPAN - 1`: `n` columns
/// read source columns `x₀` from `⌊x_s⌋` of the first to `⌊x_s⌋ + 1` of the last, at most
/// `(n - 1) w_s / w_d + 3` apart with the rounding of the Q8 coordinates; `n ≤ (SPAN - 4)
/// w_d / w_s` keeps that below `SPAN - 1`.
fn strip_width(ws: usize, wd: usize, left: usize) -> usize {
    let fit = ((SPAN - 4) * wd / ws.max(1)).max(1);
    STRIP.min(left).min(fit)
}

/// Resizes `src` into `dst` (any sizes) by bilinear interpolation (module docs).
///
/// Separable, in strips of destination columns, vertical pass first: for each destination
/// row, the two source rows are blended over the strip's source columns (`r₀ (256 - f_y) +
/// r₁ f_y`, a straight loop), then each destination pixel interpolates that blend at its two
/// source columns. The sum `Σ w_x w_y p` is formed exactly in integers either way, so the
/// bytes are those of the per-pixel formula.
///
/// Never fails for valid views; the `Result` is for API symmetry with the other kernels.
#[doc(alias = "resize")]
#[doc(alias = "INTER_LINEAR")]
pub fn resize_bilinear(src: &ImageView<'_, u8>, dst: &mut ImageMut<'_, u8>) -> Result<()> {
    let (ws, hs) = (src.width(), src.height());
    let (wd, hd) = (dst.width(), dst.height());
    if ws == 0 || hs == 0 {
        return Err(Error::InvalidImage);
    }
    let mut xs = source_q8s(ws, wd);
    let mut start = 0;
    while start < wd {
        let n = strip_width(ws, wd, wd - start);
        // Source columns relative to the strip's first, `lo`; the right one clamped at the
        // image's last column.
        let (mut c0, mut c1, mut fx) = ([0usize; STRIP], [0usize; STRIP], [0u32; STRIP]);
        let mut lo = None;
        for ((a, b), f) in c0.iter_mut().zip(c1.iter_mut()).zip(fx.iter_mut()).take(n) {
            let sx = xs.next().unwrap_or(0);
            let x0 = (sx >> 8) as usize;
            let first = *lo.get_or_insert(x0);
            *a = x0 - first;
            *b = (x0 + 1).min(ws - 1) - first;
            *f = sx & 255;
        }
        let lo = lo.unwrap_or(0);
        let hi = c1.get(n.saturating_sub(1)).map_or(lo, |&b| lo + b);
        let (c0, c1, fx) = (
            c0.get(..n).unwrap_or(&[]),
            c1.get(..n).unwrap_or(&[]),
            fx.get(..n).unwrap_or(&[]),
        );
        let mut blend = [0u32; SPAN];
        for (y, sy) in (0..hd).zip(source_q8s(hs, hd)) {
            let (y0, fy) = ((sy >> 8) as usize, sy & 255);
            let y1 = (y0 + 1).min(hs - 1);
            let span = |r: usize| src.row(r).and_then(|row| row.get(lo..=hi)).unwrap_or(&[]);
            let (wt, wb) = (256 - fy, fy);
            for ((v, &t), &b) in blend.iter_mut().zip(span(y0)).zip(span(y1)) {
                *v = u32::from(t) * wt + u32::from(b) * wb;
            }
            let Some(out) = dst.row_mut(y).and_then(|r| r.get_mut(start..start + n)) else {
                break;
            };
            for (((o, &a), &b), &f) in out.iter_mut().zip(c0).zip(c1).zip(fx) {
                let at = |c: usize| blend.get(c & (SPAN - 1)).copied().unwrap_or(0);
                // <= 255 · 2^16: the rounded quotient fits u8.
                *o = ((at(a) * (256 - f) + at(b) * f + (1 << 15)) >> 16) as u8;
            }
        }
        start += n;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-pixel form of the module docs (the implementation before the strips).
    fn reference(src: &ImageView<'_, u8>, dst: &mut ImageMut<'_, u8>) {
        let (ws, hs) = (src.width(), src.height());
        let (wd, hd) = (dst.width(), dst.height());
        for y in 0..hd {
            let sy = source_q8(y, hs, hd);
            let (y0, fy) = ((sy >> 8) as usize, sy & 255);
            let r0 = src.row(y0).unwrap();
            let r1 = src.row((y0 + 1).min(hs - 1)).unwrap();
            let out = dst.row_mut(y).unwrap();
            for (x, o) in out.iter_mut().enumerate() {
                let sx = source_q8(x, ws, wd);
                let (x0, fx) = ((sx >> 8) as usize, sx & 255);
                let x1 = (x0 + 1).min(ws - 1);
                let p = |r: &[u8], c: usize| u32::from(r[c]);
                let top = p(r0, x0) * (256 - fx) + p(r0, x1) * fx;
                let bot = p(r1, x0) * (256 - fx) + p(r1, x1) * fx;
                *o = ((top * (256 - fy) + bot * fy + (1 << 15)) >> 16) as u8;
            }
        }
    }

    /// The strips give the per-pixel formula's bytes, for reductions (the ORB pyramid's 1/1.2
    /// steps among them, and strong ones that narrow the strips), enlargements, widths across a
    /// strip boundary and strided views.
    #[test]
    fn strips_match_the_per_pixel_formula() {
        let mut g = crate::rng::Pcg32::new(11);
        let src: std::vec::Vec<u8> = (0..700 * 130).map(|_| g.below(256) as u8).collect();
        let cases = [
            ((640, 120), (533, 100)),
            ((533, 100), (444, 83)),
            ((100, 50), (64, 40)),
            ((100, 50), (65, 41)),
            ((100, 50), (129, 77)),
            ((7, 3), (200, 9)),
            ((1, 1), (70, 2)),
            ((300, 128), (300, 128)),
            ((700, 130), (1, 1)),
            // Reductions by 3.9 and 4.7 (strips near and below their span limit) and by 233.
            ((700, 130), (180, 7)),
            ((700, 130), (150, 5)),
            ((700, 130), (3, 2)),
        ];
        for ((ws, hs), (wd, hd)) in cases {
            // Strided: the source rows are 700 wide whatever ws is.
            let v = ImageView::new(&src, ws, hs, 700).unwrap();
            let mut a = std::vec![0u8; wd * hd];
            let mut b = std::vec![0u8; wd * hd];
            resize_bilinear(&v, &mut ImageMut::packed(&mut a, wd, hd).unwrap()).unwrap();
            reference(&v, &mut ImageMut::packed(&mut b, wd, hd).unwrap());
            assert_eq!(a, b, "{ws}x{hs} -> {wd}x{hd}");
        }
    }

    #[test]
    fn identity_constant_and_ramp() {
        let src: [u8; 40] = core::array::from_fn(|i| (i * 6) as u8);
        let v = ImageView::packed(&src, 8, 5).unwrap();
        let mut out = [0u8; 40];
        resize_bilinear(&v, &mut ImageMut::packed(&mut out, 8, 5).unwrap()).unwrap();
        assert_eq!(out, src);
        // A horizontal ramp 0, 10, .., 90 halved: x_s = 2x + ½, the mean of two neighbours.
        let ramp: [u8; 10] = core::array::from_fn(|i| (10 * i) as u8);
        let v = ImageView::packed(&ramp, 10, 1).unwrap();
        let mut half = [0u8; 5];
        resize_bilinear(&v, &mut ImageMut::packed(&mut half, 5, 1).unwrap()).unwrap();
        assert_eq!(half, [5, 25, 45, 65, 85]);
        // Upscaling a single pixel, and a constant stays constant.
        let one = [77u8];
        let mut big = [0u8; 12];
        let v = ImageView::packed(&one, 1, 1).unwrap();
        resize_bilinear(&v, &mut ImageMut::packed(&mut big, 4, 3).unwrap()).unwrap();
        assert!(big.iter().all(|&b| b == 77));
    }

    /// The carried quotients are the divisions of the definition, for every index of
    /// reductions, enlargements and the ORB pyramid's 1/1.2 steps.
    #[test]
    fn carried_coordinates_are_the_divisions() {
        let sizes = [1usize, 2, 3, 5, 7, 64, 100, 533, 640, 1000, 8191];
        for &ns in &sizes {
            for &nd in &sizes.map(|n| n.max(1)) {
                let got: std::vec::Vec<u32> = source_q8s(ns, nd).take(nd).collect();
                let want: std::vec::Vec<u32> = (0..nd).map(|i| source_q8(i, ns, nd)).collect();
                assert_eq!(got, want, "{ns} -> {nd}");
            }
        }
        for ns in [640usize, 533, 444, 370] {
            let nd = (ns as f64 / 1.2).round() as usize;
            let got: std::vec::Vec<u32> = source_q8s(ns, nd).take(nd).collect();
            let want: std::vec::Vec<u32> = (0..nd).map(|i| source_q8(i, ns, nd)).collect();
            assert_eq!(got, want, "{ns} -> {nd}");
        }
    }
}
