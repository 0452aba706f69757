//! Camera pose from a planar target or from 3D points, and its refinement.
//!
//! Every solver returns a world-to-camera [`Pose`] (`X_c = R X + t`, OpenCV's `rvec`/`tvec`);
//! for a planar target the world frame is the target's, with the target in its `Z = 0` plane.
//!
//! - [`pose_from_homography`]: the textbook decomposition `H ~ K [r₁ r₂ t]`, projected onto
//!   the closest rotation;
//! - [`ippe()`], [`solve_planar`]: IPPE (Collins & Bartoli 2014), both solutions of the planar
//!   ambiguity, sorted by reprojection error, refined;
//! - [`p3p()`]: Lambda Twist (Persson & Nordberg 2018), the up to four poses from three points;
//! - [`epnp()`]: EPnP (Lepetit et al. 2009) for `N ≥ 4` non-coplanar points;
//! - [`solve_pnp`], [`solve_pnp_ransac`]: EPnP + refinement, and RANSAC over P3P samples
//!   ([`PnpEstimator`]) with EPnP local optimisation (OpenCV's `solvePnP`, `solvePnPRansac`);
//! - [`solve_planar_integer`], [`refine_planar_integer`]: the planar pose with integer
//!   per-point arithmetic, for cores without an FPU;
//! - [`refine_pose`]: Levenberg-Marquardt on the reprojection error in pixels (lens
//!   distortion included), rotation updated as `exp([δω]ₓ) R`.
//!
//! ```
//! use camgeom::camera::{Camera, Distortion, Intrinsics};
//! use camgeom::nalgebra::{Point2, Point3, Vector3};
//! use camgeom::pose::{PlanarConfig, solve_planar};
//! use camgeom::transform::Pose;
//!
//! let camera = Camera::new(
//!     Intrinsics::new(600.0f64, 600.0, 320.0, 240.0)?,
//!     Distortion::from_opencv([-0.2, 0.05, 0.0, 0.0, 0.0])?,
//! );
//! let (rvec, tvec) = (Vector3::new(0.4, -0.3, 0.1), Vector3::new(-0.15, -0.1, 0.8));
//! let truth = Pose::from_rodrigues(rvec, tvec)?;
//! // A 4x3 grid of target points 0.1 m apart (Z = 0), imaged through the lens.
//! let model: [Point2<f64>; 12] =
//!     core::array::from_fn(|k| Point2::new(0.1 * (k % 4) as f64, 0.1 * (k / 4) as f64));
//! let mut pixels = [Point2::origin(); 12];
//! for (m, u) in model.iter().zip(&mut pixels) {
//!     *u = camera.project(&truth, &Point3::new(m.x, m.y, 0.0))?;
//! }
//! let mut scratch = [Point2::origin(); 12];
//! let p = solve_planar(&camera, &model, &pixels, &mut scratch, &PlanarConfig::default())?;
//! // Exact pixels: the pose comes back to rounding (the refinement runs on pixel errors).
//! assert!((p.best.pose.rotation_vector() - truth.rotation_vector()).norm() < 1e-9);
//! assert!((p.best.pose.translation() - truth.translation()).norm() < 1e-9);
//! assert!(p.best.rms_px < 1e-6 && !p.is_ambiguous(1.5));
//! # Ok::<(), camgeom::Error>(())
//! ```

mod epnp;
mod from_homography;
mod integer;
mod ippe;
mod p3p;
mod pnp;
mod refine;

pub use epnp::{BETA_GAUSS_NEWTON_ITERATIONS, epnp};
pub use from_homography::pose_from_homography;
pub use integer::{MAX_PLANAR_POINTS, PlanarPoint, refine_planar_integer, solve_planar_integer};
pub use ippe::{PlanarConfig, PlanarPose, ippe, solve_planar};
pub use p3p::{LAMBDA_REFINE_ITERATIONS, MAX_P3P_SOLUTIONS, p3p};
pub use pnp::{PNP_REFINE_ITERATIONS, PnpEstimator, solve_pnp, solve_pnp_ransac};
pub use refine::{refine_pose, refine_pose_masked, reprojection_rms};

use crate::scalar::Real;
use crate::transform::Pose;

/// A pose and its RMS reprojection error, `√(Σ |u(Xᵢ) - uᵢ|² / N)` in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseEstimate<T: Real = f32> {
    /// World-to-camera pose.
    pub pose: Pose<T>,
    /// RMS reprojection error in pixels.
    pub rms_px: T,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Camera, Distortion, Intrinsics};
    use crate::homography::dlt;
    use crate::rng::Pcg32;
    use nalgebra::{Point2, Point3, Vector3};

    fn camera() -> Camera<f64> {
        let k = Intrinsics::new(535.9, 535.9, 342.3, 235.6).unwrap();
        Camera::new(
            k,
            Distortion::from_opencv([-0.266, -0.0386, 1.78e-3, -2.81e-4, 0.238]).unwrap(),
        )
    }

    /// Angle of `R_a R_bᵀ` in degrees (via the quaternion, `2 atan2(|v|, w)`, which unlike
    /// `acos((tr R - 1)/2)` stays accurate near zero).
    fn rot_err(a: &Pose<f64>, b: &Pose<f64>) -> f64 {
        (a.isometry().rotation * b.isometry().rotation.inverse())
            .angle()
            .to_degrees()
    }

    fn board() -> [Point2<f64>; 54] {
        core::array::from_fn(|k| Point2::new(0.025 * (k % 9) as f64, 0.025 * (k / 9) as f64))
    }

    fn views() -> [Pose<f64>; 3] {
        [
            Pose::from_rodrigues(
                Vector3::new(0.169, 0.276, 0.013),
                Vector3::new(-0.075, -0.109, 0.400),
            )
            .unwrap(),
            Pose::from_rodrigues(
                Vector3::new(0.413, 0.650, -1.337),
                Vector3::new(-0.059, 0.083, 0.354),
            )
            .unwrap(),
            Pose::from_rodrigues(
                Vector3::new(-0.277, 0.187, 0.355),
                Vector3::new(-0.040, -0.100, 0.320),
            )
            .unwrap(),
        ]
    }

    #[test]
    fn exact_planar_data_gives_the_true_pose() {
        let cam = camera();
        let model = board();
        for truth in views() {
            let pixels = model.map(|p| cam.project(&truth, &Point3::new(p.x, p.y, 0.0)).unwrap());
            let mut scratch = [Point2::origin(); 54];
            let sol = solve_planar(
                &cam,
                &model,
                &pixels,
                &mut scratch,
                &PlanarConfig::default(),
            )
            .unwrap();
            assert!(sol.best.rms_px < 1e-8, "{:?}", sol.best);
            assert!(
                rot_err(&sol.best.pose, &truth) < 1e-7,
                "{} deg",
                rot_err(&sol.best.pose, &truth)
            );
            assert!((sol.best.pose.translation() - truth.translation()).amax() < 1e-9);
            // A board filling a good part of the image is not ambiguous.
            assert!(!sol.alternative.rms_px.is_nan() && !sol.is_ambiguous(1.5));
            // The raw IPPE solution (before refinement) is already exact on exact data.
            let normalized = pixels.map(|u| cam.undistort_to_normalized(&u).unwrap());
            let [(p0, e0), (_, e1)] = ippe(&model, &normalized).unwrap();
            assert!(e0 <= e1 && e0 < 1e-10, "{e0} {e1}");
            assert!(rot_err(&p0, &truth) < 1e-7);
            // So is the homography decomposition, on undistorted pixels.
            let ideal = pixels.map(|u| cam.undistort_pixel(&u).unwrap());
            let h = dlt(&model, &ideal).unwrap();
            let ph = pose_from_homography(&cam.intrinsics, &h).unwrap();
            assert!(
                rot_err(&ph, &truth) < 1e-6
                    && (ph.translation() - truth.translation()).amax() < 1e-8
            );
        }
    }

    /// With 0.5 px noise the refined IPPE pose is at least as accurate as the homography
    /// decomposition, over many trials (the decomposition ignores the geometry of the noise).
    #[test]
    fn refined_ippe_beats_homography_decomposition_under_noise() {
        let cam = camera();
        let model = board();
        let mut g = Pcg32::new(3);
        let (mut e_h, mut e_ippe) = (0.0, 0.0);
        for truth in views() {
            for _ in 0..20 {
                let pixels = model.map(|p| {
                    let u = cam.project(&truth, &Point3::new(p.x, p.y, 0.0)).unwrap();
                    Point2::new(u.x + 0.5 * g.normal(), u.y + 0.5 * g.normal())
                });
                let mut scratch = [Point2::origin(); 54];
                let sol = solve_planar(
                    &cam,
                    &model,
                    &pixels,
                    &mut scratch,
                    &PlanarConfig::default(),
                )
                .unwrap();
                let ideal = pixels.map(|u| cam.undistort_pixel(&u).unwrap());
                let ph =
                    pose_from_homography(&cam.intrinsics, &dlt(&model, &ideal).unwrap()).unwrap();
                e_h += rot_err(&ph, &truth);
                e_ippe += rot_err(&sol.best.pose, &truth);
                // The refined pose explains the data at the noise level (σ√2 ≈ 0.7 px RMS).
                assert!(sol.best.rms_px < 0.9, "{}", sol.best.rms_px);
            }
        }
        assert!(
            e_ippe <= e_h,
            "IPPE+LM {e_ippe} vs homography {e_h} (sum of degrees)"
        );
    }

    /// The second IPPE solution is refined only when it is within `alternative_ratio` of the
    /// best; the best pose is the same either way, and a skipped alternative reports its
    /// unrefined error, which refinement could only lower.
    #[test]
    fn far_alternative_is_not_refined_and_the_best_is_unchanged() {
        let cam = camera();
        let model = board();
        let mut g = Pcg32::new(17);
        for truth in views() {
            let pixels = model.map(|p| {
                let u = cam.project(&truth, &Point3::new(p.x, p.y, 0.0)).unwrap();
                Point2::new(u.x + 0.5 * g.normal(), u.y + 0.5 * g.normal())
            });
            let scratch = [Point2::origin(); 54];
            let solve = |alternative_ratio| {
                let cfg = PlanarConfig {
                    alternative_ratio,
                    ..PlanarConfig::default()
                };
                solve_planar(&cam, &model, &pixels, &mut scratch.clone(), &cfg).unwrap()
            };
            let (skipped, refined) = (solve(4), solve(u8::MAX));
            // Refined, the alternative can descend into the best's own minimum and be reported
            // in its place: the same pose to the LM's convergence (measured up to 1.1e-9 apart).
            let (a, b) = (skipped.best, refined.best);
            let dr = (a.pose.rotation().matrix() - b.pose.rotation().matrix()).amax();
            assert!(dr < 1e-8, "{dr}");
            assert!((a.pose.translation() - b.pose.translation()).norm() < 1e-8);
            assert!((a.rms_px - b.rms_px).abs() < 1e-8);
            // These views are far from fronto-parallel: the alternative is many times off.
            assert!(skipped.alternative.rms_px > 4.0 * skipped.best.rms_px);
            assert!(refined.alternative.rms_px <= skipped.alternative.rms_px);
            // Unrefined: the second IPPE solution itself, with its own error.
            let normalized = pixels.map(|u| cam.undistort_to_normalized(&u).unwrap());
            let [_, (p1, _)] = ippe(&model, &normalized).unwrap();
            assert_eq!(skipped.alternative.pose, p1);
            let lifted = |i: usize| model.get(i).map(|p| Point3::new(p.x, p.y, 0.0));
            let rms = refine::rms_with(&cam, &p1, &pixels, lifted).unwrap();
            assert_eq!(skipped.alternative.rms_px, rms);
        }
    }

    /// A small, fronto-parallel target far away: both solutions fit nearly equally well.
    #[test]
    fn fronto_parallel_target_is_flagged_ambiguous() {
        let cam = Camera::pinhole(camera().intrinsics);
        let model = [
            Point2::new(-0.02, -0.02),
            Point2::new(0.02, -0.02),
            Point2::new(0.02, 0.02),
            Point2::new(-0.02, 0.02),
        ];
        let truth = Pose::from_rodrigues(Vector3::new(0.05, 0.0, 0.0), Vector3::new(0.0, 0.0, 2.0))
            .unwrap();
        let mut g = Pcg32::new(9);
        let pixels = model.map(|p| {
            let u = cam.project(&truth, &Point3::new(p.x, p.y, 0.0)).unwrap();
            Point2::new(u.x + 0.3 * g.normal(), u.y + 0.3 * g.normal())
        });
        let mut scratch = [Point2::origin(); 4];
        let sol = solve_planar(
            &cam,
            &model,
            &pixels,
            &mut scratch,
            &PlanarConfig::default(),
        )
        .unwrap();
        assert!(sol.is_ambiguous(2.0), "{sol:?}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let cam = camera();
        let model = board();
        let mut scratch = [Point2::origin(); 4];
        let pix = [Point2::new(1.0, 1.0); 54];
        // Scratch too short.
        assert!(matches!(
            solve_planar(&cam, &model, &pix, &mut scratch, &PlanarConfig::default()),
            Err(crate::Error::LengthMismatch)
        ));
        // Too few points, collinear points, NaN.
        let n3 = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(0.0, 1.0),
        ];
        assert_eq!(ippe(&n3, &n3).err(), Some(crate::Error::TooFewPoints));
        let line = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(2.0, 0.0),
            Point2::new(3.0, 0.0),
        ];
        assert!(ippe(&line, &line).is_err());
        let mut nan = line;
        nan[2].y = f64::NAN;
        assert_eq!(
            ippe(&board()[..4], &nan).err(),
            Some(crate::Error::NonFinite)
        );
    }
}
