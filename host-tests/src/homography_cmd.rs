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

use std::path::{Path, PathBuf};

use camgeom::Real;
use camgeom::features::orb::{self, Feature, OrbConfig};
use camgeom::features::{Descriptor, Match, MatchConfig, match_descriptors};
use camgeom::homography::{Homography, find_homography};
use camgeom::nalgebra::Point2;
use camgeom::ransac::RansacConfig;
use camgeom_host::images::load_gray;
use camgeom_host::points::{read_csv, to_json};
use camgeom_host::{Error, ErrorKind, Result};
use clap::Args;
use serde::Serialize;

/// The columns of a correspondence row.
pub const COLUMNS: [&str; 4] = ["x1", "y1", "x2", "y2"];

#[derive(Args, Debug)]
pub struct HomographyArgs {
    /// Correspondences, CSV rows `x1,y1,x2,y2` (a point in the first image, its match in the
    /// second; optional header); `-` reads stdin. Exactly 4 rows: the exact 4-point solver;
    /// more: RANSAC.
    #[arg(long, value_name = "FILE.csv", required_unless_present = "images")]
    pub matches: Option<PathBuf>,
    /// Two images (PNG, JPEG; read as grey) instead of `--matches`: ORB features of both,
    /// matched with cross-check, then RANSAC on the matched keypoints.
    #[arg(
        long,
        num_args = 2,
        value_names = ["A.png", "B.png"],
        conflicts_with = "matches"
    )]
    pub images: Option<Vec<PathBuf>>,
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

/// Point correspondences `(x1, y1) -> (x2, y2)`.
pub type Correspondences = Vec<(Point2<f64>, Point2<f64>)>;

/// Most ORB features per image (`OrbConfig::default().max_features`).
const MAX_FEATURES: usize = 500;

/// Cross-check only, as OpenCV's `BFMatcher(NORM_HAMMING, crossCheck=True)` (the settings of
/// the graf1 -> graf3 feature tests).
const CROSS_CHECK: MatchConfig = MatchConfig {
    ratio: 1.0,
    cross_check: true,
    max_distance: 256,
};

/// ORB features of an image file.
pub fn orb_features(path: &Path) -> Result<Vec<Feature>> {
    let img = load_gray(path)?;
    let view = img.view().ok_or_else(|| {
        Error::new(
            path,
            ErrorKind::Unsupported(format!("image size {}x{}", img.width, img.height)),
        )
    })?;
    let config = OrbConfig::default();
    let mut scratch = vec![0u8; orb::scratch_len(img.width, img.height, config.scale_q8)];
    let mut out = Box::new(camgeom::heapless::Vec::<Feature, MAX_FEATURES>::new());
    orb::orb_detect(&view, &config, &mut scratch, &mut out)
        .map_err(|e| Error::camgeom(format!("{}: orb_detect failed", path.display()), e))?;
    Ok(out.to_vec())
}

/// Correspondences of two images: their ORB keypoints matched with cross-check.
pub fn match_images(a: &Path, b: &Path) -> Result<Correspondences> {
    let (fa, fb) = (orb_features(a)?, orb_features(b)?);
    let da: Vec<Descriptor> = fa.iter().map(|f| f.descriptor).collect();
    let db: Vec<Descriptor> = fb.iter().map(|f| f.descriptor).collect();
    let mut ms = vec![Match::default(); da.len()];
    let mut scratch = vec![0u32; camgeom::features::matching::scratch_len(db.len())];
    let n = match_descriptors(&da, &db, &CROSS_CHECK, &mut scratch, &mut ms).map_err(|e| {
        let what = format!(
            "{} -> {}: match_descriptors failed",
            a.display(),
            b.display()
        );
        Error::camgeom(what, e)
    })?;
    let point = |f: &Feature| Point2::new(f64::from(f.keypoint.x), f64::from(f.keypoint.y));
    Ok(ms[..n]
        .iter()
        .map(|m| {
            (
                point(&fa[usize::from(m.query)]),
                point(&fb[usize::from(m.train)]),
            )
        })
        .collect())
}

/// Reads the correspondences `(x1, y1) -> (x2, y2)` of a CSV file (`-`: stdin).
pub fn read_matches(path: &PathBuf) -> Result<Vec<(Point2<f64>, Point2<f64>)>> {
    Ok(read_csv(path, &COLUMNS)?
        .rows
        .iter()
        .map(|r| (Point2::new(r[0], r[1]), Point2::new(r[2], r[3])))
        .collect())
}

/// The correspondences of a subcommand's input, `--images A B` (matched with [`match_images`])
/// or else `--matches FILE.csv` ([`read_matches`]): `(source, matches, from_images)`, `source`
/// naming the input in error messages and `from_images` telling feature matches from rows.
pub fn read_input(
    images: Option<&[PathBuf]>,
    matches: Option<&PathBuf>,
) -> Result<(String, Correspondences, bool)> {
    match (images, matches) {
        (Some(images), _) => {
            let [ia, ib] = images else {
                return Err(Error::usage("--images takes two files"));
            };
            let source = format!("{} -> {}", ia.display(), ib.display());
            Ok((source, match_images(ia, ib)?, true))
        }
        (None, Some(path)) => Ok((path.display().to_string(), read_matches(path)?, false)),
        (None, None) => Err(Error::usage("one of --matches and --images is required")),
    }
}

/// Runs the subcommand: the JSON result.
pub fn run(a: &HomographyArgs) -> Result<String> {
    let (source, matches, from_images) = read_input(a.images.as_deref(), a.matches.as_ref())?;
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
        matches: from_images.then_some(matches.len()),
    })
}
