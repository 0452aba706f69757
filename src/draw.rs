//! Drawing for AR overlays: clipped lines and projected wireframes, into `u8` frames.
//!
//! Lines are clipped to the image (Liang-Barsky) and rasterised with integer Bresenham, so
//! nothing is written outside the frame whatever the endpoints. 3D edges are clipped against a
//! near plane before projection (a cube edge passing behind the camera still draws its visible
//! part) and split into short segments so lens distortion bends them as the camera does.
//!
//! ```
//! use camgeom::camera::{Camera, Intrinsics};
//! use camgeom::draw::{WireframeParams, cube, draw_line_i32, draw_wireframe};
//! use camgeom::image::ImageMut;
//! use camgeom::nalgebra::Vector3;
//! use camgeom::transform::Pose;
//!
//! let mut frame = [0u8; 64 * 64];
//! let mut img = ImageMut::packed(&mut frame, 64, 64)?;
//! // A diagonal from far outside to far outside: clipped to the 64 pixels on the frame.
//! assert_eq!(draw_line_i32(&mut img, -100, -100, 500, 500, 9), 64);
//! img.fill(0);
//! // A unit cube 5 units in front of a pinhole camera (f = 100 px, centre (32, 32)): its base
//! // (depth 5) is the square 32 ± 10, its top (depth 4) the square 32 ± 12.5.
//! let camera = Camera::pinhole(Intrinsics::new(100.0f32, 100.0, 32.0, 32.0)?);
//! let pose = Pose::from_rodrigues(Vector3::zeros(), Vector3::new(0.0, 0.0, 5.0))?;
//! let (vertices, edges) = cube(-0.5, -0.5, 1.0);
//! draw_wireframe(&mut img, &camera, &pose, &vertices, &edges, &WireframeParams::default())?;
//! let on = |x: usize, y: usize| frame[y * 64 + x] == 255;
//! assert!(on(22, 22) && on(42, 22) && on(42, 42) && on(32, 22) && on(20, 32));
//! assert!(!on(32, 32) && !on(25, 32)); // inside the base, off every edge
//! assert!((0..64 * 64).all(|i| !on(i % 64, i / 64) || (19..=45).contains(&(i % 64))));
//! # Ok::<(), camgeom::Error>(())
//! ```

use nalgebra::{Point2, Point3};

use crate::camera::Camera;
use crate::image::ImageMut;
use crate::scalar::Real;
use crate::transform::Pose;
use crate::{Error, Result};

/// Rasterises the segment `(x0, y0)–(x1, y1)` (pixel centres at integers), clipped to the
/// image; returns the number of pixels written. Integer-only.
#[doc(alias = "line")]
pub fn draw_line_i32(
    img: &mut ImageMut<'_, u8>,
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
    value: u8,
) -> usize {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let inside = |x: i32, y: i32| (0..w).contains(&i64::from(x)) && (0..h).contains(&i64::from(y));
    if inside(x0, y0) && inside(x1, y1) {
        // Nothing to clip (the clip below would give back these endpoints, with four
        // 64-bit divisions: library calls on a Cortex-M).
        return bresenham(img, x0.into(), y0.into(), x1.into(), y1.into(), value);
    }
    draw_line_clipped(img, x0, y0, x1, y1, value)
}

/// [`draw_line_i32`]'s general path: Liang-Barsky on rationals, then Bresenham.
fn draw_line_clipped(
    img: &mut ImageMut<'_, u8>,
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
    value: u8,
) -> usize {
    let (w, h) = (img.width() as i64, img.height() as i64);
    // Clip in i64 with Liang-Barsky on rationals: t = num / den, kept as (num, den) pairs.
    let (ax, ay, bx, by) = (i64::from(x0), i64::from(y0), i64::from(x1), i64::from(y1));
    let (dx, dy) = (bx - ax, by - ay);
    // t in [t0, t1] as fractions p/q with q > 0.
    let (mut t0n, mut t0d, mut t1n, mut t1d) = (0i64, 1i64, 1i64, 1i64);
    for (p, q) in [(-dx, ax), (dx, w - 1 - ax), (-dy, ay), (dy, h - 1 - ay)] {
        // Constraint p t <= q.
        if p == 0 {
            if q < 0 {
                return 0;
            }
            continue;
        }
        // t <= q/p (p > 0) or t >= q/p (p < 0); normalise to a positive denominator.
        let (n, d) = if p > 0 { (q, p) } else { (-q, -p) };
        if p > 0 {
            if n * t1d < t1n * d {
                (t1n, t1d) = (n, d);
            }
        } else if n * t0d > t0n * d {
            (t0n, t0d) = (n, d);
        }
    }
    if t0n * t1d > t1n * t0d {
        return 0;
    }
    // Clipped endpoints, rounded to the nearest pixel towards the inside.
    let at = |n: i64, d: i64| -> (i64, i64) {
        let px = ax + div_round(dx * n, d);
        let py = ay + div_round(dy * n, d);
        // `max` then `min`, not `clamp`: `clamp` asserts `min <= max`, a panic path the
        // optimiser cannot remove (it does not know that `w, h >= 1`).
        (px.max(0).min(w - 1), py.max(0).min(h - 1))
    };
    let (sx, sy) = at(t0n, t0d);
    let (ex, ey) = at(t1n, t1d);
    bresenham(img, sx, sy, ex, ey, value)
}

fn div_round(n: i64, d: i64) -> i64 {
    // `checked_*`: `/` and `%` panic for `d = 0` and for `i64::MIN / -1`.
    let (Some(q), Some(r)) = (n.checked_div(d), n.checked_rem(d)) else {
        return 0;
    };
    if 2 * r.abs() >= d.abs() {
        q + if (n < 0) != (d < 0) { -1 } else { 1 }
    } else {
        q
    }
}

fn bresenham(img: &mut ImageMut<'_, u8>, x0: i64, y0: i64, x1: i64, y1: i64, value: u8) -> usize {
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let (mut x, mut y, mut err) = (x0, y0, dx + dy);
    let mut written = 0;
    // At most max(|dx|, |dy|) + 1 pixels: the loop is bounded by the clipped length.
    for _ in 0..=dx.max(-dy) {
        if img.set(x as usize, y as usize, value) {
            written += 1;
        }
        if x == x1 && y == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
    written
}

/// [`draw_line_i32`] for float endpoints; [`Error::NonFinite`] for NaN/inf. Endpoints far
/// outside the image are first clipped in `f64` (Cohen-Sutherland, intersections computed on
/// the clipping edge itself so huge coordinates keep their precision), so they cannot overflow
/// `i32`.
#[doc(alias = "line")]
pub fn draw_line<T: Real>(
    img: &mut ImageMut<'_, u8>,
    a: &Point2<T>,
    b: &Point2<T>,
    value: u8,
) -> Result<usize> {
    crate::scalar::check_finite(&[a.x, a.y, b.x, b.y])?;
    // A box 2 pixels larger than the image; the integer clip does the exact work.
    let (wx, hy) = (
        i32::try_from(img.width()).unwrap_or(i32::MAX - 1) + 1,
        i32::try_from(img.height()).unwrap_or(i32::MAX - 1) + 1,
    );
    // Both endpoints in the box: rounded in `T`, the same integers as the `f64` path below
    // gives them (an `f32` rounds to an integer exactly in either type), without the
    // software `f64` arithmetic of a single-precision core.
    if let (Some(x0), Some(y0), Some(x1), Some(y1)) = (
        a.x.round_within(-2, wx),
        a.y.round_within(-2, hy),
        b.x.round_within(-2, wx),
        b.y.round_within(-2, hy),
    ) {
        return Ok(draw_line_i32(img, x0, y0, x1, y1, value));
    }
    Ok(draw_line_f64(img, a, b, value))
}

/// [`draw_line`]'s general path: Cohen-Sutherland in `f64` down to the box, then rounding.
fn draw_line_f64<T: Real>(
    img: &mut ImageMut<'_, u8>,
    a: &Point2<T>,
    b: &Point2<T>,
    value: u8,
) -> usize {
    let (x_lo, y_lo) = (-2.0f64, -2.0f64);
    let (x_hi, y_hi) = (img.width() as f64 + 1.0, img.height() as f64 + 1.0);
    let code = |x: f64, y: f64| -> u8 {
        u8::from(x < x_lo)
            | u8::from(x > x_hi) << 1
            | u8::from(y < y_lo) << 2
            | u8::from(y > y_hi) << 3
    };
    let (mut p, mut q) = ((a.x.to_f64(), a.y.to_f64()), (b.x.to_f64(), b.y.to_f64()));
    let (mut cp, mut cq) = (code(p.0, p.1), code(q.0, q.1));
    // Each step moves one endpoint onto a box edge and clears at least one outcode bit:
    // at most 4 steps per endpoint.
    for _ in 0..8 {
        if cp | cq == 0 {
            break;
        }
        if cp & cq != 0 {
            return 0;
        }
        let (c, (x0, y0), (x1, y1)) = if cp != 0 { (cp, p, q) } else { (cq, q, p) };
        let moved = if c & 0b1000 != 0 {
            (x0 + (x1 - x0) * (y_hi - y0) / (y1 - y0), y_hi)
        } else if c & 0b0100 != 0 {
            (x0 + (x1 - x0) * (y_lo - y0) / (y1 - y0), y_lo)
        } else if c & 0b0010 != 0 {
            (x_hi, y0 + (y1 - y0) * (x_hi - x0) / (x1 - x0))
        } else {
            (x_lo, y0 + (y1 - y0) * (x_lo - x0) / (x1 - x0))
        };
        if cp != 0 {
            p = moved;
            cp = code(p.0, p.1);
        } else {
            q = moved;
            cq = code(q.0, q.1);
        }
    }
    if cp | cq != 0 || !(p.0.is_finite() && p.1.is_finite() && q.0.is_finite() && q.1.is_finite()) {
        return 0;
    }
    let r = |v: f64| libm::round(v) as i32;
    draw_line_i32(img, r(p.0), r(p.1), r(q.0), r(q.1), value)
}

/// Options of [`draw_wireframe`], as the user writes them; checked by [`Self::check`] into the
/// [`WireframeParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireframeConfig<T: Real = f32> {
    /// Near clipping plane (camera `Z`, world units), finite and `> 0`: edge parts closer are
    /// not drawn.
    pub near: T,
    /// Segments per edge (1..=64): more follow the lens distortion's curvature better.
    pub segments: u8,
    /// Pixel value written.
    pub value: u8,
}

impl<T: Real> Default for WireframeConfig<T> {
    fn default() -> Self {
        Self {
            near: T::lit(1e-3),
            segments: 8,
            value: 255,
        }
    }
}

impl<T: Real> WireframeConfig<T> {
    /// Checks the ranges documented on each field once: [`draw_wireframe`] takes the checked
    /// [`WireframeParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field (`wireframe.near`,
    /// `wireframe.segments`).
    pub fn check(&self) -> Result<WireframeParams<T>> {
        if !(self.near.finite() && self.near > T::zero()) {
            return Err(Error::InvalidParameter("wireframe.near"));
        }
        if !(1..=64).contains(&self.segments) {
            return Err(Error::InvalidParameter("wireframe.segments"));
        }
        Ok(WireframeParams(*self))
    }
}

/// A [`WireframeConfig`] that passed [`WireframeConfig::check`]: a finite near plane `> 0` and
/// `1..=64` segments an edge. What [`draw_wireframe`] takes, so that no call checks it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WireframeParams<T: Real = f32>(WireframeConfig<T>);

impl<T: Real> WireframeParams<T> {
    /// The checked configuration.
    pub const fn config(&self) -> &WireframeConfig<T> {
        &self.0
    }
}

impl<T: Real> Default for WireframeParams<T> {
    /// The checked [`WireframeConfig::default`].
    fn default() -> Self {
        Self(WireframeConfig::default())
    }
}

impl<T: Real> TryFrom<WireframeConfig<T>> for WireframeParams<T> {
    type Error = Error;
    fn try_from(c: WireframeConfig<T>) -> Result<Self> {
        c.check()
    }
}

/// Projects the `edges` (index pairs into `vertices`, world frame) through `camera` at `pose`
/// and draws them. Returns the number of pixels written.
///
/// Errors: [`Error::InvalidParameter`] for an edge index out of range; [`Error::NonFinite`].
#[doc(alias = "projectPoints")]
#[doc(alias = "drawFrameAxes")]
pub fn draw_wireframe<T: Real>(
    img: &mut ImageMut<'_, u8>,
    camera: &Camera<T>,
    pose: &Pose<T>,
    vertices: &[Point3<T>],
    edges: &[(u8, u8)],
    params: &WireframeParams<T>,
) -> Result<usize> {
    let cfg = params.config();
    let mut written = 0usize;
    for &(i, j) in edges {
        let a = vertices
            .get(usize::from(i))
            .ok_or(Error::InvalidParameter("edges"))?;
        let b = vertices
            .get(usize::from(j))
            .ok_or(Error::InvalidParameter("edges"))?;
        let (mut ca, mut cb) = (pose.apply(a), pose.apply(b));
        crate::scalar::check_finite(&[ca.x, ca.y, ca.z, cb.x, cb.y, cb.z])?;
        // Near-plane clip: keep the part with Z >= near.
        if ca.z < cfg.near && cb.z < cfg.near {
            continue;
        }
        if ca.z < cfg.near {
            ca = cb + (ca - cb) * ((cb.z - cfg.near) / (cb.z - ca.z));
        } else if cb.z < cfg.near {
            cb = ca + (cb - ca) * ((ca.z - cfg.near) / (ca.z - cb.z));
        }
        let n = T::lit(f64::from(cfg.segments));
        let mut prev = camera.project_camera_point(&ca).ok();
        for s in 1..=cfg.segments {
            let p = ca + (cb - ca) * (T::lit(f64::from(s)) / n);
            let cur = camera.project_camera_point(&p).ok();
            if let (Some(u), Some(v)) = (prev, cur) {
                written += draw_line(img, &u, &v, cfg.value)?;
            }
            prev = cur;
        }
    }
    Ok(written)
}

/// A cube of side `size` standing on the target plane with one corner at `(x, y, 0)`: vertices
/// `(x + {0, s}, y + {0, s}, {0, -s})` and its 12 edges. The top face is at `Z = -s`: towards a
/// camera that sees the target from the front in OpenCV's convention (target `Z` pointing away
/// from the camera).
pub fn cube<T: Real>(x: T, y: T, size: T) -> ([Point3<T>; 8], [(u8, u8); 12]) {
    let z = T::zero();
    let v = [
        Point3::new(x, y, z),
        Point3::new(x + size, y, z),
        Point3::new(x + size, y + size, z),
        Point3::new(x, y + size, z),
        Point3::new(x, y, -size),
        Point3::new(x + size, y, -size),
        Point3::new(x + size, y + size, -size),
        Point3::new(x, y + size, -size),
    ];
    let e = [
        (0, 1),
        (1, 2),
        (2, 3),
        (3, 0),
        (4, 5),
        (5, 6),
        (6, 7),
        (7, 4),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    (v, e)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use nalgebra::Vector3;

    fn count(buf: &[u8]) -> usize {
        buf.iter().filter(|&&v| v != 0).count()
    }

    /// The in-box shortcuts (rounding in `T`, no integer clip) draw what the general path
    /// (`f64` clip, rounding, Liang-Barsky) draws, pixel for pixel: random segments with
    /// endpoints in, near and beyond the box, many on half-pixel ties, in `f32` and `f64`.
    #[test]
    fn in_box_shortcut_draws_what_the_general_path_draws() {
        let mut g = crate::rng::Pcg32::new(31);
        let (w, h) = (23usize, 17usize);
        for k in 0..4000 {
            let mut coord = |n: usize| {
                let v = g.uniform(-6.0, n as f64 + 6.0);
                if k % 3 == 0 {
                    (v * 2.0).round() / 2.0
                } else {
                    v
                }
            };
            let (a, b) = (
                Point2::new(coord(w), coord(h)),
                Point2::new(coord(w), coord(h)),
            );
            let (mut fast, mut slow) = ([0u8; 23 * 17], [0u8; 23 * 17]);
            for (a, b) in [(a, b), (b, a)] {
                let n1 =
                    draw_line(&mut ImageMut::packed(&mut fast, w, h).unwrap(), &a, &b, 9).unwrap();
                let n2 = draw_line_f64(&mut ImageMut::packed(&mut slow, w, h).unwrap(), &a, &b, 9);
                assert_eq!((n1, fast), (n2, slow), "{a} {b}");
                let (a32, b32) = (a.cast::<f32>(), b.cast::<f32>());
                let n1 = draw_line(
                    &mut ImageMut::packed(&mut fast, w, h).unwrap(),
                    &a32,
                    &b32,
                    7,
                )
                .unwrap();
                let n2 = draw_line_f64(
                    &mut ImageMut::packed(&mut slow, w, h).unwrap(),
                    &a32,
                    &b32,
                    7,
                );
                assert_eq!((n1, fast), (n2, slow), "{a32} {b32}");
            }
        }
    }

    /// The integer shortcut (both endpoints inside: no clip) against the clip path.
    #[test]
    fn inside_shortcut_draws_what_the_clip_draws() {
        let (w, h) = (13usize, 9usize);
        for x0 in -2..15 {
            for y0 in -2..11 {
                for (x1, y1) in [(0, 0), (12, 8), (5, 3), (12, 0), (3, 8), (x0, 4), (7, y0)] {
                    let (mut a, mut b) = ([0u8; 13 * 9], [0u8; 13 * 9]);
                    let n1 = draw_line_i32(
                        &mut ImageMut::packed(&mut a, w, h).unwrap(),
                        x0,
                        y0,
                        x1,
                        y1,
                        5,
                    );
                    let n2 = draw_line_clipped(
                        &mut ImageMut::packed(&mut b, w, h).unwrap(),
                        x0,
                        y0,
                        x1,
                        y1,
                        5,
                    );
                    assert_eq!((n1, a), (n2, b), "({x0},{y0})-({x1},{y1})");
                }
            }
        }
    }

    #[test]
    fn lines_are_clipped_and_exact_inside() {
        let mut buf = [0u8; 20 * 10];
        let mut img = ImageMut::packed(&mut buf, 20, 10).unwrap();
        // Horizontal line across the whole image and beyond: exactly the row.
        assert_eq!(draw_line_i32(&mut img, -100, 3, 1000, 3, 9), 20);
        // Entirely outside: nothing.
        assert_eq!(draw_line_i32(&mut img, -10, -10, -1, -50, 9), 0);
        assert_eq!(
            draw_line_i32(&mut img, i32::MIN, i32::MIN, i32::MAX, i32::MIN, 9),
            0
        );
        // Diagonal through the image from far outside: one pixel per row.
        assert_eq!(draw_line_i32(&mut img, -1000, -1000, 1000, 1000, 5), 10);
        assert_eq!(count(&buf), 20 + 10 - 1);
        let mut buf = [0u8; 20 * 10];
        let mut img = ImageMut::packed(&mut buf, 20, 10).unwrap();
        // Extreme float endpoints and NaN never panic.
        assert!(
            draw_line(
                &mut img,
                &Point2::new(-1e30f32, 5.0),
                &Point2::new(1e30, 5.0),
                1
            )
            .unwrap()
                == 20
        );
        assert_eq!(
            draw_line(
                &mut img,
                &Point2::new(f32::NAN, 5.0),
                &Point2::new(1.0, 5.0),
                1
            ),
            Err(Error::NonFinite)
        );
        // A single point.
        assert_eq!(draw_line_i32(&mut img, 4, 4, 4, 4, 7), 1);
    }

    #[test]
    fn cube_projects_inside_and_clips_behind_the_camera() {
        let k = Intrinsics::new(300.0f32, 300.0, 160.0, 120.0).unwrap();
        let cam = Camera::pinhole(k);
        let (v, e) = cube(-0.05f32, -0.05, 0.1);
        let pose =
            Pose::from_rodrigues(Vector3::new(0.3, 0.2, 0.0), Vector3::new(0.0, 0.0, 0.5)).unwrap();
        let mut buf = [0u8; 320 * 240];
        let mut img = ImageMut::packed(&mut buf, 320, 240).unwrap();
        let n = draw_wireframe(&mut img, &cam, &pose, &v, &e, &WireframeParams::default()).unwrap();
        assert!(n > 200, "{n}");
        // Every projected vertex is lit.
        for p in &v {
            let u = cam.project(&pose, p).unwrap();
            assert_eq!(
                img.as_view()
                    .get(u.x.round() as usize, u.y.round() as usize),
                Some(255)
            );
        }
        // Camera inside the cube: parts behind are clipped, nothing panics or overflows.
        let inside = Pose::from_rodrigues(Vector3::zeros(), Vector3::new(0.0, 0.0, 0.01)).unwrap();
        draw_wireframe(&mut img, &cam, &inside, &v, &e, &WireframeParams::default()).unwrap();
        // Bad edges and segment counts are errors.
        assert_eq!(
            draw_wireframe(
                &mut img,
                &cam,
                &pose,
                &v,
                &[(0, 8)],
                &WireframeParams::default()
            ),
            Err(Error::InvalidParameter("edges"))
        );
        let config = WireframeConfig::<f32>::default();
        for (bad, field) in [
            (
                WireframeConfig {
                    segments: 0,
                    ..config
                },
                "wireframe.segments",
            ),
            (
                WireframeConfig {
                    segments: 65,
                    ..config
                },
                "wireframe.segments",
            ),
            (
                WireframeConfig {
                    near: 0.0,
                    ..config
                },
                "wireframe.near",
            ),
            (
                WireframeConfig {
                    near: f32::NAN,
                    ..config
                },
                "wireframe.near",
            ),
            (
                WireframeConfig {
                    near: f32::INFINITY,
                    ..config
                },
                "wireframe.near",
            ),
        ] {
            assert_eq!(bad.check(), Err(Error::InvalidParameter(field)));
        }
    }
}
