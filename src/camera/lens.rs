//! The lens of a camera: one of the two models, each with its own coefficients.

use nalgebra::{Matrix2, Point2};

use super::distortion::Distortion;
use super::fisheye::Fisheye;
use super::undistort::UndistortParams;
use crate::Result;
use crate::scalar::Real;

/// Lens coefficients a [`Lens`] exposes to calibration: Brown-Conrady `(k1, k2, p1, p2, k3)`
/// or Kannala-Brandt `(k1, k2, k3, k4)` (the fifth unused, zero).
pub const LENS_COEFFICIENTS: usize = 5;

/// Which lens model, without its coefficients: what a calibration is asked to estimate
/// ([`Lens::model`] of a lens).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LensModel {
    /// Brown-Conrady `(k1, k2, p1, p2, k3)`, OpenCV's 5-coefficient model (`calibrateCamera`).
    #[default]
    BrownConrady,
    /// Kannala-Brandt fisheye `(k1, k2, k3, k4)`, OpenCV's `cv::fisheye` model
    /// (`fisheye::calibrate`).
    KannalaBrandt,
}

/// The lens map of a camera, `x_d = distort(x_n)` on normalised coordinates: one model with
/// its own coefficients, so that a camera cannot mix the two.
///
/// The default is an ideal pinhole: Brown-Conrady with every coefficient zero.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Lens<T: Real = f32> {
    /// Brown-Conrady ([`Distortion`]; all zero: an ideal pinhole).
    BrownConrady(Distortion<T>),
    /// Kannala-Brandt fisheye ([`Fisheye`]).
    KannalaBrandt(Fisheye<T>),
}

impl<T: Real> Default for Lens<T> {
    fn default() -> Self {
        Self::BrownConrady(Distortion::none())
    }
}

impl<T: Real> Lens<T> {
    /// The model of this lens.
    pub fn model(&self) -> LensModel {
        match self {
            Self::BrownConrady(_) => LensModel::BrownConrady,
            Self::KannalaBrandt(_) => LensModel::KannalaBrandt,
        }
    }

    /// A lens of `model` from its coefficients in OpenCV's order, as [`Self::coefficients`]
    /// gives them (Kannala-Brandt reads the first four). Errors: [`crate::Error::NonFinite`].
    pub fn from_coefficients(model: LensModel, c: [T; LENS_COEFFICIENTS]) -> Result<Self> {
        let [c1, c2, c3, c4, _] = c;
        Ok(match model {
            LensModel::BrownConrady => Self::BrownConrady(Distortion::from_opencv(c)?),
            LensModel::KannalaBrandt => {
                Self::KannalaBrandt(Fisheye::from_opencv([c1, c2, c3, c4])?)
            }
        })
    }

    /// The coefficients in OpenCV's order: Brown-Conrady `k1 k2 p1 p2 k3`, Kannala-Brandt
    /// `k1 k2 k3 k4` and a zero.
    pub fn coefficients(&self) -> [T; LENS_COEFFICIENTS] {
        match self {
            Self::BrownConrady(d) => d.to_opencv(),
            Self::KannalaBrandt(f) => {
                let [a, b, c, d] = f.to_opencv();
                [a, b, c, d, T::zero()]
            }
        }
    }

    /// `true` for an ideal pinhole (Brown-Conrady with every coefficient zero): the lens map
    /// is the identity.
    pub fn is_pinhole(&self) -> bool {
        matches!(self, Self::BrownConrady(d) if d.is_none())
    }

    /// Applies the lens to normalised coordinates.
    pub fn distort(&self, n: &Point2<T>) -> Result<Point2<T>> {
        match self {
            Self::BrownConrady(d) => d.distort(n),
            Self::KannalaBrandt(f) => f.distort(n),
        }
    }

    /// Inverts [`Self::distort`] (iteratively, bounded by `params`).
    pub fn undistort(&self, d: &Point2<T>, params: &UndistortParams<T>) -> Result<Point2<T>> {
        match self {
            Self::BrownConrady(b) => b.undistort(d, params),
            Self::KannalaBrandt(f) => f.undistort(d, params),
        }
    }

    /// `∂x_d/∂x_n` (2x2).
    pub(crate) fn jacobian(&self, x: T, y: T) -> Matrix2<T> {
        match self {
            Self::BrownConrady(d) => d.jacobian(x, y),
            Self::KannalaBrandt(f) => f.jacobian(x, y),
        }
    }

    /// The same lens in another float type.
    pub fn cast<U: Real>(&self) -> Lens<U> {
        let c = |v: T| U::lit(v.to_f64());
        match self {
            Self::BrownConrady(d) => Lens::BrownConrady(Distortion {
                k1: c(d.k1),
                k2: c(d.k2),
                p1: c(d.p1),
                p2: c(d.p2),
                k3: c(d.k3),
            }),
            Self::KannalaBrandt(f) => Lens::KannalaBrandt(Fisheye {
                k1: c(f.k1),
                k2: c(f.k2),
                k3: c(f.k3),
                k4: c(f.k4),
            }),
        }
    }
}
