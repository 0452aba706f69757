//! The essential matrix of calibrated cameras inside RANSAC (5-point minimal samples).

use nalgebra::Point2;

use super::five_point::five_point;
use super::fundamental::solve as eight_point_iter;
use super::refine::refine_essential_iter;
use super::{Essential, Fundamental, oriented_consistent};
use crate::camera::Intrinsics;
use crate::ransac::{Estimator, RansacParams, RansacReport, Scoring, ransac};
use crate::scalar::Real;
use crate::{Error, Result};

/// An essential matrix with the fundamental matrix it induces in pixels,
/// `F = K₂⁻ᵀ E K₁⁻¹` (what the residuals use).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EssentialModel<T: Real = f32> {
    /// `E`, on the essential manifold.
    pub essential: Essential<T>,
    /// `F = K₂⁻ᵀ E K₁⁻¹`, unit norm.
    pub fundamental: Fundamental<T>,
}

/// Essential-matrix estimation as a RANSAC [`Estimator`] over pixel correspondences of two
/// calibrated cameras (undistorted pixels): 5-point minimal samples ([`five_point`], up to 10
/// models each, those that break the oriented epipolar constraint on their own sample dropped
/// unscored: see below), Sampson residuals of `F = K₂⁻ᵀ E K₁⁻¹` in pixels², 8-point refits on
/// normalised coordinates projected onto the manifold, and a 5-parameter Sampson LM polish.
/// Models are ranked by [`Scoring::Adaptive`]: MSAC when the noise is well inside the
/// threshold, else inlier count.
///
/// The oriented epipolar constraint (Chum, Werner & Matas 2004): for a scene point in front of
/// both cameras, `(t × x̂₂) · (E x̂₁) = (λ₁/λ₂) |E x̂₁|² > 0` (`λ` its depths), so the five
/// points of an all-inlier sample give one sign under the true `E`. A solution that splits
/// the sample's signs puts some of its points behind one camera only and is not scored. On
/// the E-RANSAC bench's 200 pairs (half outliers; `--example profile_solvers e_ransac_200`)
/// this leaves 30 % of the residual evaluations and the same result.
#[derive(Debug, Clone, Copy)]
pub struct EssentialEstimator<'a, T: Real = f32> {
    k1: Intrinsics<T>,
    k2: Intrinsics<T>,
    x1: &'a [Point2<T>],
    x2: &'a [Point2<T>],
    /// Levenberg-Marquardt steps of [`Estimator::refine`].
    pub refine_iterations: u8,
    /// How [`ransac`] ranks models; default [`Scoring::Adaptive`]. With a 1 px threshold
    /// (`host-tests/scripts/twoview_study.py`), MSAC alone falls behind the inlier count
    /// from 0.5 px of noise on (at 2 px behind OpenCV's count-based RANSAC), the count alone
    /// behind MSAC at 0.1 px; they tie at 0.25 px.
    pub scoring: Scoring,
}

impl<'a, T: Real> EssentialEstimator<'a, T> {
    /// Pixel pairs `(x1[i], x2[i])` seen by cameras `k1`, `k2`; errors with
    /// [`Error::LengthMismatch`].
    pub fn new(
        k1: &Intrinsics<T>,
        k2: &Intrinsics<T>,
        x1: &'a [Point2<T>],
        x2: &'a [Point2<T>],
    ) -> Result<Self> {
        if x1.len() != x2.len() {
            return Err(Error::LengthMismatch);
        }
        Ok(Self {
            k1: *k1,
            k2: *k2,
            x1,
            x2,
            refine_iterations: 10,
            scoring: Scoring::Adaptive,
        })
    }

    fn model(&self, e: Essential<T>) -> Option<EssentialModel<T>> {
        Some(EssentialModel {
            essential: e,
            fundamental: e.to_fundamental(&self.k1, &self.k2).ok()?,
        })
    }

    fn inlier_pairs<'b>(
        &'b self,
        inliers: &'b [bool],
    ) -> impl Iterator<Item = (Point2<T>, Point2<T>)> + Clone + 'b {
        self.x1
            .iter()
            .zip(self.x2.iter())
            .zip(inliers.iter())
            .filter(|(_, m)| **m)
            .map(|((a, b), _)| (*a, *b))
    }
}

impl<T: Real> Estimator for EssentialEstimator<'_, T> {
    type Model = EssentialModel<T>;
    type Scalar = T;

    fn num_points(&self) -> usize {
        self.x1.len()
    }

    fn sample_size(&self) -> usize {
        5
    }

    fn fit_minimal(&self, sample: &[usize], emit: &mut dyn FnMut(Self::Model)) {
        let mut a = [Point2::origin(); 5];
        let mut b = [Point2::origin(); 5];
        if sample.len() != 5 {
            return;
        }
        for ((i, pa), pb) in sample.iter().zip(a.iter_mut()).zip(b.iter_mut()) {
            let n1 = self.x1.get(*i).map(|p| self.k1.pixel_to_normalized(p));
            let n2 = self.x2.get(*i).map(|p| self.k2.pixel_to_normalized(p));
            match (n1, n2) {
                (Some(Ok(p)), Some(Ok(q))) => {
                    *pa = p;
                    *pb = q;
                }
                _ => return,
            }
        }
        if let Ok(models) = five_point(&a, &b) {
            // Solutions that split the sample across the cameras cannot be the geometry of an
            // all-inlier sample: not scored ([`oriented_consistent`]).
            // By reference: `heapless`'s owning iterator drops its rest through a slice index
            // the optimiser could not prove in range behind the filter (a panic path).
            for e in models.iter() {
                if oriented_consistent(e.matrix(), &a, &b)
                    && let Some(m) = self.model(*e)
                {
                    emit(m);
                }
            }
        }
    }

    fn residual_sq(&self, m: &Self::Model, i: usize) -> Option<T> {
        m.fundamental.sampson_sq(self.x1.get(i)?, self.x2.get(i)?)
    }

    fn refit(&self, _: &Self::Model, inliers: &[bool]) -> Option<Self::Model> {
        let (k1, k2) = (self.k1, self.k2);
        let normalised = self.inlier_pairs(inliers).filter_map(move |(a, b)| {
            Some((
                k1.pixel_to_normalized(&a).ok()?,
                k2.pixel_to_normalized(&b).ok()?,
            ))
        });
        let f = eight_point_iter(normalised).ok()?;
        self.model(Essential::from_matrix(f.matrix()).ok()?)
    }

    /// The eight-point fit on the inliers: the model it starts from plays no part.
    fn refit_is_mask_only(&self) -> bool {
        true
    }

    fn scoring(&self) -> Scoring {
        self.scoring
    }

    fn refine(&self, m: &Self::Model, inliers: &[bool]) -> Option<Self::Model> {
        let r = refine_essential_iter(
            &m.essential,
            &self.k1,
            &self.k2,
            self.inlier_pairs(inliers),
            self.refine_iterations,
        )
        .ok()?;
        self.model(r.model)
    }
}

/// Robust `E` from pixel correspondences of two calibrated cameras with outliers (OpenCV's
/// `findEssentialMat(x1, x2, K, RANSAC)` counterpart, here with distinct `K₁`, `K₂`), writing
/// the inlier mask. Pass undistorted pixels.
///
/// 5-point samples scored on the Sampson distance in pixels (the threshold of `params`; OpenCV's
/// default for `E` is 1 px) and ranked by [`Scoring::Adaptive`] (MSAC while the noise is well
/// inside the threshold, else inlier count; [`EssentialEstimator`] with [`ransac`] for another
/// ranking), 8-point local optimisation, Sampson LM polish ([`super::refine_essential`]).
/// Solutions of a sample that break the oriented epipolar constraint on it are not scored
/// ([`EssentialEstimator`]). Errors: see [`ransac`].
#[doc(alias = "findEssentialMat")]
pub fn find_essential<T: Real>(
    k1: &Intrinsics<T>,
    k2: &Intrinsics<T>,
    x1: &[Point2<T>],
    x2: &[Point2<T>],
    params: &RansacParams<T>,
    inliers: &mut [bool],
) -> Result<(Essential<T>, RansacReport<T>)> {
    let est = EssentialEstimator::new(k1, k2, x1, x2)?;
    ransac(&est, params, inliers).map(|(m, r)| (m.essential, r))
}
