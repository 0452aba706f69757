//! `camgeom pose`: the pose of a calibrated camera from 3D-2D correspondences (OpenCV's
//! `solvePnP` / `solvePnPRansac`).

use std::fmt::Debug;
use std::path::PathBuf;

use camgeom::Real;
use camgeom::camera::Camera;
use camgeom::nalgebra::{Point2, Point3};
use camgeom::pose::{PlanarConfig, PoseEstimate, solve_planar, solve_pnp, solve_pnp_ransac};
use camgeom::ransac::RansacConfig;
use camgeom_host::cli::args::CameraArg;
use camgeom_host::points::{read_csv, to_json};
use camgeom_host::{Error, ErrorKind, Result, load_camera};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct PoseArgs {
    #[command(flatten)]
    camera: CameraArg,
    /// Correspondences, CSV rows `X,Y,Z,u,v` (world point, its pixel; optional header); `-`
    /// reads stdin. All Z = 0 selects the planar solver (IPPE, both solutions, refined);
    /// otherwise EPnP + Levenberg-Marquardt.
    #[arg(long, value_name = "FILE.csv")]
    points: PathBuf,
    /// Read rows `view,X,Y,Z,u,v` (`camgeom calibrate --corners-out`) and keep view `K`'s.
    #[arg(long, value_name = "K")]
    view: Option<u32>,
    /// Robust N-point pose (P3P RANSAC with EPnP local optimisation, OpenCV's
    /// solvePnPRansac) with this inlier threshold in pixels; used for planar points too.
    #[arg(long, value_name = "PX")]
    ransac: Option<f64>,
    /// Seed of the RANSAC sampler.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Compute in f32, as the firmware does (default f64).
    #[arg(long)]
    f32: bool,
}

/// One pose of the output: `X_c = R X + t`.
#[derive(Serialize)]
struct JsonPose<T> {
    /// Rotation, row-major.
    #[serde(rename = "R")]
    r: [T; 9],
    t: [T; 3],
    /// The same rotation as OpenCV's rvec (axis times angle, radians).
    rvec: [T; 3],
    rms_px: T,
}

#[derive(Serialize)]
struct JsonResult<T> {
    #[serde(rename = "R")]
    r: [T; 9],
    t: [T; 3],
    rvec: [T; 3],
    rms_px: T,
    /// The other planar solution (planar solver only), else null.
    alternative: Option<JsonPose<T>>,
    /// `planar`, `pnp` or `pnp_ransac`.
    solver: &'static str,
    points: usize,
    /// RANSAC only: inlier count and per-point mask.
    #[serde(skip_serializing_if = "Option::is_none")]
    inliers: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    inlier_mask: Option<Vec<bool>>,
}

fn json_pose<T: Real>(e: &PoseEstimate<T>) -> JsonPose<T> {
    let r = e.pose.rotation();
    let m = r.matrix();
    let t = e.pose.translation();
    let rv = e.pose.rotation_vector();
    JsonPose {
        r: [
            m[(0, 0)],
            m[(0, 1)],
            m[(0, 2)],
            m[(1, 0)],
            m[(1, 1)],
            m[(1, 2)],
            m[(2, 0)],
            m[(2, 1)],
            m[(2, 2)],
        ],
        t: [t.x, t.y, t.z],
        rvec: [rv.x, rv.y, rv.z],
        rms_px: e.rms_px,
    }
}

/// What the core's error means for this command, in words, with the error itself: `src: no
/// pose, <why>: <name> (<what camgeom says>)`.
fn no_pose(src: &impl std::fmt::Display, e: camgeom::Error, planar: bool) -> Error {
    use camgeom::Error as E;
    let what = match e {
        E::Degenerate if planar => "the points are collinear or the plane is seen edge-on",
        E::Degenerate => {
            "the world points are (nearly) coplanar or collinear without lying on Z = 0, \
             or no pose puts them in front of the camera"
        }
        E::TooFewPoints => "too few points",
        E::BehindCamera => "the pose found puts points behind the camera",
        E::NonFinite => "a computation overflowed (points at infinity or far outside the image?)",
        E::NoConvergence => "the solver did not converge",
        _ => "the solver failed",
    };
    Error::camgeom(format!("{src}: no pose, {what}"), e)
}

/// `camgeom pose`: the JSON result.
pub fn run(a: &PoseArgs) -> Result<String> {
    let spec = load_camera(&a.camera.intrinsics)?;
    let table = match a.view {
        None => read_csv(&a.points, &["X", "Y", "Z", "u", "v"])?,
        Some(k) => {
            let mut t = read_csv(&a.points, &["view", "X", "Y", "Z", "u", "v"])?;
            let keep: Vec<bool> = t.rows.iter().map(|r| r[0] == f64::from(k)).collect();
            let mut it = keep.iter();
            t.lines.retain(|_| *it.next().unwrap_or(&false));
            t.rows.retain(|r| r[0] == f64::from(k));
            t.rows.iter_mut().for_each(|r| {
                r.remove(0);
            });
            t
        }
    };
    let n = table.rows.len();
    // 4 points: the fewest IPPE and EPnP accept (6 pose unknowns, 2 equations a point, and
    // one more point than P3P to single out its solution).
    if n < 4 {
        return Err(Error::new(
            &a.points,
            ErrorKind::Shape(format!(
                "a pose needs at least 4 points (X,Y,Z,u,v rows), found {n}"
            )),
        ));
    }
    if let Some(t) = a.ransac
        && !(t.is_finite() && t > 0.0)
    {
        return Err(Error::usage(format!(
            "--ransac must be a positive number of pixels, got {t}"
        )));
    }
    let world: Vec<Point3<f64>> = table
        .rows
        .iter()
        .map(|r| Point3::new(r[0], r[1], r[2]))
        .collect();
    let pixels: Vec<Point2<f64>> = table.rows.iter().map(|r| Point2::new(r[3], r[4])).collect();
    let out = if a.f32 {
        solve(&spec.camera_f32(), &world, &pixels, a)
    } else {
        solve(&spec.camera, &world, &pixels, a)
    }?;
    Ok(out)
}

fn solve<T: Real + Serialize>(
    camera: &Camera<T>,
    world: &[Point3<f64>],
    pixels: &[Point2<f64>],
    a: &PoseArgs,
) -> Result<String> {
    let src = a.points.display();
    let world: Vec<Point3<T>> = world
        .iter()
        .map(|p| Point3::new(T::lit(p.x), T::lit(p.y), T::lit(p.z)))
        .collect();
    let pixels: Vec<Point2<T>> = pixels
        .iter()
        .map(|p| Point2::new(T::lit(p.x), T::lit(p.y)))
        .collect();
    let n = world.len();
    let planar = world.iter().all(|p| p.z == T::zero());
    let mut scratch = vec![Point2::origin(); n];
    let result = if let Some(threshold) = a.ransac {
        let cfg = RansacConfig {
            threshold: T::lit(threshold),
            seed: a.seed,
            ..RansacConfig::default()
        }
        .check()
        .map_err(|e| no_pose(&src, e, false))?;
        let mut mask = vec![false; n];
        let (est, report) =
            solve_pnp_ransac(camera, &world, &pixels, &mut scratch, &cfg, &mut mask)
                .map_err(|e| no_pose(&src, e, false))?;
        let p = json_pose(&est);
        JsonResult {
            r: p.r,
            t: p.t,
            rvec: p.rvec,
            rms_px: p.rms_px,
            alternative: None,
            solver: "pnp_ransac",
            points: n,
            inliers: Some(report.inliers),
            inlier_mask: Some(mask),
        }
    } else if planar {
        let model: Vec<Point2<T>> = world.iter().map(|p| Point2::new(p.x, p.y)).collect();
        let sol = solve_planar(
            camera,
            &model,
            &pixels,
            &mut scratch,
            &PlanarConfig::default(),
        )
        .map_err(|e| no_pose(&src, e, true))?;
        let p = json_pose(&sol.best);
        JsonResult {
            r: p.r,
            t: p.t,
            rvec: p.rvec,
            rms_px: p.rms_px,
            alternative: Some(json_pose(&sol.alternative)),
            solver: "planar",
            points: n,
            inliers: None,
            inlier_mask: None,
        }
    } else {
        let est = solve_pnp(camera, &world, &pixels, &mut scratch)
            .map_err(|e| no_pose(&src, e, false))?;
        let p = json_pose(&est);
        JsonResult {
            r: p.r,
            t: p.t,
            rvec: p.rvec,
            rms_px: p.rms_px,
            alternative: None,
            solver: "pnp",
            points: n,
            inliers: None,
            inlier_mask: None,
        }
    };
    Ok(to_json(&result))
}
