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

impl<T: Real> UndistortParams<T> {
    /// The bounded Newton iteration both lens models invert with: from `x0`, at most
    /// `max_iterations` steps; `residual(x)` gives the error norm at `x` and what `step` needs
    /// (`None`: not finite); `step(x, r)` the next iterate (or why there is none: the model
    /// folds). The best iterate is kept; the loop accepts it at the tolerance `tol` but steps
    /// on while it still improves, down to the rounding floor `floor` (the pixel error is the
    /// focal length times this residual, so stopping early would make it grow with `f`).
    ///
    /// Errors: [`Error::NoConvergence`] for a non-finite residual, a failed step, or when the
    /// best error is above `tol` after the bound.
    pub(crate) fn newton<X: Copy, R>(
        &self,
        tol: T,
        floor: T,
        x0: X,
        mut residual: impl FnMut(X) -> Option<(T, R)>,
        mut step: impl FnMut(X, R) -> Result<X>,
    ) -> Result<X> {
        let mut x = x0;
        let mut best = (T::max_value().unwrap_or(T::one() / T::EPSILON), x);
        for _ in 0..self.0.max_iterations {
            let (err, r) = residual(x).ok_or(Error::NoConvergence)?;
            if err < best.0 {
                best = (err, x);
            } else if best.0 <= tol {
                // No further progress at the rounding floor.
                break;
            }
            if err <= floor {
                break;
            }
            x = step(x, r)?;
        }
        if best.0 <= tol {
            Ok(best.1)
        } else {
            Err(Error::NoConvergence)
        }
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
