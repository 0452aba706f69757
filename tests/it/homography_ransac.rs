//! RANSAC against OpenCV's `findHomography(src, dst, RANSAC, 3.0)` on the fixture of
//! `scripts/fixtures/homography_dlt.py` (30 % outliers, 0.5 px noise).

use camgeom::homography::{Homography, find_homography};
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::ransac::RansacParams;

use crate::fixtures::homography_dlt as fixture;

fn mat(m: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

fn grid_gap(a: &Homography<f64>, b: &Matrix3<f64>) -> f64 {
    let b = Homography::from_matrix(b).unwrap();
    let mut worst = 0.0f64;
    for i in 0..=8 {
        for j in 0..=6 {
            let p = Point2::new(80.0 * i as f64, 80.0 * j as f64);
            worst = worst.max((a.transfer(&p).unwrap() - b.transfer(&p).unwrap()).norm());
        }
    }
    worst
}

#[test]
fn same_inliers_as_opencv() {
    let c = &fixture::OUTLIERS;
    let src: Vec<Point2<f64>> = c.src.iter().map(|p| Point2::new(p[0], p[1])).collect();
    let dst: Vec<Point2<f64>> = c.dst.iter().map(|p| Point2::new(p[0], p[1])).collect();
    let mut mask = vec![false; src.len()];
    let (h, report) = find_homography(&src, &dst, &RansacParams::default(), &mut mask).unwrap();
    let differ = mask
        .iter()
        .zip(c.opencv_inliers.iter())
        .filter(|(a, b)| a != b)
        .count();
    let gap_cv = grid_gap(&h, &mat(&c.opencv));
    let gap_truth = grid_gap(&h, &mat(&c.truth));
    let cv_truth = grid_gap(
        &Homography::from_matrix(&mat(&c.opencv)).unwrap(),
        &mat(&c.truth),
    );
    println!(
        "RANSAC: {} inliers ({} differ from OpenCV's), {} samples; grid gap to OpenCV {gap_cv:.3} px, \
         to truth {gap_truth:.3} px (OpenCV to truth {cv_truth:.3} px)",
        report.inliers, differ, report.iterations
    );
    // Same threshold (3 px), clean separation between the 0.5 px inliers and uniform outliers:
    // the masks must agree exactly.
    assert_eq!(differ, 0);
    // Both fit the same 42 inliers, OpenCV by forward-error LM, we by symmetric-error LM:
    // they differ by a fraction of the noise over the image.
    assert!(gap_cv < 0.5, "{gap_cv}");
    assert!(gap_truth < 1.0, "{gap_truth}");

    // f32 finds the same inliers.
    let s32: Vec<Point2<f32>> = src.iter().map(|p| p.cast()).collect();
    let d32: Vec<Point2<f32>> = dst.iter().map(|p| p.cast()).collect();
    let mut mask32 = vec![false; src.len()];
    let (h32, _) = find_homography(&s32, &d32, &RansacParams::default(), &mut mask32).unwrap();
    assert_eq!(mask32, mask);
    let h32 = Homography::from_matrix(&h32.matrix().cast::<f64>()).unwrap();
    assert!(grid_gap(&h32, h.matrix()) < 0.01);
}
