//! The metric pose of a detected tag.

use nalgebra::Point2;

use super::detector::{CORNER_TAG_COORDS, Detection};
use crate::camera::Camera;
use crate::pose::{PlanarConfig, PlanarPose, solve_planar};
use crate::{Error, Result};

/// The tag's pose for a tag of side `tag_size` (the black border's outer edge; metres or any
/// unit the translation should have), through `camera` (lens distortion included): IPPE's two
/// solutions refined by Levenberg-Marquardt on the reprojection error of the four corners
/// ([`solve_planar`]), best first; [`PlanarPose::is_ambiguous`] tells when the second is
/// nearly as good (a small or fronto-parallel tag).
///
/// The tag frame is AprilTag's (`estimate_tag_pose`): origin at the tag centre, `x` right and
/// `y` down the upright tag image, `z` into the tag; corner `i` of [`Detection::corners`] is
/// the point `(s/2) (x_i, y_i, 0)` with `(x_i, y_i)` = [`CORNER_TAG_COORDS`]`[i]`. So
/// `X_camera = R X_tag + t` with `R`, `t` comparable to AprilTag's `pose_R`, `pose_t`.
///
/// Errors: [`Error::InvalidParameter`]`("tag_size")` for a size that is not finite and
/// positive; as [`solve_planar`] otherwise.
#[doc(alias = "estimatePoseSingleMarkers")]
pub fn tag_pose(
    detection: &Detection,
    tag_size: f32,
    camera: &Camera<f32>,
    cfg: &PlanarConfig,
) -> Result<PlanarPose<f32>> {
    if !(tag_size.is_finite() && tag_size > 0.0) {
        return Err(Error::InvalidParameter("tag_size"));
    }
    let h = 0.5 * tag_size;
    let model = CORNER_TAG_COORDS.map(|(x, y)| Point2::new(h * x, h * y));
    let mut scratch = [Point2::origin(); 4];
    solve_planar(camera, &model, &detection.corners, &mut scratch, cfg)
}
