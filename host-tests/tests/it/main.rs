//! The host-side integration tests (recorded data, the CLI, OpenCV fixtures), one module a
//! subject, in one test binary: one link instead of one per file (run one subject with a
//! filter: `cargo test -p camgeom-host --test it pose_sequence:: -- --nocapture`).

mod apriltag;
mod apriltag_cli;
mod apriltag_large;
mod ar_box;
mod aruco;
mod board;
mod calib_aprilgrid;
mod calib_charuco;
mod calib_chessboard;
mod calib_cli;
mod calib_real;
mod calib_rendered;
mod calib_synthetic;
mod calib_undistort;
mod chessboard_scales;
mod cli;
mod common;
mod features;
mod figures;
mod filestorage;
mod homography_cli;
mod homography_sweep;
mod klt;
mod klt_cli;
mod loaders;
mod monitor;
mod pose_chessboard;
mod pose_cli;
mod pose_sequence;
mod projection;
mod sfm_cli;
mod sift;
mod twoview_chessboard;
mod twoview_cli;
mod undistort;
mod vanishing;
mod video;
mod warp;
