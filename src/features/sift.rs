//! SIFT: scale-invariant keypoints (extrema of the difference of Gaussians) with 128-float
//! descriptors, after Lowe 2004 and OpenCV's `cv::SIFT` (the patent expired in 2020).
//!
//! 1. **Scale space.** The image, in `[0, 1]`, is taken to be blurred by `σ_in = 0.5` (twice
//!    that when [`SiftConfig::upsample`] first doubles it: even output pixels are the input's,
//!    odd ones the mean of their two or four neighbours, so that pixel `x` of the doubled image
//!    is exactly input pixel `x / 2`). It is blurred to `σ` ([`SiftConfig::sigma`], 1.6), the
//!    first image of octave 0. Each octave holds `s + 3` images `G_i = G_σ·2^{i/s} ∗ I`
//!    (`s` = [`SiftConfig::intervals`], 3), each blurred from the previous one by the
//!    increment `σ_i = σ·2^{(i−1)/s}·√(2^{2/s} − 1)`, and `s + 2` differences
//!    `D_i = G_{i+1} − G_i`. The next octave starts from `G_s` (blur `2σ`) sampled at every
//!    second pixel, so octave `o`'s pixel `(x, y)` is level-0 pixel `2^o (x, y)` exactly.
//!    Gaussian kernels are truncated at `⌈4σ_i⌉` ([`MAX_RADIUS`] at most), borders are
//!    reflected (`BORDER_REFLECT_101`), and the blur is separable: a row pass and a column pass
//!    each written as a sum over taps of whole shifted rows, which LLVM vectorises.
//! 2. **Extrema.** A pixel of `D_1 … D_s` at least [`BORDER`] pixels from the edge with
//!    `|D| > 0.5 t / s` (`t` = [`SiftConfig::contrast_threshold`], 0.04) that is `>=` (or
//!    `<=`) all 26 neighbours in space and scale.
//! 3. **Refinement.** At most [`MAX_REFINE_STEPS`] Newton steps on the 3D quadratic model
//!    `D(x + δ) ≈ D + ∇Dᵀδ + ½ δᵀ H δ` (central differences): `δ = −H⁻¹ ∇D`; while a component
//!    of `δ` exceeds ½ the sample moves by `round(δ)`. Rejected: no convergence, a step that
//!    leaves the border or the layers `1..=s`, low contrast `|D(x̂)| s < t` with
//!    `D(x̂) = D + ½ ∇Dᵀ δ`, and edges: with the spatial Hessian `[[Dxx, Dxy], [Dxy, Dyy]]`,
//!    `det <= 0` or `tr² / det >= (r + 1)² / r` (`r` = [`SiftConfig::edge_threshold`], 10).
//! 4. **Orientation.** A 36-bin histogram of the gradient directions of `G_layer` within
//!    `⌊4.5 σ_o⌉` pixels (`σ_o = σ 2^{(layer + δ_s)/s}`, the keypoint's scale in its octave),
//!    weighted by magnitude and a Gaussian of `1.5 σ_o`, smoothed twice by `[1 4 6 4 1]/16`;
//!    every local peak of at least 0.8 of the highest gives a keypoint, its angle refined by a
//!    parabola through the peak and its neighbours.
//! 5. **Descriptor.** The gradients of `G_layer` in a window rotated to the keypoint's angle,
//!    of `4 x 4` cells of `3 σ_o` pixels, weighted by a Gaussian of half the window's width,
//!    spread by trilinear interpolation over the 4x4 cells and 8 orientation bins; the 128
//!    values normalised to unit length, clamped at 0.2, normalised again (OpenCV then rounds
//!    `512 v` to bytes; here they stay `f32`). With [`SiftConfig::root`], RootSIFT (Arandjelović
//!    and Zisserman 2012): the clamped vector is L1-normalised and square-rooted, so that the
//!    Euclidean distance of two descriptors is the Hellinger distance of the histograms.
//!
//! Only one octave is in memory at a time: [`scratch_len`] `f32`s, `2s + 6` planes of the
//! first octave plus a padded row: 1536x1024 without upsampling, `s = 3`: 12 planes of 6.3 MB,
//! 75.5 MB (302 MB doubled); 320x240: 3.7 MB. A feature ([`SiftFeature`]) is 536 bytes.
//! The work is `O(w h (s + 3) (2 ⌈4σ_i⌉ + 1))` for the blurs, plus, per keypoint,
//! `O(σ_o²)` for its orientation and descriptor windows; every loop is bounded by the image,
//! the octaves and the capacities.

use crate::features::matching::FloatDescriptor;
use crate::image::ImageView;
use crate::{Error, Result};

/// Pixels at the image border of each octave where no extremum is sought (OpenCV's
/// `SIFT_IMG_BORDER`).
pub const BORDER: usize = 5;

/// Newton steps of the sub-pixel, sub-scale refinement (`SIFT_MAX_INTERP_STEPS`).
pub const MAX_REFINE_STEPS: usize = 5;

/// Largest Gaussian kernel radius, pixels: kernels wider than this are truncated.
pub const MAX_RADIUS: usize = 24;

/// Most intervals an octave can be split into.
pub const MAX_INTERVALS: u8 = 8;

/// Smallest side of an octave that is searched (smaller octaves are not built).
pub const MIN_OCTAVE_SIDE: usize = 2 * BORDER + 6;

/// Bins of the orientation histogram.
const ORI_BINS: usize = 36;
/// Histogram peaks kept relative to the highest.
const ORI_PEAK_RATIO: f32 = 0.8;
/// Orientation window: Gaussian `σ = 1.5 σ_o`, radius `3 · 1.5 σ_o`.
const ORI_SIG_FCTR: f32 = 1.5;
const ORI_RADIUS: f32 = 3.0 * ORI_SIG_FCTR;
/// Descriptor: `4 x 4` cells of 8 orientation bins, cells `3 σ_o` wide.
const DESCR_WIDTH: usize = 4;
const DESCR_BINS: usize = 8;
const DESCR_SCL_FCTR: f32 = 3.0;
const DESCR_MAG_THR: f32 = 0.2;
/// Largest descriptor window radius, in octave pixels (the window of a keypoint at the top of
/// an octave, `σ_o < 2σ <= 8`, is about 85).
const MAX_DESCR_RADIUS: i32 = 128;

/// The length of a descriptor: `4 · 4 · 8`.
pub const DESCRIPTOR_LEN: usize = DESCR_WIDTH * DESCR_WIDTH * DESCR_BINS;

/// Settings of [`sift_detect`], as the user writes them; checked by [`Self::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SiftConfig {
    /// Most octaves; 0: as many as the image allows (each at least [`MIN_OCTAVE_SIDE`]
    /// pixels on its shorter side). Default 0.
    pub octaves: u8,
    /// Intervals `s` an octave is split into, `1..=`[`MAX_INTERVALS`]. Default 3
    /// (`nOctaveLayers`).
    pub intervals: u8,
    /// Blur `σ` of each octave's first image, in that octave's pixels, `(0.5, 4]`. Default 1.6.
    pub sigma: f32,
    /// Contrast threshold `t` on `|D(x̂)| s` (intensities in `[0, 1]`), `>= 0`. Default 0.04.
    pub contrast_threshold: f32,
    /// Edge threshold `r` on the principal curvature ratio, `> 1`. Default 10.
    pub edge_threshold: f32,
    /// Double the image first (OpenCV's default; finds about four times the keypoints of the
    /// finest scale, for four times the memory and time). Default `false`.
    pub upsample: bool,
    /// RootSIFT descriptors. Default `false`.
    pub root: bool,
    /// Most features kept, the strongest `|D(x̂)|` (OpenCV's `nfeatures`); 0: all that fit in
    /// the output. Default 0.
    pub max_features: u32,
}

impl Default for SiftConfig {
    fn default() -> Self {
        Self {
            octaves: 0,
            intervals: 3,
            sigma: 1.6,
            contrast_threshold: 0.04,
            edge_threshold: 10.0,
            upsample: false,
            root: false,
            max_features: 0,
        }
    }
}

impl SiftConfig {
    /// Checks the settings once: [`sift_detect`] takes the checked [`SiftParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field out of its range (NaN included).
    pub fn check(&self) -> Result<SiftParams> {
        if self.intervals == 0 || self.intervals > MAX_INTERVALS {
            return Err(Error::InvalidParameter("sift.intervals"));
        }
        if !(self.sigma > 0.5 && self.sigma <= 4.0) {
            return Err(Error::InvalidParameter("sift.sigma"));
        }
        if !(self.contrast_threshold >= 0.0 && self.contrast_threshold.is_finite()) {
            return Err(Error::InvalidParameter("sift.contrast_threshold"));
        }
        if !(self.edge_threshold > 1.0 && self.edge_threshold.is_finite()) {
            return Err(Error::InvalidParameter("sift.edge_threshold"));
        }
        Ok(SiftParams(*self))
    }
}

/// A [`SiftConfig`] that passed [`SiftConfig::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SiftParams(SiftConfig);

impl SiftParams {
    /// The checked configuration.
    pub const fn config(&self) -> &SiftConfig {
        &self.0
    }
}

impl Default for SiftParams {
    /// The checked [`SiftConfig::default`].
    fn default() -> Self {
        Self(SiftConfig::default())
    }
}

impl TryFrom<SiftConfig> for SiftParams {
    type Error = Error;
    fn try_from(c: SiftConfig) -> Result<Self> {
        c.check()
    }
}

/// A SIFT keypoint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SiftKeypoint {
    /// Column in input pixels (pixel centres at integers).
    pub x: f32,
    /// Row in input pixels.
    pub y: f32,
    /// Its scale: the blur `σ 2^{o + (layer + δ_s)/s}` in input pixels (OpenCV's
    /// `KeyPoint::size` is twice this).
    pub sigma: f32,
    /// Dominant gradient direction, radians in `[0, 2π)`, y down: `atan2(∂I/∂y, ∂I/∂x)` in
    /// image coordinates (OpenCV's `KeyPoint::angle`, which is in degrees).
    pub angle: f32,
    /// `|D(x̂)|`, intensities in `[0, 1]` (OpenCV's `response`, which is in units of 255).
    pub response: f32,
    /// Octave, `-1` for the doubled image.
    pub octave: i8,
    /// Layer `1..=s` of the octave.
    pub layer: u8,
}

impl SiftKeypoint {
    /// Input pixels per pixel of its octave, `2^o`.
    pub fn octave_scale(&self) -> f32 {
        libm::exp2f(f32::from(self.octave))
    }
}

/// A keypoint with its descriptor.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SiftFeature {
    /// Where, how large, which way.
    pub keypoint: SiftKeypoint,
    /// The 128 values, unit Euclidean length: index `(row · 4 + column) · 8 + bin`.
    pub descriptor: FloatDescriptor,
}

/// `f32`s of scratch [`sift_detect`] needs for a `width x height` image with `intervals`
/// intervals an octave, doubled first when `upsample`: `2 intervals + 6` planes of the first
/// octave (`s + 3` Gaussians, `s + 2` differences, one for the row pass) and a padded row.
pub const fn scratch_len(width: usize, height: usize, intervals: u8, upsample: bool) -> usize {
    let (w, h) = if upsample {
        (width.saturating_mul(2), height.saturating_mul(2))
    } else {
        (width, height)
    };
    let planes = 2 * intervals as usize + 6;
    let longer = if w > h { w } else { h };
    planes
        .saturating_mul(w.saturating_mul(h))
        .saturating_add(longer)
        .saturating_add(2 * MAX_RADIUS)
}

/// Bytes of [`scratch_len`].
pub const fn scratch_bytes(width: usize, height: usize, intervals: u8, upsample: bool) -> usize {
    scratch_len(width, height, intervals, upsample).saturating_mul(4)
}

/// The reflected index of `i` in `0..n` (`BORDER_REFLECT_101`: `-1 → 1`, `n → n − 2`),
/// clamped for kernels wider than the image.
#[inline]
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let j = if i < 0 {
        -i
    } else if i >= n {
        2 * n - 2 - i
    } else {
        i
    };
    j.clamp(0, (n - 1).max(0)) as usize
}

/// A normalised Gaussian kernel of `σ`, radius `⌈4σ⌉` (at most [`MAX_RADIUS`], at least 1):
/// the taps and the radius.
fn kernel(sigma: f32) -> ([f32; 2 * MAX_RADIUS + 1], usize) {
    let mut k = [0.0f32; 2 * MAX_RADIUS + 1];
    let r = (libm::ceilf(4.0 * sigma) as usize).clamp(1, MAX_RADIUS);
    let s2 = -0.5 / (sigma * sigma).max(1e-6);
    let mut sum = 0.0;
    for (i, t) in k.iter_mut().take(2 * r + 1).enumerate() {
        let d = i as f32 - r as f32;
        *t = libm::expf(d * d * s2);
        sum += *t;
    }
    for t in k.iter_mut() {
        *t /= sum;
    }
    (k, r)
}

/// `dst = G_σ ∗ src` on `w x h` planes (separable: rows into `tmp`, then columns), `pad` at
/// least `w + 2 MAX_RADIUS` long. Every inner loop runs over whole rows.
fn blur(src: &[f32], dst: &mut [f32], tmp: &mut [f32], pad: &mut [f32], w: usize, sigma: f32) {
    let (k, r) = kernel(sigma);
    let taps = k.get(..2 * r + 1).unwrap_or(&[]);
    let Some(pad) = pad.get_mut(..w + 2 * r) else {
        return;
    };
    // Rows.
    let w1 = w.max(1);
    for (row, out) in src.chunks_exact(w1).zip(tmp.chunks_exact_mut(w1)) {
        for (p, v) in pad.iter_mut().enumerate() {
            *v = row
                .get(reflect(p as isize - r as isize, w))
                .copied()
                .unwrap_or(0.0);
        }
        out.fill(0.0);
        for (j, &c) in taps.iter().enumerate() {
            for (o, &s) in out.iter_mut().zip(pad.iter().skip(j)) {
                *o += c * s;
            }
        }
    }
    // Columns.
    let h = src.len() / w1;
    for (y, out) in dst.chunks_exact_mut(w1).enumerate().take(h) {
        out.fill(0.0);
        for (j, &c) in taps.iter().enumerate() {
            let sy = reflect(y as isize + j as isize - r as isize, h);
            let Some(s) = tmp.get(sy * w..sy * w + w) else {
                continue;
            };
            for (o, &v) in out.iter_mut().zip(s) {
                *o += c * v;
            }
        }
    }
}

/// Reads `plane[y w + x]`, 0 outside.
#[inline]
fn at(plane: &[f32], w: usize, x: usize, y: usize) -> f32 {
    plane.get(y * w + x).copied().unwrap_or(0.0)
}

/// One octave's planes, read-only, for the per-keypoint work.
struct Octave<'a> {
    gauss: &'a [f32],
    dog: &'a [f32],
    w: usize,
    h: usize,
    /// Octave index (`-1` for the doubled image).
    index: i8,
}

impl<'a> Octave<'a> {
    fn plane(planes: &'a [f32], i: usize, wh: usize) -> &'a [f32] {
        planes.get(i * wh..(i + 1) * wh).unwrap_or(&[])
    }
    fn g(&self, i: usize) -> &'a [f32] {
        Self::plane(self.gauss, i, self.w * self.h)
    }
    fn d(&self, i: usize) -> &'a [f32] {
        Self::plane(self.dog, i, self.w * self.h)
    }
}

/// Detects SIFT features of `img` (module docs): writes the strongest `min(out.len(),
/// max_features)` into `out`, sorted by decreasing response (then by position), and returns
/// how many.
///
/// `scratch` holds [`scratch_len`]`(w, h, intervals, upsample)` `f32`s.
///
/// Errors: [`Error::BufferTooSmall`]`("scratch")` for a short scratch.
///
/// ```
/// use camgeom::features::sift::{self, SiftFeature, SiftParams, sift_detect};
/// use camgeom::image::ImageView;
///
/// // Two dark discs on a light background: blobs, the keypoints SIFT finds.
/// let (w, h) = (96, 64);
/// let img: Vec<u8> = (0..w * h)
///     .map(|i| {
///         let (x, y) = ((i % w) as f32, (i / w) as f32);
///         let disc = |cx: f32, cy: f32, r: f32| (x - cx).hypot(y - cy) < r;
///         if disc(30.0, 32.0, 6.0) || disc(66.0, 30.0, 9.0) { 40 } else { 200 }
///     })
///     .collect();
/// let mut scratch = vec![0.0; sift::scratch_len(w, h, 3, false)];
/// let mut out = [SiftFeature::default(); 32];
/// let params = SiftParams::default();
/// let n = sift_detect(&ImageView::packed(&img, w, h)?, &params, &mut scratch, &mut out)?;
/// // Each disc is a keypoint at its centre, of a scale that grows with its radius.
/// let near = |cx: f32, cy: f32| {
///     out[..n].iter().find(|f| (f.keypoint.x - cx).hypot(f.keypoint.y - cy) < 1.0)
/// };
/// let (a, b) = (near(30.0, 32.0).unwrap(), near(66.0, 30.0).unwrap());
/// assert!(b.keypoint.sigma > a.keypoint.sigma);
/// # Ok::<(), camgeom::Error>(())
/// ```
#[doc(alias = "SIFT")]
#[doc(alias = "detectAndCompute")]
#[doc(alias = "SIFT_create")]
pub fn sift_detect(
    img: &ImageView<'_, u8>,
    params: &SiftParams,
    scratch: &mut [f32],
    out: &mut [SiftFeature],
) -> Result<usize> {
    let cfg = params.config();
    let s = usize::from(cfg.intervals);
    let need = scratch_len(img.width(), img.height(), cfg.intervals, cfg.upsample);
    let scratch = scratch
        .get_mut(..need)
        .ok_or(Error::BufferTooSmall("scratch"))?;
    let (mut w, mut h) = if cfg.upsample {
        (img.width() * 2, img.height() * 2)
    } else {
        (img.width(), img.height())
    };
    let cap = if cfg.max_features == 0 {
        out.len()
    } else {
        out.len().min(cfg.max_features as usize)
    };
    let out = out.get_mut(..cap).unwrap_or(&mut []);
    if w.min(h) < MIN_OCTAVE_SIDE || cap == 0 {
        return Ok(0);
    }
    let wh0 = w * h;
    let too_small = Error::BufferTooSmall("scratch");
    let (gauss, rest) = scratch
        .split_at_mut_checked((s + 3) * wh0)
        .ok_or(too_small)?;
    let (dog, rest) = rest.split_at_mut_checked((s + 2) * wh0).ok_or(too_small)?;
    let (tmp, pad) = rest.split_at_mut_checked(wh0).ok_or(too_small)?;
    // The input in [0, 1] (doubled when asked) in the first difference plane, blurred from
    // σ_in to σ into G_0.
    let sigma_in = if cfg.upsample { 1.0 } else { 0.5 };
    load(img, cfg.upsample, dog.get_mut(..wh0).unwrap_or(&mut []));
    let first_blur = libm::sqrtf((cfg.sigma * cfg.sigma - sigma_in * sigma_in).max(0.01));
    blur(
        dog.get(..wh0).unwrap_or(&[]),
        gauss.get_mut(..wh0).unwrap_or(&mut []),
        tmp,
        pad,
        w,
        first_blur,
    );
    // Blur increments: G_i from G_{i-1}.
    let mut increments = [0.0f32; MAX_INTERVALS as usize + 3];
    let k = libm::exp2f(1.0 / s as f32);
    for (i, inc) in increments.iter_mut().enumerate().take(s + 3).skip(1) {
        let prev = cfg.sigma * libm::powf(k, (i - 1) as f32);
        *inc = prev * libm::sqrtf(k * k - 1.0);
    }
    let mut len = 0usize;
    let max_octaves = if cfg.octaves == 0 {
        u8::MAX
    } else {
        cfg.octaves
    };
    let mut index: i8 = if cfg.upsample { -1 } else { 0 };
    for _ in 0..max_octaves {
        if w.min(h) < MIN_OCTAVE_SIDE {
            break;
        }
        let wh = w * h;
        for i in 1..s + 3 {
            let Some((before, after)) = gauss.split_at_mut_checked(i * wh) else {
                break;
            };
            let src = before.get((i - 1) * wh..).unwrap_or(&[]);
            let dst = after.get_mut(..wh).unwrap_or(&mut []);
            let t = tmp.get_mut(..wh).unwrap_or(&mut []);
            blur(
                src,
                dst,
                t,
                pad,
                w,
                increments.get(i).copied().unwrap_or(1.0),
            );
        }
        for i in 0..s + 2 {
            let (Some(d), Some(a), Some(b)) = (
                dog.get_mut(i * wh..(i + 1) * wh),
                gauss.get(i * wh..(i + 1) * wh),
                gauss.get((i + 1) * wh..(i + 2) * wh),
            ) else {
                continue;
            };
            for (d, (a, b)) in d.iter_mut().zip(a.iter().zip(b)) {
                *d = b - a;
            }
        }
        let octave = Octave {
            gauss,
            dog,
            w,
            h,
            index,
        };
        find_extrema(&octave, cfg, out, &mut len);
        // The next octave's G_0: G_s at every second pixel, through `tmp`.
        let (nw, nh) = (w / 2, h / 2);
        if let Some(gs) = gauss.get(s * wh..(s + 1) * wh) {
            for y in 0..nh {
                let row = tmp.get_mut(y * nw..(y + 1) * nw).unwrap_or(&mut []);
                for (x, v) in row.iter_mut().enumerate() {
                    *v = at(gs, w, 2 * x, 2 * y);
                }
            }
        }
        if let (Some(g0), Some(t)) = (gauss.get_mut(..nw * nh), tmp.get(..nw * nh)) {
            for (d, v) in g0.iter_mut().zip(t) {
                *d = *v;
            }
        }
        (w, h) = (nw, nh);
        index = index.saturating_add(1);
    }
    let kept = out.get_mut(..len).unwrap_or(&mut []);
    crate::corners::heapsort_by(kept, |a, b| {
        b.keypoint
            .response
            .total_cmp(&a.keypoint.response)
            .then(a.keypoint.y.total_cmp(&b.keypoint.y))
            .then(a.keypoint.x.total_cmp(&b.keypoint.x))
            .then(a.keypoint.angle.total_cmp(&b.keypoint.angle))
    });
    Ok(len)
}

/// Writes the image in `[0, 1]` into `dst`, doubled when `upsample` (module docs).
fn load(img: &ImageView<'_, u8>, upsample: bool, dst: &mut [f32]) {
    let (w, h) = (img.width(), img.height());
    let px = |x: usize, y: usize| -> f32 {
        let (x, y) = (x.min(w.saturating_sub(1)), y.min(h.saturating_sub(1)));
        f32::from(img.get(x, y).unwrap_or(0)) * (1.0 / 255.0)
    };
    if !upsample {
        for (y, row) in dst.chunks_exact_mut(w.max(1)).enumerate().take(h) {
            if let Some(src) = img.row(y) {
                for (d, &v) in row.iter_mut().zip(src) {
                    *d = f32::from(v) * (1.0 / 255.0);
                }
            }
        }
        return;
    }
    let w2 = 2 * w;
    for (y2, row) in dst.chunks_exact_mut(w2.max(1)).enumerate().take(2 * h) {
        let (y, oy) = (y2 / 2, y2 % 2 == 1);
        for (x2, d) in row.iter_mut().enumerate() {
            let (x, ox) = (x2 / 2, x2 % 2 == 1);
            *d = match (ox, oy) {
                (false, false) => px(x, y),
                (true, false) => 0.5 * (px(x, y) + px(x + 1, y)),
                (false, true) => 0.5 * (px(x, y) + px(x, y + 1)),
                (true, true) => 0.25 * (px(x, y) + px(x + 1, y) + px(x, y + 1) + px(x + 1, y + 1)),
            };
        }
    }
}

/// Step 2 to 5 on one octave: every extremum of `D_1 … D_s`, refined, oriented and described,
/// offered to the `out` heap (the strongest kept).
fn find_extrema<'a>(o: &Octave<'a>, cfg: &SiftConfig, out: &mut [SiftFeature], len: &mut usize) {
    let s = usize::from(cfg.intervals);
    let (w, h) = (o.w, o.h);
    let threshold = 0.5 * cfg.contrast_threshold / s as f32;
    for layer in 1..=s {
        let (prev, cur, next) = (o.d(layer - 1), o.d(layer), o.d(layer + 1));
        for y in BORDER..h.saturating_sub(BORDER) {
            let row =
                |p: &'a [f32], yy: usize| -> &'a [f32] { p.get(yy * w..yy * w + w).unwrap_or(&[]) };
            let (c0, c1, c2) = (row(cur, y - 1), row(cur, y), row(cur, y + 1));
            let (p0, p1, p2) = (row(prev, y - 1), row(prev, y), row(prev, y + 1));
            let (n0, n1, n2) = (row(next, y - 1), row(next, y), row(next, y + 1));
            for x in BORDER..w.saturating_sub(BORDER) {
                let Some(&v) = c1.get(x) else { continue };
                if v.is_nan() || v.abs() <= threshold {
                    continue;
                }
                let win = |r: &[f32]| -> [f32; 3] {
                    match r.get(x - 1..x + 2) {
                        Some(&[a, b, c]) => [a, b, c],
                        _ => [f32::NAN; 3],
                    }
                };
                let mid = win(c1);
                let others = [
                    win(c0),
                    win(c2),
                    win(p0),
                    win(p1),
                    win(p2),
                    win(n0),
                    win(n1),
                    win(n2),
                ];
                let extremum = if v > 0.0 {
                    v >= mid[0] && v >= mid[2] && others.iter().flatten().all(|&u| v >= u)
                } else {
                    v <= mid[0] && v <= mid[2] && others.iter().flatten().all(|&u| v <= u)
                };
                if !extremum {
                    continue;
                }
                if let Some(kp) = refine(o, cfg, x, y, layer) {
                    orient_and_describe(o, cfg, kp, out, len);
                }
            }
        }
    }
}

/// A refined extremum: octave sample, layer and offsets.
#[derive(Clone, Copy)]
struct Refined {
    x: usize,
    y: usize,
    layer: usize,
    dx: f32,
    dy: f32,
    ds: f32,
    response: f32,
}

/// Step 3 (module docs) from the extremum at `(x, y)` of `D_layer`.
fn refine(o: &Octave<'_>, cfg: &SiftConfig, x: usize, y: usize, layer: usize) -> Option<Refined> {
    let s = usize::from(cfg.intervals);
    let (w, h) = (o.w, o.h);
    let (mut x, mut y, mut layer) = (x, y, layer);
    let mut step = 0;
    let (delta, grad) = loop {
        if step >= MAX_REFINE_STEPS {
            return None;
        }
        let (p, c, n) = (o.d(layer - 1), o.d(layer), o.d(layer + 1));
        let v = at(c, w, x, y);
        let grad = [
            0.5 * (at(c, w, x + 1, y) - at(c, w, x - 1, y)),
            0.5 * (at(c, w, x, y + 1) - at(c, w, x, y - 1)),
            0.5 * (at(n, w, x, y) - at(p, w, x, y)),
        ];
        let dxx = at(c, w, x + 1, y) + at(c, w, x - 1, y) - 2.0 * v;
        let dyy = at(c, w, x, y + 1) + at(c, w, x, y - 1) - 2.0 * v;
        let dss = at(n, w, x, y) + at(p, w, x, y) - 2.0 * v;
        let dxy = 0.25
            * (at(c, w, x + 1, y + 1) - at(c, w, x - 1, y + 1) - at(c, w, x + 1, y - 1)
                + at(c, w, x - 1, y - 1));
        let dxs = 0.25
            * (at(n, w, x + 1, y) - at(n, w, x - 1, y) - at(p, w, x + 1, y) + at(p, w, x - 1, y));
        let dys = 0.25
            * (at(n, w, x, y + 1) - at(n, w, x, y - 1) - at(p, w, x, y + 1) + at(p, w, x, y - 1));
        let hess = [[dxx, dxy, dxs], [dxy, dyy, dys], [dxs, dys, dss]];
        let delta = solve3(&hess, &grad)?.map(|d| -d);
        if delta.iter().all(|d| d.abs() < 0.5) {
            break (delta, grad);
        }
        if delta.iter().any(|d| d.is_nan() || d.abs() >= 1e6) {
            return None;
        }
        let mv = |a: usize, d: f32| (a as i64 + libm::roundf(d) as i64).max(0) as usize;
        (x, y, layer) = (mv(x, delta[0]), mv(y, delta[1]), mv(layer, delta[2]));
        if layer < 1 || layer > s || x < BORDER || x + BORDER >= w || y < BORDER || y + BORDER >= h
        {
            return None;
        }
        step += 1;
    };
    let c = o.d(layer);
    let v = at(c, w, x, y);
    let contrast = v + 0.5 * (grad[0] * delta[0] + grad[1] * delta[1] + grad[2] * delta[2]);
    if contrast.abs() * (s as f32) < cfg.contrast_threshold {
        return None;
    }
    let dxx = at(c, w, x + 1, y) + at(c, w, x - 1, y) - 2.0 * v;
    let dyy = at(c, w, x, y + 1) + at(c, w, x, y - 1) - 2.0 * v;
    let dxy = 0.25
        * (at(c, w, x + 1, y + 1) - at(c, w, x - 1, y + 1) - at(c, w, x + 1, y - 1)
            + at(c, w, x - 1, y - 1));
    let (tr, det) = (dxx + dyy, dxx * dyy - dxy * dxy);
    let r = cfg.edge_threshold;
    if det.is_nan() || det <= 0.0 || tr * tr * r >= (r + 1.0) * (r + 1.0) * det {
        return None;
    }
    Some(Refined {
        x,
        y,
        layer,
        dx: delta[0],
        dy: delta[1],
        ds: delta[2],
        response: contrast.abs(),
    })
}

/// `A⁻¹ b` for a symmetric 3x3 `A` by the adjugate, `None` when singular.
fn solve3(a: &[[f32; 3]; 3], b: &[f32; 3]) -> Option<[f32; 3]> {
    let [[a00, a01, a02], [a10, a11, a12], [a20, a21, a22]] = *a;
    let c00 = a11 * a22 - a12 * a21;
    let c01 = a12 * a20 - a10 * a22;
    let c02 = a10 * a21 - a11 * a20;
    let det = a00 * c00 + a01 * c01 + a02 * c02;
    if !det.is_finite() || det.abs() <= f32::MIN_POSITIVE {
        return None;
    }
    let inv = [
        [c00, a02 * a21 - a01 * a22, a01 * a12 - a02 * a11],
        [c01, a00 * a22 - a02 * a20, a02 * a10 - a00 * a12],
        [c02, a01 * a20 - a00 * a21, a00 * a11 - a01 * a10],
    ];
    let x = inv.map(|r| (r[0] * b[0] + r[1] * b[1] + r[2] * b[2]) / det);
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Steps 4 and 5 (module docs) for a refined extremum: one feature per orientation peak.
fn orient_and_describe(
    o: &Octave<'_>,
    cfg: &SiftConfig,
    r: Refined,
    out: &mut [SiftFeature],
    len: &mut usize,
) {
    let s = cfg.intervals as f32;
    let scl = cfg.sigma * libm::exp2f((r.layer as f32 + r.ds) / s);
    let g = o.g(r.layer);
    let unit = libm::exp2f(f32::from(o.index));
    let (xo, yo) = (r.x as f32 + r.dx, r.y as f32 + r.dy);
    let mut hist = [0.0f32; ORI_BINS];
    orientation_histogram(g, o.w, o.h, r.x, r.y, scl, &mut hist);
    let max = hist.iter().copied().fold(0.0f32, f32::max);
    if max.is_nan() || max <= 0.0 {
        return;
    }
    for j in 0..ORI_BINS {
        let (l, c, rr) = (
            hist.get((j + ORI_BINS - 1) % ORI_BINS)
                .copied()
                .unwrap_or(0.0),
            hist.get(j).copied().unwrap_or(0.0),
            hist.get((j + 1) % ORI_BINS).copied().unwrap_or(0.0),
        );
        if !(c > l && c > rr && c >= ORI_PEAK_RATIO * max) {
            continue;
        }
        let mut bin = j as f32 + 0.5 * (l - rr) / (l - 2.0 * c + rr);
        if bin < 0.0 {
            bin += ORI_BINS as f32;
        } else if bin >= ORI_BINS as f32 {
            bin -= ORI_BINS as f32;
        }
        // The histogram is of y-up angles `φ`; the keypoint's y-down angle is `−φ`.
        let phi = bin * (core::f32::consts::TAU / ORI_BINS as f32);
        let mut angle = core::f32::consts::TAU - phi;
        if !(0.0..core::f32::consts::TAU).contains(&angle) {
            angle = 0.0;
        }
        let mut descriptor = FloatDescriptor::default();
        describe(g, o.w, o.h, xo, yo, phi, scl, cfg.root, &mut descriptor.0);
        let feature = SiftFeature {
            keypoint: SiftKeypoint {
                x: xo * unit,
                y: yo * unit,
                sigma: scl * unit,
                angle,
                response: r.response,
                octave: o.index,
                layer: r.layer as u8,
            },
            descriptor,
        };
        super::offer_best(out, len, feature, |f| {
            i64::from(f.keypoint.response.to_bits())
        });
    }
}

/// The smoothed 36-bin histogram of y-up gradient angles around `(x, y)` of `g` (step 4).
fn orientation_histogram(
    g: &[f32],
    w: usize,
    h: usize,
    x: usize,
    y: usize,
    scl: f32,
    hist: &mut [f32; ORI_BINS],
) {
    let radius = (libm::roundf(ORI_RADIUS * scl) as i32).clamp(0, MAX_DESCR_RADIUS);
    let sig = ORI_SIG_FCTR * scl;
    let e = -1.0 / (2.0 * sig * sig);
    let mut raw = [0.0f32; ORI_BINS];
    for i in -radius..=radius {
        let yy = y as i64 + i64::from(i);
        if yy <= 0 || yy >= h as i64 - 1 {
            continue;
        }
        let yy = yy as usize;
        for j in -radius..=radius {
            let xx = x as i64 + i64::from(j);
            if xx <= 0 || xx >= w as i64 - 1 {
                continue;
            }
            let xx = xx as usize;
            let dx = at(g, w, xx + 1, yy) - at(g, w, xx - 1, yy);
            let dy = at(g, w, xx, yy - 1) - at(g, w, xx, yy + 1);
            let weight = libm::expf((i * i + j * j) as f32 * e);
            let mag = libm::sqrtf(dx * dx + dy * dy);
            let mut ang = libm::atan2f(dy, dx);
            if ang < 0.0 {
                ang += core::f32::consts::TAU;
            }
            let bin = libm::roundf(ang * (ORI_BINS as f32 / core::f32::consts::TAU)) as usize;
            if let Some(b) = raw.get_mut(bin % ORI_BINS) {
                *b += weight * mag;
            }
        }
    }
    let t = |k: isize| {
        raw.get(k.rem_euclid(ORI_BINS as isize) as usize)
            .copied()
            .unwrap_or(0.0)
    };
    for (i, v) in hist.iter_mut().enumerate() {
        let i = i as isize;
        *v = (t(i - 2) + t(i + 2)) * (1.0 / 16.0)
            + (t(i - 1) + t(i + 1)) * (4.0 / 16.0)
            + t(i) * (6.0 / 16.0);
    }
}

/// Step 5: the descriptor of the keypoint at `(xf, yf)` of `g` (octave pixels), y-up angle
/// `phi`, scale `scl` (OpenCV's `calcSIFTDescriptor`).
#[allow(clippy::too_many_arguments)]
fn describe(
    g: &[f32],
    w: usize,
    h: usize,
    xf: f32,
    yf: f32,
    phi: f32,
    scl: f32,
    root: bool,
    dst: &mut [f32; DESCRIPTOR_LEN],
) {
    const D: usize = DESCR_WIDTH;
    const N: usize = DESCR_BINS;
    const HIST: usize = (D + 2) * (D + 2) * (N + 2);
    let (px, py) = (libm::roundf(xf) as i64, libm::roundf(yf) as i64);
    let hist_width = DESCR_SCL_FCTR * scl;
    let radius = (libm::roundf(hist_width * core::f32::consts::SQRT_2 * (D as f32 + 1.0) * 0.5)
        as i32)
        .clamp(0, MAX_DESCR_RADIUS);
    let (cos_t, sin_t) = (libm::cosf(phi) / hist_width, libm::sinf(phi) / hist_width);
    let bins_per_rad = N as f32 / core::f32::consts::TAU;
    let exp_scale = -1.0 / (D as f32 * D as f32 * 0.5);
    let mut hist = [0.0f32; HIST];
    let half = D as f32 / 2.0 - 0.5;
    for i in -radius..=radius {
        for j in -radius..=radius {
            let (fi, fj) = (i as f32, j as f32);
            let c_rot = fj * cos_t - fi * sin_t;
            let r_rot = fj * sin_t + fi * cos_t;
            let (rbin, cbin) = (r_rot + half, c_rot + half);
            let (r, c) = (py + i64::from(i), px + i64::from(j));
            if !(rbin > -1.0 && rbin < D as f32 && cbin > -1.0 && cbin < D as f32) {
                continue;
            }
            if r <= 0 || r >= h as i64 - 1 || c <= 0 || c >= w as i64 - 1 {
                continue;
            }
            let (r, c) = (r as usize, c as usize);
            let dx = at(g, w, c + 1, r) - at(g, w, c - 1, r);
            let dy = at(g, w, c, r - 1) - at(g, w, c, r + 1);
            let weight = libm::expf((c_rot * c_rot + r_rot * r_rot) * exp_scale);
            let mag = libm::sqrtf(dx * dx + dy * dy) * weight;
            let mut ang = libm::atan2f(dy, dx);
            if ang < 0.0 {
                ang += core::f32::consts::TAU;
            }
            let obin = (ang - phi) * bins_per_rad;
            let (r0, c0, o0) = (libm::floorf(rbin), libm::floorf(cbin), libm::floorf(obin));
            let (rb, cb, ob) = (rbin - r0, cbin - c0, obin - o0);
            let o0 = (o0 as i32).rem_euclid(N as i32) as usize;
            let (r0, c0) = ((r0 as i32 + 1) as usize, (c0 as i32 + 1) as usize);
            let v_r1 = mag * rb;
            let v_r0 = mag - v_r1;
            let v_rc11 = v_r1 * cb;
            let v_rc10 = v_r1 - v_rc11;
            let v_rc01 = v_r0 * cb;
            let v_rc00 = v_r0 - v_rc01;
            let idx = (r0 * (D + 2) + c0) * (N + 2) + o0;
            let row = (D + 2) * (N + 2);
            for (off, v) in [
                (0, v_rc00),
                (N + 2, v_rc01),
                (row, v_rc10),
                (row + N + 2, v_rc11),
            ] {
                let v1 = v * ob;
                if let Some(b) = hist.get_mut(idx + off) {
                    *b += v - v1;
                }
                if let Some(b) = hist.get_mut(idx + off + 1) {
                    *b += v1;
                }
            }
        }
    }
    // Fold the wrapped orientation bins and copy out.
    for i in 0..D {
        for j in 0..D {
            let idx = ((i + 1) * (D + 2) + (j + 1)) * (N + 2);
            let (a, b) = (
                hist.get(idx + N).copied().unwrap_or(0.0),
                hist.get(idx + N + 1).copied().unwrap_or(0.0),
            );
            if let Some(v) = hist.get_mut(idx) {
                *v += a;
            }
            if let Some(v) = hist.get_mut(idx + 1) {
                *v += b;
            }
            for k in 0..N {
                if let (Some(d), Some(&v)) = (dst.get_mut((i * D + j) * N + k), hist.get(idx + k)) {
                    *d = v;
                }
            }
        }
    }
    normalise(dst, root);
}

/// Unit length, clamped at [`DESCR_MAG_THR`], unit length again; RootSIFT when `root`.
fn normalise(v: &mut [f32; DESCRIPTOR_LEN], root: bool) {
    let norm = |v: &[f32; DESCRIPTOR_LEN]| libm::sqrtf(v.iter().map(|x| x * x).sum::<f32>());
    let thr = norm(v) * DESCR_MAG_THR;
    for x in v.iter_mut() {
        *x = x.min(thr);
    }
    if root {
        let l1: f32 = v.iter().map(|x| x.abs()).sum();
        let l1 = l1.max(f32::MIN_POSITIVE);
        for x in v.iter_mut() {
            *x = libm::sqrtf((*x).max(0.0) / l1);
        }
        return;
    }
    let n = norm(v).max(f32::MIN_POSITIVE);
    for x in v.iter_mut() {
        *x /= n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    fn blobs(w: usize, h: usize) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let mut v = 128.0;
                for (k, (cx, cy, r)) in [(30.0, 30.0, 5.0), (80.0, 40.0, 8.0), (50.0, 75.0, 3.5)]
                    .iter()
                    .enumerate()
                {
                    let d2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
                    let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                    v += sign * 100.0 * (-d2 / (2.0 * r * r)).exp();
                }
                v as u8
            })
            .collect()
    }

    #[test]
    fn finds_blobs_at_their_centres_and_scales() {
        let (w, h) = (112, 100);
        let img = blobs(w, h);
        let view = ImageView::packed(&img, w, h).unwrap();
        for upsample in [false, true] {
            let cfg = SiftConfig {
                upsample,
                ..SiftConfig::default()
            };
            let mut scratch = vec![0.0; scratch_len(w, h, 3, upsample)];
            let mut out = vec![SiftFeature::default(); 64];
            let n = sift_detect(&view, &cfg.check().unwrap(), &mut scratch, &mut out).unwrap();
            for (cx, cy, r) in [
                (30.0f32, 30.0f32, 5.0f32),
                (80.0, 40.0, 8.0),
                (50.0, 75.0, 3.5),
            ] {
                let f = out[..n]
                    .iter()
                    .find(|f| (f.keypoint.x - cx).hypot(f.keypoint.y - cy) < 0.3)
                    .unwrap_or_else(|| panic!("no keypoint at {cx},{cy} (upsample {upsample})"));
                // A Gaussian blob of σ_b is a DoG extremum at scale ≈ σ_b (√2 σ_b for the
                // Laplacian's peak on an ideal blob; close enough for a check).
                assert!(
                    f.keypoint.sigma > 0.7 * r && f.keypoint.sigma < 2.0 * r,
                    "{:?} for blob radius {r}",
                    f.keypoint
                );
                let norm: f32 = f.descriptor.0.iter().map(|x| x * x).sum();
                assert!((norm - 1.0).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn buffers_and_parameters_are_checked() {
        let img = blobs(40, 40);
        let view = ImageView::packed(&img, 40, 40).unwrap();
        let p = SiftParams::default();
        let mut out = [SiftFeature::default(); 4];
        let mut short = vec![0.0; scratch_len(40, 40, 3, false) - 1];
        assert_eq!(
            sift_detect(&view, &p, &mut short, &mut out),
            Err(Error::BufferTooSmall("scratch"))
        );
        // Tiny images and an empty output find nothing.
        let tiny = [0u8; 9];
        let mut s = vec![0.0; scratch_len(3, 3, 3, false)];
        let v = ImageView::packed(&tiny, 3, 3).unwrap();
        assert_eq!(sift_detect(&v, &p, &mut s, &mut out), Ok(0));
        let mut s = vec![0.0; scratch_len(40, 40, 3, false)];
        assert_eq!(sift_detect(&view, &p, &mut s, &mut []), Ok(0));
        for (cfg, name) in [
            (
                SiftConfig {
                    intervals: 0,
                    ..Default::default()
                },
                "sift.intervals",
            ),
            (
                SiftConfig {
                    sigma: f32::NAN,
                    ..Default::default()
                },
                "sift.sigma",
            ),
            (
                SiftConfig {
                    contrast_threshold: -1.0,
                    ..Default::default()
                },
                "sift.contrast_threshold",
            ),
            (
                SiftConfig {
                    edge_threshold: 1.0,
                    ..Default::default()
                },
                "sift.edge_threshold",
            ),
        ] {
            assert_eq!(cfg.check(), Err(Error::InvalidParameter(name)));
        }
    }

    #[test]
    fn blur_matches_a_direct_convolution() {
        let (w, h) = (37, 23);
        let src: Vec<f32> = (0..w * h)
            .map(|i| ((i * 7919) % 255) as f32 / 255.0)
            .collect();
        let mut dst = vec![0.0; w * h];
        let mut tmp = vec![0.0; w * h];
        let mut pad = vec![0.0; w + 2 * MAX_RADIUS];
        let sigma = 1.3;
        blur(&src, &mut dst, &mut tmp, &mut pad, w, sigma);
        let (k, r) = kernel(sigma);
        for y in 0..h {
            for x in 0..w {
                let mut acc = 0.0f64;
                for i in 0..=2 * r {
                    for j in 0..=2 * r {
                        let sy = reflect(y as isize + i as isize - r as isize, h);
                        let sx = reflect(x as isize + j as isize - r as isize, w);
                        acc += f64::from(k[i]) * f64::from(k[j]) * f64::from(src[sy * w + sx]);
                    }
                }
                assert!((acc as f32 - dst[y * w + x]).abs() < 1e-5);
            }
        }
    }
}
