//! Pose from `N` 3D-2D correspondences through a calibrated camera: EPnP + Levenberg-Marquardt
//! ([`solve_pnp`]) and its robust counterpart on the generic RANSAC loop ([`solve_pnp_ransac`]).

use nalgebra::{Point2, Point3, Vector3};

use super::PoseEstimate;
use super::epnp::{epnp, epnp_with};
use super::p3p::p3p;
use super::refine::{refine_pose, refine_pose_masked};
use crate::camera::Camera;
use crate::ransac::{Estimator, RansacParams, RansacReport, ransac};
use crate::scalar::{Real, above};
use crate::transform::Pose;
use crate::{Error, Result};

/// Levenberg-Marquardt steps after EPnP (it starts close: 2..5 steps are typical).
pub const PNP_REFINE_ITERATIONS: u8 = 20;

/// A minimal sample: four world points and their bearings `(x_n, y_n, 1)`.
type Sample<T> = ([Point3<T>; 4], [Vector3<T>; 4]);

/// Pose from `N ≥ 4` non-coplanar world points and their pixels (OpenCV's
/// `solvePnP(SOLVEPNP_EPNP)` followed by `solvePnPRefineLM`): pixels are undistorted to
/// normalised coordinates into `scratch` (`scratch.len() ≥ N`), [`epnp`] gives the start, and
/// [`refine_pose`] minimises `Σ |u(R Xᵢ + t) - uᵢ|²` through the full camera model.
///
/// Errors: [`Error::LengthMismatch`] (slices, or `scratch` too short); as
/// [`Camera::undistort_to_normalized`], [`epnp`] (planar points: use
/// [`super::solve_planar`]) and [`refine_pose`].
#[doc(alias = "solvePnP")]
pub fn solve_pnp<T: Real>(
    camera: &Camera<T>,
    world: &[Point3<T>],
    pixels: &[Point2<T>],
    scratch: &mut [Point2<T>],
) -> Result<PoseEstimate<T>> {
    if world.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    let normalized = scratch
        .get_mut(..pixels.len())
        .ok_or(Error::LengthMismatch)?;
    for (n, u) in normalized.iter_mut().zip(pixels) {
        *n = camera.undistort_to_normalized(u)?;
    }
    let (start, _) = epnp(world, normalized)?;
    refine_pose(camera, &start, world, pixels, PNP_REFINE_ITERATIONS)
}

/// PnP as an [`Estimator`]: minimal samples of four points, P3P ([`p3p`]) on the first three
/// with the fourth choosing among its (up to four) poses; residual the squared reprojection
/// error in pixels through the camera, `r² = |u(R Xᵢ + t) - uᵢ|²`; local optimisation by EPnP
/// on the inliers and a few Levenberg-Marquardt steps; final polish by Levenberg-Marquardt on
/// the inliers.
#[derive(Debug, Clone, Copy)]
pub struct PnpEstimator<'a, T: Real = f32> {
    camera: &'a Camera<T>,
    world: &'a [Point3<T>],
    pixels: &'a [Point2<T>],
    normalized: &'a [Point2<T>],
    /// Levenberg-Marquardt steps of [`Estimator::refine`] (the final polish).
    pub refine_iterations: u8,
    /// Levenberg-Marquardt steps after each EPnP refit of the local optimisation.
    pub refit_iterations: u8,
}

impl<'a, T: Real> PnpEstimator<'a, T> {
    /// Correspondences `(world[i], pixels[i])` with `normalized[i]` the undistorted normalised
    /// coordinates of `pixels[i]` (see [`Camera::undistort_to_normalized`]); errors with
    /// [`Error::LengthMismatch`].
    pub fn new(
        camera: &'a Camera<T>,
        world: &'a [Point3<T>],
        pixels: &'a [Point2<T>],
        normalized: &'a [Point2<T>],
    ) -> Result<Self> {
        if world.len() != pixels.len() || normalized.len() != pixels.len() {
            return Err(Error::LengthMismatch);
        }
        Ok(Self {
            camera,
            world,
            pixels,
            normalized,
            refine_iterations: PNP_REFINE_ITERATIONS,
            refit_iterations: 5,
        })
    }

    fn gather(&self, sample: &[usize]) -> Option<Sample<T>> {
        let mut x = [Point3::origin(); 4];
        let mut y = [Vector3::zeros(); 4];
        if sample.len() != 4 {
            return None;
        }
        for ((i, xi), yi) in sample.iter().zip(x.iter_mut()).zip(y.iter_mut()) {
            *xi = *self.world.get(*i)?;
            let n = self.normalized.get(*i)?;
            *yi = Vector3::new(n.x, n.y, T::one());
        }
        Some((x, y))
    }

    /// Levenberg-Marquardt on the reprojection error of the points with `inliers[i]`.
    fn polish(&self, pose: &Pose<T>, inliers: &[bool], iterations: u8) -> Option<Pose<T>> {
        refine_pose_masked(
            self.camera,
            pose,
            self.world,
            self.pixels,
            inliers,
            iterations,
        )
        .ok()
        .map(|e| e.pose)
    }
}

impl<T: Real> Estimator for PnpEstimator<'_, T> {
    type Model = Pose<T>;
    type Scalar = T;

    fn num_points(&self) -> usize {
        self.world.len()
    }

    fn sample_size(&self) -> usize {
        4
    }

    fn is_sample_valid(&self, sample: &[usize]) -> bool {
        // The P3P triangle must not be collinear (p3p would say so, but this is cheaper).
        self.gather(sample).is_some_and(|([x1, x2, x3, _], y)| {
            let (d12, d13) = (x1 - x2, x1 - x3);
            let ok = above(
                d12.cross(&d13).norm_squared(),
                T::lit(1e-6) * d12.norm_squared() * d13.norm_squared(),
            );
            ok && y.iter().all(|v| v.x.finite() && v.y.finite())
        })
    }

    fn fit_minimal(&self, sample: &[usize], emit: &mut dyn FnMut(Self::Model)) {
        let Some(([x1, x2, x3, x4], [y1, y2, y3, y4])) = self.gather(sample) else {
            return;
        };
        let Ok(sols) = p3p(&[y1, y2, y3], &[x1, x2, x3]) else {
            return;
        };
        // The fourth point picks one pose (in normalised units, no distortion needed).
        let err = |p: &Pose<T>| -> Option<T> {
            let c = p.apply(&x4);
            above(c.z, T::zero())
                .then(|| (Vector3::new(c.x / c.z, c.y / c.z, T::one()) - y4).norm_squared())
        };
        let mut best: Option<(Pose<T>, T)> = None;
        for s in sols {
            if let Some(e) = err(&s)
                && best.as_ref().is_none_or(|b| e < b.1)
            {
                best = Some((s, e));
            }
        }
        if let Some((pose, _)) = best {
            emit(pose);
        }
    }

    fn residual_sq(&self, pose: &Pose<T>, i: usize) -> Option<T> {
        let u = self.camera.project(pose, self.world.get(i)?).ok()?;
        Some((u - self.pixels.get(i)?).norm_squared())
    }

    fn refit(&self, pose: &Pose<T>, inliers: &[bool]) -> Option<Pose<T>> {
        // EPnP on the inliers (not for planar inlier sets: then LM from the current pose).
        let start = epnp_with(self.world.len(), |i| {
            if *inliers.get(i)? {
                Some((*self.world.get(i)?, *self.normalized.get(i)?))
            } else {
                None
            }
        })
        .map_or(*pose, |(p, _)| p);
        self.polish(&start, inliers, self.refit_iterations)
    }

    fn refine(&self, pose: &Pose<T>, inliers: &[bool]) -> Option<Pose<T>> {
        self.polish(pose, inliers, self.refine_iterations)
    }
}

/// Robust pose from correspondences with outliers (OpenCV's `solvePnPRansac`), writing the
/// inlier mask into `mask`: pixels are undistorted into `scratch` (`scratch.len() ≥ N`), then
/// [`ransac`] runs [`PnpEstimator`] with the inlier threshold of `params` in pixels. The
/// returned RMS is over the inliers.
///
/// Errors: [`Error::LengthMismatch`] (slices, `scratch` too short, `mask.len() != N`); as
/// [`Camera::undistort_to_normalized`] and [`ransac`] ([`Error::Degenerate`] when no sample
/// gave a pose).
#[doc(alias = "solvePnPRansac")]
pub fn solve_pnp_ransac<T: Real>(
    camera: &Camera<T>,
    world: &[Point3<T>],
    pixels: &[Point2<T>],
    scratch: &mut [Point2<T>],
    params: &RansacParams<T>,
    mask: &mut [bool],
) -> Result<(PoseEstimate<T>, RansacReport<T>)> {
    if world.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    let normalized = scratch
        .get_mut(..pixels.len())
        .ok_or(Error::LengthMismatch)?;
    for (n, u) in normalized.iter_mut().zip(pixels) {
        *n = camera.undistort_to_normalized(u)?;
    }
    let est = PnpEstimator::new(camera, world, pixels, normalized)?;
    let (pose, report) = ransac(&est, params, mask)?;
    // The mean of the inliers' squared errors, each divided first: every one is below the
    // threshold's square (finite, `RansacConfig::check`), so the mean is too, where the sum of
    // many could overflow.
    let n = T::lit(report.inliers.max(1) as f64);
    let mut mean = T::zero();
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        mean += est.residual_sq(&pose, i).unwrap_or_else(T::zero) / n;
    }
    let rms_px = mean.sqrt();
    Ok((PoseEstimate { pose, rms_px }, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::{Distortion, Intrinsics};
    use crate::rng::Pcg32;
    use std::vec;
    use std::vec::Vec;

    fn camera() -> Camera<f64> {
        let k = Intrinsics::new(535.9, 535.9, 342.3, 235.6).unwrap();
        Camera::new(
            k,
            Distortion::from_opencv([-0.266, -0.0386, 1.78e-3, -2.81e-4, 0.238]).unwrap(),
        )
    }

    fn scene(g: &mut Pcg32, n: usize) -> (Pose<f64>, Vec<Point3<f64>>) {
        let truth = Pose::from_rodrigues(
            Vector3::new(
                g.uniform(-1.0, 1.0),
                g.uniform(-1.0, 1.0),
                g.uniform(-1.0, 1.0),
            ),
            Vector3::new(
                g.uniform(-0.5, 0.5),
                g.uniform(-0.5, 0.5),
                g.uniform(1.0, 2.0),
            ),
        )
        .unwrap();
        let inv = truth.inverse();
        let world = (0..n)
            .map(|_| {
                let z = g.uniform(1.0, 3.0);
                inv.apply(&Point3::new(
                    g.uniform(-0.5, 0.5) * z,
                    g.uniform(-0.35, 0.35) * z,
                    z,
                ))
            })
            .collect();
        (truth, world)
    }

    #[test]
    fn solve_pnp_is_exact_on_exact_data_with_distortion() {
        let cam = camera();
        let mut g = Pcg32::new(31);
        for n in [4, 5, 6, 10, 40] {
            let (truth, world) = scene(&mut g, n);
            let px: Vec<_> = world
                .iter()
                .map(|x| cam.project(&truth, x).unwrap())
                .collect();
            let mut scratch = vec![Point2::origin(); n];
            let est = solve_pnp(&cam, &world, &px, &mut scratch).unwrap();
            assert!(est.rms_px < 1e-8, "{n}: {est:?}");
            assert!((est.pose.translation() - truth.translation()).amax() < 1e-9);
        }
    }

    #[test]
    fn ransac_finds_the_pose_among_outliers() {
        let cam = camera();
        let mut g = Pcg32::new(32);
        let (truth, world) = scene(&mut g, 100);
        let px: Vec<_> = world
            .iter()
            .enumerate()
            .map(|(i, x)| {
                if i % 2 == 0 {
                    Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0))
                } else {
                    let u = cam.project(&truth, x).unwrap();
                    Point2::new(u.x + 0.5 * g.normal(), u.y + 0.5 * g.normal())
                }
            })
            .collect();
        let mut scratch = vec![Point2::origin(); 100];
        let mut mask = vec![false; 100];
        let (est, report) = solve_pnp_ransac(
            &cam,
            &world,
            &px,
            &mut scratch,
            &RansacParams::default(),
            &mut mask,
        )
        .unwrap();
        assert!(mask.iter().skip(1).step_by(2).all(|m| *m));
        assert!((50..=53).contains(&report.inliers), "{report:?}");
        let r = (est.pose.isometry().rotation * truth.isometry().rotation.inverse())
            .angle()
            .to_degrees();
        // 50 inliers with 0.5 px noise: a tenth of a degree is generous.
        assert!(r < 0.1, "{r} deg");
        assert!(est.rms_px < 0.8, "{est:?}");
        // Deterministic, and f32 finds the same inliers.
        let cam32 = cam.cast::<f32>();
        let w32: Vec<_> = world.iter().map(|p| p.cast::<f32>()).collect();
        let p32: Vec<_> = px.iter().map(|p| p.cast::<f32>()).collect();
        let mut s32 = vec![Point2::origin(); 100];
        let mut m32 = vec![false; 100];
        let (e32, _) = solve_pnp_ransac(
            &cam32,
            &w32,
            &p32,
            &mut s32,
            &RansacParams::default(),
            &mut m32,
        )
        .unwrap();
        assert_eq!(m32, mask);
        let d = (e32.pose.isometry().rotation.cast::<f64>()
            * est.pose.isometry().rotation.inverse())
        .angle()
        .to_degrees();
        assert!(d < 0.01, "{d}");
    }

    #[test]
    fn bad_inputs() {
        let cam = camera();
        let w = [Point3::new(0.0, 0.0, 1.0); 6];
        let px = [Point2::new(10.0, 10.0); 6];
        let mut scratch = [Point2::origin(); 6];
        let mut mask = [false; 6];
        let cfg = crate::ransac::RansacConfig {
            max_iterations: 20,
            ..Default::default()
        }
        .check()
        .unwrap();
        assert!(solve_pnp(&cam, &w, &px, &mut scratch).is_err());
        assert_eq!(
            solve_pnp(&cam, &w, &px, &mut scratch[..3]).unwrap_err(),
            Error::LengthMismatch
        );
        assert_eq!(
            solve_pnp_ransac(&cam, &w, &px, &mut scratch, &cfg, &mut mask).unwrap_err(),
            Error::Degenerate
        );
        assert_eq!(
            solve_pnp_ransac(&cam, &w, &px[..5], &mut scratch, &cfg, &mut mask).unwrap_err(),
            Error::LengthMismatch
        );
    }
}
