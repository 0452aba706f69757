//! ORB features (Rublee, Rabaud, Konolige and Bradski, "ORB: an efficient alternative to SIFT
//! or SURF", ICCV 2011): FAST corners ranked by their Harris response on every level of a
//! Gaussian pyramid, an orientation from the intensity centroid, and a 256-bit BRIEF descriptor
//! steered by that orientation.
//!
//! Per pyramid level `l` (level 0 is the frame; level `l + 1` is level `l` shrunk by the scale
//! step `s`: bilinearly for OpenCV's `s = 1.2`, or by the Gaussian [`crate::pyramid`] for
//! `s = 2`):
//!
//! 1. FAST-9 corners with non-maximum suppression ([`super::fast`]) at least `border` pixels
//!    from the level's edge; each is ranked by its integer Harris response and the best
//!    `quota_l` are kept (a bounded min-heap in the output vector). The quotas split
//!    `max_features` in proportion `s⁻ˡ` (OpenCV's split); what a level does not use passes to
//!    the next.
//! 2. Orientation `θ = atan2(m₀₁, m₁₀)`, `m_pq = Σ xᵖ yq I(x, y)` over the disc of radius 15
//!    ([`PATCH_RADIUS`]) around the corner, on the unsmoothed level (OpenCV's `ICAngles`).
//! 3. The level is smoothed by a 7-tap Gaussian `[9 17 24 28 24 17 9] / 128` (σ ≈ 2, as
//!    OpenCV's 7x7 σ = 2 blur) in both directions, and bit `i` of the descriptor is
//!    `S(R_θ pᵢ) < S(R_θ qᵢ)` for the `i`-th pair of [`PATTERN`], rotated by `θ` (Q14 sine and
//!    cosine, offsets rounded to the nearest pixel).
//!
//! Keypoint coordinates are mapped to level 0 through the pixel-centre-aligned maps of the
//! reductions: `x_prev = (x + ½) w_prev / w - ½` for the bilinear levels, `x_prev = 2x` for the
//! Gaussian pyramid (whose output pixel `x` is centred on input pixel `2x`).
//!
//! The sampling pattern is this crate's own, not the learned pattern of the paper: 256 pairs of
//! points drawn from an isotropic Gaussian of σ = 31/5 px (BRIEF's "G II" sampling for a 31-px
//! patch), each point rounded to the pixel grid and kept only inside the disc of radius
//! [`PATTERN_RADIUS`] (so every rotation stays inside the smoothed patch), pairs of equal
//! points rejected. The generator is SplitMix64 seeded with [`PATTERN_SEED`]; the Gaussian is
//! the sum of twelve 16-bit uniforms (Irwin-Hall, variance 1 after centring). It is evaluated
//! at compile time: the pattern is the same on every target and in every build.
//!
//! Two options, off by default (the default is OpenCV's ORB, bit for bit what it was before
//! them), for structure from motion on large photographs:
//!
//! - a spatial distribution ([`OrbConfig::grid_cell`]): each level's corners are bucketed in
//!   square cells that keep their strongest few, and the level takes the best of every cell
//!   before the second best of any; it works in the output's free capacity
//!   ([`grid_capacity`] slots, 64 bytes each) and one byte a cell of the scratch;
//! - sub-pixel positions ([`OrbConfig::subpixel`], [`subpixel_offset`]): the least-squares
//!   meeting point of the edges around the corner, on its level.
//!
//! [`orb_detect_into`] writes into a slice of any length, for outputs sized at run time.
//!
//! Memory: [`scratch_len`] bytes of caller scratch (levels 1 and 2, which odd and even levels
//! reuse in turn, one smoothed level, three rows of FAST scores): 2.2 frames for `s = 1.2`. Work: bounded by the pixel count of the pyramid (FAST and
//! smoothing) plus, per FAST corner, one 7x7 Harris sum, plus per kept feature a 31x31 centroid
//! and 512 samples.

use heapless::Vec;

use super::fast::{self, Corner, FastConfig, FastParams, harris_response};
use super::matching::Descriptor;
use super::offer_best;
use crate::image::{ImageMut, ImageView};
use crate::pyramid;
use crate::resize::resize_bilinear;
use crate::{Error, Result};

/// Radius of the orientation disc (ORB's 31-pixel patch).
pub const PATCH_RADIUS: usize = 15;
/// Radius of the disc holding every point of [`PATTERN`].
pub const PATTERN_RADIUS: i32 = 13;
/// Smallest distance of a keypoint to its level's border: the orientation disc fits, and so do
/// the rotated pattern points.
pub const MIN_BORDER: u16 = PATCH_RADIUS as u16 + 1;
/// Seed of the SplitMix64 generator that draws [`PATTERN`].
pub const PATTERN_SEED: u64 = 0x0c47_6e0b_2024_0001;

/// Half-widths of the orientation disc per row offset `|v|` (OpenCV's symmetric `umax`).
const UMAX: [i32; PATCH_RADIUS + 1] = [15, 15, 15, 15, 14, 14, 14, 13, 13, 12, 11, 10, 9, 8, 6, 3];

/// The 7 smoothing taps, summing to 128.
const BLUR: [u32; 7] = [9, 17, 24, 28, 24, 17, 9];
/// Output pixels per tile of the horizontal smoothing pass.
const TILE: usize = 256;

const fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One Gaussian coordinate of σ = 31/5, rounded to the nearest integer.
const fn gaussian_coordinate(state: &mut u64) -> i32 {
    // Twelve 16-bit uniforms: mean 6 · 2¹⁶ (minus the half-step), variance ≈ 2³².
    let mut sum: i64 = 0;
    let mut k = 0;
    while k < 3 {
        let r = splitmix64(state);
        sum += ((r & 0xffff) + ((r >> 16) & 0xffff) + ((r >> 32) & 0xffff) + (r >> 48)) as i64;
        k += 1;
    }
    let centred = 2 * sum - 12 * 65535; // 2 (sum - 6 · 65535 / 2): N(0, (2¹⁷)²)
    let num = centred * 31;
    let den = 5 * 131_072;
    // Round half away from zero.
    (if num >= 0 {
        (num + den / 2) / den
    } else {
        (num - den / 2) / den
    }) as i32
}

// `n < 256` is the loop condition: the one index cannot miss (and a miss would be a
// compile-time error, the function only runs in const evaluation).
#[allow(clippy::indexing_slicing)]
const fn make_pattern() -> [[i8; 4]; 256] {
    let mut out = [[0i8; 4]; 256];
    let mut state = PATTERN_SEED;
    let r2 = PATTERN_RADIUS * PATTERN_RADIUS;
    let mut n = 0;
    while n < 256 {
        let x1 = gaussian_coordinate(&mut state);
        let y1 = gaussian_coordinate(&mut state);
        let x2 = gaussian_coordinate(&mut state);
        let y2 = gaussian_coordinate(&mut state);
        if x1 * x1 + y1 * y1 <= r2 && x2 * x2 + y2 * y2 <= r2 && (x1 != x2 || y1 != y2) {
            out[n] = [x1 as i8, y1 as i8, x2 as i8, y2 as i8];
            n += 1;
        }
    }
    out
}

/// The 256 BRIEF test pairs `[x₁, y₁, x₂, y₂]` (pixels, relative to the keypoint, y down); see
/// the module docs for how they are drawn.
pub const PATTERN: [[i8; 4]; 256] = make_pattern();

/// Parameters of [`orb_detect`], as the user writes them; checked by [`Self::check`] into the
/// [`OrbParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OrbConfig {
    /// Features to keep over all levels (further capped by the output capacity). Default 500.
    pub max_features: u16,
    /// Pyramid levels, 1 to [`MAX_LEVELS`]. Default 8 (OpenCV's `nlevels`).
    pub levels: u8,
    /// Scale step between levels in Q8, `s = scale_q8 / 256`, in `272..=512` (1.0625 to 2).
    /// Default 307 (1.199, OpenCV's `scaleFactor` 1.2): each level is the previous one resized
    /// bilinearly ([`crate::resize`]). 512 selects the Gaussian pyramid
    /// ([`crate::pyramid::pyr_down`], smoothed, 1/3 of the memory of the default).
    pub scale_q8: u16,
    /// FAST threshold, `≥ 1`. Default 20 (OpenCV's `fastThreshold`).
    pub fast_threshold: u8,
    /// Distance of keypoints to the border of their level, raised to [`MIN_BORDER`].
    /// Default [`MIN_BORDER`] (OpenCV's `edgeThreshold` is 31).
    pub border: u16,
    /// Spatial distribution: the side, in pixels of each level, of the square grid cells the
    /// level's corners are bucketed into, `0` (default: off, every level keeps its strongest
    /// corners wherever they are) or at least [`MIN_GRID_CELL`]. With a grid each cell keeps
    /// its [`cell_keep`](Self::cell_keep) strongest corners, ranked within the cell; the level
    /// then takes the best of every cell first, then the second best, and so on (by Harris
    /// response within a rank) up to its share. See [`grid_capacity`] for the output capacity
    /// it works in.
    pub grid_cell: u16,
    /// Corners each grid cell keeps, `1..=255` when [`grid_cell`](Self::grid_cell) is on
    /// (ignored when off). Default 0.
    pub cell_keep: u8,
    /// Sub-pixel keypoint positions ([`subpixel_offset`]): the peak of the quadratic fitted to
    /// the Harris response over the 3x3 neighbourhood of the corner on its level (orientation
    /// and descriptor stay at the integer pixel). Default `false`: integer level coordinates.
    pub subpixel: bool,
}

impl Default for OrbConfig {
    fn default() -> Self {
        Self {
            max_features: 500,
            levels: 8,
            scale_q8: 307,
            fast_threshold: 20,
            border: MIN_BORDER,
            grid_cell: 0,
            cell_keep: 0,
            subpixel: false,
        }
    }
}

impl OrbConfig {
    /// Checks the ranges documented on each field once: [`orb_detect`] takes the checked
    /// [`OrbParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field (`orb.levels` outside
    /// `1..=MAX_LEVELS`, `orb.scale_q8` outside `272..=512`, `orb.fast_threshold` zero,
    /// `orb.grid_cell` in `1..MIN_GRID_CELL`, `orb.cell_keep` zero with a grid).
    pub const fn check(&self) -> Result<OrbParams> {
        if self.levels == 0 || self.levels as usize > MAX_LEVELS {
            return Err(Error::InvalidParameter("orb.levels"));
        }
        if self.fast_threshold == 0 {
            return Err(Error::InvalidParameter("orb.fast_threshold"));
        }
        if self.scale_q8 < 272 || self.scale_q8 > 512 {
            return Err(Error::InvalidParameter("orb.scale_q8"));
        }
        if self.grid_cell != 0 && self.grid_cell < MIN_GRID_CELL {
            return Err(Error::InvalidParameter("orb.grid_cell"));
        }
        if self.grid_cell != 0 && self.cell_keep == 0 {
            return Err(Error::InvalidParameter("orb.cell_keep"));
        }
        Ok(OrbParams(*self))
    }
}

/// An [`OrbConfig`] that passed [`OrbConfig::check`]: `1..=MAX_LEVELS` levels, a scale step in
/// `272..=512` (Q8), a FAST threshold `≥ 1`. What [`orb_detect`] takes, so that no call checks
/// it again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OrbParams(OrbConfig);

impl OrbParams {
    /// The checked configuration.
    pub const fn config(&self) -> &OrbConfig {
        &self.0
    }
}

impl Default for OrbParams {
    /// The checked [`OrbConfig::default`].
    fn default() -> Self {
        Self(OrbConfig::default())
    }
}

impl TryFrom<OrbConfig> for OrbParams {
    type Error = Error;
    fn try_from(c: OrbConfig) -> Result<Self> {
        c.check()
    }
}

/// Most pyramid levels.
pub const MAX_LEVELS: usize = 12;

/// Smallest grid cell side ([`OrbConfig::grid_cell`]), in pixels of a level.
pub const MIN_GRID_CELL: u16 = 8;

/// Cells of the grid of side `cell` over a `width x height` level:
/// `⌈width / cell⌉ ⌈height / cell⌉` (0 for `cell = 0`).
pub const fn grid_cells(width: usize, height: usize, cell: usize) -> usize {
    if cell == 0 {
        return 0;
    }
    width.div_ceil(cell) * height.div_ceil(cell)
}

/// Output capacity `N` at which the grid of `config` is used as configured on every level of
/// a `width x height` frame: `max_features + cell_keep · grid_cells(width, height, grid_cell)`
/// (level 0 has the most cells); `max_features` without a grid.
///
/// [`orb_detect`] ranks a level's corners in the free capacity of its output (`cell_keep`
/// slots a cell) and counts them in the scratch it already takes (one byte a cell): the grid
/// needs no other memory. When the free capacity is short it doubles the cell side until the
/// cells fit, so a smaller `N` works too, with coarser cells. A [`Feature`] is 64 bytes: a
/// 1536x1024 frame with 5000 features and 16-pixel cells keeping 4 needs `N >= 29_576`
/// (1.9 MB).
pub const fn grid_capacity(width: usize, height: usize, config: &OrbConfig) -> usize {
    let max = config.max_features as usize;
    if config.grid_cell == 0 {
        return max;
    }
    max + config.cell_keep as usize * grid_cells(width, height, config.grid_cell as usize)
}

/// An oriented keypoint.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Keypoint {
    /// Column in level-0 pixels: `x₀ = a x_l + b` for the level's pixel-centre-aligned map
    /// (`a = 2ˡ`, `b = 0` for the Gaussian pyramid).
    pub x: f32,
    /// Row in level-0 pixels.
    pub y: f32,
    /// Pyramid level it was detected on.
    pub level: u8,
    /// Level-0 pixels per pixel of its level (`≈ sˡ`): its patch covers `31 scale` pixels.
    pub scale: f32,
    /// Orientation `θ = atan2(m₀₁, m₁₀)` in radians, `(-π, π]`, y down (clockwise on screen).
    pub angle: f32,
    /// Harris response ([`super::fast::harris_response`]) on its level.
    pub response: i64,
    /// FAST score on its level.
    pub score: u8,
}

/// A keypoint with its descriptor.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Feature {
    /// Where.
    pub keypoint: Keypoint,
    /// Steered BRIEF bits: bit `i` (word `i / 32`, bit `i % 32`) is test `i` of [`PATTERN`].
    pub descriptor: Descriptor,
}

/// Size of level `level` for scale step `scale_q8`: each level is
/// `(⌈256 w / scale_q8⌉, ⌈256 h / scale_q8⌉)` of the previous one (so `(⌈w/2⌉, ⌈h/2⌉)` for
/// 512, as [`crate::pyramid::down_size`]).
pub const fn level_size(
    width: usize,
    height: usize,
    scale_q8: u16,
    level: usize,
) -> (usize, usize) {
    let (mut w, mut h, mut l) = (width, height, 0);
    let q = if scale_q8 == 0 { 1 } else { scale_q8 as usize };
    while l < level {
        w = (w * 256).div_ceil(q);
        h = (h * 256).div_ceil(q);
        l += 1;
    }
    (w, h)
}

/// Bytes of scratch [`orb_detect`] needs for a `width x height` frame and scale step
/// `scale_q8` (any number of levels): levels 1 and 2 (odd and even levels take turns in
/// them), one smoothed frame and three rows of FAST scores:
/// `|level 1| + |level 2| + width height + 3 width`.
pub const fn scratch_len(width: usize, height: usize, scale_q8: u16) -> usize {
    let (w1, h1) = level_size(width, height, scale_q8, 1);
    let (w2, h2) = level_size(width, height, scale_q8, 2);
    w1 * h1 + w2 * h2 + width * height + fast::scratch_len(width)
}

/// Level-`l` pixel `x` is level-0 pixel `a x + b` (per axis).
#[derive(Debug, Clone, Copy)]
struct LevelMap {
    ax: f32,
    bx: f32,
    ay: f32,
    by: f32,
}

impl LevelMap {
    /// The map of the next level, reduced from `prev` to `cur` pixels by `pyr_down` (`gauss`)
    /// or by [`resize_bilinear`] (`x_prev = (x + ½) prev / cur - ½`).
    fn next(self, gauss: bool, prev: (usize, usize), cur: (usize, usize)) -> Self {
        if gauss {
            return Self {
                ax: 2.0 * self.ax,
                ay: 2.0 * self.ay,
                ..self
            };
        }
        let rx = prev.0 as f32 / cur.0 as f32;
        let ry = prev.1 as f32 / cur.1 as f32;
        Self {
            ax: self.ax * rx,
            bx: self.ax * (0.5 * rx - 0.5) + self.bx,
            ay: self.ay * ry,
            by: self.ay * (0.5 * ry - 0.5) + self.by,
        }
    }
}

/// ORB features of `frame` into `out` (cleared first), strongest Harris response first.
///
/// `scratch` must hold [`scratch_len`]`(width, height, config.scale_q8)` bytes. At most
/// `min(config.max_features, N)` features; levels get shares in proportion `s⁻ˡ` (OpenCV's
/// split), what a level does not fill passes to the next.
///
/// Errors: [`Error::BufferTooSmall`] for a short `scratch`.
#[doc(alias = "ORB")]
#[doc(alias = "detectAndCompute")]
pub fn orb_detect<const N: usize>(
    frame: &ImageView<'_, u8>,
    params: &OrbParams,
    scratch: &mut [u8],
    out: &mut Vec<Feature, N>,
) -> Result<()> {
    out.clear();
    while out.push(Feature::default()).is_ok() {}
    match orb_detect_into(frame, params, scratch, out) {
        Ok(n) => {
            out.truncate(n);
            Ok(())
        }
        Err(e) => {
            out.clear();
            Err(e)
        }
    }
}

/// [`orb_detect`] into a slice of any length (a buffer sized at run time): writes the
/// features to `out[..n]`, strongest Harris response first, and returns `n`, at most
/// `min(config.max_features, out.len())`. The rest of `out` is work space (the grid of
/// [`OrbConfig::grid_cell`] ranks corners there: see [`grid_capacity`]).
///
/// Errors: [`Error::BufferTooSmall`] for a short `scratch`.
#[doc(alias = "ORB")]
#[doc(alias = "detectAndCompute")]
pub fn orb_detect_into(
    frame: &ImageView<'_, u8>,
    params: &OrbParams,
    scratch: &mut [u8],
    out: &mut [Feature],
) -> Result<usize> {
    let mut len = 0usize;
    let config = params.config();
    let levels = usize::from(config.levels);
    let q = config.scale_q8;
    let (w, h) = (frame.width(), frame.height());
    if scratch.len() < scratch_len(w, h, q) {
        return Err(Error::BufferTooSmall("scratch"));
    }
    let gauss = q == 512;
    let (w1, h1) = level_size(w, h, q, 1);
    let (w2, h2) = level_size(w, h, q, 2);
    // Checked splits: the length check above covers them, but the optimiser cannot see it.
    let too_small = Error::BufferTooSmall("scratch");
    let (buf_odd, rest) = scratch.split_at_mut_checked(w1 * h1).ok_or(too_small)?;
    let (buf_even, rest) = rest.split_at_mut_checked(w2 * h2).ok_or(too_small)?;
    let (blur_buf, fast_buf) = rest.split_at_mut_checked(w * h).ok_or(too_small)?;
    // The threshold is ORB's, checked `≥ 1` with it.
    let fast_params = FastParams::assume_checked(FastConfig {
        threshold: config.fast_threshold,
        nonmax: true,
        border: config.border.max(MIN_BORDER),
    });
    // Level shares in proportion (256/q)^l, as Q16 weights.
    let mut weights = [0u64; MAX_LEVELS];
    let mut wl = 1u64 << 16;
    for weight in weights.iter_mut().take(levels) {
        *weight = wl.max(1);
        // `q` was checked to be at least 272; `max` shows the optimiser it is not zero.
        wl = wl * 256 / u64::from(q.max(1));
    }
    let mut weight_left: u64 = weights.iter().sum();
    let mut budget = usize::from(config.max_features).min(out.len());
    let mut map = LevelMap {
        ax: 1.0,
        bx: 0.0,
        ay: 1.0,
        by: 0.0,
    };
    let mut size = (w, h);
    for l in 0..levels {
        // Level l: the frame, or the previous level reduced into the buffer of its parity.
        let level = if l == 0 {
            *frame
        } else {
            let cur = level_size(size.0, size.1, q, 1);
            let (src, dst): (&[u8], &mut [u8]) = if l % 2 == 1 {
                (if l == 1 { &[] } else { &*buf_even }, &mut *buf_odd)
            } else {
                (&*buf_odd, &mut *buf_even)
            };
            let prev = if l == 1 {
                *frame
            } else {
                ImageView::packed(src, size.0, size.1)?
            };
            let dst = dst
                .get_mut(..cur.0 * cur.1)
                .ok_or(Error::BufferTooSmall("scratch"))?;
            let mut dst_img = ImageMut::packed(dst, cur.0, cur.1)?;
            if gauss {
                pyramid::pyr_down(&prev, &mut dst_img)?;
            } else {
                resize_bilinear(&prev, &mut dst_img)?;
            }
            map = map.next(gauss, size, cur);
            size = cur;
            // Re-borrow the finished level immutably.
            let done: &[u8] = if l % 2 == 1 { &*buf_odd } else { &*buf_even };
            ImageView::packed(done.get(..cur.0 * cur.1).unwrap_or(&[]), cur.0, cur.1)?
        };
        let weight = weights.get(l).copied().unwrap_or(1);
        let quota = if l + 1 == levels {
            budget
        } else {
            ((budget as u64 * weight + weight_left / 2) / weight_left.max(1)) as usize
        };
        weight_left = weight_left.saturating_sub(weight);
        let start = len;
        let (lw, lh) = (level.width(), level.height());
        let corner = |c: Corner| {
            let (x, y) = (usize::from(c.x), usize::from(c.y));
            harris_response(&level, x, y).map(|response| Feature {
                keypoint: Keypoint {
                    x: f32::from(c.x),
                    y: f32::from(c.y),
                    level: l as u8,
                    scale: map.ax,
                    angle: 0.0,
                    response,
                    score: c.score,
                },
                descriptor: Descriptor::default(),
            })
        };
        let kept = if config.grid_cell == 0 {
            let end = (start + quota).min(out.len());
            let heap = out.get_mut(start..end).unwrap_or(&mut []);
            let mut kept = 0usize;
            fast::fast_detect(&level, &fast_params, fast_buf, |c: Corner| {
                if let Some(f) = corner(c) {
                    offer_best(heap, &mut kept, f, |f| f.keypoint.response);
                }
            })?;
            kept
        } else {
            // The cells' counts live in the smoothing buffer, free until the corners are
            // chosen.
            let counts = blur_buf.get_mut(..lw * lh).unwrap_or(&mut []);
            let grid = Grid {
                size: (lw, lh),
                cell: config.grid_cell,
                keep: config.cell_keep,
                level: l as u8,
            };
            grid.select(out, start, quota, counts, |emit| {
                fast::fast_detect(&level, &fast_params, fast_buf, |c| {
                    if let Some(f) = corner(c) {
                        emit(f);
                    }
                })
            })?
        };
        len = start + kept;
        budget -= kept.min(budget);
        if kept == 0 {
            continue;
        }
        let blur_slice = blur_buf
            .get_mut(..lw * lh)
            .ok_or(Error::BufferTooSmall("scratch"))?;
        smooth(&level, &mut ImageMut::packed(blur_slice, lw, lh)?)?;
        let smoothed = ImageView::packed(blur_slice, lw, lh)?;
        for f in out.get_mut(start..len).unwrap_or(&mut []) {
            let (x, y) = (f.keypoint.x as usize, f.keypoint.y as usize);
            let angle = orientation(&level, x, y);
            f.keypoint.angle = angle;
            f.descriptor = steered_brief(&smoothed, x, y, angle);
            if config.subpixel {
                let (dx, dy) = subpixel_offset(&level, x, y);
                f.keypoint.x += dx;
                f.keypoint.y += dy;
            }
            f.keypoint.x = map.ax * f.keypoint.x + map.bx;
            f.keypoint.y = map.ay * f.keypoint.y + map.by;
        }
    }
    // Strongest first; heapsort: core's sorts keep a panic path for comparators that are not
    // total orders, which the optimiser cannot rule out.
    let out = out.get_mut(..len).unwrap_or(&mut []);
    crate::corners::heapsort_by(out, |a, b| b.keypoint.response.cmp(&a.keypoint.response));
    Ok(len)
}

/// The grid of one level ([`OrbConfig::grid_cell`]).
struct Grid {
    /// The level's size.
    size: (usize, usize),
    /// Cell side, level pixels.
    cell: u16,
    /// Corners a cell keeps.
    keep: u8,
    /// The level's index.
    level: u8,
}

impl Grid {
    /// Chooses up to `quota` corners: `detect` reports every corner of the level through the
    /// callback it is given; each cell keeps its `keep` strongest in a min-heap of `keep`
    /// slots of `out` past `start`; the kept corners are ranked within their cell and the
    /// level takes rank 0 of every cell, then rank 1, ..., by response within a rank. The
    /// chosen corners are left at `out[start..start + kept]`; returns `kept`.
    ///
    /// `counts` holds one byte a cell; the side is doubled until the cells fit in it and in
    /// the free part of `out` (`out.len() - start` slots).
    fn select(
        &self,
        out: &mut [Feature],
        start: usize,
        quota: usize,
        counts: &mut [u8],
        detect: impl FnOnce(&mut dyn FnMut(Feature)) -> Result<()>,
    ) -> Result<usize> {
        let spare = out.len().saturating_sub(start);
        let keep = usize::from(self.keep);
        let (w, h) = self.size;
        let longest = w.max(h);
        let mut cell = usize::from(self.cell).max(1);
        let mut cells = grid_cells(w, h, cell);
        while (cells.saturating_mul(keep) > spare || cells > counts.len()) && cell < longest {
            cell = cell.saturating_mul(2);
            cells = grid_cells(w, h, cell);
        }
        // A single cell may still not fit (no free capacity left): keep fewer a cell.
        let keep = keep.min(spare / cells.max(1));
        if keep == 0 || quota == 0 || cells > counts.len() {
            return Ok(0);
        }
        let gx = w.div_ceil(cell.max(1));
        let counts = counts.get_mut(..cells).unwrap_or(&mut []);
        counts.fill(0);
        let slots = out.get_mut(start..).unwrap_or(&mut []);
        detect(&mut |f: Feature| {
            let (x, y) = (f.keypoint.x as usize, f.keypoint.y as usize);
            // Checked: `cell >= 1` and `c < cells`, `c keep <= out.len()`, which the optimiser
            // cannot see.
            let c = match (y.checked_div(cell), x.checked_div(cell)) {
                (Some(row), Some(col)) => row.saturating_mul(gx).saturating_add(col),
                _ => return,
            };
            let first = c.saturating_mul(keep);
            let (Some(count), Some(heap)) = (
                counts.get_mut(c),
                slots.get_mut(first..first.saturating_add(keep)),
            ) else {
                return;
            };
            let mut len = usize::from(*count);
            offer_best(heap, &mut len, f, |f| f.keypoint.response);
            // `len <= keep <= 255`.
            *count = len as u8;
        })?;
        // Each cell strongest first, packed to the front with its rank in `level` (the write
        // index never passes the read index: a cell gives at most its own slots).
        let mut n = 0usize;
        for (c, &count) in counts.iter().enumerate() {
            let count = usize::from(count);
            let first = c.saturating_mul(keep);
            if let Some(heap) = slots.get_mut(first..first.saturating_add(count)) {
                crate::corners::heapsort_by(heap, |a, b| {
                    b.keypoint.response.cmp(&a.keypoint.response)
                });
            }
            for r in 0..count {
                let Some(mut f) = slots.get(first.saturating_add(r)).copied() else {
                    break;
                };
                f.keypoint.level = r as u8;
                if let Some(slot) = slots.get_mut(n) {
                    *slot = f;
                }
                n += 1;
            }
        }
        let ranked = slots.get_mut(..n).unwrap_or(&mut []);
        crate::corners::heapsort_by(ranked, |a, b| {
            let (ka, kb) = (&a.keypoint, &b.keypoint);
            (ka.level, kb.response).cmp(&(kb.level, ka.response))
        });
        let kept = n.min(quota);
        for f in ranked.iter_mut().take(kept) {
            f.keypoint.level = self.level;
        }
        Ok(kept)
    }
}

/// Largest distance (per axis) from the detected pixel at which [`subpixel_offset`] keeps its estimate.
pub const SUBPIXEL_MAX_SHIFT: f32 = 4.0;

/// Half-width of the window of [`subpixel_offset`] (a 9x9 window).
pub const SUBPIXEL_RADIUS: usize = 4;

/// Weights of the window of [`subpixel_offset`] by offset `|d|` along an axis, `16 exp(-d² /
/// (2 · 2.5²))` rounded: a pixel at `(dx, dy)` weighs `W[|dx|] W[|dy|]`.
const SUBPIXEL_WEIGHTS: [i64; SUBPIXEL_RADIUS + 1] = [16, 15, 12, 8, 5];

/// Sub-pixel offset `(dx, dy)` of the corner found at pixel `(x, y)` of `img`: the point `q`
/// nearest, in the least-squares sense, to the tangent lines of the edges around it
/// (Förstner 1987; OpenCV's `cornerSubPix`),
///
/// `q = argmin Σ w(p) (∇I(p) · (q - p))² = (Σ w ∇I ∇Iᵀ)⁻¹ Σ w ∇I ∇Iᵀ p`,
///
/// over the 9x9 window ([`SUBPIXEL_RADIUS`]) around the current centre, `∇I` the 3x3 Sobel
/// derivatives, `w` Gaussian weights of σ = 2.5 px. An ideal corner (two straight edges
/// meeting) gives its vertex, wherever it lies in the window (to about 0.1 px on a pixel
/// grid: the Sobel taps straddling the vertex pull it inside the corner). The window is moved to
/// the rounded estimate and the fit repeated, up to three fits, until the estimate lies within
/// half a pixel of the centre.
///
/// `(0, 0)` when the window's structure tensor is close to singular (an edge or flat patch:
/// `det < (trace / 10)²`, the smaller eigenvalue under about a hundredth of the larger),
/// when the estimate ends more than [`SUBPIXEL_RADIUS`] pixels from `(x, y)` along an axis,
/// or when a window does not fit in the image. Sums in `i64` (exact), the 2x2 solve in `f32`.
/// Work: at most three 9x9 windows of Sobel derivatives.
#[doc(alias = "cornerSubPix")]
pub fn subpixel_offset(img: &ImageView<'_, u8>, x: usize, y: usize) -> (f32, f32) {
    let (mut cx, mut cy) = (x, y);
    for _ in 0..3 {
        let Some((dx, dy)) = edge_fit(img, cx, cy) else {
            return (0.0, 0.0);
        };
        // The estimate relative to (x, y), in pixels.
        let (ex, ey) = (cx as f32 - x as f32 + dx, cy as f32 - y as f32 + dy);
        let r = SUBPIXEL_MAX_SHIFT;
        if ex.abs() > r || ey.abs() > r {
            return (0.0, 0.0);
        }
        if dx.abs() <= 0.5 && dy.abs() <= 0.5 {
            return (ex, ey);
        }
        // Re-centre on the nearest pixel (`|e| <= r`: inside the image if (x, y) is at least
        // `2 r + 1` inside, else the next fit reports the window outside).
        let (Some(nx), Some(ny)) = (
            x.checked_add_signed(libm::roundf(ex) as isize),
            y.checked_add_signed(libm::roundf(ey) as isize),
        ) else {
            return (0.0, 0.0);
        };
        (cx, cy) = (nx, ny);
    }
    // Three fits without settling: the corner is not well defined.
    (0.0, 0.0)
}

/// One fit of [`subpixel_offset`] on the window centred at `(x, y)`: the estimate relative to
/// the centre, or `None` (window outside the image, or tensor close to singular).
fn edge_fit(img: &ImageView<'_, u8>, x: usize, y: usize) -> Option<(f32, f32)> {
    const R: usize = SUBPIXEL_RADIUS;
    const N: usize = 2 * R + 3;
    if x < R + 1 || y < R + 1 || x + R + 1 >= img.width() || y + R + 1 >= img.height() {
        return None;
    }
    // Rows of the window and its Sobel taps, as in `harris_response`.
    let mut rows = [[0i32; N]; N];
    for (j, dst) in rows.iter_mut().enumerate() {
        let row: &[u8; N] = img
            .row(y - R - 1 + j)?
            .get(x - R - 1..x + R + 2)?
            .try_into()
            .ok()?;
        *dst = row.map(i32::from);
    }
    let at = |i: usize, j: usize| rows.get(j).and_then(|r| r.get(i)).copied().unwrap_or(0);
    let (mut a, mut b, mut c, mut u, mut v) = (0i64, 0i64, 0i64, 0i64, 0i64);
    for (j, wy) in (0..2 * R + 1).zip(SUBPIXEL_WEIGHTS.iter().rev().chain(&SUBPIXEL_WEIGHTS[1..])) {
        for (i, wx) in
            (0..2 * R + 1).zip(SUBPIXEL_WEIGHTS.iter().rev().chain(&SUBPIXEL_WEIGHTS[1..]))
        {
            // Pixel (i + 1, j + 1) of the rows: offset (i - R, j - R) from the centre.
            let (pi, pj) = (i + 1, j + 1);
            let ix = (at(pi + 1, pj - 1) - at(pi - 1, pj - 1))
                + 2 * (at(pi + 1, pj) - at(pi - 1, pj))
                + (at(pi + 1, pj + 1) - at(pi - 1, pj + 1));
            let iy = (at(pi - 1, pj + 1) - at(pi - 1, pj - 1))
                + 2 * (at(pi, pj + 1) - at(pi, pj - 1))
                + (at(pi + 1, pj + 1) - at(pi + 1, pj - 1));
            let w = wx * wy;
            let (ix, iy) = (i64::from(ix), i64::from(iy));
            let (xx, yy, xy) = (w * ix * ix, w * iy * iy, w * ix * iy);
            let (dx, dy) = (i as i64 - R as i64, j as i64 - R as i64);
            a += xx;
            b += yy;
            c += xy;
            u += xx * dx + xy * dy;
            v += xy * dx + yy * dy;
        }
    }
    let (a, b, c, u, v) = (a as f32, b as f32, c as f32, u as f32, v as f32);
    let det = a * b - c * c;
    let trace = a + b;
    if !(det > 0.0 && 100.0 * det >= trace * trace) {
        return None;
    }
    Some(((b * u - c * v) / det, (a * v - c * u) / det))
}

/// `atan2(m₀₁, m₁₀)` over the disc of radius [`PATCH_RADIUS`] around `(x, y)`; pixels outside
/// the image count as 0 (they never are for keypoints at least [`MIN_BORDER`] inside).
pub fn orientation(img: &ImageView<'_, u8>, x: usize, y: usize) -> f32 {
    let (mut m01, mut m10) = (0i32, 0i32);
    for (dv, &umax) in (-(PATCH_RADIUS as i32)..=PATCH_RADIUS as i32)
        .zip(UMAX.iter().rev().chain(UMAX.iter().skip(1)))
    {
        let Some(row) = img.row(y.wrapping_add_signed(dv as isize)) else {
            continue;
        };
        let (mut sum, mut moment) = (0i32, 0i32);
        let first = x.wrapping_add_signed(-umax as isize);
        match row.get(first..=x.wrapping_add_signed(umax as isize)) {
            // The whole span inside the row (always, for keypoints at least `MIN_BORDER`
            // inside): one straight pass.
            Some(span) => {
                for (du, &p) in (-umax..=umax).zip(span) {
                    sum += i32::from(p);
                    moment += du * i32::from(p);
                }
            }
            None => {
                for du in -umax..=umax {
                    let at = x.wrapping_add_signed(du as isize);
                    let p = i32::from(row.get(at).copied().unwrap_or(0));
                    sum += p;
                    moment += du * p;
                }
            }
        }
        m10 += moment;
        m01 += dv * sum;
    }
    libm::atan2f(m01 as f32, m10 as f32)
}

/// The steered BRIEF descriptor at `(x, y)` of the smoothed level for orientation `angle`.
///
/// Each pattern point `p` is rotated by the angle in Q14 and rounded,
/// `r = ((p_x c - p_y s + 2¹³) >> 14, (p_x s + p_y c + 2¹³) >> 14)`, so `|r_x|, |r_y| <=
/// PATTERN_RADIUS + 1`; when that square lies inside the image (every keypoint at least
/// [`MIN_BORDER`] inside), a sample is one load at the offset `r_y · stride + r_x` from the
/// keypoint, else it goes through [`ImageView::get`] (0 outside).
pub fn steered_brief(smoothed: &ImageView<'_, u8>, x: usize, y: usize, angle: f32) -> Descriptor {
    let (s, c) = libm::sincosf(angle);
    let (sq, cq) = (
        libm::roundf(s * 16384.0) as i32,
        libm::roundf(c * 16384.0) as i32,
    );
    let rotate = |px: i8, py: i8| -> (isize, isize) {
        let (px, py) = (i32::from(px), i32::from(py));
        let rx = (px * cq - py * sq + 8192) >> 14;
        let ry = (px * sq + py * cq + 8192) >> 14;
        (rx as isize, ry as isize)
    };
    let r = PATTERN_RADIUS as usize + 1;
    let inside = x >= r && y >= r && x + r < smoothed.width() && y + r < smoothed.height();
    let stride = smoothed.stride() as isize;
    let (data, centre) = (smoothed.data(), y * smoothed.stride() + x);
    let sample = |px: i8, py: i8| -> u8 {
        let (rx, ry) = rotate(px, py);
        if inside {
            data.get(centre.wrapping_add_signed(ry * stride + rx))
                .copied()
                .unwrap_or(0)
        } else {
            smoothed
                .get(x.wrapping_add_signed(rx), y.wrapping_add_signed(ry))
                .unwrap_or(0)
        }
    };
    let mut bits = [0u32; 8];
    for (word, pairs) in bits.iter_mut().zip(PATTERN.chunks_exact(32)) {
        for (k, &[x1, y1, x2, y2]) in pairs.iter().enumerate() {
            *word |= u32::from(sample(x1, y1) < sample(x2, y2)) << k;
        }
    }
    Descriptor(bits)
}

/// Separable smoothing with the taps `BLUR` / 128 in x and y, borders replicated. `dst`
/// must have `src`'s size.
///
/// The taps are symmetric, so each pass adds the pairs of samples that share a tap first
/// (`9 (s₀ + s₆) + 17 (s₁ + s₅) + 24 (s₂ + s₄) + 28 s₃`): four multiplies an output instead
/// of seven, with the same integer result (no sum overflows its lane: a vertical sum is at
/// most `128 · 255`, a pair of them fits `u16`, a horizontal sum `128² · 255` fits `u32`).
pub fn smooth(src: &ImageView<'_, u8>, dst: &mut ImageMut<'_, u8>) -> Result<()> {
    let (w, h) = (src.width(), src.height());
    if (dst.width(), dst.height()) != (w, h) {
        return Err(Error::InvalidImage);
    }
    let [g0, g1, g2, g3] = [BLUR[0], BLUR[1], BLUR[2], BLUR[3]].map(|g| g as u16);
    let mut vs = [0u16; TILE + 6];
    for y in 0..h {
        let [r0, r1, r2, r3, r4, r5, r6]: [&[u8]; 7] =
            core::array::from_fn(|j| src.row_clamped(y as isize + j as isize - 3));
        let Some(out) = dst.row_mut(y) else { break };
        for (tile, out_tile) in out.chunks_mut(TILE).enumerate() {
            let first = (tile * TILE) as isize - 3;
            let n = out_tile.len() + 6;
            // Vertical taps: columns inside the image as whole slices (vectorised), the few
            // clamped ones at the two image edges pixel by pixel.
            let wi = w as isize;
            let k0 = (-first).max(0).min(n as isize) as usize;
            let k1 = (wi - first).min(n as isize).max(k0 as isize) as usize;
            let c0 = (first + k0 as isize).max(0) as usize;
            if let Some(mid) = vs.get_mut(k0..k1) {
                fn span(r: &[u8], at: usize, len: usize) -> &[u8] {
                    r.get(at..at + len).unwrap_or(&[])
                }
                let len = mid.len();
                let taps = span(r0, c0, len)
                    .iter()
                    .zip(span(r1, c0, len))
                    .zip(span(r2, c0, len))
                    .zip(span(r3, c0, len))
                    .zip(span(r4, c0, len))
                    .zip(span(r5, c0, len))
                    .zip(span(r6, c0, len));
                for (v, ((((((&a, &b), &c), &d), &e), &f), &g)) in mid.iter_mut().zip(taps) {
                    let pair = |x: u8, y: u8| u16::from(x) + u16::from(y);
                    *v = g0 * pair(a, g) + g1 * pair(b, f) + g2 * pair(c, e) + g3 * u16::from(d);
                }
            }
            for k in (0..k0).chain(k1..n) {
                // `max` then `min`: `clamp` asserts `0 <= w - 1`, which the optimiser cannot
                // see (a view is never empty).
                let col = (first + k as isize).max(0).min(wi - 1) as usize;
                let s: u32 = [r0, r1, r2, r3, r4, r5, r6]
                    .iter()
                    .zip(BLUR)
                    .map(|(r, g)| g * u32::from(r.get(col).copied().unwrap_or(0)))
                    .sum();
                if let Some(v) = vs.get_mut(k) {
                    *v = s as u16;
                }
            }
            // Horizontal taps: seven shifted views of the tile's vertical sums.
            let m = out_tile.len();
            let view = |j: usize| vs.get(j..j + m).unwrap_or(&[]);
            let taps = view(0)
                .iter()
                .zip(view(1))
                .zip(view(2))
                .zip(view(3))
                .zip(view(4))
                .zip(view(5))
                .zip(view(6));
            for (o, ((((((&a, &b), &c), &d), &e), &f), &g)) in out_tile.iter_mut().zip(taps) {
                let a = u32::from(g0) * u32::from(a + g)
                    + u32::from(g1) * u32::from(b + f)
                    + u32::from(g2) * u32::from(c + e)
                    + u32::from(g3) * u32::from(d);
                // a <= 128² · 255: the rounded quotient fits u8.
                *o = ((a + 8192) >> 14) as u8;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::features::hamming;

    #[test]
    fn smooth_matches_the_clamped_7x7_definition() {
        for (w, h) in [
            (1usize, 1usize),
            (5, 3),
            (7, 9),
            (64, 4),
            (70, 11),
            (131, 8),
        ] {
            let mut st = (w * 31 + h) as u32;
            let data: std::vec::Vec<u8> = (0..w * h)
                .map(|_| {
                    st = st.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (st >> 24) as u8
                })
                .collect();
            let img = ImageView::packed(&data, w, h).unwrap();
            let mut out = std::vec![0u8; w * h];
            smooth(&img, &mut ImageMut::packed(&mut out, w, h).unwrap()).unwrap();
            let at = |x: isize, y: isize| {
                u32::from(
                    data[y.clamp(0, h as isize - 1) as usize * w
                        + x.clamp(0, w as isize - 1) as usize],
                )
            };
            for y in 0..h as isize {
                for x in 0..w as isize {
                    let mut s = 0u32;
                    for (j, gy) in BLUR.iter().enumerate() {
                        for (i, gx) in BLUR.iter().enumerate() {
                            s += gy * gx * at(x + i as isize - 3, y + j as isize - 3);
                        }
                    }
                    let want = ((s + 8192) >> 14) as u8;
                    assert_eq!(out[y as usize * w + x as usize], want, "{w}x{h} at {x},{y}");
                }
            }
        }
    }

    #[test]
    fn pattern_is_inside_the_disc_and_varied() {
        let r2 = PATTERN_RADIUS * PATTERN_RADIUS;
        let mut sum = [0i64; 2];
        let mut sq = 0i64;
        for p in PATTERN {
            let [x1, y1, x2, y2] = p.map(i32::from);
            assert!(x1 * x1 + y1 * y1 <= r2 && x2 * x2 + y2 * y2 <= r2);
            assert!((x1, y1) != (x2, y2));
            sum[0] += i64::from(x1 + x2);
            sum[1] += i64::from(y1 + y2);
            sq += i64::from(x1 * x1 + y1 * y1 + x2 * x2 + y2 * y2);
        }
        // Centred, with a spread close to σ = 6.2 (truncated to the disc).
        assert!(sum[0].abs() < 400 && sum[1].abs() < 400, "{sum:?}"); // ~3σ of a sum of 512
        let sigma = (sq as f64 / (2.0 * 512.0)).sqrt();
        assert!((4.5..6.5).contains(&sigma), "{sigma}");
        let distinct: std::collections::BTreeSet<[i8; 4]> = PATTERN.iter().copied().collect();
        assert!(distinct.len() > 250);
    }

    #[test]
    fn smoothing_keeps_constants_and_matches_the_taps() {
        let data = [77u8; 100 * 9];
        let mut out = [0u8; 100 * 9];
        let img = ImageView::packed(&data, 100, 9).unwrap();
        smooth(&img, &mut ImageMut::packed(&mut out, 100, 9).unwrap()).unwrap();
        assert!(out.iter().all(|&v| v == 77));
        // An impulse gives the outer product of the taps.
        let mut imp = [0u8; 150 * 15];
        imp[7 * 150 + 70] = 255;
        let img = ImageView::packed(&imp, 150, 15).unwrap();
        let mut out = [0u8; 150 * 15];
        smooth(&img, &mut ImageMut::packed(&mut out, 150, 15).unwrap()).unwrap();
        for dy in 0..7 {
            for dx in 0..7 {
                let want = (255 * BLUR[dy] * BLUR[dx] + 8192) >> 14;
                assert_eq!(u32::from(out[(4 + dy) * 150 + 67 + dx]), want);
            }
        }
    }

    fn textured(w: usize, h: usize) -> std::vec::Vec<u8> {
        let mut s = 99u32;
        let mut blobs = std::vec::Vec::new();
        for _ in 0..60 {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let cx = (s >> 8) as usize % w;
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let cy = (s >> 8) as usize % h;
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            blobs.push((cx, cy, 4 + (s >> 8) as usize % 12, (s >> 24) as u8));
        }
        let mut img = std::vec![90u8; w * h];
        for (cx, cy, r, v) in blobs {
            for y in cy.saturating_sub(r)..(cy + r).min(h) {
                for x in cx.saturating_sub(r)..(cx + r).min(w) {
                    img[y * w + x] = v;
                }
            }
        }
        img
    }

    #[test]
    fn detects_sorted_features_inside_the_border() {
        let (w, h) = (200, 160);
        let data = textured(w, h);
        let img = ImageView::packed(&data, w, h).unwrap();
        let cfg = OrbConfig {
            max_features: 100,
            ..Default::default()
        };
        let mut scratch = std::vec![0u8; scratch_len(w, h, cfg.scale_q8)];
        let mut out: Vec<Feature, 128> = Vec::new();
        let params = cfg.check().unwrap();
        orb_detect(&img, &params, &mut scratch, &mut out).unwrap();
        assert!(out.len() > 30 && out.len() <= 100, "{}", out.len());
        assert!(
            out.windows(2)
                .all(|p| p[0].keypoint.response >= p[1].keypoint.response)
        );
        for f in &out {
            let k = f.keypoint;
            let b = f32::from(MIN_BORDER) * k.scale - k.scale;
            assert!(
                k.x >= b && k.y >= b && k.x < w as f32 - b && k.y < h as f32 - b,
                "{k:?}"
            );
            assert!(k.angle.abs() <= core::f32::consts::PI);
        }
        // The capacity caps the count.
        let mut small: Vec<Feature, 10> = Vec::new();
        orb_detect(&img, &params, &mut scratch, &mut small).unwrap();
        assert_eq!(small.len(), 10);
        // Errors.
        for (bad, field) in [
            (OrbConfig { levels: 0, ..cfg }, "orb.levels"),
            (OrbConfig { levels: 13, ..cfg }, "orb.levels"),
            (
                OrbConfig {
                    fast_threshold: 0,
                    ..cfg
                },
                "orb.fast_threshold",
            ),
            (
                OrbConfig {
                    scale_q8: 271,
                    ..cfg
                },
                "orb.scale_q8",
            ),
            (
                OrbConfig {
                    scale_q8: 513,
                    ..cfg
                },
                "orb.scale_q8",
            ),
        ] {
            assert_eq!(bad.check(), Err(Error::InvalidParameter(field)));
        }
        assert_eq!(
            orb_detect(&img, &params, &mut scratch[..100], &mut out),
            Err(Error::BufferTooSmall("scratch"))
        );
    }

    #[test]
    fn grid_bounds_each_cell_and_the_slice_entry_point_agrees() {
        let (w, h) = (200, 160);
        let data = textured(w, h);
        let img = ImageView::packed(&data, w, h).unwrap();
        let mut scratch = std::vec![0u8; scratch_len(w, h, 307)];
        // Without options, the slice entry point gives what `orb_detect` gives.
        let params = OrbConfig::default().check().unwrap();
        let mut v: Vec<Feature, 128> = Vec::new();
        orb_detect(&img, &params, &mut scratch, &mut v).unwrap();
        let mut slice = std::vec![Feature::default(); 128];
        let n = orb_detect_into(&img, &params, &mut scratch, &mut slice).unwrap();
        assert_eq!(&slice[..n], &v[..]);
        // One feature a 16-px cell on a single level.
        let cfg = OrbConfig {
            levels: 1,
            max_features: 60,
            grid_cell: 16,
            cell_keep: 1,
            ..OrbConfig::default()
        };
        let params = cfg.check().unwrap();
        let mut out = std::vec![Feature::default(); grid_capacity(w, h, &cfg)];
        assert_eq!(out.len(), 60 + grid_cells(w, h, 16));
        let n = orb_detect_into(&img, &params, &mut scratch, &mut out).unwrap();
        assert!((5..=60).contains(&n), "{n}");
        let mut cells = std::collections::BTreeSet::new();
        for f in &out[..n] {
            let k = f.keypoint;
            assert!(
                cells.insert((k.x as usize / 16, k.y as usize / 16)),
                "{k:?}"
            );
            assert_eq!(k.level, 0);
        }
        assert!(
            out[..n]
                .windows(2)
                .all(|p| p[0].keypoint.response >= p[1].keypoint.response)
        );
        // A short output coarsens the cells instead of failing: 30 slots for 130 cells.
        let mut short = std::vec![Feature::default(); 30];
        let m = orb_detect_into(&img, &params, &mut scratch, &mut short).unwrap();
        assert!(m > 0 && m <= 30, "{m}");
        // Errors.
        for (bad, field) in [
            (
                OrbConfig {
                    grid_cell: 4,
                    ..cfg
                },
                "orb.grid_cell",
            ),
            (
                OrbConfig {
                    cell_keep: 0,
                    ..cfg
                },
                "orb.cell_keep",
            ),
        ] {
            assert_eq!(bad.check(), Err(Error::InvalidParameter(field)));
        }
        assert_eq!(grid_cells(10, 10, 0), 0);
        assert_eq!(grid_capacity(w, h, &OrbConfig::default()), 500);
    }

    /// An ideal corner: the quadrant `x >= x0, y >= y0` at 200 on 40, each pixel the area
    /// average of its square (so the vertex is exactly at `(x0, y0)` in pixel-centre units).
    fn quadrant(n: usize, x0: f32, y0: f32) -> std::vec::Vec<u8> {
        let cover = |i: usize, c: f32| (i as f32 + 0.5 - c).clamp(0.0, 1.0);
        (0..n * n)
            .map(|k| {
                let a = cover(k % n, x0) * cover(k / n, y0);
                libm::roundf(40.0 + 160.0 * a) as u8
            })
            .collect()
    }

    #[test]
    fn subpixel_offset_finds_the_vertex_of_an_ideal_corner() {
        let n = 40;
        for (x0, y0) in [(20.0f32, 20.0f32), (20.3, 19.6), (18.8, 21.45)] {
            let data = quadrant(n, x0, y0);
            let img = ImageView::packed(&data, n, n).unwrap();
            // From the pixels around the vertex, up to two away (FAST's pixel is seldom the
            // vertex's): the same estimate, within 0.15 px (0.11 measured: the Sobel taps
            // straddling the vertex pull it inside the corner).
            for (x, y) in [(20usize, 20usize), (19, 21), (21, 18), (22, 22)] {
                let (dx, dy) = subpixel_offset(&img, x, y);
                let (ex, ey) = (x as f32 + dx - x0, y as f32 + dy - y0);
                assert!(
                    ex.abs() < 0.15 && ey.abs() < 0.15,
                    "{x0},{y0} from {x},{y}: {ex} {ey}"
                );
            }
        }
        // A straight edge (no corner) and a flat patch: no offset.
        let edge: std::vec::Vec<u8> = (0..n * n)
            .map(|k| if k % n < 20 { 40 } else { 200 })
            .collect();
        let img = ImageView::packed(&edge, n, n).unwrap();
        assert_eq!(subpixel_offset(&img, 20, 20), (0.0, 0.0));
        let flat = std::vec![90u8; n * n];
        let img = ImageView::packed(&flat, n, n).unwrap();
        assert_eq!(subpixel_offset(&img, 20, 20), (0.0, 0.0));
        // Windows outside the image.
        let data = quadrant(n, 3.0, 3.0);
        let img = ImageView::packed(&data, n, n).unwrap();
        assert_eq!(subpixel_offset(&img, 3, 3), (0.0, 0.0));
        assert_eq!(subpixel_offset(&img, 0, 39), (0.0, 0.0));
    }

    #[test]
    fn descriptor_is_rotation_invariant_for_a_rotated_patch() {
        // Rotating the image by 90° (exact, no resampling) should rotate the angle by 90° and
        // keep the descriptor close.
        let n = 64;
        let data = textured(n, n);
        let mut rot = std::vec![0u8; n * n];
        for y in 0..n {
            for x in 0..n {
                // (x, y) -> (n - 1 - y, x): a 90° clockwise turn on screen (y down).
                rot[x * n + (n - 1 - y)] = data[y * n + x];
            }
        }
        let a = ImageView::packed(&data, n, n).unwrap();
        let b = ImageView::packed(&rot, n, n).unwrap();
        let (mut sa, mut sb) = ([0u8; 64 * 64], [0u8; 64 * 64]);
        smooth(&a, &mut ImageMut::packed(&mut sa, n, n).unwrap()).unwrap();
        smooth(&b, &mut ImageMut::packed(&mut sb, n, n).unwrap()).unwrap();
        let (x, y) = (30, 33);
        let (xr, yr) = (n - 1 - y, x);
        let ta = orientation(&a, x, y);
        let tb = orientation(&b, xr, yr);
        let diff = libm::remainderf(
            tb - ta - core::f32::consts::FRAC_PI_2,
            2.0 * core::f32::consts::PI,
        );
        assert!(diff.abs() < 1e-4, "{ta} {tb}");
        let da = steered_brief(&ImageView::packed(&sa, n, n).unwrap(), x, y, ta);
        let db = steered_brief(&ImageView::packed(&sb, n, n).unwrap(), xr, yr, tb);
        assert!(hamming(&da, &db) < 40, "{}", hamming(&da, &db));
    }
}
