//! Sub-pixel corner refinement by gradient orthogonality (OpenCV's `cornerSubPix`).

use nalgebra::Point2;

use crate::image::ImageView;
use crate::{Error, Result};

/// Largest half window accepted (a 31x31 window): keeps the per-iteration cost bounded.
pub const MAX_HALF_WINDOW: u8 = 15;

/// Side of the resampled patch buffer: the largest window plus one pixel each side.
const PATCH: usize = 2 * MAX_HALF_WINDOW as usize + 3;

/// Parameters of [`corner_subpix`], OpenCV's `winSize`, `zeroZone = (-1, -1)` and
/// `TermCriteria(COUNT + EPS, max_iterations, epsilon)`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SubPixConfig {
    /// Half the window side: the window is `(2 h + 1)²` pixels (OpenCV's `winSize = (h, h)`;
    /// `5` is OpenCV's `(5, 5)`, an 11x11 window). `1..=MAX_HALF_WINDOW`.
    pub half_window: u8,
    /// Iterations at most (`1..=100`).
    pub max_iterations: u8,
    /// Stop when the squared step `|Δ|²` is at most `epsilon` (OpenCV compares the squared
    /// step with `epsilon` itself). Finite, `>= 0`.
    pub epsilon: f32,
}

impl Default for SubPixConfig {
    /// OpenCV's calibration sample: 11x11, 30 iterations, 0.001.
    fn default() -> Self {
        Self {
            half_window: 5,
            max_iterations: 30,
            epsilon: 1e-3,
        }
    }
}

impl SubPixConfig {
    /// Errors with `InvalidParameter` naming the field out of range.
    pub fn validate(&self) -> Result<()> {
        if self.half_window == 0 || self.half_window > MAX_HALF_WINDOW {
            return Err(Error::InvalidParameter("subpix.half_window"));
        }
        if self.max_iterations == 0 || self.max_iterations > 100 {
            return Err(Error::InvalidParameter("subpix.max_iterations"));
        }
        if !(self.epsilon >= 0.0 && self.epsilon.is_finite()) {
            return Err(Error::InvalidParameter("subpix.epsilon"));
        }
        Ok(())
    }
}

/// Bilinear sample with a replicated border (OpenCV's `getRectSubPix` border).
#[inline]
fn at(img: &ImageView<'_, u8>, x: isize, y: isize) -> f32 {
    let w = img.width() as isize;
    let xc = x.min(w - 1).max(0) as usize;
    img.row_clamped(y).get(xc).copied().unwrap_or(0) as f32
}

/// Refines each corner in place by the gradient-orthogonality condition of OpenCV's
/// `cornerSubPix`: inside a `(2h+1)²` window around the estimate `q`, every image gradient
/// `gᵢ` at pixel `pᵢ` is orthogonal to `pᵢ - q` at a true corner, so `q` solves
///
/// `(Σ wᵢ gᵢ gᵢᵀ) q = Σ wᵢ gᵢ gᵢᵀ pᵢ`,  `wᵢ = exp(-(dxᵢ/h)² - (dyᵢ/h)²)`,
///
/// with gradients by central differences of the window resampled bilinearly at `q`'s
/// sub-pixel offset. Each iteration re-centres the window; iteration stops after
/// `max_iterations` or when the squared step is at most `epsilon`. A corner that moves more
/// than `h` from its start keeps its start (OpenCV's rule for poor convergence), as does one
/// whose window has no gradient (a flat patch).
///
/// Errors: `InvalidParameter` for a bad `cfg`, [`Error::NonFinite`] for a non-finite corner.
pub fn corner_subpix(
    image: &ImageView<'_, u8>,
    corners: &mut [Point2<f32>],
    cfg: &SubPixConfig,
) -> Result<()> {
    cfg.validate()?;
    if corners
        .iter()
        .any(|c| !(c.x.is_finite() && c.y.is_finite()))
    {
        return Err(Error::NonFinite);
    }
    let h = cfg.half_window as isize;
    let n = (2 * h + 1) as usize;
    // Gaussian weights as OpenCV: exp(-((i - h)/h)²) per axis.
    let mut mask = [0.0f32; 2 * MAX_HALF_WINDOW as usize + 1];
    for (i, m) in mask.iter_mut().take(n).enumerate() {
        let t = (i as f32 - h as f32) / h as f32;
        *m = libm::expf(-t * t);
    }
    let (w, ht) = (image.width() as f32, image.height() as f32);
    for c in corners.iter_mut() {
        let start = *c;
        let mut q = start;
        for _ in 0..cfg.max_iterations {
            // Window of (2h + 3)² samples at q + (j - h - 1, i - h - 1), bilinear.
            let (fx, fy) = (libm::floorf(q.x), libm::floorf(q.y));
            let (ax, ay) = (q.x - fx, q.y - fy);
            let (ix, iy) = (fx as isize, fy as isize);
            // The resampled window, (2h + 3)² values: OpenCV's `getRectSubPix`.
            let side = n + 2;
            let mut patch = [0.0f32; PATCH * PATCH];
            for (i, row) in patch.chunks_exact_mut(PATCH).take(side).enumerate() {
                let y = iy + i as isize - h - 1;
                for (j, v) in row.iter_mut().take(side).enumerate() {
                    let x = ix + j as isize - h - 1;
                    let t = at(image, x, y) * (1.0 - ax) + at(image, x + 1, y) * ax;
                    let u = at(image, x, y + 1) * (1.0 - ax) + at(image, x + 1, y + 1) * ax;
                    *v = t * (1.0 - ay) + u * ay;
                }
            }
            let p = |j: usize, i: usize| patch.get(i * PATCH + j).copied().unwrap_or(0.0);
            let (mut a, mut b, mut cc, mut bb1, mut bb2) = (0.0f64, 0.0f64, 0.0f64, 0.0, 0.0);
            for (i, my) in mask.iter().take(n).enumerate() {
                let py = (i as isize - h) as f64;
                for (j, mx) in mask.iter().take(n).enumerate() {
                    let px = (j as isize - h) as f64;
                    let m = (my * mx) as f64;
                    // Window pixel (j, i) is patch pixel (j + 1, i + 1).
                    let gx = (p(j + 2, i + 1) - p(j, i + 1)) as f64;
                    let gy = (p(j + 1, i + 2) - p(j + 1, i)) as f64;
                    let (gxx, gxy, gyy) = (gx * gx * m, gx * gy * m, gy * gy * m);
                    a += gxx;
                    b += gxy;
                    cc += gyy;
                    bb1 += gxx * px + gxy * py;
                    bb2 += gxy * px + gyy * py;
                }
            }
            let det = a * cc - b * b;
            if det.abs() <= f64::EPSILON * f64::EPSILON {
                break;
            }
            let s = 1.0 / det;
            let next = Point2::new(
                (q.x as f64 + cc * s * bb1 - b * s * bb2) as f32,
                (q.y as f64 - b * s * bb1 + a * s * bb2) as f32,
            );
            let err = (next - q).norm_squared();
            q = next;
            if q.x < 0.0 || q.x >= w || q.y < 0.0 || q.y >= ht || err <= cfg.epsilon {
                break;
            }
        }
        let hf = h as f32;
        if !((q.x - start.x).abs() <= hf && (q.y - start.y).abs() <= hf) {
            q = start;
        }
        *c = q;
    }
    Ok(())
}
