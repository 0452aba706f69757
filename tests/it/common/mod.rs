//! Helpers shared by the synthetic-scene tests (`sfm.rs`, `twoview.rs`): pose errors against
//! the exact ground truth.

use camgeom::nalgebra::Vector3;
use camgeom::transform::{Frame, Transform};

/// The angle of the rotation from `b` to `a`, degrees.
pub fn rot_err<A: Frame, B: Frame>(a: &Transform<A, B, f64>, b: &Transform<A, B, f64>) -> f64 {
    (a.isometry().rotation * b.isometry().rotation.inverse())
        .angle()
        .to_degrees()
}

/// The angle between the directions of `a` and `b`, degrees.
pub fn dir_err(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.normalize()
        .dot(&b.normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}
