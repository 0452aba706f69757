//! The parameters of the three-view pipeline, checked once.

use crate::ransac::{RansacConfig, RansacParams};
use crate::scalar::{Real, above};
use crate::{Error, Result};

/// Parameters of [`reconstruct_three_views`](super::reconstruct_three_views); checked by
/// [`Self::check`] into the [`SfmParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SfmConfig<T: Real = f32> {
    /// RANSAC of the essential matrix of views 1-2 (threshold: Sampson distance, pixels).
    pub essential: RansacConfig<T>,
    /// RANSAC of the PnP registration of view 3 (threshold: reprojection error, pixels).
    pub pnp: RansacConfig<T>,
    /// Largest reprojection error of a newly triangulated point in either view, pixels, `> 0`
    /// (`+∞`: no bound).
    pub max_reprojection_px: T,
    /// Largest depth of a point, in 1-2 baselines, `> 0` (also the cheirality bound of
    /// [`recover_pose`](crate::twoview::recover_pose)).
    pub max_depth: T,
    /// Smallest angle between the two rays of a triangulated point, radians, in `[0, π)`.
    pub min_parallax: T,
    /// Levenberg-Marquardt steps of the bundle adjustment (0 skips it).
    pub bundle_iterations: u8,
}

impl<T: Real> Default for SfmConfig<T> {
    /// 1 px Sampson threshold for `E`, 2 px for PnP, 2 px reprojection bound, depth ≤ 50
    /// baselines, parallax ≥ 1°, 20 bundle steps.
    fn default() -> Self {
        Self {
            essential: RansacConfig {
                threshold: T::one(),
                confidence: T::lit(0.999),
                ..RansacConfig::default()
            },
            pnp: RansacConfig {
                threshold: T::lit(2.0),
                confidence: T::lit(0.999),
                ..RansacConfig::default()
            },
            max_reprojection_px: T::lit(2.0),
            max_depth: T::lit(50.0),
            min_parallax: T::lit(1.0f64.to_radians()),
            bundle_iterations: 20,
        }
    }
}

impl<T: Real> SfmConfig<T> {
    /// Checks the ranges documented on each field once, the two RANSAC configurations into
    /// the [`RansacParams`] the [`SfmParams`] keeps. Errors: those of [`RansacConfig::check`]
    /// for [`Self::essential`], then for [`Self::pnp`]; [`Error::InvalidParameter`] naming the
    /// field (`sfm.max_reprojection_px`, `sfm.max_depth`, `sfm.min_parallax`).
    pub fn check(&self) -> Result<SfmParams<T>> {
        let essential = self.essential.check()?;
        let pnp = self.pnp.check()?;
        let checks = [
            (
                above(self.max_reprojection_px, T::zero()),
                "sfm.max_reprojection_px",
            ),
            (above(self.max_depth, T::zero()), "sfm.max_depth"),
            (
                self.min_parallax >= T::zero() && self.min_parallax < T::pi(),
                "sfm.min_parallax",
            ),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some((_, name)) => Err(Error::InvalidParameter(name)),
            None => Ok(SfmParams {
                config: *self,
                essential,
                pnp,
            }),
        }
    }
}

/// An [`SfmConfig`] that passed [`SfmConfig::check`], with its two RANSAC configurations
/// checked into [`RansacParams`]: what
/// [`reconstruct_three_views`](super::reconstruct_three_views) takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SfmParams<T: Real = f32> {
    config: SfmConfig<T>,
    essential: RansacParams<T>,
    pnp: RansacParams<T>,
}

impl<T: Real> SfmParams<T> {
    /// The checked configuration.
    pub const fn config(&self) -> &SfmConfig<T> {
        &self.config
    }

    /// The checked [`SfmConfig::essential`].
    pub const fn essential(&self) -> &RansacParams<T> {
        &self.essential
    }

    /// The checked [`SfmConfig::pnp`].
    pub const fn pnp(&self) -> &RansacParams<T> {
        &self.pnp
    }
}

impl<T: Real> Default for SfmParams<T> {
    /// The checked [`SfmConfig::default`] (the test below checks it).
    fn default() -> Self {
        let config = SfmConfig::default();
        Self {
            essential: RansacParams::assume_checked(config.essential),
            pnp: RansacParams::assume_checked(config.pnp),
            config,
        }
    }
}

impl<T: Real> TryFrom<SfmConfig<T>> for SfmParams<T> {
    type Error = Error;
    fn try_from(c: SfmConfig<T>) -> Result<Self> {
        c.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_names_the_bad_field() {
        assert_eq!(
            SfmConfig::<f64>::default().check(),
            Ok(SfmParams::default())
        );
        assert_eq!(
            SfmConfig::<f32>::default().check(),
            Ok(SfmParams::default())
        );
        fn with(f: impl Fn(&mut SfmConfig<f64>)) -> Result<SfmParams<f64>> {
            let mut c = SfmConfig::default();
            f(&mut c);
            SfmParams::try_from(c)
        }
        let bad = |name| Err(Error::InvalidParameter(name));
        assert_eq!(
            with(|c| c.essential.threshold = 0.0),
            bad("ransac.threshold")
        );
        assert_eq!(with(|c| c.pnp.confidence = 1.5), bad("ransac.confidence"));
        for v in [0.0, -1.0, f64::NAN] {
            assert_eq!(
                with(|c| c.max_reprojection_px = v),
                bad("sfm.max_reprojection_px")
            );
            assert_eq!(with(|c| c.max_depth = v), bad("sfm.max_depth"));
        }
        for v in [-1e-9, core::f64::consts::PI, f64::INFINITY, f64::NAN] {
            assert_eq!(with(|c| c.min_parallax = v), bad("sfm.min_parallax"));
        }
        assert!(with(|c| c.max_reprojection_px = f64::INFINITY).is_ok());
        assert!(with(|c| c.min_parallax = 0.0).is_ok());
        assert!(with(|c| c.bundle_iterations = 0).is_ok());
    }
}
