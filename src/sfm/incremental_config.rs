//! The parameters of the incremental reconstruction, checked once.

use crate::ransac::{RansacConfig, RansacParams};
use crate::scalar::{Real, above};
use crate::{Error, Result};

/// Parameters of [`reconstruct`](super::reconstruct); checked by [`Self::check`] into the
/// [`IncrementalParams`] it takes. Defaults follow COLMAP's incremental mapper where it has the
/// same notion (4 px filter, 1.5° triangulation angle, 30 PnP inliers, 0.25 inlier ratio, 0.8
/// homography ratio).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IncrementalConfig<T: Real = f32> {
    /// RANSAC of the essential matrix of a candidate initial pair (threshold: Sampson
    /// distance, pixels); also the homography's (transfer error, pixels).
    pub essential: RansacConfig<T>,
    /// RANSAC of each view's PnP registration (threshold: reprojection error, pixels).
    pub pnp: RansacConfig<T>,
    /// Candidate initial pairs tried, best covisibility first, `≥ 1`. Default 20.
    pub initial_pair_trials: u16,
    /// Fewest essential-matrix inliers (after cheirality) of the initial pair. Default 50.
    pub min_initial_inliers: u32,
    /// Largest ratio of homography inliers to essential inliers of the initial pair, in
    /// `(0, 1]`: above it the pair is planar or rotates without moving, and its pose is not
    /// determined. Default 0.8.
    pub max_homography_ratio: T,
    /// Smallest median triangulation angle of the initial pair's inliers, radians, in
    /// `[0, π)`. Default 2°.
    pub min_initial_angle: T,
    /// Fewest PnP inliers to register a view, `≥ 4`. Default 30.
    pub min_registration_inliers: u32,
    /// Smallest ratio of PnP inliers to 2D-3D correspondences, in `[0, 1]`. Default 0.25.
    pub min_inlier_ratio: T,
    /// Largest reprojection error of an observation kept, pixels, `> 0`. Default 4.
    pub max_reprojection_px: T,
    /// Smallest angle between two rays of a triangulated point, radians, in `[0, π)`.
    /// Default 1.5°.
    pub min_triangulation_angle: T,
    /// Largest depth of a point, in initial baselines, `> 0`. Default 100.
    pub max_depth: T,
    /// Huber threshold of the bundle adjustments, pixels, `> 0`. Default 1.
    pub loss_px: T,
    /// Levenberg-Marquardt steps of the bundle adjustment after each registration. Default 10.
    pub bundle_iterations: u8,
    /// Views a local bundle adjustment moves: the new view and those sharing the most tracks
    /// with it, `≥ 1`. Default 6 (COLMAP's).
    pub local_views: u16,
    /// A registration is followed by a global bundle adjustment (every view) when the
    /// registered views have grown by this factor since the last global one, else by a local
    /// one; `≥ 1`. Default 1.2.
    pub global_growth: T,
    /// Steps of the final bundle adjustment. Default 40.
    pub final_bundle_iterations: u8,
}

impl<T: Real> Default for IncrementalConfig<T> {
    fn default() -> Self {
        Self {
            essential: RansacConfig {
                threshold: T::one(),
                confidence: T::lit(0.9999),
                ..RansacConfig::default()
            },
            pnp: RansacConfig {
                threshold: T::lit(4.0),
                confidence: T::lit(0.9999),
                ..RansacConfig::default()
            },
            initial_pair_trials: 20,
            min_initial_inliers: 50,
            max_homography_ratio: T::lit(0.8),
            min_initial_angle: T::lit(2.0f64.to_radians()),
            min_registration_inliers: 30,
            min_inlier_ratio: T::lit(0.25),
            max_reprojection_px: T::lit(4.0),
            min_triangulation_angle: T::lit(1.5f64.to_radians()),
            max_depth: T::lit(100.0),
            loss_px: T::one(),
            bundle_iterations: 10,
            local_views: 6,
            global_growth: T::lit(1.2),
            final_bundle_iterations: 40,
        }
    }
}

impl<T: Real> IncrementalConfig<T> {
    /// Checks the ranges documented on each field once.
    ///
    /// Errors: those of [`RansacConfig::check`] for [`Self::essential`], then [`Self::pnp`];
    /// [`Error::InvalidParameter`] naming the field (`sfm.initial_pair_trials`, ...).
    pub fn check(&self) -> Result<IncrementalParams<T>> {
        let essential = self.essential.check()?;
        let pnp = self.pnp.check()?;
        let angle = |a: T| a >= T::zero() && a < T::pi();
        let checks = [
            (self.initial_pair_trials >= 1, "sfm.initial_pair_trials"),
            (
                above(self.max_homography_ratio, T::zero())
                    && self.max_homography_ratio <= T::one(),
                "sfm.max_homography_ratio",
            ),
            (angle(self.min_initial_angle), "sfm.min_initial_angle"),
            (
                self.min_registration_inliers >= 4,
                "sfm.min_registration_inliers",
            ),
            (
                self.min_inlier_ratio >= T::zero() && self.min_inlier_ratio <= T::one(),
                "sfm.min_inlier_ratio",
            ),
            (
                above(self.max_reprojection_px, T::zero()),
                "sfm.max_reprojection_px",
            ),
            (
                angle(self.min_triangulation_angle),
                "sfm.min_triangulation_angle",
            ),
            (above(self.max_depth, T::zero()), "sfm.max_depth"),
            (
                above(self.loss_px, T::zero()) && self.loss_px.finite(),
                "sfm.loss_px",
            ),
            (self.local_views >= 1, "sfm.local_views"),
            (
                self.global_growth >= T::one() && self.global_growth.finite(),
                "sfm.global_growth",
            ),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, name)) => Err(Error::InvalidParameter(name)),
            None => Ok(IncrementalParams {
                config: *self,
                essential,
                pnp,
            }),
        }
    }
}

/// An [`IncrementalConfig`] that passed [`IncrementalConfig::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IncrementalParams<T: Real = f32> {
    config: IncrementalConfig<T>,
    essential: RansacParams<T>,
    pnp: RansacParams<T>,
}

impl<T: Real> IncrementalParams<T> {
    /// The checked configuration.
    pub const fn config(&self) -> &IncrementalConfig<T> {
        &self.config
    }

    /// The checked [`IncrementalConfig::essential`].
    pub const fn essential(&self) -> &RansacParams<T> {
        &self.essential
    }

    /// The checked [`IncrementalConfig::pnp`].
    pub const fn pnp(&self) -> &RansacParams<T> {
        &self.pnp
    }
}

impl<T: Real> Default for IncrementalParams<T> {
    /// The checked [`IncrementalConfig::default`] (the test below checks it).
    fn default() -> Self {
        let config = IncrementalConfig::default();
        Self {
            essential: RansacParams::assume_checked(config.essential),
            pnp: RansacParams::assume_checked(config.pnp),
            config,
        }
    }
}

impl<T: Real> TryFrom<IncrementalConfig<T>> for IncrementalParams<T> {
    type Error = Error;
    fn try_from(c: IncrementalConfig<T>) -> Result<Self> {
        c.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_names_the_bad_field() {
        assert_eq!(
            IncrementalConfig::<f64>::default().check(),
            Ok(IncrementalParams::default())
        );
        fn with(f: impl Fn(&mut IncrementalConfig<f64>)) -> Result<IncrementalParams<f64>> {
            let mut c = IncrementalConfig::default();
            f(&mut c);
            c.check()
        }
        let bad = |name| Err(Error::InvalidParameter(name));
        assert_eq!(
            with(|c| c.initial_pair_trials = 0),
            bad("sfm.initial_pair_trials")
        );
        assert_eq!(
            with(|c| c.max_homography_ratio = 0.0),
            bad("sfm.max_homography_ratio")
        );
        assert_eq!(
            with(|c| c.min_registration_inliers = 3),
            bad("sfm.min_registration_inliers")
        );
        assert_eq!(
            with(|c| c.min_inlier_ratio = f64::NAN),
            bad("sfm.min_inlier_ratio")
        );
        assert_eq!(with(|c| c.loss_px = f64::INFINITY), bad("sfm.loss_px"));
        assert_eq!(with(|c| c.local_views = 0), bad("sfm.local_views"));
        assert_eq!(with(|c| c.global_growth = 0.5), bad("sfm.global_growth"));
        assert_eq!(
            with(|c| c.min_initial_angle = 4.0),
            bad("sfm.min_initial_angle")
        );
        assert_eq!(with(|c| c.pnp.threshold = 0.0), bad("ransac.threshold"));
    }
}
