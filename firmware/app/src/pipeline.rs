//! The board's pipeline: frame in, pyramid, [`PlanarTarget::step`], AR overlay, report out.
//!
//! Per frame `k`:
//!
//! 1. the [`FrameSource`] writes frame `k` into the free one of two frame buffers;
//! 2. its Gaussian pyramid is built into the free one of two pyramid buffers
//!    ([`camgeom::pyramid`]);
//! 3. [`PlanarTarget::step`] runs the core's per-frame policy on it: acquisition (frame 0, after
//!    a loss), KLT in Q16.16 fixed point from frame `k - 1`'s pyramid, the RANSAC homography
//!    target plane → image, the IPPE + LM pose, re-detection and relocation;
//! 4. frame `k - 1` is no longer needed as the KLT template: the overlay of frame `k - 1` (its
//!    outline and an AR cube, [`camgeom::draw`]) is drawn into its own buffer and handed to the
//!    caller, then the buffers swap roles.
//!
//! No frame is ever copied. The overlay lags one frame because a frame is the next flow's
//! template: drawing into it earlier would put the drawing into the tracking.
//! [`Pipeline::finish`] draws the last frame's overlay.
//!
//! Every buffer is a fixed-size array whose length comes from a `const fn` of the geometry
//! (width, height, pyramid levels, KLT window, candidates, tracks): a board places one
//! [`Pipeline`] in a `static` (all zeros, so in `.bss`), and the linker checks its RAM against
//! the memory map. The [`pipeline_type!`](crate::pipeline_type) macro spells the type from the
//! geometry.

use camgeom::Error;
use camgeom::draw::{WireframeConfig, cube, draw_line, draw_wireframe};
use camgeom::image::{ImageMut, ImageView};
use camgeom::klt::Fixed;
use camgeom::nalgebra::Point2;
use camgeom::pose::{PlanarPose, PoseEstimate};
use camgeom::pyramid::{self, Pyramid};
use camgeom::target::{Acquire, PlanarTarget, Stage, StageProbe, TargetParams, TargetState};

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

/// The concrete [`Pipeline`] type of a geometry: `pipeline_type!(width, height, levels, win,
/// candidates, tracks)`, every argument a constant expression. With a last argument `kept`,
/// the flow scratch also keeps the forward-backward check's templates for the next frame
/// ([`kept_flow_scratch_len`]: the same results, less work with the check on, much more RAM).
#[macro_export]
macro_rules! pipeline_type {
    ($w:expr, $h:expr, $levels:expr, $win:expr, $candidates:expr, $n:expr) => {
        $crate::pipeline_type!(@ $w, $h, $levels, $candidates, $n,
            $crate::pipeline::flow_scratch_len($win))
    };
    ($w:expr, $h:expr, $levels:expr, $win:expr, $candidates:expr, $n:expr, kept) => {
        $crate::pipeline_type!(@ $w, $h, $levels, $candidates, $n,
            $crate::pipeline::kept_flow_scratch_len($win, $levels - 1, $n))
    };
    (@ $w:expr, $h:expr, $levels:expr, $candidates:expr, $n:expr, $flow:expr) => {
        $crate::pipeline::Pipeline<
            { $crate::pipeline::frame_len($w, $h) },
            { $crate::pipeline::pyramid_len($w, $h, $levels) },
            { $flow },
            { $crate::pipeline::corner_scratch_len($w) },
            $candidates,
            $n,
        >
    };
}

/// Where the AR cube stands on the target plane: one corner at `(x, y, 0)`, side `size`
/// (target units), its top towards the camera (see [`camgeom::draw::cube`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubeConfig {
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
    pub cube: CubeConfig,
    /// How the cube is drawn.
    pub wire: WireframeConfig<f32>,
    /// Pixel value of the target's outline.
    pub outline_value: u8,
}

/// The board's clock: a monotonic count in its own unit (cycles on hardware, instructions on
/// QEMU with `-icount`). Differences are what the cost record holds.
pub trait Clock {
    /// The count now.
    fn now(&mut self) -> u64;
}

/// A clock that always reads 0 (every cost 0): for replays where only the results matter.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoClock;

impl Clock for NoClock {
    fn now(&mut self) -> u64 {
        0
    }
}

/// What one frame cost, in the [`Clock`]'s unit (saturating at `u32::MAX`). A stage that did
/// not run costs 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StageCosts {
    /// Reading the frame from the source (not part of `total`: a camera's DMA does it).
    pub capture: u32,
    /// The pyramid of the new frame.
    pub pyramid: u32,
    /// The acquisition step (a detector; nothing when the corners are given).
    pub acquire: u32,
    /// KLT (forward and back when checked).
    pub flow: u32,
    /// RANSAC homography.
    pub homography: u32,
    /// IPPE and its refinement.
    pub pose: u32,
    /// Feature detection (after an acquisition, with too few tracks, relocation after a loss).
    pub redetect: u32,
    /// Drawing the previous frame's overlay.
    pub draw: u32,
    /// Pyramid to draw, everything but the capture.
    pub total: u32,
}

/// The names of [`StageCosts`]' fields, in table order.
pub const STAGES: [&str; 9] = [
    "capture",
    "pyramid",
    "acquire",
    "flow",
    "homography",
    "pose",
    "redetect",
    "draw",
    "total",
];

impl StageCosts {
    /// The costs in the order of [`STAGES`].
    pub const fn to_array(&self) -> [u32; 9] {
        [
            self.capture,
            self.pyramid,
            self.acquire,
            self.flow,
            self.homography,
            self.pose,
            self.redetect,
            self.draw,
            self.total,
        ]
    }

    /// The inverse of [`Self::to_array`].
    pub const fn from_array(a: [u32; 9]) -> Self {
        let [
            capture,
            pyramid,
            acquire,
            flow,
            homography,
            pose,
            redetect,
            draw,
            total,
        ] = a;
        Self {
            capture,
            pyramid,
            acquire,
            flow,
            homography,
            pose,
            redetect,
            draw,
            total,
        }
    }
}

fn span(from: u64, to: u64) -> u32 {
    u32::try_from(to.saturating_sub(from)).unwrap_or(u32::MAX)
}

/// Times the stages of [`PlanarTarget::step`].
struct Probe<'a, C: Clock> {
    clock: &'a mut C,
    last: u64,
    costs: &'a mut StageCosts,
}

impl<C: Clock> StageProbe<Stage> for Probe<'_, C> {
    fn stage_done(&mut self, stage: Stage) {
        let now = self.clock.now();
        let d = span(self.last, now);
        self.last = now;
        let slot = match stage {
            Stage::Acquire => &mut self.costs.acquire,
            Stage::Flow => &mut self.costs.flow,
            Stage::Homography => &mut self.costs.homography,
            Stage::Pose => &mut self.costs.pose,
            Stage::Redetect => &mut self.costs.redetect,
        };
        *slot = slot.saturating_add(d);
    }
}

/// The outcome of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameReport {
    /// Frame number in the sequence (0 is the start frame).
    pub index: u32,
    /// The tracker's state after the frame.
    pub state: TargetState,
    /// The target was acquired on this frame.
    pub acquired: bool,
    /// Tracks that survived the flow.
    pub tracked: usize,
    /// Homography inliers.
    pub inliers: usize,
    /// Features added by acquisition, re-detection or relocation.
    pub added: usize,
    /// Features alive after the frame.
    pub features: usize,
    /// Both planar poses (target → camera), when tracking.
    pub pose: Option<PlanarPose<f32>>,
    /// The target's outline in this frame, when tracking.
    pub outline: Option<[Point2<f32>; 4]>,
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
    /// The source ended before the start frame.
    NoFrame,
    /// The configuration does not fit the pipeline's buffers (geometry) or the source's frame
    /// size.
    Geometry,
    /// [`Pipeline::step`] before [`Pipeline::start`].
    NotStarted,
    /// The core returned an error (a bad configuration or degenerate start corners).
    Core(Error),
}

impl<E> AppError<E> {
    /// The error in snake case (`source`, `no_frame`, `geometry`, `not_started`, or the core
    /// error's [`Error::name`]).
    pub fn name(&self) -> &'static str {
        match self {
            AppError::Source(_) => "source",
            AppError::NoFrame => "no_frame",
            AppError::Geometry => "geometry",
            AppError::NotStarted => "not_started",
            AppError::Core(e) => e.name(),
        }
    }
}

impl<E> From<Error> for AppError<E> {
    fn from(e: Error) -> Self {
        AppError::Core(e)
    }
}

/// The previous frame: its number, best pose and outline (what its overlay draws).
type LastFrame = (u32, Option<PoseEstimate<f32>>, Option<[Point2<f32>; 4]>);

/// The application's state: every buffer, the target, and which buffer holds which frame.
///
/// `F`, `P`, `S`, `C`: lengths from [`frame_len`], [`pyramid_len`], [`flow_scratch_len`],
/// [`corner_scratch_len`]; `K` candidate corners for the detector; `N` tracks. Spell the type
/// with [`pipeline_type!`](crate::pipeline_type).
pub struct Pipeline<
    const F: usize,
    const P: usize,
    const S: usize,
    const C: usize,
    const K: usize,
    const N: usize,
> {
    frames: [[u8; F]; 2],
    pyramids: [[u8; P]; 2],
    target: PlanarTarget<Fixed, N, S, C, K>,
    /// The buffer holding the latest frame.
    current: usize,
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
    pub const RAM: usize = core::mem::size_of::<Self>();

    /// An empty pipeline: zero buffers, a target not acquired and an empty [`Slot`], so a
    /// `static` of it lives in `.bss` (no flash image, never built on the stack). Were it to
    /// move to `.data`, the main job's flash would triple and its size check
    /// (`cargo xtask size`) would fail.
    pub const fn new() -> Self {
        Self {
            frames: [[0; F]; 2],
            pyramids: [[0; P]; 2],
            target: PlanarTarget::new(),
            current: 0,
            last: Slot::empty(),
        }
    }

    /// The target's state (for a board's own policy or checks).
    pub fn target(&self) -> &PlanarTarget<Fixed, N, S, C, K> {
        &self.target
    }

    /// Checks `cfg` (and the source's frame size) against the buffers.
    fn check<E>(cfg: &AppConfig, size: (usize, usize)) -> Result<(), AppError<E>> {
        let fits = size == (cfg.width, cfg.height)
            && F == frame_len(cfg.width, cfg.height)
            && P == pyramid_len(cfg.width, cfg.height, cfg.levels);
        if fits {
            Ok(())
        } else {
            Err(AppError::Geometry)
        }
    }

    /// Reads the start frame, builds its pyramid and runs its [`PlanarTarget::step`]: the
    /// target is acquired through `acquire` (e.g. [`camgeom::target::GivenCorners`]) and its
    /// pose solved. Returns the start frame's report. Errors: as [`AppError`].
    pub fn start<Src: FrameSource, Clk: Clock>(
        &mut self,
        cfg: &AppConfig,
        source: &mut Src,
        acquire: &mut (impl Acquire + ?Sized),
        clock: &mut Clk,
    ) -> Result<FrameReport, AppError<Src::Error>> {
        Self::check(cfg, source.size())?;
        self.target.reset();
        self.current = 0;
        let mut costs = StageCosts::default();
        let t0 = clock.now();
        let [frame, _] = &mut self.frames;
        let [pyr, _] = &mut self.pyramids;
        {
            let mut img = ImageMut::packed(&mut frame[..], cfg.width, cfg.height)?;
            if !source.next_frame(&mut img).map_err(AppError::Source)? {
                return Err(AppError::NoFrame);
            }
        }
        let t1 = clock.now();
        costs.capture = span(t0, t1);
        let out = {
            let view = ImageView::packed(&frame[..], cfg.width, cfg.height)?;
            let next = Pyramid::build(view, &mut pyr[..], cfg.levels)?;
            let t2 = clock.now();
            costs.pyramid = span(t1, t2);
            let mut probe = Probe {
                clock: &mut *clock,
                last: t2,
                costs: &mut costs,
            };
            self.target
                .step(&cfg.target, None, &next, acquire, &mut probe)?
        };
        costs.total = span(t1, clock.now());
        self.last.set((0, out.pose.map(|p| p.best), out.outline));
        Ok(self.report(0, &out, costs))
    }

    /// Runs one frame (see the module documentation). Returns `Ok(None)` once the source has
    /// ended. `acquire` is asked when the target is lost; `overlay` receives the previous
    /// frame's number and its picture with the outline and cube drawn.
    pub fn step<Src: FrameSource, Clk: Clock>(
        &mut self,
        cfg: &AppConfig,
        source: &mut Src,
        acquire: &mut (impl Acquire + ?Sized),
        clock: &mut Clk,
        overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
    ) -> Result<Option<FrameReport>, AppError<Src::Error>> {
        let Some((prev_index, prev_pose, prev_outline)) = self.last.get().copied() else {
            return Err(AppError::NotStarted);
        };
        let index = prev_index.saturating_add(1);
        let (w, h, levels) = (cfg.width, cfg.height, cfg.levels);
        let [f0, f1] = &mut self.frames;
        let [p0, p1] = &mut self.pyramids;
        let (prev_frame, next_frame, prev_pyr, next_pyr) = if self.current == 0 {
            (f0, f1, p0, p1)
        } else {
            (f1, f0, p1, p0)
        };
        let mut costs = StageCosts::default();
        let t0 = clock.now();
        {
            let mut img = ImageMut::packed(&mut next_frame[..], w, h)?;
            if !source.next_frame(&mut img).map_err(AppError::Source)? {
                return Ok(None);
            }
        }
        let t1 = clock.now();
        costs.capture = span(t0, t1);
        let out = {
            let next = Pyramid::build(
                ImageView::packed(&next_frame[..], w, h)?,
                &mut next_pyr[..],
                levels,
            )?;
            let prev_view = ImageView::packed(&prev_frame[..], w, h)?;
            let prev = Pyramid::from_buffer(prev_view, &prev_pyr[..], levels)?;
            let t2 = clock.now();
            costs.pyramid = span(t1, t2);
            let mut probe = Probe {
                clock: &mut *clock,
                last: t2,
                costs: &mut costs,
            };
            self.target
                .step(&cfg.target, Some(&prev), &next, acquire, &mut probe)?
        };
        // The previous frame has served as the template: draw its overlay into it.
        let t3 = clock.now();
        draw_overlay(cfg, &mut prev_frame[..], prev_pose, prev_outline)?;
        overlay(prev_index, &ImageView::packed(&prev_frame[..], w, h)?);
        let t4 = clock.now();
        costs.draw = span(t3, t4);
        costs.total = span(t1, t4);
        self.current = 1 - self.current;
        self.last
            .set((index, out.pose.map(|p| p.best), out.outline));
        Ok(Some(self.report(index, &out, costs)))
    }

    fn report(
        &self,
        index: u32,
        out: &camgeom::target::TargetFrame,
        costs: StageCosts,
    ) -> FrameReport {
        FrameReport {
            index,
            state: out.state,
            acquired: out.acquired,
            tracked: out.tracked,
            inliers: out.inliers,
            added: out.added,
            features: out.features,
            pose: out.pose,
            outline: out.outline,
            checksum: track_checksum(&self.target),
            costs,
        }
    }

    /// Draws the latest frame's overlay and hands it to `overlay` (after the source ended).
    pub fn finish<E>(
        &mut self,
        cfg: &AppConfig,
        overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
    ) -> Result<(), AppError<E>> {
        let Some((index, pose, outline)) = self.last.take() else {
            return Err(AppError::NotStarted);
        };
        let [f0, f1] = &mut self.frames;
        let frame = if self.current == 0 { f0 } else { f1 };
        draw_overlay(cfg, &mut frame[..], pose, outline)?;
        overlay(
            index,
            &ImageView::packed(&frame[..], cfg.width, cfg.height)?,
        );
        Ok(())
    }
}

/// The outline (straight lines between the corners) and, with a pose, the cube.
fn draw_overlay(
    cfg: &AppConfig,
    frame: &mut [u8],
    pose: Option<PoseEstimate<f32>>,
    outline: Option<[Point2<f32>; 4]>,
) -> Result<usize, Error> {
    let mut img = ImageMut::packed(frame, cfg.width, cfg.height)?;
    let mut written = 0;
    if let Some(q) = outline {
        for (a, b) in q.iter().zip(q.iter().cycle().skip(1)) {
            written += draw_line(&mut img, a, b, cfg.outline_value)?;
        }
    }
    if let Some(p) = pose {
        let (vertices, edges) = cube(cfg.cube.x, cfg.cube.y, cfg.cube.size);
        written += draw_wireframe(
            &mut img,
            cfg.target.camera(),
            &p.pose,
            &vertices,
            &edges,
            &cfg.wire,
        )?;
    }
    Ok(written)
}
