//! Tracking a planar target across frames: the AR loop, one call a frame.
//!
//! A target is a `w x h` plane (metres, or any unit the pose should use) with corners
//! `(0, 0), (w, 0), (w, h), (0, h)`. [`PlanarTarget::step`] is the whole per-frame policy; the
//! board's pipeline, the host's `camgeom ar` and the tests all call it. Each frame it runs
//!
//! 1. **acquisition**, while there is no target yet (and every
//!    [`TargetConfig::reacquire_every`] frames when set): an [`Acquire`] step gives the target's
//!    four image corners (given by hand, [`GivenCorners`], or found by a detector); features
//!    are detected inside them and tied to target-plane coordinates through the corners'
//!    homography, and the pose follows at once;
//! 2. **flow**: KLT from the previous pyramid to the new one (optionally forward-backward
//!    checked), dropping the tracks it loses;
//! 3. **homography**: RANSAC on (target point, image point) pairs, `u ~ H (X, Y, 1)`, dropping
//!    the outlier tracks;
//! 4. **pose** from the inliers: IPPE's two solutions refined on the reprojection error, in
//!    `f32` through the full camera model ([`crate::pose::solve_planar`]) or, for a target of
//!    [`Fixed`] arithmetic, with integer per-point work from the homography
//!    ([`crate::pose::solve_planar_integer`]; [`PoseArith`]);
//! 5. **re-detection** inside the target's current outline when fewer than
//!    [`TargetConfig::min_tracks`] survive, the new features mapped to the target by `H⁻¹`;
//! 6. after a **loss** (too few inliers, or no pose): acquisition again, and when it finds
//!    nothing, re-detection around the last known outline, so that the next frame can pick the
//!    target up where it was last seen ([`TargetConfig::relocate`]; with a detector the next
//!    frames only acquire).
//!
//! An [`Acquire`] step that can find the target near a prediction ([`Acquire::tracks`], as a
//! tag detector does: [`crate::apriltag::TagTarget`]) replaces steps 2 to 5 by **tracking by
//! detection**: each frame the target is looked for near its corners predicted from the last
//! two frames ([`Acquire::track`]), else acquired afresh (and every
//! [`TargetConfig::reacquire_every`] frames as a guard); the pose comes from the four corners
//! found, as an acquisition's does, with the planar ambiguity resolved by the last rotation.
//!
//! The configuration is checked once ([`TargetParams::new`]) and kept apart from the state
//! ([`PlanarTarget`]), which holds `N` tracks and every work buffer of the loop, sized by
//! `const` parameters from [`flow_scratch_len`] and [`corner_scratch_len`]. A
//! [`PlanarTarget::new`] is all zeros, so a board places it in a `static` in `.bss`.
//!
//! ```
//! use camgeom::camera::{Camera, Intrinsics};
//! use camgeom::image::ImageView;
//! use camgeom::klt::Fixed;
//! use camgeom::nalgebra::Point2;
//! use camgeom::pyramid::{Pyramid, buffer_len};
//! use camgeom::target::{
//!     GivenCorners, PlanarTarget, TargetConfig, TargetParams, TargetState, corner_scratch_len,
//!     flow_scratch_len,
//! };
//!
//! # fn main() -> camgeom::Result<()> {
//! // 64x48 frames of a textured square: 32 tracks, 15x15 windows, 256 corner candidates.
//! const W: usize = 64;
//! type Target = PlanarTarget<Fixed, 32, { flow_scratch_len(15) }, { corner_scratch_len(W) }, 256>;
//! let frame: Vec<u8> = (0..W * 48)
//!     .map(|i| {
//!         let (x, y) = ((i % W) as f32, (i / W) as f32);
//!         (128.0 + 100.0 * (x * 0.7).sin() * (y * 0.6).cos()) as u8
//!     })
//!     .collect();
//! let camera = Camera::pinhole(Intrinsics::new(60.0, 60.0, 31.5, 23.5)?);
//! let params = TargetParams::new(&TargetConfig::default(), camera, [0.1, 0.1])?;
//! let mut target = Box::new(Target::new());
//! let corners = [(8.0, 8.0), (56.0, 8.0), (56.0, 40.0), (8.0, 40.0)].map(|(x, y)| Point2::new(x, y));
//! let mut given = GivenCorners::new(corners);
//! let mut buf = vec![0u8; buffer_len(W, 48, 3)];
//! let pyr = Pyramid::build(ImageView::packed(&frame, W, 48)?, &mut buf, 3)?;
//! // Frame 0: no previous pyramid, the corners are acquired and the pose solved.
//! let report = target.step(&params, None, &pyr, &mut given, &mut ())?;
//! assert_eq!(report.state, TargetState::Tracking);
//! assert!(report.acquired && report.pose.is_some());
//! // Every later frame: `target.step(&params, Some(&previous), &next, &mut given, &mut ())`.
//! # Ok(())
//! # }
//! ```

use heapless::Vec;
use nalgebra::{Point2, Point3, UnitQuaternion, Vector2};

use crate::camera::Camera;
use crate::corners::{Corner, CornerConfig, CornerParams, good_features};
use crate::homography::{Homography, find_homography};
use crate::image::ImageView;
use crate::klt::Fixed;
use crate::klt::{
    Coordinate, Flow, FlowArith, FlowBuffers, FlowItem, LkConfig, LkParams, Templates,
};
use crate::pose::{
    MAX_PLANAR_POINTS, PlanarConfig, PlanarPoint, PlanarPose, PoseEstimate, solve_planar,
    solve_planar_integer,
};
use crate::pyramid::Pyramid;
use crate::ransac::{RansacConfig, RansacParams};
use crate::{Error, Result};

/// `i16` elements of a [`PlanarTarget`]'s flow scratch for `win x win` windows (its `S`).
pub const fn flow_scratch_len(win: usize) -> usize {
    crate::klt::scratch_len(win)
}

/// `i16` elements of a [`PlanarTarget`]'s flow scratch that also keeps the templates of each
/// frame's forward-backward check for the next frame's forward pass
/// ([`crate::klt::templates_len`] after the kernel's part; `N` tracks, windows `win x win` up
/// to level `max_level`). The same flows to the bit; with `lk.fb_threshold` off nothing is
/// kept.
pub const fn kept_flow_scratch_len(win: usize, max_level: usize, n: usize) -> usize {
    crate::klt::scratch_len(win) + crate::klt::templates_len(win, max_level, n)
}

/// `u32` elements of a [`PlanarTarget`]'s corner-detector scratch for frames up to `width`
/// pixels wide (its `C`).
pub const fn corner_scratch_len(width: usize) -> usize {
    crate::corners::scratch_len(width)
}

/// Parameters of the loop, as the user writes them; [`TargetParams::new`] checks them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TargetConfig {
    /// Frame-to-frame flow (its `fb_threshold` enables the forward-backward check).
    pub lk: LkConfig,
    /// Feature detection inside the target.
    pub corners: CornerConfig,
    /// Robust homography from the target plane to the image.
    pub ransac: RansacConfig<f32>,
    /// Pose refinement.
    pub planar: PlanarConfig,
    /// Re-detect features inside the target when fewer tracks than this survive.
    pub min_tracks: usize,
    /// Fewer homography inliers than this (at least 4) and the target is lost.
    pub min_inliers: usize,
    /// Features closer than this to the target's outline (pixels, finite, not negative) are
    /// not used: their windows would straddle the background.
    pub border: f32,
    /// While tracking, ask the [`Acquire`] step again every this many frames (0: only while
    /// there is no target or after a loss). With a detector this bounds the drift of the
    /// tracks; a detection that succeeds starts the features afresh from its corners.
    pub reacquire_every: u32,
    /// After a loss that the [`Acquire`] step does not end, look for features around the
    /// last outline (the target is likely still where it was, as after a few dark frames).
    /// Off for a detector: what is left around the outline of a target that has gone is
    /// background, and the detector finds the target again by itself.
    pub relocate: bool,
    /// When the planar pose is ambiguous (the alternative's error within this factor of the
    /// best's, [`PlanarPose::is_ambiguous`]), report as best the solution whose rotation is
    /// nearer the previous frame's: a small or nearly fronto-parallel target flips between
    /// its two solutions otherwise. `≥ 1`; 0 turns the rule off.
    pub ambiguity_ratio: f32,
}

impl TargetConfig {
    /// These settings for a target that a detector finds (a fiducial, through
    /// [`Acquire`]): such a target is small in the frame and has few features, so the KLT
    /// windows stay off its edge (`border` half a window and a pixel: a window there would
    /// take in the quiet zone and the background beyond), every track is checked forward and
    /// backward (`fb_threshold` 1 px), no features are added between acquisitions
    /// (`min_tracks = min_inliers`: features found inside the outline during an occlusion are
    /// the occluder's) and the detector alone finds the target again after a loss (no
    /// `relocate`). Measured on the rendered tag sequence (`cargo xtask run`'s tag job, a
    /// detection every 5th frame): rotation error p95 35° without these, 3.0° with them.
    pub fn for_detector(self) -> Self {
        Self {
            border: (self.lk.win / 2 + 1) as f32,
            relocate: false,
            lk: LkConfig {
                fb_threshold: Some(1.0),
                ..self.lk
            },
            min_tracks: self.min_inliers,
            ..self
        }
    }
}

impl Default for TargetConfig {
    fn default() -> Self {
        Self {
            // 15x15 windows over 3 levels (OpenCV's lk_track sample): a target's features move a
            // few pixels a frame, and each window and level costs the board ~30 % of a frame.
            // The loop reads no track's error, so its pass (a tenth of the flow) is skipped.
            lk: LkConfig {
                win: 15,
                max_level: 2,
                fb_threshold: Some(1.0),
                compute_error: false,
                ..LkConfig::default()
            },
            corners: CornerConfig {
                quality: 0.02,
                min_distance: 8,
                max_corners: 0,
            },
            // The homography sorts inliers from outliers (its local optimisation keeps the
            // inlier set stable) and outlines the target; the pose is refined on the
            // reprojection error next, so RANSAC's own LM refinement is skipped.
            ransac: RansacConfig {
                threshold: 2.0,
                max_iterations: 200,
                refine: false,
                ..RansacConfig::default()
            },
            planar: PlanarConfig::default(),
            min_tracks: 24,
            min_inliers: 8,
            border: 4.0,
            reacquire_every: 0,
            relocate: true,
            ambiguity_ratio: 1.5,
        }
    }
}

/// A [`TargetConfig`] checked once (its flow, corner and RANSAC parts into the params the
/// algorithms take), with the camera and the target's size: everything
/// [`PlanarTarget::step`] is told. Small and `Copy`; keep it beside the state.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TargetParams {
    cfg: TargetConfig,
    lk: LkParams,
    corners: CornerParams,
    ransac: RansacParams<f32>,
    camera: Camera<f32>,
    size: [f32; 2],
}

impl TargetParams {
    /// Checks `cfg` and the target's `size = [w, h]`.
    ///
    /// Errors: as [`LkConfig::check`], [`CornerConfig::check`] and [`RansacConfig::check`];
    /// [`Error::InvalidParameter`] for a `size` that is not finite and positive (`size`), a
    /// `min_inliers` below 4 (`min_inliers`), a `border` that is negative or not finite
    /// (`border`) or an `ambiguity_ratio` that is neither 0 nor at least 1
    /// (`ambiguity_ratio`).
    pub fn new(cfg: &TargetConfig, camera: Camera<f32>, size: [f32; 2]) -> Result<Self> {
        let lk = cfg.lk.check()?;
        let corners = cfg.corners.check()?;
        let ransac = cfg.ransac.check()?;
        if !size.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(Error::InvalidParameter("size"));
        }
        if cfg.min_inliers < 4 {
            return Err(Error::InvalidParameter("min_inliers"));
        }
        if !(cfg.border.is_finite() && cfg.border >= 0.0) {
            return Err(Error::InvalidParameter("border"));
        }
        if !(cfg.ambiguity_ratio == 0.0 || cfg.ambiguity_ratio >= 1.0)
            || !cfg.ambiguity_ratio.is_finite()
        {
            return Err(Error::InvalidParameter("ambiguity_ratio"));
        }
        Ok(Self {
            cfg: *cfg,
            lk,
            corners,
            ransac,
            camera,
            size,
        })
    }

    /// The checked configuration.
    pub fn config(&self) -> &TargetConfig {
        &self.cfg
    }

    /// The camera the pose is solved through.
    pub fn camera(&self) -> &Camera<f32> {
        &self.camera
    }

    /// The target's `[w, h]`.
    pub fn size(&self) -> [f32; 2] {
        self.size
    }

    /// The target's corners `(0, 0), (w, 0), (w, h), (0, h)` on the target plane: the order
    /// of every corner quadruple of this module.
    pub fn corners(&self) -> [Point2<f32>; 4] {
        let [w, h] = self.size;
        [
            Point2::new(0.0, 0.0),
            Point2::new(w, 0.0),
            Point2::new(w, h),
            Point2::new(0.0, h),
        ]
    }

    /// The target's corners in the image through `h`.
    pub fn outline(&self, h: &Homography<f32>) -> Result<[Point2<f32>; 4]> {
        let mut out = [Point2::origin(); 4];
        for (o, c) in out.iter_mut().zip(self.corners().iter()) {
            *o = h.transfer(c)?;
        }
        Ok(out)
    }
}

/// How a frame finds the target without tracking it: its four image corners, in the order of
/// [`TargetParams::corners`], or `None` when it is not in the frame.
///
/// [`PlanarTarget::step`] asks while there is no target, after a loss, and every
/// [`TargetConfig::reacquire_every`] frames. [`GivenCorners`] answers once with corners
/// picked by hand; a fiducial detector answers from the frame. `()` never finds anything.
pub trait Acquire {
    /// Looks for the target in `frame`. `lost_frames`: how many frames in a row the target has
    /// been lost, this one included (0 before the first acquisition and while tracking).
    /// Errors are the detector's own (they end the frame).
    fn acquire(
        &mut self,
        frame: &ImageView<'_, u8>,
        lost_frames: u32,
    ) -> Result<Option<[Point2<f32>; 4]>>;

    /// Whether [`Self::track`] finds the target near a prediction: the loop then tracks by
    /// it instead of by KLT (default: no). See [`PlanarTarget::step`].
    fn tracks(&self) -> bool {
        false
    }

    /// Finds the target in `frame` near `predicted`, its corners predicted for this frame
    /// (the order of [`TargetParams::corners`]), as a detector does in a region around them;
    /// `None` when it is not there (the loop then asks [`Self::acquire`]). A target found
    /// only partly seen says so ([`Tracked::partial`]). The default finds nothing. Errors are
    /// the detector's own (they end the frame).
    fn track(
        &mut self,
        frame: &ImageView<'_, u8>,
        predicted: &[Point2<f32>; 4],
    ) -> Result<Option<Tracked>> {
        let _ = (frame, predicted);
        Ok(None)
    }
}

/// What [`Acquire::track`] found: the target's corners (the order of
/// [`TargetParams::corners`]) and whether they come from a partly seen target.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tracked {
    /// The corners.
    pub corners: [Point2<f32>; 4],
    /// The target was only partly seen (hidden in part, or cut by the frame's edge): some
    /// corners are where the seen parts of its edges meet, not measured where they are (e.g.
    /// [`crate::apriltag::Detector::refine_partial`]).
    pub partial: bool,
}

impl Tracked {
    /// Corners of a wholly seen target.
    pub const fn whole(corners: [Point2<f32>; 4]) -> Self {
        Self {
            corners,
            partial: false,
        }
    }
}

impl Acquire for () {
    fn acquire(&mut self, _: &ImageView<'_, u8>, _: u32) -> Result<Option<[Point2<f32>; 4]>> {
        Ok(None)
    }
}

/// Corners known before the run (picked by hand in the first frame, or where the user is told
/// to hold the target): the first [`Acquire::acquire`] returns them; later ones only after
/// [`Self::again_after`] lost frames in a row, so a target lost for a moment is looked for
/// around its last outline rather than at the given corners.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GivenCorners {
    corners: [Point2<f32>; 4],
    used: bool,
    again_after: u32,
}

impl GivenCorners {
    /// The target's corners in the first frame; never given again.
    pub const fn new(corners: [Point2<f32>; 4]) -> Self {
        Self {
            corners,
            used: false,
            again_after: 0,
        }
    }

    /// Gives the corners again once the target has been lost `frames` frames in a row (0:
    /// never): the target starts over where the user holds it.
    pub const fn again_after(mut self, frames: u32) -> Self {
        self.again_after = frames;
        self
    }
}

impl Acquire for GivenCorners {
    fn acquire(
        &mut self,
        _frame: &ImageView<'_, u8>,
        lost_frames: u32,
    ) -> Result<Option<[Point2<f32>; 4]>> {
        let again = self.again_after > 0 && lost_frames >= self.again_after;
        if self.used && !again {
            return Ok(None);
        }
        self.used = true;
        Ok(Some(self.corners))
    }
}

/// Where the tracker stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TargetState {
    /// No target acquired yet.
    #[default]
    Uninitialised,
    /// The last frame gave a homography and a pose.
    Tracking,
    /// The last frame had too few inliers or no pose: the pose is not valid.
    Lost,
}

impl TargetState {
    /// The state in snake case (`uninitialised`, `tracking`, `lost`).
    pub const fn name(self) -> &'static str {
        match self {
            TargetState::Uninitialised => "uninitialised",
            TargetState::Tracking => "tracking",
            TargetState::Lost => "lost",
        }
    }
}

/// The outcome of one [`PlanarTarget::step`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TargetFrame {
    /// State after the frame.
    pub state: TargetState,
    /// The target was (re-)acquired on this frame: its features start from the [`Acquire`]
    /// step's corners, and the pose is theirs.
    pub acquired: bool,
    /// Both planar poses (world = target frame), when tracking: `best` the one with the
    /// lower error or, when the two are ambiguous, the one nearer the previous frame's
    /// ([`TargetConfig::ambiguity_ratio`]).
    pub pose: Option<PlanarPose<f32>>,
    /// The target's corners `(0, 0), (w, 0), (w, h), (0, h)` in this frame, when tracking.
    pub outline: Option<[Point2<f32>; 4]>,
    /// Tracks that survived the flow (0 on an acquisition; 4, the corners, when
    /// [`Acquire::track`] found the target).
    pub tracked: usize,
    /// The pose comes from a partly seen target ([`Tracked::partial`]): its corners are where
    /// the seen parts of its edges meet. Only tracking by detection gives such a frame.
    pub partial: bool,
    /// Homography inliers (the tracks kept; on an acquisition the features detected).
    pub inliers: usize,
    /// Features added by acquisition, re-detection or relocation.
    pub added: usize,
    /// Features alive after the frame.
    pub features: usize,
}

/// The stages of one [`PlanarTarget::step`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// The [`Acquire`] step.
    Acquire,
    /// KLT from the previous pyramid to the new one (and back, when checked).
    Flow,
    /// RANSAC homography target plane → image on the tracked features.
    Homography,
    /// IPPE and its refinement on the inliers.
    Pose,
    /// Feature detection inside the target's outline (after an acquisition, with too few
    /// tracks, or around the last outline after a loss).
    Redetect,
}

impl Stage {
    /// Every stage, in the order a frame runs them (a probe's cost table follows it).
    pub const ALL: [Stage; 5] = [
        Stage::Acquire,
        Stage::Flow,
        Stage::Homography,
        Stage::Pose,
        Stage::Redetect,
    ];

    /// Its place in [`Self::ALL`] (a cost table's index).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Its name in snake case (a cost table's column).
    pub const fn name(self) -> &'static str {
        match self {
            Stage::Acquire => "acquire",
            Stage::Flow => "flow",
            Stage::Homography => "homography",
            Stage::Pose => "pose",
            Stage::Redetect => "redetect",
        }
    }
}

/// Told as each [`Stage`] of [`PlanarTarget::step`] ends (`StageProbe<Stage>`): a board reads
/// its cycle counter there. A stage may be reported more than once in a frame (re-detection
/// after a loss).
pub use crate::probe::StageProbe;

#[derive(Debug, Clone, Copy)]
struct Feature<C> {
    pos: [C; 2],
    target: Point2<f32>,
}

impl<C: Copy> FlowItem<C> for Feature<C> {
    fn position(&self) -> [C; 2] {
        self.pos
    }

    fn moved(&mut self, flow: &Flow<C>) {
        self.pos = [flow.x, flow.y];
    }
}

/// The arithmetic of the loop's pose stage, chosen with its flow's by the type `A` of a
/// [`PlanarTarget`] (sealed: `f32` and [`Fixed`]).
///
/// - `f32`: [`solve_planar`]: IPPE from a DLT over every pair, refined on the pixel error through
///   the lens model in `f32`.
/// - [`Fixed`]: [`solve_planar_integer`]: IPPE from the loop's homography at four points,
///   refined with integer per-point arithmetic on the error in the undistorted image; for cores
///   without an FPU, where it costs a fraction of the float path's instructions (measured in
///   BENCHMARKS.md: the Cortex-M3 row of the main job's pose column), and within a stated bound
///   of it (`solve_planar_integer`'s tests,
///   and the host test over the box sequence).
pub trait PoseArith: FlowArith {
    /// One pair of the pose stage's scratch.
    type PoseScratch: Copy + core::fmt::Debug;
    /// Its zero (for `const` initialisers).
    const POSE_SCRATCH: Self::PoseScratch;
    /// Most tracks (`N`) the stage takes; a [`PlanarTarget`] with more does not compile.
    const MAX_TRACKS: usize;
    /// Both planar poses from the pairs, `hint` the homography from the model plane to the
    /// pixels.
    fn solve(
        camera: &Camera<f32>,
        hint: &Homography<f32>,
        model: &[Point2<f32>],
        pixels: &[Point2<f32>],
        scratch: &mut [Self::PoseScratch],
        cfg: &PlanarConfig,
    ) -> Result<PlanarPose<f32>>;
}

impl PoseArith for f32 {
    type PoseScratch = Point2<f32>;
    const POSE_SCRATCH: Point2<f32> = Point2::new(0.0, 0.0);
    const MAX_TRACKS: usize = usize::MAX;
    fn solve(
        camera: &Camera<f32>,
        _hint: &Homography<f32>,
        model: &[Point2<f32>],
        pixels: &[Point2<f32>],
        scratch: &mut [Point2<f32>],
        cfg: &PlanarConfig,
    ) -> Result<PlanarPose<f32>> {
        solve_planar(camera, model, pixels, scratch, cfg)
    }
}

impl PoseArith for Fixed {
    type PoseScratch = PlanarPoint;
    const POSE_SCRATCH: PlanarPoint = PlanarPoint::ZERO;
    const MAX_TRACKS: usize = MAX_PLANAR_POINTS;
    fn solve(
        camera: &Camera<f32>,
        hint: &Homography<f32>,
        model: &[Point2<f32>],
        pixels: &[Point2<f32>],
        scratch: &mut [PlanarPoint],
        cfg: &PlanarConfig,
    ) -> Result<PlanarPose<f32>> {
        solve_planar_integer(camera, hint, model, pixels, scratch, cfg)
    }
}

/// The state of a tracked planar target: up to `N` features, arithmetic `A` for the flow
/// ([`crate::klt::Fixed`] or `f32`), and the loop's work buffers: `S` ≥
/// [`flow_scratch_len`]`(win)` flow scratch, `C` ≥ [`corner_scratch_len`]`(width)` corner
/// scratch and `K` ≥ 2 corner candidates (the strongest `K / 2` local maxima of a detection are
/// exact). `size_of::<Self>()` is all of its RAM.
#[derive(Debug, Clone)]
pub struct PlanarTarget<
    A: PoseArith,
    const N: usize,
    const S: usize,
    const C: usize,
    const K: usize,
> {
    features: Vec<Feature<A::Coord>, N>,
    buffers: FlowBuffers<A, N>,
    model: [Point2<f32>; N],
    pixels: [Point2<f32>; N],
    scratch: [A::PoseScratch; N],
    mask: [bool; N],
    h: Option<Homography<f32>>,
    state: TargetState,
    since_acquired: u32,
    lost_frames: u32,
    /// The best pose's rotation of the last frame that had one (for the ambiguity rule).
    last_rotation: Option<UnitQuaternion<f32>>,
    /// The last frame's outline when it was tracked, and each corner's motion from the frame
    /// before (zero when that one had none): the prediction of tracking by detection.
    corners: Option<[Point2<f32>; 4]>,
    motion: [Vector2<f32>; 4],
    flow_scratch: [i16; S],
    corner_scratch: [u32; C],
    candidates: [Corner; K],
}

impl<A: PoseArith, const N: usize, const S: usize, const C: usize, const K: usize> Default
    for PlanarTarget<A, N, S, C, K>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<A: PoseArith, const N: usize, const S: usize, const C: usize, const K: usize>
    PlanarTarget<A, N, S, C, K>
{
    /// A target not acquired yet. All zeros: a `static` of it lives in `.bss`.
    pub const fn new() -> Self {
        const { assert!(N <= A::MAX_TRACKS, "more tracks than the pose stage takes") };
        let origin = Point2::new(0.0, 0.0);
        Self {
            features: Vec::new(),
            buffers: FlowBuffers::new(),
            model: [origin; N],
            pixels: [origin; N],
            scratch: [A::POSE_SCRATCH; N],
            mask: [false; N],
            h: None,
            state: TargetState::Uninitialised,
            since_acquired: 0,
            lost_frames: 0,
            last_rotation: None,
            corners: None,
            motion: [Vector2::new(0.0, 0.0); 4],
            flow_scratch: [0; S],
            corner_scratch: [0; C],
            candidates: [Corner {
                x: 0,
                y: 0,
                score: 0,
            }; K],
        }
    }

    /// The state after the last frame.
    pub fn state(&self) -> TargetState {
        self.state
    }

    /// Forgets the target: the next frame acquires it again.
    pub fn reset(&mut self) {
        self.features.clear();
        self.h = None;
        self.state = TargetState::Uninitialised;
        self.since_acquired = 0;
        self.lost_frames = 0;
        self.last_rotation = None;
        self.corners = None;
        self.motion = [Vector2::zeros(); 4];
    }

    /// Features currently tracked: `(image position, target-plane position)`.
    pub fn features(&self) -> impl Iterator<Item = (Point2<f32>, Point2<f32>)> + '_ {
        self.features
            .iter()
            .map(|f| (Point2::new(f.pos[0].to_f32(), f.pos[1].to_f32()), f.target))
    }

    /// The image positions of the features currently tracked, in the flow's own coordinates
    /// ([`crate::klt::Q16`] for [`crate::klt::Fixed`], `f32` pixels for `f32`), in the order of
    /// [`Self::features`]: what a determinism check compares bit for bit at any image size.
    pub fn tracks(&self) -> impl Iterator<Item = [A::Coord; 2]> + '_ {
        self.features.iter().map(|f| f.pos)
    }

    /// One frame of the loop (see the module documentation): `next` is the new frame's
    /// pyramid, `prev` the previous frame's (`None` for the first frame of a run, which can
    /// only acquire). `acquire` finds the target when there is none; `probe` is told as each
    /// stage ends.
    ///
    /// A frame that loses the target is not an error: it returns [`TargetState::Lost`].
    /// Errors: [`Error::BufferTooSmall`] when `S`, `C` or `K` is too small for `params` and
    /// the frame (`flow_scratch`, `corner_scratch`, `candidates`); [`Error::InvalidImage`] for
    /// pyramids of different sizes; [`Error::InvalidParameter`] (`prev`) for a frame after the
    /// first without `prev`; the acquisition's errors, and as [`Homography::from_four_points`]
    /// for acquired corners that do not form a proper quadrilateral.
    pub fn step<Q: Acquire + ?Sized, P: StageProbe<Stage> + ?Sized>(
        &mut self,
        params: &TargetParams,
        prev: Option<&Pyramid<'_>>,
        next: &Pyramid<'_>,
        acquire: &mut Q,
        probe: &mut P,
    ) -> Result<TargetFrame> {
        let frame = next.level(0).ok_or(Error::InvalidImage)?;
        self.fits(params, frame.width())?;
        let mut out = TargetFrame {
            state: TargetState::Lost,
            acquired: false,
            pose: None,
            outline: None,
            tracked: 0,
            partial: false,
            inliers: 0,
            added: 0,
            features: 0,
        };
        // Frames since the last acquisition, this one included.
        self.since_acquired = self.since_acquired.saturating_add(1);
        let every = params.cfg.reacquire_every;
        let due =
            self.state == TargetState::Uninitialised || (every > 0 && self.since_acquired >= every);
        if acquire.tracks() {
            self.step_by_detection(params, &frame, acquire, probe, due, &mut out)?;
            return Ok(out);
        }
        if due && self.try_acquire(params, &frame, acquire, probe, &mut out)? {
            return Ok(out);
        }
        if self.state == TargetState::Uninitialised {
            out.state = TargetState::Uninitialised;
            return Ok(out);
        }
        let prev = prev.ok_or(Error::InvalidParameter("prev"))?;
        out.tracked = self.flow(params, prev, next)?;
        probe.stage_done(Stage::Flow);
        let fitted = self.fit(params);
        probe.stage_done(Stage::Homography);
        if let Some(h) = fitted {
            self.h = Some(h);
            out.inliers = self.features.len();
            out.pose = self.solve(params);
            probe.stage_done(Stage::Pose);
            out.outline = Some(params.outline(&h)?);
            if self.features.len() < params.cfg.min_tracks {
                out.added = self.detect(params, &frame, &h)?;
                probe.stage_done(Stage::Redetect);
            }
        }
        if out.pose.is_some() {
            self.state = TargetState::Tracking;
        } else {
            // Lost: look for the target afresh, else around its last outline on this frame.
            self.state = TargetState::Lost;
            if !due && self.try_acquire(params, &frame, acquire, probe, &mut out)? {
                return Ok(out);
            }
            if !params.cfg.relocate {
                // Nothing left to track: the next frames only acquire.
                self.features.clear();
            } else if let Some(h) = self.h {
                out.added += self.detect(params, &frame, &h)?;
                probe.stage_done(Stage::Redetect);
            }
        }
        self.end_frame(params, &mut out);
        Ok(out)
    }

    /// One frame of tracking by detection ([`Acquire::tracks`]): while tracking, and unless
    /// the guard's full acquisition is `due`, the target is looked for near its corners
    /// predicted from the last two frames (constant motion of each corner;
    /// [`Acquire::track`]); when that fails (or after a loss) it is acquired afresh
    /// ([`Acquire::acquire`]), and when the guard's acquisition misses a tracked target, it is
    /// looked for near the prediction. The pose comes from the four corners found, as an
    /// acquisition's does, the ambiguity resolved by the last rotation; no features are
    /// tracked.
    fn step_by_detection<Q: Acquire + ?Sized, P: StageProbe<Stage> + ?Sized>(
        &mut self,
        params: &TargetParams,
        frame: &ImageView<'_, u8>,
        acquire: &mut Q,
        probe: &mut P,
        due: bool,
        out: &mut TargetFrame,
    ) -> Result<()> {
        let predicted = match (self.state, self.corners) {
            (TargetState::Tracking, Some(last)) => {
                let mut p = last;
                for (p, m) in p.iter_mut().zip(self.motion.iter()) {
                    *p += m;
                }
                Some(p)
            }
            _ => None,
        };
        let mut found = None;
        if let Some(p) = predicted.as_ref()
            && !due
        {
            found = acquire.track(frame, p)?;
            probe.stage_done(Stage::Acquire);
        }
        let mut tracked = found.is_some();
        if !tracked {
            let lost = match self.state {
                TargetState::Lost => self.lost_frames.saturating_add(1),
                _ => 0,
            };
            found = acquire.acquire(frame, lost)?.map(Tracked::whole);
            probe.stage_done(Stage::Acquire);
            if found.is_some() {
                self.since_acquired = 0;
                out.acquired = true;
            } else if let Some(p) = predicted.as_ref()
                && due
            {
                // The guard's detection missed a target that was tracked: look where it must be.
                found = acquire.track(frame, p)?;
                probe.stage_done(Stage::Acquire);
                tracked = found.is_some();
            }
        }
        self.features.clear();
        self.state = TargetState::Lost;
        if let Some(Tracked { corners, partial }) = found
            && let Ok(h) = Homography::from_four_points(&params.corners(), &corners)
        {
            self.h = Some(h);
            out.tracked = if tracked { 4 } else { 0 };
            out.inliers = 4;
            out.pose = self.solve_corners(params, &corners);
            probe.stage_done(Stage::Pose);
            if out.pose.is_some() {
                self.state = TargetState::Tracking;
                out.outline = Some(corners);
                out.partial = partial;
            }
        }
        self.end_frame(params, out);
        Ok(())
    }

    /// Records the frame's outcome in the state and in `out`, after the ambiguity rule
    /// ([`TargetConfig::ambiguity_ratio`]) has picked between the two poses.
    fn end_frame(&mut self, params: &TargetParams, out: &mut TargetFrame) {
        let ratio = params.cfg.ambiguity_ratio;
        if let (Some(p), Some(last)) = (out.pose.as_mut(), self.last_rotation)
            && ratio > 0.0
            && p.is_ambiguous(ratio)
        {
            let near = |e: &PoseEstimate<f32>| e.pose.isometry().rotation.angle_to(&last);
            if near(&p.alternative) < near(&p.best) {
                core::mem::swap(&mut p.best, &mut p.alternative);
            }
        }
        self.last_rotation = match (self.state, &out.pose) {
            (TargetState::Tracking, Some(p)) => Some(p.best.pose.isometry().rotation),
            _ => None,
        };
        self.lost_frames = match self.state {
            TargetState::Lost => self.lost_frames.saturating_add(1),
            _ => 0,
        };
        // The outline's corners and their motion since the last frame (for the prediction of
        // tracking by detection).
        let now = match self.state {
            TargetState::Tracking => out.outline,
            _ => None,
        };
        self.motion = [Vector2::zeros(); 4];
        if let (Some(a), Some(b)) = (self.corners, now) {
            for ((m, p), q) in self.motion.iter_mut().zip(a.iter()).zip(b.iter()) {
                *m = q - p;
            }
        }
        self.corners = now;
        out.state = self.state;
        out.features = self.features.len();
    }

    /// `S`, `C` and `K` against `params` and a frame `width` pixels wide.
    fn fits(&self, params: &TargetParams, width: usize) -> Result<()> {
        if S < flow_scratch_len(params.lk.config().win) {
            return Err(Error::BufferTooSmall("flow_scratch"));
        }
        if C < corner_scratch_len(width) {
            return Err(Error::BufferTooSmall("corner_scratch"));
        }
        if K < 2 {
            return Err(Error::BufferTooSmall("candidates"));
        }
        Ok(())
    }

    /// Asks `acquire`; with corners, starts the features from them and solves the pose into
    /// `out`. Returns whether it did.
    fn try_acquire<Q: Acquire + ?Sized, P: StageProbe<Stage> + ?Sized>(
        &mut self,
        params: &TargetParams,
        frame: &ImageView<'_, u8>,
        acquire: &mut Q,
        probe: &mut P,
        out: &mut TargetFrame,
    ) -> Result<bool> {
        // This frame counts as lost when it is asked after a loss.
        let lost = match self.state {
            TargetState::Lost => self.lost_frames.saturating_add(1),
            _ => 0,
        };
        let found = acquire.acquire(frame, lost)?;
        probe.stage_done(Stage::Acquire);
        let Some(corners) = found else {
            return Ok(false);
        };
        let h = Homography::from_four_points(&params.corners(), &corners)?;
        self.features.clear();
        self.h = Some(h);
        self.since_acquired = 0;
        let added = self.detect(params, frame, &h)?;
        probe.stage_done(Stage::Redetect);
        out.acquired = true;
        out.added += added;
        out.inliers = added;
        if added >= params.cfg.min_inliers {
            // The features were just tied to the target through the corners' homography, so
            // this is the pose of the four corners, refined over every feature.
            self.load_pairs();
            out.pose = self.solve(params);
        } else {
            // Too few features to track (a small or distant target), but the acquisition
            // measured the four corners in this frame: they give the pose, as a detector's
            // own pose would. The next frame cannot track and acquires again.
            out.pose = self.solve_corners(params, &corners);
        }
        probe.stage_done(Stage::Pose);
        out.outline = out.pose.map(|_| corners);
        self.state = if out.pose.is_some() {
            TargetState::Tracking
        } else {
            TargetState::Lost
        };
        self.end_frame(params, out);
        Ok(true)
    }

    /// Runs the flow and keeps the tracked features; returns how many.
    fn flow(
        &mut self,
        params: &TargetParams,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
    ) -> Result<usize> {
        // The scratch beyond the kernel's keeps the templates when it holds them all
        // (`kept_flow_scratch_len`).
        let cfg = params.lk.config();
        let (scratch, rest) = self
            .flow_scratch
            .split_at_mut(flow_scratch_len(cfg.win).min(S));
        let templates = if S >= kept_flow_scratch_len(cfg.win, cfg.max_level, N) {
            Templates::Keep(rest)
        } else {
            Templates::Compute
        };
        let features = self.features.as_mut_view();
        let lk = &params.lk;
        let mut buffers = self.buffers.as_mut_view();
        buffers.track(prev, next, features, lk, templates, scratch)
    }

    /// The live features into the model/pixel arrays.
    fn load_pairs(&mut self) {
        for ((m, p), f) in self
            .model
            .iter_mut()
            .zip(self.pixels.iter_mut())
            .zip(self.features.iter())
        {
            *m = f.target;
            *p = Point2::new(f.pos[0].to_f32(), f.pos[1].to_f32());
        }
    }

    /// Both planar poses from the first `features.len()` model/pixel pairs; a numerical
    /// failure loses the frame, not the tracker.
    fn solve(&mut self, params: &TargetParams) -> Option<PlanarPose<f32>> {
        self.solve_first(params, self.features.len())
    }

    /// Both planar poses from the target's four corners seen at `corners` alone.
    fn solve_corners(
        &mut self,
        params: &TargetParams,
        corners: &[Point2<f32>; 4],
    ) -> Option<PlanarPose<f32>> {
        for ((m, p), (a, b)) in self
            .model
            .iter_mut()
            .zip(self.pixels.iter_mut())
            .zip(params.corners().iter().zip(corners))
        {
            (*m, *p) = (*a, *b);
        }
        self.solve_first(params, 4)
    }

    /// Both planar poses from the first `n` model/pixel pairs, the homography of the frame as
    /// the hint.
    fn solve_first(&mut self, params: &TargetParams, n: usize) -> Option<PlanarPose<f32>> {
        let (model, pixels, scratch) = (
            self.model.get(..n)?,
            self.pixels.get(..n)?,
            self.scratch.get_mut(..n)?,
        );
        let hint = self.h.as_ref()?;
        let cfg = &params.cfg.planar;
        A::solve(&params.camera, hint, model, pixels, scratch, cfg).ok()
    }

    /// RANSAC homography target → image on the live features; drops the outliers. `None`
    /// when fewer than `min_inliers` remain or no model is found.
    fn fit(&mut self, params: &TargetParams) -> Option<Homography<f32>> {
        let n = self.features.len();
        let min = params.cfg.min_inliers;
        if n < min {
            return None;
        }
        self.load_pairs();
        let mask = self.mask.get_mut(..n)?;
        let (h, report) = find_homography(
            self.model.get(..n)?,
            self.pixels.get(..n)?,
            &params.ransac,
            mask,
        )
        .ok()?;
        if report.inliers < min {
            return None;
        }
        // Keep the inliers only, in the features and in the model/pixel arrays alike.
        let mut k = 0usize;
        let mask_ro: &[bool] = mask;
        self.features.retain(|_| {
            let keep = mask_ro.get(k).copied().unwrap_or(false);
            k += 1;
            keep
        });
        let mut w = 0usize;
        for i in 0..n {
            if mask_ro.get(i).copied().unwrap_or(false) {
                // Compaction: w <= i, so slot w is free to overwrite.
                let pair = (self.model.get(i).copied(), self.pixels.get(i).copied());
                if let (Some(m), Some(p)) = pair
                    && let (Some(mw), Some(pw)) = (self.model.get_mut(w), self.pixels.get_mut(w))
                {
                    *mw = m;
                    *pw = p;
                }
                w += 1;
            }
        }
        Some(h)
    }

    /// Detects features inside the outline `H (target corners)` of `frame`, away from the live
    /// features, and ties them to the target through `H⁻¹`. Returns how many were added.
    fn detect(
        &mut self,
        params: &TargetParams,
        frame: &ImageView<'_, u8>,
        h: &Homography<f32>,
    ) -> Result<usize> {
        let outline = params.outline(h)?;
        let (fw, fh) = (frame.width() as f32, frame.height() as f32);
        let (mut x0, mut y0, mut x1, mut y1) = (fw, fh, 0.0f32, 0.0f32);
        for p in &outline {
            x0 = x0.min(p.x);
            y0 = y0.min(p.y);
            x1 = x1.max(p.x);
            y1 = y1.max(p.y);
        }
        let (x0, y0) = (x0.max(0.0) as usize, y0.max(0.0) as usize);
        let (x1, y1) = (
            x1.min(fw - 1.0).max(0.0) as usize,
            y1.min(fh - 1.0).max(0.0) as usize,
        );
        if x1 <= x0 + 2 || y1 <= y0 + 2 {
            return Ok(0);
        }
        let roi = frame.sub(x0, y0, x1 - x0 + 1, y1 - y0 + 1)?;
        let mut found: Vec<Corner, N> = Vec::new();
        let ccfg = params.corners.up_to(N.saturating_sub(self.features.len()));
        let existing = self
            .features
            .iter()
            .map(|f| [f.pos[0].round() - x0 as i32, f.pos[1].round() - y0 as i32]);
        good_features(
            &roi,
            &ccfg,
            existing,
            &mut found,
            &mut self.candidates,
            &mut self.corner_scratch,
        )?;
        let inv = h.inverse()?;
        let mut added = 0;
        for c in &found {
            let p = Point2::new(f32::from(c.x) + x0 as f32, f32::from(c.y) + y0 as f32);
            if !inside(&outline, &p, params.cfg.border) {
                continue;
            }
            let Ok(t) = inv.transfer(&p) else { continue };
            let pos = [
                A::Coord::from_px(i32::from(c.x) + x0 as i32),
                A::Coord::from_px(i32::from(c.y) + y0 as i32),
            ];
            if self.features.push(Feature { pos, target: t }).is_err() {
                break;
            }
            added += 1;
        }
        Ok(added)
    }
}

/// `p` inside the convex quadrilateral `q` (either orientation) and at least `margin` pixels
/// from each edge.
fn inside(q: &[Point2<f32>; 4], p: &Point2<f32>, margin: f32) -> bool {
    let mut sign = 0.0f32;
    for (a, b) in q.iter().zip(q.iter().cycle().skip(1)) {
        let e = b - a;
        let len = e.norm();
        if len <= f32::EPSILON {
            return false;
        }
        // Signed distance of p from the edge line (positive on the left).
        let d = (e.x * (p.y - a.y) - e.y * (p.x - a.x)) / len;
        if sign == 0.0 {
            sign = if d >= 0.0 { 1.0 } else { -1.0 };
        }
        if d * sign < margin {
            return false;
        }
    }
    true
}

/// The target's corners as 3D points of the target plane (`Z = 0`), for drawing.
pub fn corners_3d(width: f32, height: f32) -> [Point3<f32>; 4] {
    [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(width, 0.0, 0.0),
        Point3::new(width, height, 0.0),
        Point3::new(0.0, height, 0.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::klt::Fixed;
    use crate::pyramid::{PyramidPair, buffer_len};
    use crate::transform::Pose;
    use nalgebra::Vector3;
    use std::vec;
    use std::vec::Vec as StdVec;

    const W: usize = 160;
    const H: usize = 120;
    const SIZE: f64 = 0.2;

    /// A smooth texture on the target (0..SIZE)², constant grey elsewhere.
    fn texture(x: f64, y: f64) -> f64 {
        if !(0.0..=SIZE).contains(&x) || !(0.0..=SIZE).contains(&y) {
            return 90.0;
        }
        let (u, v) = (x / SIZE * 6.0, y / SIZE * 6.0);
        128.0
            + 80.0 * (4.0 * (u * 3.3).sin() * (v * 2.9 + 0.3 * u).sin()).tanh()
            + 30.0 * ((u * 1.7 + v * 2.3).sin() * (u * 0.9 - v * 1.3).cos())
    }

    /// Renders the target plane seen at `pose` by intersecting each pixel's ray with `Z = 0`
    /// in f64, 4 samples per pixel: independent of camgeom's projection and warping code.
    fn render(k: &Intrinsics<f64>, pose: &Pose<f64>) -> StdVec<u8> {
        let kinv = k.inverse_matrix();
        let inv = pose.inverse();
        let c = inv.origin_in_target_frame();
        let mut img = vec![0u8; W * H];
        for (i, px) in img.iter_mut().enumerate() {
            let (u, v) = ((i % W) as f64, (i / W) as f64);
            let mut acc = 0.0;
            for (du, dv) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let d = inv.apply_vector(&(kinv * Vector3::new(u + du, v + dv, 1.0)));
                let s = -c.z / d.z;
                acc += texture(c.x + s * d.x, c.y + s * d.y);
            }
            *px = (acc / 4.0).round().clamp(0.0, 255.0) as u8;
        }
        img
    }

    fn pose_at(t: f64) -> Pose<f64> {
        // The camera circles slowly over the target, 0.5 m away, looking at its centre.
        let r = Vector3::new(0.25 + 0.02 * t, -0.15 + 0.015 * t, 0.05 * t);
        let rot = nalgebra::Rotation3::new(r);
        let centre = Vector3::new(SIZE / 2.0, SIZE / 2.0, 0.0);
        let t_vec = Vector3::new(0.0, 0.0, 0.5) - rot * centre;
        Pose::from_rodrigues(r, t_vec).unwrap()
    }

    /// Records the stages a step reports.
    #[derive(Default)]
    struct Stages(StdVec<Stage>);

    impl StageProbe<Stage> for Stages {
        fn stage_done(&mut self, stage: Stage) {
            self.0.push(stage);
        }
    }

    type Tracker =
        PlanarTarget<Fixed, 48, { flow_scratch_len(11) }, { corner_scratch_len(W) }, 512>;

    fn config() -> TargetConfig {
        TargetConfig {
            lk: LkConfig {
                win: 11,
                max_level: 2,
                fb_threshold: Some(1.0),
                ..LkConfig::default()
            },
            corners: CornerConfig {
                quality: 0.02,
                min_distance: 6,
                max_corners: 0,
            },
            min_tracks: 20,
            ..TargetConfig::default()
        }
    }

    /// The target's corners in frame `t` through the true pose.
    fn true_corners(k: &Intrinsics<f64>, params: &TargetParams, t: f64) -> [Point2<f32>; 4] {
        let truth = pose_at(t);
        params.corners().map(|c| {
            let p = truth.apply(&Point3::new(f64::from(c.x), f64::from(c.y), 0.0));
            let n = k.normalized_to_pixel(&Point2::new(p.x / p.z, p.y / p.z));
            Point2::new(n.x as f32, n.y as f32)
        })
    }

    fn pose_error(est: &Pose<f32>, t: f64) -> (f64, f64) {
        let truth = pose_at(t);
        let dr = (est.isometry().rotation.cast::<f64>() * truth.isometry().rotation.inverse())
            .angle()
            .to_degrees();
        let dt = (est.translation().cast::<f64>() - truth.translation()).norm()
            / truth.translation().norm();
        (dr, dt)
    }

    /// Runs `frames` through `step`, two pyramid buffers swapping roles; returns each frame's
    /// report and the stages it reported.
    fn run(
        params: &TargetParams,
        frames: &[StdVec<u8>],
        acquire: &mut dyn Acquire,
    ) -> StdVec<(TargetFrame, StdVec<Stage>)> {
        run_with(params, frames, acquire, |_, _| {})
    }

    /// [`run`], with `before(acquire, t)` called before frame `t`.
    fn run_with<Q: Acquire + ?Sized>(
        params: &TargetParams,
        frames: &[StdVec<u8>],
        acquire: &mut Q,
        mut before: impl FnMut(&mut Q, usize),
    ) -> StdVec<(TargetFrame, StdVec<Stage>)> {
        let levels = 3;
        let mut target = std::boxed::Box::new(Tracker::new());
        let mut pair = PyramidPair::new(
            [vec![0u8; W * H], vec![0u8; W * H]],
            [(); 2].map(|()| vec![0u8; buffer_len(W, H, levels)]),
        );
        pair.set_geometry(W, H, levels).unwrap();
        let mut out = StdVec::new();
        for (t, frame) in frames.iter().enumerate() {
            before(acquire, t);
            let mut img = pair.capture().unwrap();
            img.copy_from(&ImageView::packed(frame, W, H).unwrap())
                .unwrap();
            let pyramids = pair.advance().unwrap();
            let mut stages = Stages::default();
            let r = target
                .step(
                    params,
                    pyramids.previous.as_ref(),
                    &pyramids.next,
                    acquire,
                    &mut stages,
                )
                .unwrap();
            out.push((r, stages.0));
        }
        out
    }

    #[test]
    fn tracks_a_rendered_target_with_accurate_pose() {
        let k = Intrinsics::new(200.0f64, 200.0, 79.5, 59.5).unwrap();
        let cam = Camera::pinhole(k.cast::<f32>());
        let params = TargetParams::new(&config(), cam, [SIZE as f32; 2]).unwrap();
        let frames: StdVec<StdVec<u8>> = (0..8).map(|t| render(&k, &pose_at(t as f64))).collect();
        let mut given = GivenCorners::new(true_corners(&k, &params, 0.0));
        let reports = run(&params, &frames, &mut given);
        let (first, stages0) = &reports[0];
        // Frame 0 acquires from the given corners and has a pose at once.
        assert!(first.acquired && first.added >= 20, "{first:?}");
        assert_eq!(first.state, TargetState::Tracking);
        assert_eq!(stages0[..], [Stage::Acquire, Stage::Redetect, Stage::Pose]);
        let mut worst_rot = 0.0f64;
        let mut worst_t = 0.0f64;
        for (t, (out, stages)) in reports.iter().enumerate() {
            assert_eq!(out.state, TargetState::Tracking, "frame {t}: {out:?}");
            if t > 0 {
                // Every stage that ran was reported, once, in order.
                let mut expected = vec![Stage::Flow, Stage::Homography, Stage::Pose];
                if out.added > 0 {
                    expected.push(Stage::Redetect);
                }
                assert_eq!(stages[..], expected[..], "frame {t}");
                assert!(!out.acquired);
            }
            let (dr, dt) = pose_error(&out.pose.unwrap().best.pose, t as f64);
            worst_rot = worst_rot.max(dr);
            worst_t = worst_t.max(dt);
        }
        std::println!(
            "rendered target, 8 frames: worst rotation {worst_rot:.3} deg, translation {:.3} %",
            worst_t * 100.0
        );
        // A 0.2 m target filling ~60 % of a 160x120 frame, tracked to ~0.05 px: the pose is
        // good to a fraction of a degree and about 1 % of the distance.
        assert!(
            worst_rot < 0.5 && worst_t < 0.01,
            "{worst_rot} deg, {worst_t}"
        );
    }

    /// A detector stand-in: answers with the true corners of the frame it is asked on, except
    /// on the frames listed as blind, and counts its calls.
    struct Oracle<'a> {
        k: &'a Intrinsics<f64>,
        params: &'a TargetParams,
        frame: usize,
        blind: &'a [usize],
        calls: StdVec<usize>,
    }

    impl Acquire for Oracle<'_> {
        fn acquire(&mut self, _: &ImageView<'_, u8>, _: u32) -> Result<Option<[Point2<f32>; 4]>> {
            self.calls.push(self.frame);
            Ok((!self.blind.contains(&self.frame))
                .then(|| true_corners(self.k, self.params, self.frame as f64)))
        }
    }

    /// An oracle that also tracks: the true corners near the prediction, except on the frames
    /// of `blind` and `miss` (where only the full acquisition finds the target).
    struct TrackingOracle<'a> {
        oracle: Oracle<'a>,
        miss: &'a [usize],
        tracked: StdVec<(usize, [Point2<f32>; 4])>,
    }

    impl Acquire for TrackingOracle<'_> {
        fn acquire(
            &mut self,
            f: &ImageView<'_, u8>,
            lost: u32,
        ) -> Result<Option<[Point2<f32>; 4]>> {
            self.oracle.acquire(f, lost)
        }

        fn tracks(&self) -> bool {
            true
        }

        fn track(
            &mut self,
            _: &ImageView<'_, u8>,
            predicted: &[Point2<f32>; 4],
        ) -> Result<Option<Tracked>> {
            let t = self.oracle.frame;
            self.tracked.push((t, *predicted));
            let o = &self.oracle;
            let hidden = o.blind.contains(&t) || self.miss.contains(&t);
            Ok((!hidden).then(|| Tracked::whole(true_corners(o.k, o.params, t as f64))))
        }
    }

    #[test]
    fn tracks_by_detection_with_a_guard_and_falls_back_to_acquisition() {
        let k = Intrinsics::new(200.0f64, 200.0, 79.5, 59.5).unwrap();
        let cam = Camera::pinhole(k.cast::<f32>());
        let cfg = TargetConfig {
            reacquire_every: 4,
            ..config()
        };
        let params = TargetParams::new(&cfg, cam, [SIZE as f32; 2]).unwrap();
        let frames: StdVec<StdVec<u8>> = (0..10).map(|t| render(&k, &pose_at(t as f64))).collect();
        let mut acq = TrackingOracle {
            oracle: Oracle {
                k: &k,
                params: &params,
                frame: 0,
                blind: &[6],
                calls: StdVec::new(),
            },
            miss: &[2],
            tracked: StdVec::new(),
        };
        let run = run_with(&params, &frames, &mut acq, |o, t| o.oracle.frame = t);
        let mut states = StdVec::new();
        for (t, (r, stages)) in run.iter().enumerate() {
            if r.state == TargetState::Tracking {
                let (dr, dt) = pose_error(&r.pose.unwrap().best.pose, t as f64);
                assert!(dr < 0.5 && dt < 0.01, "frame {t}: {dr} deg, {dt}");
                assert_eq!(r.outline, Some(true_corners(&k, &params, t as f64)));
            }
            // No KLT: no flow, no features.
            assert!(
                !stages.contains(&Stage::Flow) && r.features == 0,
                "frame {t}"
            );
            states.push((r.state, r.acquired, r.tracked));
        }
        use TargetState::{Lost, Tracking};
        assert_eq!(
            states,
            [
                (Tracking, true, 0),
                (Tracking, false, 4),
                // Missed where it must be: the full acquisition finds it.
                (Tracking, true, 0),
                (Tracking, false, 4),
                (Tracking, false, 4),
                (Tracking, false, 4),
                // Four frames after the last acquisition the guard runs, finds nothing, and
                // the target is not where it must be either.
                (Lost, false, 0),
                // After a loss: acquisition only.
                (Tracking, true, 0),
                (Tracking, false, 4),
                (Tracking, false, 4),
            ]
        );
        assert_eq!(acq.oracle.calls, [0, 2, 6, 7]);
        let asked: StdVec<usize> = acq.tracked.iter().map(|(t, _)| *t).collect();
        assert_eq!(asked, [1, 2, 3, 4, 5, 6, 8, 9]);
        // The prediction: the last corners moved as they moved the frame before (frame 4 from
        // frames 2 and 3), the last corners alone after an acquisition that follows a loss.
        let c = |t: usize| true_corners(&k, &params, t as f64);
        let (_, p4) = acq.tracked[3];
        for ((p, a), b) in p4.iter().zip(c(3)).zip(c(2)) {
            let want = a + (a - b);
            assert!((p - want).norm() < 1e-4, "{p} vs {want}");
        }
        assert_eq!(acq.tracked[6].1, c(7));
    }

    #[test]
    fn acquires_after_a_loss_and_every_n_frames() {
        let k = Intrinsics::new(200.0f64, 200.0, 79.5, 59.5).unwrap();
        let cam = Camera::pinhole(k.cast::<f32>());
        let cfg = TargetConfig {
            reacquire_every: 3,
            ..config()
        };
        let params = TargetParams::new(&cfg, cam, [SIZE as f32; 2]).unwrap();
        // Frames 0-1 blank (nothing to acquire), 2-9 the target, 5 blank again (lost).
        let blank = vec![90u8; W * H];
        let frames: StdVec<StdVec<u8>> = (0..10)
            .map(|t| {
                if t < 2 || t == 5 {
                    blank.clone()
                } else {
                    render(&k, &pose_at(t as f64))
                }
            })
            .collect();
        let mut oracle = Oracle {
            k: &k,
            params: &params,
            frame: 0,
            blind: &[0, 1, 5],
            calls: StdVec::new(),
        };
        let mut states = StdVec::new();
        let run = run_with(&params, &frames, &mut oracle, |o, t| o.frame = t);
        for (t, (r, _)) in run.iter().enumerate() {
            if r.state == TargetState::Tracking {
                let (dr, dt) = pose_error(&r.pose.unwrap().best.pose, t as f64);
                // As the tracking test: a fraction of a degree, about 1 % of the distance.
                assert!(dr < 0.5 && dt < 0.01, "frame {t}: {dr} deg, {dt}");
            }
            states.push((r.state, r.acquired));
        }
        use TargetState::{Lost, Tracking, Uninitialised};
        assert_eq!(
            states,
            [
                (Uninitialised, false),
                (Uninitialised, false),
                (Tracking, true),
                (Tracking, false),
                (Tracking, false),
                // The blank frame loses the target; the detector finds nothing there.
                (Lost, false),
                // Found again.
                (Tracking, true),
                (Tracking, false),
                (Tracking, false),
                // Three frames after the last acquisition: asked again while tracking.
                (Tracking, true),
            ]
        );
        // Asked while there was no target (0, 1, 2), after the loss (5, 6) and when due (9).
        assert_eq!(oracle.calls, [0, 1, 2, 5, 6, 9]);
    }

    #[test]
    fn bad_configuration_and_buffers_are_errors() {
        let cam = Camera::pinhole(Intrinsics::new(10.0, 10.0, 4.0, 4.0).unwrap());
        let ok = TargetConfig::default();
        for (size, cfg, name) in [
            ([0.0, 1.0], ok, "size"),
            ([f32::NAN, 1.0], ok, "size"),
            (
                [1.0, 1.0],
                TargetConfig {
                    min_inliers: 3,
                    ..ok
                },
                "min_inliers",
            ),
            ([1.0, 1.0], TargetConfig { border: -1.0, ..ok }, "border"),
            (
                [1.0, 1.0],
                TargetConfig {
                    lk: LkConfig {
                        epsilon: 11.0,
                        ..ok.lk
                    },
                    ..ok
                },
                "lk.epsilon",
            ),
        ] {
            assert_eq!(
                TargetParams::new(&cfg, cam, size).err(),
                Some(Error::InvalidParameter(name))
            );
        }
        let params = TargetParams::new(&ok, cam, [1.0, 1.0]).unwrap();
        let img = [0u8; 64];
        let v = ImageView::packed(&img, 8, 8).unwrap();
        let mut buf = [0u8; 64];
        let p = Pyramid::build(v, &mut buf, 1).unwrap();
        // A flow scratch for 11x11 windows is too small for the default 15x15.
        let mut small = PlanarTarget::<f32, 8, { flow_scratch_len(11) }, 96, 8>::new();
        assert_eq!(
            small.step(&params, None, &p, &mut (), &mut ()).err(),
            Some(Error::BufferTooSmall("flow_scratch"))
        );
        let mut narrow = PlanarTarget::<f32, 8, { flow_scratch_len(15) }, 95, 8>::new();
        assert_eq!(
            narrow.step(&params, None, &p, &mut (), &mut ()).err(),
            Some(Error::BufferTooSmall("corner_scratch"))
        );
        let mut t = PlanarTarget::<f32, 8, { flow_scratch_len(15) }, 96, 8>::new();
        // Nothing to acquire: not an error, no target yet.
        let r = t.step(&params, None, &p, &mut (), &mut ()).unwrap();
        assert_eq!(r.state, TargetState::Uninitialised);
        // Collinear corners are not a target.
        let line = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(2.0, 2.0),
            Point2::new(3.0, 3.0),
        ];
        assert!(
            t.step(&params, None, &p, &mut GivenCorners::new(line), &mut ())
                .is_err()
        );
        // A flat image has no features: acquired, the pose is the four corners' alone
        // (nothing to track, so the next frame acquires again).
        let quad = [
            Point2::new(1.0, 1.0),
            Point2::new(6.0, 1.0),
            Point2::new(6.0, 6.0),
            Point2::new(1.0, 6.0),
        ];
        let r = t
            .step(&params, None, &p, &mut GivenCorners::new(quad), &mut ())
            .unwrap();
        assert!(r.acquired && r.pose.is_some() && r.features == 0);
        assert_eq!(r.state, TargetState::Tracking);
        // Tracking needs the previous frame.
        assert_eq!(
            t.step(&params, None, &p, &mut (), &mut ()).err(),
            Some(Error::InvalidParameter("prev"))
        );
    }

    #[test]
    fn given_corners_come_again_only_after_a_long_loss() {
        let img = [0u8; 4];
        let v = ImageView::packed(&img, 2, 2).unwrap();
        let c = [Point2::new(1.0, 2.0); 4];
        let mut once = GivenCorners::new(c);
        let mut again = GivenCorners::new(c).again_after(2);
        let asked: StdVec<_> = [0, 1, 2, 0, 3]
            .iter()
            .map(|&lost| {
                (
                    once.acquire(&v, lost).unwrap().is_some(),
                    again.acquire(&v, lost).unwrap().is_some(),
                )
            })
            .collect();
        assert_eq!(
            asked,
            [
                (true, true),
                (false, false),
                (false, true),
                (false, false),
                (false, true)
            ]
        );
    }
}
