//! `camgeom sfm`: three-view structure from motion on three images of one calibrated camera.
//!
//! 1. ORB features of each image ([`camgeom::features::orb::orb_detect`], default settings),
//!    matched pairwise with cross-check (`A-B`, `B-C`, `A-C`, as `camgeom homography --images`);
//! 2. tracks: every `A-B` match, extended to `C` through its `B-C` match (dropped there if the
//!    direct `A-C` match disagrees), then the `B-C` and `A-C` matches not yet in a track;
//! 3. [`camgeom::sfm::reconstruct_three_views`] (without its bundle adjustment): `E` of views
//!    A-B (5-point RANSAC) and the cheirality test, triangulation, PnP of view C, triangulation
//!    of the new tracks; then [`camgeom::sfm::bundle_adjust`] of every pose but the first and
//!    every point (lens distortion is modelled: observations are raw pixels), with the mean and
//!    RMS reprojection error over the used observations before and after;
//! 4. writes `DIR/points.ply` (ASCII PLY: the points in grey, then the three camera centres in
//!    red, green, blue), `DIR/plot.png` (top-down `X-Z` and side `Z-Y` orthographic views of the
//!    points and cameras, each camera with its viewing direction) and prints a JSON summary.
//!
//! The world frame is view A's camera frame (`x` right, `y` down, `z` forward); the unit is the
//! A-B baseline.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use camgeom::camera::Camera;
use camgeom::features::orb::Feature;
use camgeom::nalgebra::{Point2, Point3, Vector3};
use camgeom::sfm::{
    PointBlock, SfmConfig, SfmWorkspace, Track, bundle_adjust, reconstruct_three_views,
};
use camgeom::transform::Pose;
use camgeom_host::cli::args::CameraArg;
use camgeom_host::cli::files::{create_dir, write_file};
use camgeom_host::cli::matches::{cross_check, orb_features};
use camgeom_host::points::to_json;
use camgeom_host::rgb::{Overlay, RgbImage};
use camgeom_host::{Error, Result, load_camera};
use clap::Args;
use serde::Serialize;

/// Most tracks (three images of at most 500 ORB features each give fewer).
const MAX_TRACKS: usize = 1024;

#[derive(Args, Debug)]
pub struct SfmArgs {
    /// Three images of a static scene from one camera (PNG, JPEG; read as grey), in order.
    #[arg(long, num_args = 3, value_names = ["A.png", "B.png", "C.png"], required = true)]
    pub images: Vec<PathBuf>,
    #[command(flatten)]
    pub camera: CameraArg,
    /// Output directory (created): `points.ply` and `plot.png`.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Inlier threshold of the A-B essential matrix, pixels (Sampson distance).
    #[arg(long, value_name = "PX", default_value_t = 1.0)]
    pub threshold: f64,
    /// Inlier threshold of the PnP registration of view C, pixels (reprojection error).
    #[arg(long, value_name = "PX", default_value_t = 2.0)]
    pub pnp_threshold: f64,
    /// Seed of both RANSAC samplers.
    #[arg(long, value_name = "SEED", default_value_t = camgeom::ransac::RansacConfig::<f64>::default().seed)]
    pub seed: u64,
    /// Levenberg-Marquardt steps of the bundle adjustment (0 skips it).
    #[arg(long, value_name = "N", default_value_t = 20)]
    pub bundle_iterations: u8,
}

/// One camera of the summary.
#[derive(Serialize, Debug)]
pub struct View {
    /// The image file.
    pub image: String,
    /// ORB features detected.
    pub features: usize,
    /// World-to-camera rotation, row-major.
    #[serde(rename = "R")]
    pub r: [f64; 9],
    /// World-to-camera translation.
    pub t: [f64; 3],
    /// Camera centre in the world frame, `-Rᵀ t`.
    pub center: [f64; 3],
}

/// The JSON summary.
#[derive(Serialize, Debug)]
pub struct SfmOutput {
    /// The three views.
    pub views: Vec<View>,
    /// Cross-checked matches per pair: `[A-B, B-C, A-C]`.
    pub matches: [usize; 3],
    /// Tracks given to the reconstruction (seen by at least two views).
    pub tracks: usize,
    /// Tracks seen by all three views.
    pub tracks_in_three: usize,
    /// Reconstructed points.
    pub points: usize,
    /// Inliers of the A-B essential matrix after cheirality.
    pub initial_inliers: usize,
    /// Inliers of the PnP registration of view C.
    pub pnp_inliers: usize,
    /// Points added from view C.
    pub new_points: usize,
    /// Observations in the bundle adjustment.
    pub observations: usize,
    /// Mean reprojection error over those observations before the bundle adjustment, pixels.
    pub reprojection_mean_before_px: f64,
    /// The same after.
    pub reprojection_mean_after_px: f64,
    /// RMS reprojection error over those observations before the bundle adjustment, pixels.
    pub reprojection_rms_before_px: f64,
    /// The same after.
    pub reprojection_rms_after_px: f64,
    /// Levenberg-Marquardt steps taken.
    pub bundle_iterations: u8,
    /// The files written.
    pub ply: String,
    /// The plot.
    pub plot: String,
}

/// Tracks of features `(a, b, c)` (indices) from the pairwise matches (step 2 of the module
/// docs); every feature is in at most one track.
pub fn build_tracks(
    ab: &[(usize, usize)],
    bc: &[(usize, usize)],
    ac: &[(usize, usize)],
) -> Vec<[Option<usize>; 3]> {
    use std::collections::{HashMap, HashSet};
    let bc_map: HashMap<usize, usize> = bc.iter().copied().collect();
    let ac_map: HashMap<usize, usize> = ac.iter().copied().collect();
    let mut used = [HashSet::new(), HashSet::new(), HashSet::new()];
    let mut tracks = Vec::new();
    let mut push = |t: [Option<usize>; 3], tracks: &mut Vec<[Option<usize>; 3]>| {
        if t.iter()
            .zip(used.iter())
            .any(|(i, u)| i.is_some_and(|i| u.contains(&i)))
        {
            return;
        }
        for (i, u) in t.iter().zip(used.iter_mut()) {
            if let Some(i) = i {
                u.insert(*i);
            }
        }
        tracks.push(t);
    };
    for &(a, b) in ab {
        let c = bc_map
            .get(&b)
            .copied()
            .filter(|c| ac_map.get(&a).is_none_or(|c2| c2 == c));
        push([Some(a), Some(b), c], &mut tracks);
    }
    for &(b, c) in bc {
        push([None, Some(b), Some(c)], &mut tracks);
    }
    for &(a, c) in ac {
        push([Some(a), None, Some(c)], &mut tracks);
    }
    tracks
}

/// Runs the subcommand: writes the files, returns the JSON summary.
pub fn run(a: &SfmArgs) -> Result<String> {
    let [ia, ib, ic] = a.images.as_slice() else {
        return Err(Error::usage("--images takes three files"));
    };
    let mut config = SfmConfig::<f64>::default();
    config.essential.threshold = a.threshold;
    config.essential.seed = a.seed;
    config.pnp.threshold = a.pnp_threshold;
    config.pnp.seed = a.seed;
    // The bundle adjustment runs below, on its own, so that its effect can be measured.
    config.bundle_iterations = 0;
    let params = config
        .check()
        .map_err(|e| Error::camgeom("sfm configuration (--threshold, --pnp-threshold)", e))?;
    let spec = load_camera(&a.camera.intrinsics)?;
    let feats = [orb_features(ia)?, orb_features(ib)?, orb_features(ic)?];
    let [fa, fb, fc] = &feats;
    let ab = cross_check(fa, fb, "A-B")?;
    let bc = cross_check(fb, fc, "B-C")?;
    let ac = cross_check(fa, fc, "A-C")?;
    let mut ids = build_tracks(&ab, &bc, &ac);
    ids.truncate(MAX_TRACKS);
    let point = |f: &Feature| Point2::new(f64::from(f.keypoint.x), f64::from(f.keypoint.y));
    let tracks: Vec<Track<f64>> = ids
        .iter()
        .map(|t| core::array::from_fn(|v| t[v].and_then(|i| feats[v].get(i)).map(point)))
        .collect();
    let mut ws: Box<SfmWorkspace<f64, MAX_TRACKS>> = Box::default();
    let source = format!("{} {} {}", ia.display(), ib.display(), ic.display());
    let r = reconstruct_three_views(&spec.camera, &tracks, &params, &mut ws).map_err(|e| {
        let what = format!(
            "{source}: reconstruct_three_views failed on {} tracks",
            tracks.len()
        );
        Error::camgeom(what, e)
    })?;
    let n = tracks.len();
    let mut poses = r.poses;
    let mean_before = mean_error(&spec.camera, &poses, &tracks, &ws.points, &ws.used);
    let mut blocks = vec![PointBlock::<f64>::default(); n];
    let bundle = bundle_adjust(
        &spec.camera,
        &mut poses,
        &mut ws.points[..n],
        &tracks,
        &ws.used[..n],
        &mut blocks,
        a.bundle_iterations,
    )
    .map_err(|e| Error::camgeom(format!("{source}: bundle_adjust failed"), e))?;
    let mean_after = mean_error(&spec.camera, &poses, &tracks, &ws.points, &ws.used);
    let points: Vec<Point3<f64>> = ws.points.iter().take(n).flatten().copied().collect();
    let views: Vec<View> = poses
        .iter()
        .zip([ia, ib, ic])
        .zip(&feats)
        .map(|((p, path), f)| {
            let m = p.rotation().into_inner();
            let t = p.translation();
            let c = p.camera_center();
            View {
                image: path.display().to_string(),
                features: f.len(),
                r: [
                    m.m11, m.m12, m.m13, m.m21, m.m22, m.m23, m.m31, m.m32, m.m33,
                ],
                t: [t.x, t.y, t.z],
                center: [c.x, c.y, c.z],
            }
        })
        .collect();
    create_dir(&a.out)?;
    let ply = a.out.join("points.ply");
    let plot = a.out.join("plot.png");
    write_ply(&ply, &points, &views)?;
    write_plot(&plot, &points, &views)?;
    let summary = SfmOutput {
        matches: [ab.len(), bc.len(), ac.len()],
        tracks: tracks.len(),
        tracks_in_three: ids.iter().filter(|t| t.iter().all(Option::is_some)).count(),
        points: points.len(),
        initial_inliers: r.initial_inliers,
        pnp_inliers: r.pnp_inliers,
        new_points: r.new_points,
        observations: bundle.observations,
        reprojection_mean_before_px: mean_before,
        reprojection_mean_after_px: mean_after,
        reprojection_rms_before_px: bundle.initial_rms_px,
        reprojection_rms_after_px: bundle.final_rms_px,
        bundle_iterations: bundle.iterations,
        views,
        ply: ply.display().to_string(),
        plot: plot.display().to_string(),
    };
    Ok(to_json(&summary))
}

/// Mean pixel reprojection error (through the lens model) of the used observations of the
/// reconstructed tracks; an observation that does not project is skipped (the bundle
/// adjustment refuses such a start anyway).
fn mean_error(
    camera: &Camera<f64>,
    poses: &[Pose<f64>; 3],
    tracks: &[Track<f64>],
    points: &[Option<Point3<f64>>],
    used: &[[bool; 3]],
) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for ((track, point), used) in tracks.iter().zip(points).zip(used) {
        let Some(x) = point else { continue };
        for ((obs, pose), u) in track.iter().zip(poses).zip(used) {
            if let (Some(obs), true) = (obs, u)
                && let Ok(p) = camera.project(pose, x)
            {
                sum += (p - obs).norm();
                count += 1;
            }
        }
    }
    if count == 0 { 0.0 } else { sum / count as f64 }
}

/// The colours of the three cameras: red, green, blue.
const CAMERA_RGB: [[u8; 3]; 3] = [[230, 40, 40], [40, 180, 40], [40, 90, 230]];

/// ASCII PLY: `x y z red green blue` per vertex, the points (grey) then the camera centres.
fn write_ply(path: &Path, points: &[Point3<f64>], views: &[View]) -> Result<()> {
    let mut s = String::new();
    let n = points.len() + views.len();
    let _ = write!(
        s,
        "ply\nformat ascii 1.0\ncomment camgeom sfm: {} points, then {} camera centres (red, green, blue)\n\
         element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        points.len(),
        views.len()
    );
    for p in points {
        let _ = writeln!(s, "{} {} {} 160 160 160", p.x, p.y, p.z);
    }
    for (v, [r, g, b]) in views.iter().zip(CAMERA_RGB) {
        let [x, y, z] = v.center;
        let _ = writeln!(s, "{x} {y} {z} {r} {g} {b}");
    }
    write_file(path, s)
}

/// Bresenham's line from `(x0, y0)` to `(x1, y1)`, clipped to the image.
fn draw_line(img: &mut RgbImage, (mut x0, mut y0): (i64, i64), (x1, y1): (i64, i64), c: [u8; 3]) {
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let mut err = dx + dy;
    for _ in 0..=(dx - dy).min(1 << 16) {
        img.put(x0, y0, c);
        if x0 == x1 && y0 == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x0 += sx;
        }
        if e2 <= dx {
            err += dx;
            y0 += sy;
        }
    }
}

/// A filled disc of radius `r` around `(x, y)`, clipped to the image.
fn draw_disc(img: &mut RgbImage, (x, y): (i64, i64), r: i64, c: [u8; 3]) {
    for j in -r..=r {
        for i in -r..=r {
            if i * i + j * j <= r * r {
                img.put(x + i, y + j, c);
            }
        }
    }
}

/// Two orthographic panels side by side: top-down (`X` right, `Z` up) and side (`Z` right,
/// `-Y` up, so the camera's up is up), each fitted to the points' 2nd..98th percentiles and the
/// cameras; cameras as discs with a line along their optical axis.
fn write_plot(path: &Path, points: &[Point3<f64>], views: &[View]) -> Result<()> {
    const PANEL: u32 = 480;
    const MARGIN: f64 = 24.0;
    let mut canvas = RgbImage::from_pixel(2 * PANEL, PANEL, image::Rgb([255, 255, 255]));
    // Panel axes: (horizontal, vertical-up) as functions of a world point.
    type Axis = fn(&Vector3<f64>) -> (f64, f64);
    let panels: [Axis; 2] = [|p| (p.x, p.z), |p| (p.z, -p.y)];
    let centres: Vec<Vector3<f64>> = views.iter().map(|v| Vector3::from(v.center)).collect();
    // Optical axes: the third row of R is the viewing direction in the world frame.
    let axes: Vec<Vector3<f64>> = views
        .iter()
        .map(|v| Vector3::new(v.r[6], v.r[7], v.r[8]))
        .collect();
    for (k, proj) in panels.iter().enumerate() {
        let pts: Vec<(f64, f64)> = points.iter().map(|p| proj(&p.coords)).collect();
        let cams: Vec<(f64, f64)> = centres.iter().map(proj).collect();
        let range = |sel: fn(&(f64, f64)) -> f64| {
            let mut v: Vec<f64> = pts.iter().map(sel).collect();
            v.sort_by(f64::total_cmp);
            let lo = v.get(v.len() / 50).copied();
            let hi = v
                .get(v.len() - v.len() / 50 - usize::from(!v.is_empty()))
                .copied();
            cams.iter()
                .map(sel)
                .chain(lo)
                .chain(hi)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(x), b.max(x))
                })
        };
        let ((h0, h1), (v0, v1)) = (range(|p| p.0), range(|p| p.1));
        let span = (h1 - h0).max(v1 - v0).max(1e-9);
        let scale = (f64::from(PANEL) - 2.0 * MARGIN) / span;
        let x_off = f64::from(PANEL) * k as f64;
        let to_px = |(h, v): (f64, f64)| {
            (
                (x_off + MARGIN + (h - h0) * scale + (span - (h1 - h0)) * scale / 2.0) as i64,
                (f64::from(PANEL) - MARGIN - (v - v0) * scale - (span - (v1 - v0)) * scale / 2.0)
                    as i64,
            )
        };
        for p in &pts {
            draw_disc(&mut canvas, to_px(*p), 1, [90, 90, 90]);
        }
        for ((c, axis), rgb) in centres.iter().zip(&axes).zip(CAMERA_RGB) {
            let tip = c + axis * (0.15 * span);
            draw_line(&mut canvas, to_px(proj(c)), to_px(proj(&tip)), rgb);
            draw_disc(&mut canvas, to_px(proj(c)), 4, rgb);
        }
    }
    // Panel separator.
    draw_line(
        &mut canvas,
        (i64::from(PANEL), 0),
        (i64::from(PANEL), i64::from(PANEL) - 1),
        [0, 0, 0],
    );
    canvas.save_png(path)
}
