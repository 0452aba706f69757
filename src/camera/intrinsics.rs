//! Pinhole intrinsics `K`.

use nalgebra::{Matrix3, Point2};

use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Pinhole intrinsics, the upper-triangular camera matrix
///
/// `K = [fx s cx; 0 fy cy; 0 0 1]`,  pixel `u = K x_n` for normalised `x_n = (X/Z, Y/Z, 1)`.
///
/// Construction validates: all finite, `fx > 0`, `fy > 0`; so `K` is always invertible.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Intrinsics<T: Real = f32> {
    fx: T,
    fy: T,
    cx: T,
    cy: T,
    skew: T,
}

impl<T: Real> Intrinsics<T> {
    /// Zero-skew intrinsics.
    pub fn new(fx: T, fy: T, cx: T, cy: T) -> Result<Self> {
        Self::with_skew(fx, fy, cx, cy, T::zero())
    }

    /// Intrinsics with a skew term `s` (`K[0][1]`).
    pub fn with_skew(fx: T, fy: T, cx: T, cy: T, skew: T) -> Result<Self> {
        check_finite(&[fx, fy, cx, cy, skew])?;
        // Focal lengths must be strictly positive and large enough that 1/f is finite.
        let min_f = T::EPSILON.sqrt();
        if !(fx > min_f && fy > min_f) {
            return Err(Error::InvalidIntrinsics);
        }
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            skew,
        })
    }

    /// From a 3x3 matrix whose last row must be `[0 0 1]` and lower triangle zero (as OpenCV's
    /// `camera_matrix`).
    pub fn from_matrix(k: &Matrix3<T>) -> Result<Self> {
        check_finite(k.as_slice())?;
        if k.m21 != T::zero() || k.m31 != T::zero() || k.m32 != T::zero() || k.m33 != T::one() {
            return Err(Error::InvalidIntrinsics);
        }
        Self::with_skew(k.m11, k.m22, k.m13, k.m23, k.m12)
    }

    /// Focal length in pixels along `x`.
    pub fn fx(&self) -> T {
        self.fx
    }
    /// Focal length in pixels along `y`.
    pub fn fy(&self) -> T {
        self.fy
    }
    /// Principal point `x`.
    pub fn cx(&self) -> T {
        self.cx
    }
    /// Principal point `y`.
    pub fn cy(&self) -> T {
        self.cy
    }
    /// Skew `s`.
    pub fn skew(&self) -> T {
        self.skew
    }

    /// `K`.
    pub fn matrix(&self) -> Matrix3<T> {
        let (z, o) = (T::zero(), T::one());
        Matrix3::new(self.fx, self.skew, self.cx, z, self.fy, self.cy, z, z, o)
    }

    /// `K^-1 = [1/fx  -s/(fx fy)  (s cy - cx fy)/(fx fy); 0 1/fy -cy/fy; 0 0 1]`.
    pub fn inverse_matrix(&self) -> Matrix3<T> {
        let (z, o) = (T::zero(), T::one());
        let fxfy = self.fx * self.fy;
        Matrix3::new(
            o / self.fx,
            -self.skew / fxfy,
            (self.skew * self.cy - self.cx * self.fy) / fxfy,
            z,
            o / self.fy,
            -self.cy / self.fy,
            z,
            z,
            o,
        )
    }

    /// Normalised image coordinates to pixels: `u = fx x + s y + cx`, `v = fy y + cy`.
    pub fn normalized_to_pixel(&self, n: &Point2<T>) -> Point2<T> {
        Point2::new(
            self.fx * n.x + self.skew * n.y + self.cx,
            self.fy * n.y + self.cy,
        )
    }

    /// Pixels to normalised coordinates: `y = (v - cy)/fy`, `x = (u - cx - s y)/fx`.
    ///
    /// Errors: [`Error::NonFinite`] for NaN/inf input or a result that overflows (e.g.
    /// `v - cy` beyond the float range, or a tiny `fx` against a large skew term).
    pub fn pixel_to_normalized(&self, p: &Point2<T>) -> Result<Point2<T>> {
        check_finite(&[p.x, p.y])?;
        let y = (p.y - self.cy) / self.fy;
        let x = (p.x - self.cx - self.skew * y) / self.fx;
        check_finite(&[x, y])?;
        Ok(Point2::new(x, y))
    }

    /// The same intrinsics in another float type.
    pub fn cast<U: Real>(&self) -> Intrinsics<U> {
        Intrinsics {
            fx: U::lit(self.fx.to_f64()),
            fy: U::lit(self.fy.to_f64()),
            cx: U::lit(self.cx.to_f64()),
            cy: U::lit(self.cy.to_f64()),
            skew: U::lit(self.skew.to_f64()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn inverse_is_inverse() {
        let k = Intrinsics::with_skew(535.9f64, 530.1, 342.3, 235.6, 1.5).unwrap();
        assert_relative_eq!(
            k.matrix() * k.inverse_matrix(),
            Matrix3::identity(),
            epsilon = 1e-12
        );
        let p = Point2::new(17.0, 400.5);
        let n = k.pixel_to_normalized(&p).unwrap();
        assert_relative_eq!(k.normalized_to_pixel(&n), p, epsilon = 1e-9);
    }

    #[test]
    fn rejects_bad_intrinsics() {
        assert_eq!(
            Intrinsics::new(0.0f32, 500.0, 320.0, 240.0),
            Err(Error::InvalidIntrinsics)
        );
        assert_eq!(
            Intrinsics::new(500.0f32, -1.0, 320.0, 240.0),
            Err(Error::InvalidIntrinsics)
        );
        assert_eq!(
            Intrinsics::new(f32::NAN, 500.0, 320.0, 240.0),
            Err(Error::NonFinite)
        );
        assert_eq!(
            Intrinsics::new(500.0f32, 500.0, f32::INFINITY, 240.0),
            Err(Error::NonFinite)
        );
        let mut k = Matrix3::new(500.0f32, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        assert!(Intrinsics::from_matrix(&k).is_ok());
        k.m33 = 0.0; // singular
        assert_eq!(Intrinsics::from_matrix(&k), Err(Error::InvalidIntrinsics));
        k.m33 = 1.0;
        k.m31 = 0.1;
        assert_eq!(Intrinsics::from_matrix(&k), Err(Error::InvalidIntrinsics));
        let k0 = Intrinsics::new(500.0f32, 500.0, 320.0, 240.0).unwrap();
        assert_eq!(
            k0.pixel_to_normalized(&Point2::new(f32::NAN, 1.0)),
            Err(Error::NonFinite)
        );
    }
}
