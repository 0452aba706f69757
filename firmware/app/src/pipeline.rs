//! The board's pipeline: frame in, pyramid, [`PlanarTarget::step`], AR overlay, report out.
//!
//! Per frame `k`, in [`FrameLoop::step`]:
//!
//! 1. the [`FrameSource`] writes frame `k` into the free frame buffer of the pipeline's
//!    [`PyramidPair`] ([`PyramidPair::capture`]);
//! 2. [`PyramidPair::advance`] builds its Gaussian pyramid into the free pyramid buffer and
//!    hands it out with frame `k - 1`'s;
//! 3. [`PlanarTarget::step`] runs the core's per-frame policy on them: acquisition (the first
//!    frame, after a loss), KLT in Q16.16 fixed point from frame `k - 1`'s pyramid, the RANSAC
//!    homography target plane → image, the IPPE + LM pose, re-detection and relocation;
//! 4. frame `k - 1` is no longer needed as the KLT template: the overlay of frame `k - 1` (its
//!    outline and an AR cube, [`camgeom::draw`]) is drawn into its own buffer
//!    ([`PyramidPair::previous_mut`]) and handed to the caller.
//!
//! No frame is ever copied. The overlay lags one frame because a frame is the next flow's
//! template: drawing into it earlier would put the drawing into the tracking.
//! [`FrameLoop::finish`] draws the last frame's overlay. A frame that fails (a camera error,
//! a core error) leaves the pipeline as it was: the next frame is tracked from the last good
//! one.
//!
//! Every buffer is a fixed-size array whose length comes from a `const fn` of the geometry
//! (width, height, pyramid levels, KLT window, candidates, tracks): a board places one
//! [`Pipeline`] in a `static` (all zeros, so in `.bss`; the main job's are named in
//! [`crate::sizes`]), and the linker checks its RAM against the memory map. Code that runs a
//! pipeline takes it as a [`FrameLoop`], without the sizes.

use camgeom::Error;
use camgeom::draw::{WireframeParams, cube, draw_line, draw_wireframe};
use camgeom::image::{ImageMut, ImageView};
use camgeom::klt::Fixed;
use camgeom::nalgebra::Point2;
use camgeom::pose::PoseEstimate;
use camgeom::pyramid::{self, PyramidPair};
use camgeom::target::{Acquire, PlanarTarget, TargetFrame, TargetParams, TargetState};

pub use crate::costs::{Clock, NoClock};
use crate::costs::{Cost, Probe, StageCosts, span};
use crate::slot::Slot;
use crate::source::FrameSource;

pub use camgeom::target::{corner_scratch_len, flow_scratch_len, kept_flow_scratch_len};

/// Bytes of one `width x height` grayscale frame.
pub const fn frame_len(width: usize, height: usize) -> usize {
    width * height
}

/// Bytes of one pyramid buffer (levels `1..levels`; level 0 is the frame itself).
pub const fn pyramid_len(width: usize, height: usize, levels: usize) -> usize {
    pyramid::buffer_len(width, height, levels)
}

/// Where the AR cube stands on the target plane: one corner at `(x, y, 0)`, side `size`
/// (target units), its top towards the camera (see [`camgeom::draw::cube`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubePlacement {
    /// Target-plane `X` of the cube's first corner.
    pub x: f32,
    /// Target-plane `Y` of the cube's first corner.
    pub y: f32,
    /// Side.
    pub size: f32,
}

/// What the application is told once: geometry, the checked target parameters (camera, size,
/// tracking), drawing. Kept apart from the state ([`Pipeline`]), so one configuration can
/// serve any number of runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AppConfig {
    /// Frame width (pixels); must match the pipeline's buffers.
    pub width: usize,
    /// Frame height (pixels).
    pub height: usize,
    /// Pyramid levels, the frame included (`lk.max_level + 1` is enough).
    pub levels: usize,
    /// The target, its camera and the tracking parameters, checked once.
    pub target: TargetParams,
    /// The AR cube.
    pub cube: CubePlacement,
    /// How the cube is drawn.
    pub wire: WireframeParams<f32>,
    /// Pixel value of the target's outline.
    pub outline_value: u8,
}

/// The outcome of one frame: the core's [`TargetFrame`], and what the board adds to it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// Frame number since the pipeline started (0 is the first frame).
    pub index: u32,
    /// What the core's loop found.
    pub frame: TargetFrame,
    /// [`track_checksum`] of the live features after the frame.
    pub checksum: u32,
    /// What the frame cost.
    pub costs: StageCosts,
}

/// FNV-1a (32 bit) over the features' image positions in Q16.16 (`x`, `y` as little-endian
/// `i32`, [`PlanarTarget::tracks`]), in order: two builds track identically exactly when their
/// checksums agree on every frame (up to hash collisions).
pub fn track_checksum<const N: usize, const S: usize, const C: usize, const K: usize>(
    target: &PlanarTarget<Fixed, N, S, C, K>,
) -> u32 {
    let mut h: u32 = 0x811c_9dc5;
    for q in target.tracks() {
        for b in q.iter().flat_map(|v| v.to_bits().to_le_bytes()) {
            h ^= u32::from(b);
            h = h.wrapping_mul(0x0100_0193);
        }
    }
    h
}

/// What can go wrong in the pipeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AppError<E> {
    /// The frame source failed.
    Source(E),
    /// The configuration does not fit the pipeline's buffers (geometry) or the source's frame
    /// size.
    Geometry,
    /// The core returned an error (a bad configuration or degenerate start corners).
    Core(Error),
}

impl<E> AppError<E> {
    /// The error in snake case (`source`, `geometry`, or the core error's [`Error::name`]).
    pub fn name(&self) -> &'static str {
        match self {
            AppError::Source(_) => "source",
            AppError::Geometry => "geometry",
            AppError::Core(e) => e.name(),
        }
    }
}

impl<E> From<Error> for AppError<E> {
    fn from(e: Error) -> Self {
        AppError::Core(e)
    }
}

/// The latest frame: its number and what its overlay draws. Flags rather than `Option`s: two
/// `Option` tags would take 8 bytes of the pipeline's static where these take 2.
#[derive(Debug, Clone, Copy)]
struct LastFrame {
    index: u32,
    pose: PoseEstimate<f32>,
    outline: [Point2<f32>; 4],
    has_pose: bool,
    has_outline: bool,
}

impl LastFrame {
    fn of(index: u32, frame: &TargetFrame) -> Self {
        let best = frame.pose.map(|p| p.best);
        Self {
            index,
            pose: best.unwrap_or(PoseEstimate {
                pose: camgeom::transform::Pose::identity(),
                rms_px: 0.0,
            }),
            outline: frame.outline.unwrap_or([Point2::origin(); 4]),
            has_pose: best.is_some(),
            has_outline: frame.outline.is_some(),
        }
    }

    fn pose(&self) -> Option<PoseEstimate<f32>> {
        self.has_pose.then_some(self.pose)
    }

    fn outline(&self) -> Option<[Point2<f32>; 4]> {
        self.has_outline.then_some(self.outline)
    }
}

/// A frame loop, whatever its buffer sizes: what code that runs a [`Pipeline`] needs.
pub trait FrameLoop {
    /// Runs one frame (see the module documentation): the first after [`Self::reset`] (or
    /// ever) checks `cfg` against the buffers and the source and acquires the target. Returns
    /// `Ok(None)` once the source has ended. `acquire` is asked when there is no target;
    /// `overlay` receives the previous frame's number and its picture with the outline and cube
    /// drawn.
    ///
    /// Errors: [`AppError::Geometry`] when `cfg` does not fit the buffers or the source;
    /// [`AppError::Source`]; [`AppError::Core`] from the core's loop or the drawing. A frame
    /// that fails is dropped: the next one is tracked from the last good frame.
    fn step<Src: FrameSource, Clk: Clock>(
        &mut self,
        cfg: &AppConfig,
        source: &mut Src,
        acquire: &mut (impl Acquire + ?Sized),
        clock: &mut Clk,
        overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
    ) -> Result<Option<FrameReport>, AppError<Src::Error>>;

    /// Draws the latest frame's overlay and hands it to `overlay` (after the source ended);
    /// nothing when no frame ran. Errors: [`AppError::Core`] from the drawing.
    fn finish<E>(
        &mut self,
        cfg: &AppConfig,
        overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
    ) -> Result<(), AppError<E>>;

    /// Hands `f` the latest frame's pixels as the camera delivered them (between
    /// [`Self::step`]s; the next step draws its overlay into it): `None` before the first
    /// frame.
    fn with_latest<R>(&mut self, f: impl FnOnce(&ImageView<'_, u8>) -> R) -> Option<R>;

    /// Forgets the frames and the target: the next frame starts again.
    fn reset(&mut self);

    /// Lends one of the pipeline's frame buffers, as a `width x height` frame, for another
    /// use while it does not track (the calibrate mode's frames: a board holds no second
    /// frame buffer for it). Forgets the frames and the target first ([`Self::reset`]); the
    /// next [`Self::step`] starts again. `None` when the buffer holds no such frame.
    fn lend_frame(&mut self, width: usize, height: usize) -> Option<ImageMut<'_, u8>>;

    /// The tracker's state after the last frame.
    fn state(&self) -> TargetState;

    /// Bytes of RAM the pipeline takes (buffers, target, bookkeeping).
    fn bytes(&self) -> usize;
}

/// The application's state: the frames and their pyramids ([`PyramidPair`]), the target, and
/// what the latest frame's overlay will draw.
///
/// `F`, `P`, `S`, `C`: lengths from [`frame_len`], [`pyramid_len`], [`flow_scratch_len`],
/// [`corner_scratch_len`]; `K` candidate corners for the detector; `N` tracks. The main job's
/// sizes are named in [`crate::sizes`]; everything that runs a pipeline takes it as a
/// [`FrameLoop`].
pub struct Pipeline<
    const F: usize,
    const P: usize,
    const S: usize,
    const C: usize,
    const K: usize,
    const N: usize,
> {
    frames: PyramidPair<[u8; F], [u8; P]>,
    target: PlanarTarget<Fixed, N, S, C, K>,
    /// The latest frame's number and what to draw on it.
    last: Slot<LastFrame>,
}

impl<const F: usize, const P: usize, const S: usize, const C: usize, const K: usize, const N: usize>
    Default for Pipeline<F, P, S, C, K, N>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const F: usize, const P: usize, const S: usize, const C: usize, const K: usize, const N: usize>
    Pipeline<F, P, S, C, K, N>
{
    /// Bytes of RAM this pipeline takes (buffers, target, bookkeeping).
    pub const BYTES: usize = core::mem::size_of::<Self>();

    /// An empty pipeline: zero buffers, a target not acquired and an empty [`Slot`], so a
    /// `static` of it lives in `.bss` (no flash image, never built on the stack). Were it to
    /// move to `.data`, the main job's flash would triple and its size check
    /// (`cargo xtask size`) would fail.
    pub const fn new() -> Self {
        Self {
            frames: PyramidPair::new([[0; F]; 2], [[0; P]; 2]),
            target: PlanarTarget::new(),
            last: Slot::empty(),
        }
    }

    /// The target's state (for a board's own policy or checks).
    pub fn target(&self) -> &PlanarTarget<Fixed, N, S, C, K> {
        &self.target
    }

    /// Checks `cfg` (and the source's frame size) against the buffers and sets the frame
    /// geometry.
    fn start<E>(&mut self, cfg: &AppConfig, size: (usize, usize)) -> Result<(), AppError<E>> {
        let fits = size == (cfg.width, cfg.height)
            && F == frame_len(cfg.width, cfg.height)
            && P == pyramid_len(cfg.width, cfg.height, cfg.levels);
        if !fits {
            return Err(AppError::Geometry);
        }
        self.frames
            .set_geometry(cfg.width, cfg.height, cfg.levels)
            .map_err(|_| AppError::Geometry)?;
        self.target.reset();
        self.last.take();
        Ok(())
    }
}

impl<const F: usize, const P: usize, const S: usize, const C: usize, const K: usize, const N: usize>
    FrameLoop for Pipeline<F, P, S, C, K, N>
{
    fn step<Src: FrameSource, Clk: Clock>(
        &mut self,
        cfg: &AppConfig,
        source: &mut Src,
        acquire: &mut (impl Acquire + ?Sized),
        clock: &mut Clk,
        overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
    ) -> Result<Option<FrameReport>, AppError<Src::Error>> {
        if self.frames.held() == 0 {
            self.start(cfg, source.size())?;
        }
        // Only the number is held across the frame; the previous frame's overlay is read back
        // after the core's loop, which does not touch it (less stack under the loop).
        let index = self.last.get().map_or(0, |p| p.index.saturating_add(1));
        let mut costs = StageCosts::default();
        let t0 = clock.now();
        {
            let mut img = self.frames.capture()?;
            if !source.next_frame(&mut img).map_err(AppError::Source)? {
                return Ok(None);
            }
        }
        let t1 = clock.now();
        costs[Cost::Capture] = span(t0, t1);
        let result = {
            let pyramids = self.frames.advance()?;
            let t2 = clock.now();
            costs[Cost::Pyramid] = span(t1, t2);
            let mut probe = Probe {
                clock: &mut *clock,
                last: t2,
                costs: &mut costs,
            };
            self.target.step(
                &cfg.target,
                pyramids.previous.as_ref(),
                &pyramids.next,
                acquire,
                &mut probe,
            )
        };
        let out = match result {
            Ok(out) => out,
            Err(e) => {
                self.frames.rewind();
                return Err(e.into());
            }
        };
        // The previous frame has served as the template: draw its overlay into it.
        let t3 = clock.now();
        if let Some(p) = self.last.get().copied()
            && let Some(mut img) = self.frames.previous_mut()?
        {
            draw_overlay(cfg, &mut img, p.pose(), p.outline())?;
            overlay(p.index, &img.as_view());
            costs[Cost::Draw] = span(t3, clock.now());
        }
        costs.total = span(t1, clock.now());
        self.last.set(LastFrame::of(index, &out));
        Ok(Some(FrameReport {
            index,
            frame: out,
            checksum: track_checksum(&self.target),
            costs,
        }))
    }

    fn finish<E>(
        &mut self,
        cfg: &AppConfig,
        overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
    ) -> Result<(), AppError<E>> {
        if let Some(last) = self.last.take()
            && let Some(mut img) = self.frames.latest_mut()?
        {
            draw_overlay(cfg, &mut img, last.pose(), last.outline())?;
            overlay(last.index, &img.as_view());
        }
        Ok(())
    }

    fn with_latest<R>(&mut self, f: impl FnOnce(&ImageView<'_, u8>) -> R) -> Option<R> {
        let img = self.frames.latest_mut().ok().flatten()?;
        Some(f(&img.as_view()))
    }

    fn reset(&mut self) {
        self.frames.clear();
        self.target.reset();
        self.last.take();
    }

    fn lend_frame(&mut self, width: usize, height: usize) -> Option<ImageMut<'_, u8>> {
        self.reset();
        self.frames.set_geometry(width, height, 1).ok()?;
        self.frames.capture().ok()
    }

    fn state(&self) -> TargetState {
        self.target.state()
    }

    fn bytes(&self) -> usize {
        Self::BYTES
    }
}

/// The outline (straight lines between the corners) and, with a pose, the cube.
fn draw_overlay(
    cfg: &AppConfig,
    img: &mut ImageMut<'_, u8>,
    pose: Option<PoseEstimate<f32>>,
    outline: Option<[Point2<f32>; 4]>,
) -> Result<usize, Error> {
    let mut written = 0;
    if let Some(q) = outline {
        for (a, b) in q.iter().zip(q.iter().cycle().skip(1)) {
            written += draw_line(img, a, b, cfg.outline_value)?;
        }
    }
    if let Some(p) = pose {
        let (vertices, edges) = cube(cfg.cube.x, cfg.cube.y, cfg.cube.size);
        written += draw_wireframe(
            img,
            cfg.target.camera(),
            &p.pose,
            &vertices,
            &edges,
            &cfg.wire,
        )?;
    }
    Ok(written)
}
