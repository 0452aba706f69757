//! Kalibr's AprilGrid calibration target: a grid of tag36h11 tags with a 2-cell black border
//! ([`crate::apriltag::families::TAG36H11_B2`]) whose 4 corners each are identified board
//! points, so a view that shows only part of the board still gives identified points for
//! calibration ([`crate::calib::Calibrator::with_points`]).
//!
//! - [`AprilGrid`]: the layout, exactly Kalibr's (`GridCalibrationTargetAprilgrid`): ids,
//!   origin, point numbering and the order of each tag's corners.
//! - [`grid_corners`]: the identified corners of one view from its tag detections;
//!   [`refine_corners`]: the corners refined as saddle points at Kalibr's corner squares
//!   (Kalibr's `cornerSubPix`); [`AprilGrid::detect_corners`]: the three in one call.
//!
//! ```
//! use camgeom::aprilgrid::AprilGrid;
//!
//! // Kalibr's `aprilgrid.yaml`: tagCols 6, tagRows 6, tagSize 0.088, tagSpacing 0.3.
//! let grid = AprilGrid::new(6, 6, 0.088, 0.3)?;
//! assert_eq!((grid.tags(), grid.points()), (36, 144));
//! // Tag 7 (second row, second column): bottom-left, bottom-right, top-right, top-left.
//! assert_eq!(grid.tag_points(7), Some([26, 27, 39, 38]));
//! let p = grid.point(27).unwrap();
//! assert!((p.x - (1.3 * 0.088 + 0.088)).abs() < 1e-6 && (p.y - 1.3 * 0.088).abs() < 1e-6);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod detect;
mod grid;

pub use detect::{GridCorner, MAX_REFINE_SHIFT, grid_corners, refine_corners};
pub use grid::{AprilGrid, MAX_TAGS};

#[cfg(test)]
mod tests;
