//! Two-view geometry on real chessboard pairs: `E` from the recorded corners
//! (`chessboard/corners.csv`, undistorted through camgeom's camera model), the recovered
//! relative pose against OpenCV's calibrated per-view poses (`left_intrinsics.yml`), and the
//! triangulated corners against the board's known geometry (9x6 corners, 25 mm squares).
//!
//! A chessboard is a plane, and a plane seen from two views admits two relative poses that
//! explain every correspondence exactly (the two decompositions of the plane's homography, so
//! two essential matrices): no two-view method can tell them apart from the points alone, and
//! which one RANSAC lands on is a matter of the sample drawn. OpenCV's `findEssentialMat` +
//! `recoverPose` on the same undistorted corners lands on the twin (or a cheirality split) in 8
//! of the 12 pairs below, camgeom in 6 (`host-tests/scripts/chessboard_twoview_opencv.py`;
//! neither is wrong: the data cannot decide). This test therefore checks:
//! every pair's answer explains the corners at their noise level (a twin or the truth, never a
//! wrong fit); the pairs on the true pose are within the stated bounds; the twins are told
//! apart by the board's shape (a twin reconstructs a perspective-distorted board).

use crate::common::{bundled_camera, bundled_poses, chessboard};
use camgeom::camera::Camera;
use camgeom::nalgebra::{Matrix3, Point2, Rotation3, Vector3};
use camgeom::ransac::RansacConfig;
use camgeom::transform::Transform;
use camgeom::twoview::{View1, find_essential, recover_pose, triangulate_optimal};

const NAMES: [&str; 13] = [
    "left01", "left02", "left03", "left04", "left05", "left06", "left07", "left08", "left09",
    "left11", "left12", "left13", "left14",
];

/// Corners `(i, j) -> (u, v)` of one image.
fn corners(image: &str) -> std::collections::BTreeMap<(u32, u32), Point2<f64>> {
    let text = std::fs::read_to_string(chessboard("corners.csv")).unwrap();
    text.lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0] == image).then(|| {
                (
                    (f[1].parse().unwrap(), f[2].parse().unwrap()),
                    Point2::new(f[3].parse().unwrap(), f[4].parse().unwrap()),
                )
            })
        })
        .collect()
}

fn pose(k: usize) -> (Rotation3<f64>, Vector3<f64>) {
    let p = bundled_poses()[k];
    (
        Rotation3::from_scaled_axis(Vector3::new(p[0], p[1], p[2])),
        Vector3::new(p[3], p[4], p[5]),
    )
}

/// RMS residual (same units as `b`) and scale of the best similarity `b ≈ s R a + t`
/// (Umeyama 1991).
fn similarity_fit(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> (f64, f64) {
    let n = a.len() as f64;
    let (ma, mb) = (
        a.iter().sum::<Vector3<f64>>() / n,
        b.iter().sum::<Vector3<f64>>() / n,
    );
    let mut cov = Matrix3::zeros();
    let mut va = 0.0;
    for (p, q) in a.iter().zip(b) {
        cov += (q - mb) * (p - ma).transpose();
        va += (p - ma).norm_squared();
    }
    cov /= n;
    va /= n;
    let svd = cov.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Vector3::new(1.0, 1.0, 1.0);
    if (u * vt).determinant() < 0.0 {
        d.z = -1.0;
    }
    let r = u * Matrix3::from_diagonal(&d) * vt;
    let s = svd.singular_values.dot(&d) / va;
    let t = mb - s * r * ma;
    let sq: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| (s * r * p + t - q).norm_squared())
        .sum();
    ((sq / n).sqrt(), s)
}

struct PairResult {
    rot_err_deg: f64,
    dir_err_deg: f64,
    reprojection_rms_px: f64,
    board_rms_mm: f64,
    board_scale: f64,
    inliers: usize,
}

fn run_pair(camera: &Camera<f64>, a: usize, b: usize) -> PairResult {
    let (ca, cb) = (corners(NAMES[a]), corners(NAMES[b]));
    let keys: Vec<(u32, u32)> = ca.keys().filter(|k| cb.contains_key(k)).copied().collect();
    let undist = |p: &Point2<f64>| camera.undistort_pixel(p).unwrap();
    let x1: Vec<Point2<f64>> = keys.iter().map(|k| undist(&ca[k])).collect();
    let x2: Vec<Point2<f64>> = keys.iter().map(|k| undist(&cb[k])).collect();
    let k = camera.intrinsics;
    let cfg = RansacConfig {
        threshold: 1.0,
        confidence: 0.999,
        ..Default::default()
    }
    .check()
    .unwrap();
    let mut mask = vec![false; x1.len()];
    let (e, _) = find_essential(&k, &k, &x1, &x2, &cfg, &mut mask).unwrap();
    let rp = recover_pose(&e, &k, &k, &x1, &x2, 50.0, &mut mask).unwrap();
    let ((ra, ta), (rb, tb)) = (pose(a), pose(b));
    let r_true = rb * ra.inverse();
    let t_true = tb - r_true * ta;
    let rot_err_deg = (rp.pose.rotation() * r_true.inverse()).angle().to_degrees();
    let dir_err_deg = rp
        .pose
        .translation()
        .dot(&t_true.normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    // Triangulate the supporting corners, scale by the true baseline (metres), fit the board.
    let p1 = Transform::<View1, View1, f64>::identity();
    let (mut rec, mut board, mut sq) = (vec![], vec![], 0.0);
    for ((key, (p, q)), m) in keys.iter().zip(x1.iter().zip(&x2)).zip(&mask) {
        if !m {
            continue;
        }
        let (n1, n2) = (
            k.pixel_to_normalized(p).unwrap(),
            k.pixel_to_normalized(q).unwrap(),
        );
        let Ok(t) = triangulate_optimal(&p1, &rp.pose, &n1, &n2) else {
            continue;
        };
        sq += (t.error1 * k.fx()).powi(2) + (t.error2 * k.fx()).powi(2);
        rec.push(t.point.coords * t_true.norm());
        board.push(Vector3::new(
            0.025 * key.0 as f64,
            0.025 * key.1 as f64,
            0.0,
        ));
    }
    let (board_rms, board_scale) = similarity_fit(&board, &rec);
    PairResult {
        rot_err_deg,
        dir_err_deg,
        reprojection_rms_px: (sq / (2 * rec.len()) as f64).sqrt(),
        board_rms_mm: board_rms * 1000.0 / board_scale,
        board_scale,
        inliers: rec.len(),
    }
}

#[test]
fn chessboard_pairs_against_calibrated_poses() {
    let camera = bundled_camera().camera;
    let idx = |n: &str| NAMES.iter().position(|m| *m == n).unwrap();
    let pairs = [
        ("left01", "left02"),
        ("left01", "left03"),
        ("left02", "left03"),
        ("left03", "left05"),
        ("left11", "left12"),
        ("left05", "left12"),
        ("left06", "left07"),
        ("left07", "left08"),
        ("left01", "left04"),
        ("left11", "left14"),
        ("left04", "left09"),
        ("left02", "left13"),
    ];
    let mut truths = 0;
    println!("pair | rot err deg | t dir err deg | inliers | reproj RMS px | board RMS mm | scale");
    for (a, b) in pairs {
        let r = run_pair(&camera, idx(a), idx(b));
        println!(
            "{a}-{b} | {:.3} | {:.3} | {} | {:.3} | {:.2} | {:.3}",
            r.rot_err_deg,
            r.dir_err_deg,
            r.inliers,
            r.reprojection_rms_px,
            r.board_rms_mm,
            r.board_scale
        );
        // Every answer explains the corners at their noise level (cornerSubPix: ~0.1 px).
        assert!(
            r.reprojection_rms_px < 0.3,
            "{a}-{b}: {}",
            r.reprojection_rms_px
        );
        let is_truth = r.rot_err_deg < 5.0;
        if is_truth {
            truths += 1;
            // The calibrated poses are themselves estimates (0.1-0.2 deg per view from the
            // calibration's reprojection RMS of ~0.2 px), and E from a plane is less
            // well conditioned than from a scene with depth: 1.5 deg and 3 deg leave a
            // margin over the worst pair measured (left01-left02, 1.2 deg and 1.7 deg).
            assert!(r.rot_err_deg < 1.5 && r.dir_err_deg < 3.0, "{a}-{b}");
            // The board up to scale: 54 corners on a 200 x 125 mm board, within 2 mm RMS
            // (a 0.1 px corner error at 0.3-0.6 m depth is 0.05-0.1 mm across the image,
            // 0.5-1.5 mm along the rays for these baselines); scaled by the true baseline the
            // board comes out at its true size within 5 % (the t direction error moves the
            // depth of every point).
            assert!(r.board_rms_mm < 2.0, "{a}-{b}: {} mm", r.board_rms_mm);
            assert!(
                (r.board_scale - 1.0).abs() < 0.05,
                "{a}-{b}: {}",
                r.board_scale
            );
        } else {
            // The planar twin: it explains the corners (above) but reconstructs a board that
            // no similarity maps onto the true one.
            assert!(r.board_rms_mm > 5.0, "{a}-{b}: {} mm", r.board_rms_mm);
        }
    }
    // Deterministic (seeded RANSAC): 7 of these 12 pairs land on the true pose.
    println!("{truths} of {} pairs on the true pose", pairs.len());
    assert!(truths >= 6, "{truths}");
}
