//! The pinhole camera with lens distortion: projection and back-projection.
//!
//! A world point `X` is imaged as
//!
//! `X_c = R X + t`,  `x_n = (X_c/Z_c, Y_c/Z_c)`,  `x_d = distort(x_n)`,  `u = K x_d`,
//!
//! which is OpenCV's `projectPoints` with the 5-coefficient model.

mod distortion;
mod intrinsics;

pub use distortion::{Distortion, UndistortConfig};
pub use intrinsics::Intrinsics;

use nalgebra::{Point2, Point3, Unit, Vector3};

use crate::scalar::{Real, check_finite};
use crate::transform::Pose;
use crate::{Error, Result};

/// A calibrated camera: intrinsics `K` and lens distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Camera<T: Real = f32> {
    /// `K`.
    pub intrinsics: Intrinsics<T>,
    /// Lens distortion of normalised coordinates.
    pub distortion: Distortion<T>,
    /// Bounds of the iterative undistortion used by back-projection.
    pub undistort: UndistortConfig<T>,
}

impl<T: Real> Camera<T> {
    /// A camera with lens distortion.
    pub fn new(intrinsics: Intrinsics<T>, distortion: Distortion<T>) -> Self {
        Self {
            intrinsics,
            distortion,
            undistort: UndistortConfig::default(),
        }
    }

    /// An ideal pinhole camera (no distortion).
    pub fn pinhole(intrinsics: Intrinsics<T>) -> Self {
        Self::new(intrinsics, Distortion::none())
    }

    /// Projects a point given in the camera frame.
    ///
    /// Errors: [`Error::BehindCamera`] when `Z_c <= ε |X_c|` (on or behind the principal plane),
    /// [`Error::NonFinite`] for NaN/inf input or a projection that overflows.
    pub fn project_camera_point(&self, xc: &Point3<T>) -> Result<Point2<T>> {
        check_finite(xc.coords.as_slice())?;
        if xc.z <= T::EPSILON * xc.coords.amax() || xc.z <= T::zero() {
            return Err(Error::BehindCamera);
        }
        let n = Point2::new(xc.x / xc.z, xc.y / xc.z);
        let d = self.distortion.distort(&n)?;
        let u = self.intrinsics.normalized_to_pixel(&d);
        check_finite(&[u.x, u.y])?;
        Ok(u)
    }

    /// Projects a world point through the world-to-camera `pose`: `u = K distort(π(R X + t))`.
    pub fn project(&self, pose: &Pose<T>, xw: &Point3<T>) -> Result<Point2<T>> {
        check_finite(xw.coords.as_slice())?;
        self.project_camera_point(&pose.apply(xw))
    }

    /// Projects many points; each output holds the point's own result, so one point behind the
    /// camera does not spoil the others. Errors with [`Error::LengthMismatch`] when the slices
    /// differ in length.
    pub fn project_points(
        &self,
        pose: &Pose<T>,
        world: &[Point3<T>],
        out: &mut [Result<Point2<T>>],
    ) -> Result<()> {
        if world.len() != out.len() {
            return Err(Error::LengthMismatch);
        }
        for (x, o) in world.iter().zip(out.iter_mut()) {
            *o = self.project(pose, x);
        }
        Ok(())
    }

    /// Removes lens distortion from a pixel: the pixel an ideal pinhole camera with the same
    /// `K` would see.
    pub fn undistort_pixel(&self, pixel: &Point2<T>) -> Result<Point2<T>> {
        let n = self.undistort_to_normalized(pixel)?;
        Ok(self.intrinsics.normalized_to_pixel(&n))
    }

    /// Applies lens distortion to an ideal pinhole pixel.
    pub fn distort_pixel(&self, ideal: &Point2<T>) -> Result<Point2<T>> {
        let n = self.intrinsics.pixel_to_normalized(ideal)?;
        let d = self.distortion.distort(&n)?;
        Ok(self.intrinsics.normalized_to_pixel(&d))
    }

    /// Pixel to undistorted normalised coordinates `x_n = distort⁻¹(K⁻¹ u)`.
    pub fn undistort_to_normalized(&self, pixel: &Point2<T>) -> Result<Point2<T>> {
        let d = self.intrinsics.pixel_to_normalized(pixel)?;
        self.distortion.undistort(&d, &self.undistort)
    }

    /// Back-projects a pixel to the unit direction of its ray in the camera frame (`z > 0`):
    /// `d = (x_n, y_n, 1) / |(x_n, y_n, 1)|`. Every point `s d`, `s > 0`, projects to `pixel`.
    pub fn back_project(&self, pixel: &Point2<T>) -> Result<Unit<Vector3<T>>> {
        let n = self.undistort_to_normalized(pixel)?;
        let v = Vector3::new(n.x, n.y, T::one());
        check_finite(v.as_slice())?;
        Ok(Unit::new_normalize(v))
    }

    /// The same camera in another float type.
    pub fn cast<U: Real>(&self) -> Camera<U> {
        let c = |v: T| U::lit(v.to_f64());
        let d = &self.distortion;
        Camera {
            intrinsics: self.intrinsics.cast(),
            distortion: Distortion {
                k1: c(d.k1),
                k2: c(d.k2),
                p1: c(d.p1),
                p2: c(d.p2),
                k3: c(d.k3),
            },
            undistort: UndistortConfig {
                max_iterations: self.undistort.max_iterations,
                tolerance: c(self.undistort.tolerance),
            },
        }
    }
}
