//! What a calibration found: the camera, its errors, each view's pose and what the views do
//! not constrain.

use heapless::Vec;

use crate::camera::{CAMERA_PARAMETERS, Camera};
use crate::scalar::Real;
use crate::transform::Pose;

/// A parameter the views do not constrain (its standard deviation is beyond the configured
/// bound): add views at other angles or fix it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationWarning {
    /// `fx` or `fy` (typical of views all nearly fronto-parallel).
    FocalLengthUnconstrained,
    /// `cx` or `cy`.
    PrincipalPointUnconstrained,
    /// A lens coefficient.
    DistortionUnconstrained,
}

/// Why a view was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ViewRejection {
    /// Fewer than 4 board points (a plane's homography and pose need 4).
    TooFewPoints,
    /// The view's board points lie on a line (no homography).
    Degenerate,
    /// No pose through the initial camera fits the view.
    PoseNotFound,
}

impl ViewRejection {
    /// A short name for a report (`too_few_points`, `degenerate`, `pose_not_found`).
    pub fn name(self) -> &'static str {
        match self {
            Self::TooFewPoints => "too_few_points",
            Self::Degenerate => "degenerate",
            Self::PoseNotFound => "pose_not_found",
        }
    }
}

/// Everything a calibration found, for a report, a file or a JSON answer.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationReport<T: Real, const V: usize> {
    /// The calibrated camera (pixels of the calibration images).
    pub camera: Camera<T>,
    /// RMS reprojection error over every used corner, pixels (OpenCV's `rms`).
    pub rms_px: T,
    /// RMS before the joint refinement (from the closed-form start).
    pub initial_rms_px: T,
    /// Per view: `Some(rms)` for a used view, `None` for a rejected one (in the order added).
    pub per_view_rms_px: [Option<T>; V],
    /// Per view: the board's pose (board frame: corner `(i, j)` at `(i s, j s, 0)`, metres
    /// or whatever unit the square size was given in), `None` for a rejected view.
    pub poses: [Option<Pose<T>>; V],
    /// Per view: why it was rejected, `None` for a used one.
    pub rejections: [Option<ViewRejection>; V],
    /// Views used.
    pub views_used: usize,
    /// Views added.
    pub views_added: usize,
    /// Standard deviation of `fx, fy, cx, cy` and the lens coefficients (OpenCV's order:
    /// `k1 k2 p1 p2 k3`, or fisheye `k1 k2 k3 k4` and a zero); zero for a fixed parameter.
    pub std: [T; CAMERA_PARAMETERS],
    /// Accepted Levenberg-Marquardt steps.
    pub iterations: u8,
    /// Parameters the views do not constrain.
    pub warnings: Vec<CalibrationWarning, 3>,
}

impl<T: Real, const V: usize> CalibrationReport<T, V> {
    /// Indices of the rejected views (in the order added).
    pub fn rejected(&self) -> impl Iterator<Item = usize> + '_ {
        self.per_view_rms_px
            .iter()
            .take(self.views_added)
            .enumerate()
            .filter_map(|(i, r)| r.is_none().then_some(i))
    }
}
