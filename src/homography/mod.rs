//! Plane homographies: the projective maps `x' ~ H x` between two views of a plane (or two
//! views under pure rotation).
//!
//! - [`Homography`]: a validated, non-singular `H` with [`Homography::transfer`] and
//!   [`Homography::inverse`];
//! - [`Normalization`]: Hartley's isotropic point normalisation;
//! - [`Homography::from_four_points`]: the exact map of a minimal sample, with the sample checks
//!   (no three points collinear, no fold) that make it safe inside RANSAC;
//! - [`dlt()`], [`dlt_masked`], [`dlt_weighted`]: the normalised direct linear transform for any
//!   number of correspondences, streamed through [`crate::linalg::StreamingQr`] in constant
//!   memory;
//! - [`refine()`], [`refine_masked`]: Levenberg-Marquardt on the symmetric transfer error;
//! - [`find_homography`]: RANSAC (MSAC, local optimisation, final refinement) on the generic
//!   [`crate::ransac`] loop, with [`HomographyEstimator`] as its [`crate::ransac::Estimator`].
//!
//! ```
//! use camgeom::homography::Homography;
//! use camgeom::nalgebra::Point2;
//!
//! let p = Point2::new;
//! let square = [p(0.0f64, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)];
//! let quad = [p(0.0, 0.0), p(6.0, 0.0), p(3.0, 3.0), p(0.0, 3.0)];
//! let h = Homography::from_four_points(&square, &quad)?;
//! for (s, q) in square.iter().zip(&quad) {
//!     assert!((h.transfer(s)? - q).norm() < 1e-12);
//! }
//! // Incidence survives: the square's centre goes to where the quad's diagonals meet,
//! // y = x and y = 3 - x / 2, that is (2, 2).
//! assert!((h.transfer(&p(0.5, 0.5))? - p(2.0, 2.0)).norm() < 1e-12);
//! // Three collinear points fit no homography.
//! let line = [p(0.0, 0.0), p(1.0, 1.0), p(2.0, 2.0), p(0.0, 1.0)];
//! assert_eq!(Homography::from_four_points(&line, &quad), Err(camgeom::Error::Degenerate));
//! # Ok::<(), camgeom::Error>(())
//! ```

mod dlt;
mod four_point;
mod normalize;
mod ransac;
mod refine;

pub use dlt::{dlt, dlt_masked, dlt_weighted, rank_tolerance};
pub use four_point::{COLLINEARITY_TOL, check_sample};
pub use normalize::Normalization;
pub use ransac::{HomographyEstimator, HomographyModel, find_homography};
pub use refine::{Refinement, refine, refine_masked};

use nalgebra::{Matrix3, Point2, Vector3};

use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// A plane projective transformation `x' ~ H x`, `x = (x, y, 1)`:
///
/// `x' = (h11 x + h12 y + h13) / w`,  `y' = (h21 x + h22 y + h23) / w`,
/// `w = h31 x + h32 y + h33`.
///
/// `H` is defined up to scale; it is stored with `h33 = 1` unless `|h33| ≤ ε max|h_ij|` (the
/// origin maps to, or near, infinity), then with unit Frobenius norm. Construction rejects
/// NaN/inf and numerically singular matrices, so the inverse always exists.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Homography<T: Real = f32> {
    h: Matrix3<T>,
}

impl<T: Real> Default for Homography<T> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<T: Real> Homography<T> {
    /// `H = I`.
    pub fn identity() -> Self {
        Self {
            h: Matrix3::identity(),
        }
    }

    /// Validates and normalises `m` (see the type docs).
    ///
    /// Errors: [`Error::NonFinite`] for NaN/inf entries; [`Error::Degenerate`] for a
    /// numerically singular `m`, `|det m| ≤ ε min(∏ᵢ|rowᵢ|, ∏ⱼ|colⱼ|)`. By Hadamard's inequality
    /// the ratio is in `[0, 1]`, and it does not change when rows or columns are scaled (pixel
    /// units, zoom), only when `m` is close to rank 2.
    pub fn from_matrix(m: &Matrix3<T>) -> Result<Self> {
        check_finite(m.as_slice())?;
        let amax = m.amax();
        if amax == T::zero() {
            return Err(Error::Degenerate);
        }
        // Scale first so norms and the determinant cannot overflow or underflow.
        let m = m / amax;
        let rows = m.row_iter().fold(T::one(), |acc, r| acc * r.norm());
        let cols = m.column_iter().fold(T::one(), |acc, c| acc * c.norm());
        let det = m.determinant();
        if !above(det.abs(), T::EPSILON * rows.min(cols)) {
            return Err(Error::Degenerate);
        }
        let h = if m.m33.abs() > T::EPSILON {
            m / m.m33
        } else {
            m / m.norm()
        };
        check_finite(h.as_slice())?;
        Ok(Self { h })
    }

    /// `H`, normalised as in the type docs.
    pub fn matrix(&self) -> &Matrix3<T> {
        &self.h
    }

    /// Maps a point: `x' = (H x)_{1,2} / (H x)_3`.
    ///
    /// Errors: [`Error::NonFinite`] for NaN/inf input or an overflowing result;
    /// [`Error::AtInfinity`] when `|w| ≤ ε max(|(H x)₁|, |(H x)₂|)` (the point is on, or within
    /// rounding of, the line `H` sends to infinity).
    #[doc(alias = "perspectiveTransform")]
    pub fn transfer(&self, p: &Point2<T>) -> Result<Point2<T>> {
        check_finite(&[p.x, p.y])?;
        let v = self.h * Vector3::new(p.x, p.y, T::one());
        check_finite(v.as_slice())?;
        let num = v.x.abs().max(v.y.abs());
        if !above(v.z.abs(), T::EPSILON * num) {
            return Err(Error::AtInfinity);
        }
        let q = Point2::new(v.x / v.z, v.y / v.z);
        check_finite(&[q.x, q.y])?;
        Ok(q)
    }

    /// `H⁻¹ ~ adj(H)` (the adjugate; the scale is irrelevant), normalised.
    ///
    /// Errors as [`Self::from_matrix`] (an overflowing adjugate gives [`Error::NonFinite`]).
    pub fn inverse(&self) -> Result<Self> {
        Self::from_matrix(&adjugate(&self.h))
    }

    /// The composition "`self`, then `next`": `H = H_next H_self`.
    pub fn then(&self, next: &Self) -> Result<Self> {
        Self::from_matrix(&(next.h * self.h))
    }

    /// The same homography in another float type (validated again: a matrix that is
    /// non-singular in `f64` may be singular or overflow in `f32`).
    pub fn cast<U: Real>(&self) -> Result<Homography<U>> {
        Homography::from_matrix(&self.h.map(|v| U::lit(v.to_f64())))
    }
}

pub(crate) use crate::scalar::above;

/// `adj M = [r₂ × r₃, r₃ × r₁, r₁ × r₂]` (columns), so that `M adj M = det(M) I`.
pub(crate) fn adjugate<T: Real>(m: &Matrix3<T>) -> Matrix3<T> {
    let (r1, r2, r3) = rows(m);
    Matrix3::from_columns(&[r2.cross(&r3), r3.cross(&r1), r1.cross(&r2)])
}

fn rows<T: Real>(m: &Matrix3<T>) -> (Vector3<T>, Vector3<T>, Vector3<T>) {
    (
        Vector3::new(m.m11, m.m12, m.m13),
        Vector3::new(m.m21, m.m22, m.m23),
        Vector3::new(m.m31, m.m32, m.m33),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sample() -> Matrix3<f64> {
        Matrix3::new(1.2, 0.1, -30.0, -0.05, 0.9, 12.0, 2e-4, -1e-4, 1.0)
    }

    #[test]
    fn normalisation_and_accessors() {
        let h = Homography::from_matrix(&(sample() * -3.0)).unwrap();
        assert!((h.matrix() - sample()).amax() < 1e-12);
        // h33 = 0: unit Frobenius norm instead.
        let mut m = sample();
        m.m33 = 0.0;
        let h = Homography::from_matrix(&(m * 7.0)).unwrap();
        assert!((h.matrix().norm() - 1.0).abs() < 1e-12);
        assert_eq!(Homography::<f32>::default(), Homography::identity());
    }

    #[test]
    fn transfer_and_inverse() {
        let h = Homography::from_matrix(&sample()).unwrap();
        let p = Point2::new(100.0, -40.0);
        let q = h.transfer(&p).unwrap();
        let m = sample();
        let w = m.m31 * p.x + m.m32 * p.y + m.m33;
        assert!((q.x - (m.m11 * p.x + m.m12 * p.y + m.m13) / w).abs() < 1e-12);
        let hi = h.inverse().unwrap();
        assert!((hi.transfer(&q).unwrap() - p).amax() < 1e-10);
        let prod = h.matrix() * hi.matrix(); // the identity up to scale
        assert!((prod / prod.m33 - Matrix3::identity()).amax() < 1e-12);
        let id = h.then(&hi).unwrap();
        assert!((id.matrix() - Matrix3::identity()).amax() < 1e-12);
        let h32 = h.cast::<f32>().unwrap();
        assert!((h32.transfer(&p.cast()).unwrap() - q.cast()).amax() < 1e-3);
    }

    #[test]
    fn errors() {
        let h = Homography::from_matrix(&sample()).unwrap();
        assert_eq!(
            h.transfer(&Point2::new(f64::NAN, 0.0)),
            Err(Error::NonFinite)
        );
        // A point on the vanishing line w = 0: 2e-4 x - 1e-4 y + 1 = 0.
        assert_eq!(
            h.transfer(&Point2::new(0.0, 10_000.0)),
            Err(Error::AtInfinity)
        );
        assert_eq!(
            Homography::from_matrix(&Matrix3::<f32>::zeros()),
            Err(Error::Degenerate)
        );
        let mut m = sample();
        m.m12 = f64::INFINITY;
        assert_eq!(Homography::from_matrix(&m), Err(Error::NonFinite));
        // Rank 2: third row = first + second.
        let r = Matrix3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 5.0, 7.0, 9.0);
        assert_eq!(Homography::from_matrix(&r), Err(Error::Degenerate));
        // Row and column scaling does not make a matrix singular.
        let zoom = Matrix3::new(1e6f32, 0.0, 0.0, 0.0, 1e6, 0.0, 0.0, 0.0, 1.0);
        assert!(Homography::from_matrix(&zoom).is_ok());
        let tiny = Matrix3::new(1e-30f32, 0.0, 0.0, 0.0, 1e-30, 0.0, 0.0, 0.0, 1e-30);
        assert_eq!(
            *Homography::from_matrix(&tiny).unwrap().matrix(),
            Matrix3::identity()
        );
    }

    proptest! {
        #[test]
        fn transfer_round_trips(
            a in -0.5f64..0.5, b in -0.5f64..0.5, c in -0.5f64..0.5, d in -0.5f64..0.5,
            tx in -200.0f64..200.0, ty in -200.0f64..200.0,
            g in -1e-3f64..1e-3, k in -1e-3f64..1e-3,
            x in -300.0f64..300.0, y in -300.0f64..300.0,
        ) {
            let m = Matrix3::new(1.0 + a, b, tx, c, 1.0 + d, ty, g, k, 1.0);
            let h = Homography::from_matrix(&m).unwrap();
            let hi = h.inverse().unwrap();
            let p = Point2::new(x, y);
            match h.transfer(&p) {
                Ok(q) => {
                    let back = hi.transfer(&q).unwrap();
                    let scale = 1.0 + q.coords.amax();
                    prop_assert!((back - p).amax() < 1e-9 * scale, "{p} -> {q} -> {back}");
                    // f32 too, with its own tolerance.
                    // (An ill-conditioned H may be singular at f32 precision: then a typed
                    // error is the right answer, and there is nothing to round-trip.)
                    let h32 = h.cast::<f32>();
                    let b32 = h32.and_then(|h32| {
                        let hi32 = h32.inverse()?;
                        h32.transfer(&p.cast()).and_then(|q| hi32.transfer(&q))
                    });
                    if let Ok(b32) = b32 {
                        prop_assert!((b32.cast::<f64>() - p).amax() < 2e-3 * scale);
                    }
                }
                Err(e) => prop_assert_eq!(e, Error::AtInfinity),
            }
        }
    }
}
