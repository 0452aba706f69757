//! Brown-Conrady lens distortion (OpenCV's 5-coefficient model).

use nalgebra::{Matrix2, Point2, Vector2};

use super::undistort::UndistortParams;
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Radial (`k1`, `k2`, `k3`) and tangential (`p1`, `p2`) distortion of normalised coordinates:
///
/// `x_d = x a + 2 p1 x y + p2 (r² + 2x²)`, `y_d = y a + p1 (r² + 2y²) + 2 p2 x y`,
/// with `a = 1 + k1 r² + k2 r⁴ + k3 r⁶` and `r² = x² + y²`.
///
/// The coefficient order is OpenCV's `distortion_coefficients`: `(k1, k2, p1, p2, k3)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Distortion<T: Real = f32> {
    /// `r²` coefficient.
    pub k1: T,
    /// `r⁴` coefficient.
    pub k2: T,
    /// First tangential coefficient.
    pub p1: T,
    /// Second tangential coefficient.
    pub p2: T,
    /// `r⁶` coefficient.
    pub k3: T,
}

impl<T: Real> Distortion<T> {
    /// No distortion.
    pub fn none() -> Self {
        let z = T::zero();
        Self {
            k1: z,
            k2: z,
            p1: z,
            p2: z,
            k3: z,
        }
    }

    /// From OpenCV's order `[k1, k2, p1, p2, k3]`.
    pub fn from_opencv(c: [T; 5]) -> Result<Self> {
        check_finite(&c)?;
        let [k1, k2, p1, p2, k3] = c;
        Ok(Self { k1, k2, p1, p2, k3 })
    }

    /// OpenCV's order `[k1, k2, p1, p2, k3]`.
    pub fn to_opencv(&self) -> [T; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// `true` when all coefficients are zero.
    pub fn is_none(&self) -> bool {
        self.to_opencv().iter().all(|c| *c == T::zero())
    }

    /// Applies the distortion to normalised coordinates.
    pub fn distort(&self, n: &Point2<T>) -> Result<Point2<T>> {
        check_finite(&[n.x, n.y])?;
        if self.is_none() {
            return Ok(*n);
        }
        let d = self.eval(n.x, n.y);
        check_finite(&[d.x, d.y])?;
        Ok(Point2::new(d.x, d.y))
    }

    /// Inverts [`Self::distort`] by Newton's method on the 2x2 system, bounded by `params`.
    ///
    /// Errors with [`Error::NoConvergence`] when the point lies where the model folds over
    /// (the Jacobian stops being invertible) or the bound is reached before the tolerance.
    pub fn undistort(&self, d: &Point2<T>, params: &UndistortParams<T>) -> Result<Point2<T>> {
        let cfg = params.config();
        check_finite(&[d.x, d.y])?;
        if self.is_none() {
            return Ok(*d);
        }
        let target = Vector2::new(d.x, d.y);
        let scale = T::one().max(target.amax());
        // Accept at `tol`, but keep stepping while Newton still improves, down to the rounding
        // floor (`2 ε`): the pixel error is `f` times this residual, so stopping early would
        // make the error grow with the focal length.
        let tol = cfg.tolerance.max(T::lit(8.0) * T::EPSILON * scale);
        let floor = T::lit(2.0) * T::EPSILON * scale;
        let x = params.newton(
            tol,
            floor,
            target,
            |x| {
                let r = self.eval(x.x, x.y) - target;
                (r.x.finite() && r.y.finite()).then(|| (r.amax(), r))
            },
            |x, r| {
                let j = self.jacobian(x.x, x.y);
                let det = j.determinant();
                // A non-positive determinant means the model has folded: no unique inverse here.
                if !det.finite() || det <= T::EPSILON * j.amax() * j.amax() {
                    return Err(Error::NoConvergence);
                }
                let inv = Matrix2::new(j.m22, -j.m12, -j.m21, j.m11) / det;
                Ok(x - inv * r)
            },
        )?;
        Ok(Point2::new(x.x, x.y))
    }

    fn eval(&self, x: T, y: T) -> Vector2<T> {
        let two = T::lit(2.0);
        let r2 = x * x + y * y;
        let a = T::one() + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xy = x * y;
        Vector2::new(
            x * a + two * self.p1 * xy + self.p2 * (r2 + two * x * x),
            y * a + self.p1 * (r2 + two * y * y) + two * self.p2 * xy,
        )
    }

    /// `∂(x_d, y_d)/∂(k1, k2, p1, p2, k3)`:
    /// `[x r², x r⁴, 2xy, r² + 2x², x r⁶; y r², y r⁴, r² + 2y², 2xy, y r⁶]`.
    pub(crate) fn coefficient_jacobian(x: T, y: T) -> nalgebra::SMatrix<T, 2, 5> {
        let two = T::lit(2.0);
        let r2 = x * x + y * y;
        let r4 = r2 * r2;
        let xy2 = two * x * y;
        nalgebra::SMatrix::<T, 2, 5>::new(
            x * r2,
            x * r4,
            xy2,
            r2 + two * x * x,
            x * r4 * r2,
            y * r2,
            y * r4,
            r2 + two * y * y,
            xy2,
            y * r4 * r2,
        )
    }

    /// `∂(x_d, y_d)/∂(x, y)`.
    pub(crate) fn jacobian(&self, x: T, y: T) -> Matrix2<T> {
        let two = T::lit(2.0);
        let r2 = x * x + y * y;
        let a = T::one() + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let da = self.k1 + r2 * (two * self.k2 + T::lit(3.0) * self.k3 * r2);
        let cross = two * x * y * da + two * self.p1 * x + two * self.p2 * y;
        Matrix2::new(
            a + two * x * x * da + two * self.p1 * y + T::lit(6.0) * self.p2 * x,
            cross,
            cross,
            a + two * y * y * da + T::lit(6.0) * self.p1 * y + two * self.p2 * x,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens() -> Distortion<f64> {
        Distortion::from_opencv([-0.266, -0.0386, 1.78e-3, -2.81e-4, 0.238]).unwrap()
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let d = lens();
        let h = 1e-6;
        for &(x, y) in &[(0.1, -0.2), (0.5, 0.4), (-0.6, 0.3)] {
            let j = d.jacobian(x, y);
            let fx = (d.eval(x + h, y) - d.eval(x - h, y)) / (2.0 * h);
            let fy = (d.eval(x, y + h) - d.eval(x, y - h)) / (2.0 * h);
            assert!((j.column(0) - fx).amax() < 1e-8);
            assert!((j.column(1) - fy).amax() < 1e-8);
        }
    }

    #[test]
    fn coefficient_jacobian_matches_finite_differences() {
        let h = 1e-6;
        for &(x, y) in &[(0.1, -0.2), (0.5, 0.4), (-0.6, 0.3)] {
            let j = Distortion::<f64>::coefficient_jacobian(x, y);
            for k in 0..5 {
                let mut c = lens().to_opencv();
                c[k] += h;
                let p = Distortion::from_opencv(c).unwrap().eval(x, y);
                c[k] -= 2.0 * h;
                let m = Distortion::from_opencv(c).unwrap().eval(x, y);
                // The model is linear in its coefficients: only rounding (~ε/h) remains.
                assert!((j.column(k) - (p - m) / (2.0 * h)).amax() < 1e-8);
            }
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let d = lens();
        let cfg = UndistortParams::default();
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (0.7, 0.5), (-0.8, -0.55)] {
            let p = Point2::new(x, y);
            let back = d.undistort(&d.distort(&p).unwrap(), &cfg).unwrap();
            assert!((back - p).amax() < 1e-12, "{p:?} -> {back:?}");
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let d = lens();
        let cfg = UndistortParams::default();
        assert_eq!(
            d.distort(&Point2::new(f64::NAN, 0.0)),
            Err(Error::NonFinite)
        );
        assert_eq!(
            d.undistort(&Point2::new(0.0, f64::INFINITY), &cfg),
            Err(Error::NonFinite)
        );
        // Barrel distortion with only k1 = -0.5 peaks at r_d = 0.544 (r² = 2/3): a distorted
        // radius of 1 has no preimage, and the answer must be a typed error, not a wrong point.
        let barrel = Distortion::from_opencv([-0.5, 0.0, 0.0, 0.0, 0.0]).unwrap();
        assert_eq!(
            barrel.undistort(&Point2::new(1.0, 0.0), &cfg),
            Err(Error::NoConvergence)
        );
        // Huge inputs overflow the polynomial.
        let big = Point2::new(1e300, 1e300);
        assert_eq!(d.distort(&big), Err(Error::NonFinite));
        assert_eq!(
            Distortion::from_opencv([0.0, f64::NAN, 0.0, 0.0, 0.0]),
            Err(Error::NonFinite)
        );
    }
}
