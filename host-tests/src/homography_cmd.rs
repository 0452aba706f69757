//! `camgeom homography`: the plane homography of point correspondences (OpenCV's
//! `findHomography(src, dst, RANSAC, threshold)` and, for exactly four rows,
//! `getPerspectiveTransform`).
//!
//! Input: CSV rows `x1,y1,x2,y2` (a point in the first image and its match in the second;
//! optional header), or two images (`--images A.png B.png`): ORB features of both
//! ([`camgeom::features::orb_detect`], default settings) matched with cross-check
//! (OpenCV's `BFMatcher(NORM_HAMMING, crossCheck=True)`), the matched keypoints being the
//! correspondences (always RANSAC, and the output adds `"matches": M`). Output: `{"H": [h11, h12, h13, h21, .., h33], "inliers": N,
//! "inlier_mask": [true, ...], "method": "ransac" | "four_point", "iterations": K}` with
//! `x2 ~ H x1` and `h33 = 1` (unless the origin maps to, or near, infinity: then `|H|_F = 1`).
//!
//! With exactly four rows the exact 4-point solver runs (every row is an inlier); with more,
//! [`camgeom::homography::find_homography`] (RANSAC with MSAC scoring, local optimisation and a
//! final Levenberg-Marquardt polish) with the options below. A failure of camgeom (too few rows,
//! collinear or coincident points, a parameter out of range) is an input error: status 2 and one
//! line naming the error (`degenerate`, `too_few_points`, `invalid_parameter (parameter out of
//! range: threshold)`, ...).

use camgeom::Real;
use camgeom::homography::{Homography, find_homography};
use camgeom::nalgebra::Point2;
use camgeom::ransac::RansacConfig;
use camgeom_host::cli::args::MatchesArg;
use camgeom_host::cli::matches::read_input;
use camgeom_host::points::to_json;
use camgeom_host::{Error, Result};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct HomographyArgs {
    #[command(flatten)]
    pub input: MatchesArg,
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
    /// Feature matches found between the images (`--images` only; the mask is per match).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matches: Option<usize>,
}

/// Runs the subcommand: the JSON result.
pub fn run(a: &HomographyArgs) -> Result<String> {
    let (source, matches, from_images) = read_input(&a.input)?;
    let json = if a.f32 {
        to_json(&estimate::<f32>(a, &source, &matches, from_images)?)
    } else {
        to_json(&estimate::<f64>(a, &source, &matches, from_images)?)
    };
    Ok(json)
}

/// The homography in `T` (f64, or f32 as on the firmware) of the correspondences read from
/// `source` (named in error messages). `from_images`: feature matches, always RANSAC (never the
/// 4-point solver), and the output counts them.
pub fn estimate<T: Real>(
    a: &HomographyArgs,
    source: &str,
    matches: &[(Point2<f64>, Point2<f64>)],
    from_images: bool,
) -> Result<HomographyOutput<T>> {
    let cast = |p: &Point2<f64>| Point2::new(T::lit(p.x), T::lit(p.y));
    let src: Vec<Point2<T>> = matches.iter().map(|m| cast(&m.0)).collect();
    let dst: Vec<Point2<T>> = matches.iter().map(|m| cast(&m.1)).collect();
    let fail = |what: &str, e: camgeom::Error| {
        let n = matches.len();
        Error::camgeom(format!("{source}: {what} failed on {n} correspondences"), e)
    };
    let four = <[Point2<T>; 4]>::try_from(src.as_slice())
        .ok()
        .zip(<[Point2<T>; 4]>::try_from(dst.as_slice()).ok())
        .filter(|_| !from_images);
    let (h, mask, method, iterations) = if let Some((s4, d4)) = four {
        let h = Homography::from_four_points(&s4, &d4).map_err(|e| fail("from_four_points", e))?;
        (h, vec![true; 4], "four_point", None)
    } else {
        let config = RansacConfig {
            threshold: T::lit(a.threshold),
            confidence: T::lit(a.confidence),
            max_iterations: a.max_iters,
            seed: a.seed,
            ..RansacConfig::default()
        }
        .check()
        .map_err(|e| fail("find_homography", e))?;
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
        matches: from_images.then_some(matches.len()),
    })
}
