//! A homography from point matches with outliers: RANSAC (MSAC, adaptive stopping, local
//! optimisation) then Levenberg-Marquardt on the inliers.
//!
//! `cargo run --example homography`
//!
//! The matches are made here from a known homography `H` (`x' ~ H x`), with 0.5 px of noise
//! on every match and 30 % of them replaced by random pixels; the estimate is then compared
//! with `H` by the transfer error over the image.

use camgeom::homography::{Homography, find_homography};
use camgeom::nalgebra::{Matrix3, Point2};
use camgeom::ransac::RansacParams;
use camgeom::rng::Pcg32;

fn main() -> camgeom::Result<()> {
    let truth = Homography::from_matrix(&Matrix3::new(
        0.9, 0.05, 30.0, //
        -0.04, 1.1, 12.0, //
        1e-4, 2e-4, 1.0,
    ))?;
    let mut rng = Pcg32::new(7);
    let (mut src, mut dst) = (Vec::new(), Vec::new());
    for k in 0..200 {
        let p = Point2::new(
            rng.uniform(0.0, 640.0) as f32,
            rng.uniform(0.0, 480.0) as f32,
        );
        let q = if k % 10 < 3 {
            Point2::new(
                rng.uniform(0.0, 640.0) as f32,
                rng.uniform(0.0, 480.0) as f32,
            )
        } else {
            let t = truth.transfer(&p)?;
            Point2::new(
                t.x + 0.5 * rng.normal() as f32,
                t.y + 0.5 * rng.normal() as f32,
            )
        };
        src.push(p);
        dst.push(q);
    }
    let mut inliers = vec![false; src.len()];
    let (h, report) = find_homography(&src, &dst, &RansacParams::default(), &mut inliers)?;
    println!(
        "{} inliers of {} after {} samples; MSAC cost {:.1}",
        report.inliers,
        src.len(),
        report.iterations,
        report.cost
    );
    let mut worst = 0.0f32;
    for y in (0..480).step_by(40) {
        for x in (0..640).step_by(40) {
            let p = Point2::new(x as f32, y as f32);
            worst = worst.max((h.transfer(&p)? - truth.transfer(&p)?).norm());
        }
    }
    println!("largest transfer error against the true H over the image: {worst:.2} px");
    Ok(())
}
