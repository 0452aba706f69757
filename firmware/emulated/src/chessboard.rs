//! The bundled chessboard data set (`host-tests/data/chessboard/`): OpenCV's calibration
//! sample camera (640x480, `left_intrinsics.yml`) and the pose of its first view (`left01`).
//!
//! The numbers are copied verbatim from `left_intrinsics.yml` (OpenCV writes 17 significant
//! digits), so that they can be compared with it as text.
#![allow(clippy::excessive_precision)]

/// Inner corners of the chessboard: 9 columns, 6 rows, 25 mm squares.
pub const COLS: usize = 9;
pub const ROWS: usize = 6;
pub const CORNERS: usize = COLS * ROWS;
pub const SQUARE: f64 = 0.025;
/// Image size of the bundled chessboard views.
pub const WIDTH: f32 = 640.0;
pub const HEIGHT: f32 = 480.0;

/// The bundled chessboard camera (OpenCV's calibration sample, 640x480).
pub const FX: f64 = 535.91573396163199;
pub const FY: f64 = 535.91573396163199;
pub const CX: f64 = 342.28315473308373;
pub const CY: f64 = 235.57082909788173;
/// OpenCV's order `(k1, k2, p1, p2, k3)`.
pub const DISTORTION: [f64; 5] = [
    -0.26637260909660682,
    -0.038588898922304653,
    0.0017831947042852964,
    -0.00028122100441115472,
    0.23839153080878486,
];
/// World-to-camera pose of the first chessboard view.
pub const RVEC: [f64; 3] = [
    0.16866673097722978,
    0.27567195383689680,
    0.013463666677617407,
];
pub const TVEC: [f64; 3] = [
    -0.075217911266918208,
    -0.10895943925991841,
    0.39970206949907272,
];

/// `cv2.projectPoints` of a few corners `(index, u, v)` with the first view's pose, from
/// `host-tests/data/chessboard/opencv_projections.csv` (view 0).
pub const OPENCV_PROJECTIONS: [(usize, f64, f64); 5] = [
    (0, 244.4654740907659, 94.00254552665538),
    (8, 514.0535737009153, 86.71658560116734),
    (31, 372.43500491828536, 192.03910199361502),
    (45, 248.8005607563719, 253.62565821635206),
    (53, 510.39673533819024, 266.22060110900924),
];
