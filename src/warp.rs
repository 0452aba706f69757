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
//! Two arithmetics, chosen by type ([`crate::arith`]):
//!
//! - `f32`: `x_s = X / W` per pixel and the bilinear sample
//!   `t + (b - t) f_y` (`t`, `b` the cell's rows at `f_x`) in `f32`, rounded once at the end.
//! - [`Fixed`](crate::arith::Fixed), for cores without an FPU: `M` is quantised once to `i64` with `F`
//!   fractional bits (the largest `F <= 40` that keeps every product below 2⁶² — see
//!   [`warp_perspective_into`]). Along a scanline the homogeneous numerators and the
//!   denominator advance by constant integer deltas, `X += m₁₁`, `Y += m₂₁`, `W += m₃₁`, which
//!   is exact: the stepped values *are* the quantised `M` applied to the pixel, with no
//!   accumulated error. Per pixel: the source coordinates in Q8, `u = ⌊(256 X + W/2) / W⌋`
//!   (exact quotients, never a division per pixel: a board's 64-bit division is a library
//!   call), and the integer bilinear sample with 8-bit weights, exact. On the boards each
//!   quotient is carried from the last one and corrected by comparing the remainder; the
//!   only floating point is the once-per-warp set-up (inverse and quantisation of `M`). With
//!   SIMD the quotients of 16 pixels are guessed at once in `f32` lanes under an error
//!   bound, and the few lanes the bound cannot settle take the remainder test: the same
//!   integers, bit for bit (tested), in about 1.2 times the float path's time. The
//!   difference from the `f32` path is at most one grey level on the pixels both write
//!   (tested), and the set of written pixels differs only where a pixel centre is within
//!   rounding of the outline.
//!
//! Both work on 16 pixels of a scanline at a time in vectors of four lanes (`wide`: SSE2,
//! NEON, or arrays on the boards): the source points and cells, then the loads of each cell's
//! 2x2 pixels (the only scalar step, two bytes a row), then the samples, whose weighted pairs
//! are `i16` dot products in the integer path (`pmaddwd`; on Cortex-M4/M7 the
//! DSP halfword multiply-accumulates `SMLABB`/`SMLATB`).
//!
//! Optional constant-alpha blending: `out = (α s + (255 - α) d + 127) / 255`.
//!
//! ```
//! use camgeom::image::{ImageMut, ImageView};
//! use camgeom::nalgebra::Point2;
//! use camgeom::arith::{Arithmetic, Fixed};
//! use camgeom::warp::{WarpConfig, warp_into_quad};
//!
//! // A 5x5 logo, a ramp 0, 50, .. 200 across; into the square (10, 10)-(18, 18): twice as big.
//! let logo: [u8; 25] = core::array::from_fn(|i| 50 * (i % 5) as u8);
//! let quad = [(10.0, 10.0), (18.0, 10.0), (18.0, 18.0), (10.0, 18.0)];
//! let quad = quad.map(|(x, y)| Point2::new(x, y));
//! fn check<A: Arithmetic>(logo: &[u8], quad: &[Point2<f32>; 4]) -> camgeom::Result<()> {
//!     let mut frame = [7u8; 32 * 32];
//!     let mut dst = ImageMut::packed(&mut frame, 32, 32)?;
//!     let cfg = WarpConfig::default();
//!     let report = warp_into_quad::<A>(&ImageView::packed(logo, 5, 5)?, &mut dst, quad, &cfg)?;
//!     assert_eq!(report.written, 9 * 9); // the pixel centres 10..=18 on both axes
//!     for x in 10..=18 {
//!         // Source column (x - 10) / 2: on a logo pixel, or halfway between two.
//!         assert_eq!(frame[14 * 32 + x], (25 * (x - 10)) as u8);
//!     }
//!     assert_eq!((frame[14 * 32 + 9], frame[14 * 32 + 19], frame[9 * 32 + 14]), (7, 7, 7));
//!     Ok(())
//! }
//! check::<f32>(&logo, &quad)?;
//! check::<Fixed>(&logo, &quad)?;
//! # Ok::<(), camgeom::Error>(())
//! ```

use nalgebra::{Matrix3, Point2, Vector3};

use crate::arith::Arithmetic;
use crate::homography::Homography;
use crate::image::{ImageMut, ImageView};
use crate::{Error, Result, SIMD};
use wide::{f32x4, i16x8, i32x4, u8x16};

/// Parameters of [`warp_perspective_into`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WarpConfig {
    /// Constant opacity of the source, `out = (α s + (255 - α) d + 127) / 255`; 255 (the
    /// default) replaces the destination pixels.
    pub alpha: u8,
}

impl Default for WarpConfig {
    fn default() -> Self {
        Self { alpha: 255 }
    }
}

/// What a warp did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WarpReport {
    /// Destination pixels written.
    pub written: u32,
    /// Fractional bits `F` of the quantised inverse map ([`Fixed`](crate::arith::Fixed); 0 for `f32`).
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
/// [`Error::Overflow`] ([`Fixed`](crate::arith::Fixed) only) when `M` cannot be quantised with at least
/// 8 fractional bits (a quadrilateral of a fraction of a pixel showing a whole logo).
#[doc(alias = "warpPerspective")]
pub fn warp_perspective_into<A: Arithmetic>(
    src: &ImageView<'_, u8>,
    dst: &mut ImageMut<'_, u8>,
    h: &Homography<f32>,
    config: &WarpConfig,
) -> Result<WarpReport> {
    let Some(s) = setup((src.width(), src.height()), (dst.width(), dst.height()), h)? else {
        return Ok(WarpReport::default());
    };
    if A::INTEGER {
        warp_fixed::<SIMD>(src, dst, &s, config.alpha)
    } else {
        Ok(warp_float::<SIMD>(src, dst, &s, config.alpha))
    }
}

/// Warps `src` so that its corner pixel centres `(0, 0)`, `(w-1, 0)`, `(w-1, h-1)`, `(0, h-1)`
/// land on `quad[0..4]` (destination pixels), through [`Homography::from_four_points`].
///
/// Errors: [`Error::NonFinite`] for NaN/inf corners, [`Error::Degenerate`] for a quadrilateral
/// with three collinear corners or a fold (self-intersecting, or not convex), else as
/// [`warp_perspective_into`].
pub fn warp_into_quad<A: Arithmetic>(
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
    warp_perspective_into::<A>(src, dst, &hom, config).map_err(|e| match e {
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

/// Lanes of the warp's vectors: four `f32` or `i32` (128 bits: SSE2 on x86-64, NEON on
/// aarch64, an array of four on the boards).
const LANES: usize = 4;

/// Pixels of a scanline the warp handles in one pass: the source points and cells of
/// [`VECS`] vectors, then the loads of their pixels, then the samples.
const CHUNK: usize = 16;

/// Vectors of a chunk.
const VECS: usize = CHUNK / LANES;

/// A chunk's cells ([`Source::cells_f32`], [`Source::cells_q8`]): the column and row of each
/// pixel's cell, and the source point's position in it, `f_x` and `f_y` (fractions of 1 for
/// `f32`, of `2⁸` for Q8).
struct Cells<F> {
    cx: [i32x4; VECS],
    cy: [i32x4; VECS],
    fx: [F; VECS],
    fy: [F; VECS],
}

/// The source image as the bilinear sampler reads it: cells of 2x2 pixels.
#[derive(Clone, Copy)]
struct Source<'a> {
    data: &'a [u8],
    /// The row stride, and `(1, stride - 1)` as an `i16` pair per lane (`stride` is at most
    /// `4 MAX_DIM = 2¹⁵`): a cell's index `c_y stride + c_x` is one dot product plus `c_y`.
    stride: (usize, i16x8),
    /// Largest column and row of a cell's top-left pixel (`width - 2`, `height - 2`, or 0 for
    /// a source one pixel wide or high).
    cell: (i32, i32),
    /// From a cell's top-left pixel to its lower neighbours (`stride`, or 0 for a source one
    /// pixel high); `wide` is false for a source one pixel wide (no right neighbour).
    down: usize,
    wide: bool,
    /// The largest source coordinates, `width - 1` and `height - 1`.
    end: (f32, f32),
}

impl<'a> Source<'a> {
    fn new(src: &ImageView<'a, u8>) -> Self {
        let (w, h, stride) = (src.width(), src.height(), src.stride());
        let pair = pairs(i32x4::splat(1), i32x4::splat(stride as i32 - 1));
        Self {
            data: src.data(),
            stride: (stride, bytemuck::cast(pair)),
            // `MAX_DIM` bounds both, far inside `i32`.
            cell: (w.saturating_sub(2) as i32, h.saturating_sub(2) as i32),
            down: if h > 1 { stride } else { 0 },
            wide: w > 1,
            end: ((w - 1) as f32, (h - 1) as f32),
        }
    }

    /// The cells of the source points `(sx, sy)` (lanes), each clamped into
    /// `[0, w-1] x [0, h-1]` first (NaN to a point inside: only pixels with `W = 0`, which are
    /// not written, have one): `c = min(⌊s⌋, w - 2)` and `f = s - c` in `[0, 1]` (on the last
    /// column or row the cell before it with `f = 1`).
    #[inline(always)]
    fn cells_f32(&self, s: [(f32x4, f32x4); VECS]) -> Cells<f32x4> {
        let (end, cell) = (
            (f32x4::splat(self.end.0), f32x4::splat(self.end.1)),
            (
                f32x4::splat(self.cell.0 as f32),
                f32x4::splat(self.cell.1 as f32),
            ),
        );
        // NaN: `fast_max(s, 0)` is 0 on SSE2; NEON's truncation gives 0; the arrays' `fast_min`
        // gives the far end. Any of them is a cell inside the source.
        let s = s.map(|(x, y)| {
            (
                x.fast_max(f32x4::ZERO).fast_min(end.0),
                y.fast_max(f32x4::ZERO).fast_min(end.1),
            )
        });
        let c = s.map(|(x, y)| {
            (
                x.fast_min(cell.0).fast_trunc_int(),
                y.fast_min(cell.1).fast_trunc_int(),
            )
        });
        let mut f = [(f32x4::ZERO, f32x4::ZERO); VECS];
        for (f, ((x, y), (cx, cy))) in f.iter_mut().zip(s.iter().zip(&c)) {
            *f = (*x - cx.round_float(), *y - cy.round_float());
        }
        Cells {
            cx: c.map(|c| c.0),
            cy: c.map(|c| c.1),
            fx: f.map(|f| f.0),
            fy: f.map(|f| f.1),
        }
    }

    /// The cells of the source points `(u, v) / 2⁸` (Q8 lanes, `0 <= u <= 2⁸ (w - 1)`,
    /// `0 <= v <= 2⁸ (h - 1)`, which both fixed-point forms keep): `c = min(⌊u / 2⁸⌋, w - 2)`
    /// and `f = u - 2⁸ c` in `0..=2⁸` (`2⁸` only at `u = 2⁸ (w - 1)`, in the last cell).
    #[inline(always)]
    fn cells_q8(&self, u: [i32x4; VECS], v: [i32x4; VECS]) -> Cells<i32x4> {
        let cx = u.map(|u| (u >> 8_i32).min(i32x4::splat(self.cell.0)));
        let cy = v.map(|v| (v >> 8_i32).min(i32x4::splat(self.cell.1)));
        let (mut fx, mut fy) = ([i32x4::ZERO; VECS], [i32x4::ZERO; VECS]);
        for ((fx, fy), ((u, v), (cx, cy))) in fx
            .iter_mut()
            .zip(fy.iter_mut())
            .zip(u.iter().zip(&v).zip(cx.iter().zip(&cy)))
        {
            *fx = *u - (*cx << 8_i32);
            *fy = *v - (*cy << 8_i32);
        }
        Cells { cx, cy, fx, fy }
    }

    /// The 2x2 pixels of each cell of a chunk, per vector as `i16` pairs, the shape of a dot
    /// product with a pair of weights: the top rows' `(p₀₀, p₀₁)` of the four lanes, then
    /// the bottom rows' `(p₁₀, p₁₁)`. Each cell is one checked read of `stride + 2` pixels
    /// (a lane out of the image reads 0: only the fixed path's SIMD lanes past a row's end,
    /// which are not written, have one); these loads are the only scalar part of a sample.
    #[inline(always)]
    fn gather<const V: bool, F>(&self, cells: &Cells<F>) -> [(i16x8, i16x8); VECS] {
        let mut rows = [[0u16; 2 * LANES]; VECS];
        let s = self.down;
        for (rows, (cx, cy)) in rows.iter_mut().zip(cells.cx.iter().zip(&cells.cy)) {
            // `c_y stride + c_x`: one dot product with SIMD, a multiply-add a lane without.
            let index = if V {
                bytemuck::cast::<i32x4, i16x8>(pairs(*cx, *cy)).dot(self.stride.1) + *cy
            } else {
                let (x, y) = (cx.to_array(), cy.to_array());
                i32x4::new(core::array::from_fn(|j| {
                    let (x, y) = (x.get(j).copied(), y.get(j).copied());
                    y.unwrap_or(0) * self.stride.0 as i32 + x.unwrap_or(0)
                }))
            };
            let (top, bot) = rows.split_at_mut(LANES);
            for ((t, b), i) in top.iter_mut().zip(bot.iter_mut()).zip(index.to_array()) {
                let i = i as usize;
                if self.wide {
                    // A lane past a row's end may hold any index: a wrapped end is an empty
                    // range.
                    if let Some(c) = self.data.get(i..i.wrapping_add(s + 2)) {
                        let pair = |k: usize| match c.get(k..k + 2) {
                            Some(&[a, b]) => u16::from_le_bytes([a, b]),
                            _ => 0,
                        };
                        (*t, *b) = (pair(0), pair(s));
                    }
                } else {
                    // A source one pixel wide: each row's pixel twice.
                    let p = |i: usize| u16::from(self.data.get(i).copied().unwrap_or(0)) * 0x101;
                    (*t, *b) = (p(i), p(i.wrapping_add(s)));
                }
            }
        }
        rows.map(|r| {
            if V {
                let bytes = bytemuck::cast::<[u16; 2 * LANES], u8x16>(r);
                (
                    bytemuck::cast(u8x16::unpack_low(bytes, u8x16::ZERO)),
                    bytemuck::cast(u8x16::unpack_high(bytes, u8x16::ZERO)),
                )
            } else {
                // The same lanes, a byte at a time (an array shuffle would move each twice).
                let spread = |base: usize| {
                    i16x8::new(core::array::from_fn(|k| {
                        let pair = r.get(base + k / 2).copied().unwrap_or(0);
                        (if k % 2 == 0 { pair & 0xFF } else { pair >> 8 }) as i16
                    }))
                };
                (spread(0), spread(LANES))
            }
        })
    }

    /// The samples of a chunk's cells: [`Self::gather`]'s pixels, then `sample`
    /// ([`sample_f32`] or [`sample_q8`]) a vector at a time.
    #[inline(always)]
    fn samples<const V: bool, F: Copy>(
        &self,
        cells: &Cells<F>,
        sample: impl Fn((i16x8, i16x8), F, F) -> i32x4,
    ) -> [i32x4; VECS] {
        let taps = self.gather::<V, F>(cells);
        let mut val = [i32x4::ZERO; VECS];
        let fractions = cells.fx.iter().zip(&cells.fy);
        for (v, (t, (fx, fy))) in val.iter_mut().zip(taps.iter().zip(fractions)) {
            *v = sample(*t, *fx, *fy);
        }
        val
    }
}

/// Bilinear samples in `f32` of the pairs `(top, bot)` ([`Source::gather`]) at `(f_x, f_y)`,
/// rounded to the nearest grey level: `t = p₀₀ + (p₀₁ - p₀₀) f_x`,
/// `b = p₁₀ + (p₁₁ - p₁₀) f_x`, `t + (b - t) f_y`.
#[inline(always)]
fn sample_f32((top, bot): (i16x8, i16x8), fx: f32x4, fy: f32x4) -> i32x4 {
    let (top, bot) = (
        bytemuck::cast::<i16x8, i32x4>(top),
        bytemuck::cast::<i16x8, i32x4>(bot),
    );
    let low = i32x4::splat(0xFFFF);
    let (p00, p01) = ((top & low).round_float(), (top >> 16_i32).round_float());
    let (p10, p11) = ((bot & low).round_float(), (bot >> 16_i32).round_float());
    let t = p00 + (p01 - p00) * fx;
    let b = p10 + (p11 - p10) * fx;
    // In `[0, 255]` up to rounding: `+ 1/2` and truncation round it.
    (t + (b - t) * fy + f32x4::splat(0.5)).fast_trunc_int()
}

/// Bilinear samples in integers of the pairs `(top, bot)` ([`Source::gather`]) at
/// `(f_x, f_y) / 2⁸`, exact: `t = p₀₀ (2⁸ - f_x) + p₀₁ f_x`, `b = p₁₀ (2⁸ - f_x) + p₁₁ f_x`
/// and the sample `(t (2⁸ - f_y) + b f_y + 2¹⁵) >> 16`. Each weighted pair is one `i16` dot
/// product (`pmaddwd`; `SMLABB`/`SMLATB` on Cortex-M4/M7): `t` and `b` (up to 65,280)
/// enter the vertical one less `2¹⁵`, so that they fit `i16`, and the `2¹⁵ · 2⁸` this takes
/// off is added back.
#[inline(always)]
fn sample_q8((top, bot): (i16x8, i16x8), fx: i32x4, fy: i32x4) -> i32x4 {
    let one = i32x4::splat(1 << 8);
    let wx = bytemuck::cast(pairs(one - fx, fx));
    let half = i32x4::splat(1 << 15);
    let t = top.dot(wx) - half;
    let b = bot.dot(wx) - half;
    let s = bytemuck::cast::<i32x4, i16x8>(pairs(t, b)).dot(bytemuck::cast(pairs(one - fy, fy)));
    (s + i32x4::splat((1 << 23) + (1 << 15))) >> 16_i32
}

/// Each lane `a | b << 16`: the `i16` pair `(a, b)` of lanes in `-2¹⁵..2¹⁵`.
#[inline]
fn pairs(a: i32x4, b: i32x4) -> i32x4 {
    (a & i32x4::splat(0xFFFF)) | (b << 16_i32)
}

/// Writes the pixels of a chunk's samples `val` (grey levels) that `keep` has set into `out`,
/// blended, and returns how many.
#[inline(always)]
fn put<const V: bool>(out: &mut [u8], val: [i32x4; VECS], keep: u32, alpha: u8) -> u32 {
    // Every sample is in `0..=255`: SIMD packs them with saturation (`packssdw`,
    // `packuswb`), elsewhere a truncation a lane is the same and cheaper.
    let bytes = if V {
        let [a, b, c, d] = val;
        let narrow = |a: i32x4, b: i32x4| i16x8::from_i32x8_saturate(bytemuck::cast([a, b]));
        u8x16::narrow_i16x8(narrow(a, b), narrow(c, d)).to_array()
    } else {
        bytemuck::cast::<[i32x4; VECS], [i32; CHUNK]>(val).map(|v| v as u8)
    };
    if keep == (1 << CHUNK) - 1
        && alpha == 255
        && let Ok(whole) = <&mut [u8; CHUNK]>::try_from(&mut *out)
    {
        *whole = bytes;
        return CHUNK as u32;
    }
    let mut n = 0;
    for (j, (d, v)) in out.iter_mut().zip(bytes).enumerate() {
        if keep >> j & 1 != 0 {
            *d = blend(v, *d, alpha);
            n += 1;
        }
    }
    n
}

fn warp_float<const V: bool>(
    src: &ImageView<'_, u8>,
    dst: &mut ImageMut<'_, u8>,
    s: &Setup,
    alpha: u8,
) -> WarpReport {
    let m: Matrix3<f32> = s.m.map(|v| v as f32);
    let source = Source::new(src);
    let (sw, sh) = source.end;
    let steps: [f32x4; VECS] = core::array::from_fn(lane_steps);
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
        let (bx, by, bw) = (f32x4::splat(bx), f32x4::splat(by), f32x4::splat(bw));
        let (m11, m21, m31) = (
            f32x4::splat(m.m11),
            f32x4::splat(m.m21),
            f32x4::splat(m.m31),
        );
        for (k, chunk) in out.chunks_mut(CHUNK).enumerate() {
            // Frame columns below `MAX_DIM`: exact in `f32`.
            let x0 = f32x4::splat((lo + k * CHUNK) as f32);
            let x = steps.map(|s| x0 + s);
            let w = x.map(|x| m31 * x + bw);
            let mut points = [(f32x4::ZERO, f32x4::ZERO); VECS];
            // A pixel with `W <= 0` (only on the outline) is skipped.
            let mut keep = 0;
            for (j, (p, (x, w))) in points.iter_mut().zip(x.iter().zip(&w)).enumerate() {
                *p = ((m11 * *x + bx) / *w, (m21 * *x + by) / *w);
                let positive = if V {
                    w.simd_gt(f32x4::ZERO).to_bitmask()
                } else {
                    let w = w.to_array();
                    (0..LANES).fold(0, |m, l| {
                        m | u32::from(w.get(l).is_some_and(|&w| w > 0.0)) << l
                    })
                };
                keep |= positive << (j * LANES);
            }
            let cells = source.cells_f32(points);
            let val = source.samples::<V, _>(&cells, sample_f32);
            written += put::<V>(chunk, val, keep, alpha);
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

/// `⌊n / d⌋` along a scanline ([`Fixed`](crate::arith::Fixed)'s source coordinates `(2⁸ X + W/2) / W`),
/// without a division per pixel. The quotient moves by nearly the same step from pixel to
/// pixel, so the last quotient plus the last step, `q`, is `⌊n / d⌋` or next to it: the
/// remainder `e = n - q d` tells which (`0 <= e < d`: `q`; `-d <= e < 0`: `q - 1`;
/// `d <= e < 2d`: `q + 1`), exactly; any other `e` (the first pixel, a turn of the
/// perspective) costs one division. The quotients are the divisions', bit for bit.
///
/// Bounds: every quotient of a pixel inside the quadrilateral lies in `0..=hi`
/// (`hi = 2⁸ (w - 1)`: the clip keeps `0 <= X <= (w - 1) W`), so a prediction lies in
/// `-hi..=2 hi`; with `0 <= n, d < 2⁶²` and `hi d < 2⁶²` (the warp's choice of `F`), `q d`
/// and `e` stay inside `i64`.
struct Quotient {
    /// The last quotient and the step to it.
    q: i64,
    step: i64,
    hi: i64,
}

impl Quotient {
    /// Quotients in `0..=hi` (values outside come from the division and are clamped by the
    /// caller).
    fn new(hi: i64) -> Self {
        Self { q: 0, step: 0, hi }
    }

    /// `⌊n / d⌋` for `d > 0`.
    #[inline]
    fn next(&mut self, n: i64, d: i64) -> i64 {
        // `q` in `-hi..=2 hi` (both quotients in `0..=hi`): `|q d| < 2⁶³`, no overflow.
        let q = corrected(self.q + self.step, n, d);
        self.step = q - self.q;
        self.q = q;
        q
    }
}

/// `⌊n / d⌋` for `d > 0` from a guess `q` with `|q d| < 2⁶²`: the remainder `e = n - q d`
/// tells whether `q` is the quotient (`0 <= e < d`), one above it (`-d <= e < 0`) or one
/// below it (`d <= e < 2d`); any other `e` costs one division. Exact for every guess.
#[inline(always)]
fn corrected(q: i64, n: i64, d: i64) -> i64 {
    let e = n - q * d;
    if e < -d || e >= 2 * d {
        n.div_euclid(d)
    } else {
        q + i64::from(e >= d) - i64::from(e < 0)
    }
}

/// [`warp_fixed`]'s Q8 source coordinates of a row's chunks in `f32` lanes (the SIMD
/// form), exact.
///
/// The quotient of column `x₀ + j` is `⌊t_j⌋`, `t_j = 2⁸ X_j / W_j + 1/2 - ε_j` with
/// `0 <= ε_j <= 1 / 2W_j` (the `⌊W / 2⌋`), and from the chunk's first column
/// `t_j = t₀ + j A / (1 + j B) - ε_j` with `A = 2⁸ (m₁₁ - m₃₁ X₀ / W₀) / W₀`,
/// `B = m₃₁ / W₀` (the integers `X₀`, `W₀`, `m`: exact; likewise `Y`). `t₀`, `A`, `B` come
/// in `f64` once a chunk; the offsets `j A / (1 + j B)` (at most `D` in size) in `f32`
/// lanes, added to `t₀ - n + K` (`n` the integer nearest `t₀`; `K >= ⌈D⌉ + 1` keeps the sum
/// positive, so truncation is the floor).
///
/// With `u = 2⁻²⁴`, the lanes' sum is off by at most `11.2 u D + 2 u (K + 1)` (the
/// conversions of `A` and `B`, a product, the sum `1 + j B` (at least 1/2), the reciprocal
/// and the product: `10.1 u` of the offset; the base's and the sum's roundings), plus the
/// `f64` parts (`t₀`: `2⁻⁵⁰ (2⁸ end + 1)`; `A`: `2⁻⁵⁰ D`), plus `ε <= 1 / W_min`. `δ` is
/// twice that, bounded once a row from its smallest `W` (at an end: `W` is linear in `x`)
/// and `0 <= X₀ / W₀ <= end` (the clip): a lane whose sum lies further than `δ` from every
/// integer has the exact quotient; the others (about one in a hundred) are flagged for
/// [`corrected`]. So a row's quotients are independent where the carried [`Quotient`]
/// chains them, and the divisions' bit for bit.
struct Guess {
    /// `m₁₁`, `m₂₁`, `m₃₁`.
    step: (f64, f64, f64),
    /// `K`, and `δ` and `1 - δ` in lanes.
    k: i64,
    delta: (f32x4, f32x4),
}

/// `f32`'s unit roundoff `2⁻²⁴`, and `2⁻⁵⁰` for the bounds of [`Guess`]'s `f64` parts.
const U_F32: f64 = 1.0 / (1u64 << 24) as f64;
const TWO_POW_M50: f64 = 1.0 / (1u64 << 50) as f64;

/// `1.5 · 2⁵²`: `t + ROUND_F64` is `t` rounded to an integer `n` for `|t| < 2⁵¹`, with `n`
/// in its low mantissa bits (two's complement).
const ROUND_F64: f64 = 1.5 * (1u64 << 52) as f64;

/// [`Guess::chunk`]'s lanes: Q8 coordinates and the masks of the lanes that need
/// [`corrected`] (bit `j` for column `x₀ + j`).
struct Guesses {
    u: [i32x4; VECS],
    v: [i32x4; VECS],
    flag_u: u32,
    flag_v: u32,
}

impl Guess {
    /// The bound of a row with these steps `(m₁₁, m₂₁, m₃₁)` on which `W >= w_min > 0`,
    /// and the last source column and row `end`; `None` where the lanes cannot resolve it
    /// (`15 |B| > 1/2` or `δ >= 1/4`: `W` small against its step or the coordinates' range).
    fn row((m11, m21, m31): (i64, i64, i64), w_min: i64, end: (i64, i64)) -> Option<Self> {
        let step = (m11 as f64, m21 as f64, m31 as f64);
        let (end_u, end_v) = (end.0 as f64, end.1 as f64);
        let rw = 1.0 / w_min as f64;
        let last = (CHUNK - 1) as f64;
        let reach = 1.0 - last * step.2.abs() * rw;
        let a = 256.0
            * (step.0.abs() + step.2.abs() * end_u).max(step.1.abs() + step.2.abs() * end_v)
            * rw;
        let d = last * a / reach;
        // `!(x < y)`: NaN fails too.
        if !(reach >= 0.5 && d < 1e6) {
            return None;
        }
        // `⌊D⌋ + 2 >= ⌈D⌉ + 1`.
        let k = d as i64 + 2;
        let f64_parts = (256.0 * end_u.max(end_v) + 1.0 + d) * TWO_POW_M50;
        let delta = 2.0 * (11.2 * U_F32 * d + 2.0 * U_F32 * (k as f64 + 1.0) + f64_parts + rw);
        // Finite: `D` is, and `1 / W_min <= 1`.
        if delta >= 0.25 {
            return None;
        }
        Some(Self {
            step,
            k,
            delta: (f32x4::splat(delta as f32), f32x4::splat(1.0 - delta as f32)),
        })
    }

    /// The `f64` part of the guesses of the chunk whose first column (inside the row) has the
    /// integers `(X₀, Y₀, W₀)`: per axis `A`, the base `t₀ - n + K` (`n` the integer
    /// nearest `t₀`) and `n - K`, and `B`.
    #[inline(always)]
    fn terms(&self, (x0, y0, w0): (i64, i64, i64)) -> Terms {
        let ((m11, m21, m31), k) = (self.step, self.k);
        let rw = 1.0 / w0 as f64;
        let axis = |m: f64, n: i64| {
            let r = n as f64 * rw;
            let (t, a) = (256.0 * r + 0.5, 256.0 * (m - m31 * r) * rw);
            // `t₀` rounded to an integer by the `f64` addition (`0 <= t₀ < 2²³`, the clip), its
            // low mantissa bits that integer; `|t₀ - n| <= 1/2` leaves `c >= K - 1/2 > D`.
            let rounded = t + ROUND_F64;
            let c = t - (rounded - ROUND_F64) + k as f64;
            let shift = (rounded.to_bits() as i32).wrapping_sub(k as i32);
            (
                f32x4::splat(a as f32),
                f32x4::splat(c as f32),
                i32x4::splat(shift),
            )
        };
        Terms {
            u: axis(m11, x0),
            v: axis(m21, y0),
            b: f32x4::splat((m31 * rw) as f32),
        }
    }

    /// The guesses of a chunk from its [`Self::terms`].
    #[inline(always)]
    fn chunk(&self, terms: &Terms) -> Guesses {
        let (delta, near) = self.delta;
        // An axis's lanes: `⌊s⌋ - K + n`, and the flags of `s` within `δ` of an integer.
        let lane = |(a, c, shift): (f32x4, f32x4, i32x4), j: usize, r: f32x4| {
            let s = c + lane_steps(j) * a * r;
            let q = s.fast_trunc_int();
            // Exact: `0 < s < 2²⁴` and `⌊s⌋` share their leading bits.
            let frac = s - q.round_float();
            let flags = (frac.simd_lt(delta) | frac.simd_gt(near)).to_bitmask();
            (q + shift, flags << (j * LANES))
        };
        let mut g = Guesses {
            u: [i32x4::ZERO; VECS],
            v: [i32x4::ZERO; VECS],
            flag_u: 0,
            flag_v: 0,
        };
        for (j, (gu, gv)) in g.u.iter_mut().zip(g.v.iter_mut()).enumerate() {
            let r = f32x4::ONE / (f32x4::ONE + lane_steps(j) * terms.b);
            let ((u, fu), (v, fv)) = (lane(terms.u, j, r), lane(terms.v, j, r));
            (*gu, *gv) = (u, v);
            g.flag_u |= fu;
            g.flag_v |= fv;
        }
        g
    }
}

/// [`Guess::terms`]: per axis `(A, t₀ - n + K, n - K)` in lanes, and `B`.
struct Terms {
    u: (f32x4, f32x4, i32x4),
    v: (f32x4, f32x4, i32x4),
    b: f32x4,
}

/// The columns of vector `j` of a chunk relative to its first: `4 j, 4 j + 1, 4 j + 2, 4 j + 3`.
#[inline(always)]
fn lane_steps(j: usize) -> f32x4 {
    f32x4::new([0.0, 1.0, 2.0, 3.0]) + f32x4::splat((j * LANES) as f32)
}

fn warp_fixed<const V: bool>(
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
    // `⌊(2⁸ n + W / 2) / W⌋` clamped to `0..=2⁸ end`: a source coordinate in Q8 (below
    // `2⁸ MAX_DIM`, inside `i32`).
    let q8 = |q: &mut Quotient, n: i64, w: i64| q.next(256 * n + (w >> 1), w).clamp(0, q.hi) as i32;
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
        let Some(out) = dst
            .row_mut(y as usize)
            .and_then(|r| r.get_mut(lo as usize..=hi as usize))
        else {
            continue;
        };
        let (mut xn, mut yn, mut wn) = (m11 * lo + bx, m21 * lo + by, m31 * lo + bw);
        // SIMD: independent guesses where the lanes resolve the row (`W > 0` at both its ends,
        // so along it).
        let w_min = (m31 * lo + bw).min(m31 * hi + bw);
        let guess = match V && w_min > 0 {
            true => Guess::row((m11, m21, m31), w_min, (sw, sh)),
            false => None,
        };
        if let Some(guess) = guess {
            let first = |x: i64| (m11 * x + bx, m21 * x + by, m31 * x + bw);
            let mut terms = guess.terms(first(lo));
            for (k, chunk) in out.chunks_mut(CHUNK).enumerate() {
                let x0 = lo + (k * CHUNK) as i64;
                let Guesses {
                    mut u,
                    mut v,
                    flag_u,
                    flag_v,
                } = guess.chunk(&terms);
                // The next chunk's terms ahead of this one's samples: their `f64` chain (a
                // division, then products) runs beside the samples.
                if x0 + (CHUNK as i64) <= hi {
                    terms = guess.terms(first(x0 + CHUNK as i64));
                }
                let keep = u32::MAX >> (32 - chunk.len().min(CHUNK));
                // `⌊(2⁸ n + ⌊W / 2⌋) / W⌋` exactly for the flagged lanes (the guess clamped
                // into `0..=2⁸ end` keeps `|q W| < 2⁶²` by the choice of F).
                let exact =
                    |lanes: &mut [i32x4; VECS], flags: u32, (m, b): (i64, i64), end: i64| {
                        let mut q: [i32; CHUNK] = bytemuck::cast(*lanes);
                        let mut flags = flags & keep;
                        while flags != 0 {
                            let j = flags.trailing_zeros();
                            flags &= flags - 1;
                            let x = x0 + i64::from(j);
                            let (n, w) = (m * x + b, m31 * x + bw);
                            if let Some(q) = q.get_mut(j as usize) {
                                let guess = i64::from(*q).max(0).min(256 * end);
                                *q = corrected(guess, 256 * n + (w >> 1), w)
                                    .max(0)
                                    .min(256 * end) as i32;
                            }
                        }
                        *lanes = bytemuck::cast(q);
                    };
                if (flag_u | flag_v) & keep != 0 {
                    exact(&mut u, flag_u, (m11, bx), sw);
                    exact(&mut v, flag_v, (m21, by), sh);
                }
                let cells = source.cells_q8(u, v);
                let val = source.samples::<V, _>(&cells, sample_q8);
                written += put::<V>(chunk, val, keep, alpha);
            }
            continue;
        }
        let (mut qu, mut qv) = (Quotient::new(256 * sw), Quotient::new(256 * sh));
        for chunk in out.chunks_mut(CHUNK) {
            // The columns, then the rows (one quotient's state at a time stays in registers).
            let (mut u, mut v, mut keep) = ([0i32; CHUNK], [0i32; CHUNK], 0u32);
            let mut w = wn;
            for (j, u) in u.iter_mut().take(chunk.len()).enumerate() {
                // A pixel with `W <= 0` (only on the outline) is skipped.
                if w > 0 {
                    *u = q8(&mut qu, xn, w);
                    keep |= 1 << j;
                }
                xn += m11;
                w += m31;
            }
            let mut w = wn;
            for v in v.iter_mut().take(chunk.len()) {
                if w > 0 {
                    *v = q8(&mut qv, yn, w);
                }
                yn += m21;
                w += m31;
            }
            wn = w;
            let cells = source.cells_q8(bytemuck::cast(u), bytemuck::cast(v));
            let val = source.samples::<V, _>(&cells, sample_q8);
            written += put::<V>(chunk, val, keep, alpha);
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
    use crate::arith::Fixed;
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

    const CFG: WarpConfig = WarpConfig { alpha: 255 };

    /// [`warp_into_quad`] in the integer (`fixed`) or the `f32` arithmetic.
    fn wq(
        fixed: bool,
        src: &ImageView<'_, u8>,
        dst: &mut ImageMut<'_, u8>,
        quad: &[Point2<f32>; 4],
        cfg: &WarpConfig,
    ) -> Result<WarpReport> {
        if fixed {
            warp_into_quad::<Fixed>(src, dst, quad, cfg)
        } else {
            warp_into_quad::<f32>(src, dst, quad, cfg)
        }
    }

    /// [`warp_perspective_into`] in the integer (`fixed`) or the `f32` arithmetic.
    fn wp(
        fixed: bool,
        src: &ImageView<'_, u8>,
        dst: &mut ImageMut<'_, u8>,
        h: &Homography<f32>,
        cfg: &WarpConfig,
    ) -> Result<WarpReport> {
        if fixed {
            warp_perspective_into::<Fixed>(src, dst, h, cfg)
        } else {
            warp_perspective_into::<f32>(src, dst, h, cfg)
        }
    }

    #[test]
    fn integer_translation_copies_and_clips() {
        let (w, h) = (20, 12);
        let src = logo(w, h);
        let sv = ImageView::packed(&src, w, h).unwrap();
        for fixed in [false, true] {
            let cfg = CFG;
            // Shift by (+7, -3) into a 24x10 frame: partly outside on the right and the top.
            let mut out = std::vec![0u8; 24 * 10];
            let mut dv = ImageMut::packed(&mut out, 24, 10).unwrap();
            let r = wp(
                fixed,
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
            let ra = wp(
                false,
                &sv,
                &mut ImageMut::packed(&mut a, 200, 150).unwrap(),
                &hm,
                &CFG,
            )
            .unwrap();
            let rb = wp(
                true,
                &sv,
                &mut ImageMut::packed(&mut b, 200, 150).unwrap(),
                &hm,
                &CFG,
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
        for fixed in [false, true] {
            let cfg = CFG;
            let mut dv = ImageMut::packed(&mut out, 50, 40).unwrap();
            let quad = |c: [[f32; 2]; 4]| c.map(|p| Point2::new(p[0], p[1]));
            // Entirely outside: nothing written.
            let far = quad([
                [1e6, 1e6],
                [1e6 + 50.0, 1e6],
                [1e6 + 50.0, 1e6 + 50.0],
                [1e6, 1e6 + 50.0],
            ]);
            assert_eq!(wq(fixed, &sv, &mut dv, &far, &cfg).unwrap().written, 0);
            // Covering the whole frame: every pixel written once.
            let huge = quad([[-1e5, -1e5], [1e5, -1e5], [1e5, 1e5], [-1e5, 1e5]]);
            assert_eq!(wq(fixed, &sv, &mut dv, &huge, &cfg).unwrap().written, 2000);
            // NaN, collinear, folded (bow-tie), non-convex.
            let nan = quad([[f32::NAN, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]);
            assert_eq!(wq(fixed, &sv, &mut dv, &nan, &cfg), Err(Error::NonFinite));
            let line = quad([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [0.0, 10.0]]);
            assert_eq!(wq(fixed, &sv, &mut dv, &line, &cfg), Err(Error::Degenerate));
            let bowtie = quad([[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]]);
            assert_eq!(
                wq(fixed, &sv, &mut dv, &bowtie, &cfg),
                Err(Error::Degenerate)
            );
            let dart = quad([[0.0, 0.0], [20.0, 0.0], [5.0, 5.0], [0.0, 20.0]]);
            assert_eq!(wq(fixed, &sv, &mut dv, &dart, &cfg), Err(Error::Degenerate));
            // H whose vanishing line crosses the logo.
            let cross = hom([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -0.1, 0.0, 1.0]);
            assert_eq!(
                wp(fixed, &sv, &mut dv, &cross, &cfg),
                Err(Error::AtInfinity)
            );
        }
    }

    /// Sources one pixel wide or high (cells with no right or lower neighbour): stretched by 2
    /// along their length, every sample is the exact interpolation (`x_s` stays exactly 0).
    #[test]
    fn one_pixel_wide_and_high_sources() {
        let line = [0u8, 60, 120, 180];
        let want = [0u8, 30, 60, 90, 120, 150, 180];
        for fixed in [false, true] {
            let cfg = CFG;
            let sv = ImageView::packed(&line, 1, 4).unwrap();
            let mut out = [7u8; 2 * 8];
            let mut dv = ImageMut::packed(&mut out, 2, 8).unwrap();
            let stretch = hom([1., 0., 0., 0., 2., 0., 0., 0., 1.]);
            let r = wp(fixed, &sv, &mut dv, &stretch, &cfg).unwrap();
            assert_eq!(r.written, 7, "{cfg:?}");
            let column: Vec<u8> = out.chunks(2).map(|row| row[0]).collect();
            assert_eq!(column[..7], want, "{cfg:?}");
            assert!(
                out.chunks(2).all(|row| row[1] == 7) && column[7] == 7,
                "{cfg:?}"
            );

            let sv = ImageView::packed(&line, 4, 1).unwrap();
            let mut out = [7u8; 8 * 2];
            let mut dv = ImageMut::packed(&mut out, 8, 2).unwrap();
            let stretch = hom([2., 0., 0., 0., 1., 0., 0., 0., 1.]);
            let r = wp(fixed, &sv, &mut dv, &stretch, &cfg).unwrap();
            assert_eq!(r.written, 7, "{cfg:?}");
            assert_eq!(out[..7], want, "{cfg:?}");
            assert!(out[7..].iter().all(|&v| v == 7), "{cfg:?}");
        }
    }

    /// [`walk_row`]'s answer: `(flagged, lanes)`, or the first wrong unflagged lane.
    type Walk = core::result::Result<(u32, u32), (i64, i64, i64)>;

    /// Walks the row `lo..=hi` in [`Guess`]'s chunks with `X = m₁₁ x + b_X`,
    /// `W = m₃₁ x + b_W` and `Y = end W - X` (both axes in `0..=end W`, as the clip keeps
    /// them): the lanes of the row and the flagged ones, or the first unflagged lane whose
    /// guess is not the division's quotient, `(column, guess, quotient)`.
    fn walk_row(
        (m11, bx): (i64, i64),
        (m31, bw): (i64, i64),
        end: i64,
        (lo, hi): (i64, i64),
    ) -> Option<Walk> {
        let (m21, by) = (end * m31 - m11, end * bw - bx);
        let at = |x: i64| (m11 * x + bx, m21 * x + by, m31 * x + bw);
        let g = Guess::row((m11, m21, m31), at(lo).2.min(at(hi).2), (end, end))?;
        let (mut flagged, mut lanes) = (0, 0);
        for x0 in (lo..=hi).step_by(CHUNK) {
            let guesses = g.chunk(&g.terms(at(x0)));
            let axes = [
                (
                    bytemuck::cast::<_, [i32; CHUNK]>(guesses.u),
                    guesses.flag_u,
                    0,
                ),
                (
                    bytemuck::cast::<_, [i32; CHUNK]>(guesses.v),
                    guesses.flag_v,
                    1,
                ),
            ];
            for (q, flags, axis) in axes {
                for (j, &q) in q
                    .iter()
                    .enumerate()
                    .take((hi - x0 + 1).min(CHUNK as i64) as usize)
                {
                    let col = x0 + j as i64;
                    let (x, y, w) = at(col);
                    let n = if axis == 0 { x } else { y };
                    let exact = (256 * n + (w >> 1)).div_euclid(w);
                    lanes += 1;
                    if flags >> j & 1 != 0 {
                        flagged += 1;
                    } else if i64::from(q) != exact {
                        return Some(Err((col, i64::from(q), exact)));
                    }
                }
            }
        }
        Some(Ok((flagged, lanes)))
    }

    /// On a row like the features bench's (a 128-pixel logo across 200 frame columns, mild
    /// perspective, `W` near `2⁴⁰`), the lanes resolve the row (`δ` about 0.004: under 1 %
    /// of the quotients flagged, so under 3 % leaves room for the bound's constants) and the
    /// guesses are the quotients.
    #[test]
    fn guesses_resolve_a_typical_row() {
        let (lo, hi, end) = (60i64, 260i64, 127i64);
        let (m31, bw) = (1i64 << 28, 1i64 << 40);
        // `X / W` from 0 at `lo` to `end` at `hi`.
        let m11 = end * (m31 * hi + bw) / (hi - lo);
        let row = walk_row((m11, -m11 * lo), (m31, bw), end, (lo, hi));
        let (flagged, lanes) = row.expect("the lanes resolve the row").unwrap();
        assert_eq!(lanes, 2 * 201);
        assert!(flagged * 100 < 3 * lanes, "{flagged} of {lanes} flagged");
    }

    /// The lane-at-a-time forms the boards run give the SIMD forms' pixels, bit for bit
    /// (both arithmetics, alpha, partial chunks, a mirror, a strided source).
    #[test]
    fn board_and_simd_forms_agree() {
        let (w, h) = (70, 50);
        let buf = logo(80, h);
        let sv = ImageView::new(&buf, w, h, 80).unwrap();
        let maps = [
            [
                1.46, -0.146, 60.3, 0.166, 1.098, 40.7, -1.37e-4, -9.3e-6, 1.0,
            ],
            [0.7, 0.3, 20.0, -0.25, 0.9, 90.0, 1.2e-3, -8e-4, 1.0],
            [-1.0, 0.0, 150.0, 0.0, 1.0, 10.0, 0.0, 0.0, 1.0],
        ];
        for m in maps {
            let setup = setup((w, h), (200, 150), &hom(m)).unwrap().unwrap();
            for alpha in [255, 100] {
                let run = |simd: bool, fixed: bool| {
                    let mut out = std::vec![7u8; 200 * 150];
                    let mut dv = ImageMut::packed(&mut out, 200, 150).unwrap();
                    let n = match (simd, fixed) {
                        (true, false) => warp_float::<true>(&sv, &mut dv, &setup, alpha).written,
                        (false, false) => warp_float::<false>(&sv, &mut dv, &setup, alpha).written,
                        (true, true) => {
                            warp_fixed::<true>(&sv, &mut dv, &setup, alpha)
                                .unwrap()
                                .written
                        }
                        (false, true) => {
                            warp_fixed::<false>(&sv, &mut dv, &setup, alpha)
                                .unwrap()
                                .written
                        }
                    };
                    (out, n)
                };
                for fixed in [false, true] {
                    let (a, b) = (run(true, fixed), run(false, fixed));
                    assert!(a.1 > 1000, "{m:?}");
                    assert_eq!(a, b, "{m:?} alpha {alpha} fixed {fixed}");
                }
            }
        }
    }

    #[test]
    fn alpha_blends() {
        let src = [200u8; 16];
        let sv = ImageView::packed(&src, 4, 4).unwrap();
        let mut out = [100u8; 16];
        let cfg = WarpConfig { alpha: 64 };
        let fixed = true;
        let r = wp(
            fixed,
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

    /// The integer pixel pairs of four cells, as [`Source::gather`] hands them over.
    fn taps(p: &[u8; 16]) -> (i16x8, i16x8) {
        let lane = |k: usize| i16::from(p[k]);
        (
            i16x8::new(core::array::from_fn(|k| lane(4 * (k / 2) + k % 2))),
            i16x8::new(core::array::from_fn(|k| lane(4 * (k / 2) + 2 + k % 2))),
        )
    }

    proptest! {
        /// The Q8 sampler is the integer bilinear formula exactly; the `f32` sampler is within
        /// rounding of bilinear interpolation in `f64` (half a grey level, plus `f32`'s
        /// rounding of a few operations on values up to 255: `1e-3` is ample).
        #[test]
        fn samplers_match_the_formula(
            p in proptest::array::uniform16(any::<u8>()),
            f in proptest::array::uniform8(0i32..=256),
            g in proptest::array::uniform8(0.0f32..=1.0),
        ) {
            let (fx, fy) = (i32x4::new([f[0], f[1], f[2], f[3]]), i32x4::new([f[4], f[5], f[6], f[7]]));
            let q8 = sample_q8(taps(&p), fx, fy).to_array();
            let (gx, gy) = (f32x4::new([g[0], g[1], g[2], g[3]]), f32x4::new([g[4], g[5], g[6], g[7]]));
            let fl = sample_f32(taps(&p), gx, gy).to_array();
            for j in 0..4 {
                let c: [i32; 4] = core::array::from_fn(|k| i32::from(p[4 * j + k]));
                let (fx, fy) = (f[j], f[4 + j]);
                let t = c[0] * (256 - fx) + c[1] * fx;
                let b = c[2] * (256 - fx) + c[3] * fx;
                prop_assert_eq!(q8[j], ((t << 8) + (b - t) * fy + (1 << 15)) >> 16);
                let (gx, gy) = (f64::from(g[j]), f64::from(g[4 + j]));
                let c = c.map(f64::from);
                let t = c[0] + (c[1] - c[0]) * gx;
                let b = c[2] + (c[3] - c[2]) * gx;
                let exact = t + (b - t) * gy;
                prop_assert!((f64::from(fl[j]) - exact).abs() <= 0.5 + 1e-3, "{} vs {exact}", fl[j]);
            }
        }

        /// The carried quotient is the division's, along straight runs (steps of `n` and `d`
        /// as along a scanline) and after jumps (a fresh division).
        #[test]
        fn carried_quotients_are_exact(
            q0 in 0i64..1 << 21,
            d0 in 1i64..1 << 38,
            r in 0.0f64..1.0,
            a in -(1i64 << 36)..1 << 36,
            b in -(1i64 << 28)..1 << 28,
            jumps in proptest::collection::vec((0usize..40, 0i64..1 << 21), 0..3),
        ) {
            let hi = 1i64 << 21;
            let mut q = Quotient::new(hi);
            let mut n0 = q0 * d0 + (r * d0 as f64) as i64;
            for k in 0..40i64 {
                if let Some(&(_, to)) = jumps.iter().find(|j| j.0 as i64 == k) {
                    n0 = to * (d0 + b * k) - a * k;
                }
                let (n, d) = (n0 + a * k, d0 + b * k);
                if d <= 0 || n < 0 || n / d > hi {
                    break;
                }
                prop_assert_eq!(q.next(n, d), n.div_euclid(d), "k = {}", k);
            }
        }

        /// The SIMD form's fixed-point coordinates (guessed in lanes, the flagged ones
        /// corrected) are the boards' carried quotients bit for bit, on random
        /// quadrilaterals of every size against sources wide and narrow: strong perspective,
        /// quads far larger and far smaller than the source, partly outside the frame.
        #[test]
        fn simd_fixed_is_the_boards(
            c in proptest::array::uniform8(-150.0f64..450.0),
            scale in prop_oneof![0.005f64..0.1, 0.1f64..3.0],
            (w, h) in (1usize..300, 1usize..200),
        ) {
            let src = logo(w, h);
            let sv = ImageView::packed(&src, w, h).unwrap();
            let (cx, cy) = (c.iter().step_by(2).sum::<f64>() / 4.0, c.iter().skip(1).step_by(2).sum::<f64>() / 4.0);
            let quad: [Point2<f64>; 4] = core::array::from_fn(|k| {
                Point2::new(cx + (c[2 * k] - cx) * scale, cy + (c[2 * k + 1] - cy) * scale)
            });
            let (sw, sh) = ((w - 1) as f64, (h - 1) as f64);
            let corners = [
                Point2::new(0.0, 0.0),
                Point2::new(sw, 0.0),
                Point2::new(sw, sh),
                Point2::new(0.0, sh),
            ];
            let Ok(hom) = Homography::<f64>::from_four_points(&corners, &quad).and_then(|h| h.cast::<f32>()) else {
                return Ok(());
            };
            let Ok(Some(setup)) = setup((w, h), (320, 240), &hom) else {
                return Ok(());
            };
            let run = |simd: bool| {
                let mut out = std::vec![7u8; 320 * 240];
                let mut dv = ImageMut::packed(&mut out, 320, 240).unwrap();
                let r = match simd {
                    true => warp_fixed::<true>(&sv, &mut dv, &setup, 255),
                    false => warp_fixed::<false>(&sv, &mut dv, &setup, 255),
                };
                (out, r.map(|r| r.written))
            };
            let (a, b) = (run(true), run(false));
            prop_assert_eq!(a.1, b.1);
            prop_assert!(a.0 == b.0, "the forms' frames differ");
        }

        /// [`Guess`] on synthetic rows (`X / W` running between two source columns from
        /// `lo` to `hi`, `Y / W` the mirror): every lane it does not flag is the exact
        /// quotient, on both axes.
        #[test]
        fn unflagged_guesses_are_exact(
            (shrink, frac) in (0i32..32, 0.5f64..1.0),
            slope in -1.0f64..1.0,
            (u0, u1) in (0.0f64..1.0, 0.0f64..1.0),
            end in 1i64..2000,
            (lo, len) in (0i64..4000, 1i64..600),
        ) {
            let hi = lo + len;
            // `W` up to the warp's largest (`F` keeps `2⁸ X` and `2⁸ end W` below `2⁶²`).
            let w0 = libm::ldexp(frac / (256 * end) as f64, 61 - shrink) as i64;
            // A slope of up to 1/64 of it across the row.
            let m31 = (slope * w0 as f64 / 64.0 / len as f64) as i64;
            let bw = w0 - m31 * lo;
            let w = |x: i64| m31 * x + bw;
            let (xa, xb) = (u0 * end as f64, u1 * end as f64);
            let (xa, xb) = ((xa * w(lo) as f64) as i64, (xb * w(hi) as f64) as i64);
            let m11 = (xb - xa) / len;
            let bx = xa - m11 * lo;
            let x = |x: i64| m11 * x + bx;
            prop_assume!(x(lo) >= 0 && x(hi) >= 0);
            prop_assume!(x(lo) <= end * w(lo) && x(hi) <= end * w(hi));
            if let Some(row) = walk_row((m11, bx), (m31, bw), end, (lo, hi)) {
                prop_assert_eq!(row.map(|_| ()), Ok(()));
            }
        }

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
            let cfg = CFG;
            let written = {
                let mut dv = ImageMut::new(&mut buf[5 * 80 + 10..], 60, 40, 80).unwrap();
                match wq(fixed, &sv, &mut dv, &quad, &cfg) {
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
