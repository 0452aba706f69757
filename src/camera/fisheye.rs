//! Kannala-Brandt fisheye distortion (OpenCV's `cv::fisheye` model).

use nalgebra::{Matrix2, Point2, SMatrix};

use super::undistort::UndistortParams;
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Equidistant fisheye distortion with a 4-term odd polynomial in the incidence angle:
///
/// `r = |x_n|`, `θ = atan r`, `θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`,
/// `x_d = (θ_d / r) x_n`,
///
/// `x_n = (X/Z, Y/Z)` the pinhole normalised point. This is OpenCV's `cv::fisheye` model
/// (`fisheye::projectPoints`, `fisheye::calibrate`) with coefficients `D = (k1, k2, k3, k4)`;
/// OpenCV's skew `alpha` is camgeom's `skew / fx`. The model is defined for `Z > 0` only
/// (fields of view below 180°), as OpenCV's.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fisheye<T: Real = f32> {
    /// `θ³` coefficient.
    pub k1: T,
    /// `θ⁵` coefficient.
    pub k2: T,
    /// `θ⁷` coefficient.
    pub k3: T,
    /// `θ⁹` coefficient.
    pub k4: T,
}

/// Below this `r = |x_n|` the scale `θ_d / r` and its derivative use their Taylor series:
/// `θ_d / r = 1 + (k1 - 1/3) r² + O(r⁴)`, `(d/dr)(θ_d / r) / r = 2 (k1 - 1/3) + O(r²)`; the
/// neglected terms are below `1e-6` relative here, while the closed forms lose digits to
/// cancellation.
const SERIES_RADIUS: f64 = 1e-3;

impl<T: Real> Fisheye<T> {
    /// OpenCV's order `[k1, k2, k3, k4]`.
    pub fn from_opencv(c: [T; 4]) -> Result<Self> {
        check_finite(&c)?;
        let [k1, k2, k3, k4] = c;
        Ok(Self { k1, k2, k3, k4 })
    }

    /// OpenCV's order `[k1, k2, k3, k4]`.
    pub fn to_opencv(&self) -> [T; 4] {
        [self.k1, self.k2, self.k3, self.k4]
    }

    /// The equidistant lens (`θ_d = θ`, all coefficients zero).
    pub fn equidistant() -> Self {
        let z = T::zero();
        Self {
            k1: z,
            k2: z,
            k3: z,
            k4: z,
        }
    }

    /// `θ_d(θ)` and `dθ_d/dθ`.
    fn theta_d(&self, th: T) -> (T, T) {
        let t2 = th * th;
        let poly = T::one() + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4)));
        let dpoly = T::one()
            + t2 * (T::lit(3.0) * self.k1
                + t2 * (T::lit(5.0) * self.k2
                    + t2 * (T::lit(7.0) * self.k3 + t2 * T::lit(9.0) * self.k4)));
        (th * poly, dpoly)
    }

    /// `s = θ_d / r` and `g = (ds/dr) / r` at `r² = r2`.
    fn scale(&self, r2: T) -> (T, T) {
        let r = r2.sqrt();
        let third = T::lit(1.0 / 3.0);
        if r < T::lit(SERIES_RADIUS) {
            let c = self.k1 - third;
            return (T::one() + c * r2, T::lit(2.0) * c);
        }
        let th = r.atan();
        let (td, dtd) = self.theta_d(th);
        let s = td / r;
        let g = (dtd / (T::one() + r2) - s) / r2;
        (s, g)
    }

    /// Applies the distortion to pinhole normalised coordinates.
    pub fn distort(&self, n: &Point2<T>) -> Result<Point2<T>> {
        check_finite(&[n.x, n.y])?;
        let (s, _) = self.scale(n.x * n.x + n.y * n.y);
        let d = Point2::new(n.x * s, n.y * s);
        check_finite(&[d.x, d.y])?;
        Ok(d)
    }

    /// `∂(x_d, y_d)/∂(x, y)` `= s I + g [x² xy; xy y²]`, `s = θ_d / r`, `g = (ds/dr) / r`.
    pub(crate) fn jacobian(&self, x: T, y: T) -> Matrix2<T> {
        let (s, g) = self.scale(x * x + y * y);
        Matrix2::new(s + g * x * x, g * x * y, g * x * y, s + g * y * y)
    }

    /// `∂(x_d, y_d)/∂(k1, k2, k3, k4)`: `x_n θ^(2j+1) / r` for `k_j`.
    pub(crate) fn coefficient_jacobian(&self, x: T, y: T) -> SMatrix<T, 2, 4> {
        let r = (x * x + y * y).sqrt();
        // θ / r → 1 on the axis.
        let (th, th_over_r) = if r < T::lit(SERIES_RADIUS) {
            (r, T::one())
        } else {
            let th = r.atan();
            (th, th / r)
        };
        let t2 = th * th;
        let mut m = SMatrix::<T, 2, 4>::zeros();
        let mut p = t2 * th_over_r;
        for mut col in m.column_iter_mut() {
            col.x = x * p;
            col.y = y * p;
            p *= t2;
        }
        m
    }

    /// Inverts [`Self::distort`]: Newton's method on `θ_d(θ) = |x_d|` from `θ = |x_d|`
    /// (OpenCV's `fisheye::undistortPoints`), bounded by `params`, then `x_n = x_d tan θ / θ_d`.
    /// Where the model folds (`θ_d` not increasing beyond some angle) two angles share an
    /// image; the answer is then a preimage where `θ_d` is increasing, as OpenCV's.
    ///
    /// Errors with [`Error::NoConvergence`] where `θ_d(θ)` is not increasing (the model folds
    /// over), when the angle reaches 90° (no pinhole point: the ray is behind the image plane)
    /// or the bound is reached before the tolerance.
    pub fn undistort(&self, d: &Point2<T>, params: &UndistortParams<T>) -> Result<Point2<T>> {
        let cfg = params.config();
        check_finite(&[d.x, d.y])?;
        let td = (d.x * d.x + d.y * d.y).sqrt();
        if td == T::zero() {
            return Ok(*d);
        }
        let tol = cfg
            .tolerance
            .max(T::lit(8.0) * T::EPSILON * T::one().max(td));
        let floor = T::lit(2.0) * T::EPSILON * T::one().max(td);
        let half_pi = T::frac_pi_2();
        let th = params.newton(
            tol,
            floor,
            td.min(half_pi * T::lit(0.999)),
            |th| {
                let (f, df) = self.theta_d(th);
                let r = f - td;
                r.finite().then_some((r.abs(), (r, df)))
            },
            |th, (r, df)| {
                if !above(df, T::EPSILON) {
                    return Err(Error::NoConvergence);
                }
                let next = th - r / df;
                if !above(next, T::zero()) || next >= half_pi {
                    return Err(Error::NoConvergence);
                }
                Ok(next)
            },
        )?;
        // The model must be increasing up to the solution for the inverse to be unique.
        if !above(self.theta_d(th).1, T::zero()) {
            return Err(Error::NoConvergence);
        }
        let k = th.tan() / td;
        let n = Point2::new(d.x * k, d.y * k);
        check_finite(&[n.x, n.y])?;
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lens() -> Fisheye<f64> {
        Fisheye::from_opencv([-0.013, 0.021, -0.011, 0.002]).unwrap()
    }

    fn eval(f: &Fisheye<f64>, x: f64, y: f64) -> Point2<f64> {
        f.distort(&Point2::new(x, y)).unwrap()
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let d = lens();
        let h = 1e-6;
        for &(x, y) in &[(0.1, -0.2), (0.5, 0.4), (-1.6, 0.3), (2e-4, -1e-4)] {
            let j = d.jacobian(x, y);
            let fx = (eval(&d, x + h, y) - eval(&d, x - h, y)) / (2.0 * h);
            let fy = (eval(&d, x, y + h) - eval(&d, x, y - h)) / (2.0 * h);
            // Central differences of a smooth function: truncation ~h² and rounding ~ε/h
            // (1e-10): 1e-7 leaves margin for the series branch near the axis.
            assert!((j.column(0) - fx).amax() < 1e-7, "{x} {y}");
            assert!((j.column(1) - fy).amax() < 1e-7, "{x} {y}");
            let jk = d.coefficient_jacobian(x, y);
            for k in 0..4 {
                let mut c = d.to_opencv();
                c[k] += h;
                let p = Fisheye::from_opencv(c).unwrap();
                c[k] -= 2.0 * h;
                let m = Fisheye::from_opencv(c).unwrap();
                let num = (eval(&p, x, y) - eval(&m, x, y)) / (2.0 * h);
                assert!((jk.column(k) - num).amax() < 1e-7, "k{k} at {x} {y}");
            }
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let d = lens();
        let cfg = UndistortParams::default();
        for &(x, y) in &[
            (0.0, 0.0),
            (1e-5, 0.0),
            (0.3, -0.2),
            (1.7, 0.5),
            (-3.0, -2.5),
        ] {
            let p = Point2::new(x, y);
            let back = d.undistort(&d.distort(&p).unwrap(), &cfg).unwrap();
            assert!(
                (back - p).amax() < 1e-11 * (1.0 + p.coords.amax()),
                "{p:?} -> {back:?}"
            );
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
        // θ_d = 2 rad is beyond the 90° this lens reaches (θ_d(π/2) ≈ 1.56).
        assert_eq!(
            d.undistort(&Point2::new(2.0, 0.0), &cfg),
            Err(Error::NoConvergence)
        );
        assert_eq!(
            Fisheye::from_opencv([0.0, f64::INFINITY, 0.0, 0.0]),
            Err(Error::NonFinite)
        );
    }
}
