//! The bounds of the iterative undistortion both lens models share, checked once.

use crate::scalar::Real;
use crate::{Error, Result};

/// Bounds of the iterative undistortion of both lens models (`Distortion::undistort`,
/// `Fisheye::undistort`): Newton's method on the lens map, stopped at a tolerance or after a
/// number of steps.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UndistortConfig<T: Real = f32> {
    /// Newton iterations at most (each costs one distortion and one 2x2 solve), at least 1.
    pub max_iterations: u8,
    /// Accept when `|distort(x) - x_d|` (normalised units) is at most this (finite, `≥ 0`).
    /// Raised to `8 ε max(1, |x_d|)` when smaller; the iteration keeps improving past it while
    /// it can, down to the rounding floor `2 ε max(1, |x_d|)`.
    pub tolerance: T,
}

impl<T: Real> Default for UndistortConfig<T> {
    fn default() -> Self {
        // Newton converges quadratically from x = x_d for lenses like the bundled chessboard
        // camera in 3..5 steps; 20 leaves a wide margin and still bounds the cost.
        Self {
            max_iterations: 20,
            tolerance: T::zero(),
        }
    }
}

impl<T: Real> UndistortConfig<T> {
    /// Checks the ranges documented on each field. Errors: [`Error::InvalidParameter`] naming
    /// the field (`undistort.max_iterations`, `undistort.tolerance`).
    pub fn check(&self) -> Result<UndistortParams<T>> {
        if self.max_iterations == 0 {
            return Err(Error::InvalidParameter("undistort.max_iterations"));
        }
        if !(self.tolerance.finite() && self.tolerance >= T::zero()) {
            return Err(Error::InvalidParameter("undistort.tolerance"));
        }
        Ok(UndistortParams(*self))
    }
}

/// An [`UndistortConfig`] that passed [`UndistortConfig::check`]: what a camera holds and the
/// undistortions take.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UndistortParams<T: Real = f32>(UndistortConfig<T>);

impl<T: Real> UndistortParams<T> {
    /// The checked configuration.
    pub const fn config(&self) -> &UndistortConfig<T> {
        &self.0
    }

    /// The same bounds in another float type (a tolerance beyond `U`'s range becomes its
    /// largest finite value, so the result is still checked).
    pub fn cast<U: Real>(&self) -> UndistortParams<U> {
        let t = U::lit(self.0.tolerance.to_f64());
        let tolerance = if t.finite() {
            t
        } else {
            U::max_value().unwrap_or(U::one() / U::EPSILON)
        };
        UndistortParams(UndistortConfig {
            max_iterations: self.0.max_iterations,
            tolerance,
        })
    }
}

impl<T: Real> Default for UndistortParams<T> {
    /// The checked [`UndistortConfig::default`].
    fn default() -> Self {
        Self(UndistortConfig::default())
    }
}

impl<T: Real> TryFrom<UndistortConfig<T>> for UndistortParams<T> {
    type Error = Error;
    fn try_from(c: UndistortConfig<T>) -> Result<Self> {
        c.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_names_the_bad_field() {
        assert!(UndistortConfig::<f64>::default().check().is_ok());
        let bad = UndistortConfig::<f64> {
            max_iterations: 0,
            ..UndistortConfig::default()
        };
        assert_eq!(
            bad.check(),
            Err(Error::InvalidParameter("undistort.max_iterations"))
        );
        for t in [f64::NAN, f64::INFINITY, -1e-9] {
            let bad = UndistortConfig {
                tolerance: t,
                ..UndistortConfig::default()
            };
            assert_eq!(
                UndistortParams::try_from(bad),
                Err(Error::InvalidParameter("undistort.tolerance"))
            );
        }
        let big = UndistortConfig {
            tolerance: 1e300,
            ..UndistortConfig::default()
        }
        .check()
        .unwrap();
        assert!(big.cast::<f32>().config().tolerance.is_finite());
    }
}
