//! Structure from motion in caller-owned memory: incremental reconstruction over any number of
//! views ([`reconstruct`], with [`TrackBuilder`] to make its [`TrackSet`] from pairwise matches
//! and [`bundle_adjust_views`]), and the fixed-capacity three-view pipeline below.
//!
//!
//! [`reconstruct_three_views`] runs the classic incremental pipeline on point tracks seen by
//! one calibrated camera from three positions:
//!
//! 1. views 1-2: [`find_essential`] (5-point RANSAC) and [`recover_pose`] (cheirality), so
//!    `X₂ = R X₁ + t` with `|t| = 1` (the scale is not observable; the 1-2 baseline is the unit);
//! 2. triangulate the inlier tracks ([`triangulate_optimal`]), keeping points in front of
//!    both views, with enough parallax and a reprojection error below the bound;
//! 3. register view 3 by PnP on the triangulated points ([`solve_pnp_ransac`]: P3P + RANSAC +
//!    LM);
//! 4. triangulate the tracks seen by view 3 and one of views 1, 2 but not yet reconstructed;
//! 5. [`bundle_adjust`] every pose but the first and every point (Schur complement).
//!
//! The world frame is view 1's camera frame. Observations are raw pixels: lens distortion is
//! removed for the minimal solvers and modelled by the bundle adjustment. Every buffer lives
//! in a caller-owned [`SfmWorkspace`] of capacity `N` tracks (e.g. 256).
//!
//! ```
//! use camgeom::camera::{Camera, Intrinsics};
//! use camgeom::nalgebra::{Point3, Vector3};
//! use camgeom::sfm::{SfmParams, SfmWorkspace, Track, reconstruct_three_views};
//! use camgeom::transform::Pose;
//!
//! let camera = Camera::pinhole(Intrinsics::new(500.0f64, 500.0, 320.0, 240.0)?);
//! // View 1 at the origin, view 2 one unit to its right (the baseline sets the scale), view 3
//! // further on, all turned a little towards the scene.
//! let pose = |r: [f64; 3], t: [f64; 3]| Pose::from_rodrigues(r.into(), Vector3::from(t));
//! let views = [pose([0.0; 3], [0.0; 3])?, pose([0.0, -0.1, 0.02], [-1.0, 0.0, 0.0])?,
//!     pose([0.05, -0.2, 0.0], [-1.8, 0.3, 0.2])?];
//! let scene: [Point3<f64>; 40] = core::array::from_fn(|i| {
//!     let f = |m: usize, n: usize| ((i * m) % n) as f64 / n as f64 - 0.5;
//!     Point3::new(0.5 + 3.0 * f(37, 11), 2.0 * f(53, 7), 5.0 + 2.5 * f(29, 13))
//! });
//! // Every point in every view, except that view 3 misses every seventh.
//! let tracks: Vec<Track<f64>> = (0..40).map(|i| {
//!     let see = |v: usize| camera.project(&views[v], &scene[i]).ok();
//!     [see(0), see(1), if i % 7 == 0 { None } else { see(2) }]
//! }).collect();
//! let mut ws = SfmWorkspace::<f64, 64>::new();
//! let r = reconstruct_three_views(&camera, &tracks, &SfmParams::default(), &mut ws)?;
//! assert_eq!(r.points, 40);
//! // Exact observations: poses and points come back to rounding, in the baseline's unit.
//! for (rebuilt, truth) in r.poses.iter().zip(&views) {
//!     assert!((rebuilt.translation() - truth.translation()).norm() < 1e-6);
//!     assert!((rebuilt.rotation_vector() - truth.rotation_vector()).norm() < 1e-6);
//! }
//! for (p, x) in ws.points.iter().zip(&scene) {
//!     assert!(p.is_some_and(|p| (p - x).norm() < 1e-6));
//! }
//! # Ok::<(), camgeom::Error>(())
//! ```

mod bundle;
mod bundle_views;
mod config;
mod incremental;
mod incremental_config;
mod initial_pair;
mod scene;
mod track;
mod track_builder;
mod track_set;

pub use bundle::{BundleReport, PointBlock, bundle_adjust};
pub use bundle_views::{
    BundleScratch, BundleSettings, Gauge, PointScratch, ViewsBundleReport, bundle_adjust_views,
};
pub use config::{SfmConfig, SfmParams};
pub use incremental::{Reconstruction, reconstruct};
pub use incremental_config::{IncrementalConfig, IncrementalParams};
pub use scene::{InitialRefusal, Scene, ViewRefusal, ViewResult, ViewState, Workspace};
pub use track::Track;
pub use track_builder::{NO_TRACK, TrackBuilder};
pub use track_set::{MAX_VIEWS, Observation, TrackSet};

use nalgebra::{Point2, Point3};

use crate::camera::Camera;
use crate::pose::solve_pnp_ransac;
use crate::scalar::{Real, above};
use crate::transform::Pose;
use crate::twoview::{find_essential, recover_pose, triangulate_optimal};
use crate::{Error, Result};

/// The caller-owned memory of [`reconstruct_three_views`] for up to `N` tracks: the outputs
/// ([`Self::points`], [`Self::used`]) and the scratch of every stage: about 100 scalars and
/// a few words per track (~110 KB for `N = 256` in `f32`; put it in a `static` on a board).
#[derive(Debug, Clone)]
pub struct SfmWorkspace<T: Real, const N: usize> {
    /// The reconstructed point of each track (world = view 1's frame), `None` if not.
    pub points: [Option<Point3<T>>; N],
    /// The observations the reconstruction used (inliers), per track and view.
    pub used: [[bool; 3]; N],
    normalized: [[Option<Point2<T>>; 3]; N],
    a: [Point2<T>; N],
    b: [Point2<T>; N],
    world: [Point3<T>; N],
    index: [usize; N],
    mask: [bool; N],
    blocks: [PointBlock<T>; N],
}

impl<T: Real, const N: usize> Default for SfmWorkspace<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, const N: usize> SfmWorkspace<T, N> {
    /// Capacity in tracks.
    pub const CAPACITY: usize = N;

    /// An empty workspace.
    pub fn new() -> Self {
        Self {
            points: [None; N],
            used: [[false; 3]; N],
            normalized: [[None; 3]; N],
            a: [Point2::origin(); N],
            b: [Point2::origin(); N],
            world: [Point3::origin(); N],
            index: [0; N],
            mask: [false; N],
            blocks: core::array::from_fn(|_| PointBlock::default()),
        }
    }
}

/// What [`reconstruct_three_views`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThreeViewReconstruction<T: Real = f32> {
    /// World-to-camera poses of the three views; `poses[0]` is the identity and
    /// `|poses[1].translation()| = 1`.
    pub poses: [Pose<T>; 3],
    /// Tracks with a reconstructed point.
    pub points: usize,
    /// Inliers of the views 1-2 essential matrix (after cheirality).
    pub initial_inliers: usize,
    /// Inliers of the PnP registration of view 3.
    pub pnp_inliers: usize,
    /// Points added from view 3 (step 4).
    pub new_points: usize,
    /// The bundle adjustment (RMS before and after, over every used observation).
    pub bundle: BundleReport<T>,
}

/// Runs the three-view pipeline of the module docs on `tracks` (at most `N`) with the checked
/// `params` ([`SfmConfig::check`]), writing the points and the used observations into `ws`.
///
/// Errors: [`Error::LengthMismatch`] for more tracks than `N`; [`Error::TooFewPoints`] when
/// fewer than 5 tracks link views 1-2 or fewer than 4 reconstructed points are seen by view 3;
/// otherwise those of [`find_essential`], [`recover_pose`], [`solve_pnp_ransac`] and
/// [`bundle_adjust`].
pub fn reconstruct_three_views<T: Real, const N: usize>(
    camera: &Camera<T>,
    tracks: &[Track<T>],
    params: &SfmParams<T>,
    ws: &mut SfmWorkspace<T, N>,
) -> Result<ThreeViewReconstruction<T>> {
    let config = params.config();
    let n = tracks.len();
    if n > N {
        return Err(Error::LengthMismatch);
    }
    let k = camera.intrinsics;
    ws.points.iter_mut().for_each(|p| *p = None);
    ws.used.iter_mut().for_each(|u| *u = [false; 3]);
    for (norm, track) in ws.normalized.iter_mut().zip(tracks.iter()) {
        for (o, t) in norm.iter_mut().zip(track.iter()) {
            *o = t.and_then(|p| camera.undistort_to_normalized(&p).ok());
        }
    }

    // 1. Views 1-2: undistorted pixels of the tracks seen by both.
    let mut m = 0usize;
    for (i, norm) in ws.normalized.iter().enumerate().take(n) {
        if let [Some(p), Some(q), _] = norm
            && let (Some(a), Some(b), Some(idx)) =
                (ws.a.get_mut(m), ws.b.get_mut(m), ws.index.get_mut(m))
        {
            *a = k.normalized_to_pixel(p);
            *b = k.normalized_to_pixel(q);
            *idx = i;
            m += 1;
        }
    }
    if m < 5 {
        return Err(Error::TooFewPoints);
    }
    let (a, b, mask) = (
        ws.a.get(..m).ok_or(Error::LengthMismatch)?,
        ws.b.get(..m).ok_or(Error::LengthMismatch)?,
        ws.mask.get_mut(..m).ok_or(Error::LengthMismatch)?,
    );
    let (e, _) = find_essential(&k, &k, a, b, params.essential(), mask)?;
    let rel = recover_pose(&e, &k, &k, a, b, config.max_depth, mask)?;
    let p1 = Pose::identity();
    let p2 = Pose::from_isometry(*rel.pose.isometry());

    // 2. Triangulate the 1-2 inliers.
    let mut initial_inliers = 0usize;
    for idx in inliers(&ws.index, &ws.mask, m) {
        initial_inliers += 1;
        let (Some(norm), Some(track)) = (ws.normalized.get(idx), tracks.get(idx)) else {
            continue;
        };
        if let Some(x) = triangulate_checked(camera, config, [(&p1, 0), (&p2, 1)], norm, track)
            && let (Some(pt), Some(used)) = (ws.points.get_mut(idx), ws.used.get_mut(idx))
        {
            *pt = Some(x);
            used[0] = true;
            used[1] = true;
        }
    }

    // 3. Register view 3 by PnP on the reconstructed points it sees.
    let mut m = 0usize;
    for (i, (point, track)) in ws.points.iter().zip(tracks.iter()).enumerate() {
        if let (Some(x), [_, _, Some(u)]) = (point, track)
            && let (Some(w), Some(a), Some(idx)) =
                (ws.world.get_mut(m), ws.a.get_mut(m), ws.index.get_mut(m))
        {
            *w = *x;
            *a = *u;
            *idx = i;
            m += 1;
        }
    }
    if m < 4 {
        return Err(Error::TooFewPoints);
    }
    let (world, pixels, scratch, mask) = (
        ws.world.get(..m).ok_or(Error::LengthMismatch)?,
        ws.a.get(..m).ok_or(Error::LengthMismatch)?,
        ws.b.get_mut(..m).ok_or(Error::LengthMismatch)?,
        ws.mask.get_mut(..m).ok_or(Error::LengthMismatch)?,
    );
    let (est, report) = solve_pnp_ransac(camera, world, pixels, scratch, params.pnp(), mask)?;
    let p3 = est.pose;
    for idx in inliers(&ws.index, &ws.mask, m) {
        if let Some(used) = ws.used.get_mut(idx) {
            used[2] = true;
        }
    }

    // 4. New points between view 3 and view 1 (the longer baseline, usually), else view 2.
    let mut new_points = 0usize;
    for ((point, used), (norm, track)) in ws
        .points
        .iter_mut()
        .zip(ws.used.iter_mut())
        .zip(ws.normalized.iter().zip(tracks.iter()))
    {
        if point.is_some() {
            continue;
        }
        let pairs = [[(&p1, 0), (&p3, 2)], [(&p2, 1), (&p3, 2)]];
        for pair in pairs {
            if let Some(x) = triangulate_checked(camera, config, pair, norm, track) {
                *point = Some(x);
                let [(_, va), _] = pair;
                if let Some(u) = used.get_mut(va) {
                    *u = true;
                }
                used[2] = true;
                new_points += 1;
                break;
            }
        }
    }

    // 5. Bundle adjustment.
    let mut poses = [p1, p2, p3];
    let bundle = bundle_adjust(
        camera,
        &mut poses,
        ws.points.get_mut(..n).ok_or(Error::LengthMismatch)?,
        tracks,
        ws.used.get(..n).ok_or(Error::LengthMismatch)?,
        ws.blocks.get_mut(..n).ok_or(Error::LengthMismatch)?,
        config.bundle_iterations,
    )?;
    let points = ws.points.iter().filter(|p| p.is_some()).count();
    Ok(ThreeViewReconstruction {
        poses,
        points,
        initial_inliers,
        pnp_inliers: report.inliers,
        new_points,
        bundle,
    })
}

/// The track indices of the first `m` correspondences that `mask` marks as inliers.
fn inliers<'a>(index: &'a [usize], mask: &'a [bool], m: usize) -> impl Iterator<Item = usize> + 'a {
    index
        .iter()
        .zip(mask)
        .take(m)
        .filter_map(|(&i, &inlier)| inlier.then_some(i))
}

/// Triangulates a track between two views (optimal method) and accepts the point when it is
/// in front of both, nearer than `max_depth`, with parallax ≥ `min_parallax` and a pixel
/// reprojection error ≤ `max_reprojection_px` in both views (through the distortion model).
fn triangulate_checked<T: Real>(
    camera: &Camera<T>,
    config: &SfmConfig<T>,
    views: [(&Pose<T>, usize); 2],
    normalized: &[Option<Point2<T>>; 3],
    track: &Track<T>,
) -> Option<Point3<T>> {
    let [(pa, va), (pb, vb)] = views;
    let (na, nb) = (normalized.get(va)?.as_ref()?, normalized.get(vb)?.as_ref()?);
    let (ua, ub) = (track.get(va)?.as_ref()?, track.get(vb)?.as_ref()?);
    let t = triangulate_optimal(pa, pb, na, nb).ok()?;
    if !above(config.max_depth, t.depth1.max(t.depth2)) {
        return None;
    }
    // Parallax: the angle between the two rays at the point.
    let ca = pa.inverse().origin_in_target_frame();
    let cb = pb.inverse().origin_in_target_frame();
    let (ra, rb) = (t.point - ca, t.point - cb);
    let cos = ra.dot(&rb) / (ra.norm() * rb.norm());
    if !above(config.min_parallax.cos(), cos) {
        return None;
    }
    for (p, u) in [(pa, ua), (pb, ub)] {
        let e = (camera.project(p, &t.point).ok()? - u).norm();
        if !above(config.max_reprojection_px, e) {
            return None;
        }
    }
    Some(t.point)
}
