//! Hartley's isotropic normalisation of a point set.

use nalgebra::{Matrix3, Point2};

use crate::linalg::hypot;
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// The similarity `x̂ = s (x - c)` that moves the centroid `c` of a point set to the origin and
/// scales its mean distance from the centroid to `√2` (Hartley, "In defense of the eight-point
/// algorithm", 1997), as the matrix `T = [s 0 -s cx; 0 s -s cy; 0 0 1]`.
///
/// It makes the DLT's coefficients `O(1)`, so the algebraic least-squares problem is well
/// conditioned and the estimate invariant to similarity transforms of either image.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Normalization<T: Real = f32> {
    /// Centroid `x`.
    pub cx: T,
    /// Centroid `y`.
    pub cy: T,
    /// Scale `s = √2 / mean |x - c|`.
    pub scale: T,
}

impl<T: Real> Normalization<T> {
    /// The normalisation of `points`. See [`Self::from_points_iter`].
    pub fn from_points(points: &[Point2<T>]) -> Result<Self> {
        Self::from_points_iter(points.iter().copied())
    }

    /// The normalisation of the points an iterator yields (it is walked twice).
    ///
    /// The centroid is accumulated relative to the first point, `c = p₀ + mean(p - p₀)`, so
    /// large offsets (pixel coordinates) lose no precision and coincident points give exactly
    /// zero spread. Errors: no points ([`Error::TooFewPoints`]), NaN/inf or overflowing
    /// coordinates ([`Error::NonFinite`]), all points coincident, i.e. zero mean distance or
    /// one so small that `√2 / d` overflows ([`Error::Degenerate`]).
    pub fn from_points_iter<I>(points: I) -> Result<Self>
    where
        I: Iterator<Item = Point2<T>> + Clone,
    {
        let mut it = points.clone();
        let Some(p0) = it.next() else {
            return Err(Error::TooFewPoints);
        };
        check_finite(&[p0.x, p0.y])?;
        let (mut sx, mut sy, mut n) = (T::zero(), T::zero(), T::zero());
        for p in points.clone() {
            check_finite(&[p.x, p.y])?;
            sx += p.x - p0.x;
            sy += p.y - p0.y;
            n += T::one();
        }
        let cx = p0.x + sx / n;
        let cy = p0.y + sy / n;
        check_finite(&[cx, cy])?;
        let mut sd = T::zero();
        for p in points {
            sd += hypot(p.x - cx, p.y - cy);
        }
        let mean = sd / n;
        check_finite(&[mean])?;
        let scale = T::lit(core::f64::consts::SQRT_2) / mean;
        if !(mean > T::zero() && scale.finite()) {
            return Err(Error::Degenerate);
        }
        Ok(Self { cx, cy, scale })
    }

    /// `x̂ = s (x - c)`.
    pub fn apply(&self, p: &Point2<T>) -> Point2<T> {
        Point2::new(self.scale * (p.x - self.cx), self.scale * (p.y - self.cy))
    }

    /// `T = [s 0 -s cx; 0 s -s cy; 0 0 1]`.
    pub fn matrix(&self) -> Matrix3<T> {
        let (z, o, s) = (T::zero(), T::one(), self.scale);
        Matrix3::new(s, z, -s * self.cx, z, s, -s * self.cy, z, z, o)
    }

    /// `T⁻¹ = [1/s 0 cx; 0 1/s cy; 0 0 1]`.
    pub fn inverse_matrix(&self) -> Matrix3<T> {
        let (z, o) = (T::zero(), T::one());
        let r = o / self.scale;
        Matrix3::new(r, z, self.cx, z, r, self.cy, z, z, o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centroid_and_mean_distance() {
        let pts = [
            Point2::new(600.0f64, 400.0),
            Point2::new(602.0, 400.0),
            Point2::new(600.0, 402.0),
            Point2::new(602.0, 402.0),
        ];
        let n = Normalization::from_points(&pts).unwrap();
        assert_eq!((n.cx, n.cy), (601.0, 401.0));
        let mut mean = 0.0;
        let mut c = Point2::origin();
        for p in &pts {
            let q = n.apply(p);
            mean += q.coords.norm() / 4.0;
            c += q.coords / 4.0;
            // The matrix form agrees with apply.
            let h = n.matrix() * p.to_homogeneous();
            assert!((h.xy() - q.coords).amax() < 1e-12);
            let back = n.inverse_matrix() * q.to_homogeneous();
            assert!((back.xy() - p.coords).amax() < 1e-12);
        }
        assert!((mean - 2f64.sqrt()).abs() < 1e-12);
        assert!(c.coords.amax() < 1e-12);
    }

    #[test]
    fn bad_sets_are_errors() {
        let empty: [Point2<f32>; 0] = [];
        assert_eq!(Normalization::from_points(&empty), Err(Error::TooFewPoints));
        let same = [Point2::new(0.1f32, 0.7); 5];
        assert_eq!(Normalization::from_points(&same), Err(Error::Degenerate));
        let one = [Point2::new(3.0f32, 4.0)];
        assert_eq!(Normalization::from_points(&one), Err(Error::Degenerate));
        let nan = [Point2::new(0.0f32, 0.0), Point2::new(f32::NAN, 1.0)];
        assert_eq!(Normalization::from_points(&nan), Err(Error::NonFinite));
        let inf = [Point2::new(f32::INFINITY, 0.0), Point2::new(0.0, 1.0)];
        assert_eq!(Normalization::from_points(&inf), Err(Error::NonFinite));
        let huge = [Point2::new(-3e38f32, 0.0), Point2::new(3e38, 1.0)];
        assert_eq!(Normalization::from_points(&huge), Err(Error::NonFinite));
        // Two distinct points are enough to normalise.
        let two = [Point2::new(0.0f32, 0.0), Point2::new(0.0, 2.0)];
        let n = Normalization::from_points(&two).unwrap();
        assert!((n.scale - 2f32.sqrt()).abs() < 1e-6);
    }
}
