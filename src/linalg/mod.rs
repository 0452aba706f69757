//! Small dense linear algebra for fixed-size systems, without allocation.
//!
//! - [`svd_jacobi`]: one-sided Jacobi SVD `A = U Σ Vᵀ` of an `R x C` static matrix (`R ≥ C`),
//!   bounded sweeps, singular values sorted descending;
//! - [`StreamingQr`]: the `R` of `A = Q R` for a tall `A` absorbed row by row, so that
//!   `AᵀA = RᵀR` without forming `AᵀA` (whose condition number is `cond(A)²`).
//!
//! - [`lm`]: a bounded Levenberg-Marquardt driver on top of the streaming QR.
//!
//! Together they give least-squares null vectors of arbitrarily many equations in constant
//! memory: push the rows into a [`StreamingQr`], then take [`Svd::null_vector`] of `R`. That is
//! how [`crate::homography`] solves the DLT.

pub mod lm;
mod qr;
mod svd;

pub use qr::StreamingQr;
pub use svd::{MAX_SWEEPS, Svd, svd_jacobi};

use crate::scalar::Real;

/// `√(a² + b²)` without intermediate overflow or underflow, computed in `T`.
///
/// Used instead of `hypot` because libm's `hypotf` works in `f64`, which is software-emulated
/// on single-precision FPUs (Cortex-M4F/M7): a few hundred cycles per call in the QR's inner
/// loop. Accurate to a couple of ulps; NaN in, NaN out.
#[inline]
pub(crate) fn hypot<T: Real>(a: T, b: T) -> T {
    let (a, b) = (a.abs(), b.abs());
    let (big, small) = if a >= b { (a, b) } else { (b, a) };
    if big == T::zero() {
        return big;
    }
    let r = small / big;
    big * (T::one() + r * r).sqrt()
}

#[cfg(test)]
mod tests {
    #[test]
    fn hypot_is_safe() {
        use super::hypot;
        assert_eq!(hypot(3.0f32, -4.0), 5.0);
        assert_eq!(hypot(0.0f32, 0.0), 0.0);
        assert_eq!(hypot(-2.0f64, 0.0), 2.0);
        assert!((hypot(3e30f32, 4e30) / 5e30 - 1.0).abs() < 1e-6);
        assert!((hypot(3e-30f32, 4e-30) / 5e-30 - 1.0).abs() < 1e-6);
        assert!(hypot(f32::NAN, 1.0).is_nan());
        assert!(hypot(1.0, f32::NAN).is_nan());
        assert_eq!(hypot(f32::INFINITY, 1.0), f32::INFINITY);
    }
}
