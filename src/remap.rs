//! Frame undistortion: a fixed-point lookup table and an integer bilinear remap (OpenCV's
//! `initUndistortRectifyMap` + `remap` with `CV_16SC2` maps and `INTER_LINEAR`).
//!
//! The map stores, for every pixel `(x, y)` of the undistorted frame, where it comes from in
//! the camera's frame: `u = K distort(K'⁻¹ (x, y, 1))` with `K'` the new camera matrix
//! ([`new_camera_matrix`]), in fixed point with 5 fractional bits (1/32 px: OpenCV's
//! `INTER_BITS = 5`), `q = round(32 u)`. [`remap`] then samples bilinearly with 5-bit weights
//! `fx = q_x mod 32`, `fy = q_y mod 32` at the integer pixel `(⌊q_x / 32⌋, ⌊q_y / 32⌋)`,
//! `out = (Σ (32 - fx | fx)(32 - fy | fy) p + 512) >> 10`, which is OpenCV's fixed-point
//! `INTER_LINEAR` for 8-bit images (its Q15 coefficients are these weights times 32), with
//! taps outside the source replaced by the border value (`BORDER_CONSTANT`).
//!
//! Two kinds of map entry ([`MapEntry`]) hold `q`, with the same sampling:
//! - `[i16; 2]`, Q10.5 (`q` itself in an `i16`): 4 bytes a pixel, frames up to
//!   [`MAX_MAP_DIM`] = 1023 px each way; the board's map.
//! - [`WideEntry`], OpenCV's own form for `CV_16SC2` maps: the integer pixel in two `i16`
//!   and the fraction index `32 fy + fx` in a `u16` (OpenCV's `CV_16SC2` + `CV_16UC1` pair,
//!   interleaved): 6 bytes a pixel, frames up to [`WideEntry::MAX_DIM`] = 32767 px each way
//!   (73 MB at 4032x3024, 12 MB at 1920x1080); the host's map for any camera.
//!
//! Both give the same `q` wherever both can hold it, so the same output pixels on a frame
//! both address.
//!
//! RAM for the full Q10.5 map, 4 bytes a pixel ([`map_len`]): 76.8 KB at 160x120, 307 KB at
//! 320x240, 1.23 MB at 640x480 (beyond a 512 KB board). The compact [`GridMap`] keeps one node
//! every `2^shift` pixels and interpolates the map per pixel
//! ([`grid_len`] nodes of 8 bytes: 8-px nodes are 39.5 KB at 640x480 and 10.2 KB at 320x240,
//! 16-px nodes 10.2 KB and 2.7 KB);
//! the error this adds is measured in `docs/notes/calibration.md` (for the bundled camera
//! at 640x480: mean 0.009 px, max 0.06 px with 8-px nodes; mean 0.03 px, max 0.19 px with
//! 16-px nodes).
//!
//! ```
//! use camgeom::camera::{Camera, Distortion, Intrinsics};
//! use camgeom::image::{ImageMut, ImageView};
//! use camgeom::remap::{build_map, map_len, new_camera_matrix, remap};
//!
//! let cam = Camera::new(
//!     Intrinsics::new(60.0f32, 60.0, 31.5, 23.5)?,
//!     Distortion::from_opencv([-0.25, 0.05, 0.0, 0.0, 0.0])?,
//! );
//! let (w, h) = (64, 48);
//! let k_new = new_camera_matrix(&cam, w, h, 0.0)?;
//! let mut map = [[0i16; 2]; map_len(64, 48)];
//! build_map(&cam, &k_new, w, h, &mut map)?;
//! let src = [128u8; 64 * 48];
//! let mut out = [0u8; 64 * 48];
//! remap(&ImageView::packed(&src, w, h)?, &map, &mut ImageMut::packed(&mut out, w, h)?, 0)?;
//! // alpha = 0 keeps only valid pixels: a flat frame stays flat everywhere.
//! assert!(out.iter().all(|&p| p == 128));
//! # Ok::<(), camgeom::Error>(())
//! ```
//!
//! A frame of any size takes [`WideEntry`] maps the same way:
//!
//! ```
//! # use camgeom::camera::{Camera, Distortion, Intrinsics};
//! use camgeom::remap::{MapEntry, WideEntry, build_map, map_len, new_camera_matrix};
//!
//! let cam = Camera::new(
//!     Intrinsics::new(1500.0f64, 1500.0, 959.5, 539.5)?,
//!     Distortion::from_opencv([-0.25, 0.05, 0.0, 0.0, 0.0])?,
//! );
//! let k_new = new_camera_matrix(&cam, 1920, 1080, 0.0)?;
//! let mut map = vec![WideEntry::INVALID; map_len(1920, 1080)];
//! build_map(&cam, &k_new, 1920, 1080, &mut map)?;
//! // Too wide for the Q10.5 map:
//! let mut small = vec![[0i16; 2]; map_len(1920, 1080)];
//! assert_eq!(build_map(&cam, &k_new, 1920, 1080, &mut small), Err(camgeom::Error::InvalidImage));
//! # Ok::<(), camgeom::Error>(())
//! ```

use nalgebra::Point2;

use crate::camera::{Camera, Intrinsics, LensModel};
use crate::image::{ImageMut, ImageView};
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Fractional bits of a map entry (OpenCV's `INTER_BITS`).
pub const MAP_BITS: u32 = 5;
/// Largest width or height a Q10.5 map can address (`i16::MAX / 32`): `[i16; 2]`'s
/// [`MapEntry::MAX_DIM`].
pub const MAX_MAP_DIM: usize = 1023;
/// A Q10.5 map entry for a pixel whose source does not exist (behind the lens, or beyond the
/// model's range, or beyond ±1023.97 px): [`remap`] writes the border value there.
/// `[i16; 2]`'s [`MapEntry::INVALID`].
pub const INVALID: [i16; 2] = [i16::MIN, i16::MIN];
/// Largest width or height of a [`GridMap`]: its far-off nodes are clamped to four times the
/// frame's size in Q.8 (`4 · 256 · 2^20 = 2^30`, within `i32`).
pub const MAX_GRID_DIM: usize = 1 << 20;

mod sealed {
    pub trait Sealed {}
    impl Sealed for [i16; 2] {}
    impl Sealed for super::WideEntry {}
    pub trait SealedPixel {}
    impl SealedPixel for u8 {}
    impl<const N: usize> SealedPixel for [u8; N] {}
}

/// One entry of a full undistortion map: the source position `q = round(32 u)` of one
/// undistorted pixel in Q.5 fixed point, or "no source". Implemented by `[i16; 2]` (Q10.5,
/// 4 bytes, frames up to 1023 px) and [`WideEntry`] (OpenCV's `CV_16SC2` + `CV_16UC1` form,
/// 6 bytes, frames up to 32767 px); [`build_map`] and [`remap`] take either.
pub trait MapEntry: Copy + sealed::Sealed {
    /// Largest width or height of a map of these entries ([`build_map`] refuses larger ones
    /// with [`Error::InvalidImage`]).
    const MAX_DIM: usize;
    /// The entry of a pixel without a source: [`remap`] writes the border value there.
    const INVALID: Self;
    /// The entry holding Q.5 position `(qx, qy)` (pixels times 32), `None` when this kind of
    /// entry cannot hold it (the position is then beyond any frame it addresses).
    fn from_q5(qx: i32, qy: i32) -> Option<Self>;
    /// The Q.5 position, `None` for [`MapEntry::INVALID`].
    fn q5(self) -> Option<[i32; 2]>;
}

/// Q10.5: `[round(32 u_x), round(32 u_y)]`, positions in `(-1024, 1024)` px; `i16::MIN` is
/// kept for [`INVALID`].
impl MapEntry for [i16; 2] {
    const MAX_DIM: usize = MAX_MAP_DIM;
    const INVALID: Self = INVALID;
    #[inline]
    fn from_q5(qx: i32, qy: i32) -> Option<Self> {
        let c = |q: i32| i16::try_from(q).ok().filter(|&v| v != i16::MIN);
        Some([c(qx)?, c(qy)?])
    }
    #[inline]
    fn q5(self) -> Option<[i32; 2]> {
        (self != INVALID).then_some([i32::from(self[0]), i32::from(self[1])])
    }
}

/// A map entry for frames of any camera, OpenCV's split fixed-point map interleaved: the
/// integer source pixel `xy = (⌊q_x / 32⌋, ⌊q_y / 32⌋)` (OpenCV's `CV_16SC2` map1) and the
/// fraction index `frac = 32 (q_y mod 32) + (q_x mod 32)` (its `CV_16UC1` map2), so
/// `q = 32 xy + (frac mod 32, frac / 32)`. Positions in `(-32767, 32768)` px; 6 bytes a pixel.
#[doc(alias = "CV_16SC2")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WideEntry {
    /// Integer source pixel; `[i16::MIN; 2]` is [`WideEntry::INVALID`].
    pub xy: [i16; 2],
    /// Fraction index `32 fy + fx`, each fraction in 1/32 px (`0..1024`).
    pub frac: u16,
}

impl MapEntry for WideEntry {
    const MAX_DIM: usize = i16::MAX as usize;
    const INVALID: Self = Self {
        xy: [i16::MIN, i16::MIN],
        frac: 0,
    };
    #[inline]
    fn from_q5(qx: i32, qy: i32) -> Option<Self> {
        let c = |q: i32| i16::try_from(q >> MAP_BITS).ok().filter(|&v| v != i16::MIN);
        Some(Self {
            xy: [c(qx)?, c(qy)?],
            frac: (((qy & 31) << MAP_BITS) | (qx & 31)) as u16,
        })
    }
    #[inline]
    fn q5(self) -> Option<[i32; 2]> {
        if self.xy == Self::INVALID.xy {
            return None;
        }
        let f = i32::from(self.frac);
        Some([
            (i32::from(self.xy[0]) << MAP_BITS) | (f & 31),
            (i32::from(self.xy[1]) << MAP_BITS) | ((f >> MAP_BITS) & 31),
        ])
    }
}

/// Entries of the full map of a `width x height` frame.
pub const fn map_len(width: usize, height: usize) -> usize {
    width * height
}

/// Nodes of a [`GridMap`] with one node every `2^shift` pixels: `(⌈w/2^s⌉ + 1)(⌈h/2^s⌉ + 1)`.
pub const fn grid_len(width: usize, height: usize, shift: u32) -> usize {
    let s = 1usize << shift;
    (width.div_ceil(s) + 1) * (height.div_ceil(s) + 1)
}

/// The source pixel of undistorted pixel `(x, y)`: `K distort(K'⁻¹ (x, y, 1))`.
fn source<T: Real>(camera: &Camera<T>, k_new: &Intrinsics<T>, x: T, y: T) -> Option<Point2<T>> {
    let n = k_new.pixel_to_normalized(&Point2::new(x, y)).ok()?;
    let d = camera.distort_normalized(&n).ok()?;
    let u = camera.intrinsics.normalized_to_pixel(&d);
    (u.x.finite() && u.y.finite()).then_some(u)
}

/// `round(32 v)` as an `i32`, or `None` when out of its range.
fn q5<T: Real>(v: T) -> Option<i32> {
    let s = libm::rint(v.to_f64() * f64::from(1u32 << MAP_BITS));
    (s >= f64::from(i32::MIN) + 1.0 && s <= f64::from(i32::MAX)).then_some(s as i32)
}

/// Fills `map` (row-major, [`map_len`] entries) for a `width x height` undistorted frame seen
/// through `k_new` (OpenCV's `initUndistortRectifyMap` without rectification, `CV_16SC2`):
/// entry `(x, y)` holds `round(32 K distort(K'⁻¹ (x, y, 1)))` ([`MapEntry`]). `[i16; 2]`
/// entries fold the fractional parts into each coordinate (Q10.5, frames up to 1023 px);
/// [`WideEntry`] keeps OpenCV's split form (frames up to 32767 px).
///
/// Errors: [`Error::InvalidImage`] for a zero size or one beyond the entry's
/// [`MapEntry::MAX_DIM`], `BufferTooSmall("map")`; an entry whose source cannot be computed
/// or held is [`MapEntry::INVALID`].
#[doc(alias = "initUndistortRectifyMap")]
pub fn build_map<T: Real, E: MapEntry>(
    camera: &Camera<T>,
    k_new: &Intrinsics<T>,
    width: usize,
    height: usize,
    map: &mut [E],
) -> Result<()> {
    check_size(width, height, E::MAX_DIM)?;
    let map = map
        .get_mut(..map_len(width, height))
        .ok_or(Error::BufferTooSmall("map"))?;
    for (y, row) in map.chunks_exact_mut(width).enumerate() {
        for (x, e) in row.iter_mut().enumerate() {
            *e = source(camera, k_new, T::lit(x as f64), T::lit(y as f64))
                .and_then(|u| E::from_q5(q5(u.x)?, q5(u.y)?))
                .unwrap_or(E::INVALID);
        }
    }
    Ok(())
}

fn check_size(width: usize, height: usize, max: usize) -> Result<()> {
    if width == 0 || height == 0 || width > max || height > max {
        return Err(Error::InvalidImage);
    }
    Ok(())
}

/// A pixel [`remap`] interpolates: `u8` (grey) or `[u8; N]` (`N` interleaved channels, e.g.
/// RGB), each channel sampled with the same weights.
pub trait RemapPixel: Copy + sealed::SealedPixel {
    /// The pixel with every channel `v` (the border value).
    fn splat(v: u8) -> Self;
    /// `Σ wᵢ pᵢ` rounded, `(Σ wᵢ pᵢ + 512) >> 10` channel by channel, for weights summing to
    /// 1024.
    fn blend(p: [Self; 4], w: [i32; 4]) -> Self;
}

#[inline]
fn blend1(p: [u8; 4], w: [i32; 4]) -> u8 {
    let v = i32::from(p[0]) * w[0]
        + i32::from(p[1]) * w[1]
        + i32::from(p[2]) * w[2]
        + i32::from(p[3]) * w[3];
    ((v + 512) >> 10) as u8
}

impl RemapPixel for u8 {
    #[inline]
    fn splat(v: u8) -> Self {
        v
    }
    #[inline]
    fn blend(p: [Self; 4], w: [i32; 4]) -> Self {
        blend1(p, w)
    }
}

impl<const N: usize> RemapPixel for [u8; N] {
    #[inline]
    fn splat(v: u8) -> Self {
        [v; N]
    }
    #[inline]
    fn blend(p: [Self; 4], w: [i32; 4]) -> Self {
        core::array::from_fn(|c| {
            let ch = |q: &[u8; N]| q.get(c).copied().unwrap_or(0);
            blend1([ch(&p[0]), ch(&p[1]), ch(&p[2]), ch(&p[3])], w)
        })
    }
}

/// One bilinear sample at Q.5 `(mx, my)` (pixels times 32), taps outside `src` set to
/// `border`.
#[inline]
fn sample<P: RemapPixel>(src: &ImageView<'_, P>, mx: i32, my: i32, border: u8) -> P {
    let (x, y) = (mx >> MAP_BITS, my >> MAP_BITS);
    let (fx, fy) = (mx & 31, my & 31);
    let w = [
        (32 - fx) * (32 - fy),
        fx * (32 - fy),
        (32 - fx) * fy,
        fx * fy,
    ];
    // All four taps inside: two rows, two pixels each.
    if x >= 0 && y >= 0 {
        let (xu, yu) = (x as usize, y as usize);
        if let (Some(&[a, b]), Some(&[c, d])) = (
            src.row(yu).and_then(|r| r.get(xu..xu + 2)),
            src.row(yu + 1).and_then(|r| r.get(xu..xu + 2)),
        ) {
            return P::blend([a, b, c, d], w);
        }
    }
    let b = P::splat(border);
    let tap = |xx: i32, yy: i32| -> P {
        if xx < 0 || yy < 0 {
            return b;
        }
        src.get(xx as usize, yy as usize).unwrap_or(b)
    };
    P::blend(
        [tap(x, y), tap(x + 1, y), tap(x, y + 1), tap(x + 1, y + 1)],
        w,
    )
}

/// `dst(x, y) = src(map(x, y))`, bilinear in fixed point (see the module documentation),
/// through a map of either [`MapEntry`] kind, of grey or interleaved multi-channel pixels
/// ([`RemapPixel`]: every channel with the same weights, as OpenCV's `remap` of a `CV_8UC3`
/// image); [`MapEntry::INVALID`] entries and sources wholly outside `src` give `border` (in
/// every channel).
///
/// Errors: `BufferTooSmall("map")` when the map has fewer than `dst`'s pixels.
pub fn remap<E: MapEntry, P: RemapPixel>(
    src: &ImageView<'_, P>,
    map: &[E],
    dst: &mut ImageMut<'_, P>,
    border: u8,
) -> Result<()> {
    let (w, h) = (dst.width(), dst.height());
    let map = map
        .get(..map_len(w, h))
        .ok_or(Error::BufferTooSmall("map"))?;
    for (y, mrow) in map.chunks_exact(w.max(1)).enumerate() {
        let Some(row) = dst.row_mut(y) else { break };
        for (o, m) in row.iter_mut().zip(mrow) {
            *o = match m.q5() {
                Some([mx, my]) => sample(src, mx, my, border),
                None => P::splat(border),
            };
        }
    }
    Ok(())
}

/// A compact undistortion map: the source position at one node every `2^shift` pixels
/// (Q.8 fixed point, `i32`), bilinearly interpolated per pixel by [`GridMap::remap`].
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridMap<'a> {
    nodes: &'a [[i32; 2]],
    width: usize,
    height: usize,
    shift: u32,
    cols: usize,
}

impl<'a> GridMap<'a> {
    /// Builds the nodes into `nodes` ([`grid_len`] entries) for a `width x height` frame
    /// seen through `k_new`, `shift` in `1..=6` (2..64 px). Nodes are Q.8 (`round(256 u)`),
    /// those farther out than four times the frame's size (or 4092 px) clamped there.
    ///
    /// Errors: [`Error::InvalidImage`] for a zero size or one beyond [`MAX_GRID_DIM`], `InvalidParameter("shift")`,
    /// `BufferTooSmall("nodes")`, [`Error::Degenerate`] when a node's source cannot be
    /// computed (the new camera sees beyond the lens model: use a smaller field of view).
    #[doc(alias = "initUndistortRectifyMap")]
    pub fn build<T: Real>(
        camera: &Camera<T>,
        k_new: &Intrinsics<T>,
        width: usize,
        height: usize,
        shift: u32,
        nodes: &'a mut [[i32; 2]],
    ) -> Result<Self> {
        check_size(width, height, MAX_GRID_DIM)?;
        if !(1..=6).contains(&shift) {
            return Err(Error::InvalidParameter("shift"));
        }
        let s = 1usize << shift;
        let cols = width.div_ceil(s) + 1;
        let rows = height.div_ceil(s) + 1;
        let nodes = nodes
            .get_mut(..cols * rows)
            .ok_or(Error::BufferTooSmall("nodes"))?;
        for (j, row) in nodes.chunks_exact_mut(cols).enumerate() {
            for (i, n) in row.iter_mut().enumerate() {
                let u = source(
                    camera,
                    k_new,
                    T::lit((i * s) as f64),
                    T::lit((j * s) as f64),
                )
                .ok_or(Error::Degenerate)?;
                let q8 = |v: T| libm::rint(v.to_f64() * 256.0);
                let (a, b) = (q8(u.x), q8(u.y));
                // Far outside the frame: clamp (the pixel reads the border either way).
                let lim = 4.0 * 256.0 * MAX_MAP_DIM.max(width).max(height) as f64;
                *n = [a.clamp(-lim, lim) as i32, b.clamp(-lim, lim) as i32];
            }
        }
        Ok(Self {
            nodes,
            width,
            height,
            shift,
            cols,
        })
    }

    /// The interpolated Q10.5 map entry of pixel `(x, y)`.
    pub fn entry(&self, x: usize, y: usize) -> [i32; 2] {
        let s = self.shift;
        let (i, j) = (x >> s, y >> s);
        let (dx, dy) = ((x & ((1 << s) - 1)) as i64, (y & ((1 << s) - 1)) as i64);
        let n = |i: usize, j: usize| self.nodes.get(j * self.cols + i).copied().unwrap_or([0, 0]);
        let (a, b, c, d) = (n(i, j), n(i + 1, j), n(i, j + 1), n(i + 1, j + 1));
        let full = 1i64 << s;
        let w = |k: usize| {
            let g = |p: [i32; 2]| p.get(k).copied().unwrap_or(0) as i64;
            g(a) * (full - dx) * (full - dy)
                + g(b) * dx * (full - dy)
                + g(c) * (full - dx) * dy
                + g(d) * dx * dy
        };
        // Q.8 times 2^(2s) down to Q.5, rounded.
        let sh = 2 * s + 3;
        let round = 1i64 << (sh - 1);
        [((w(0) + round) >> sh) as i32, ((w(1) + round) >> sh) as i32]
    }

    /// [`remap`] through the interpolated map, one row at a time (no full map in memory).
    ///
    /// Errors: [`Error::InvalidImage`] when `dst` is not the map's size.
    pub fn remap(
        &self,
        src: &ImageView<'_, u8>,
        dst: &mut ImageMut<'_, u8>,
        border: u8,
    ) -> Result<()> {
        if dst.width() != self.width || dst.height() != self.height {
            return Err(Error::InvalidImage);
        }
        for y in 0..self.height {
            let Some(row) = dst.row_mut(y) else { break };
            for (x, o) in row.iter_mut().enumerate() {
                let [mx, my] = self.entry(x, y);
                *o = sample(src, mx, my, border);
            }
        }
        Ok(())
    }
}

/// The new camera matrix of the undistorted frame (same size), for a Brown-Conrady camera
/// OpenCV's `getOptimalNewCameraMatrix(alpha)`: with the inscribed and circumscribed
/// rectangles of the undistorted image outline (9x9 sampled points), `alpha = 0` maps the
/// inscribed one onto the frame (only valid pixels), `alpha = 1` the circumscribed one (every
/// source pixel kept), linearly between. For a fisheye camera OpenCV's
/// `fisheye::estimateNewCameraMatrixForUndistortRectify(balance = alpha)`: from the
/// undistorted midpoints of the four edges, `f = alpha f_min + (1 - alpha) f_max`, centred on
/// their centroid.
///
/// Errors: `InvalidParameter("alpha")` outside `[0, 1]`, [`Error::InvalidImage`] for a zero
/// size, as [`Camera::undistort_to_normalized`] for an outline point the lens model cannot
/// invert, [`Error::Degenerate`] for a collapsed outline.
#[doc(alias = "getOptimalNewCameraMatrix")]
#[doc(alias = "estimateNewCameraMatrixForUndistortRectify")]
pub fn new_camera_matrix<T: Real>(
    camera: &Camera<T>,
    width: usize,
    height: usize,
    alpha: T,
) -> Result<Intrinsics<T>> {
    if !(alpha >= T::zero() && alpha <= T::one()) {
        return Err(Error::InvalidParameter("alpha"));
    }
    if width == 0 || height == 0 {
        return Err(Error::InvalidImage);
    }
    let (w, h) = (T::lit(width as f64), T::lit(height as f64));
    match camera.lens.model() {
        LensModel::BrownConrady => {
            const N: usize = 9;
            let big = T::max_value().unwrap_or(T::one() / T::EPSILON);
            let (mut ox0, mut oy0, mut ox1, mut oy1) = (big, big, -big, -big);
            let (mut ix0, mut iy0, mut ix1, mut iy1) = (-big, -big, big, big);
            for yi in 0..N {
                for xi in 0..N {
                    let px = Point2::new(
                        T::lit(xi as f64) * (w - T::one()) / T::lit((N - 1) as f64),
                        T::lit(yi as f64) * (h - T::one()) / T::lit((N - 1) as f64),
                    );
                    let p = camera.undistort_to_normalized(&px)?;
                    ox0 = ox0.min(p.x);
                    oy0 = oy0.min(p.y);
                    ox1 = ox1.max(p.x);
                    oy1 = oy1.max(p.y);
                    if xi == 0 {
                        ix0 = ix0.max(p.x);
                    }
                    if xi == N - 1 {
                        ix1 = ix1.min(p.x);
                    }
                    if yi == 0 {
                        iy0 = iy0.max(p.y);
                    }
                    if yi == N - 1 {
                        iy1 = iy1.min(p.y);
                    }
                }
            }
            let (iw, ih, ow, oh) = (ix1 - ix0, iy1 - iy0, ox1 - ox0, oy1 - oy0);
            if !(above(iw, T::zero())
                && above(ih, T::zero())
                && above(ow, T::zero())
                && above(oh, T::zero()))
            {
                return Err(Error::Degenerate);
            }
            let (fx0, fy0) = ((w - T::one()) / iw, (h - T::one()) / ih);
            let (cx0, cy0) = (-fx0 * ix0, -fy0 * iy0);
            let (fx1, fy1) = ((w - T::one()) / ow, (h - T::one()) / oh);
            let (cx1, cy1) = (-fx1 * ox0, -fy1 * oy0);
            let mix = |a: T, b: T| a * (T::one() - alpha) + b * alpha;
            Intrinsics::new(mix(fx0, fx1), mix(fy0, fy1), mix(cx0, cx1), mix(cy0, cy1))
        }
        LensModel::KannalaBrandt => {
            let half = T::lit(0.5);
            let edge = [
                Point2::new(w * half, T::zero()),
                Point2::new(w, h * half),
                Point2::new(w * half, h),
                Point2::new(T::zero(), h * half),
            ];
            let k = &camera.intrinsics;
            let aspect = k.fx() / k.fy();
            let mut pts = [Point2::origin(); 4];
            for (p, e) in pts.iter_mut().zip(edge.iter()) {
                *p = camera.undistort_to_normalized(e)?;
            }
            // OpenCV's "identity ratio" step as it is: the centroid's x and the points' y
            // are scaled by the aspect ratio (the same for fx = fy).
            let mut cn = pts
                .iter()
                .fold(nalgebra::Vector2::zeros(), |a, p| a + p.coords)
                * T::lit(0.25);
            cn.x *= aspect;
            for p in pts.iter_mut() {
                p.y *= aspect;
            }
            let big = T::max_value().unwrap_or(T::one() / T::EPSILON);
            let (mut minx, mut miny, mut maxx, mut maxy) = (big, big, -big, -big);
            for p in &pts {
                minx = minx.min(p.x);
                miny = miny.min(p.y);
                maxx = maxx.max(p.x);
                maxy = maxy.max(p.y);
            }
            let f = [
                w * half / (cn.x - minx),
                w * half / (maxx - cn.x),
                h * half * aspect / (cn.y - miny),
                h * half * aspect / (maxy - cn.y),
            ];
            check_finite(&f)?;
            let fmin = f.iter().fold(big, |a, b| a.min(*b));
            let fmax = f.iter().fold(-big, |a, b| a.max(*b));
            let fnew = alpha * fmin + (T::one() - alpha) * fmax;
            let cx = -cn.x * fnew + w * half;
            let cy = (-cn.y * fnew + h * aspect * half) / aspect;
            Intrinsics::new(fnew, fnew / aspect, cx, cy)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Distortion, Fisheye};
    use std::vec;
    use std::vec::Vec;

    /// A strong barrel lens with its principal point off centre, for a `w x h` frame.
    fn barrel(w: usize, h: usize) -> Camera<f64> {
        let f = 0.8 * w.max(h) as f64;
        Camera::new(
            Intrinsics::new(f, 1.01 * f, 0.52 * w as f64, 0.47 * h as f64).unwrap(),
            Distortion::from_opencv([-0.3, 0.09, 0.001, -0.0005, -0.01]).unwrap(),
        )
    }

    fn fisheye(w: usize, h: usize) -> Camera<f64> {
        let f = 0.3 * w.max(h) as f64;
        Camera::fisheye(
            Intrinsics::new(f, f, 0.5 * w as f64, 0.5 * h as f64).unwrap(),
            Fisheye::from_opencv([0.06, -0.02, 0.008, -0.002]).unwrap(),
        )
    }

    fn pattern(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                ((((x / 7 + y / 5) % 2) * 140 + (3 * x + y) % 97) % 256) as u8
            })
            .collect()
    }

    #[test]
    fn entries_round_trip_their_q5_positions() {
        for q in [
            0, 1, 31, 32, 33, -1, -31, -32, -33, 32735, -32735, 32767, -32767,
        ] {
            let n = <[i16; 2]>::from_q5(q, -q).unwrap();
            assert_eq!(n.q5(), Some([q, -q]));
            let w = WideEntry::from_q5(q, -q).unwrap();
            assert_eq!(w.q5(), Some([q, -q]), "{w:?}");
            // OpenCV's split: the floor and the fraction index 32 fy + fx.
            assert_eq!(i32::from(w.xy[0]), q.div_euclid(32));
            assert_eq!(
                i32::from(w.frac),
                32 * (-q).rem_euclid(32) + q.rem_euclid(32)
            );
        }
        // Q10.5 holds (-1024, 1024) px; the wide entry (-32767, 32768) px.
        assert_eq!(<[i16; 2]>::from_q5(32768, 0), None);
        assert_eq!(<[i16; 2]>::from_q5(0, -32768), None);
        let far = 32767 * 32 + 31;
        assert_eq!(
            WideEntry::from_q5(far, -far + 31).unwrap().q5(),
            Some([far, -far + 31])
        );
        assert_eq!(WideEntry::from_q5(far + 1, 0), None);
        assert_eq!(WideEntry::from_q5(0, -32767 * 32 - 1), None);
        assert_eq!(WideEntry::INVALID.q5(), None);
        assert_eq!(INVALID.q5(), None);
    }

    #[test]
    fn wide_map_equals_the_q10_5_map_on_a_frame_both_address() {
        let (w, h) = (200, 150);
        let src = pattern(w, h);
        let view = ImageView::packed(&src, w, h).unwrap();
        for (cam, alpha) in [
            (barrel(w, h), 0.0),
            (barrel(w, h), 1.0),
            (fisheye(w, h), 0.5),
        ] {
            let k = new_camera_matrix(&cam, w, h, alpha).unwrap();
            let mut narrow = vec![[0i16; 2]; map_len(w, h)];
            let mut wide = vec![WideEntry::INVALID; map_len(w, h)];
            build_map(&cam, &k, w, h, &mut narrow).unwrap();
            build_map(&cam, &k, w, h, &mut wide).unwrap();
            let mut out_of_range = 0;
            for (n, e) in narrow.iter().zip(&wide) {
                match n.q5() {
                    Some(q) => assert_eq!(e.q5(), Some(q)),
                    // Beyond ±1024 px: outside this frame either way.
                    None => {
                        out_of_range += 1;
                        if let Some([x, y]) = e.q5() {
                            assert!(x.abs().max(y.abs()) >= 32767, "{x} {y}");
                        }
                    }
                }
            }
            assert!(out_of_range < w * h / 2);
            let (mut a, mut b) = (vec![0u8; w * h], vec![0u8; w * h]);
            remap(
                &view,
                &narrow,
                &mut ImageMut::packed(&mut a, w, h).unwrap(),
                7,
            )
            .unwrap();
            remap(
                &view,
                &wide,
                &mut ImageMut::packed(&mut b, w, h).unwrap(),
                7,
            )
            .unwrap();
            assert_eq!(a, b);
        }
    }

    #[test]
    fn interleaved_channels_are_each_remapped_as_a_grey_plane() {
        let (w, h) = (90, 70);
        let cam = barrel(w, h);
        let k = new_camera_matrix(&cam, w, h, 1.0).unwrap();
        let mut map = vec![WideEntry::INVALID; map_len(w, h)];
        build_map(&cam, &k, w, h, &mut map).unwrap();
        let planes = [pattern(w, h), pattern(h, w), vec![200u8; w * h]];
        let rgb: Vec<[u8; 3]> = (0..w * h)
            .map(|i| [planes[0][i], planes[1][i], planes[2][i]])
            .collect();
        let mut out = vec![[0u8; 3]; w * h];
        remap(
            &ImageView::packed(&rgb, w, h).unwrap(),
            &map,
            &mut ImageMut::packed(&mut out, w, h).unwrap(),
            9,
        )
        .unwrap();
        for (c, plane) in planes.iter().enumerate() {
            let mut grey = vec![0u8; w * h];
            remap(
                &ImageView::packed(plane, w, h).unwrap(),
                &map,
                &mut ImageMut::packed(&mut grey, w, h).unwrap(),
                9,
            )
            .unwrap();
            assert!(
                out.iter().zip(&grey).all(|(o, g)| o[c] == *g),
                "channel {c}"
            );
        }
        // alpha = 1 keeps every source pixel: some pixels are border.
        assert!(out.contains(&[9, 9, 9]));
    }

    #[test]
    fn a_1500_px_frame_takes_the_wide_map() {
        let (w, h) = (1500, 1100);
        let cam = barrel(w, h);
        let k = new_camera_matrix(&cam, w, h, 0.0).unwrap();
        let mut narrow = vec![[0i16; 2]; map_len(w, h)];
        assert_eq!(
            build_map(&cam, &k, w, h, &mut narrow),
            Err(Error::InvalidImage)
        );
        let mut wide = vec![WideEntry::INVALID; map_len(w, h)];
        build_map(&cam, &k, w, h, &mut wide).unwrap();
        // Every pixel has its source, inside the frame up to the 9x9 sampling of the outline
        // that alpha = 0 inscribes (a fraction of a pixel).
        let (mut lo, mut hi) = ([i32::MAX; 2], [i32::MIN; 2]);
        for e in &wide {
            let q = e.q5().unwrap();
            for c in 0..2 {
                lo[c] = lo[c].min(q[c]);
                hi[c] = hi[c].max(q[c]);
            }
        }
        assert!(lo.iter().all(|&v| v > -32), "{lo:?}");
        assert!(hi[0] < 32 * w as i32 && hi[1] < 32 * h as i32, "{hi:?}");
        assert!(
            hi[0] > 32 * (w as i32 - 4) && hi[1] > 32 * (h as i32 - 4),
            "{hi:?}"
        );
        // A flat frame stays flat inside.
        let src = vec![90u8; w * h];
        let mut out = vec![0u8; w * h];
        remap(
            &ImageView::packed(&src, w, h).unwrap(),
            &wide,
            &mut ImageMut::packed(&mut out, w, h).unwrap(),
            0,
        )
        .unwrap();
        for y in 2..h - 2 {
            assert!(out[y * w + 2..y * w + w - 2].iter().all(|&p| p == 90));
        }
        // The grid map addresses it too, within 1/8 px of the full map with 8-px nodes.
        let mut nodes = vec![[0i32; 2]; grid_len(w, h, 3)];
        let g = GridMap::build(&cam, &k, w, h, 3, &mut nodes).unwrap();
        for y in (0..h).step_by(7) {
            for x in (0..w).step_by(5) {
                let a = g.entry(x, y);
                let b = wide[y * w + x].q5().unwrap();
                assert!((a[0] - b[0]).abs().max((a[1] - b[1]).abs()) <= 4, "{x},{y}");
            }
        }
    }

    #[test]
    fn sizes_beyond_an_entrys_range_are_typed_errors() {
        let cam = barrel(64, 48);
        let k = cam.intrinsics;
        let mut narrow = [[0i16; 2]; 4];
        let mut wide = [WideEntry::INVALID; 4];
        // Checked before the buffer: a 1-px-tall frame of each width.
        for (w, ok) in [(1023, true), (1024, false)] {
            let r = build_map(&cam, &k, w, 1, &mut narrow);
            assert_eq!(
                r.is_ok() || r == Err(Error::BufferTooSmall("map")),
                ok,
                "{w}"
            );
            let r = build_map(&cam, &k, 1, w, &mut narrow);
            assert_eq!(
                r.is_ok() || r == Err(Error::BufferTooSmall("map")),
                ok,
                "{w}"
            );
        }
        for (w, ok) in [
            (1024, true),
            (32767, true),
            (32768, false),
            (usize::MAX, false),
        ] {
            let r = build_map(&cam, &k, w, 1, &mut wide);
            assert_eq!(r == Err(Error::BufferTooSmall("map")), ok, "{w}");
            assert_eq!(r == Err(Error::InvalidImage), !ok, "{w}");
            let r = build_map(&cam, &k, 1, w, &mut wide);
            assert_eq!(r == Err(Error::InvalidImage), !ok, "{w}");
        }
        assert_eq!(
            build_map(&cam, &k, 0, 1, &mut wide),
            Err(Error::InvalidImage)
        );
        let mut nodes = [[0i32; 2]; 4];
        for (w, ok) in [
            (4000, true),
            (MAX_GRID_DIM, true),
            (MAX_GRID_DIM + 1, false),
        ] {
            let r = GridMap::build(&cam, &k, w, 1, 3, &mut nodes);
            assert_eq!(r.err() == Some(Error::InvalidImage), !ok, "{w}");
        }
    }
}
