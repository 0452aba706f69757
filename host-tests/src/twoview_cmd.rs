//! `camgeom twoview`: the epipolar geometry and relative pose of two calibrated views (OpenCV's
//! `findFundamentalMat(FM_RANSAC)`, `findEssentialMat(RANSAC)`, `recoverPose` and
//! `triangulatePoints` in one call).
//!
//! Input: CSV rows `x1,y1,x2,y2` (a pixel in view 1 and its match in view 2; optional header),
//! or two images (`--images A.png B.png`: ORB features matched with cross-check, as
//! `camgeom homography --images`), and the camera file of each view. Lens distortion of the
//! camera files is removed from every pixel first ([`camgeom::camera::Camera::undistort_pixel`]);
//! `F` relates those undistorted pixels.
//!
//! Then, with `x̂ = K⁻¹ u`:
//!
//! 1. `F`: [`camgeom::twoview::find_fundamental`] (7-point RANSAC, MSAC on the Sampson
//!    distance, `--f-threshold`, 8-point local optimisation, Sampson LM), `x₂ᵀ F x₁ = 0`;
//! 2. `E`: [`camgeom::twoview::find_essential`] (5-point RANSAC, `--threshold` on the Sampson
//!    distance of `K₂⁻ᵀ E K₁⁻¹` in pixels), `x̂₂ᵀ E x̂₁ = 0`, singular values `(1, 1, 0)`;
//! 3. `R`, `t`: [`camgeom::twoview::recover_pose`] on the `E` inliers, `X₂ = R X₁ + t`,
//!    `|t| = 1` (the scale is not observable), the cheirality test keeping the pairs in front of
//!    both cameras and nearer than `--max-distance` baselines;
//! 4. `points`: [`camgeom::twoview::triangulate_optimal`] of those pairs, in view 1's camera
//!    frame in units of the baseline; `point_rows` gives the input row of each point.
//!
//! Output: JSON `{"F": [9], "E": [9], "R": [9], "t": [3], "inliers": N, "points": [[X, Y, Z],
//! ...], ...}` (matrices row-major; `F` with unit Frobenius norm). A camgeom failure is an input
//! error (status 2, one line naming the error).
//!
//! `--matches-out FILE.csv` also writes every correspondence (the ORB matches with `--images`,
//! the input rows otherwise) as `x1,y1,x2,y2,inlier`: raw pixels as read or matched, `inlier`
//! 1 for the rows counted in `inliers` (the JSON's `inlier_mask`), 0 otherwise.

use std::path::{Path, PathBuf};

use camgeom::Real;
use camgeom::camera::Camera;
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::ransac::RansacConfig;
use camgeom::transform::Transform;
use camgeom::twoview::{
    View1, find_essential, find_fundamental, recover_pose, triangulate_optimal,
};
use camgeom_host::cli::args::MatchesArg;
use camgeom_host::cli::files::write_file;
use camgeom_host::cli::matches::read_input;
use camgeom_host::points::{format_csv, format_float, to_json};
use camgeom_host::{Error, Result, load_camera};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct TwoviewArgs {
    #[command(flatten)]
    pub input: MatchesArg,
    /// Camera file of view 1 (OpenCV YAML/XML, camgeom JSON/TOML; see `camgeom camera`).
    #[arg(long, value_name = "FILE")]
    pub intrinsics1: PathBuf,
    /// Camera file of view 2; default: the camera of view 1.
    #[arg(long, value_name = "FILE")]
    pub intrinsics2: Option<PathBuf>,
    /// Inlier threshold of `E` in pixels, on the Sampson distance (OpenCV's findEssentialMat
    /// default).
    #[arg(long, value_name = "PX", default_value_t = 1.0)]
    pub threshold: f64,
    /// Inlier threshold of `F` in pixels, on the Sampson distance (OpenCV's
    /// findFundamentalMat default).
    #[arg(long, value_name = "PX", default_value_t = 3.0)]
    pub f_threshold: f64,
    /// Probability of having drawn an all-inlier sample when RANSAC stops early, in (0, 1].
    #[arg(long, value_name = "P", default_value_t = 0.999)]
    pub confidence: f64,
    /// Most RANSAC samples drawn (each of F and E).
    #[arg(long, value_name = "N", default_value_t = 2000)]
    pub max_iters: u32,
    /// Seed of RANSAC's sampler: the same seed and input give the same output everywhere.
    #[arg(long, value_name = "SEED", default_value_t = RansacConfig::<f64>::default().seed)]
    pub seed: u64,
    /// Cheirality bound: points farther than this many baselines do not vote for a pose and
    /// are not triangulated (OpenCV's recoverPose `distanceThresh`).
    #[arg(long, value_name = "BASELINES", default_value_t = 50.0)]
    pub max_distance: f64,
    /// Compute in f32, as the firmware does (default f64).
    #[arg(long)]
    pub f32: bool,
    /// Also write every correspondence (the feature matches with `--images`) as CSV rows
    /// `x1,y1,x2,y2,inlier` (raw pixels; `inlier` 1 for the pairs counted in `inliers`, else 0).
    #[arg(long, value_name = "FILE.csv")]
    pub matches_out: Option<PathBuf>,
}

/// The JSON result.
#[derive(Serialize, Debug)]
pub struct TwoviewOutput<T> {
    /// `F`, row-major, unit Frobenius norm, on undistorted pixels: `x₂ᵀ F x₁ = 0`.
    #[serde(rename = "F")]
    pub f: [T; 9],
    /// `E = [t]ₓ R`, row-major, singular values `(1, 1, 0)`.
    #[serde(rename = "E")]
    pub e: [T; 9],
    /// `R` of `X₂ = R X₁ + t`, row-major.
    #[serde(rename = "R")]
    pub r: [T; 9],
    /// `t`, unit length.
    pub t: [T; 3],
    /// Pairs that are `E` inliers and in front of both cameras (the triangulated ones).
    pub inliers: usize,
    /// Inliers of `F` (at `--f-threshold`).
    pub f_inliers: usize,
    /// Inliers of `E` before the cheirality test.
    pub e_inliers: usize,
    /// Pairs supporting the runner-up pose (a margin for the cheirality decision).
    pub runner_up: usize,
    /// Per input row: whether it is one of `inliers`.
    pub inlier_mask: Vec<bool>,
    /// Triangulated inliers, view 1's camera frame, in baselines.
    pub points: Vec<[T; 3]>,
    /// The input row (0-based, header excluded) of each point.
    pub point_rows: Vec<usize>,
    /// RMS reprojection error of the triangulated points in both views, pixels (`fx` scale).
    pub reprojection_rms_px: T,
    /// Feature matches found between the images (`--images` only; the mask is per match).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matches: Option<usize>,
}

/// Runs the subcommand: the JSON result.
pub fn run(a: &TwoviewArgs) -> Result<String> {
    let (source, matches, from_images) = read_input(&a.input)?;
    let spec1 = load_camera(&a.intrinsics1)?;
    let spec2 = match &a.intrinsics2 {
        Some(p) => load_camera(p)?,
        None => spec1,
    };
    let (out, mask) = if a.f32 {
        let o = estimate(
            a,
            &source,
            &matches,
            from_images,
            &spec1.camera_f32(),
            &spec2.camera_f32(),
        )?;
        (to_json(&o), o.inlier_mask)
    } else {
        let o = estimate(
            a,
            &source,
            &matches,
            from_images,
            &spec1.camera,
            &spec2.camera,
        )?;
        (to_json(&o), o.inlier_mask)
    };
    if let Some(path) = &a.matches_out {
        write_matches(path, &matches, &mask)?;
    }
    Ok(out)
}

/// Writes `matches` with their inlier flags as CSV rows `x1,y1,x2,y2,inlier` (`--matches-out`).
fn write_matches(path: &Path, matches: &[(Point2<f64>, Point2<f64>)], mask: &[bool]) -> Result<()> {
    let rows = matches.iter().zip(mask).map(|((p, q), &inlier)| {
        [
            format_float(p.x),
            format_float(p.y),
            format_float(q.x),
            format_float(q.y),
            u8::from(inlier).to_string(),
        ]
    });
    write_file(path, format_csv(&["x1", "y1", "x2", "y2", "inlier"], rows))
}

fn flat<T: Real>(m: &Matrix3<T>) -> [T; 9] {
    [
        m.m11, m.m12, m.m13, m.m21, m.m22, m.m23, m.m31, m.m32, m.m33,
    ]
}

/// The two-view geometry in `T` (f64, or f32 as on the firmware) of `matches` (raw pixels)
/// seen by `c1` and `c2`; `source` names the input in error messages.
pub fn estimate<T: Real>(
    a: &TwoviewArgs,
    source: &str,
    matches: &[(Point2<f64>, Point2<f64>)],
    from_images: bool,
    c1: &Camera<T>,
    c2: &Camera<T>,
) -> Result<TwoviewOutput<T>> {
    let fail = |what: &str, e: camgeom::Error| {
        let n = matches.len();
        Error::camgeom(format!("{source}: {what} failed on {n} correspondences"), e)
    };
    let cast = |p: &Point2<f64>| Point2::new(T::lit(p.x), T::lit(p.y));
    let mut x1 = Vec::with_capacity(matches.len());
    let mut x2 = Vec::with_capacity(matches.len());
    for (row, (p, q)) in matches.iter().enumerate() {
        let u1 = c1
            .undistort_pixel(&cast(p))
            .map_err(|e| fail(&format!("undistorting row {row} in view 1"), e))?;
        let u2 = c2
            .undistort_pixel(&cast(q))
            .map_err(|e| fail(&format!("undistorting row {row} in view 2"), e))?;
        x1.push(u1);
        x2.push(u2);
    }
    let (k1, k2) = (c1.intrinsics, c2.intrinsics);
    // Each checked just before the estimator that takes it, its error reported as that
    // estimator's.
    let params = |threshold: f64, what: &str| {
        RansacConfig {
            threshold: T::lit(threshold),
            confidence: T::lit(a.confidence),
            max_iterations: a.max_iters,
            seed: a.seed,
            ..RansacConfig::default()
        }
        .check()
        .map_err(|e| fail(what, e))
    };
    let mut f_mask = vec![false; x1.len()];
    let f_params = params(a.f_threshold, "find_fundamental")?;
    let (f, f_report) = find_fundamental(&x1, &x2, &f_params, &mut f_mask)
        .map_err(|e| fail("find_fundamental", e))?;
    let mut mask = vec![false; x1.len()];
    let e_params = params(a.threshold, "find_essential")?;
    let (e, e_report) = find_essential(&k1, &k2, &x1, &x2, &e_params, &mut mask)
        .map_err(|e| fail("find_essential", e))?;
    let rp = recover_pose(&e, &k1, &k2, &x1, &x2, T::lit(a.max_distance), &mut mask)
        .map_err(|e| fail("recover_pose", e))?;
    let p1 = Transform::<View1, View1, T>::identity();
    let (mut points, mut point_rows) = (Vec::new(), Vec::new());
    let mut sq = T::zero();
    for (row, m) in mask.iter_mut().enumerate() {
        if !*m {
            continue;
        }
        let tri = k1
            .pixel_to_normalized(&x1[row])
            .and_then(|n1| Ok((n1, k2.pixel_to_normalized(&x2[row])?)))
            .and_then(|(n1, n2)| triangulate_optimal(&p1, &rp.pose, &n1, &n2));
        match tri {
            Ok(t) => {
                let (e1, e2) = (t.error1 * k1.fx(), t.error2 * k2.fx());
                sq += e1 * e1 + e2 * e2;
                points.push([t.point.x, t.point.y, t.point.z]);
                point_rows.push(row);
            }
            // Not triangulable (parallel rays, behind a camera): not an inlier after all.
            Err(_) => *m = false,
        }
    }
    let reprojection_rms_px = if points.is_empty() {
        T::zero()
    } else {
        (sq / T::lit(2.0 * points.len() as f64)).sqrt()
    };
    let (r, t) = (rp.pose.rotation(), rp.pose.translation());
    Ok(TwoviewOutput {
        f: flat(f.matrix()),
        e: flat(e.matrix()),
        r: flat(r.matrix()),
        t: [t.x, t.y, t.z],
        inliers: points.len(),
        f_inliers: f_report.inliers,
        e_inliers: e_report.inliers,
        runner_up: rp.runner_up,
        inlier_mask: mask,
        points,
        point_rows,
        reprojection_rms_px,
        matches: from_images.then_some(matches.len()),
    })
}
