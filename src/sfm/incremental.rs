//! Incremental structure from motion over any number of views of one calibrated camera, in
//! caller-owned memory.
//!
//! 1. Every observation is undistorted once to normalised coordinates.
//! 2. The initial pair ([`super::initial_pair`]): the most covisible pairs are tried; the best
//!    one that determines a relative pose starts the reconstruction (world = its first view,
//!    unit = its baseline), or the reconstruction is refused with the reason.
//! 3. Its tracks are triangulated, then bundle adjusted.
//! 4. Repeatedly, the unregistered view that sees the most reconstructed points is registered
//!    by PnP-RANSAC on its 2D-3D correspondences, if enough of them agree (count and ratio);
//!    else it is refused with the reason, and tried again only once more points see it. The
//!    tracks it shares with registered views are triangulated (the widest pair of rays, checked
//!    for depth, angle and reprojection error in every registered view); a bundle adjustment
//!    follows ([`bundle_adjust_views`]): global (every view and point) when the registered
//!    views have grown by [`IncrementalConfig::global_growth`](super::IncrementalConfig) since
//!    the last global one, else local (the new view and the
//!    [`local_views`](super::IncrementalConfig) - 1 views sharing the most tracks with it, and
//!    the points they see), then observations whose
//!    reprojection error exceeds the bound are dropped, observations of reconstructed points
//!    that the refined poses now explain are taken back, and points left with fewer than two
//!    observations or too small an angle go.
//! 5. A final, longer bundle adjustment and filtering; each view's inliers and RMS error.
//!
//! A view is never given a pose the data does not determine: it is registered only with the
//! configured number and ratio of PnP inliers, and a view whose observations do not survive the
//! refinement loses its pose again ([`ViewRefusal::LostInRefinement`]).

use nalgebra::{Point2, Point3};

use super::bundle_views::{BundleSettings, Gauge, ViewsBundleReport, bundle_adjust_views};
use super::incremental_config::IncrementalParams;
use super::initial_pair::{choose, covisibility};
use super::scene::{InitialRefusal, Scene, ViewRefusal, ViewResult, ViewState, Workspace};
use super::track_set::TrackSet;
use crate::camera::Camera;
use crate::pose::solve_pnp_ransac;
use crate::scalar::{Real, above};
use crate::transform::Pose;
use crate::twoview::triangulate_optimal;
use crate::{Error, Result};

/// What [`reconstruct`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Reconstruction<T: Real = f32> {
    /// The initial pair, or why there is none (then nothing else was done).
    pub initial: core::result::Result<(u16, u16), InitialRefusal<T>>,
    /// Inliers of the initial pair's essential matrix.
    pub initial_inliers: u32,
    /// Views with a pose.
    pub registered: usize,
    /// Reconstructed points.
    pub points: usize,
    /// Used observations.
    pub observations: usize,
    /// RMS reprojection error of the used observations, pixels.
    pub rms_px: T,
    /// The final bundle adjustment.
    pub bundle: Option<ViewsBundleReport<T>>,
}

/// Reconstructs the views and points of `tracks` (see the module docs) into `scene`.
///
/// Errors (bad input only; data that does not determine a reconstruction is an `Ok` with the
/// reason in [`Reconstruction::initial`] and each view's [`ViewResult::state`]):
/// [`Error::LengthMismatch`] for `scene` slices that are not one per view, track and
/// observation; [`Error::BufferTooSmall`] for `ws`.
pub fn reconstruct<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    params: &IncrementalParams<T>,
    scene: &mut Scene<'_, T>,
    ws: &mut Workspace<'_, T>,
) -> Result<Reconstruction<T>> {
    let (views, n_tracks, n_obs) = (tracks.views(), tracks.len(), tracks.observations().len());
    scene.check(views, n_tracks, n_obs)?;
    ws.check(views, n_tracks, n_obs)?;
    let config = params.config();
    scene.poses.iter_mut().for_each(|p| *p = None);
    scene
        .views
        .iter_mut()
        .for_each(|v| *v = ViewResult::default());
    scene.points.iter_mut().for_each(|p| *p = None);
    scene.used.iter_mut().for_each(|u| *u = false);
    ws.tried.iter_mut().for_each(|t| *t = 0);
    // 1.
    for (n, o) in ws.normalized.iter_mut().zip(tracks.observations()) {
        *n = camera.undistort_to_normalized(&o.pixel).ok();
    }
    // 2.
    covisibility(tracks, ws.normalized, ws.covisibility);
    let mut out = Reconstruction {
        initial: Err(InitialRefusal::NoSharedTracks),
        initial_inliers: 0,
        registered: 0,
        points: 0,
        observations: 0,
        rms_px: T::zero(),
        bundle: None,
    };
    let pair = match choose(camera, tracks, params, ws) {
        Ok(p) => p,
        Err(r) => {
            out.initial = Err(r);
            return Ok(out);
        }
    };
    out.initial = Ok(pair.views);
    out.initial_inliers = pair.inliers;
    let (a, b) = (usize::from(pair.views.0), usize::from(pair.views.1));
    let gauge = Gauge {
        anchor: pair.views.0,
        scale: pair.views.1,
    };
    set_registered(scene, a, Pose::identity());
    set_registered(scene, b, pair.pose);
    // 3.
    triangulate_new(camera, tracks, config, scene, ws);
    let iterations = config.bundle_iterations;
    refine(camera, tracks, params, scene, ws, gauge, iterations, None)?;
    let mut last_global = 2usize;
    // 4. Each round registers a view or records a refusal at a count that must grow before
    // the view is tried again, so `4 views` rounds bound the loop.
    for _ in 0..4 * views {
        let Some((v, found)) = next_view(tracks, scene, ws) else {
            break;
        };
        match register(camera, tracks, params, scene, ws, v, found) {
            Ok(()) => {
                triangulate_new(camera, tracks, config, scene, ws);
                let registered = scene.poses.iter().filter(|p| p.is_some()).count();
                let grown =
                    T::lit(registered as f64) >= config.global_growth * T::lit(last_global as f64);
                let local = if grown {
                    last_global = registered;
                    None
                } else {
                    Some(v)
                };
                refine(camera, tracks, params, scene, ws, gauge, iterations, local)?;
            }
            Err(r) => {
                if let Some(t) = ws.tried.get_mut(v) {
                    *t = found;
                }
                if let Some(s) = scene.views.get_mut(v) {
                    s.state = ViewState::Refused(r);
                }
            }
        }
    }
    // 5.
    triangulate_new(camera, tracks, config, scene, ws);
    out.bundle = refine(
        camera,
        tracks,
        params,
        scene,
        ws,
        gauge,
        config.final_bundle_iterations,
        None,
    )?;
    drop_weak_views(tracks, config.min_registration_inliers, scene, gauge);
    filter(camera, tracks, config, scene);
    // Statistics.
    let (mut sq_all, mut n_all) = (T::zero(), 0usize);
    for i in 0..n_tracks {
        let Some(x) = scene.points.get(i).copied().flatten() else {
            continue;
        };
        let range = tracks.range(i);
        for (o, &u) in tracks
            .track(i)
            .iter()
            .zip(scene.used.get(range).unwrap_or(&[]))
        {
            let view = usize::from(o.view);
            let (true, Some(Some(pose))) = (u, scene.poses.get(view)) else {
                continue;
            };
            let Ok(p) = camera.project(pose, &x) else {
                continue;
            };
            let e2 = (p - o.pixel).norm_squared();
            if let Some(r) = scene.views.get_mut(view) {
                r.inliers += 1;
                r.rms_px += e2;
            }
            sq_all += e2;
            n_all += 1;
        }
    }
    // Views the loop never tried saw too few reconstructed points to be (count them now).
    let needed = config.min_registration_inliers;
    for (v, r) in scene.views.iter_mut().enumerate() {
        if r.state == ViewState::Refused(ViewRefusal::NotReached) {
            let found = (0..n_tracks)
                .filter(|&i| matches!(scene.points.get(i), Some(Some(_))))
                .filter(|&i| tracks.track(i).iter().any(|o| usize::from(o.view) == v))
                .count() as u32;
            r.state = ViewState::Refused(ViewRefusal::TooFewCorrespondences { found, needed });
        }
    }
    for r in scene.views.iter_mut() {
        if r.inliers > 0 {
            r.rms_px = (r.rms_px / T::lit(f64::from(r.inliers))).sqrt();
        }
    }
    out.registered = scene.poses.iter().filter(|p| p.is_some()).count();
    out.points = scene.points.iter().filter(|p| p.is_some()).count();
    out.observations = n_all;
    out.rms_px = if n_all > 0 {
        (sq_all / T::lit(n_all as f64)).sqrt()
    } else {
        T::zero()
    };
    Ok(out)
}

fn set_registered<T: Real>(scene: &mut Scene<'_, T>, v: usize, pose: Pose<T>) {
    if let (Some(p), Some(r)) = (scene.poses.get_mut(v), scene.views.get_mut(v)) {
        *p = Some(pose);
        r.state = ViewState::Registered;
    }
}

/// The unregistered view with the most 2D-3D correspondences, if that count grew since its
/// last refusal: `(view, count)`.
fn next_view<T: Real>(
    tracks: &TrackSet<'_, T>,
    scene: &Scene<'_, T>,
    ws: &mut Workspace<'_, T>,
) -> Option<(usize, u32)> {
    let views = tracks.views();
    let counts = ws.counts.get_mut(..views)?;
    counts.iter_mut().for_each(|c| *c = 0);
    for i in 0..tracks.len() {
        if scene.points.get(i).copied().flatten().is_none() {
            continue;
        }
        let range = tracks.range(i);
        for (o, n) in tracks
            .track(i)
            .iter()
            .zip(ws.normalized.get(range).unwrap_or(&[]))
        {
            let v = usize::from(o.view);
            if n.is_some()
                && matches!(scene.poses.get(v), Some(None))
                && let Some(c) = counts.get_mut(v)
            {
                *c += 1;
            }
        }
    }
    counts
        .iter()
        .zip(ws.tried.iter())
        .enumerate()
        .filter(|(_, (c, t))| **c > **t)
        .max_by_key(|(_, (c, _))| **c)
        .map(|(v, (c, _))| (v, *c))
}

/// PnP-RANSAC registration of view `v` on its 2D-3D correspondences (`found` of them).
fn register<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    params: &IncrementalParams<T>,
    scene: &mut Scene<'_, T>,
    ws: &mut Workspace<'_, T>,
    v: usize,
    found: u32,
) -> core::result::Result<(), ViewRefusal> {
    let config = params.config();
    let needed = config.min_registration_inliers;
    if found < needed {
        return Err(ViewRefusal::TooFewCorrespondences { found, needed });
    }
    let mut m = 0usize;
    for i in 0..tracks.len() {
        let Some(x) = scene.points.get(i).copied().flatten() else {
            continue;
        };
        let range = tracks.range(i);
        let start = range.start;
        for (k, (o, n)) in tracks
            .track(i)
            .iter()
            .zip(ws.normalized.get(range).unwrap_or(&[]))
            .enumerate()
        {
            if usize::from(o.view) == v
                && n.is_some()
                && let (Some(w), Some(p), Some(idx)) = (
                    ws.world.get_mut(m),
                    ws.first.get_mut(m),
                    ws.index.get_mut(m),
                )
            {
                *w = x;
                *p = o.pixel;
                *idx = (start + k) as u32;
                m += 1;
            }
        }
    }
    let (Some(world), Some(pixels), Some(scratch), Some(mask)) = (
        ws.world.get(..m),
        ws.first.get(..m),
        ws.second.get_mut(..m),
        ws.mask.get_mut(..m),
    ) else {
        return Err(ViewRefusal::NoPose);
    };
    let Ok((est, report)) = solve_pnp_ransac(camera, world, pixels, scratch, params.pnp(), mask)
    else {
        return Err(ViewRefusal::NoPose);
    };
    let inliers = report.inliers as u32;
    let ratio_ok = T::lit(f64::from(inliers)) >= config.min_inlier_ratio * T::lit(m as f64);
    if inliers < needed || !ratio_ok {
        return Err(ViewRefusal::TooFewInliers {
            inliers,
            correspondences: m as u32,
        });
    }
    set_registered(scene, v, est.pose);
    for (&idx, &inlier) in ws.index.iter().zip(ws.mask.iter()).take(m) {
        if inlier && let Some(u) = scene.used.get_mut(idx as usize) {
            *u = true;
        }
    }
    Ok(())
}

/// The angle between the rays of two views to `x`, radians.
fn ray_angle<T: Real>(ca: &Point3<T>, cb: &Point3<T>, x: &Point3<T>) -> T {
    let (ra, rb) = (x - ca, x - cb);
    let cos = ra.dot(&rb) / (ra.norm() * rb.norm());
    if cos.finite() {
        cos.clamp(-T::one(), T::one()).acos()
    } else {
        T::zero()
    }
}

/// Triangulates every track without a point that two registered views see (module docs,
/// step 4), marking the observations it keeps as used.
fn triangulate_new<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    config: &super::IncrementalConfig<T>,
    scene: &mut Scene<'_, T>,
    ws: &Workspace<'_, T>,
) {
    for i in 0..tracks.len() {
        if !matches!(scene.points.get(i), Some(None)) {
            continue;
        }
        let range = tracks.range(i);
        let obs = tracks.track(i);
        let norm = ws.normalized.get(range.clone()).unwrap_or(&[]);
        // The pair of registered observations whose viewing directions differ most.
        let mut best: Option<(T, usize, usize)> = None;
        let dir = |k: usize| -> Option<(Pose<T>, nalgebra::Vector3<T>, Point2<T>)> {
            let o = obs.get(k)?;
            let n = (*norm.get(k)?)?;
            let pose = (*scene.poses.get(usize::from(o.view))?)?;
            let d = pose.rotation().inverse() * nalgebra::Vector3::new(n.x, n.y, T::one());
            Some((pose, d.normalize(), n))
        };
        for ka in 0..obs.len() {
            let Some((_, da, _)) = dir(ka) else { continue };
            for kb in ka + 1..obs.len() {
                let Some((_, db, _)) = dir(kb) else { continue };
                let c = da.dot(&db);
                if best.is_none_or(|(bc, _, _)| c < bc) {
                    best = Some((c, ka, kb));
                }
            }
        }
        let Some((_, ka, kb)) = best else { continue };
        let (Some((pa, _, na)), Some((pb, _, nb))) = (dir(ka), dir(kb)) else {
            continue;
        };
        let Ok(t) = triangulate_optimal(&pa, &pb, &na, &nb) else {
            continue;
        };
        if !above(config.max_depth, t.depth1.max(t.depth2)) {
            continue;
        }
        let angle = ray_angle(&pa.camera_center(), &pb.camera_center(), &t.point);
        if angle < config.min_triangulation_angle {
            continue;
        }
        // Keep the observations it explains; a point needs two.
        let poses: &[Option<Pose<T>>] = scene.poses;
        let explained = |k: usize, o: &super::Observation<T>| {
            matches!(norm.get(k), Some(Some(_)))
                && poses
                    .get(usize::from(o.view))
                    .copied()
                    .flatten()
                    .and_then(|p| camera.project(&p, &t.point).ok())
                    .is_some_and(|u| above(config.max_reprojection_px, (u - o.pixel).norm()))
        };
        if obs
            .iter()
            .enumerate()
            .filter(|&(k, o)| explained(k, o))
            .count()
            < 2
        {
            continue;
        }
        for (k, o) in obs.iter().enumerate() {
            if let Some(u) = scene.used.get_mut(range.start + k) {
                *u = explained(k, o);
            }
        }
        if let Some(p) = scene.points.get_mut(i) {
            *p = Some(t.point);
        }
    }
}

/// Bundle adjustment of everything, then [`filter`]. `None` when the adjustment could not run
/// (no observation), which leaves the scene as it was.
#[allow(clippy::too_many_arguments)]
fn refine<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    params: &IncrementalParams<T>,
    scene: &mut Scene<'_, T>,
    ws: &mut Workspace<'_, T>,
    gauge: Gauge,
    iterations: u8,
    local: Option<usize>,
) -> Result<Option<ViewsBundleReport<T>>> {
    let config = params.config();
    choose_free(scene.poses, config.local_views, local, ws);
    filter(camera, tracks, config, scene);
    let report = match bundle_adjust_views(
        camera,
        tracks,
        scene.poses,
        scene.points,
        scene.used,
        &BundleSettings {
            gauge,
            loss_px: config.loss_px,
            max_iterations: iterations,
        },
        &mut ws.bundle,
    ) {
        Ok(r) => Some(r),
        Err(Error::TooFewPoints | Error::BehindCamera) => None,
        Err(e) => return Err(e),
    };
    complete(camera, tracks, config, scene);
    filter(camera, tracks, config, scene);
    Ok(report)
}

/// Marks the views a bundle adjustment moves: every one (`local` is `None`), or view `local`
/// and the `local_views - 1` registered views that share the most tracks with it.
fn choose_free<T: Real>(
    poses: &[Option<Pose<T>>],
    local_views: u16,
    local: Option<usize>,
    ws: &mut Workspace<'_, T>,
) {
    let views = poses.len();
    let free = &mut *ws.bundle.free;
    let Some(v) = local else {
        free.iter_mut().for_each(|f| *f = true);
        return;
    };
    free.iter_mut().for_each(|f| *f = false);
    if let Some(f) = free.get_mut(v) {
        *f = true;
    }
    let covisibility = &*ws.covisibility;
    let shared = |w: usize| {
        let (a, b) = if v < w { (v, w) } else { (w, v) };
        covisibility.get(a * views + b).copied().unwrap_or(0)
    };
    for _ in 1..local_views {
        let best = (0..views)
            .filter(|&w| {
                !free.get(w).copied().unwrap_or(true) && matches!(poses.get(w), Some(Some(_)))
            })
            .max_by_key(|&w| shared(w));
        match best {
            Some(w) if shared(w) > 0 => {
                if let Some(f) = free.get_mut(w) {
                    *f = true;
                }
            }
            _ => break,
        }
    }
}

/// Takes back the unused observations of reconstructed points in registered views that the
/// refined point and pose now explain (COLMAP's track completion): an observation rejected
/// under an early, rougher pose constrains the next adjustment once it fits.
fn complete<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    config: &super::IncrementalConfig<T>,
    scene: &mut Scene<'_, T>,
) {
    for i in 0..tracks.len() {
        let Some(x) = scene.points.get(i).copied().flatten() else {
            continue;
        };
        let range = tracks.range(i);
        for (k, o) in tracks.track(i).iter().enumerate() {
            let Some(u) = scene.used.get_mut(range.start + k) else {
                continue;
            };
            if *u {
                continue;
            }
            *u = scene
                .poses
                .get(usize::from(o.view))
                .copied()
                .flatten()
                .and_then(|p| camera.project(&p, &x).ok())
                .is_some_and(|p| above(config.max_reprojection_px, (p - o.pixel).norm()));
        }
    }
}

/// Drops used observations whose reprojection error exceeds the bound (or that do not project),
/// then points with fewer than two used observations or whose widest pair of rays is narrower
/// than the smallest triangulation angle.
fn filter<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    config: &super::IncrementalConfig<T>,
    scene: &mut Scene<'_, T>,
) {
    for i in 0..tracks.len() {
        let range = tracks.range(i);
        let obs = tracks.track(i);
        let Some(x) = scene.points.get(i).copied().flatten() else {
            if let Some(u) = scene.used.get_mut(range) {
                u.iter_mut().for_each(|u| *u = false);
            }
            continue;
        };
        let mut kept = 0usize;
        let mut widest = T::zero();
        for (k, o) in obs.iter().enumerate() {
            let Some(u) = scene.used.get_mut(range.start + k) else {
                continue;
            };
            let pose = scene.poses.get(usize::from(o.view)).copied().flatten();
            let ok = *u
                && pose
                    .and_then(|p| camera.project(&p, &x).ok())
                    .is_some_and(|p| above(config.max_reprojection_px, (p - o.pixel).norm()));
            *u = ok;
            if !ok {
                continue;
            }
            kept += 1;
            let Some(pa) = pose else { continue };
            for (kb, ob) in obs.iter().enumerate().take(k) {
                if !scene.used.get(range.start + kb).copied().unwrap_or(false) {
                    continue;
                }
                if let Some(Some(pb)) = scene.poses.get(usize::from(ob.view)) {
                    widest = widest.max(ray_angle(&pa.camera_center(), &pb.camera_center(), &x));
                }
            }
        }
        if kept < 2 || widest < config.min_triangulation_angle {
            if let Some(p) = scene.points.get_mut(i) {
                *p = None;
            }
            if let Some(u) = scene.used.get_mut(range) {
                u.iter_mut().for_each(|u| *u = false);
            }
        }
    }
}

/// Views (other than the gauge pair) left with fewer used observations than a registration
/// needs lose their pose: nothing determines it any more.
fn drop_weak_views<T: Real>(
    tracks: &TrackSet<'_, T>,
    needed: u32,
    scene: &mut Scene<'_, T>,
    gauge: Gauge,
) {
    for v in 0..tracks.views() {
        if v == usize::from(gauge.anchor) || v == usize::from(gauge.scale) {
            continue;
        }
        if !matches!(scene.poses.get(v), Some(Some(_))) {
            continue;
        }
        let kept = tracks
            .observations()
            .iter()
            .zip(scene.used.iter())
            .filter(|(o, u)| **u && usize::from(o.view) == v)
            .count() as u32;
        if kept < needed {
            if let (Some(p), Some(r)) = (scene.poses.get_mut(v), scene.views.get_mut(v)) {
                *p = None;
                r.state = ViewState::Refused(ViewRefusal::LostInRefinement { inliers: kept });
            }
            for (o, u) in tracks.observations().iter().zip(scene.used.iter_mut()) {
                if usize::from(o.view) == v {
                    *u = false;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec;
    use std::vec::Vec;

    use nalgebra::Vector3;

    use super::*;
    use crate::camera::Intrinsics;
    use crate::sfm::{BundleScratch, IncrementalConfig, Observation, PointScratch};

    const POINTS: usize = 400;

    /// The true poses, the reconstruction's poses, its report.
    type Run = (Vec<Pose<f64>>, Vec<Option<Pose<f64>>>, Reconstruction<f64>);

    /// `views` cameras on an arc looking at a box of points, exact observations (or with
    /// `noise` px of deterministic jitter); returns the truth and the reconstruction's poses.
    fn run(views: usize, noise: f64) -> Run {
        let camera = Camera::pinhole(Intrinsics::new(800.0, 800.0, 320.0, 240.0).unwrap());
        let truth: Vec<Pose<f64>> = (0..views)
            .map(|v| {
                // Centres on an arc of 40° around (0, 0, 6), each looking at it.
                let a = 0.7 * v as f64 / views as f64;
                let c = Vector3::new(6.0 * a.sin(), 0.3 * (v % 2) as f64, 6.0 - 6.0 * a.cos());
                let r = nalgebra::Rotation3::from_euler_angles(0.0, -a, 0.0);
                Pose::new(r, -(r * c)).unwrap()
            })
            .collect();
        let mut starts = vec![0u32];
        let mut obs = Vec::new();
        let mut k = 0u64;
        for i in 0..POINTS {
            let f = |m: usize, n: usize| ((i * m) % n) as f64 / n as f64 - 0.5;
            let x = Point3::new(4.0 * f(37, 101), 3.0 * f(53, 97), 6.0 + 3.0 * f(29, 89));
            for (v, p) in truth.iter().enumerate() {
                if (i + v) % 5 == 0 {
                    continue;
                }
                if let Ok(u) = camera.project(p, &x) {
                    k = k
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let j = |s: u32| ((k >> s) & 0xffff) as f64 / 65535.0 - 0.5;
                    obs.push(Observation {
                        view: v as u16,
                        pixel: u + nalgebra::Vector2::new(j(16), j(32)) * noise,
                    });
                }
            }
            if obs.len() - *starts.last().unwrap() as usize >= 2 {
                starts.push(obs.len() as u32);
            } else {
                obs.truncate(*starts.last().unwrap() as usize);
            }
        }
        let set = TrackSet::new_checked(&starts, &obs, views).unwrap();
        let (nt, no) = (set.len(), obs.len());
        let mut poses = vec![None; views];
        let mut results = vec![ViewResult::default(); views];
        let mut points = vec![None; nt];
        let mut used = vec![false; no];
        let mut normalized = vec![None; no];
        let mut covisibility = vec![0; views * views];
        let mut tried = vec![0; views];
        let mut counts = vec![0; views];
        let mut free = vec![true; views];
        let (mut first, mut second) = (vec![Point2::origin(); nt], vec![Point2::origin(); nt]);
        let mut world = vec![Point3::origin(); nt];
        let mut index = vec![0; nt];
        let (mut mask, mut mask2) = (vec![false; nt], vec![false; nt]);
        let mut angles = vec![0.0; nt];
        let mut system = vec![0.0; BundleScratch::<f64>::system_len(views)];
        let (mut rhs, mut gradient) = (vec![0.0; 6 * views], vec![0.0; 6 * views]);
        let mut bindex = vec![0; views];
        let mut trial = vec![None; views];
        let mut coupling = vec![Default::default(); no];
        let mut pscratch = vec![PointScratch::default(); nt];
        let mut scene = Scene {
            poses: &mut poses,
            views: &mut results,
            points: &mut points,
            used: &mut used,
        };
        let mut ws = Workspace {
            normalized: &mut normalized,
            covisibility: &mut covisibility,
            tried: &mut tried,
            counts: &mut counts,
            first: &mut first,
            second: &mut second,
            world: &mut world,
            index: &mut index,
            mask: &mut mask,
            mask2: &mut mask2,
            angles: &mut angles,
            bundle: BundleScratch {
                system: &mut system,
                rhs: &mut rhs,
                gradient: &mut gradient,
                index: &mut bindex,
                free: &mut free,
                trial: &mut trial,
                coupling: &mut coupling,
                points: &mut pscratch,
            },
        };
        let params = IncrementalConfig::default().check().unwrap();
        let r = reconstruct(&camera, &set, &params, &mut scene, &mut ws).unwrap();
        (truth, poses, r)
    }

    /// Largest rotation error between every pair of views, degrees.
    fn worst_pair_error(truth: &[Pose<f64>], est: &[Option<Pose<f64>>]) -> f64 {
        let mut worst = 0.0f64;
        for i in 0..truth.len() {
            for j in i + 1..truth.len() {
                let (Some(a), Some(b)) = (est[i], est[j]) else {
                    panic!("view not registered")
                };
                let r_est = b.rotation() * a.rotation().inverse();
                let r_true = truth[j].rotation() * truth[i].rotation().inverse();
                worst = worst.max((r_est * r_true.inverse()).angle().to_degrees());
            }
        }
        worst
    }

    #[test]
    fn exact_tracks_give_the_cameras_back() {
        let (truth, poses, r) = run(8, 0.0);
        assert_eq!(r.registered, 8);
        assert!(r.rms_px < 1e-6, "{}", r.rms_px);
        let e = worst_pair_error(&truth, &poses);
        assert!(e < 1e-4, "{e}");
    }

    #[test]
    fn noisy_tracks_stay_close() {
        // ±0.5 px uniform jitter: a bundle adjustment averages it down.
        let (truth, poses, r) = run(12, 1.0);
        assert_eq!(r.registered, 12);
        assert!(r.rms_px < 0.5, "{}", r.rms_px);
        let e = worst_pair_error(&truth, &poses);
        std::println!("noisy: worst {e} deg, rms {}", r.rms_px);
        assert!(e < 0.1, "{e}");
    }
}
