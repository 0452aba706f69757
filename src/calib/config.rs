//! What a calibration estimates and how: the lens model, OpenCV's flags, the iteration bound
//! and the warning thresholds, checked once into [`CalibrationParams`].

use crate::camera::{CAMERA_PARAMETERS, LensModel};
use crate::scalar::Real;
use crate::{Error, Result};

/// The fixed aspect ratios [`CalibrationFlags::fix_aspect_ratio`] accepts, `1e-3 ..= 1e3`
/// (real pixels are within a few percent of square). The closed form divides by the ratio's
/// square: a ratio far outside this range (`8e-39` squares to zero in `f32`) made the
/// calibration fail with an undocumented `NonFinite` instead of a parameter error.
pub const ASPECT_RATIO_RANGE: core::ops::RangeInclusive<f64> = 1e-3..=1e3;

/// Which parameters stay fixed, as OpenCV's calibration flags.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationFlags {
    /// `Some(a)`: `fx = a fy` throughout (`CALIB_FIX_ASPECT_RATIO`, with the ratio given here
    /// rather than through an initial camera matrix). In [`ASPECT_RATIO_RANGE`].
    pub fix_aspect_ratio: Option<f64>,
    /// The principal point stays at the image centre `((w - 1)/2, (h - 1)/2)`
    /// (`CALIB_FIX_PRINCIPAL_POINT`).
    pub fix_principal_point: bool,
    /// Brown-Conrady only: `p1 = p2 = 0` (`CALIB_ZERO_TANGENT_DIST`).
    pub zero_tangent: bool,
    /// `k3 = 0` (`CALIB_FIX_K3`; for the fisheye model OpenCV's `fisheye::CALIB_FIX_K3`).
    pub fix_k3: bool,
    /// Fisheye only: `k4 = 0` (`fisheye::CALIB_FIX_K4`).
    pub fix_k4: bool,
}

/// Options of a calibration (`Calibrator::solve` takes them checked, as
/// [`CalibrationParams`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationConfig {
    /// The lens model to estimate: Brown-Conrady (OpenCV's `calibrateCamera`) or
    /// Kannala-Brandt (OpenCV's `fisheye::calibrate`, with `CALIB_FIX_SKEW`).
    pub model: LensModel,
    /// Fixed parameters.
    pub flags: CalibrationFlags,
    /// Levenberg-Marquardt steps at most (`1..=255`; OpenCV's default criteria stop at 30).
    pub max_iterations: u8,
    /// Warn when the standard deviation of `fx` or `fy` exceeds this fraction of its value.
    pub focal_warning: f64,
    /// Warn when the standard deviation of `cx` or `cy` exceeds this fraction of the image's
    /// width or height.
    pub principal_point_warning: f64,
    /// Warn when the standard deviation of a lens coefficient exceeds this.
    pub distortion_warning: f64,
}

impl Default for CalibrationConfig {
    /// Brown-Conrady, nothing fixed, 50 steps; warnings at 5 % of the focal length, 5 % of
    /// the image size and a coefficient standard deviation of 1. The bundled 13-view
    /// calibration has 0.09 % / 0.2 % / 0.24 (k3), well inside; fronto-parallel views alone
    /// give a focal-length deviation of tens of percent.
    fn default() -> Self {
        Self {
            model: LensModel::BrownConrady,
            flags: CalibrationFlags::default(),
            max_iterations: 50,
            focal_warning: 0.05,
            principal_point_warning: 0.05,
            distortion_warning: 1.0,
        }
    }
}

impl CalibrationConfig {
    /// Checks the ranges documented on each field. Errors: `InvalidParameter("max_iterations")`
    /// for zero steps, `InvalidParameter("flags.fix_aspect_ratio")` for a ratio outside
    /// [`ASPECT_RATIO_RANGE`].
    pub fn check(&self) -> Result<CalibrationParams> {
        if self.max_iterations == 0 {
            return Err(Error::InvalidParameter("max_iterations"));
        }
        match self.flags.fix_aspect_ratio {
            Some(a) if !ASPECT_RATIO_RANGE.contains(&a) => {
                Err(Error::InvalidParameter("flags.fix_aspect_ratio"))
            }
            _ => Ok(CalibrationParams(*self)),
        }
    }
}

/// A [`CalibrationConfig`] that passed [`CalibrationConfig::check`]: what `Calibrator::solve`
/// takes, so that no call validates it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationParams(CalibrationConfig);

impl CalibrationParams {
    /// The checked configuration.
    pub const fn config(&self) -> &CalibrationConfig {
        &self.0
    }

    /// The fixed aspect ratio `fx / fy` in `T`.
    pub(super) fn aspect<T: Real>(&self) -> Option<T> {
        self.0.flags.fix_aspect_ratio.map(T::lit)
    }

    /// Which camera parameters (`fx fy cx cy` and the lens coefficients of the model) are
    /// free.
    pub(super) fn free(&self) -> [bool; CAMERA_PARAMETERS] {
        let f = &self.0.flags;
        let mut free = [true; CAMERA_PARAMETERS];
        let set = |free: &mut [bool; CAMERA_PARAMETERS], k: usize| {
            if let Some(x) = free.get_mut(k) {
                *x = false;
            }
        };
        if f.fix_aspect_ratio.is_some() {
            set(&mut free, 0);
        }
        if f.fix_principal_point {
            set(&mut free, 2);
            set(&mut free, 3);
        }
        match self.0.model {
            LensModel::BrownConrady => {
                if f.zero_tangent {
                    set(&mut free, 6);
                    set(&mut free, 7);
                }
                if f.fix_k3 {
                    set(&mut free, 8);
                }
            }
            LensModel::KannalaBrandt => {
                if f.fix_k3 {
                    set(&mut free, 6);
                }
                if f.fix_k4 {
                    set(&mut free, 7);
                }
                set(&mut free, 8);
            }
        }
        free
    }
}

impl Default for CalibrationParams {
    /// The checked [`CalibrationConfig::default`].
    fn default() -> Self {
        Self(CalibrationConfig::default())
    }
}

impl TryFrom<CalibrationConfig> for CalibrationParams {
    type Error = Error;
    fn try_from(c: CalibrationConfig) -> Result<Self> {
        c.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_names_the_bad_option() {
        assert_eq!(
            CalibrationConfig::default().check(),
            Ok(CalibrationParams::default())
        );
        let bad = CalibrationConfig {
            max_iterations: 0,
            ..CalibrationConfig::default()
        };
        assert_eq!(bad.check(), Err(Error::InvalidParameter("max_iterations")));
        for a in [f64::NAN, 0.0, 1e-4, 1e4, f64::INFINITY] {
            let mut bad = CalibrationConfig::default();
            bad.flags.fix_aspect_ratio = Some(a);
            assert_eq!(
                CalibrationParams::try_from(bad),
                Err(Error::InvalidParameter("flags.fix_aspect_ratio"))
            );
        }
        let mut ok = CalibrationConfig::default();
        ok.flags.fix_aspect_ratio = Some(1e3);
        assert_eq!(ok.check().map(|p| p.aspect::<f32>()), Ok(Some(1e3)));
    }
}
