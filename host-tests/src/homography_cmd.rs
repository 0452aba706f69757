//! `camgeom homography`: the plane homography of point correspondences (OpenCV's
//! `findHomography(src, dst, RANSAC, threshold)` and, for exactly four rows,
//! `getPerspectiveTransform`).
//!
//! Input: CSV rows `x1,y1,x2,y2` (a point in the first image and its match in the second;
//! optional header). Output: `{"H": [h11, h12, h13, h21, .., h33], "inliers": N,
//! "inlier_mask": [true, ...], "method": "ransac" | "four_point", "iterations": K}` with
//! `x2 ~ H x1` and `h33 = 1` (unless the origin maps to, or near, infinity: then `|H|_F = 1`).
//!
//! With exactly four rows the exact 4-point solver runs (every row is an inlier); with more,
//! [`camgeom::homography::find_homography`] (RANSAC with MSAC scoring, local optimisation and a
//! final Levenberg-Marquardt polish) with the options below. A failure of camgeom (too few rows,
//! collinear or coincident points, a parameter out of range) is an input error: status 2 and one
//! line naming the error (`degenerate`, `too_few_points`, `invalid_parameter`, ...).

use std::path::PathBuf;

use camgeom::Real;
use camgeom::homography::{Homography, find_homography};
use camgeom::nalgebra::Point2;
use camgeom::ransac::RansacConfig;
use camgeom_host::points::read_csv;
use camgeom_host::status_name;
use clap::Args;
use serde::Serialize;

/// The columns of a correspondence row.
pub const COLUMNS: [&str; 4] = ["x1", "y1", "x2", "y2"];

#[derive(Args, Debug)]
pub struct HomographyArgs {
    /// Correspondences, CSV rows `x1,y1,x2,y2` (a point in the first image, its match in the
    /// second; optional header); `-` reads stdin. Exactly 4 rows: the exact 4-point solver;
    /// more: RANSAC.
    #[arg(long, value_name = "FILE.csv")]
    pub matches: PathBuf,
    /// RANSAC inlier threshold in pixels, on camgeom's symmetric transfer error
    /// `sqrt((|x2 - H x1|² + |x1 - H⁻¹ x2|²) / 2)`.
    #[arg(long, value_name = "PX", default_value_t = 3.0)]
    pub threshold: f64,
    /// Probability of having drawn an all-inlier sample when RANSAC stops early, in (0, 1).
    #[arg(long, value_name = "P", default_value_t = 0.995)]
    pub confidence: f64,
    /// Most RANSAC samples drawn.
    #[arg(long, value_name = "N", default_value_t = 2000)]
    pub max_iters: u32,
    /// Seed of RANSAC's sampler: the same seed and input give the same output everywhere.
    #[arg(long, value_name = "SEED", default_value_t = RansacConfig::<f64>::default().seed)]
    pub seed: u64,
    /// Compute in f32, as the firmware does (default f64).
    #[arg(long)]
    pub f32: bool,
}

/// The JSON result.
#[derive(Serialize, Debug)]
pub struct HomographyOutput<T> {
    /// `H`, row-major, 9 numbers.
    #[serde(rename = "H")]
    pub h: [T; 9],
    /// Number of `true` entries of `inlier_mask`.
    pub inliers: usize,
    /// Per input row: whether it is an inlier of `H`.
    pub inlier_mask: Vec<bool>,
    /// `four_point` (exactly 4 rows) or `ransac`.
    pub method: &'static str,
    /// RANSAC samples drawn (absent for the 4-point solver).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<u32>,
}

/// Reads the correspondences `(x1, y1) -> (x2, y2)` of a CSV file (`-`: stdin).
pub fn read_matches(path: &PathBuf) -> camgeom_host::Result<Vec<(Point2<f64>, Point2<f64>)>> {
    Ok(read_csv(path, &COLUMNS)?
        .rows
        .iter()
        .map(|r| (Point2::new(r[0], r[1]), Point2::new(r[2], r[3])))
        .collect())
}

/// Runs the subcommand; `Err` is the one-line message of an input error (status 2).
pub fn run(a: &HomographyArgs) -> Result<String, String> {
    let matches = read_matches(&a.matches).map_err(|e| e.to_string())?;
    let json = if a.f32 {
        to_json(&estimate::<f32>(a, &matches)?)
    } else {
        to_json(&estimate::<f64>(a, &matches)?)
    };
    Ok(json)
}

/// The homography in `T` (f64, or f32 as on the firmware).
pub fn estimate<T: Real>(
    a: &HomographyArgs,
    matches: &[(Point2<f64>, Point2<f64>)],
) -> Result<HomographyOutput<T>, String> {
    let cast = |p: &Point2<f64>| Point2::new(T::lit(p.x), T::lit(p.y));
    let src: Vec<Point2<T>> = matches.iter().map(|m| cast(&m.0)).collect();
    let dst: Vec<Point2<T>> = matches.iter().map(|m| cast(&m.1)).collect();
    let fail = |what: &str, e: camgeom::Error| {
        format!(
            "{}: {what} failed: {} ({e}), {} correspondences",
            a.matches.display(),
            status_name(&e),
            matches.len()
        )
    };
    let (h, mask, method, iterations) = if let (Ok(s4), Ok(d4)) = (
        <[Point2<T>; 4]>::try_from(src.as_slice()),
        <[Point2<T>; 4]>::try_from(dst.as_slice()),
    ) {
        let h = Homography::from_four_points(&s4, &d4).map_err(|e| fail("from_four_points", e))?;
        (h, vec![true; 4], "four_point", None)
    } else {
        let config = RansacConfig {
            threshold: T::lit(a.threshold),
            confidence: T::lit(a.confidence),
            max_iterations: a.max_iters,
            seed: a.seed,
            ..RansacConfig::default()
        };
        let mut mask = vec![false; src.len()];
        let (h, report) = find_homography(&src, &dst, &config, &mut mask)
            .map_err(|e| fail("find_homography", e))?;
        (h, mask, "ransac", Some(report.iterations))
    };
    let m = h.matrix();
    Ok(HomographyOutput {
        h: [
            m.m11, m.m12, m.m13, m.m21, m.m22, m.m23, m.m31, m.m32, m.m33,
        ],
        inliers: mask.iter().filter(|m| **m).count(),
        inlier_mask: mask,
        method,
        iterations,
    })
}

/// Pretty-printed JSON with a final newline.
fn to_json<S: Serialize>(value: &S) -> String {
    // Numbers, booleans and strings only: serialising cannot fail.
    let mut s = serde_json::to_string_pretty(value).unwrap_or_default();
    s.push('\n');
    s
}
