//! Pose from a plane-to-image homography.

use nalgebra::Matrix3;

use crate::camera::Intrinsics;
use crate::homography::Homography;
use crate::linalg::closest_rotation;
use crate::scalar::{Real, above};
use crate::transform::Pose;
use crate::{Error, Result};

/// The pose of a planar target from the homography `u ~ H (X, Y, 1)` that maps target-plane
/// points (`Z = 0`, metres) to undistorted pixels:
///
/// `M = K⁻¹ H = [m₁ m₂ m₃]`, `λ = ±2 / (|m₁| + |m₂|)`, `r₁ = λ m₁`, `r₂ = λ m₂`, `t = λ m₃`,
/// `r₃ = r₁ × r₂`, then the closest rotation `R = U diag(1, 1, det(U Vᵀ)) Vᵀ` of
/// `[r₁ r₂ r₃] = U Σ Vᵀ`. The sign of `λ` puts the target in front of the camera (`t_z > 0`).
///
/// This is the textbook recipe: it spreads the homography's noise evenly over `r₁`, `r₂`;
/// [`super::solve_planar`] (IPPE plus refinement) is more accurate.
///
/// Errors: [`Error::Degenerate`] when `m₁` or `m₂` vanishes; as [`closest_rotation`].
#[doc(alias = "decomposeHomographyMat")]
pub fn pose_from_homography<T: Real>(k: &Intrinsics<T>, h: &Homography<T>) -> Result<Pose<T>> {
    let m = k.inverse_matrix() * h.matrix();
    let (m1, m2, m3) = (m.column(0), m.column(1), m.column(2));
    let norms = m1.norm() + m2.norm();
    if !above(norms, T::EPSILON * m.amax()) {
        return Err(Error::Degenerate);
    }
    let mut lambda = T::lit(2.0) / norms;
    if m3.z * lambda < T::zero() {
        lambda = -lambda;
    }
    let (r1, r2, t) = (m1 * lambda, m2 * lambda, m3 * lambda);
    let r = closest_rotation(&Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]))?;
    Pose::new(r, t)
}
