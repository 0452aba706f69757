//! `camgeom sfm`: incremental structure from motion over any number of images of one calibrated
//! camera, or over tracks the user brings.
//!
//! 1. features of each image, `--features sift` (the default: [`sift_features`], RootSIFT,
//!    Euclidean distance) or `--features orb` ([`orb_features`]: a count and a grid sized from
//!    the image, Hamming distance), matched between every pair of images with the ratio test and
//!    the mutual check ([`SfmFeature::match_guided`]);
//! 2. each pair's matches verified by an essential matrix (5-point RANSAC on undistorted
//!    pixels) or, when it explains more, a homography (a plane, a camera that only turned): a
//!    pair keeps that model's inliers when there are at least `--min-pair-inliers`, else none;
//!    with `--guided`, a verified pair is then matched again under its model (COLMAP's guided
//!    matching, [`guided_pair`]): each feature's candidates are only the features within
//!    `--verify-threshold` of its epipolar line (Sampson distance) or of its homography
//!    transfer, the ratio test and the mutual check among those, no farther in descriptor distance
//!    than the pair's first verified matches, and the matches found are verified again by the
//!    same kind of model;
//! 3. tracks: the verified matches joined strongest first (pairs with more verified matches,
//!    then smaller distances), a match that would give a track two features of one image left
//!    out ([`consistent_tracks`]); each track aligned by KLT to its finest keypoint
//!    ([`refine_tracks`]); or, with `--matches`, the tracks of a CSV file (`track,view,x,y`);
//! 4. [`camgeom::sfm::reconstruct`]: the initial pair (refused when planar, low-parallax or
//!    short of inliers), PnP-RANSAC registration of each next view, triangulation, bundle
//!    adjustments of every view and point, outlier filtering; then, unless `--no-extend`, the
//!    tracks are completed by projecting each point into the registered views that lack it
//!    ([`extend_tracks`]) and the reconstruction runs again on them;
//! 5. prints JSON: per image in the order given, `registered`, the `reason` when not, `R`
//!    (row-major), `t` (`X_cam = R X_world + t`), `center`, `inliers`, `reprojection_rms_px`;
//!    writes `DIR/points.ply` (points coloured from the images, then the camera centres) and
//!    `DIR/plot.png` (top-down and side views of points and cameras).
//!
//! The world frame is the first view of the initial pair (`x` right, `y` down, `z` forward);
//! the unit is the initial pair's baseline. Fewer than two registered views is an error (exit
//! status 1) that says why; no pose is printed that the data does not determine.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use camgeom::camera::Camera;
use camgeom::features::orb::Feature;
use camgeom::features::sift::SiftFeature;
use camgeom::homography::find_homography;
use camgeom::nalgebra::{Matrix3, Point2, Point3};
use camgeom::ransac::{RansacConfig, RansacParams};
use camgeom::sfm::{
    BundleScratch, IncrementalConfig, IncrementalParams, InitialRefusal, Observation, PointScratch,
    Reconstruction, Scene, TrackSet, ViewRefusal, ViewResult, ViewState, Workspace, reconstruct,
};
use camgeom::transform::Pose;
use camgeom::twoview::find_essential;
use camgeom_host::cli::args::CameraArg;
use camgeom_host::cli::files::{create_dir, write_file};
use camgeom_host::cli::matches::{RATIO_MUTUAL, SfmFeature, orb_features, sift_features};
use camgeom_host::figures::{
    CAMERA_COLOURS, SceneCamera, correspondences_plot, reprojection_plot, scene_plot,
};
use camgeom_host::images::{GrayImage, load_gray};
use camgeom_host::points::{read_csv, to_json};
use camgeom_host::rgb::RgbImage;
use camgeom_host::{Error, ErrorKind, Result, load_camera};
use clap::{Args, ValueEnum};
use serde::Serialize;

#[derive(Args, Debug)]
pub struct SfmArgs {
    /// Two or more images of a static scene from one camera (PNG, JPEG), in any order; the
    /// output lists them in this order.
    #[arg(long, num_args = 2.., value_name = "IMAGE", required = true)]
    pub images: Vec<PathBuf>,
    /// The features matched between the images: SIFT (scale-space keypoints, float
    /// descriptors) or ORB (FAST corners on a pyramid, binary descriptors).
    #[arg(long, value_enum, default_value_t = FeatureKind::Sift)]
    pub features: FeatureKind,
    /// With `--features sift`: double the images first (OpenCV's default), for about 1.6 times
    /// the features and the finest scales, at twice the time.
    #[arg(long)]
    pub sift_upsample: bool,
    /// Tracks instead of features: a CSV file of rows `track,view,x,y` (`view` indexes
    /// `--images`, pixels as in the images); the images then only colour the points.
    #[arg(long, value_name = "FILE.csv")]
    pub matches: Option<PathBuf>,
    #[command(flatten)]
    pub camera: CameraArg,
    /// Also write the tracks given to the reconstruction, rows `track,view,x,y` (what
    /// `--matches` reads back).
    #[arg(long, value_name = "FILE.csv")]
    pub tracks_out: Option<PathBuf>,
    /// Output directory (created): `points.ply` and `plot.png`.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Inlier threshold of the initial pair's essential matrix, pixels (Sampson distance).
    #[arg(long, value_name = "PX", default_value_t = 1.0)]
    pub threshold: f64,
    /// Inlier threshold of the PnP registrations and of the observations kept, pixels.
    #[arg(long, value_name = "PX", default_value_t = 4.0)]
    pub pnp_threshold: f64,
    /// Inlier threshold of the pairwise verification of the matches, pixels (Sampson).
    #[arg(long, value_name = "PX", default_value_t = 4.0)]
    pub verify_threshold: f64,
    /// Fewest verified matches for a pair of images to count.
    #[arg(long, value_name = "N", default_value_t = 15)]
    pub min_pair_inliers: usize,
    /// Match each verified pair again under its geometry (COLMAP's guided matching): off by
    /// default, since with ORB it finds more wrong matches along epipolar lines than it adds
    /// right ones (BENCHMARKS.md, "Structure from motion on real buildings").
    #[arg(long)]
    pub guided: bool,
    /// One reconstruction: no extension of the tracks by the first one's points projected
    /// into its registered views.
    #[arg(long)]
    pub no_extend: bool,
    /// Keep the keypoints where the detector put them (no KLT alignment of each track to its
    /// finest observation).
    #[arg(long)]
    pub no_refine: bool,
    /// Seed of every RANSAC sampler.
    #[arg(long, value_name = "SEED", default_value_t = RansacConfig::<f64>::default().seed)]
    pub seed: u64,
    /// Levenberg-Marquardt steps of the final bundle adjustment.
    #[arg(long, value_name = "N", default_value_t = 40)]
    pub bundle_iterations: u8,
}

/// The features of `--features`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FeatureKind {
    /// [`camgeom::features::sift`], RootSIFT descriptors.
    Sift,
    /// [`camgeom::features::orb`] with a grid and sub-pixel positions.
    Orb,
}

/// One image of the summary.
#[derive(Serialize, Debug)]
pub struct View {
    /// The image file.
    pub image: String,
    /// Whether it has a pose.
    pub registered: bool,
    /// Why not (absent when registered).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// World-to-camera rotation, row-major (absent when not registered).
    #[serde(rename = "R", skip_serializing_if = "Option::is_none")]
    pub r: Option<[f64; 9]>,
    /// World-to-camera translation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub t: Option<[f64; 3]>,
    /// Camera centre in the world frame, `-Rᵀ t`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 3]>,
    /// Observations of the reconstruction in this image.
    pub inliers: u32,
    /// Their RMS reprojection error, pixels.
    pub reprojection_rms_px: f64,
    /// Features detected (0 with `--matches`).
    pub features: usize,
}

/// One pair of images.
#[derive(Serialize, Debug)]
pub struct Pair {
    /// Indices into `views`.
    pub views: [usize; 2],
    /// Matches (ratio test and mutual check).
    pub matches: usize,
    /// Matches verified: of the first pass, or of the guided pass when there was one (0 when
    /// below `--min-pair-inliers`).
    pub verified: usize,
    /// Matches of the guided pass, before their verification (0 without one).
    pub guided: usize,
}

/// The JSON summary.
#[derive(Serialize, Debug)]
pub struct SfmOutput {
    /// Every image, in the order given.
    pub views: Vec<View>,
    /// Registered views.
    pub registered: usize,
    /// Reconstructed points.
    pub points: usize,
    /// Tracks given to the reconstruction.
    pub tracks: usize,
    /// Observations added to the tracks by projecting the first reconstruction's points into
    /// its registered views (0 with `--no-extend`; then one reconstruction).
    pub extended: usize,
    /// Observations used.
    pub observations: usize,
    /// RMS reprojection error of those, pixels.
    pub reprojection_rms_px: f64,
    /// The initial pair (indices into `views`).
    pub initial_pair: [usize; 2],
    /// Its inliers.
    pub initial_inliers: u32,
    /// Pairwise matching (absent with `--matches`).
    pub pairs: Vec<Pair>,
    /// Wall time, seconds: features and matching, then the reconstruction (both, with the
    /// track completion).
    pub seconds: [f64; 2],
    /// The files written.
    pub ply: String,
    /// The scene from above and from the side (`plot.png`).
    pub plot: String,
    /// The initial pair's matches, verified (inliers) or not (`matches.png`).
    pub matches_plot: String,
    /// Each registered view's observed and reprojected points (`reprojection-KK.png`).
    pub reprojection_plots: Vec<String>,
}

/// Tracks in compressed rows: `starts` (one more than tracks) and the observations.
struct Tracks {
    starts: Vec<u32>,
    observations: Vec<Observation<f64>>,
}

fn pixel<F: SfmFeature>(f: &F) -> Point2<f64> {
    f.pixel()
}

/// Each pair's matches (pixels in the first and the second image, verified), by `(i, j)`, `i < j`.
type PairMatches = BTreeMap<(usize, usize), Vec<(Point2<f64>, Point2<f64>, bool)>>;

/// The geometry a pair of images was verified with, on undistorted pixels.
#[derive(Clone, Copy, Debug)]
enum PairModel {
    /// The fundamental matrix `F = K⁻ᵀ E K⁻¹` of the essential matrix.
    Fundamental(Matrix3<f64>),
    /// A homography `y ~ H x` and its inverse.
    Homography(Matrix3<f64>, Matrix3<f64>),
}

/// Step 2's verification of matches `x1[k] ↔ x2[k]` (undistorted pixels): the essential
/// matrix, or the homography when it explains more. The inlier mask and the model, or `None`
/// when neither has `min` inliers.
fn verify_pair(
    camera: &Camera<f64>,
    x1: &[Point2<f64>],
    x2: &[Point2<f64>],
    params: &RansacParams<f64>,
    min: usize,
) -> Option<(Vec<bool>, PairModel)> {
    let k = camera.intrinsics;
    if x1.len() < min.max(5) {
        return None;
    }
    // The model that explains more: the essential matrix for a pair that moved, a homography
    // for a plane or a camera that only turned (whose matches still make tracks, though such a
    // pair cannot start the reconstruction).
    let (mut mask, mut mask_h) = (vec![false; x1.len()], vec![false; x1.len()]);
    let e = find_essential(&k, &k, x1, x2, params, &mut mask).ok();
    let h = find_homography(x1, x2, params, &mut mask_h).ok();
    let (ne, nh) = (
        e.as_ref().map_or(0, |r| r.1.inliers),
        h.as_ref().map_or(0, |r| r.1.inliers),
    );
    let model = if nh > ne {
        mask = mask_h;
        let (h, _) = h?;
        PairModel::Homography(*h.matrix(), *h.inverse().ok()?.matrix())
    } else {
        let (e, _) = e?;
        PairModel::Fundamental(*e.to_fundamental(&k, &k).ok()?.matrix())
    };
    (mask.iter().filter(|&&b| b).count() >= min).then_some((mask, model))
}

/// COLMAP's guided matching of features `a` and `b` (undistorted pixels `ua`, `ub`; `None`
/// outside the lens model) under a pair's verified geometry: the candidates of a feature are
/// the features of the other image within `threshold` pixels, the verification's inlier test
/// (squared Sampson distance to `F`, or symmetric transfer error of `H`, `< threshold²`); among
/// them the ratio test and the mutual check as in the first pass
/// ([`camgeom::features::matching::match_descriptors_guided`]). Per feature of `a` the
/// epipolar line `F x` (or the transfer `H x`) is computed once, per feature of `b` `Fᵀ y`
/// (or `H⁻¹ y`), so each pair costs a few multiplications before any descriptor distance.
fn guided_pair<F: SfmFeature>(
    a: &[F],
    b: &[F],
    ua: &[Option<Point2<f64>>],
    ub: &[Option<Point2<f64>>],
    model: &PairModel,
    threshold: f64,
    what: &str,
) -> Result<Vec<(usize, usize)>> {
    let t2 = threshold * threshold;
    let nan = [f64::NAN; 4];
    // Per feature of `a`: `[l₀, l₁, l₂, l₀² + l₁²]` with `l = F x`, or `[Hx, x]`; of `b`:
    // `[y, m₀² + m₁²]` with `m = Fᵀ y` (the third entry unused), or `[y, H⁻¹ y]`. NaN outside
    // the lens model: never a candidate.
    let lift = |p: &Point2<f64>| camgeom::nalgebra::Vector3::new(p.x, p.y, 1.0);
    let (pa, pb): (Vec<[f64; 4]>, Vec<[f64; 4]>) = match model {
        PairModel::Fundamental(f) => (
            ua.iter()
                .map(|x| {
                    x.map_or(nan, |x| {
                        let l = f * lift(&x);
                        [l.x, l.y, l.z, l.x * l.x + l.y * l.y]
                    })
                })
                .collect(),
            ub.iter()
                .map(|y| {
                    y.map_or(nan, |y| {
                        let m = f.transpose() * lift(&y);
                        [y.x, y.y, 0.0, m.x * m.x + m.y * m.y]
                    })
                })
                .collect(),
        ),
        PairModel::Homography(h, hinv) => {
            let transfer = |m: &Matrix3<f64>, p: &Point2<f64>| {
                let q = m * lift(p);
                Point2::new(q.x / q.z, q.y / q.z)
            };
            (
                ua.iter()
                    .map(|x| {
                        x.map_or(nan, |x| {
                            let q = transfer(h, &x);
                            [q.x, q.y, x.x, x.y]
                        })
                    })
                    .collect(),
                ub.iter()
                    .map(|y| {
                        y.map_or(nan, |y| {
                            let q = transfer(hinv, &y);
                            [y.x, y.y, q.x, q.y]
                        })
                    })
                    .collect(),
            )
        }
    };
    let fundamental = matches!(model, PairModel::Fundamental(_));
    // NaN compares false: a feature outside the lens model is never admitted.
    let admit = |i: usize, j: usize| -> bool {
        let (Some(p), Some(q)) = (pa.get(i), pb.get(j)) else {
            return false;
        };
        if fundamental {
            let e = q[0] * p[0] + q[1] * p[1] + p[2];
            e * e < t2 * (p[3] + q[3])
        } else {
            let f = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
            let g = (q[2] - p[2]).powi(2) + (q[3] - p[3]).powi(2);
            (f + g) * 0.5 < t2
        }
    };
    F::match_guided(a, b, admit, what)
}

/// Steps 1-3 of the module docs from images.
fn tracks_from_images<F: SfmFeature>(
    a: &SfmArgs,
    camera: &Camera<f64>,
    features: &[Vec<F>],
) -> Result<(Tracks, Vec<Pair>, PairMatches, Members)> {
    let mut verify = RansacConfig::<f64> {
        threshold: a.verify_threshold,
        confidence: 0.999,
        seed: a.seed,
        ..RansacConfig::default()
    }
    .check()
    .map_err(|e| Error::camgeom("--verify-threshold", e));
    let verify = verify.as_mut().map_err(|e| Error::usage(e.to_string()))?;
    let offsets: Vec<u32> = std::iter::once(0)
        .chain(features.iter().scan(0u32, |acc, f| {
            *acc += f.len() as u32;
            Some(*acc)
        }))
        .collect();
    // Undistorted pixels of every feature (`None` outside the lens model).
    let undistorted: Vec<Vec<Option<Point2<f64>>>> = features
        .iter()
        .map(|fs| {
            fs.iter()
                .map(|f| camera.undistort_pixel(&pixel(f)).ok())
                .collect()
        })
        .collect();
    let mut pairs = Vec::new();
    let mut pair_matches = PairMatches::new();
    // Every verified match: its pair's verified count, its distance, its two nodes.
    let mut joins: Vec<(usize, u32, u32, u32)> = Vec::new();
    for i in 0..features.len() {
        for j in i + 1..features.len() {
            let what = format!("{} - {}", a.images[i].display(), a.images[j].display());
            let first = F::match_guided(&features[i], &features[j], |_, _| true, &what)?;
            let (ui, uj) = (&undistorted[i], &undistorted[j]);
            // The matches with both pixels in the lens model, and the verified ones.
            let verified = |m: &[(usize, usize)]| {
                let pts: Vec<&(usize, usize)> = m
                    .iter()
                    .filter(|&&(p, q)| ui[p].is_some() && uj[q].is_some())
                    .collect();
                let x1: Vec<Point2<f64>> = pts.iter().filter_map(|&&(p, _)| ui[p]).collect();
                let x2: Vec<Point2<f64>> = pts.iter().filter_map(|&&(_, q)| uj[q]).collect();
                verify_pair(camera, &x1, &x2, verify, a.min_pair_inliers).map(|(mask, model)| {
                    let kept: Vec<(usize, usize)> = pts
                        .iter()
                        .zip(&mask)
                        .filter(|(_, b)| **b)
                        .map(|(&&pq, _)| pq)
                        .collect();
                    (kept, model)
                })
            };
            let mut m = first.clone();
            let mut inliers: Vec<(usize, usize)> = Vec::new();
            let mut guided = 0;
            if let Some((kept, model)) = verified(&first) {
                inliers = kept;
                if a.guided {
                    let bound = inliers
                        .iter()
                        .map(|&(p, q)| features[i][p].distance(&features[j][q]))
                        .fold(0.0f32, f32::max);
                    let mut g = guided_pair(
                        &features[i],
                        &features[j],
                        ui,
                        uj,
                        &model,
                        a.verify_threshold,
                        &what,
                    )?;
                    // No farther than the first pass's verified matches of this pair.
                    g.retain(|&(p, q)| features[i][p].distance(&features[j][q]) <= bound);
                    guided = g.len();
                    if let Some((kept, _)) = verified(&g) {
                        inliers = kept;
                        m = g;
                    }
                }
            }
            for &(p, q) in &inliers {
                // Non-negative: the bits order as the distances.
                let d = features[i][p].distance(&features[j][q]).max(0.0).to_bits();
                joins.push((
                    inliers.len(),
                    d,
                    offsets[i] + p as u32,
                    offsets[j] + q as u32,
                ));
            }
            let kept: std::collections::BTreeSet<(usize, usize)> =
                inliers.iter().copied().collect();
            pair_matches.insert(
                (i, j),
                m.iter()
                    .map(|&(p, q)| {
                        let ok = kept.contains(&(p, q));
                        (pixel(&features[i][p]), pixel(&features[j][q]), ok)
                    })
                    .collect(),
            );
            pairs.push(Pair {
                views: [i, j],
                matches: first.len(),
                verified: inliers.len(),
                guided,
            });
        }
    }
    let mut members = consistent_tracks(&offsets, &mut joins);
    // `compress` keeps the tracks of two or more observations: so do the members.
    members.retain(|m| m.len() >= 2);
    let tracks = if a.no_refine {
        plain_tracks(features, &members)
    } else {
        refine_tracks(&a.images, features, &members)?
    };
    Ok((compress(tracks), pairs, pair_matches, members))
}

/// Tracks from verified matches `(pair's verified count, distance, node, node)` that never
/// hold two features of one image: the matches are joined strongest first (pairs with more
/// verified matches, then smaller distances), and a match that would put two features of one
/// image into one track is left out (instead of dropping the whole component).
fn consistent_tracks(offsets: &[u32], joins: &mut [(usize, u32, u32, u32)]) -> Members {
    let nodes = offsets.last().copied().unwrap_or(0) as usize;
    let view_of = |n: u32| offsets.partition_point(|&o| o <= n) - 1;
    let mut parent: Vec<u32> = (0..nodes as u32).collect();
    let mut views: Vec<Vec<u16>> = (0..nodes as u32).map(|n| vec![view_of(n) as u16]).collect();
    fn root(parent: &mut [u32], mut n: u32) -> u32 {
        while parent[n as usize] != n {
            let up = parent[parent[n as usize] as usize];
            parent[n as usize] = up;
            n = up;
        }
        n
    }
    joins.sort_by(|x, y| {
        y.0.cmp(&x.0)
            .then(x.1.cmp(&y.1))
            .then(x.2.cmp(&y.2))
            .then(x.3.cmp(&y.3))
    });
    for &(_, _, p, q) in joins.iter() {
        let (rp, rq) = (root(&mut parent, p), root(&mut parent, q));
        if rp == rq
            || views[rp as usize]
                .iter()
                .any(|v| views[rq as usize].contains(v))
        {
            continue;
        }
        let (big, small) = if views[rp as usize].len() >= views[rq as usize].len() {
            (rp, rq)
        } else {
            (rq, rp)
        };
        parent[small as usize] = big;
        let moved = std::mem::take(&mut views[small as usize]);
        views[big as usize].extend(moved);
    }
    // Label components in order of their first node.
    let mut label: BTreeMap<u32, usize> = BTreeMap::new();
    let mut members: Members = Vec::new();
    for n in 0..nodes as u32 {
        let r = root(&mut parent, n);
        if views[r as usize].len() < 2 {
            continue;
        }
        let l = *label.entry(r).or_insert_with(|| {
            members.push(Vec::new());
            members.len() - 1
        });
        let v = view_of(n);
        members[l].push((v, (n - offsets[v]) as usize));
    }
    members
}

/// Each track's features, `(view, index into that view's features)`.
type Members = Vec<Vec<(usize, usize)>>;

/// Tracks at the features' keypoints (`--no-refine`).
fn plain_tracks<F: SfmFeature>(
    features: &[Vec<F>],
    members: &[Vec<(usize, usize)>],
) -> Vec<Vec<Observation<f64>>> {
    members
        .iter()
        .map(|m| {
            m.iter()
                .map(|&(v, f)| Observation {
                    view: v as u16,
                    pixel: pixel(&features[v][f]),
                })
                .collect()
        })
        .collect()
}

/// A reconstruction's outcome, owned.
struct Solved {
    poses: Vec<Option<Pose<f64>>>,
    results: Vec<ViewResult<f64>>,
    points: Vec<Option<Point3<f64>>>,
    used: Vec<bool>,
    r: Reconstruction<f64>,
}

/// Step 4: [`reconstruct`] with buffers sized for `tracks`.
fn solve(
    camera: &Camera<f64>,
    tracks: &Tracks,
    views: usize,
    params: &IncrementalParams<f64>,
) -> Result<Solved> {
    let set = TrackSet::new_checked(&tracks.starts, &tracks.observations, views)
        .map_err(|e| Error::camgeom("tracks", e))?;
    let (v, nt, no) = (set.views(), set.len(), set.observations().len());
    let mut poses = vec![None; v];
    let mut results = vec![ViewResult::<f64>::default(); v];
    let mut points = vec![None; nt];
    let mut used = vec![false; no];
    let mut normalized = vec![None; no];
    let mut covisibility = vec![0u32; v * v];
    let mut tried = vec![0u32; v];
    let mut next_counts = vec![0u32; v];
    let mut free = vec![true; v];
    let (mut first, mut second) = (vec![Point2::origin(); nt], vec![Point2::origin(); nt]);
    let mut world = vec![Point3::origin(); nt];
    let mut index = vec![0u32; nt];
    let (mut mask, mut mask2) = (vec![false; nt], vec![false; nt]);
    let mut angles = vec![0.0; nt];
    let mut system = vec![0.0; BundleScratch::<f64>::system_len(v)];
    let (mut rhs, mut gradient) = (vec![0.0; 6 * v], vec![0.0; 6 * v]);
    let mut bindex = vec![0u16; v];
    let mut trial = vec![None; v];
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
        counts: &mut next_counts,
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
    let r = reconstruct(camera, &set, params, &mut scene, &mut ws)
        .map_err(|e| Error::camgeom("sfm: reconstruct", e))?;
    Ok(Solved {
        poses,
        results,
        points,
        used,
        r,
    })
}

/// Track completion by projection (the search by projection of ORB-SLAM): each reconstructed
/// point `X` of a track is projected into every registered view the track does not see,
/// `x = π(K, R X + t)`; the features of that view within `radius` pixels of `x` (the
/// reconstruction's own inlier threshold, `--pnp-threshold`) that belong to no track are its
/// candidates, scored by the descriptor distance to the nearest of the track's descriptors. The
/// nearest candidate joins the track when it passes the first pass's ratio test against the
/// second-nearest candidate and is no farther than the track's own descriptors are from each
/// other (the largest distance between two of them: no threshold of its own), and when no other
/// track claims the same feature. Returns the grown members and the observations added.
fn extend_tracks<F: SfmFeature>(
    camera: &Camera<f64>,
    features: &[Vec<F>],
    members: &[Vec<(usize, usize)>],
    solved: &Solved,
    radius: f64,
) -> (Members, usize) {
    let ratio = f64::from(RATIO_MUTUAL.ratio);
    let mut taken: Vec<Vec<bool>> = features.iter().map(|f| vec![false; f.len()]).collect();
    for m in members {
        for &(v, f) in m {
            taken[v][f] = true;
        }
    }
    // The free features of each view in cells of `radius` pixels.
    let cell = radius.max(1.0);
    let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let grids: Vec<BTreeMap<(i64, i64), Vec<usize>>> = features
        .iter()
        .zip(&taken)
        .map(|(fs, tk)| {
            let mut g: BTreeMap<(i64, i64), Vec<usize>> = BTreeMap::new();
            for (k, f) in fs.iter().enumerate().filter(|(k, _)| !tk[*k]) {
                let p = pixel(f);
                g.entry(key(p.x, p.y)).or_default().push(k);
            }
            g
        })
        .collect();
    // (view, feature) -> the tracks that claim it.
    let mut claims: BTreeMap<(usize, usize), Vec<usize>> = BTreeMap::new();
    for (t, m) in members.iter().enumerate() {
        let Some(x) = solved.points.get(t).copied().flatten() else {
            continue;
        };
        let descriptors: Vec<&F> = m.iter().map(|&(v, f)| &features[v][f]).collect();
        let spread = descriptors
            .iter()
            .enumerate()
            .flat_map(|(k, a)| descriptors[k + 1..].iter().map(move |b| a.distance(b)))
            .fold(0.0f32, f32::max);
        for (v, pose) in solved.poses.iter().enumerate() {
            let Some(pose) = pose else { continue };
            if m.iter().any(|&(w, _)| w == v) {
                continue;
            }
            let Ok(p) = camera.project(pose, &x) else {
                continue;
            };
            let (cx, cy) = key(p.x, p.y);
            let (mut d1, mut d2, mut best) = (f32::INFINITY, f32::INFINITY, usize::MAX);
            for gx in cx - 1..=cx + 1 {
                for gy in cy - 1..=cy + 1 {
                    for &k in grids[v].get(&(gx, gy)).map_or(&[][..], Vec::as_slice) {
                        let f = &features[v][k];
                        if (pixel(f) - p).norm() >= radius {
                            continue;
                        }
                        let d = descriptors
                            .iter()
                            .map(|e| e.distance(f))
                            .fold(f32::INFINITY, f32::min);
                        if d < d1 {
                            (d2, d1, best) = (d1, d, k);
                        } else if d < d2 {
                            d2 = d;
                        }
                    }
                }
            }
            let ratio_ok = d2 == f32::INFINITY || f64::from(d1) < ratio * f64::from(d2);
            if best != usize::MAX && d1 <= spread && ratio_ok {
                claims.entry((v, best)).or_default().push(t);
            }
        }
    }
    let mut grown = members.to_vec();
    let mut added = 0;
    for ((v, f), c) in claims {
        if let [t] = c[..] {
            grown[t].push((v, f));
            added += 1;
        }
    }
    (grown, added)
}

/// One alignment of [`refine_tracks`]: track, member, reference pixel, initial guess.
type Request = (usize, usize, [f64; 2], [f64; 2]);

/// Largest move of a keypoint by [`refine_tracks`], in pixels of its own pyramid level: FAST
/// places a corner within about a pixel of its level; a larger move is a window that slid off
/// to other texture, and the keypoint stays where it was.
const MAX_REFINE_SHIFT: f64 = 1.5;

/// Each track's observations aligned to its finest one (the keypoint of the smallest scale)
/// by KLT from there (`calc_flow` with the match as the initial guess, 21x21 windows, two
/// levels): ORB keypoints of one scene point sit at view-dependent offsets (a FAST corner's
/// position on its pyramid level), which bias the geometry; windows aligned to one reference
/// agree to a small fraction of a pixel.
fn refine_tracks<F: SfmFeature>(
    images: &[PathBuf],
    features: &[Vec<F>],
    members: &[Vec<(usize, usize)>],
) -> Result<Vec<Vec<Observation<f64>>>> {
    use camgeom::klt::{FlowStatus, LkConfig};
    use camgeom_host::klt::{flow_from_guesses, pyramid};
    let cfg = LkConfig {
        win: 21,
        max_level: 1,
        ..LkConfig::default()
    };
    let grey: Vec<GrayImage> = images.iter().map(load_gray).collect::<Result<_>>()?;
    let mut bufs: Vec<Vec<u8>> = vec![Vec::new(); grey.len()];
    let pyramids: Vec<_> = grey
        .iter()
        .zip(bufs.iter_mut())
        .map(|(g, b)| pyramid(g, b, 2))
        .collect();
    // Requests per (reference view, view): (track, member, reference pixel, guess).
    let mut requests: BTreeMap<(usize, usize), Vec<Request>> = BTreeMap::new();
    let mut out: Vec<Vec<Observation<f64>>> = Vec::with_capacity(members.len());
    for (t, m) in members.iter().enumerate() {
        let reference = m
            .iter()
            .enumerate()
            .min_by(|x, y| {
                let s = |&(_, &(v, f)): &(usize, &(usize, usize))| features[v][f].fineness();
                s(x).total_cmp(&s(y))
            })
            .map_or(0, |(k, _)| k);
        let (rv, rf) = m[reference];
        let rp = pixel(&features[rv][rf]);
        for (k, &(v, f)) in m.iter().enumerate() {
            if k != reference {
                let g = pixel(&features[v][f]);
                requests
                    .entry((rv, v))
                    .or_default()
                    .push((t, k, [rp.x, rp.y], [g.x, g.y]));
            }
        }
        out.push(
            m.iter()
                .map(|&(v, f)| Observation {
                    view: v as u16,
                    pixel: pixel(&features[v][f]),
                })
                .collect(),
        );
    }
    for ((rv, v), reqs) in &requests {
        let pts: Vec<[f64; 2]> = reqs.iter().map(|r| r.2).collect();
        let guesses: Vec<[f64; 2]> = reqs.iter().map(|r| r.3).collect();
        let Ok(flows) = flow_from_guesses(&pyramids[*rv], &pyramids[*v], &pts, &guesses, &cfg)
        else {
            continue;
        };
        for (r, f) in reqs.iter().zip(flows) {
            let (v_feat, scale) = {
                let (vv, ff) = members[r.0][r.1];
                (vv, features[vv][ff].level_scale())
            };
            debug_assert_eq!(v_feat, *v);
            let moved = ((f.x - r.3[0]).powi(2) + (f.y - r.3[1]).powi(2)).sqrt();
            if f.status == FlowStatus::Tracked && moved <= MAX_REFINE_SHIFT * scale {
                out[r.0][r.1].pixel = Point2::new(f.x, f.y);
            }
        }
    }
    Ok(out)
}

fn compress(members: Vec<Vec<Observation<f64>>>) -> Tracks {
    let mut starts = vec![0u32];
    let mut observations = Vec::new();
    for m in members {
        if m.len() < 2 {
            continue;
        }
        observations.extend(m);
        starts.push(observations.len() as u32);
    }
    Tracks {
        starts,
        observations,
    }
}

/// Tracks of a CSV file `track,view,x,y` (step 3 with `--matches`): a track seen twice in one
/// view, or once, is dropped.
fn tracks_from_csv(path: &PathBuf, views: usize) -> Result<Tracks> {
    let rows = read_csv(path, &["track", "view", "x", "y"])?.rows;
    let mut by_track: BTreeMap<i64, Vec<Observation<f64>>> = BTreeMap::new();
    for (line, r) in rows.iter().enumerate() {
        let (t, v) = (r[0], r[1]);
        if t.fract() != 0.0 || v.fract() != 0.0 || v < 0.0 || v >= views as f64 {
            return Err(Error::at_line(
                path,
                line + 2,
                ErrorKind::Syntax(format!("track and view must be integers, view < {views}")),
            ));
        }
        by_track.entry(t as i64).or_default().push(Observation {
            view: v as u16,
            pixel: Point2::new(r[2], r[3]),
        });
    }
    let members = by_track
        .into_values()
        .filter(|m| {
            let mut v: Vec<u16> = m.iter().map(|o| o.view).collect();
            v.sort_unstable();
            v.windows(2).all(|w| w[0] != w[1])
        })
        .collect();
    Ok(compress(members))
}

fn describe_view(r: &ViewRefusal) -> String {
    match r {
        ViewRefusal::NotReached => "not reached: no initial pair".into(),
        ViewRefusal::TooFewCorrespondences { found, needed } => format!(
            "too_few_correspondences: {found} of its features see reconstructed points, {needed} needed"
        ),
        ViewRefusal::NoPose => "no_pose: PnP-RANSAC found no pose".into(),
        ViewRefusal::TooFewInliers {
            inliers,
            correspondences,
        } => format!(
            "too_few_inliers: the best pose explains {inliers} of {correspondences} correspondences"
        ),
        ViewRefusal::LostInRefinement { inliers } => {
            format!("lost_in_refinement: {inliers} observations left after the bundle adjustment")
        }
        _ => r.name().into(),
    }
}

fn describe_initial(r: &InitialRefusal<f64>, names: &[String]) -> String {
    let n = |(a, b): (u16, u16)| {
        let get = |i: u16| names.get(usize::from(i)).map_or("?", String::as_str);
        format!("{} and {}", get(a), get(b))
    };
    match r {
        InitialRefusal::NoSharedTracks => "no two images share a verified track".into(),
        InitialRefusal::TooFewInliers {
            pair,
            inliers,
            needed,
        } => format!(
            "the best pair ({}) has {inliers} inliers, {needed} needed",
            n(*pair)
        ),
        InitialRefusal::Planar { pair, ratio } => format!(
            "the best pair ({}) is explained by a homography ({:.0} % of the inliers): a planar scene or a pure rotation",
            n(*pair),
            ratio * 100.0
        ),
        InitialRefusal::LowParallax { pair, median_angle } => format!(
            "the best pair ({}) has a median triangulation angle of {:.2} deg: too little parallax",
            n(*pair),
            median_angle.to_degrees()
        ),
        InitialRefusal::NoModel { pair } => {
            format!("no essential matrix for the best pair ({})", n(*pair))
        }
        _ => r.name().into(),
    }
}

/// What steps 1 to 4 give [`run`].
struct Outcome {
    tracks: Tracks,
    pairs: Vec<Pair>,
    counts: Vec<usize>,
    pair_matches: PairMatches,
    solved: Solved,
    extended: usize,
    /// Features and matching; the reconstructions.
    seconds: [f64; 2],
}

/// Steps 1 to 4 from the features of the images (`t0`: when their detection started).
fn from_images<F: SfmFeature>(
    a: &SfmArgs,
    camera: &Camera<f64>,
    params: &IncrementalParams<f64>,
    features: &[Vec<F>],
    t0: Instant,
) -> Result<Outcome> {
    let views_n = a.images.len();
    let counts = features.iter().map(Vec::len).collect();
    let (mut tracks, pairs, pair_matches, members) = tracks_from_images(a, camera, features)?;
    let t_match = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut solved = solve(camera, &tracks, views_n, params)?;
    let mut extended = 0;
    if !a.no_extend && !features.is_empty() && solved.r.initial.is_ok() {
        let (grown, added) = extend_tracks(camera, features, &members, &solved, a.pnp_threshold);
        if added > 0 {
            let observations = if a.no_refine {
                plain_tracks(features, &grown)
            } else {
                refine_tracks(&a.images, features, &grown)?
            };
            tracks = compress(observations);
            solved = solve(camera, &tracks, views_n, params)?;
            extended = added;
        }
    }
    Ok(Outcome {
        tracks,
        pairs,
        counts,
        pair_matches,
        solved,
        extended,
        seconds: [t_match, t1.elapsed().as_secs_f64()],
    })
}

/// Runs the subcommand: writes the files, returns the JSON summary.
pub fn run(a: &SfmArgs) -> Result<String> {
    let spec = load_camera(&a.camera.intrinsics)?;
    let camera = spec.camera;
    let names: Vec<String> = a.images.iter().map(|p| p.display().to_string()).collect();
    if a.images.len() > camgeom::sfm::MAX_VIEWS {
        return Err(Error::usage("too many images"));
    }
    let t0 = Instant::now();
    let mut config = IncrementalConfig::<f64>::default();
    config.essential.threshold = a.threshold;
    config.essential.seed = a.seed;
    config.pnp.threshold = a.pnp_threshold;
    config.pnp.seed = a.seed;
    config.max_reprojection_px = a.pnp_threshold;
    config.final_bundle_iterations = a.bundle_iterations;
    let params = config.check().map_err(|e| {
        Error::usage(format!(
            "sfm configuration (--threshold, --pnp-threshold): {e}"
        ))
    })?;
    let views_n = a.images.len();
    let Outcome {
        tracks,
        pairs,
        counts,
        pair_matches,
        solved,
        extended,
        seconds: [t_match, t_rec],
    } = match &a.matches {
        Some(path) => {
            let tracks = tracks_from_csv(path, views_n)?;
            let t_match = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let solved = solve(&camera, &tracks, views_n, &params)?;
            Outcome {
                tracks,
                pairs: Vec::new(),
                counts: vec![0; views_n],
                pair_matches: PairMatches::new(),
                solved,
                extended: 0,
                seconds: [t_match, t1.elapsed().as_secs_f64()],
            }
        }
        None => match a.features {
            FeatureKind::Sift => {
                let features: Vec<Vec<SiftFeature>> = a
                    .images
                    .iter()
                    .map(|p| sift_features(p, a.sift_upsample))
                    .collect::<Result<_>>()?;
                from_images(a, &camera, &params, &features, t0)?
            }
            FeatureKind::Orb => {
                let features: Vec<Vec<Feature>> = a
                    .images
                    .iter()
                    .map(|p| orb_features(p))
                    .collect::<Result<_>>()?;
                from_images(a, &camera, &params, &features, t0)?
            }
        },
    };
    if let Some(path) = &a.tracks_out {
        let mut csv = String::from("track,view,x,y\n");
        for (t, w) in tracks.starts.windows(2).enumerate() {
            for o in &tracks.observations[w[0] as usize..w[1] as usize] {
                let _ = writeln!(csv, "{t},{},{},{}", o.view, o.pixel.x, o.pixel.y);
            }
        }
        write_file(path, csv)?;
    }
    let set = TrackSet::new_checked(&tracks.starts, &tracks.observations, views_n)
        .map_err(|e| Error::camgeom("tracks", e))?;
    let (v, nt) = (set.views(), set.len());
    let Solved {
        poses,
        results,
        points,
        used,
        r,
    } = solved;
    let initial = match r.initial {
        Ok(p) => p,
        Err(refusal) => {
            return Err(Error::undetermined(format!(
                "sfm: no reconstruction from {} tracks: {}",
                nt,
                describe_initial(&refusal, &names)
            )));
        }
    };
    if r.registered < 2 {
        return Err(Error::undetermined(format!(
            "sfm: only {} view(s) registered",
            r.registered
        )));
    }
    let views: Vec<View> = (0..v)
        .map(|i| {
            let res = results[i];
            let pose = poses[i];
            let (rm, t, c) = match pose {
                Some(p) => {
                    let m = p.rotation().into_inner();
                    let t = p.translation();
                    let c = p.camera_center();
                    (
                        Some([
                            m.m11, m.m12, m.m13, m.m21, m.m22, m.m23, m.m31, m.m32, m.m33,
                        ]),
                        Some([t.x, t.y, t.z]),
                        Some([c.x, c.y, c.z]),
                    )
                }
                None => (None, None, None),
            };
            View {
                image: names[i].clone(),
                registered: pose.is_some(),
                reason: match res.state {
                    ViewState::Registered => None,
                    ViewState::Refused(r) => Some(describe_view(&r)),
                },
                r: rm,
                t,
                center: c,
                inliers: res.inliers,
                reprojection_rms_px: res.rms_px,
                features: counts[i],
            }
        })
        .collect();
    // Each point's colour: the mean of its used observations' pixels.
    let images: Vec<Option<RgbImage>> = a
        .images
        .iter()
        .map(|p| image::open(p).ok().map(|i| i.to_rgb8()))
        .collect();
    let mut coloured = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let Some(x) = p else { continue };
        let (mut sum, mut n) = ([0u32; 3], 0u32);
        for (o, &u) in set.track(i).iter().zip(&used[set.range(i)]) {
            let img = images.get(usize::from(o.view)).and_then(Option::as_ref);
            if let (true, Some(img)) = (u, img) {
                let (px, py) = (o.pixel.x.round(), o.pixel.y.round());
                if px >= 0.0 && py >= 0.0 && (px as u32) < img.width() && (py as u32) < img.height()
                {
                    let c = img.get_pixel(px as u32, py as u32).0;
                    for (s, c) in sum.iter_mut().zip(c) {
                        *s += u32::from(c);
                    }
                    n += 1;
                }
            }
        }
        let rgb = if n == 0 {
            [160, 160, 160]
        } else {
            sum.map(|s| (s / n) as u8)
        };
        coloured.push((*x, rgb));
    }
    create_dir(&a.out)?;
    let ply = a.out.join("points.ply");
    let plot = a.out.join("plot.png");
    write_ply(&ply, &coloured, &views)?;
    let file = |i: usize| {
        a.images[i]
            .file_name()
            .map_or_else(|| names[i].clone(), |f| f.to_string_lossy().into_owned())
    };
    let cameras: Vec<SceneCamera> = (0..v)
        .filter_map(|i| {
            let p = poses[i]?;
            let k = camera.intrinsics;
            let size = images[i]
                .as_ref()
                .map_or((0, 0), |m| (m.width(), m.height()));
            Some(SceneCamera {
                label: file(i),
                rotation: p.rotation().into_inner(),
                center: p.camera_center(),
                intrinsics: (k.fx(), k.fy(), k.cx(), k.cy()),
                size,
            })
        })
        .collect();
    scene_plot(&plot, &coloured, &cameras, "initial baseline")?;
    // The course's figures: the initial pair's correspondences, each view's reprojections.
    let (ia, ib) = (usize::from(initial.0), usize::from(initial.1));
    let pair_plot = a.out.join("matches.png");
    if let (Some(m), Some(Some(ima)), Some(Some(imb))) = (
        pair_matches.get(&(ia.min(ib), ia.max(ib))),
        images.get(ia),
        images.get(ib),
    ) {
        let (first, second) = if ia < ib { (ima, imb) } else { (imb, ima) };
        let title = format!(
            "{} - {}: matches verified by the pair's geometry (initial pair)",
            file(ia.min(ib)),
            file(ia.max(ib))
        );
        correspondences_plot(&pair_plot, first, second, m, &title)?;
    }
    let mut reprojection_plots = Vec::new();
    for i in (0..v).filter(|&i| poses[i].is_some()) {
        let (Some(pose), Some(Some(img))) = (poses[i], images.get(i)) else {
            continue;
        };
        let (mut observed, mut reprojected) = (Vec::new(), Vec::new());
        for t in 0..nt {
            let Some(x) = points[t] else { continue };
            for (o, &u) in set.track(t).iter().zip(&used[set.range(t)]) {
                if u && usize::from(o.view) == i
                    && let Ok(p) = camera.project(&pose, &x)
                {
                    observed.push(o.pixel);
                    reprojected.push(p);
                }
            }
        }
        let path = a.out.join(format!("reprojection-{i:02}.png"));
        let title = format!("{}: observed and reprojected points", file(i));
        reprojection_plot(&path, img, &observed, &reprojected, None, &title)?;
        reprojection_plots.push(path.display().to_string());
    }
    let summary = SfmOutput {
        registered: r.registered,
        points: r.points,
        tracks: nt,
        extended,
        observations: r.observations,
        reprojection_rms_px: r.rms_px,
        initial_pair: [usize::from(initial.0), usize::from(initial.1)],
        initial_inliers: r.initial_inliers,
        pairs,
        seconds: [t_match, t_rec],
        views,
        ply: ply.display().to_string(),
        plot: plot.display().to_string(),
        matches_plot: pair_plot.display().to_string(),
        reprojection_plots,
    };
    Ok(to_json(&summary))
}

/// ASCII PLY: `x y z red green blue` per vertex, the points (their colour in the images) then
/// the registered camera centres (in `plot.png`'s camera colours).
fn write_ply(path: &Path, points: &[(Point3<f64>, [u8; 3])], views: &[View]) -> Result<()> {
    let mut s = String::new();
    let centres: Vec<(usize, [f64; 3])> = views
        .iter()
        .enumerate()
        .filter_map(|(k, v)| v.center.map(|c| (k, c)))
        .collect();
    let n = points.len() + centres.len();
    let _ = write!(
        s,
        "ply\nformat ascii 1.0\ncomment camgeom sfm: {} points, then {} camera centres\n\
         element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        points.len(),
        centres.len()
    );
    for (p, [r, g, b]) in points {
        let _ = writeln!(s, "{} {} {} {r} {g} {b}", p.x, p.y, p.z);
    }
    for (k, [x, y, z]) in centres {
        let [r, g, b] = CAMERA_COLOURS[k % CAMERA_COLOURS.len()];
        let _ = writeln!(s, "{x} {y} {z} {r} {g} {b}");
    }
    write_file(path, s)
}
