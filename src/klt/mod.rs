//! Pyramidal Lucas-Kanade tracking (KLT), coarse to fine, allocation-free.
//!
//! For a point `u` of the previous frame `I`, find `v` in the next frame `J` minimising
//! `Σ_w (J(v + w) - I(u + w))²` over a `win x win` window. Each Gauss-Newton step solves
//!
//! `G δ = -b`, `G = Σ [Ix² IxIy; IxIy Iy²]`, `b = Σ (J - I) [Ix Iy]ᵀ`,
//!
//! on pyramid levels from coarsest to finest, the estimate doubling between levels. This is
//! OpenCV's `calcOpticalFlowPyrLK` scheme: Scharr derivatives in `i16` ([`crate::gradient`]),
//! window samples by bilinear interpolation with 14-bit integer weights (`I` kept in 1/32 grey
//! levels), the same stopping rules (`|δ| <= ε`, iteration cap, oscillation halving), the
//! minimum-eigenvalue test `λ_min(G) / (2²⁰ win²) < min_eigenvalue` and the error measure
//! (mean absolute difference). Borders as OpenCV: images reflected (`BORDER_REFLECT_101`) and
//! derivatives zero outside, so a point is only lost when its window leaves the image entirely.
//!
//! The arithmetic is chosen by type ([`FlowArith`]): [`Fixed`] ([`Q16`] coordinates, the
//! crate's one Q16.16 type, saturating, and an integer 2x2 solve; for cores without an FPU) or
//! `f32` (as OpenCV). Both share the point arithmetic of [`Coordinate`] (`+`, `-`, level
//! scaling), so `FlowArith` holds only what differs: the bilinear weights of a position, the
//! 2x2 solve, the stopping tests and the error measure. Sums are exact `i64` in both.
//! [`Tracker`] keeps tracks across frames.
//!
//! Scratch: [`scratch_len`]`(win)` `i16` per call, whatever the number of points.
//!
//! Where RAM allows, [`calc_flow`] given [`Borders::Copy`] first copies the coarse levels of
//! both pyramids with a reflected border ([`bordered_len`] bytes for the level-1 size; which
//! levels, by the windows' work, is [`Borders::Copy`]'s rule), as OpenCV keeps its
//! pyramids: a window that crosses a level's edge then reads the copy instead of copying out
//! its own reflected block at its template and at each mismatch that moves it. The flows are
//! the same to the bit; on the host the copies cost less than the blocks they save once many
//! points sit near the edges of the coarse levels (BENCHMARKS.md, "KLT / Host speed per
//! tracked feature").
//!
//! With the forward-backward check, [`FlowBuffers`] (and so [`Tracker`] and
//! [`crate::target::PlanarTarget`]) can keep the backward pass's templates for the next
//! frame's forward pass, which needs the same ones again (the new frame at the tracked
//! positions): give it [`Templates::Keep`] with [`templates_len`]`(win, max_level, N)`
//! elements. A kept template is used only when the pixels it was made from are equal byte for
//! byte, so the flows are the same to the bit; on the Cortex-M7 main job with the check on,
//! the flow costs 6 % less (BENCHMARKS.md, "Kept templates"), for 1,728 B a point and level
//! (15x15 windows, the boards' kernel).
//!
//! ```
//! use camgeom::image::ImageView;
//! use camgeom::klt::{Borders, Flow, FlowStatus, Gradients, LkConfig, calc_flow, scratch_len};
//! use camgeom::pyramid::{Pyramid, buffer_len};
//!
//! // A smooth texture, and the same texture moved by (+3, +2) pixels.
//! let tex = |x: f32, y: f32| {
//!     128.0 + 50.0 * (0.35 * x + 0.2 * y).sin() + 40.0 * (0.3 * x - 0.25 * y).cos()
//! };
//! let frame = |dx: f32, dy: f32| -> [u8; 64 * 64] {
//!     core::array::from_fn(|i| tex((i % 64) as f32 - dx, (i / 64) as f32 - dy).round() as u8)
//! };
//! let (a, b) = (frame(0.0, 0.0), frame(3.0, 2.0));
//! let params = LkConfig { max_level: 1, ..LkConfig::default() }.check()?;
//! let (mut ba, mut bb) = ([0u8; buffer_len(64, 64, 2)], [0u8; buffer_len(64, 64, 2)]);
//! let pa = Pyramid::build(ImageView::packed(&a, 64, 64)?, &mut ba, 2)?;
//! let pb = Pyramid::build(ImageView::packed(&b, 64, 64)?, &mut bb, 2)?;
//! let pts = [[30.0f32, 30.0], [24.5, 36.0], [40.0, 27.25]];
//! let mut flows = [Flow::default(); 3];
//! let mut scratch = [0i16; scratch_len(21)];
//! let (grads, borders) = (Gradients::PerWindow, Borders::None);
//! calc_flow::<f32>(&pa, &pb, &pts, &mut flows, &params, grads, borders, &mut scratch)?;
//! for (p, f) in pts.iter().zip(&flows) {
//!     assert_eq!(f.status, FlowStatus::Tracked);
//!     // Within the stopping step (epsilon = 0.01 px): the texture moves without change.
//!     assert!((f.x - p[0] - 3.0).abs() < 0.01 && (f.y - p[1] - 2.0).abs() < 0.01);
//! }
//! # Ok::<(), camgeom::Error>(())
//! ```

use crate::{Error, Result};

mod arith;
mod cache;
mod flow;
mod kernel;
mod lk;
mod tracker;

pub use arith::{
    Bilinear, Coordinate, Fixed, FixedGram, FixedParams, FloatGram, FloatParams, FlowArith, Q16,
};
pub use cache::templates_len;
pub use flow::{FlowBuffers, FlowBuffersView, FlowItem, calc_flow, forward_backward};
pub use kernel::{bordered_len, scratch_len};
pub use tracker::{Track, Tracker, TrackerConfig, TrackerParams, TrackerStats};

/// Largest window side accepted.
pub const MAX_WIN: usize = 63;

/// `[Ix, Iy]` elements a [`Gradients::PerLevel`] buffer needs for a `width x height` frame
/// (level 0 is the largest).
pub const fn level_gradient_len(width: usize, height: usize) -> usize {
    width * height
}

/// Parameters of [`calc_flow`] (OpenCV's names in parentheses).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LkConfig {
    /// Window side in pixels, 3 ..= [`MAX_WIN`] (OpenCV `winSize`). Default 21.
    pub win: usize,
    /// Coarsest pyramid level used (0 = no pyramid) (`maxLevel`). Levels whose size is not
    /// larger than the window are skipped, as OpenCV does. Default 3.
    pub max_level: usize,
    /// Iteration cap per level, 1 ..= 100 (`criteria.maxCount`). Default 30.
    pub max_iter: u32,
    /// Stop when `|δ| <= epsilon` pixels, 0 ..= 10 (`criteria.epsilon`; OpenCV clamps it to that
    /// range, camgeom rejects a value outside it). Default 0.01.
    pub epsilon: f32,
    /// Reject windows with `λ_min(G) / (2²⁰ win²)` below this, finite and not negative
    /// (`minEigThreshold`). Default 1e-4.
    pub min_eigenvalue: f32,
    /// Start the coarsest level from the positions already in the output
    /// (`OPTFLOW_USE_INITIAL_FLOW`). Default `false`.
    pub use_initial_flow: bool,
    /// Forward-backward threshold in pixels (finite, not negative) for [`forward_backward`];
    /// `None` disables it.
    pub fb_threshold: Option<f32>,
    /// Compute [`Flow::err`]: one more pass over each window at its final position, and a
    /// point whose final window has left the image becomes [`FlowStatus::OutOfBounds`] (what
    /// OpenCV does when given an `err` array). `false` skips both and leaves `err` 0 (OpenCV
    /// without `err`). Default `true`.
    pub compute_error: bool,
}

impl LkConfig {
    /// Checks every field once: the flow functions take the checked [`LkParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field: `lk.win` outside 3 ..= [`MAX_WIN`],
    /// `lk.max_iter` outside 1 ..= 100, `lk.epsilon` outside 0 ..= 10 (or NaN),
    /// `lk.min_eigenvalue` negative or not finite, `lk.fb_threshold` negative or not finite.
    pub fn check(&self) -> Result<LkParams> {
        if self.win < 3 || self.win > MAX_WIN {
            return Err(Error::InvalidParameter("lk.win"));
        }
        if self.max_iter == 0 || self.max_iter > 100 {
            return Err(Error::InvalidParameter("lk.max_iter"));
        }
        if !(0.0..=10.0).contains(&self.epsilon) {
            return Err(Error::InvalidParameter("lk.epsilon"));
        }
        if !(self.min_eigenvalue.is_finite() && self.min_eigenvalue >= 0.0) {
            return Err(Error::InvalidParameter("lk.min_eigenvalue"));
        }
        if self
            .fb_threshold
            .is_some_and(|t| !(t.is_finite() && t >= 0.0))
        {
            return Err(Error::InvalidParameter("lk.fb_threshold"));
        }
        Ok(LkParams(*self))
    }
}

/// An [`LkConfig`] that passed [`LkConfig::check`]: what [`calc_flow`], [`forward_backward`]
/// and the trackers take, so that no call validates or clamps it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LkParams(LkConfig);

impl LkParams {
    /// The checked configuration.
    pub const fn config(&self) -> &LkConfig {
        &self.0
    }

    /// The same parameters with [`LkConfig::use_initial_flow`] set to `on`.
    pub const fn with_initial_flow(mut self, on: bool) -> Self {
        self.0.use_initial_flow = on;
        self
    }
}

impl Default for LkParams {
    /// The checked [`LkConfig::default`].
    fn default() -> Self {
        Self(LkConfig::default())
    }
}

impl TryFrom<LkConfig> for LkParams {
    type Error = Error;
    fn try_from(c: LkConfig) -> Result<Self> {
        c.check()
    }
}

impl Default for LkConfig {
    fn default() -> Self {
        Self {
            win: 21,
            max_level: 3,
            max_iter: 30,
            epsilon: 0.01,
            min_eigenvalue: 1e-4,
            use_initial_flow: false,
            fb_threshold: None,
            compute_error: true,
        }
    }
}

/// What happened to one point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlowStatus {
    /// Tracked: the position and error are valid.
    #[default]
    Tracked,
    /// The window left the image (or the input point was not finite).
    OutOfBounds,
    /// The window has too little texture: `λ_min(G)` below the threshold, or `G` singular.
    SmallEigenvalue,
    /// Tracking back from the result did not return within the forward-backward threshold.
    Inconsistent,
}

impl FlowStatus {
    /// The status in snake case (`tracked`, `out_of_bounds`, ...).
    pub const fn name(self) -> &'static str {
        match self {
            FlowStatus::Tracked => "tracked",
            FlowStatus::OutOfBounds => "out_of_bounds",
            FlowStatus::SmallEigenvalue => "small_eigenvalue",
            FlowStatus::Inconsistent => "inconsistent",
        }
    }
}

/// The result for one point: its position `(x, y)` in the next frame (full resolution), the
/// status, and the error `Σ |J - I| / win²` (grey levels; 0 unless tracked).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Flow<C> {
    /// Column.
    pub x: C,
    /// Row.
    pub y: C,
    /// Outcome.
    pub status: FlowStatus,
    /// Mean absolute difference of the two windows.
    pub err: C,
}

/// Whether [`calc_flow`] copies the coarse levels of both pyramids with a reflected border
/// first, as OpenCV keeps its pyramids. A window that leaves a level but not the border then
/// reads the copy's rows where it would otherwise copy out its own reflected block, at its
/// template and at every mismatch that moves it; the flows are the same to the bit either way.
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Borders<'a> {
    /// No copies: each window that leaves a level copies out its own block.
    None,
    /// The copies go into this buffer, which must hold [`bordered_len`]`(w, h, win)` bytes for
    /// the level-1 size `w x h` of the pyramids whenever the flow runs on level 1 or above
    /// ([`Error::BufferTooSmall`]`("borders")` otherwise; with only level 0 any length does).
    ///
    /// Which levels are copied is a rule of the flow's own, not of the buffer's length: levels
    /// 1 and up (level 0 is the frame itself, too large to be worth a copy), each where the
    /// windows' work outweighs a pass over the level, `w h <= n (win + 1)²` for `n` points (the
    /// rule of [`Gradients::Auto`]), and only where the target's kernel reads copies (the
    /// vector kernel of targets with 128-bit SIMD; the boards' kernel reads the level alone,
    /// so there the buffer is checked and left unused).
    Copy(&'a mut [u8]),
}

/// Whether [`FlowBuffersView::run`] keeps the templates its forward-backward check
/// interpolates (the new frame at the tracked positions) for the next call's forward pass,
/// which starts from those positions in that frame. A kept template is used only when the key
/// of its window (level, integer corner, bilinear weights) and the `(win + 3)²` pixels it was
/// made from are equal, so the flows are the same to the bit either way.
#[derive(Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Templates<'a> {
    /// Every template computed.
    Compute,
    /// Kept in this buffer, at least [`templates_len`]`(win, max_level, N)` elements for
    /// buffers of capacity `N` ([`Error::BufferTooSmall`]`("templates")` otherwise). Give the
    /// same buffer from call to call: it carries the templates over (whatever else it holds is
    /// never matched, so never used). Nothing is kept without the forward-backward check.
    Keep(&'a mut [i16]),
}

/// Where the window derivatives come from (same numbers either way, see [`crate::gradient`]).
#[derive(Debug)]
pub enum Gradients<'a> {
    /// Computed per window from the previous frame: no buffer; the board default.
    PerWindow,
    /// Computed once per level into this buffer of at least
    /// [`level_gradient_len`]`(w, h)` elements of the level-0 size.
    PerLevel(&'a mut [[i16; 2]]),
    /// Per level where that is the cheaper way and the level fits this buffer, per window
    /// elsewhere. A level's pass costs about its `w h` pixels; the windows cost
    /// `n (win + 1)²` for `n` points. So the coarse levels go per level (with 278 points and
    /// 21x21 windows on a 640x480 frame: levels 1 to 3; with 50 points on 320x240: every
    /// level but 0), and a buffer of [`level_gradient_len`] of the level-1 size (a quarter of
    /// the frame's) or smaller serves them.
    Auto(&'a mut [[i16; 2]]),
}
