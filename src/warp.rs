//! Perspective warp of a source image (a logo) into a quadrilateral of a destination frame, by
//! inverse mapping with bilinear interpolation.
//!
//! `H` maps source pixels to destination pixels (`x_d ~ H x_s`, pixel centres at integers). The
//! logo's corner pixel centres `(0, 0)`, `(w-1, 0)`, `(w-1, h-1)`, `(0, h-1)` go to the four
//! corners of the quadrilateral. Destination pixel `x` is written exactly when its
//! back-projection `x_s = π(M x)`, `M ~ H⁻¹`, lies in the source rectangle
//! `[0, w-1] x [0, h-1]`. With `M` scaled so that `W = (M x)₃ > 0` on the quadrilateral, that is
//! four linear inequalities in the destination coordinates,
//!
//! `X >= 0`,  `(w-1) W - X >= 0`,  `Y >= 0`,  `(h-1) W - Y >= 0`   (`(X, Y, W) = M x`),
//!
//! so on each scanline the pixels to write form one interval, found by four divisions: this is
//! the scanline rasterisation of the quadrilateral by its edges, clipped to the frame. Nothing
//! outside the quadrilateral or the frame is visited, and every sample is clamped into the
//! source, so no input can make a read or a write go out of bounds. Work: one row setup per
//! frame row the quadrilateral covers, then per written pixel one bilinear sample.
//!
//! Two arithmetics, chosen by [`Arithmetic`]:
//!
//! - [`Arithmetic::Float`]: `f32`; `x_s = X / W` per pixel, rounded to 10 fraction bits, then
//!   the integer bilinear sample below with 10-bit weights. The coordinates of 16 pixels are
//!   computed in one straight-line pass (vectorised: the divisions run several lanes at a
//!   time), then sampled one by one.
//! - [`Arithmetic::Fixed`], for cores without an FPU: `M` is quantised once to `i64` with `F`
//!   fractional bits (the largest `F <= 40` that keeps every product below 2⁶² — see
//!   [`warp_perspective_into`]). Along a scanline the homogeneous numerators and the
//!   denominator advance by constant integer deltas, `X += m₁₁`, `Y += m₂₁`, `W += m₃₁`, which
//!   is exact: the stepped values *are* the quantised `M` applied to the pixel, with no
//!   accumulated error. Per pixel: two `i64` divisions `u = ⌊(256 X + W/2) / W⌋` (source
//!   coordinate in Q8) and the integer bilinear sample with 8-bit weights. The only floating
//!   point is the once-per-warp set-up (inverse and quantisation of `M`). The difference from
//!   the `f32` path is at most one grey level on the pixels both write (tested), and the set
//!   of written pixels differs only where a pixel centre is within rounding of the outline.
//!
//! Optional constant-alpha blending: `out = (α s + (255 - α) d + 127) / 255`.
//!
//! ```
//! use camgeom::image::{ImageMut, ImageView};
//! use camgeom::nalgebra::Point2;
//! use camgeom::warp::{Arithmetic, WarpConfig, warp_into_quad};
//!
//! // A 5x5 logo, a ramp 0, 50, .. 200 across; into the square (10, 10)-(18, 18): twice as big.
//! let logo: [u8; 25] = core::array::from_fn(|i| 50 * (i % 5) as u8);
//! let quad = [(10.0, 10.0), (18.0, 10.0), (18.0, 18.0), (10.0, 18.0)];
//! let quad = quad.map(|(x, y)| Point2::new(x, y));
//! for arithmetic in [Arithmetic::Float, Arithmetic::Fixed] {
//!     let mut frame = [7u8; 32 * 32];
//!     let mut dst = ImageMut::packed(&mut frame, 32, 32)?;
//!     let cfg = WarpConfig { arithmetic, ..WarpConfig::default() };
//!     let report = warp_into_quad(&ImageView::packed(&logo, 5, 5)?, &mut dst, &quad, &cfg)?;
//!     assert_eq!(report.written, 9 * 9); // the pixel centres 10..=18 on both axes
//!     for x in 10..=18 {
//!         // Source column (x - 10) / 2: on a logo pixel, or halfway between two.
//!         assert_eq!(frame[14 * 32 + x], (25 * (x - 10)) as u8);
//!     }
//!     assert_eq!((frame[14 * 32 + 9], frame[14 * 32 + 19], frame[9 * 32 + 14]), (7, 7, 7));
//! }
//! # Ok::<(), camgeom::Error>(())
//! ```

use nalgebra::{Matrix3, Point2, Vector3};

use crate::homography::Homography;
use crate::image::{ImageMut, ImageView};
use crate::{Error, Result};

/// Arithmetic of the per-pixel work of [`warp_perspective_into`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Arithmetic {
    /// `f32` coordinates and weights.
    #[default]
    Float,
    /// Integer homogeneous stepping and an integer bilinear sample (module docs).
    Fixed,
}

/// Parameters of [`warp_perspective_into`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WarpConfig {
    /// Constant opacity of the source, `out = (α s + (255 - α) d + 127) / 255`; 255 (the
    /// default) replaces the destination pixels.
    pub alpha: u8,
    /// Float or fixed-point per-pixel arithmetic. Default [`Arithmetic::Float`].
    pub arithmetic: Arithmetic,
}

impl Default for WarpConfig {
    fn default() -> Self {
        Self {
            alpha: 255,
            arithmetic: Arithmetic::Float,
        }
    }
}

/// What a warp did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WarpReport {
    /// Destination pixels written.
    pub written: u32,
    /// Fractional bits `F` of the quantised inverse map ([`Arithmetic::Fixed`]; 0 for float).
    pub fraction_bits: u8,
}

/// Destination-to-source map and the frame rows and columns the quadrilateral can cover.
struct Setup {
    /// `M ~ H⁻¹` with `W > 0` on the quadrilateral and `max |W| = 1` over the clip box corners.
    m: Matrix3<f64>,
    /// Inclusive clip box in the destination.
    x0: i64,
    x1: i64,
    y0: i64,
    y1: i64,
}

/// The source corners, `H` in `f64`, the sign checks and the clip box; `None` when the
/// quadrilateral misses the frame.
fn setup(src: (usize, usize), dst: (usize, usize), h: &Homography<f32>) -> Result<Option<Setup>> {
    let hd = h.cast::<f64>()?;
    let hm = *hd.matrix();
    let (sw, sh) = ((src.0 - 1) as f64, (src.1 - 1) as f64);
    let corners = [(0.0, 0.0), (sw, 0.0), (sw, sh), (0.0, sh)];
    // Every corner must map to a finite point on the same side of the vanishing line, else the
    // image of the logo is not a bounded quadrilateral.
    let mut sign = 0.0f64;
    let (mut bx0, mut bx1, mut by0, mut by1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in corners {
        let v = hm * Vector3::new(x, y, 1.0);
        let scale = v.x.abs().max(v.y.abs()).max(1.0);
        if !greater(v.z.abs(), 1e-12 * scale) {
            return Err(Error::AtInfinity);
        }
        if sign == 0.0 {
            sign = v.z.signum();
        } else if v.z.signum() != sign {
            return Err(Error::AtInfinity);
        }
        let (px, py) = (v.x / v.z, v.y / v.z);
        if !(px.is_finite() && py.is_finite()) {
            return Err(Error::NonFinite);
        }
        bx0 = bx0.min(px);
        bx1 = bx1.max(px);
        by0 = by0.min(py);
        by1 = by1.max(py);
    }
    let (dw, dh) = (dst.0 as f64 - 1.0, dst.1 as f64 - 1.0);
    let x0 = libm::ceil(bx0).max(0.0);
    let x1 = libm::floor(bx1).min(dw);
    let y0 = libm::ceil(by0).max(0.0);
    let y1 = libm::floor(by1).min(dh);
    if !(in_order(x0, x1) && in_order(y0, y1)) {
        return Ok(None);
    }
    let mut m = *hd.inverse()?.matrix();
    // W > 0 on the quadrilateral: test at the image of the logo's centre.
    let c = hm * Vector3::new(sw / 2.0, sh / 2.0, 1.0);
    let centre = Vector3::new(c.x / c.z, c.y / c.z, 1.0);
    if (m * centre).z < 0.0 {
        m = -m;
    }
    // max |W| over the clip box corners = 1 (W is affine: its maximum over the box).
    let wmax = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        .iter()
        .map(|&(x, y)| (m.m31 * x + m.m32 * y + m.m33).abs())
        .fold(0.0f64, f64::max);
    if !(greater(wmax, 0.0) && wmax.is_finite()) {
        return Err(Error::Degenerate);
    }
    m /= wmax;
    if !m.iter().all(|v| v.is_finite()) {
        return Err(Error::NonFinite);
    }
    Ok(Some(Setup {
        m,
        x0: x0 as i64,
        x1: x1 as i64,
        y0: y0 as i64,
        y1: y1 as i64,
    }))
}

/// `a > b`, false when either is NaN.
#[inline]
fn greater<T: PartialOrd>(a: T, b: T) -> bool {
    matches!(a.partial_cmp(&b), Some(core::cmp::Ordering::Greater))
}

/// `a <= b`, false when either is NaN.
#[inline]
fn in_order<T: PartialOrd>(a: T, b: T) -> bool {
    matches!(
        a.partial_cmp(&b),
        Some(core::cmp::Ordering::Less | core::cmp::Ordering::Equal)
    )
}

/// Blends `s` over `d` with opacity `alpha`.
#[inline]
fn blend(s: u8, d: u8, alpha: u8) -> u8 {
    if alpha == 255 {
        return s;
    }
    let a = u32::from(alpha);
    ((a * u32::from(s) + (255 - a) * u32::from(d) + 127) / 255) as u8
}

/// Warps `src` into `dst` through `h` (source to destination pixels), see the module docs.
/// Destination pixels outside the quadrilateral are left untouched.
///
/// Errors: [`Error::AtInfinity`] when a source corner maps to infinity or the corners map to
/// both sides of `H`'s vanishing line (the image of the logo is unbounded);
/// [`Error::NonFinite`] / [`Error::Degenerate`] from the set-up of the inverse;
/// [`Error::Overflow`] ([`Arithmetic::Fixed`] only) when `M` cannot be quantised with at least
/// 8 fractional bits (a quadrilateral of a fraction of a pixel showing a whole logo).
pub fn warp_perspective_into(
    src: &ImageView<'_, u8>,
    dst: &mut ImageMut<'_, u8>,
    h: &Homography<f32>,
    config: &WarpConfig,
) -> Result<WarpReport> {
    let Some(s) = setup((src.width(), src.height()), (dst.width(), dst.height()), h)? else {
        return Ok(WarpReport::default());
    };
    match config.arithmetic {
        Arithmetic::Float => Ok(warp_float(src, dst, &s, config.alpha)),
        Arithmetic::Fixed => warp_fixed(src, dst, &s, config.alpha),
    }
}

/// Warps `src` so that its corner pixel centres `(0, 0)`, `(w-1, 0)`, `(w-1, h-1)`, `(0, h-1)`
/// land on `quad[0..4]` (destination pixels), through [`Homography::from_four_points`].
///
/// Errors: [`Error::NonFinite`] for NaN/inf corners, [`Error::Degenerate`] for a quadrilateral
/// with three collinear corners or a fold (self-intersecting, or not convex), else as
/// [`warp_perspective_into`].
pub fn warp_into_quad(
    src: &ImageView<'_, u8>,
    dst: &mut ImageMut<'_, u8>,
    quad: &[Point2<f32>; 4],
    config: &WarpConfig,
) -> Result<WarpReport> {
    let (w, h) = ((src.width() - 1) as f64, (src.height() - 1) as f64);
    let corners = [
        Point2::new(0.0, 0.0),
        Point2::new(w, 0.0),
        Point2::new(w, h),
        Point2::new(0.0, h),
    ];
    let q = quad.map(|p| p.cast::<f64>());
    let hom = Homography::<f64>::from_four_points(&corners, &q)?.cast::<f32>()?;
    warp_perspective_into(src, dst, &hom, config).map_err(|e| match e {
        // The four points passed the fold test, so a vanishing-line crossing is degeneracy of
        // the quadrilateral (for instance a logo of one pixel's width).
        Error::AtInfinity => Error::Degenerate,
        other => other,
    })
}

/// Intersects `[lo, hi]` with `{x : a x + b >= 0}` (floats; NaN empties the interval).
#[inline]
fn clip_f32(lo: &mut f32, hi: &mut f32, a: f32, b: f32) {
    if a > 0.0 {
        *lo = lo.max(libm::ceilf(-b / a));
    } else if a < 0.0 {
        *hi = hi.min(libm::floorf(b / -a));
    } else if b.is_nan() || b < 0.0 {
        *hi = f32::MIN;
    }
    if !in_order(*lo, *hi) {
        *hi = f32::MIN;
    }
}

/// Fraction bits of [`warp_float`]'s source coordinates and weights (OpenCV's bilinear
/// remap uses 5 and 15-bit weights; 10 keeps the float path's samples within rounding of an
/// exact bilinear interpolation).
const FLOAT_BITS: u32 = 10;

/// Pixels of a scanline whose source coordinates [`warp_float`] computes in one straight-line
/// pass (which LLVM vectorises: the divisions and conversions run several lanes at a time)
/// before sampling them one by one.
const FLOAT_CHUNK: usize = 16;

/// The source image as the bilinear sampler reads it: cells of 2x2 pixels.
#[derive(Clone, Copy)]
struct Source<'a> {
    data: &'a [u8],
    stride: usize,
    /// Largest column and row of a cell's top-left pixel (`width - 2`, `height - 2`, or 0 for
    /// a source one pixel wide or high).
    cell: (u32, u32),
    /// From a cell's top-left pixel to its right and lower neighbours (1 and `stride`, or 0
    /// for a source one pixel wide or high).
    step: (usize, usize),
}

impl<'a> Source<'a> {
    fn new(src: &ImageView<'a, u8>) -> Self {
        let (w, h, stride) = (src.width(), src.height(), src.stride());
        Self {
            data: src.data(),
            stride,
            // `MAX_DIM` bounds both, far inside `u32`.
            cell: (w.saturating_sub(2) as u32, h.saturating_sub(2) as u32),
            step: (usize::from(w > 1), if h > 1 { stride } else { 0 }),
        }
    }

    /// The cell of the source coordinates `(u, v) / 2ᴮ` (fixed point with `B` fraction bits,
    /// `0 <= u <= 2ᴮ (w - 1)`, `0 <= v <= 2ᴮ (h - 1)`): the column and row of its top-left
    /// pixel and the weights `f_x, f_y` in `0..=2ᴮ` of its right column and lower row,
    /// `[ix, iy, fx, fy]`. On the last column or row the cell is the one before it with weight
    /// `2ᴮ`, which reads the same pixels at the same weights as a clamped cell would. Any
    /// `(u, v)` gives a cell inside the image. Plain `u32` arithmetic, the same in every lane:
    /// it vectorises.
    #[inline]
    fn cell<const B: u32>(&self, u: u32, v: u32) -> [u32; 4] {
        let ix = (u >> B).min(self.cell.0);
        let iy = (v >> B).min(self.cell.1);
        // `ix <= u / 2ᴮ`: no underflow; the bound only acts on out-of-range input.
        [
            ix,
            iy,
            (u - (ix << B)).min(1 << B),
            (v - (iy << B)).min(1 << B),
        ]
    }

    /// Bilinear sample of the cell `[ix, iy, fx, fy]` ([`Self::cell`], `B <= 10`), rounded:
    /// `((p₀₀ (2ᴮ - f_x) + p₀₁ f_x) (2ᴮ - f_y) + (p₁₀ (2ᴮ - f_x) + p₁₁ f_x) f_y + 2²ᴮ⁻¹) >> 2B`,
    /// each `a (2ᴮ - f) + b f` formed as `2ᴮ a + (b - a) f` (the same integers, one product;
    /// below `2³⁰` for `B = 10`).
    #[inline]
    fn sample<const B: u32>(&self, [ix, iy, fx, fy]: [u32; 4]) -> u8 {
        const { assert!(B >= 1 && B <= 10, "sample: 1 to 10 fraction bits fit i32") };
        let i = iy as usize * self.stride + ix as usize;
        let p = |i: usize| i32::from(self.data.get(i).copied().unwrap_or(0));
        let (fx, fy) = (fx as i32, fy as i32);
        let (a, b) = (p(i), p(i + self.step.0));
        let top = (a << B) + (b - a) * fx;
        let j = i + self.step.1;
        let (a, b) = (p(j), p(j + self.step.0));
        let bot = (a << B) + (b - a) * fx;
        (((top << B) + (bot - top) * fy + (1 << (2 * B - 1))) >> (2 * B)) as u8
    }
}

/// `x` rounded to the nearest integer (ties to even) for `0 <= x < 2²³`, by the float's own
/// rounding: adding `2²³` leaves the integer in the low mantissa bits. Branch-free and alike
/// in every lane, so the chunk loop of [`warp_float`] vectorises (the saturating `as u32`
/// does not); Q10 coordinates of a [`crate::image::MAX_DIM`] source stay below `2²³`
/// (`8191 · 1024 = 8,387,584`).
#[inline]
fn round_small(x: f32) -> u32 {
    (x + 8_388_608.0).to_bits().wrapping_sub(0x4B00_0000)
}

fn warp_float(
    src: &ImageView<'_, u8>,
    dst: &mut ImageMut<'_, u8>,
    s: &Setup,
    alpha: u8,
) -> WarpReport {
    let m: Matrix3<f32> = s.m.map(|v| v as f32);
    let source = Source::new(src);
    let (sw, sh) = ((src.width() - 1) as f32, (src.height() - 1) as f32);
    let q = (1u32 << FLOAT_BITS) as f32;
    let mut written = 0u32;
    for y in s.y0..=s.y1 {
        let yf = y as f32;
        let bx = m.m12 * yf + m.m13;
        let by = m.m22 * yf + m.m23;
        let bw = m.m32 * yf + m.m33;
        let (mut lo, mut hi) = (s.x0 as f32, s.x1 as f32);
        clip_f32(&mut lo, &mut hi, m.m11, bx);
        clip_f32(&mut lo, &mut hi, sw * m.m31 - m.m11, sw * bw - bx);
        clip_f32(&mut lo, &mut hi, m.m21, by);
        clip_f32(&mut lo, &mut hi, sh * m.m31 - m.m21, sh * bw - by);
        if !in_order(lo, hi) {
            continue;
        }
        let (lo, hi) = (lo as usize, hi as usize);
        let Some(out) = dst.row_mut(y as usize).and_then(|r| r.get_mut(lo..=hi)) else {
            continue;
        };
        for (k, chunk) in out.chunks_mut(FLOAT_CHUNK).enumerate() {
            // The chunk's cells from its source coordinates `2ᴮ X / W` (`B = FLOAT_BITS`),
            // rounded and clamped into the source, and each `W` (a pixel with `W <= 0` is
            // skipped).
            let x0 = (lo + k * FLOAT_CHUNK) as f32;
            let mut cells = [[0u32; 4]; FLOAT_CHUNK];
            let mut ws = [0.0f32; FLOAT_CHUNK];
            for (j, (c, w)) in cells.iter_mut().zip(ws.iter_mut()).enumerate() {
                let xf = x0 + j as f32;
                *w = m.m31 * xf + bw;
                let u = round_small((q * (m.m11 * xf + bx) / *w).clamp(0.0, q * sw));
                let v = round_small((q * (m.m21 * xf + by) / *w).clamp(0.0, q * sh));
                *c = source.cell::<FLOAT_BITS>(u, v);
            }
            for (d, (&c, &w)) in chunk.iter_mut().zip(cells.iter().zip(ws.iter())) {
                if w > 0.0 {
                    *d = blend(source.sample::<FLOAT_BITS>(c), *d, alpha);
                    written += 1;
                }
            }
        }
    }
    WarpReport {
        written,
        fraction_bits: 0,
    }
}

/// `⌈n / d⌉` for `d > 0`.
#[inline]
fn ceil_div(n: i64, d: i64) -> i64 {
    -((-n).div_euclid(d))
}

/// Intersects `[lo, hi]` with `{x : a x + b >= 0}` (integers, exact).
#[inline]
fn clip_i64(lo: &mut i64, hi: &mut i64, a: i64, b: i64) {
    if a > 0 {
        *lo = (*lo).max(ceil_div(-b, a));
    } else if a < 0 {
        *hi = (*hi).min(b.div_euclid(-a));
    } else if b < 0 {
        *hi = i64::MIN;
    }
}

fn warp_fixed(
    src: &ImageView<'_, u8>,
    dst: &mut ImageMut<'_, u8>,
    s: &Setup,
    alpha: u8,
) -> Result<WarpReport> {
    let (sw, sh) = ((src.width() - 1) as i64, (src.height() - 1) as i64);
    // Bound of |X|, |Y|, |W| for coordinates up to C (the clip box, one step past its end,
    // and the source size, which multiplies W in the clipping forms), for the choice of F.
    let c = (s.x1.max(s.y1).max(sw).max(sh) + 1) as f64;
    let m = &s.m;
    let row_bound = |a: f64, b: f64, k: f64| (a.abs() + b.abs()) * c + k.abs();
    let bx = row_bound(m.m11, m.m12, m.m13);
    let by = row_bound(m.m21, m.m22, m.m23);
    let bw = row_bound(m.m31, m.m32, m.m33);
    // The largest values formed: 256 X (the division) and (w-1) W - X (the row clipping).
    let big = 256.0 * (bx.max(by) + c * bw) + 1.0;
    let f = (0..=40)
        .rev()
        .find(|&f| libm::ldexp(big, f) < libm::ldexp(1.0, 62))
        .ok_or(Error::Overflow)?;
    if f < 8 {
        return Err(Error::Overflow);
    }
    let q = |v: f64| libm::round(libm::ldexp(v, f)) as i64;
    let m = s.m.map(q);
    let (m11, m12, m13) = (m.m11, m.m12, m.m13);
    let (m21, m22, m23) = (m.m21, m.m22, m.m23);
    let (m31, m32, m33) = (m.m31, m.m32, m.m33);
    let source = Source::new(src);
    let mut written = 0u32;
    for y in s.y0..=s.y1 {
        // |m y| < 2^62 by the choice of F; the sums stay below 2^63.
        let bx = m12 * y + m13;
        let by = m22 * y + m23;
        let bw = m32 * y + m33;
        let (mut lo, mut hi) = (s.x0, s.x1);
        clip_i64(&mut lo, &mut hi, m11, bx);
        clip_i64(&mut lo, &mut hi, sw * m31 - m11, sw * bw - bx);
        clip_i64(&mut lo, &mut hi, m21, by);
        clip_i64(&mut lo, &mut hi, sh * m31 - m21, sh * bw - by);
        if lo > hi {
            continue;
        }
        let Some(row) = dst.row_mut(y as usize) else {
            continue;
        };
        let (mut xn, mut yn, mut wn) = (m11 * lo + bx, m21 * lo + by, m31 * lo + bw);
        for x in lo..=hi {
            if wn > 0 {
                let u = ((256 * xn + wn / 2).div_euclid(wn)).clamp(0, 256 * sw);
                let v = ((256 * yn + wn / 2).div_euclid(wn)).clamp(0, 256 * sh);
                let val = source.sample::<8>(source.cell::<8>(u as u32, v as u32));
                if let Some(d) = row.get_mut(x as usize) {
                    *d = blend(val, *d, alpha);
                    written += 1;
                }
            }
            xn += m11;
            yn += m21;
            wn += m31;
        }
    }
    Ok(WarpReport {
        written,
        fraction_bits: f as u8,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    fn logo(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                (((x / 4 + y / 4) % 2) as u8) * 150 + (x * 3 + y) as u8 % 50
            })
            .collect()
    }

    fn hom(m: [f32; 9]) -> Homography<f32> {
        Homography::from_matrix(&Matrix3::from_row_slice(&m)).unwrap()
    }

    const FLOAT: WarpConfig = WarpConfig {
        alpha: 255,
        arithmetic: Arithmetic::Float,
    };
    const FIXED: WarpConfig = WarpConfig {
        alpha: 255,
        arithmetic: Arithmetic::Fixed,
    };

    #[test]
    fn integer_translation_copies_and_clips() {
        let (w, h) = (20, 12);
        let src = logo(w, h);
        let sv = ImageView::packed(&src, w, h).unwrap();
        for cfg in [FLOAT, FIXED] {
            // Shift by (+7, -3) into a 24x10 frame: partly outside on the right and the top.
            let mut out = std::vec![0u8; 24 * 10];
            let mut dv = ImageMut::packed(&mut out, 24, 10).unwrap();
            let r = warp_perspective_into(
                &sv,
                &mut dv,
                &hom([1., 0., 7., 0., 1., -3., 0., 0., 1.]),
                &cfg,
            )
            .unwrap();
            let mut count = 0;
            for y in 0..10 {
                for x in 0..24 {
                    let (sx, sy) = (x as isize - 7, y as isize + 3);
                    let inside = (0..w as isize).contains(&sx) && (0..h as isize).contains(&sy);
                    let want = if inside {
                        src[sy as usize * w + sx as usize]
                    } else {
                        0
                    };
                    count += usize::from(inside);
                    assert_eq!(out[y * 24 + x], want, "{cfg:?} ({x}, {y})");
                }
            }
            assert_eq!(r.written as usize, count);
        }
    }

    #[test]
    fn fixed_agrees_with_float_on_perspective_maps() {
        let (w, h) = (64, 48);
        let src = logo(w, h);
        let sv = ImageView::packed(&src, w, h).unwrap();
        let maps = [
            [
                1.46, -0.146, 60.3, 0.166, 1.098, 40.7, -1.37e-4, -9.3e-6, 1.0,
            ],
            [0.7, 0.3, 20.0, -0.25, 0.9, 90.0, 1.2e-3, -8e-4, 1.0],
            [3.5, 0.0, -30.0, 0.0, 4.0, -20.0, 0.0, 2e-3, 1.0],
            [-1.0, 0.0, 150.0, 0.0, 1.0, 10.0, 0.0, 0.0, 1.0], // a mirror
        ];
        for m in maps {
            let hm = hom(m);
            let mut a = std::vec![7u8; 200 * 150];
            let mut b = std::vec![7u8; 200 * 150];
            let ra = warp_perspective_into(
                &sv,
                &mut ImageMut::packed(&mut a, 200, 150).unwrap(),
                &hm,
                &FLOAT,
            )
            .unwrap();
            let rb = warp_perspective_into(
                &sv,
                &mut ImageMut::packed(&mut b, 200, 150).unwrap(),
                &hm,
                &FIXED,
            )
            .unwrap();
            assert!(ra.written > 1000, "{ra:?}");
            assert!(rb.fraction_bits >= 30, "{rb:?}");
            // The written sets differ only on the outline (rounding of the clip), by < 1 %.
            let diff_set = a
                .iter()
                .zip(&b)
                .filter(|(x, y)| (**x == 7) != (**y == 7))
                .count();
            assert!(
                diff_set * 100 <= ra.written as usize,
                "{diff_set} of {}",
                ra.written
            );
            let worst = a
                .iter()
                .zip(&b)
                .filter(|(x, y)| **x != 7 && **y != 7)
                .map(|(x, y)| x.abs_diff(*y))
                .max()
                .unwrap();
            assert!(worst <= 1, "{m:?}: {worst}");
        }
    }

    #[test]
    fn quads_far_outside_huge_and_invalid() {
        let src = logo(32, 32);
        let sv = ImageView::packed(&src, 32, 32).unwrap();
        let mut out = std::vec![0u8; 50 * 40];
        for cfg in [FLOAT, FIXED] {
            let mut dv = ImageMut::packed(&mut out, 50, 40).unwrap();
            let quad = |c: [[f32; 2]; 4]| c.map(|p| Point2::new(p[0], p[1]));
            // Entirely outside: nothing written.
            let far = quad([
                [1e6, 1e6],
                [1e6 + 50.0, 1e6],
                [1e6 + 50.0, 1e6 + 50.0],
                [1e6, 1e6 + 50.0],
            ]);
            assert_eq!(warp_into_quad(&sv, &mut dv, &far, &cfg).unwrap().written, 0);
            // Covering the whole frame: every pixel written once.
            let huge = quad([[-1e5, -1e5], [1e5, -1e5], [1e5, 1e5], [-1e5, 1e5]]);
            assert_eq!(
                warp_into_quad(&sv, &mut dv, &huge, &cfg).unwrap().written,
                2000
            );
            // NaN, collinear, folded (bow-tie), non-convex.
            let nan = quad([[f32::NAN, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]);
            assert_eq!(
                warp_into_quad(&sv, &mut dv, &nan, &cfg),
                Err(Error::NonFinite)
            );
            let line = quad([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [0.0, 10.0]]);
            assert_eq!(
                warp_into_quad(&sv, &mut dv, &line, &cfg),
                Err(Error::Degenerate)
            );
            let bowtie = quad([[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]);
            assert_eq!(
                warp_into_quad(&sv, &mut dv, &bowtie, &cfg),
                Err(Error::Degenerate)
            );
            let dart = quad([[0.0, 0.0], [20.0, 0.0], [5.0, 5.0], [0.0, 20.0]]);
            assert_eq!(
                warp_into_quad(&sv, &mut dv, &dart, &cfg),
                Err(Error::Degenerate)
            );
            // H whose vanishing line crosses the logo.
            let cross = hom([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -0.1, 0.0, 1.0]);
            assert_eq!(
                warp_perspective_into(&sv, &mut dv, &cross, &cfg),
                Err(Error::AtInfinity)
            );
        }
    }

    #[test]
    fn alpha_blends() {
        let src = [200u8; 16];
        let sv = ImageView::packed(&src, 4, 4).unwrap();
        let mut out = [100u8; 16];
        let cfg = WarpConfig { alpha: 64, ..FIXED };
        let r = warp_perspective_into(
            &sv,
            &mut ImageMut::packed(&mut out, 4, 4).unwrap(),
            &Homography::identity(),
            &cfg,
        )
        .unwrap();
        assert_eq!(r.written, 16);
        // (64 · 200 + 191 · 100 + 127) / 255 = 125
        assert!(out.iter().all(|&v| v == 125), "{out:?}");
    }

    proptest! {
        /// Random quads anywhere (mostly partly outside): the writes stay inside the view (a
        /// guard band around it in the same buffer keeps its value), and the fixed path
        /// never fails where the float path succeeds.
        #[test]
        fn never_writes_outside(
            c in proptest::array::uniform8(-300.0f32..400.0),
            fixed in any::<bool>(),
        ) {
            let src = logo(16, 16);
            let sv = ImageView::packed(&src, 16, 16).unwrap();
            // A 60x40 view at (10, 5) of a 80x50 buffer.
            let mut buf = std::vec![3u8; 80 * 50];
            let quad = [
                Point2::new(c[0], c[1]), Point2::new(c[2], c[3]),
                Point2::new(c[4], c[5]), Point2::new(c[6], c[7]),
            ];
            let cfg = if fixed { FIXED } else { FLOAT };
            let written = {
                let mut dv = ImageMut::new(&mut buf[5 * 80 + 10..], 60, 40, 80).unwrap();
                match warp_into_quad(&sv, &mut dv, &quad, &cfg) {
                    Ok(r) => r.written as usize,
                    Err(e) => {
                        prop_assert!(matches!(e, Error::Degenerate | Error::AtInfinity), "{e:?}");
                        0
                    }
                }
            };
            let mut inside = 0;
            for y in 0..50 {
                for x in 0..80 {
                    let in_view = (10..70).contains(&x) && (5..45).contains(&y);
                    let v = buf[y * 80 + x];
                    if !in_view {
                        prop_assert_eq!(v, 3);
                    } else if v != 3 {
                        inside += 1;
                    }
                }
            }
            prop_assert!(inside <= written);
        }
    }
}
