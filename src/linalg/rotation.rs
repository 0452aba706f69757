//! Rotations from matrices and steps: the nearest rotation to a 3x3 matrix (orthogonal
//! Procrustes) and the rotation of a Levenberg-Marquardt step on SO(3).

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::svd::svd_jacobi;
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
}
