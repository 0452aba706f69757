//! Synthetic sweep of the homography estimators: random ground-truth homographies of a plane
//! seen by two cameras, N ∈ {4, 8, 20, 50, 100, 300} correspondences, outlier fractions
//! {0, 0.1, 0.3, 0.5, 0.6}, pixel noise σ ∈ {0, 0.5, 1, 2}, fixed seeds, f64 and f32.
//!
//! The bounds are OpenCV's own (`modules/calib3d/test/test_homography.cpp`, test
//! `Calib3d_Homography.accuracy`), which we read and reproduce here. That test draws `N = 4..303`
//! points uniformly in a 100 x 100 image, maps them by a Euclidean `H` (rotation, translation
//! < 10 px, `h31 = h32 = 0`), and checks `findHomography` with methods 0 (all points), LMEDS,
//! RANSAC and RHO, threshold 3 px:
//!
//! 1. noise-free: `cvtest::norm(H_true, H_found, NORM_L1 | NORM_L2 | NORM_INF) <= max_diff =
//!    0.032`, both matrices with `h33 = 1` (the entry-wise L1 sum, the Frobenius norm and the
//!    largest entry of the 3x3 difference); RANSAC's mask must be all inliers;
//! 2. then noise `N(0, σ = 0.01)` is added to the destination points only; a point is an
//!    inlier of the "original mask" when its noise is within the threshold; for RANSAC:
//!    - the found mask must be exactly the set of points whose distance to `H_found x` is
//!      within the threshold (`MESSAGE_RANSAC_MASK_4`),
//!    - every original inlier must be in the found mask (`MESSAGE_RANSAC_MASK_5`),
//!    - for each found inlier, `|H_found x - H_true x|_p - |noise|_p <= max_2diff = 0.020` for
//!      p = 1, 2, ∞ (`MESSAGE_RANSAC_DIFF`);
//!    - for method 0, the same per point, and over all points stacked
//!      `|E|_p - |noise|_p <= max_diff = 0.032` (`MESSAGE_REPROJ_DIFF_2`).
//!
//! What differs here, and how the bounds carry over (stated, not hidden):
//!
//! - the homographies are general (perspective, 640 x 480 images: see [`scene`]) and there are
//!   outliers, which OpenCV's test does not have;
//! - camgeom's residual is the symmetric transfer error
//!   `r = sqrt((|x' - H x|² + |x - H⁻¹ x'|²) / 2)`, not OpenCV's one-sided `|x' - H x|`, so the
//!   mask check (MASK_4) and the "original inlier" set use `r` (under `H_found`, resp.
//!   `H_true`), which is what camgeom's threshold means;
//! - OpenCV's noise is 0.01 px, where its absolute bounds 0.020 and 0.032 are 2σ and 3.2σ; our
//!   noise goes up to 2 px, so for σ > 0 the bounds scale with σ: per point `2σ`, stacked
//!   `3.2σ` (at σ = 0 they are OpenCV's numbers as they are). The matrix bound (1) is applied
//!   at σ = 0 only, as in OpenCV (entry differences of a noisy fit have units of pixels);
//! - "every original inlier found" (MASK_5) is kept at σ = 0; with noise an original inlier near
//!   the 3 px threshold may fall just outside it under the estimate, so for σ ∈ {0.5, 1} we
//!   require at least 80 % of them per run when there are at least 20 (with 7, one miss is
//!   already 14 %), and 80 % over all runs of each σ together;
//! - at σ = 2 px the 3 px threshold is only 1.5σ (a third of the true correspondences are
//!   already outside it under the true H). Per run we assert the mask check (MASK_4), and over
//!   all σ = 2 runs together that 80 % of the original inliers are found; the per-run recall
//!   and reprojection bounds are asserted by `sigma_2_bounds`. It used to fail (N = 300, 30 %
//!   outliers, seed 1213399563: 126 inliers and a worst grid error of 6.7 px, where
//!   `cv2.findHomography(RANSAC, 3)` found 133 and 2.8 px) because local optimisation refitted
//!   only on the inliers at the threshold itself and could settle on a subset; it now refits
//!   at a threshold shrinking from 3t to t (`camgeom::ransac`), and passes;
//! - combinations where the model is not identifiable are skipped: outliers with N = 4, and
//!   fewer than 6 inliers (a random 4-point sample fits its own 4 points exactly, so with 4 or 5
//!   true inliers the truth need not have the lowest MSAC cost).
//!
//! The f32 runs use the same data cast to f32, with the rounding of f32 allowed for in the mask
//! check (residuals within 1e-3 px of the threshold are not judged) and the matrix check
//! relative to f32's precision on a 640-px image (`0.032` still holds, see the assertion).
//!
//! `cargo test -p camgeom-host --test it homography_sweep::` runs every combination on one scene
//! each (a few seconds in debug) and the σ = 2 bounds. The full sweep, 5 scenes per combination
//! in f64 and f32, is ignored in debug builds for time (0.4 s in release):
//!
//! ```sh
//! cargo test --release -p camgeom-host --test it -- --ignored homography_sweep::full_sweep
//! ```

use camgeom::Real;
use camgeom::homography::{Homography, check_sample, dlt, find_homography};
use camgeom::nalgebra::{Matrix3, Point2, Rotation3, Vector3};
use camgeom::ransac::{RansacConfig, RansacParams};
use camgeom::rng::Pcg32;

const SIZES: [usize; 6] = [4, 8, 20, 50, 100, 300];
const OUTLIER_FRACTIONS: [f64; 5] = [0.0, 0.1, 0.3, 0.5, 0.6];
const SIGMAS: [f64; 4] = [0.0, 0.5, 1.0, 2.0];
const WIDTH: f64 = 640.0;
const HEIGHT: f64 = 480.0;
/// RANSAC threshold (px), OpenCV's `reproj_threshold`.
const THRESHOLD: f64 = 3.0;
/// OpenCV's `max_diff` (matrix bound, and the stacked reprojection bound at σ = 0.01).
const MAX_DIFF: f64 = 0.032;
/// OpenCV's `max_2diff` (per-point reprojection bound at σ = 0.01).
const MAX_2DIFF: f64 = 0.020;
/// OpenCV's noise level, at which its absolute bounds were set.
const OPENCV_SIGMA: f64 = 0.01;
/// Share of the original inliers that must be found when σ > 0 (per run with at least
/// [`MIN_ORIGINAL_FOR_RECALL`] of them, and over all runs of each σ together).
const MIN_RECALL: f64 = 0.8;
/// Below this many original inliers one miss is already more than 20 %: judged in aggregate.
const MIN_ORIGINAL_FOR_RECALL: usize = 20;
/// f32 runs: allowance per coordinate (px) for f32 rounding of the inputs and of the solve
/// (about 4 ulp of a 640-px coordinate), added to the reprojection bounds. OpenCV's test needs
/// none: `findHomography` computes in f64 even for float input.
const F32_FLOOR: f64 = 2.5e-4;
/// Outliers land at least this far (px) from their true match.
const OUTLIER_MIN_OFFSET: f64 = 10.0;

/// A random homography of a plane seen by two pinhole cameras: `H = K (R + t nᵀ / d) K⁻¹`
/// (camera 1 at the origin, `X₂ = R X₁ + t`, plane `nᵀ X₁ = d`), `f ∈ [500, 800]` px, principal
/// point at the image centre, the plane tilted up to 40° from fronto-parallel at `d ∈ [1, 3]`,
/// camera 2 rotated up to 15° about a random axis and moved up to 0.3 d sideways, 0.2 d in
/// depth.
fn scene(g: &mut Pcg32) -> Matrix3<f64> {
    let f = g.uniform(500.0, 800.0);
    let k = Matrix3::new(f, 0.0, WIDTH / 2.0, 0.0, f, HEIGHT / 2.0, 0.0, 0.0, 1.0);
    let k_inv = k.try_inverse().unwrap();
    let tilt_axis = Vector3::new(g.normal(), g.normal(), 0.0).normalize();
    let tilt = Rotation3::new(tilt_axis * g.uniform(0.0, 40f64.to_radians()));
    let n = tilt * Vector3::z();
    let d = g.uniform(1.0, 3.0);
    let axis = Vector3::new(g.normal(), g.normal(), g.normal()).normalize();
    let r = Rotation3::new(axis * g.uniform(0.0, 15f64.to_radians()));
    let t = Vector3::new(
        g.uniform(-0.3, 0.3),
        g.uniform(-0.3, 0.3),
        g.uniform(-0.2, 0.2),
    ) * d;
    let h = k * (r.matrix() + t * n.transpose() / d) * k_inv;
    h / h.m33
}

/// `H x` (inhomogeneous) and the depth ratio `w` (> 0: the point is in front of camera 2).
fn map(h: &Matrix3<f64>, p: &Point2<f64>) -> (Point2<f64>, f64) {
    let v = h * Vector3::new(p.x, p.y, 1.0);
    (Point2::new(v.x / v.z, v.y / v.z), v.z)
}

/// One synthetic problem.
struct Case {
    h: Matrix3<f64>,
    src: Vec<Point2<f64>>,
    /// Noise-free `H src` (outliers: their true position).
    clean: Vec<Point2<f64>>,
    dst: Vec<Point2<f64>>,
    outlier: Vec<bool>,
}

fn make_case(seed: u64, n: usize, outlier_fraction: f64, sigma: f64) -> Case {
    let mut g = Pcg32::new(seed);
    let h = scene(&mut g);
    let (mut src, mut clean) = (Vec::new(), Vec::new());
    while src.len() < n {
        let p = Point2::new(g.uniform(0.0, WIDTH), g.uniform(0.0, HEIGHT));
        let (q, w) = map(&h, &p);
        // In front of camera 2 and inside a generous window around its image.
        let inside = (-WIDTH..2.0 * WIDTH).contains(&q.x) && (-HEIGHT..2.0 * HEIGHT).contains(&q.y);
        if w > 0.05 && inside {
            src.push(p);
            clean.push(q);
        }
    }
    // As OpenCV: noise on the destination points only.
    let mut dst: Vec<Point2<f64>> = clean
        .iter()
        .map(|q| Point2::new(q.x + sigma * g.normal(), q.y + sigma * g.normal()))
        .collect();
    let outliers = (outlier_fraction * n as f64).round() as usize;
    let mut outlier = vec![false; n];
    // The first `outliers` indices of a random permutation.
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        order.swap(i, g.below(i as u32 + 1) as usize);
    }
    for &i in order.iter().take(outliers) {
        outlier[i] = true;
        loop {
            let q = Point2::new(g.uniform(0.0, WIDTH), g.uniform(0.0, HEIGHT));
            if (q - clean[i]).norm() >= OUTLIER_MIN_OFFSET {
                dst[i] = q;
                break;
            }
        }
    }
    Case {
        h,
        src,
        clean,
        dst,
        outlier,
    }
}

/// camgeom's symmetric transfer error of a pair under `h` (pixels), `inf` when a point maps to
/// infinity.
fn residual(h: &Matrix3<f64>, h_inv: &Matrix3<f64>, s: &Point2<f64>, d: &Point2<f64>) -> f64 {
    let (f, wf) = map(h, s);
    let (b, wb) = map(h_inv, d);
    if wf == 0.0 || wb == 0.0 {
        return f64::INFINITY;
    }
    (((f - d).norm_squared() + (b - s).norm_squared()) / 2.0).sqrt()
}

/// `|v|_p` of a 2-vector for OpenCV's NORM_L1, NORM_L2, NORM_INF.
fn norms(v: &[f64]) -> [f64; 3] {
    let l1 = v.iter().map(|x| x.abs()).sum();
    let l2 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let inf = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    [l1, l2, inf]
}

/// OpenCV's `check_matrix_diff` for all three norms, on `h33`-normalised matrices.
fn matrix_diff(truth: &Matrix3<f64>, found: &Matrix3<f64>) -> [f64; 3] {
    let d = truth / truth.m33 - found / found.m33;
    norms(d.as_slice())
}

/// Per-point and stacked reprojection bounds (OpenCV's `max_2diff`, `max_diff`) at noise σ.
fn bounds(sigma: f64) -> (f64, f64) {
    if sigma == 0.0 {
        (MAX_2DIFF, MAX_DIFF)
    } else {
        let s = sigma / OPENCV_SIGMA;
        (MAX_2DIFF * s, MAX_DIFF * s)
    }
}

/// What a run found, for the summary.
#[derive(Default, Debug, Clone, Copy)]
struct Stats {
    runs: usize,
    skipped: usize,
    /// N = 4 samples that the noise folded (rejected as `Degenerate`, as they must be).
    folded: usize,
    worst_recall: f64,
    /// Worst `|H x - H_true x| - |noise|` of a found inlier (L1, L2 or ∞), per σ.
    worst_point_excess: [f64; 4],
    worst_matrix_diff: f64,
    /// Original inliers found and present, per σ (indexed as [`SIGMAS`]).
    found: [usize; 4],
    original: [usize; 4],
}

/// OpenCV's reprojection checks on `points`: for each, `|H_found x - H_true x|_p - |noise|_p`
/// (per point, p = 1, 2, ∞) and the same over all of them stacked. Returns the worst per-point
/// excess.
fn reprojection_checks(
    what: &str,
    case: &Case,
    found: &Matrix3<f64>,
    points: &[usize],
    sigma: f64,
    f32: bool,
    strict: bool,
) -> f64 {
    let (per_point, stacked) = bounds(sigma);
    // f32 rounding per coordinate, added to each bound in the norm's own way: 2 coordinates per
    // point, 2m stacked (L1: sum, L2: square root of the count, ∞: once).
    let floor = if f32 { F32_FLOOR } else { 0.0 };
    let m = 2.0 * points.len() as f64;
    let point_floor = [2.0 * floor, 2f64.sqrt() * floor, floor];
    let stacked_floor = [m * floor, m.sqrt() * floor, floor];
    let mut worst = f64::NEG_INFINITY;
    let (mut e_all, mut n_all) = (Vec::new(), Vec::new());
    for &k in points {
        let (q, _) = map(found, &case.src[k]);
        let e = [q.x - case.clean[k].x, q.y - case.clean[k].y];
        let noise = [
            case.dst[k].x - case.clean[k].x,
            case.dst[k].y - case.clean[k].y,
        ];
        for ((ne, nn), fl) in norms(&e).iter().zip(norms(&noise)).zip(point_floor) {
            let excess = ne - nn;
            worst = worst.max(excess);
            let per_point = per_point + fl;
            assert!(
                !strict || excess <= per_point,
                "{what}: point {k}: |H x - H_true x| - |noise| = {excess} > {per_point}"
            );
        }
        e_all.extend_from_slice(&e);
        n_all.extend_from_slice(&noise);
    }
    for ((ne, nn), fl) in norms(&e_all).iter().zip(norms(&n_all)).zip(stacked_floor) {
        let stacked = stacked + fl;
        assert!(
            !strict || ne - nn <= stacked,
            "{what}: stacked |E| - |noise| = {} > {stacked}",
            ne - nn
        );
    }
    worst
}

fn cast<T: Real>(p: &[Point2<f64>]) -> Vec<Point2<T>> {
    p.iter()
        .map(|p| Point2::new(T::lit(p.x), T::lit(p.y)))
        .collect()
}

fn to_f64<T: Real>(h: &Homography<T>) -> Matrix3<f64> {
    h.matrix().map(|v| v.to_f64())
}

/// One combination on one scene in `T` (counted as skipped when not identifiable).
fn run<T: Real>(seed: u64, n: usize, frac: f64, sigma: f64, strict2: bool, stats: &mut Stats) {
    // RANSAC's recall and reprojection bounds are asserted for σ < 2 (see the module docs).
    let strict = sigma < 2.0 || strict2;
    let case = make_case(seed, n, frac, sigma);
    let outliers = case.outlier.iter().filter(|o| **o).count();
    // N = 4 with outliers has fewer than 6 inliers too.
    if outliers > 0 && n - outliers < 6 {
        stats.skipped += 1;
        return;
    }
    stats.runs += 1;
    let f32 = T::EPSILON.to_f64() > 1e-10;
    let what = format!(
        "{} N={n} outliers={outliers} sigma={sigma} seed={seed}",
        if f32 { "f32" } else { "f64" }
    );
    // The inputs as the estimator sees them (rounded to T).
    let src_t = cast::<T>(&case.src);
    let dst_t = cast::<T>(&case.dst);
    let src: Vec<Point2<f64>> = src_t.iter().map(|p| p.map(|v| v.to_f64())).collect();
    let dst: Vec<Point2<f64>> = dst_t.iter().map(|p| p.map(|v| v.to_f64())).collect();
    let truth_inv = case.h.try_inverse().unwrap();
    // OpenCV's "original mask": non-outliers within the threshold of the true H.
    let original: Vec<usize> = (0..n)
        .filter(|&k| {
            !case.outlier[k] && residual(&case.h, &truth_inv, &src[k], &dst[k]) <= THRESHOLD
        })
        .collect();

    // N = 4 with noise: the noisy sample may fold (one point across the line the map sends to
    // infinity), which no plane seen by two cameras gives; the 4-point solver and RANSAC must
    // then say `Degenerate` (OpenCV's RANSAC rejects such samples too, its method 0 does not).
    if let (Ok(s4), Ok(d4)) = (
        <[Point2<T>; 4]>::try_from(src_t.as_slice()),
        <[Point2<T>; 4]>::try_from(dst_t.as_slice()),
    ) && check_sample(&s4, &d4).is_err()
    {
        assert!(sigma > 0.0, "{what}: a noise-free sample folds");
        let e = Homography::from_four_points(&s4, &d4);
        assert_eq!(e, Err(camgeom::Error::Degenerate), "{what}");
        let mut mask = [true; 4];
        let r = find_homography(&s4, &d4, &RansacParams::<T>::default(), &mut mask);
        assert_eq!(r.err(), Some(camgeom::Error::Degenerate), "{what}");
        stats.folded += 1;
        return;
    }
    // Method 0 (every point): the DLT, and the exact solver for N = 4.
    if outliers == 0 {
        let h = dlt(&src_t, &dst_t).unwrap_or_else(|e| panic!("{what}: dlt: {e:?}"));
        let h = to_f64(&h);
        if sigma == 0.0 {
            let d = matrix_diff(&case.h, &h);
            stats.worst_matrix_diff = stats.worst_matrix_diff.max(d[0]);
            assert!(d.iter().all(|d| *d <= MAX_DIFF), "{what}: dlt: {d:?}");
        }
        let all: Vec<usize> = (0..n).collect();
        reprojection_checks(&format!("{what} dlt"), &case, &h, &all, sigma, f32, true);
        if let (Ok(s4), Ok(d4)) = (
            <[Point2<T>; 4]>::try_from(src_t.as_slice()),
            <[Point2<T>; 4]>::try_from(dst_t.as_slice()),
        ) {
            let h4 = Homography::from_four_points(&s4, &d4)
                .unwrap_or_else(|e| panic!("{what}: from_four_points: {e:?}"));
            let h4 = to_f64(&h4);
            if sigma == 0.0 {
                let d = matrix_diff(&case.h, &h4);
                assert!(d.iter().all(|d| *d <= MAX_DIFF), "{what}: 4-point: {d:?}");
            }
            reprojection_checks(
                &format!("{what} 4-point"),
                &case,
                &h4,
                &all,
                sigma,
                f32,
                true,
            );
        }
    }

    // RANSAC.
    let config = RansacConfig::<T> {
        threshold: T::lit(THRESHOLD),
        ..RansacConfig::default()
    }
    .check()
    .unwrap();
    let mut mask = vec![false; n];
    let (h, report) = find_homography(&src_t, &dst_t, &config, &mut mask)
        .unwrap_or_else(|e| panic!("{what}: find_homography: {e:?}"));
    let h = to_f64(&h);
    let h_inv = h.try_inverse().unwrap();
    assert_eq!(
        report.inliers,
        mask.iter().filter(|m| **m).count(),
        "{what}"
    );
    // MASK_4: the mask is exactly the set within the threshold of the estimate.
    let slack = if f32 { 1e-3 } else { 1e-9 };
    for k in 0..n {
        let r = residual(&h, &h_inv, &src[k], &dst[k]);
        if (r - THRESHOLD).abs() <= slack {
            continue;
        }
        assert_eq!(mask[k], r < THRESHOLD, "{what}: point {k}: residual {r}");
    }
    // MASK_5: the original inliers are found (all at σ = 0, 80 % with noise).
    let found = original.iter().filter(|&&k| mask[k]).count();
    let si = SIGMAS.iter().position(|s| *s == sigma).unwrap_or(0);
    stats.found[si] += found;
    stats.original[si] += original.len();
    let recall = found as f64 / original.len().max(1) as f64;
    stats.worst_recall = stats.worst_recall.min(recall);
    let need = if sigma == 0.0 {
        1.0
    } else if strict && original.len() >= MIN_ORIGINAL_FOR_RECALL {
        MIN_RECALL
    } else {
        0.0
    };
    assert!(
        recall >= need,
        "{what}: found {found} of {} original inliers",
        original.len()
    );
    if sigma == 0.0 {
        let d = matrix_diff(&case.h, &h);
        stats.worst_matrix_diff = stats.worst_matrix_diff.max(d[0]);
        assert!(d.iter().all(|d| *d <= MAX_DIFF), "{what}: ransac: {d:?}");
    }
    // RANSAC_DIFF: per found inlier (that is a true correspondence).
    let checked: Vec<usize> = original.iter().copied().filter(|&k| mask[k]).collect();
    let worst = reprojection_checks(
        &format!("{what} ransac"),
        &case,
        &h,
        &checked,
        sigma,
        f32,
        strict,
    );
    let si = SIGMAS.iter().position(|s| *s == sigma).unwrap_or(0);
    stats.worst_point_excess[si] = stats.worst_point_excess[si].max(worst);
}

fn sweep(scenes: u64, types: &[&str], strict2: bool) -> Stats {
    let mut stats = Stats {
        worst_recall: 1.0,
        worst_point_excess: [f64::NEG_INFINITY; 4],
        ..Stats::default()
    };
    for (ni, &n) in SIZES.iter().enumerate() {
        for (fi, &frac) in OUTLIER_FRACTIONS.iter().enumerate() {
            for (si, &sigma) in SIGMAS.iter().enumerate() {
                for scene in 0..scenes {
                    let seed = 0x4853_0000 + 1000 * scene + 100 * ni as u64 + 10 * fi as u64;
                    let seed = seed + si as u64;
                    for t in types {
                        match *t {
                            "f64" => run::<f64>(seed, n, frac, sigma, strict2, &mut stats),
                            _ => run::<f32>(seed, n, frac, sigma, strict2, &mut stats),
                        }
                    }
                }
            }
        }
    }
    println!("{stats:?}");
    for (i, sigma) in SIGMAS.iter().enumerate() {
        println!(
            "sigma {sigma}: RANSAC found {} of {} original inliers ({:.1} %), worst per-point \
             excess {:.3} px",
            stats.found[i],
            stats.original[i],
            100.0 * stats.found[i] as f64 / stats.original[i].max(1) as f64,
            stats.worst_point_excess[i]
        );
    }
    stats
}

/// 80 % of the original inliers found over all runs of each σ.
fn assert_recall(stats: &Stats) {
    for (i, sigma) in SIGMAS.iter().enumerate() {
        let (found, original) = (stats.found[i] as f64, stats.original[i] as f64);
        assert!(found >= MIN_RECALL * original, "sigma {sigma}: {stats:?}");
    }
}

#[test]
fn every_combination_once() {
    let stats = sweep(1, &["f64", "f32"], false);
    assert!(stats.runs >= 180, "{stats:?}");
    assert_recall(&stats);
}

#[test]
#[ignore = "the full sweep: run in release, see the module docs"]
fn full_sweep() {
    let stats = sweep(5, &["f64", "f32"], false);
    assert!(stats.runs >= 900, "{stats:?}");
    assert_recall(&stats);
}

/// RANSAC's per-run bounds at σ = 2 px (see the module docs).
#[test]
fn sigma_2_bounds() {
    sweep(1, &["f64"], true);
}
