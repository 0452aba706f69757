//! Argument groups several subcommands flatten into theirs (`#[command(flatten)]`).

use std::path::PathBuf;

use clap::Args;

/// The camera file of the subcommands that need one camera (`project`, `camera`, `pose`, `ar`,
/// `sfm`, `undistort`).
#[derive(Args, Debug, Clone)]
pub struct CameraArg {
    /// Camera file: .yml/.yaml or .xml (OpenCV calibration: camera_matrix and
    /// distortion_coefficients; fisheye files with `fisheye_model: 1`), .json or .toml
    /// (camgeom: fx, fy, cx, cy and optional skew, distortion, width and height; see `camgeom
    /// camera`).
    #[arg(long, value_name = "FILE")]
    pub intrinsics: PathBuf,
}

/// Point correspondences of two images, `--matches FILE.csv` or `--images A B` (one of them;
/// `homography`, `twoview`). Read by [`crate::cli::matches::read_input`].
#[derive(Args, Debug, Clone)]
pub struct MatchesArg {
    /// Correspondences, CSV rows `x1,y1,x2,y2` (a pixel in the first image and its match in
    /// the second, as recorded; optional header); `-` reads stdin.
    #[arg(long, value_name = "FILE.csv", required_unless_present = "images")]
    pub matches: Option<PathBuf>,
    /// Two images (PNG, JPEG; read as grey) instead of `--matches`: ORB features of both,
    /// matched with cross-check, the matched keypoints being the correspondences.
    #[arg(
        long,
        num_args = 2,
        value_names = ["A.png", "B.png"],
        conflicts_with = "matches"
    )]
    pub images: Option<Vec<PathBuf>>,
}
