//! The pinhole camera with lens distortion: projection and back-projection.
//!
//! A world point `X` is imaged as
//!
//! `X_c = R X + t`,  `x_n = (X_c/Z_c, Y_c/Z_c)`,  `x_d = distort(x_n)`,  `u = K x_d`,
//!
//! which is OpenCV's `projectPoints` with the 5-coefficient model, or, for a fisheye lens
//! ([`Lens::KannalaBrandt`]), `x_d = (θ_d / r) x_n` with `θ_d = θ (1 + k1 θ² + … + k4 θ⁸)`,
//! `θ = atan |x_n|` (OpenCV's `fisheye::projectPoints`). Every entry point taking a [`Camera`]
//! (projection, back-projection, pose solvers and refinement, drawing) follows its [`Lens`].
//!
//! ```
//! use camgeom::camera::{Camera, Distortion, Intrinsics};
//! use camgeom::nalgebra::{Point2, Point3};
//!
//! let cam = Camera::new(
//!     Intrinsics::new(500.0f64, 500.0, 320.0, 240.0)?,
//!     Distortion::from_opencv([-0.2, 0.0, 0.0, 0.0, 0.0])?,
//! );
//! let x = Point3::new(0.2, -0.1, 2.0);
//! let u = cam.project_camera_point(&x)?;
//! // By hand: x_n = (0.1, -0.05), r² = 0.0125, radial factor 1 - 0.2 r² = 0.9975.
//! let expected = Point2::new(320.0 + 500.0 * 0.1 * 0.9975, 240.0 - 500.0 * 0.05 * 0.9975);
//! assert!((u - expected).norm() < 1e-9);
//! // Back-projection undoes the distortion (iteratively): the ray points at `x` again.
//! let ray = cam.back_project(&u)?;
//! assert!((ray.into_inner() - x.coords.normalize()).norm() < 1e-9);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod distortion;
mod fisheye;
mod intrinsics;
mod lens;
mod undistort;

pub use distortion::Distortion;
pub use fisheye::Fisheye;
pub use intrinsics::Intrinsics;
pub use lens::{LENS_COEFFICIENTS, Lens, LensModel};
pub use undistort::{UndistortConfig, UndistortParams};

use nalgebra::{Matrix2, Matrix2x3, Point2, Point3, SMatrix, Unit, Vector3};

use crate::scalar::{Real, check_finite};
use crate::transform::Pose;
use crate::{Error, Result};

/// Parameters of a camera as calibration sees them: `fx fy cx cy` and the lens coefficients.
pub const CAMERA_PARAMETERS: usize = 4 + LENS_COEFFICIENTS;

/// A calibrated camera: intrinsics `K` and its lens.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Camera<T: Real = f32> {
    /// `K`.
    pub intrinsics: Intrinsics<T>,
    /// The lens map of normalised coordinates: Brown-Conrady or Kannala-Brandt fisheye.
    pub lens: Lens<T>,
    /// Bounds of the iterative undistortion used by back-projection.
    pub undistort: UndistortParams<T>,
}

impl<T: Real> Camera<T> {
    /// A camera with Brown-Conrady lens distortion.
    pub fn new(intrinsics: Intrinsics<T>, distortion: Distortion<T>) -> Self {
        Self::with_lens(intrinsics, Lens::BrownConrady(distortion))
    }

    /// A fisheye camera (Kannala-Brandt, OpenCV's `cv::fisheye` model).
    pub fn fisheye(intrinsics: Intrinsics<T>, lens: Fisheye<T>) -> Self {
        Self::with_lens(intrinsics, Lens::KannalaBrandt(lens))
    }

    /// A camera with either lens.
    pub fn with_lens(intrinsics: Intrinsics<T>, lens: Lens<T>) -> Self {
        Self {
            intrinsics,
            lens,
            undistort: UndistortParams::default(),
        }
    }

    /// The lens map of normalised coordinates, `x_d = distort(x_n)`, of this camera's lens.
    pub fn distort_normalized(&self, n: &Point2<T>) -> Result<Point2<T>> {
        self.lens.distort(n)
    }

    /// Inverts [`Self::distort_normalized`], bounded by [`Self::undistort`].
    pub fn undistort_normalized(&self, d: &Point2<T>) -> Result<Point2<T>> {
        self.lens.undistort(d, &self.undistort)
    }

    /// [`Self::project_with_jacobian`] and the Jacobian of the pixel with respect to the
    /// camera's own parameters `(fx, fy, cx, cy, c₁ … c₅)`, the lens coefficients `c` in
    /// OpenCV's order ([`LENS_COEFFICIENTS`]: Brown-Conrady `k1 k2 p1 p2 k3`, fisheye
    /// `k1 k2 k3 k4` and a zero column). With `u = fx x_d + s y_d + cx`, `v = fy y_d + cy`:
    /// `∂u/∂fx = x_d`, `∂v/∂fy = y_d`, `∂u/∂cx = ∂v/∂cy = 1`, `∂u/∂c = K₂ ∂x_d/∂c`. This is what
    /// calibration linearises.
    pub fn project_with_parameter_jacobian(
        &self,
        xc: &Point3<T>,
    ) -> Result<(Point2<T>, Matrix2x3<T>, SMatrix<T, 2, CAMERA_PARAMETERS>)> {
        let (u, j) = self.project_with_jacobian(xc)?;
        let iz = T::one() / xc.z;
        let (x, y) = (xc.x * iz, xc.y * iz);
        let d = self.distort_normalized(&Point2::new(x, y))?;
        let k = &self.intrinsics;
        let k2 = Matrix2::new(k.fx(), k.skew(), T::zero(), k.fy());
        let (z, o) = (T::zero(), T::one());
        let mut jp = SMatrix::<T, 2, CAMERA_PARAMETERS>::zeros();
        jp.fixed_view_mut::<2, 4>(0, 0)
            .copy_from(&nalgebra::Matrix2x4::new(d.x, z, o, z, z, d.y, z, o));
        match &self.lens {
            Lens::BrownConrady(_) => {
                let jc = k2 * Distortion::<T>::coefficient_jacobian(x, y);
                jp.fixed_view_mut::<2, 5>(0, 4).copy_from(&jc);
            }
            Lens::KannalaBrandt(f) => {
                let jc = k2 * f.coefficient_jacobian(x, y);
                jp.fixed_view_mut::<2, 4>(0, 4).copy_from(&jc);
            }
        }
        check_finite(jp.as_slice())?;
        Ok((u, j, jp))
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
        let d = self.distort_normalized(&n)?;
        let u = self.intrinsics.normalized_to_pixel(&d);
        check_finite(&[u.x, u.y])?;
        Ok(u)
    }

    /// [`Self::project_camera_point`] with its Jacobian `∂u/∂X_c` (2x3):
    /// `K₂ ∂distort/∂x_n [1/Z 0 -X/Z²; 0 1/Z -Y/Z²]`, `K₂` the upper-left 2x2 of `K`.
    pub fn project_with_jacobian(&self, xc: &Point3<T>) -> Result<(Point2<T>, Matrix2x3<T>)> {
        let u = self.project_camera_point(xc)?;
        let iz = T::one() / xc.z;
        let (x, y) = (xc.x * iz, xc.y * iz);
        let dn = Matrix2x3::new(iz, T::zero(), -x * iz, T::zero(), iz, -y * iz);
        let k = &self.intrinsics;
        let k2 = Matrix2::new(k.fx(), k.skew(), T::zero(), k.fy());
        let j = if self.lens.is_pinhole() {
            k2 * dn
        } else {
            k2 * self.lens.jacobian(x, y) * dn
        };
        check_finite(j.as_slice())?;
        Ok((u, j))
    }

    /// Projects a world point through the world-to-camera `pose`: `u = K distort(π(R X + t))`.
    pub fn project(&self, pose: &Pose<T>, xw: &Point3<T>) -> Result<Point2<T>> {
        check_finite(xw.coords.as_slice())?;
        self.project_camera_point(&pose.apply(xw))
    }

    /// Projects many points; each output holds the point's own result, so one point behind the
    /// camera does not spoil the others. Errors with [`Error::LengthMismatch`] when the slices
    /// differ in length.
    #[doc(alias = "projectPoints")]
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
    /// `K` would see. Errors: as [`Self::undistort_to_normalized`]; [`Error::NonFinite`] when
    /// the result overflows.
    #[doc(alias = "undistortPoints")]
    #[doc(alias = "undistortImagePoints")]
    pub fn undistort_pixel(&self, pixel: &Point2<T>) -> Result<Point2<T>> {
        let n = self.undistort_to_normalized(pixel)?;
        let u = self.intrinsics.normalized_to_pixel(&n);
        // `K` maps back: with extreme intrinsics (a huge skew or principal point) that can
        // overflow.
        check_finite(&[u.x, u.y])?;
        Ok(u)
    }

    /// Applies lens distortion to an ideal pinhole pixel. Errors: [`Error::NonFinite`] for
    /// NaN/inf input or a result that overflows.
    #[doc(alias = "distortPoints")]
    pub fn distort_pixel(&self, ideal: &Point2<T>) -> Result<Point2<T>> {
        let n = self.intrinsics.pixel_to_normalized(ideal)?;
        let d = self.distort_normalized(&n)?;
        let u = self.intrinsics.normalized_to_pixel(&d);
        check_finite(&[u.x, u.y])?;
        Ok(u)
    }

    /// Pixel to undistorted normalised coordinates `x_n = distort⁻¹(K⁻¹ u)`.
    #[doc(alias = "undistortPoints")]
    pub fn undistort_to_normalized(&self, pixel: &Point2<T>) -> Result<Point2<T>> {
        let d = self.intrinsics.pixel_to_normalized(pixel)?;
        self.undistort_normalized(&d)
    }

    /// Back-projects a pixel to the unit direction of its ray in the camera frame (`z > 0`):
    /// `d = (x_n, y_n, 1) / |(x_n, y_n, 1)|`. Every point `s d`, `s > 0`, projects to `pixel`.
    pub fn back_project(&self, pixel: &Point2<T>) -> Result<Unit<Vector3<T>>> {
        let n = self.undistort_to_normalized(pixel)?;
        let v = Vector3::new(n.x, n.y, T::one());
        check_finite(v.as_slice())?;
        // Scale by the largest component first: `|v|²` of a ray far off the axis (normalised
        // coordinates beyond ~1e19 in f32) overflows, and normalising by an infinite norm
        // would return the zero vector.
        let v = v / v.amax();
        Ok(Unit::new_normalize(v))
    }

    /// The same camera in another float type.
    pub fn cast<U: Real>(&self) -> Camera<U> {
        Camera {
            intrinsics: self.intrinsics.cast(),
            lens: self.lens.cast(),
            undistort: self.undistort.cast(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::homogeneous::{Line2h, Point2h};
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    /// The bundled chessboard camera (OpenCV's calibration sample, `left_intrinsics.yml`).
    fn chessboard_camera() -> Camera<f64> {
        let k = Intrinsics::new(
            535.915_733_961_632,
            535.915_733_961_632,
            342.283_154_733_084,
            235.570_829_097_882,
        )
        .unwrap();
        let d = Distortion::from_opencv([
            -0.266_372_609_096_607,
            -0.038_588_898_922_304_7,
            0.001_783_194_704_285_30,
            -0.000_281_221_004_411_155,
            0.238_391_530_808_785,
        ])
        .unwrap();
        Camera::new(k, d)
    }

    fn pose(r: [f64; 3], t: [f64; 3]) -> Pose<f64> {
        Pose::from_rodrigues(Vector3::from(r), Vector3::from(t)).unwrap()
    }

    fn fisheye_camera() -> Camera<f64> {
        let k = Intrinsics::new(310.0, 305.0, 322.0, 238.0).unwrap();
        Camera::fisheye(
            k,
            Fisheye::from_opencv([-0.013, 0.021, -0.011, 0.002]).unwrap(),
        )
    }

    #[test]
    fn fisheye_camera_round_trips_and_holds_one_lens() {
        let cam = fisheye_camera();
        // 75° off the axis: far outside what a pinhole lens of this focal length images.
        let xc = Point3::new(3.0, -2.0, 1.0);
        let u = cam.project(&Pose::identity(), &xc).unwrap();
        let ray = cam.back_project(&u).unwrap();
        assert_relative_eq!(ray.into_inner(), xc.coords.normalize(), epsilon = 1e-12);
        // Brown-Conrady coefficients are no field beside the fisheye ones (a fisheye camera
        // with them cannot be built): giving the camera some replaces its lens, and it then
        // projects through Brown-Conrady alone.
        assert_eq!(cam.lens.model(), LensModel::KannalaBrandt);
        let brown = Distortion::from_opencv([0.1, 0.0, 0.0, 0.0, 0.0]).unwrap();
        let mut other = cam;
        other.lens = Lens::BrownConrady(brown);
        assert_eq!(other.lens.model(), LensModel::BrownConrady);
        let expected = cam
            .intrinsics
            .normalized_to_pixel(&brown.distort(&Point2::new(3.0, -2.0)).unwrap());
        assert_eq!(other.project(&Pose::identity(), &xc), Ok(expected));
    }

    /// `∂u/∂X_c` and `∂u/∂(fx fy cx cy c)` of both models against central differences.
    #[test]
    fn parameter_jacobian_matches_finite_differences() {
        let h = 1e-6;
        for cam in [chessboard_camera(), fisheye_camera()] {
            for xc in [Point3::new(0.1, -0.2, 1.0), Point3::new(-0.4, 0.3, 0.8)] {
                let (u, jx, jp) = cam.project_with_parameter_jacobian(&xc).unwrap();
                assert_eq!(u, cam.project_camera_point(&xc).unwrap());
                for k in 0..3 {
                    let mut a = xc;
                    a[k] += h;
                    let mut b = xc;
                    b[k] -= h;
                    let num = (cam.project_camera_point(&a).unwrap()
                        - cam.project_camera_point(&b).unwrap())
                        / (2.0 * h);
                    // Pixel derivatives are ~500 px per unit: truncation h² · 500 and
                    // rounding 500 ε / h stay below 1e-5.
                    assert!((jx.column(k) - num).amax() < 1e-5);
                }
                let param = |c: &Camera<f64>, k: usize, d: f64| {
                    let mut c = *c;
                    let i = &c.intrinsics;
                    let mut kk = [i.fx(), i.fy(), i.cx(), i.cy()];
                    if k < 4 {
                        kk[k] += d;
                    } else {
                        match &mut c.lens {
                            Lens::BrownConrady(b) => {
                                let mut v = b.to_opencv();
                                v[k - 4] += d;
                                *b = Distortion::from_opencv(v).unwrap();
                            }
                            Lens::KannalaBrandt(f) => {
                                let mut v = f.to_opencv();
                                if let Some(x) = v.get_mut(k - 4) {
                                    *x += d;
                                }
                                *f = Fisheye::from_opencv(v).unwrap();
                            }
                        }
                    }
                    c.intrinsics = Intrinsics::new(kk[0], kk[1], kk[2], kk[3]).unwrap();
                    c.project_camera_point(&xc).unwrap()
                };
                for k in 0..CAMERA_PARAMETERS {
                    let num = (param(&cam, k, h) - param(&cam, k, -h)) / (2.0 * h);
                    assert!((jp.column(k) - num).amax() < 1e-5, "parameter {k}");
                }
            }
        }
    }

    #[test]
    fn points_behind_or_on_the_camera_plane_are_errors() {
        let cam = chessboard_camera();
        let id = Pose::identity();
        assert_eq!(
            cam.project(&id, &Point3::new(0.1, 0.2, -1.0)),
            Err(Error::BehindCamera)
        );
        assert_eq!(
            cam.project(&id, &Point3::new(0.1, 0.2, 0.0)),
            Err(Error::BehindCamera)
        );
        assert_eq!(
            cam.project(&id, &Point3::new(f64::NAN, 0.2, 1.0)),
            Err(Error::NonFinite)
        );
        assert_eq!(
            cam.project(&id, &Point3::new(0.0, 0.0, f64::INFINITY)),
            Err(Error::NonFinite)
        );
        let mut out = [Ok(Point2::origin()); 2];
        let pts = [Point3::new(0.0, 0.0, 1.0), Point3::new(0.0, 0.0, -1.0)];
        cam.project_points(&id, &pts, &mut out).unwrap();
        assert!(out[0].is_ok());
        assert_eq!(out[1], Err(Error::BehindCamera));
        assert_eq!(
            cam.project_points(&id, &pts, &mut out[..1]),
            Err(Error::LengthMismatch)
        );
        assert_eq!(
            cam.back_project(&Point2::new(f64::NAN, 1.0)),
            Err(Error::NonFinite)
        );
    }

    #[test]
    fn principal_point_is_the_optical_axis() {
        let cam = chessboard_camera();
        let c = Point2::new(cam.intrinsics.cx(), cam.intrinsics.cy());
        let ray = cam.back_project(&c).unwrap();
        assert_relative_eq!(ray.into_inner(), Vector3::z(), epsilon = 1e-15);
        assert_relative_eq!(
            cam.project(&Pose::identity(), &Point3::new(0.0, 0.0, 3.0))
                .unwrap(),
            c
        );
    }

    /// The vanishing point of a family of parallel 3D lines is the image of their common
    /// direction, `v = K R d`; two directions of a plane give its vanishing line `K⁻ᵀ R n`.
    #[test]
    fn vanishing_geometry_of_a_grid() {
        let cam = Camera::pinhole(chessboard_camera().intrinsics);
        let pose = pose([0.4, -0.3, 0.1], [-0.2, 0.1, 2.0]);
        let k = cam.intrinsics.matrix();
        let mut vps = [Point2h::ideal(1.0, 0.0).unwrap(); 2];
        for (axis, vp) in [Vector3::x(), Vector3::y()].iter().zip(vps.iter_mut()) {
            // Two grid lines along `axis` through different points of the z = 0 plane.
            let line = |o: Vector3<f64>| {
                let a = cam.project(&pose, &Point3::from(o)).unwrap();
                let b = cam.project(&pose, &Point3::from(o + axis * 0.5)).unwrap();
                Point2h::from_euclidean(&a)
                    .unwrap()
                    .join(&Point2h::from_euclidean(&b).unwrap())
                    .unwrap()
            };
            let other = Vector3::new(axis.y, axis.x, 0.0);
            // Five grid lines of the family, 10 cm apart: their least-squares common point.
            let family: [Line2h<f64>; 5] = core::array::from_fn(|i| line(other * (0.1 * i as f64)));
            *vp = crate::homogeneous::vanishing_point(&family).unwrap();
            let expected = k * pose.apply_vector(axis);
            let (a, b) = (vp.normalized().coords().normalize(), expected.normalize());
            assert!((a - b).amax() < 1e-9 || (a + b).amax() < 1e-9, "{a} vs {b}");
        }
        let horizon: Line2h<f64> = crate::homogeneous::vanishing_line(&vps[0], &vps[1]).unwrap();
        let n = k.try_inverse().unwrap().transpose() * pose.apply_vector(&Vector3::z());
        let (a, b) = (horizon.coords().normalize(), n.normalize());
        assert!((a - b).amax() < 1e-9 || (a + b).amax() < 1e-9);
    }

    /// The undistortion error in pixels is `f` times its normalised residual, so it must reach
    /// the rounding floor: the same lens on a sensor three times larger (f = 1608 px,
    /// 1920x1440) still round-trips within 1e-3 px in f32.
    #[test]
    fn undistort_precision_does_not_degrade_with_focal_length() {
        let c = chessboard_camera();
        let k = Intrinsics::new(
            3.0 * c.intrinsics.fx(),
            3.0 * c.intrinsics.fy(),
            3.0 * c.intrinsics.cx(),
            3.0 * c.intrinsics.cy(),
        )
        .unwrap();
        let cam = Camera::with_lens(k, c.lens).cast::<f32>();
        let mut worst = 0.0f32;
        for y in (0..1440).step_by(7) {
            for x in (0..1920).step_by(7) {
                let p = Point2::new(x as f32, y as f32);
                let back = cam
                    .distort_pixel(&cam.undistort_pixel(&p).unwrap())
                    .unwrap();
                worst = worst.max((back - p).amax());
            }
        }
        assert!(worst < 1e-3, "worst {worst} px");
    }

    fn finite_pose() -> impl Strategy<Value = Pose<f64>> {
        (
            prop::array::uniform3(-1.5f64..1.5),
            prop::array::uniform3(-1.0f64..1.0),
        )
            .prop_map(|(r, t)| pose(r, t))
    }

    proptest! {
        /// back_project(project(X)) is the direction of X in the camera frame.
        #[test]
        fn project_back_project_round_trip(
            pose in finite_pose(),
            x in prop::array::uniform2(-0.5f64..0.5),
            depth in 0.3f64..20.0,
        ) {
            let cam = chessboard_camera();
            // A camera-frame point inside the lens's calibrated field (|x_n| ≤ 0.5).
            let xc = Point3::new(x[0] * depth, x[1] * depth, depth);
            let xw = pose.inverse().apply(&xc);
            let u = cam.project(&pose, &xw).unwrap();
            let ray = cam.back_project(&u).unwrap();
            prop_assert!((ray.into_inner() - xc.coords.normalize()).amax() < 1e-10);
            // And the point along the ray at the original depth reprojects to the same pixel.
            let again = cam.project_camera_point(&Point3::from(ray.into_inner() * xc.coords.norm())).unwrap();
            prop_assert!((again - u).amax() < 1e-8);
        }

        /// f32 and f64 paths agree to f32 rounding (a few 1e-4 px at 600 px from the origin).
        #[test]
        fn f32_matches_f64(x in prop::array::uniform2(-0.5f64..0.5), depth in 0.3f64..20.0) {
            let cam = chessboard_camera();
            let xc = Point3::new(x[0] * depth, x[1] * depth, depth);
            let u64 = cam.project_camera_point(&xc).unwrap();
            let u32 = cam.cast::<f32>().project_camera_point(&xc.cast::<f32>()).unwrap();
            prop_assert!((u32.cast::<f64>() - u64).amax() < 1e-3);
        }

        /// Projection never panics, whatever the input.
        #[test]
        fn projection_total(v in prop::array::uniform3(prop::num::f32::ANY)) {
            let cam = chessboard_camera().cast::<f32>();
            if let Ok(u) = cam.project_camera_point(&Point3::from(v)) {
                prop_assert!(u.x.is_finite() && u.y.is_finite());
            }
            if let Ok(r) = cam.back_project(&Point2::new(v[0], v[1])) {
                prop_assert!(r.into_inner().iter().all(|c| c.is_finite()));
            }
        }
    }
}
