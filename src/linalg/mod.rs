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
//!
//! ```
//! use camgeom::linalg::{StreamingQr, svd_jacobi};
//! use camgeom::nalgebra::{Matrix2, Vector3};
//!
//! // AᵀA = [25 20; 20 25] has eigenvalues 45 and 5: the singular values are √45 and √5.
//! let a = Matrix2::new(3.0f64, 0.0, 4.0, 5.0);
//! let svd = svd_jacobi(&a)?;
//! assert!((svd.singular_values[0] - 45f64.sqrt()).abs() < 1e-12);
//! assert!((svd.singular_values[1] - 5f64.sqrt()).abs() < 1e-12);
//! assert!((svd.recompose() - a).amax() < 1e-12);
//! // The line 2x - y + 3 = 0 from 100 of its points, one row (x, y, 1) at a time.
//! let mut qr = StreamingQr::<f64, 3>::new();
//! for i in 0..100 {
//!     let x = f64::from(i) * 0.37 - 9.0;
//!     qr.push_row(&[x, 2.0 * x + 3.0, 1.0])?;
//! }
//! let (l, residual) = qr.null_vector()?;
//! let truth = Vector3::new(2.0, -1.0, 3.0).normalize();
//! assert!(residual < 1e-10 && (l - truth).amax().min((l + truth).amax()) < 1e-12);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod eigen;
pub mod lm;
mod nullspace;
mod qr;
mod reduction;
mod svd;

pub(crate) use eigen::{null_vector, real_eigenvalues};
pub(crate) use nullspace::null_space;
pub use qr::StreamingQr;
pub(crate) use reduction::Reduced;
pub use svd::{MAX_SWEEPS, Svd, svd_jacobi};

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};

use crate::Result;
use crate::scalar::Real;

/// The rotation closest to `m` in the Frobenius norm (orthogonal Procrustes):
/// `R = U diag(1, 1, det(U Vᵀ)) Vᵀ` for `m = U Σ Vᵀ`.
///
/// Errors: as [`svd_jacobi`] (NaN/inf input, no convergence).
pub fn closest_rotation<T: Real>(m: &Matrix3<T>) -> Result<Rotation3<T>> {
    let svd = svd_jacobi(m)?;
    let d = if (svd.u * svd.v.transpose()).determinant() < T::zero() {
        -T::one()
    } else {
        T::one()
    };
    let mut u = svd.u;
    u.column_mut(2).scale_mut(d);
    Ok(Rotation3::from_matrix_unchecked(u * svd.v.transpose()))
}

/// The rotation of a Levenberg-Marquardt step `δ` on the rotation manifold (`R ← rotation_step(δ) R`),
/// in rational arithmetic: the unit quaternion `(1, δ/2) / |(1, δ/2)|` (the Cayley map),
///
/// `R(δ) = I + c ([a]ₓ + [a]ₓ²)`, `a = δ/2`, `c = 2 / (1 + |a|²)`,
///
/// a rotation by `2 atan(|δ|/2)` about `δ`: equal to `exp([δ]ₓ)` to second order, so the
/// Jacobians of the steps are the same, and defined for every `δ`. No trigonometry: libm's
/// `f32` sine and cosine compute in `f64`, which boards without a double-precision FPU
/// (Cortex-M4F/M7/M33, and every FPU-less core) emulate in software.
pub(crate) fn rotation_step<T: Real>(d: &Vector3<T>) -> Rotation3<T> {
    let a = d * T::lit(0.5);
    let c = T::lit(2.0) / (T::one() + a.norm_squared());
    let ax = a.cross_matrix();
    Rotation3::from_matrix_unchecked(Matrix3::identity() + (ax + ax * ax) * c)
}

/// Column `c` of `m` (zeros for `c >= C`, which no caller passes): `m.column(c).into_owned()`
/// without its panic paths (`into_owned` asserts the length of an iterator, and `column` its
/// index, where the optimiser cannot prove them).
#[inline]
pub(crate) fn column<T: Real, const R: usize, const C: usize>(
    m: &SMatrix<T, R, C>,
    c: usize,
) -> SVector<T, R> {
    let mut v = SVector::<T, R>::zeros();
    if c < C {
        v.copy_from(&m.column(c));
    }
    v
}

/// Swaps rows `i < j` of `rows` entry by entry (nothing for `i >= j` or out of range): a
/// whole-array swap of rows this size is a `memcpy` call on a Cortex-M, this stays in registers.
#[inline]
pub(crate) fn swap_rows<T, const N: usize>(rows: &mut [[T; N]], i: usize, j: usize) {
    if i < j
        && let Some((upper, lower)) = rows.split_at_mut_checked(j)
        && let (Some(x), Some(y)) = (upper.get_mut(i), lower.first_mut())
    {
        x.iter_mut()
            .zip(y.iter_mut())
            .for_each(|(u, v)| core::mem::swap(u, v));
    }
}

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
    fn rotation_step_is_the_cayley_rotation_and_exp_to_second_order() {
        use nalgebra::{Rotation3, Vector3};
        for d in [
            Vector3::new(0.0f64, 0.0, 0.0),
            Vector3::new(1e-3, -2e-3, 5e-4),
            Vector3::new(0.3, -1.2, 2.0),
            Vector3::new(40.0, 0.0, -3.0),
        ] {
            let r = super::rotation_step(&d);
            let m = r.matrix();
            // A rotation to rounding: orthonormal, determinant 1.
            assert!((m.transpose() * m - nalgebra::Matrix3::identity()).amax() < 1e-14);
            assert!((m.determinant() - 1.0).abs() < 1e-14);
            // About δ by 2 atan(|δ|/2).
            let n = d.norm();
            let want = if n > 0.0 {
                Rotation3::from_axis_angle(
                    &nalgebra::Unit::new_normalize(d),
                    2.0 * (n / 2.0).atan(),
                )
            } else {
                Rotation3::identity()
            };
            assert!((r.matrix() - want.matrix()).amax() < 1e-14, "{d}");
            // exp([δ]ₓ) to second order: the difference is O(|δ|³).
            let exp = Rotation3::new(d);
            assert!((r.matrix() - exp.matrix()).amax() <= n * n * n / 12.0 * 1.01 + 1e-15);
        }
    }

    #[test]
    fn closest_rotation_projects_onto_so3() {
        use nalgebra::{Matrix3, Rotation3, Vector3};
        let r = Rotation3::new(Vector3::new(0.3f64, -1.2, 2.0));
        // A rotation is its own closest rotation.
        let back = super::closest_rotation(r.matrix()).unwrap();
        assert!((back.matrix() - r.matrix()).amax() < 1e-14);
        // A perturbed and scaled rotation comes back orthonormal with det +1.
        let m =
            r.matrix() * 1.7 + Matrix3::new(0.01, -0.02, 0.0, 0.0, 0.03, 0.01, -0.01, 0.0, 0.02);
        let q = super::closest_rotation(&m).unwrap();
        assert!((q.matrix().transpose() * q.matrix() - Matrix3::identity()).amax() < 1e-14);
        assert!((q.matrix().determinant() - 1.0).abs() < 1e-14);
        assert!(q.angle_to(&r) < 0.05);
        // A reflection maps to a proper rotation, not to itself.
        let refl = Matrix3::from_diagonal(&Vector3::new(1.0f64, 1.0, -1.0));
        assert!(
            (super::closest_rotation(&refl)
                .unwrap()
                .matrix()
                .determinant()
                - 1.0)
                .abs()
                < 1e-14
        );
    }

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
