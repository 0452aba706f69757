//! ChArUco boards (OpenCV's `aruco::CharucoBoard`, `CharucoDetector`): a chessboard whose
//! white squares hold ArUco markers, so each inner corner is identified and a view that shows
//! only part of the board still gives identified points for calibration
//! ([`crate::calib::Calibrator::with_points`]).
//!
//! - [`CharucoBoard`]: the layout, exactly OpenCV ≥ 4.6's (non-legacy) marker ids, marker
//!   corners and chessboard corners.
//! - [`interpolate_corners`]: the corners from markers found by
//!   [`crate::apriltag::Detector`] with the board's dictionary, predicted from the adjacent
//!   markers and refined as saddle points ([`crate::chessboard::saddle_subpix`]).
//!
//! ```
//! use camgeom::apriltag::families;
//! use camgeom::charuco::CharucoBoard;
//!
//! let board = CharucoBoard::new(5, 4, 0.04, 0.03, &families::DICT_4X4_50)?;
//! assert_eq!((board.markers(), board.corners()), (10, 12));
//! assert_eq!(board.marker_square(0), Some((1, 0)));
//! assert_eq!(board.corner_markers(0), Some([0, 2]));
//! # Ok::<(), camgeom::Error>(())
//! ```

mod board;
mod interpolate;

pub use board::{CharucoBoard, MAX_SQUARES};
pub use interpolate::{CharucoConfig, CharucoCorner, CharucoParams, interpolate_corners};
