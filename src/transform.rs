//! Rigid transforms between typed coordinate frames.
//!
//! A [`Transform<A, B>`] maps coordinates expressed in frame `A` into frame `B`:
//!
//! `X_B = R X_A + t`, as the 4x4 matrix `T = [R t; 0 1]`.
//!
//! The frames are marker types, so a world-to-camera pose ([`Transform<World, Camera>`], what
//! OpenCV's `rvec`/`tvec` hold) cannot be passed where a camera-to-world pose is expected.
//! Composition follows the arrows: `a_to_b.then(&b_to_c)` is `a_to_c`.
//!
//! ```
//! use camgeom::nalgebra::{Point3, Vector3};
//! use camgeom::transform::{Camera, Pose, Target, Transform};
//!
//! // A quarter turn about z, then 2 along z: (1, 0, 0) goes to (0, 1, 2).
//! let pose = Pose::<f64>::from_rodrigues(
//!     Vector3::new(0.0, 0.0, core::f64::consts::FRAC_PI_2),
//!     Vector3::new(0.0, 0.0, 2.0),
//! )?;
//! let p = pose.apply(&Point3::new(1.0, 0.0, 0.0));
//! assert!((p - Point3::new(0.0, 1.0, 2.0)).norm() < 1e-12);
//! // The camera centre C = -Rᵀt maps to the camera's origin.
//! assert!(pose.apply(&pose.camera_center()).coords.norm() < 1e-12);
//! // World -> Camera -> Target composed with its inverse is the identity.
//! let cam_to_target: Transform<Camera, Target, f64> =
//!     Transform::from_rodrigues(Vector3::new(0.3, -0.2, 0.1), Vector3::new(1.0, 2.0, 3.0))?;
//! let world_to_target = pose.then(&cam_to_target);
//! let round = world_to_target.then(&world_to_target.inverse());
//! assert!((round.matrix() - camgeom::nalgebra::Matrix4::identity()).amax() < 1e-12);
//! # Ok::<(), camgeom::Error>(())
//! ```

use core::fmt;
use core::marker::PhantomData;

use nalgebra::{
    Isometry3, Matrix3, Matrix4, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// A named coordinate frame (a marker type; it holds no data).
pub trait Frame {
    /// Name used in debug output.
    const NAME: &'static str;
}

/// Declares marker frame types. Users may declare their own with the same macro.
#[macro_export]
macro_rules! frame {
    ($(#[$m:meta])* $name:ident) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        pub enum $name {}
        impl $crate::transform::Frame for $name {
            const NAME: &'static str = stringify!($name);
        }
    };
}

frame!(
    /// The world (scene) frame.
    World
);
frame!(
    /// The camera frame: `x` right, `y` down, `z` along the optical axis (OpenCV's convention).
    Camera
);
frame!(
    /// The frame of a planar target (the target lies in its `z = 0` plane).
    Target
);

/// A rigid transform from frame `A` to frame `B`: `X_B = R X_A + t`.
pub struct Transform<A: Frame, B: Frame, T: Real = f32> {
    iso: Isometry3<T>,
    // `fn(A) -> B`: no ownership of A or B, and Send/Sync whatever the markers are.
    _frames: PhantomData<fn(A) -> B>,
}

impl<A: Frame, B: Frame, T: Real> Clone for Transform<A, B, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<A: Frame, B: Frame, T: Real> Copy for Transform<A, B, T> {}

impl<A: Frame, B: Frame, T: Real> PartialEq for Transform<A, B, T> {
    fn eq(&self, other: &Self) -> bool {
        self.iso == other.iso
    }
}

impl<A: Frame, B: Frame, T: Real> fmt::Debug for Transform<A, B, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Transform<{} -> {}>({:?})", A::NAME, B::NAME, self.iso)
    }
}

#[cfg(feature = "defmt")]
impl<A: Frame, B: Frame> defmt::Format for Transform<A, B, f32> {
    fn format(&self, f: defmt::Formatter<'_>) {
        let r = self.rotation_vector();
        let t = self.translation();
        defmt::write!(
            f,
            "Transform<{=str} -> {=str}>(rvec [{} {} {}], t [{} {} {}])",
            A::NAME,
            B::NAME,
            r.x,
            r.y,
            r.z,
            t.x,
            t.y,
            t.z
        )
    }
}

impl<A: Frame, B: Frame, T: Real> Default for Transform<A, B, T> {
    fn default() -> Self {
        Self::identity()
    }
}

impl<A: Frame, B: Frame, T: Real> Transform<A, B, T> {
    /// The identity: the two frames coincide.
    pub fn identity() -> Self {
        Self::from_isometry(Isometry3::identity())
    }

    /// Wraps an nalgebra isometry that maps `A` coordinates to `B` coordinates.
    pub fn from_isometry(iso: Isometry3<T>) -> Self {
        Self {
            iso,
            _frames: PhantomData,
        }
    }

    /// From a rotation and a translation: `X_B = R X_A + t`. A rotation matrix slightly off
    /// orthonormal (rounding) is taken to the nearby rotation of its unit quaternion.
    /// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when the matrix has no rotation
    /// part (its quaternion is zero).
    pub fn new(rotation: Rotation3<T>, translation: Vector3<T>) -> Result<Self> {
        check_finite(rotation.matrix().as_slice())?;
        check_finite(translation.as_slice())?;
        // `from_rotation_matrix` trusts its input: a matrix a little off orthonormal (a
        // solver's rounding) gives a quaternion a little off unit length, and with it a
        // "rotation" that scales. Normalise it.
        let q = UnitQuaternion::from_rotation_matrix(&rotation).into_inner();
        let n = q.norm();
        if !(n.finite() && n > T::zero()) {
            return Err(Error::Degenerate);
        }
        Ok(Self::from_isometry(Isometry3::from_parts(
            Translation3::from(translation),
            UnitQuaternion::new_unchecked(q / n),
        )))
    }

    /// From OpenCV's `rvec` (axis-angle, `|r|` = angle in radians) and `tvec`.
    #[doc(alias = "Rodrigues")]
    pub fn from_rodrigues(rvec: Vector3<T>, tvec: Vector3<T>) -> Result<Self> {
        check_finite(rvec.as_slice())?;
        check_finite(tvec.as_slice())?;
        Ok(Self::from_isometry(Isometry3::new(tvec, rvec)))
    }

    /// From a 3x3 matrix that must be a rotation (orthonormal, `det = +1`, within `tol` on every
    /// entry of `R^T R - I` and on `det - 1`), and a translation.
    pub fn from_matrix_parts(r: &Matrix3<T>, t: Vector3<T>, tol: T) -> Result<Self> {
        check_finite(r.as_slice())?;
        let err = (r.transpose() * r - Matrix3::identity()).amax();
        if err > tol || (r.determinant() - T::one()).abs() > tol {
            return Err(Error::InvalidParameter("rotation"));
        }
        Self::new(Rotation3::from_matrix_unchecked(*r), t)
    }

    /// The underlying isometry.
    pub fn isometry(&self) -> &Isometry3<T> {
        &self.iso
    }

    /// Rotation `R`.
    pub fn rotation(&self) -> Rotation3<T> {
        self.iso.rotation.to_rotation_matrix()
    }

    /// Rotation as an axis-angle vector (OpenCV's `rvec`).
    #[doc(alias = "Rodrigues")]
    pub fn rotation_vector(&self) -> Vector3<T> {
        self.iso.rotation.scaled_axis()
    }

    /// Translation `t`.
    pub fn translation(&self) -> Vector3<T> {
        self.iso.translation.vector
    }

    /// The 4x4 homogeneous matrix `[R t; 0 1]`.
    pub fn matrix(&self) -> Matrix4<T> {
        self.iso.to_homogeneous()
    }

    /// Maps a point: `X_B = R X_A + t`.
    pub fn apply(&self, p: &Point3<T>) -> Point3<T> {
        self.iso.transform_point(p)
    }

    /// Maps a direction (rotation only): `d_B = R d_A`.
    pub fn apply_vector(&self, v: &Vector3<T>) -> Vector3<T> {
        self.iso.transform_vector(v)
    }

    /// The inverse, from `B` to `A`: `[R^T  -R^T t; 0 1]`.
    pub fn inverse(&self) -> Transform<B, A, T> {
        Transform::from_isometry(self.iso.inverse())
    }

    /// Composition along the arrows: `(A -> B) then (B -> C)` is `A -> C`, `T_AC = T_BC T_AB`.
    pub fn then<C: Frame>(&self, next: &Transform<B, C, T>) -> Transform<A, C, T> {
        Transform::from_isometry(next.iso * self.iso)
    }

    /// Position of frame `A`'s origin expressed in `B` (equals `t`).
    pub fn origin_in_target_frame(&self) -> Point3<T> {
        Point3::from(self.iso.translation.vector)
    }
}

/// World-to-camera pose: what OpenCV's `solvePnP` returns as `rvec`, `tvec`.
pub type Pose<T = f32> = Transform<World, Camera, T>;

impl<T: Real> Transform<World, Camera, T> {
    /// The camera centre in world coordinates, `C = -R^T t`.
    pub fn camera_center(&self) -> Point3<T> {
        self.inverse().origin_in_target_frame()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn compose_and_invert_round_trip() {
        let a: Transform<World, Camera, f64> =
            Transform::from_rodrigues(Vector3::new(0.1, -0.4, 0.3), Vector3::new(1.0, 2.0, 3.0))
                .unwrap();
        let b: Transform<Camera, Target, f64> =
            Transform::from_rodrigues(Vector3::new(-0.7, 0.2, 0.05), Vector3::new(-0.5, 0.0, 4.0))
                .unwrap();
        let ab = a.then(&b);
        let p = Point3::new(0.3, -1.2, 5.0);
        // Composition equals applying one after the other.
        assert_relative_eq!(ab.apply(&p), b.apply(&a.apply(&p)), epsilon = 1e-12);
        // The 4x4 matrices compose the same way: T_AC = T_BC T_AB.
        assert_relative_eq!(ab.matrix(), b.matrix() * a.matrix(), epsilon = 1e-12);
        // Inverse undoes the transform and its matrix is the matrix inverse.
        assert_relative_eq!(a.inverse().apply(&a.apply(&p)), p, epsilon = 1e-12);
        assert_relative_eq!(
            a.inverse().matrix(),
            a.matrix().try_inverse().unwrap(),
            epsilon = 1e-12
        );
        // Camera centre maps to the camera origin.
        assert_relative_eq!(
            a.apply(&a.camera_center()),
            Point3::origin(),
            epsilon = 1e-12
        );
    }

    #[test]
    fn rejects_non_finite_and_non_rotation() {
        let nan = Vector3::new(f32::NAN, 0.0, 0.0);
        assert_eq!(
            Pose::from_rodrigues(nan, Vector3::zeros()),
            Err(Error::NonFinite)
        );
        assert_eq!(
            Pose::from_rodrigues(Vector3::zeros(), nan),
            Err(Error::NonFinite)
        );
        let scaled = Matrix3::identity() * 2.0f32;
        assert_eq!(
            Pose::from_matrix_parts(&scaled, Vector3::zeros(), 1e-5),
            Err(Error::InvalidParameter("rotation"))
        );
        let reflection = Matrix3::from_diagonal(&Vector3::new(1.0f32, 1.0, -1.0));
        assert_eq!(
            Pose::from_matrix_parts(&reflection, Vector3::zeros(), 1e-5),
            Err(Error::InvalidParameter("rotation"))
        );
    }

    #[test]
    fn rodrigues_matches_opencv_convention() {
        // A quarter turn about z maps x to y.
        let t = Pose::from_rodrigues(
            Vector3::new(0.0, 0.0, core::f32::consts::FRAC_PI_2),
            Vector3::zeros(),
        )
        .unwrap();
        assert_relative_eq!(
            t.apply(&Point3::new(1.0, 0.0, 0.0)),
            Point3::new(0.0, 1.0, 0.0),
            epsilon = 1e-6
        );
        assert_relative_eq!(
            t.rotation_vector(),
            Vector3::new(0.0, 0.0, core::f32::consts::FRAC_PI_2),
            epsilon = 1e-6
        );
    }
}
