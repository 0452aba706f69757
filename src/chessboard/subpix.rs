//! Sub-pixel corner refinement: gradient orthogonality (OpenCV's `cornerSubPix`) and the
//! saddle point of a quadratic fit to the smoothed image.
//!
//! Both are unbiased for an ideal corner at any angle between its edges. `cornerSubPix` is
//! here so that results compare one to one with OpenCV's (on OpenCV's corners camgeom's
//! calibration equals OpenCV's). The saddle fit is camgeom's default because it measured more
//! accurate on boards rendered by OpenCV with exact truth (rotation, perspective, lens
//! distortion, blur, noise, uneven light) than `cornerSubPix` (fixed or adaptive window) and
//! OpenCV's `findChessboardCornersSB` (BENCHMARKS.md, "Corner error against rendered
//! truth"): the fit uses every sample of a small smoothed window, where gradient
//! orthogonality leans on the few pixels with a strong gradient and a Gaussian weight that
//! spans the corner's neighbourhood (`docs/notes/calibration.md`).

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
    /// Half side 5 (OpenCV's `winSize = (5, 5)`, an 11x11 window), 30 iterations, 0.001.
    /// (OpenCV's calibration sample uses `(11, 11)`, a 23x23 window: half side 11.)
    fn default() -> Self {
        Self {
            half_window: 5,
            max_iterations: 30,
            epsilon: 1e-3,
        }
    }
}

impl SubPixConfig {
    /// Checks every field once: [`corner_subpix`] takes the checked [`SubPixParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field: `subpix.half_window` outside
    /// 1 ..= [`MAX_HALF_WINDOW`], `subpix.max_iterations` outside 1 ..= 100, `subpix.epsilon`
    /// negative or not finite.
    pub fn check(&self) -> Result<SubPixParams> {
        if self.half_window == 0 || self.half_window > MAX_HALF_WINDOW {
            return Err(Error::InvalidParameter("subpix.half_window"));
        }
        if self.max_iterations == 0 || self.max_iterations > 100 {
            return Err(Error::InvalidParameter("subpix.max_iterations"));
        }
        if !(self.epsilon >= 0.0 && self.epsilon.is_finite()) {
            return Err(Error::InvalidParameter("subpix.epsilon"));
        }
        Ok(SubPixParams(*self))
    }
}

/// A [`SubPixConfig`] that passed [`SubPixConfig::check`]: what [`corner_subpix`] takes, so
/// that no call validates it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SubPixParams(SubPixConfig);

impl SubPixParams {
    /// The checked configuration.
    pub const fn config(&self) -> &SubPixConfig {
        &self.0
    }

    /// A configuration already checked with the one that holds it
    /// ([`super::DetectConfig::check`] checks its refinement's).
    pub(super) const fn from_checked(c: SubPixConfig) -> Self {
        Self(c)
    }

    /// The same parameters with the half window `half_window` clamped to
    /// `1 ..= self.half_window` (still checked).
    /// The same refinement for a view `scale` times larger (a finer pyramid level than the one
    /// the corners were found on): the window `scale` times wider, within the checked range.
    pub(super) fn scaled(self, scale: u8) -> Self {
        let half_window = self.0.half_window.saturating_mul(scale);
        Self(SubPixConfig {
            half_window: half_window.min(MAX_HALF_WINDOW),
            ..self.0
        })
    }

    fn with_smaller_window(self, half_window: u8) -> Self {
        Self(SubPixConfig {
            half_window: half_window.max(1).min(self.0.half_window),
            ..self.0
        })
    }
}

impl Default for SubPixParams {
    /// The checked [`SubPixConfig::default`].
    fn default() -> Self {
        Self(SubPixConfig::default())
    }
}

impl TryFrom<SubPixConfig> for SubPixParams {
    type Error = Error;
    fn try_from(c: SubPixConfig) -> Result<Self> {
        c.check()
    }
}

/// The integer part of a window position, clamped to `±2²⁴`: the window offsets and the
/// bilinear neighbour are added to it, which overflowed `isize` for a corner near `f32::MAX`
/// (`as` saturates). An image is at most [`crate::image::MAX_DIM`] wide, far below `2²⁴`, so
/// a window beyond the clamp samples the same replicated border pixels as one at the clamp.
#[inline]
fn window_origin(f: f32) -> isize {
    const LIMIT: f32 = (1 << 24) as f32;
    f.clamp(-LIMIT, LIMIT) as isize
}

/// Pixel `(x, y)` with a replicated border (OpenCV's `getRectSubPix` border).
#[inline]
fn at(img: &ImageView<'_, u8>, x: isize, y: isize) -> f32 {
    let w = img.width() as isize;
    let xc = x.min(w - 1).max(0) as usize;
    img.row_clamped(y).get(xc).copied().unwrap_or(0) as f32
}

/// OpenCV's `getRectSubPix`: the `side x side` samples at `q + (j - half, i - half)`,
/// `i, j < side`, bilinear with a replicated border, into the first `side` rows of `out`
/// (rows `stride` apart). All samples share `q`'s sub-pixel offset `(ax, ay)`:
/// `(1 - ay) ((1 - ax) I₀₀ + ax I₁₀) + ay ((1 - ax) I₀₁ + ax I₁₁)`.
#[inline]
fn resample_window(
    image: &ImageView<'_, u8>,
    q: &Point2<f32>,
    half: isize,
    side: usize,
    out: &mut [f32],
    stride: usize,
) {
    let (fx, fy) = (libm::floorf(q.x), libm::floorf(q.y));
    let (ax, ay) = (q.x - fx, q.y - fy);
    let (ix, iy) = (window_origin(fx), window_origin(fy));
    for (i, row) in out.chunks_exact_mut(stride).take(side).enumerate() {
        let y = iy + i as isize - half;
        for (j, v) in row.iter_mut().take(side).enumerate() {
            let x = ix + j as isize - half;
            let t = at(image, x, y) * (1.0 - ax) + at(image, x + 1, y) * ax;
            let u = at(image, x, y + 1) * (1.0 - ax) + at(image, x + 1, y + 1) * ax;
            *v = t * (1.0 - ay) + u * ay;
        }
    }
}

/// [`Error::NonFinite`] when a corner is not finite (the refiners' input check).
fn check_finite(corners: &[Point2<f32>]) -> Result<()> {
    if corners
        .iter()
        .any(|c| !(c.x.is_finite() && c.y.is_finite()))
    {
        return Err(Error::NonFinite);
    }
    Ok(())
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
/// Errors: [`Error::NonFinite`] for a non-finite corner.
#[doc(alias = "cornerSubPix")]
pub fn corner_subpix(
    image: &ImageView<'_, u8>,
    corners: &mut [Point2<f32>],
    params: &SubPixParams,
) -> Result<()> {
    let cfg = params.config();
    check_finite(corners)?;
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
            // The window and a pixel around it, (2h + 3)² samples at q + (j - h - 1, i - h - 1).
            let mut patch = [0.0f32; PATCH * PATCH];
            resample_window(image, &q, h + 1, n + 2, &mut patch, PATCH);
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

/// [`corner_subpix`] of each corner of a board with rows of `cols` corners, its window shrunk
/// to its squares (see [`super::Refinement::AdaptiveCornerSubPix`]).
pub(super) fn corner_subpix_adaptive(
    image: &ImageView<'_, u8>,
    corners: &mut [Point2<f32>],
    cols: usize,
    params: &SubPixParams,
) -> Result<()> {
    let sp = params.config();
    let n = corners.len();
    let mut windows = [0u8; 4096];
    for (k, w) in windows.iter_mut().enumerate().take(n) {
        let p = corners.get(k).copied().unwrap_or(Point2::origin());
        let (i, j) = (k % cols.max(1), k / cols.max(1));
        let mut d = f32::MAX;
        let mut near = |q: Option<&Point2<f32>>| {
            if let Some(q) = q {
                d = d.min((q - p).norm());
            }
        };
        if i > 0 {
            near(corners.get(k - 1));
        }
        if i + 1 < cols {
            near(corners.get(k + 1));
        }
        if j > 0 {
            near(corners.get(k - cols));
        }
        near(corners.get(k + cols));
        // `max` then `min`: `clamp` would panic for a half window below 2.
        let fit = libm::floorf(0.5 * d).max(2.0).min(sp.half_window as f32);
        // `with_smaller_window` clamps it to `1 ..= half_window`.
        *w = fit as u8;
    }
    for (c, w) in corners.iter_mut().zip(windows.iter()) {
        let fitted = params.with_smaller_window(*w);
        corner_subpix(image, core::slice::from_mut(c), &fitted)?;
    }
    Ok(())
}

/// Parameters of [`saddle_subpix`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SaddleConfig {
    /// Half side of the fitted window (`1..=4`): `(2r + 1)²` smoothed samples.
    pub half_window: u8,
    /// Gaussian smoothing before the fit, px (`0.5..=3`).
    pub sigma: f32,
    /// Iterations at most (`1..=100`).
    pub max_iterations: u8,
    /// Stop when the squared step is at most this (px²).
    pub epsilon: f32,
}

impl Default for SaddleConfig {
    /// A 5x5 fit after σ = 1 px smoothing, to convergence (20 iterations, 1e-8 px²): the best
    /// of the settings measured on the rendered boards (r 2..3, σ 1..2), and the only one
    /// that holds on 10-px squares and uneven light.
    fn default() -> Self {
        Self {
            half_window: 2,
            sigma: 1.0,
            max_iterations: 20,
            epsilon: 1e-8,
        }
    }
}

/// Largest smoothing kernel radius of [`saddle_subpix`] (3σ at σ = 3).
/// Largest [`SaddleConfig::half_window`].
pub const MAX_SADDLE_HALF_WINDOW: u8 = 4;

/// Largest [`SaddleConfig::sigma`] (its kernel's radius `⌈3σ⌉` fits the patch).
pub const MAX_SADDLE_SIGMA: f32 = 3.0;

const SADDLE_KERNEL: usize = 9;
/// Side of its sample buffer.
const SADDLE_PATCH: usize = 2 * (4 + SADDLE_KERNEL) + 1;

impl SaddleConfig {
    /// Checks every field once: [`saddle_subpix`] takes the checked [`SaddleParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field: `saddle.half_window` outside
    /// 1 ..= 4, `saddle.sigma` outside 0.5 ..= 3 (or NaN), `saddle.max_iterations` outside
    /// 1 ..= 100, `saddle.epsilon` negative or not finite.
    pub fn check(&self) -> Result<SaddleParams> {
        if !(1..=MAX_SADDLE_HALF_WINDOW).contains(&self.half_window) {
            return Err(Error::InvalidParameter("saddle.half_window"));
        }
        if !(self.sigma >= 0.5 && self.sigma <= MAX_SADDLE_SIGMA) {
            return Err(Error::InvalidParameter("saddle.sigma"));
        }
        if self.max_iterations == 0 || self.max_iterations > 100 {
            return Err(Error::InvalidParameter("saddle.max_iterations"));
        }
        if !(self.epsilon >= 0.0 && self.epsilon.is_finite()) {
            return Err(Error::InvalidParameter("saddle.epsilon"));
        }
        Ok(SaddleParams(*self))
    }
}

/// A [`SaddleConfig`] that passed [`SaddleConfig::check`]: what [`saddle_subpix`] takes, so
/// that no call validates it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SaddleParams(SaddleConfig);

impl SaddleParams {
    /// The checked configuration.
    pub const fn config(&self) -> &SaddleConfig {
        &self.0
    }

    /// A configuration already checked with the one that holds it
    /// ([`super::DetectConfig::check`] checks its refinement's).
    pub(super) const fn from_checked(c: SaddleConfig) -> Self {
        Self(c)
    }

    /// The same refinement for a view `scale` times larger (a finer pyramid level than the one
    /// the corners were found on, where the edges are `scale` times more blurred in pixels):
    /// the window and the smoothing `scale` times wider, within the checked ranges.
    pub(super) fn scaled(self, scale: u8) -> Self {
        let c = self.0;
        Self(SaddleConfig {
            half_window: c
                .half_window
                .saturating_mul(scale)
                .min(MAX_SADDLE_HALF_WINDOW),
            sigma: (c.sigma * f32::from(scale)).min(MAX_SADDLE_SIGMA),
            ..c
        })
    }

    /// The smoothing kernel's radius, `⌈3σ⌉` px.
    fn kernel_radius(&self) -> usize {
        (libm::ceilf(3.0 * self.0.sigma) as usize).min(SADDLE_KERNEL)
    }

    /// How far from a corner the refinement reads the image, px: the window's half side plus
    /// the smoothing kernel's radius, plus the bilinear neighbour (a corner at least this far
    /// inside the frame is fitted on the frame's own pixels, none repeated from its border).
    pub(crate) fn reach(&self) -> f32 {
        (usize::from(self.0.half_window) + self.kernel_radius() + 1) as f32
    }
}

impl Default for SaddleParams {
    /// The checked [`SaddleConfig::default`].
    fn default() -> Self {
        Self(SaddleConfig::default())
    }
}

impl TryFrom<SaddleConfig> for SaddleParams {
    type Error = Error;
    fn try_from(c: SaddleConfig) -> Result<Self> {
        c.check()
    }
}

/// Refines each corner in place to the saddle point of the smoothed image: around the estimate
/// `q`, the image is resampled bilinearly on a unit grid, smoothed by a Gaussian of `sigma`,
/// and `I(x, y) ≈ a + b x + c y + d x² + e x y + f y²` fitted by least squares over
/// `(2r + 1)²` samples (on the symmetric grid the fit separates into closed-form sums); the
/// saddle `[2d e; e 2f] δ = -(b, c)` moves `q`. A chessboard corner is point-symmetric
/// (`I(-p) = I(p)` about the crossing), so the smoothed image has its saddle exactly at the
/// crossing for any angle between the edges. A corner whose fit is not a saddle
/// (`4 d f - e² ≥ 0`), or that moves more than the window, keeps its start.
///
/// Errors: [`Error::NonFinite`] for a non-finite corner.
pub fn saddle_subpix(
    image: &ImageView<'_, u8>,
    corners: &mut [Point2<f32>],
    params: &SaddleParams,
) -> Result<()> {
    check_finite(corners)?;
    let fit = SaddleFit::new(params);
    for c in corners.iter_mut() {
        *c = fit.refine(image, *c).0;
    }
    Ok(())
}

/// The saddle refinement of one corner ([`saddle_subpix`]) when it converged: `Some` only when
/// the iteration reached a step of at most `epsilon` (a fixed point of the fit, a saddle at
/// every step, no step over one pixel) within `max_iterations`, and stayed within the window
/// of its start. A corner that ends on a fit that is not a saddle, on a step over a pixel, or
/// still moving after the last iteration is `None`: the window does not hold one clean saddle
/// (another corner, an edge or a marker's corner of its own in reach, a cut or covered corner)
/// and where the iteration stopped says nothing of the crossing.
///
/// Errors: [`Error::NonFinite`] for a non-finite corner.
pub(crate) fn saddle_converged(
    image: &ImageView<'_, u8>,
    corner: Point2<f32>,
    params: &SaddleParams,
) -> Result<Option<Point2<f32>>> {
    check_finite(&[corner])?;
    let (q, converged) = SaddleFit::new(params).refine(image, corner);
    Ok(converged.then_some(q))
}

/// The fixed parts of [`saddle_subpix`]'s fit: the smoothing kernel and the fit's sums on the
/// symmetric grid.
struct SaddleFit {
    cfg: SaddleConfig,
    kernel: [f32; 2 * SADDLE_KERNEL + 1],
    /// Window half side and kernel radius.
    r: usize,
    kr: usize,
    m2: f32,
    sx2: f32,
    sx2y2: f32,
    sq: f32,
}

impl SaddleFit {
    fn new(params: &SaddleParams) -> Self {
        let cfg = *params.config();
        let r = cfg.half_window as usize;
        let kr = params.kernel_radius();
        let mut kernel = [0.0f32; 2 * SADDLE_KERNEL + 1];
        let mut ksum = 0.0;
        for (i, k) in kernel.iter_mut().take(2 * kr + 1).enumerate() {
            let t = i as f32 - kr as f32;
            *k = libm::expf(-0.5 * t * t / (cfg.sigma * cfg.sigma));
            ksum += *k;
        }
        for k in kernel.iter_mut() {
            *k /= ksum;
        }
        // Fit denominators on the symmetric grid.
        let rr = r as isize;
        let m2 = (-rr..=rr).map(|x| (x * x) as f32).sum::<f32>() / (2 * r + 1) as f32;
        let n1 = (2 * r + 1) as f32;
        let sx2: f32 = (-rr..=rr).map(|x| (x * x) as f32).sum::<f32>() * n1;
        let s2: f32 = (-rr..=rr).map(|x| (x * x) as f32).sum();
        let sx2y2 = s2 * s2;
        let sq: f32 = (-rr..=rr)
            .map(|x| {
                let t = (x * x) as f32 - m2;
                t * t
            })
            .sum::<f32>()
            * n1;
        Self {
            cfg,
            kernel,
            r,
            kr,
            m2,
            sx2,
            sx2y2,
            sq,
        }
    }

    /// The refined corner from `start` and whether the iteration converged (its last step at
    /// most `epsilon`).
    fn refine(&self, image: &ImageView<'_, u8>, start: Point2<f32>) -> (Point2<f32>, bool) {
        let Self {
            cfg,
            kernel,
            r,
            kr,
            m2,
            sx2,
            sx2y2,
            sq,
        } = *self;
        let side = 2 * (r + kr) + 1;
        let half = (r + kr) as isize;
        let mut q = start;
        let mut converged = false;
        for _ in 0..cfg.max_iterations {
            let mut raw = [0.0f32; SADDLE_PATCH * SADDLE_PATCH];
            resample_window(image, &q, half, side, &mut raw, SADDLE_PATCH);
            let px = |j: usize, i: usize| raw.get(i * SADDLE_PATCH + j).copied().unwrap_or(0.0);
            // Horizontal then vertical smoothing, only where the fit needs it.
            let mut hs = [0.0f32; SADDLE_PATCH * SADDLE_PATCH];
            for i in 0..side {
                for j in kr..kr + 2 * r + 1 {
                    let mut s = 0.0;
                    for (k, w) in kernel.iter().take(2 * kr + 1).enumerate() {
                        s += w * px(j + k - kr, i);
                    }
                    if let Some(o) = hs.get_mut(i * SADDLE_PATCH + j) {
                        *o = s;
                    }
                }
            }
            let (mut sb, mut sc, mut se, mut sd, mut sf) = (0.0f32, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
            for i in kr..kr + 2 * r + 1 {
                for j in kr..kr + 2 * r + 1 {
                    let mut s = 0.0;
                    for (k, w) in kernel.iter().take(2 * kr + 1).enumerate() {
                        s += w * hs
                            .get((i + k - kr) * SADDLE_PATCH + j)
                            .copied()
                            .unwrap_or(0.0);
                    }
                    let (x, y) = ((j - kr) as f32 - r as f32, (i - kr) as f32 - r as f32);
                    sb += x * s;
                    sc += y * s;
                    se += x * y * s;
                    sd += (x * x - m2) * s;
                    sf += (y * y - m2) * s;
                }
            }
            let (b, cc, e, d, f) = (sb / sx2, sc / sx2, se / sx2y2, sd / sq, sf / sq);
            let det = 4.0 * d * f - e * e;
            // Not a saddle (or NaN): keep the estimate.
            if det.is_nan() || det >= 0.0 {
                break;
            }
            let dx = (-2.0 * f * b + e * cc) / det;
            let dy = (e * b - 2.0 * d * cc) / det;
            if !(dx.abs() <= 1.0 && dy.abs() <= 1.0) {
                q = start;
                break;
            }
            q = Point2::new(q.x + dx, q.y + dy);
            if dx * dx + dy * dy <= cfg.epsilon {
                converged = true;
                break;
            }
        }
        let lim = r as f32 + 1.0;
        if !((q.x - start.x).abs() <= lim && (q.y - start.y).abs() <= lim) {
            return (start, false);
        }
        (q, converged)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = 40;

    /// A 40x40 image of `f(x, y)` at the pixel centres, rounded.
    fn render(f: impl Fn(f32, f32) -> f32) -> [u8; N * N] {
        let mut img = [0u8; N * N];
        for (k, px) in img.iter_mut().enumerate() {
            *px = libm::roundf(f((k % N) as f32, (k / N) as f32)) as u8;
        }
        img
    }

    /// A clean corner converges onto its crossing; a flat patch and a straight edge (no
    /// saddle) are refused, where `saddle_subpix` keeps their start.
    #[test]
    fn saddle_converged_only_on_a_saddle() {
        let p = SaddleParams::default();
        let c = Point2::new(20.3f32, 19.6);
        // A blurred corner, point-symmetric about `c`.
        let corner = render(|x, y| {
            120.0 + 80.0 * libm::tanhf((x - c.x) / 2.0) * libm::tanhf((y - c.y) / 2.0)
        });
        let v = ImageView::new(&corner, N, N, N).unwrap();
        let q = saddle_converged(&v, Point2::new(20.8, 19.2), &p)
            .unwrap()
            .unwrap();
        assert!((q - c).norm() < 0.05, "{q:?}");
        let flat = [128u8; N * N];
        let edge = render(|x, _| 120.0 + 80.0 * libm::tanhf((x - 20.3) / 2.0));
        for img in [&flat, &edge] {
            let v = ImageView::new(img, N, N, N).unwrap();
            let start = Point2::new(20.0, 20.0);
            assert_eq!(saddle_converged(&v, start, &p).unwrap(), None);
            let mut kept = [start];
            saddle_subpix(&v, &mut kept, &p).unwrap();
            assert_eq!(kept[0], start);
        }
        assert_eq!(
            saddle_converged(&v, Point2::new(f32::NAN, 1.0), &p),
            Err(Error::NonFinite)
        );
    }
}
