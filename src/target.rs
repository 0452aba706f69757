//! Tracking a planar target across frames: the on-board AR loop.
//!
//! Given the target's four corners in a first frame and its metric size `w x h`, features are
//! detected inside the target and tied to target-plane coordinates through the homography of
//! the corners. Each frame then runs
//!
//! 1. KLT from the previous pyramid to the new one (optionally forward-backward checked),
//! 2. RANSAC on (target point, image point) pairs: `u ~ H (X, Y, 1)`, dropping outlier tracks,
//! 3. the pose from the inliers: IPPE's two solutions, refined on the pixel reprojection error
//!    through the full camera model ([`crate::pose::solve_planar`]),
//! 4. re-detection inside the target's current outline when fewer than
//!    [`TargetConfig::min_tracks`] survive, the new features mapped to the target by `H⁻¹`.
//!
//! When too few inliers remain for a homography the tracker reports [`TargetState::Lost`] and
//! keeps its last homography, so a later frame can re-detect around the last known outline
//! ([`PlanarTarget::relocate`]) or the caller can re-initialise it from new corners.
//!
//! Everything is fixed-capacity: `N` tracks, with the caller's pyramids and scratch buffers.

use heapless::Vec;
use nalgebra::{Point2, Point3};

use crate::camera::Camera;
use crate::corners::{Corner, CornerConfig, good_features};
use crate::homography::{Homography, find_homography};
use crate::image::ImageView;
use crate::klt::{FlowArith, FlowBuffers, FlowStatus, LkConfig};
use crate::pose::{PlanarConfig, PlanarPose, solve_planar};
use crate::pyramid::Pyramid;
use crate::ransac::RansacConfig;
use crate::{Error, Result};

/// Parameters of a [`PlanarTarget`].
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
    /// Features closer than this to the target's outline (pixels) are not used: their
    /// windows would straddle the background.
    pub border: f32,
}

impl Default for TargetConfig {
    fn default() -> Self {
        Self {
            // 15x15 windows over 3 levels (OpenCV's lk_track sample): a target's features move a
            // few pixels a frame, and each window and level costs the board ~30 % of a frame.
            lk: LkConfig {
                win: 15,
                max_level: 2,
                fb_threshold: Some(1.0),
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
        }
    }
}

/// Where the tracker stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TargetState {
    /// No corners given yet.
    #[default]
    Uninitialised,
    /// The last frame gave a homography and a pose.
    Tracking,
    /// The last frame had too few inliers: the pose is not valid.
    Lost,
}

/// The outcome of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TargetFrame {
    /// State after the frame.
    pub state: TargetState,
    /// Both planar poses (world = target frame), when tracking.
    pub pose: Option<PlanarPose<f32>>,
    /// The target's corners `(0, 0), (w, 0), (w, h), (0, h)` in this frame, when tracking.
    pub outline: Option<[Point2<f32>; 4]>,
    /// Tracks that survived the flow.
    pub tracked: usize,
    /// Homography inliers (the tracks kept).
    pub inliers: usize,
    /// Features added by re-detection.
    pub added: usize,
}

/// The stages of one [`PlanarTarget::step`], in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// KLT from the previous pyramid to the new one (and back, when checked).
    Flow,
    /// RANSAC homography target plane → image on the tracked features.
    Homography,
    /// IPPE and its refinement on the inliers.
    Pose,
    /// Feature detection inside the target's outline.
    Redetect,
}

/// Told as each [`Stage`] of [`PlanarTarget::step_probed`] ends: a board reads its cycle
/// counter here. `()` is the probe that does nothing.
pub trait StageProbe {
    /// `stage` has just finished.
    fn stage_done(&mut self, stage: Stage);
}

impl StageProbe for () {
    fn stage_done(&mut self, _stage: Stage) {}
}

#[derive(Debug, Clone, Copy)]
struct Feature<C> {
    pos: [C; 2],
    target: Point2<f32>,
}

/// A planar target tracked with up to `N` features, arithmetic `A` for the flow
/// ([`crate::klt::Fixed`] or `f32`).
#[derive(Debug, Clone)]
pub struct PlanarTarget<A: FlowArith, const N: usize> {
    size: [f32; 2],
    features: Vec<Feature<A::Coord>, N>,
    buffers: FlowBuffers<A, N>,
    model: [Point2<f32>; N],
    pixels: [Point2<f32>; N],
    scratch: [Point2<f32>; N],
    mask: [bool; N],
    h: Option<Homography<f32>>,
    state: TargetState,
}

impl<A: FlowArith, const N: usize> PlanarTarget<A, N> {
    /// A tracker for a `width x height` target (metres, or any unit the pose should use).
    /// Errors: [`Error::InvalidParameter`] for a size that is not finite and positive.
    pub fn new(width: f32, height: f32) -> Result<Self> {
        if !(width.is_finite() && height.is_finite() && width > 0.0 && height > 0.0) {
            return Err(Error::InvalidParameter("size"));
        }
        Ok(Self {
            size: [width, height],
            features: Vec::new(),
            buffers: FlowBuffers::new(),
            model: [Point2::origin(); N],
            pixels: [Point2::origin(); N],
            scratch: [Point2::origin(); N],
            mask: [false; N],
            h: None,
            state: TargetState::Uninitialised,
        })
    }

    /// The state after the last call.
    pub fn state(&self) -> TargetState {
        self.state
    }

    /// Features currently tracked: `(image position, target-plane position)`.
    pub fn features(&self) -> impl Iterator<Item = (Point2<f32>, Point2<f32>)> + '_ {
        self.features.iter().map(|f| {
            (
                Point2::new(A::to_f32(f.pos[0]), A::to_f32(f.pos[1])),
                f.target,
            )
        })
    }

    /// The image positions of the features currently tracked, in the flow's own coordinates
    /// (Q16.16 `i32` for [`crate::klt::Fixed`], `f32` pixels for `f32`), in the order of
    /// [`Self::features`]: what a determinism check compares bit for bit at any image size.
    pub fn tracks(&self) -> impl Iterator<Item = [A::Coord; 2]> + '_ {
        self.features.iter().map(|f| f.pos)
    }

    /// The target's corners `(0, 0), (w, 0), (w, h), (0, h)` on the target plane.
    pub fn target_corners(&self) -> [Point2<f32>; 4] {
        let [w, h] = self.size;
        [
            Point2::new(0.0, 0.0),
            Point2::new(w, 0.0),
            Point2::new(w, h),
            Point2::new(0.0, h),
        ]
    }

    /// Starts tracking on `frame` from the target's four image corners, in the order of
    /// [`Self::target_corners`]. Detects features inside the outline; returns how many.
    ///
    /// `candidates` and `scratch` as [`good_features`]. Errors: as
    /// [`Homography::from_four_points`] for corners that do not form a proper quadrilateral,
    /// [`Error::TooFewPoints`] when fewer than `cfg.min_inliers` features are found.
    pub fn init(
        &mut self,
        frame: &ImageView<'_, u8>,
        corners: &[Point2<f32>; 4],
        cfg: &TargetConfig,
        candidates: &mut [Corner],
        scratch: &mut [u32],
    ) -> Result<usize> {
        let h = Homography::from_four_points(&self.target_corners(), corners)?;
        self.features.clear();
        self.h = Some(h);
        let added = self.detect(frame, &h, cfg, candidates, scratch)?;
        if added < cfg.min_inliers.max(4) {
            self.state = TargetState::Lost;
            return Err(Error::TooFewPoints);
        }
        self.state = TargetState::Tracking;
        Ok(added)
    }

    /// Re-detects features around the last known outline (after [`TargetState::Lost`]).
    /// Errors: [`Error::Degenerate`] when there never was a homography.
    pub fn relocate(
        &mut self,
        frame: &ImageView<'_, u8>,
        cfg: &TargetConfig,
        candidates: &mut [Corner],
        scratch: &mut [u32],
    ) -> Result<usize> {
        let h = self.h.ok_or(Error::Degenerate)?;
        self.detect(frame, &h, cfg, candidates, scratch)
    }

    /// Tracks the target from `prev` to `next` and solves its pose seen through `camera`.
    ///
    /// `flow_scratch`: [`crate::klt::scratch_len`]`(cfg.lk.win)` `i16`; `candidates`,
    /// `scratch`: as [`good_features`] for the re-detection. A frame with too few inliers is
    /// not an error: it returns [`TargetState::Lost`]. Errors: [`Error::InvalidParameter`]
    /// before [`Self::init`]; as [`crate::klt::calc_flow`] for mismatched pyramids or bad
    /// configuration.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: &Camera<f32>,
        cfg: &TargetConfig,
        flow_scratch: &mut [i16],
        candidates: &mut [Corner],
        scratch: &mut [u32],
    ) -> Result<TargetFrame> {
        self.step_probed(
            prev,
            next,
            camera,
            cfg,
            flow_scratch,
            candidates,
            scratch,
            &mut (),
        )
    }

    /// [`Self::step`], telling `probe` as each [`Stage`] ends (to time the stages on a
    /// board). A stage that does not run (no re-detection needed, target lost before the
    /// pose) is not reported.
    #[allow(clippy::too_many_arguments)]
    pub fn step_probed<P: StageProbe>(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        camera: &Camera<f32>,
        cfg: &TargetConfig,
        flow_scratch: &mut [i16],
        candidates: &mut [Corner],
        scratch: &mut [u32],
        probe: &mut P,
    ) -> Result<TargetFrame> {
        if self.state == TargetState::Uninitialised {
            return Err(Error::InvalidParameter("state"));
        }
        let frame = next.level(0).ok_or(Error::InvalidImage)?;
        let tracked = self.flow(prev, next, cfg, flow_scratch)?;
        probe.stage_done(Stage::Flow);
        let mut out = TargetFrame {
            state: TargetState::Lost,
            pose: None,
            outline: None,
            tracked,
            inliers: 0,
            added: 0,
        };
        let fitted = self.fit(cfg);
        probe.stage_done(Stage::Homography);
        let Some(h) = fitted else {
            self.state = TargetState::Lost;
            return Ok(out);
        };
        self.h = Some(h);
        out.inliers = self.features.len();
        let n = self.features.len();
        let (model, pixels, scr) = (
            self.model.get(..n).ok_or(Error::LengthMismatch)?,
            self.pixels.get(..n).ok_or(Error::LengthMismatch)?,
            self.scratch.get_mut(..n).ok_or(Error::LengthMismatch)?,
        );
        // Pose from the inliers; a numerical failure loses the frame, not the tracker.
        out.pose = solve_planar(camera, model, pixels, scr, &cfg.planar).ok();
        probe.stage_done(Stage::Pose);
        let mut outline = [Point2::origin(); 4];
        for (o, c) in outline.iter_mut().zip(self.target_corners().iter()) {
            *o = h.transfer(c)?;
        }
        out.outline = Some(outline);
        if self.features.len() < cfg.min_tracks {
            out.added = self.detect(&frame, &h, cfg, candidates, scratch)?;
            probe.stage_done(Stage::Redetect);
        }
        self.state = if out.pose.is_some() {
            TargetState::Tracking
        } else {
            TargetState::Lost
        };
        out.state = self.state;
        Ok(out)
    }

    /// Runs the flow and keeps the tracked features; returns how many.
    fn flow(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        cfg: &TargetConfig,
        scratch: &mut [i16],
    ) -> Result<usize> {
        let n = self.features.len();
        let positions = self.features.iter().map(|f| f.pos);
        let flows = self
            .buffers
            .run(prev, next, n, positions, &cfg.lk, scratch)?;
        let mut k = 0usize;
        self.features.retain(|_| {
            let keep = flows
                .get(k)
                .is_some_and(|f| f.status == FlowStatus::Tracked);
            k += 1;
            keep
        });
        let mut kept = flows.iter().filter(|f| f.status == FlowStatus::Tracked);
        for f in self.features.iter_mut() {
            if let Some(fl) = kept.next() {
                f.pos = [fl.x, fl.y];
            }
        }
        Ok(self.features.len())
    }

    /// RANSAC homography target → image on the live features; drops the outliers. `None`
    /// when fewer than `cfg.min_inliers` remain or no model is found.
    fn fit(&mut self, cfg: &TargetConfig) -> Option<Homography<f32>> {
        let n = self.features.len();
        if n < cfg.min_inliers.max(4) {
            return None;
        }
        for ((m, p), f) in self
            .model
            .iter_mut()
            .zip(self.pixels.iter_mut())
            .zip(self.features.iter())
        {
            *m = f.target;
            *p = Point2::new(A::to_f32(f.pos[0]), A::to_f32(f.pos[1]));
        }
        let mask = self.mask.get_mut(..n)?;
        let (h, report) = find_homography(
            self.model.get(..n)?,
            self.pixels.get(..n)?,
            &cfg.ransac,
            mask,
        )
        .ok()?;
        if report.inliers < cfg.min_inliers.max(4) {
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
    /// features, and ties them to the target through `H⁻¹`.
    fn detect(
        &mut self,
        frame: &ImageView<'_, u8>,
        h: &Homography<f32>,
        cfg: &TargetConfig,
        candidates: &mut [Corner],
        scratch: &mut [u32],
    ) -> Result<usize> {
        let mut outline = [Point2::origin(); 4];
        for (o, c) in outline.iter_mut().zip(self.target_corners().iter()) {
            *o = h.transfer(c)?;
        }
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
        let free = N.saturating_sub(self.features.len());
        let mut found: Vec<Corner, N> = Vec::new();
        let ccfg = CornerConfig {
            max_corners: if cfg.corners.max_corners == 0 {
                free
            } else {
                cfg.corners.max_corners.min(free)
            },
            ..cfg.corners
        };
        let existing = self.features.iter().map(|f| {
            [
                A::round(f.pos[0]) - x0 as i32,
                A::round(f.pos[1]) - y0 as i32,
            ]
        });
        good_features(&roi, &ccfg, existing, &mut found, candidates, scratch)?;
        let inv = h.inverse()?;
        let mut added = 0;
        for c in &found {
            let p = Point2::new(f32::from(c.x) + x0 as f32, f32::from(c.y) + y0 as f32);
            if !inside(&outline, &p, cfg.border) {
                continue;
            }
            let Ok(t) = inv.transfer(&p) else { continue };
            let pos = [
                A::from_px(i32::from(c.x) + x0 as i32),
                A::from_px(i32::from(c.y) + y0 as i32),
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
    use crate::corners::scratch_len as corner_scratch_len;
    use crate::klt::{Fixed, scratch_len};
    use crate::pyramid::buffer_len;
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

    impl StageProbe for Stages {
        fn stage_done(&mut self, stage: Stage) {
            self.0.push(stage);
        }
    }

    #[test]
    fn tracks_a_rendered_target_with_accurate_pose() {
        let k = Intrinsics::new(200.0f64, 200.0, 79.5, 59.5).unwrap();
        let cam = Camera::pinhole(k.cast::<f32>());
        let cfg = TargetConfig {
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
        };
        let levels = 3;
        let mut target = PlanarTarget::<Fixed, 48>::new(SIZE as f32, SIZE as f32).unwrap();
        let mut cand = vec![Corner::default(); 512];
        let mut cscr = vec![0u32; corner_scratch_len(W)];
        let mut fscr = vec![0i16; scratch_len(cfg.lk.win)];
        let frames: StdVec<StdVec<u8>> = (0..8).map(|t| render(&k, &pose_at(t as f64))).collect();
        let truth0 = pose_at(0.0);
        let corners = target.target_corners().map(|c| {
            let p = truth0.apply(&Point3::new(f64::from(c.x), f64::from(c.y), 0.0));
            let n = k.normalized_to_pixel(&Point2::new(p.x / p.z, p.y / p.z));
            Point2::new(n.x as f32, n.y as f32)
        });
        let f0 = ImageView::packed(&frames[0], W, H).unwrap();
        let n0 = target
            .init(&f0, &corners, &cfg, &mut cand, &mut cscr)
            .unwrap();
        assert!(n0 >= 20, "{n0} features");
        let mut bufs = [
            vec![0u8; buffer_len(W, H, levels)],
            vec![0u8; buffer_len(W, H, levels)],
        ];
        let mut worst_rot = 0.0f64;
        let mut worst_t = 0.0f64;
        for t in 1..frames.len() {
            let (a, b) = bufs.split_at_mut(1);
            let (pb, nb) = if t % 2 == 1 {
                (&mut a[0], &mut b[0])
            } else {
                (&mut b[0], &mut a[0])
            };
            let prev = Pyramid::build(ImageView::packed(&frames[t - 1], W, H).unwrap(), pb, levels)
                .unwrap();
            let next =
                Pyramid::build(ImageView::packed(&frames[t], W, H).unwrap(), nb, levels).unwrap();
            let mut stages = Stages::default();
            let out = target
                .step_probed(
                    &prev,
                    &next,
                    &cam,
                    &cfg,
                    &mut fscr,
                    &mut cand,
                    &mut cscr,
                    &mut stages,
                )
                .unwrap();
            assert_eq!(out.state, TargetState::Tracking, "frame {t}: {out:?}");
            // Every stage that ran was reported, once, in order.
            let mut expected = vec![Stage::Flow, Stage::Homography, Stage::Pose];
            if out.added > 0 {
                expected.push(Stage::Redetect);
            }
            assert_eq!(stages.0[..expected.len()], expected[..], "frame {t}");
            assert!(stages.0.len() <= 4, "frame {t}: {:?}", stages.0);
            let est = out.pose.unwrap().best.pose;
            let truth = pose_at(t as f64);
            let dr = (est.isometry().rotation.cast::<f64>() * truth.isometry().rotation.inverse())
                .angle()
                .to_degrees();
            let dt = (est.translation().cast::<f64>() - truth.translation()).norm()
                / truth.translation().norm();
            worst_rot = worst_rot.max(dr);
            worst_t = worst_t.max(dt);
        }
        std::println!(
            "rendered target, 7 frames: worst rotation {worst_rot:.3} deg, translation {:.3} %",
            worst_t * 100.0
        );
        // A 0.2 m target filling ~60 % of a 160x120 frame, tracked to ~0.05 px: the pose is
        // good to a fraction of a degree and about 1 % of the distance.
        assert!(
            worst_rot < 0.5 && worst_t < 0.01,
            "{worst_rot} deg, {worst_t}"
        );
    }

    #[test]
    fn bad_use_is_an_error() {
        assert_eq!(
            PlanarTarget::<f32, 8>::new(0.0, 1.0).err(),
            Some(Error::InvalidParameter("size"))
        );
        assert_eq!(
            PlanarTarget::<f32, 8>::new(f32::NAN, 1.0).err(),
            Some(Error::InvalidParameter("size"))
        );
        let mut t = PlanarTarget::<f32, 8>::new(1.0, 1.0).unwrap();
        let img = [0u8; 64];
        let v = ImageView::packed(&img, 8, 8).unwrap();
        let mut buf = [0u8; 64];
        let p = Pyramid::build(v, &mut buf, 1).unwrap();
        let cam = Camera::pinhole(Intrinsics::new(10.0, 10.0, 4.0, 4.0).unwrap());
        let mut f = [0i16; 4096];
        let mut c = [Corner::default(); 8];
        let mut s = [0u32; corner_scratch_len(8)];
        assert_eq!(
            t.step(
                &p,
                &p,
                &cam,
                &TargetConfig::default(),
                &mut f,
                &mut c,
                &mut s
            )
            .err(),
            Some(Error::InvalidParameter("state"))
        );
        // Collinear corners are not a target.
        let line = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(2.0, 2.0),
            Point2::new(3.0, 3.0),
        ];
        assert!(
            t.init(&v, &line, &TargetConfig::default(), &mut c, &mut s)
                .is_err()
        );
        // A flat image has no features.
        let quad = [
            Point2::new(1.0, 1.0),
            Point2::new(6.0, 1.0),
            Point2::new(6.0, 6.0),
            Point2::new(1.0, 6.0),
        ];
        assert_eq!(
            t.init(&v, &quad, &TargetConfig::default(), &mut c, &mut s)
                .err(),
            Some(Error::TooFewPoints)
        );
    }
}
