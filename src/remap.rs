//! Frame undistortion: a fixed-point lookup table and an integer bilinear remap (OpenCV's
//! `initUndistortRectifyMap` + `remap` with `CV_16SC2` maps and `INTER_LINEAR`).
//!
//! The map stores, for every pixel `(x, y)` of the undistorted frame, where it comes from in
//! the camera's frame: `u = K distort(K'⁻¹ (x, y, 1))` with `K'` the new camera matrix
//! ([`new_camera_matrix`]), in Q10.5 fixed point (`i16` per coordinate, 1/32 px: OpenCV's
//! `INTER_BITS = 5`). [`remap`] then samples bilinearly with 5-bit weights,
//! `out = (Σ (32 - fx | fx)(32 - fy | fy) p + 512) >> 10`, which is OpenCV's fixed-point
//! `INTER_LINEAR` for 8-bit images (its Q15 coefficients are these weights times 32), with
//! taps outside the source replaced by the border value (`BORDER_CONSTANT`).
//!
//! RAM for the full map, 4 bytes a pixel ([`map_len`]): 76.8 KB at 160x120, 307 KB at
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

use nalgebra::Point2;

use crate::camera::{Camera, Intrinsics, LensModel};
use crate::image::{ImageMut, ImageView};
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Fractional bits of a map entry (OpenCV's `INTER_BITS`).
pub const MAP_BITS: u32 = 5;
/// Largest width or height a Q10.5 map can address (`i16::MAX / 32`).
pub const MAX_MAP_DIM: usize = 1023;
/// A map entry for a pixel whose source does not exist (behind the lens, or beyond the
/// model's range): [`remap`] writes the border value there.
pub const INVALID: [i16; 2] = [i16::MIN, i16::MIN];

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

/// `round(32 v)` saturated to `i16`, or `None` when out of range.
fn q5<T: Real>(v: T) -> Option<i16> {
    let s = libm::rint(v.to_f64() * f64::from(1u32 << MAP_BITS));
    (s >= f64::from(i16::MIN) + 1.0 && s <= f64::from(i16::MAX)).then_some(s as i16)
}

/// Fills `map` (row-major, [`map_len`] entries) for a `width x height` undistorted frame seen
/// through `k_new` (OpenCV's `initUndistortRectifyMap` without rectification, `CV_16SC2`
/// with the fractional parts folded into each coordinate).
///
/// Errors: [`Error::InvalidImage`] for a zero size or one beyond [`MAX_MAP_DIM`],
/// `BufferTooSmall("map")`; an entry whose source cannot be computed is [`INVALID`].
#[doc(alias = "initUndistortRectifyMap")]
pub fn build_map<T: Real>(
    camera: &Camera<T>,
    k_new: &Intrinsics<T>,
    width: usize,
    height: usize,
    map: &mut [[i16; 2]],
) -> Result<()> {
    check_size(width, height)?;
    let map = map
        .get_mut(..map_len(width, height))
        .ok_or(Error::BufferTooSmall("map"))?;
    for (y, row) in map.chunks_exact_mut(width).enumerate() {
        for (x, e) in row.iter_mut().enumerate() {
            *e = source(camera, k_new, T::lit(x as f64), T::lit(y as f64))
                .and_then(|u| Some([q5(u.x)?, q5(u.y)?]))
                .unwrap_or(INVALID);
        }
    }
    Ok(())
}

fn check_size(width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_MAP_DIM || height > MAX_MAP_DIM {
        return Err(Error::InvalidImage);
    }
    Ok(())
}

/// One bilinear 8-bit sample at Q10.5 `(mx, my)`, taps outside `src` set to `border`.
#[inline]
fn sample(src: &ImageView<'_, u8>, mx: i32, my: i32, border: u8) -> u8 {
    let (x, y) = (mx >> MAP_BITS, my >> MAP_BITS);
    let (fx, fy) = (mx & 31, my & 31);
    let tap = |xx: i32, yy: i32| -> i32 {
        if xx < 0 || yy < 0 {
            return border as i32;
        }
        src.get(xx as usize, yy as usize).unwrap_or(border) as i32
    };
    let v = tap(x, y) * (32 - fx) * (32 - fy)
        + tap(x + 1, y) * fx * (32 - fy)
        + tap(x, y + 1) * (32 - fx) * fy
        + tap(x + 1, y + 1) * fx * fy;
    ((v + 512) >> 10) as u8
}

/// `dst(x, y) = src(map(x, y))`, bilinear in fixed point (see the module documentation);
/// [`INVALID`] entries and sources wholly outside `src` give `border`.
///
/// Errors: `BufferTooSmall("map")` when the map has fewer than `dst`'s pixels.
pub fn remap(
    src: &ImageView<'_, u8>,
    map: &[[i16; 2]],
    dst: &mut ImageMut<'_, u8>,
    border: u8,
) -> Result<()> {
    let (w, h) = (dst.width(), dst.height());
    let map = map
        .get(..map_len(w, h))
        .ok_or(Error::BufferTooSmall("map"))?;
    for (y, mrow) in map.chunks_exact(w.max(1)).enumerate() {
        let Some(row) = dst.row_mut(y) else { break };
        for (o, m) in row.iter_mut().zip(mrow) {
            *o = if *m == INVALID {
                border
            } else {
                sample(src, m[0] as i32, m[1] as i32, border)
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
    /// seen through `k_new`, `shift` in `1..=6` (2..64 px).
    ///
    /// Errors: [`Error::InvalidImage`] for a bad size, `InvalidParameter("shift")`,
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
        check_size(width, height)?;
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
                // Far outside any frame: clamp (the pixel reads the border either way).
                let lim = 4.0 * 256.0 * MAX_MAP_DIM as f64;
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
