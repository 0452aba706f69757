//! Robust homography estimation: RANSAC with the 4-point solver, MSAC scoring, DLT local
//! optimisation and a final Levenberg-Marquardt polish, on the generic [`crate::ransac`] loop.

use nalgebra::Point2;

use super::refine::refine_masked;
use super::{Homography, check_sample, dlt_masked};
use crate::Result;
use crate::ransac::{Estimator, RansacParams, RansacReport, ransac};
use crate::scalar::Real;

/// The four points of a minimal sample.
type Quad<T> = [Point2<T>; 4];

/// A homography with its inverse, for the symmetric residual.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HomographyModel<T: Real = f32> {
    /// `H`, `dst ~ H src`.
    pub h: Homography<T>,
    /// `H⁻¹`.
    pub inverse: Homography<T>,
}

impl<T: Real> HomographyModel<T> {
    /// `H` and its inverse; errors as [`Homography::inverse`].
    pub fn new(h: Homography<T>) -> Result<Self> {
        Ok(Self {
            h,
            inverse: h.inverse()?,
        })
    }
}

/// Homography estimation over point correspondences as an [`Estimator`].
///
/// Residual: the mean squared symmetric transfer error of a pair,
/// `r² = (|dst - π(H src)|² + |src - π(H⁻¹ dst)|²) / 2` (pixels²), so the RANSAC threshold is
/// in pixels as for a one-sided error.
#[derive(Debug, Clone, Copy)]
pub struct HomographyEstimator<'a, T: Real = f32> {
    src: &'a [Point2<T>],
    dst: &'a [Point2<T>],
    /// Levenberg-Marquardt steps of [`Estimator::refine`].
    pub refine_iterations: u8,
}

impl<'a, T: Real> HomographyEstimator<'a, T> {
    /// Pairs `(src[i], dst[i])`; errors with [`crate::Error::LengthMismatch`].
    pub fn new(src: &'a [Point2<T>], dst: &'a [Point2<T>]) -> Result<Self> {
        if src.len() != dst.len() {
            return Err(crate::Error::LengthMismatch);
        }
        Ok(Self {
            src,
            dst,
            refine_iterations: 10,
        })
    }

    fn gather(&self, sample: &[usize]) -> Option<(Quad<T>, Quad<T>)> {
        let mut s = [Point2::origin(); 4];
        let mut d = [Point2::origin(); 4];
        if sample.len() != 4 {
            return None;
        }
        for ((i, ps), pd) in sample.iter().zip(s.iter_mut()).zip(d.iter_mut()) {
            *ps = *self.src.get(*i)?;
            *pd = *self.dst.get(*i)?;
        }
        Some((s, d))
    }
}

impl<T: Real> Estimator for HomographyEstimator<'_, T> {
    type Model = HomographyModel<T>;
    type Scalar = T;

    fn num_points(&self) -> usize {
        self.src.len()
    }

    fn sample_size(&self) -> usize {
        4
    }

    fn is_sample_valid(&self, sample: &[usize]) -> bool {
        self.gather(sample)
            .is_some_and(|(s, d)| check_sample(&s, &d).is_ok())
    }

    fn fit_minimal(&self, sample: &[usize], emit: &mut dyn FnMut(Self::Model)) {
        if let Some((s, d)) = self.gather(sample)
            && let Ok(m) = Homography::from_four_points(&s, &d).and_then(HomographyModel::new)
        {
            emit(m);
        }
    }

    fn residual_sq(&self, m: &Self::Model, i: usize) -> Option<T> {
        let (s, d) = (self.src.get(i)?, self.dst.get(i)?);
        let f = m.h.transfer(s).ok()? - d;
        let b = m.inverse.transfer(d).ok()? - s;
        Some((f.norm_squared() + b.norm_squared()) * T::lit(0.5))
    }

    fn refit(&self, _: &Self::Model, inliers: &[bool]) -> Option<Self::Model> {
        dlt_masked(self.src, self.dst, inliers)
            .and_then(HomographyModel::new)
            .ok()
    }

    /// A DLT on the inliers: the model it starts from plays no part.
    fn refit_is_mask_only(&self) -> bool {
        true
    }

    fn refine(&self, m: &Self::Model, inliers: &[bool]) -> Option<Self::Model> {
        refine_masked(&m.h, self.src, self.dst, inliers, self.refine_iterations)
            .and_then(|r| HomographyModel::new(r.homography))
            .ok()
    }
}

/// Robust homography `dst ~ H src` from correspondences with outliers (OpenCV's
/// `findHomography(src, dst, RANSAC)` counterpart), writing the inlier mask into `inliers`.
///
/// Minimal samples go through [`check_sample`] (collinear or folding samples are skipped
/// without solving), models are scored by MSAC on the symmetric transfer error, every new best
/// model is refitted by [`dlt_masked`] on its inliers (`local_optimization` rounds of the
/// [`RansacConfig`](crate::ransac::RansacConfig) checked into `params`), and the winner is
/// polished by [`super::refine_masked`] (10 Levenberg-Marquardt steps) when `refine`. The
/// iteration count adapts to the inlier ratio and is capped by `max_iterations`; the same
/// `seed` gives the same result everywhere.
///
/// Errors: see [`ransac`] ([`crate::Error::Degenerate`] when no sample gave a model).
///
/// ```
/// use camgeom::homography::{Homography, find_homography};
/// use camgeom::nalgebra::{Matrix3, Point2, Vector2};
/// use camgeom::ransac::RansacParams;
///
/// let truth = Homography::from_matrix(&Matrix3::new(
///     0.9, 0.05, 30.0, -0.04, 1.1, 12.0, 1e-4, 2e-4, 1.0,
/// ))?;
/// // A 6x5 grid of exact matches; every fourth is moved 40 px away (an outlier).
/// let src: Vec<Point2<f32>> =
///     (0..30).map(|i| Point2::new((i % 6) as f32 * 100.0, (i / 6) as f32 * 100.0)).collect();
/// let mut dst = Vec::new();
/// for (i, s) in src.iter().enumerate() {
///     let off = if i % 4 == 0 { Vector2::new(40.0, -30.0) } else { Vector2::zeros() };
///     dst.push(truth.transfer(s)? + off);
/// }
/// let mut inliers = [false; 30];
/// let (h, report) = find_homography(&src, &dst, &RansacParams::default(), &mut inliers)?;
/// assert_eq!(report.inliers, 22);
/// assert!(inliers.iter().enumerate().all(|(i, &ok)| ok == (i % 4 != 0)));
/// // The inliers are exact: what is left is f32 rounding.
/// let probe = Point2::new(250.0, 180.0);
/// assert!((h.transfer(&probe)? - truth.transfer(&probe)?).norm() < 0.01);
/// # Ok::<(), camgeom::Error>(())
/// ```
#[doc(alias = "findHomography")]
pub fn find_homography<T: Real>(
    src: &[Point2<T>],
    dst: &[Point2<T>],
    params: &RansacParams<T>,
    inliers: &mut [bool],
) -> Result<(Homography<T>, RansacReport<T>)> {
    let est = HomographyEstimator::new(src, dst)?;
    ransac(&est, params, inliers).map(|(m, r)| (m.h, r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;
    use crate::rng::Pcg32;
    use nalgebra::Matrix3;

    fn truth() -> Matrix3<f64> {
        Matrix3::new(0.9, -0.12, 35.0, 0.08, 1.05, -20.0, 1.5e-4, -2e-4, 1.0)
    }

    fn apply(h: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
        Point2::from_homogeneous(h * p.to_homogeneous()).unwrap()
    }

    fn data(g: &mut Pcg32, outlier_every: usize) -> ([Point2<f64>; 100], [Point2<f64>; 100]) {
        let src: [Point2<f64>; 100] =
            core::array::from_fn(|_| Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)));
        let mut dst = src.map(|p| {
            let q = apply(&truth(), &p);
            Point2::new(q.x + 0.3 * g.normal(), q.y + 0.3 * g.normal())
        });
        for (i, d) in dst.iter_mut().enumerate() {
            if i % outlier_every == 0 {
                *d = Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0));
            }
        }
        (src, dst)
    }

    fn grid_gap(h: &Homography<f64>) -> f64 {
        let mut worst = 0.0f64;
        for i in 0..=8 {
            for j in 0..=6 {
                let p = Point2::new(80.0 * i as f64, 80.0 * j as f64);
                worst = worst.max((h.transfer(&p).unwrap() - apply(&truth(), &p)).norm());
            }
        }
        worst
    }

    #[test]
    fn recovers_the_homography_among_outliers() {
        let mut g = Pcg32::new(51);
        // Every second point an outlier (50 %).
        let (src, dst) = data(&mut g, 2);
        let mut mask = [false; 100];
        let (h, report) = find_homography(&src, &dst, &RansacParams::default(), &mut mask).unwrap();
        assert!(grid_gap(&h) < 1.0, "{}", grid_gap(&h));
        // The 50 true inliers are found (a random outlier may land within 3 px by chance).
        assert!((50..=53).contains(&report.inliers), "{}", report.inliers);
        assert!(mask.iter().skip(1).step_by(2).all(|m| *m));
        assert!(report.iterations < 300, "{}", report.iterations);
        // f32, same seed: the same inliers.
        let s32 = src.map(|p| p.cast::<f32>());
        let d32 = dst.map(|p| p.cast::<f32>());
        let mut mask32 = [false; 100];
        let cfg32 = RansacParams::<f32>::default();
        let (h32, r32) = find_homography(&s32, &d32, &cfg32, &mut mask32).unwrap();
        assert_eq!(r32.inliers, report.inliers);
        assert_eq!(mask32, mask);
        let h32 = Homography::from_matrix(&h32.matrix().cast::<f64>()).unwrap();
        assert!(grid_gap(&h32) < 1.0);
    }

    #[test]
    fn refinement_and_local_optimisation_help() {
        let mut g = Pcg32::new(52);
        let (src, dst) = data(&mut g, 4);
        let mut mask = [false; 100];
        let plain = crate::ransac::RansacConfig {
            local_optimization: 0,
            refine: false,
            ..Default::default()
        }
        .check()
        .unwrap();
        let (h0, r0) = find_homography(&src, &dst, &plain, &mut mask).unwrap();
        let (h1, r1) = find_homography(&src, &dst, &RansacParams::default(), &mut mask).unwrap();
        assert!(r1.cost <= r0.cost);
        assert!(
            grid_gap(&h1) <= grid_gap(&h0) + 1e-9,
            "{} {}",
            grid_gap(&h1),
            grid_gap(&h0)
        );
    }

    #[test]
    fn hopeless_inputs() {
        let line: [Point2<f64>; 20] =
            core::array::from_fn(|i| Point2::new(i as f64, 2.0 * i as f64));
        let mut mask = [true; 20];
        let cfg = crate::ransac::RansacConfig {
            max_iterations: 50,
            ..Default::default()
        }
        .check()
        .unwrap();
        assert_eq!(
            find_homography(&line, &line, &cfg, &mut mask).unwrap_err(),
            Error::Degenerate
        );
        assert!(mask.iter().all(|m| !*m));
        assert_eq!(
            find_homography(&line[..3], &line[..3], &cfg, &mut mask[..3]).unwrap_err(),
            Error::TooFewPoints
        );
        assert_eq!(
            find_homography(&line, &line[..5], &cfg, &mut mask).unwrap_err(),
            Error::LengthMismatch
        );
    }
}
