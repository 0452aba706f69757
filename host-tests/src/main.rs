//! `camgeom`: camgeom's algorithms on files, for checking them against other tools.
//!
//! Conventions shared by every subcommand are in `host-tests/CLI.md`: point lists are CSV in and
//! out (optional header on input, a header on output), structured results are pretty-printed
//! JSON, and a usage or input error exits with status 2 and one line on stderr.
//!
//! Every subcommand returns its standard output or a [`camgeom_host::Error`]; [`exit_code`] maps
//! an error to the exit status, in one place.

use std::fmt::Debug;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use camgeom::Real;
use camgeom::camera::Camera;
use camgeom::nalgebra::{Point3, Vector3};
use camgeom::transform::Pose;
use camgeom_host::cli::args::CameraArg;
use camgeom_host::intrinsics::CameraSpec;
use camgeom_host::points::{format_csv, format_float, parse_vector, read_points3, to_json};
use camgeom_host::{Error, ErrorKind, Result, load_camera, status_name};
use clap::{Args, Parser, Subcommand};
use serde::Serialize;

mod apriltag_cmd;
mod ar_cmd;
mod calibrate_cmd;
mod homography_cmd;
mod klt_cmd;
mod monitor_cmd;
mod pose_cmd;
mod sfm_cmd;
mod twoview_cmd;
mod undistort_cmd;
mod vanishing_cmd;
mod warp_cmd;

/// Exit status of a usage or input error (as clap uses for usage errors).
const EXIT_INPUT: u8 = 2;
/// Exit status when the output cannot be written, or the data determines no result.
const EXIT_OUTPUT: u8 = 1;

#[derive(Parser, Debug)]
#[command(
    name = "camgeom",
    version,
    about = "camgeom's camera geometry on files: check the library against OpenCV and recorded data",
    after_help = "Point lists are CSV (one point per line, optional header line, `-` reads stdin); \
                  structured results are JSON. Exit status: 0 ok, 2 usage or input error, \
                  1 output error. See CLI.md."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Project 3-D points through a calibrated camera (OpenCV's projectPoints).
    ///
    /// Reads world points `X,Y,Z` (CSV), maps them through the world-to-camera pose given by
    /// OpenCV's rvec/tvec (identity by default), applies the lens distortion and K, and writes
    /// `u,v,status` per input point: status is `ok` or the camgeom error that stopped that
    /// point (`behind_camera`, `non_finite`, ...), with u and v `nan` in CSV (`null` in JSON).
    Project(ProjectArgs),
    /// Read a camera file in any supported format and print it in camgeom's JSON (or TOML) form.
    Camera(CameraArgs),
    /// Plane homography of point correspondences (OpenCV's findHomography with RANSAC).
    ///
    /// Reads rows `x1,y1,x2,y2` (CSV), or matches ORB features of two images (`--images A B`),
    /// and prints JSON `{"H": [h11, h12, h13, h21, .., h33], "inliers": N, "inlier_mask": [..],
    /// "method": .., "iterations": ..}` (H row-major, 9 numbers) with `x2 ~ H x1`, `h33 = 1`.
    /// Exactly 4 rows: the exact 4-point solver (getPerspectiveTransform); more: RANSAC.
    Homography(homography_cmd::HomographyArgs),
    /// Paste a logo into a frame inside a quadrilateral (OpenCV's warpPerspective).
    ///
    /// Inverse mapping with bilinear interpolation, clipped to the frame. Reads the logo and the
    /// frame (PNG/JPEG, converted to grey) and 4 corner rows `x,y` (CSV); writes the frame to
    /// --out and prints JSON `{"H": .., "written": N, "arithmetic": ..}`.
    Warp(warp_cmd::WarpArgs),
    /// Track points from one frame to the next (pyramidal Lucas-Kanade, OpenCV's
    /// calcOpticalFlowPyrLK).
    ///
    /// Reads rows `x,y` (CSV) and writes `x,y,status` per input point: status `ok`, or
    /// `out_of_bounds`, `small_eigenvalue`, `inconsistent` (with `--fb`), and x, y `nan`.
    Flow(klt_cmd::FlowArgs),
    /// Track features through a folder of frames or a video (Shi-Tomasi detection, KLT,
    /// replenishment).
    ///
    /// Writes rows `frame,id,x,y` to --out (optionally overlay PNGs) and prints a JSON summary.
    Track(klt_cmd::TrackArgs),
    /// Camera pose from 3D-2D correspondences (OpenCV's solvePnP / solvePnPRansac).
    ///
    /// Reads rows `X,Y,Z,u,v` (CSV). All Z = 0: the planar solver (IPPE, both solutions,
    /// refined); otherwise EPnP refined by Levenberg-Marquardt; `--ransac PX`: P3P RANSAC.
    /// Prints JSON `{"R": [9, row-major], "t": [3], "rms_px": e, "alternative": {..} or null}`.
    Pose(pose_cmd::PoseArgs),
    /// Track a planar target through a folder of frames and draw a cube standing on it.
    ///
    /// The target is given by its corners in the first frame (--corners, --size) or is an
    /// AprilTag the detector finds and finds again (--tag, --family, --tag-size). Writes
    /// overlay PNGs, `poses.csv` and `contact_sheet.png` to --out and prints a JSON summary.
    Ar(ar_cmd::ArArgs),
    /// Detect AprilTags in an image or a folder of frames (AprilTag 3's detector), with each
    /// tag's pose given its size and the camera.
    ///
    /// Prints JSON `{"detections": [{"id", "family", "hamming", "margin", "corners": [[x, y] x
    /// 4], "H": [9], ..}], "width", "height"}` (with --frames, an array of these, one per
    /// frame); with --intrinsics and --tag-size each detection also has "R", "t", "rms_px"
    /// and "alternative". Corners in AprilTag's order, camgeom's pixel coordinates (pixel
    /// centres at integers) unless --apriltag-coords.
    Apriltag(apriltag_cmd::ApriltagArgs),
    /// Epipolar geometry and relative pose of two calibrated views (OpenCV's
    /// findFundamentalMat, findEssentialMat, recoverPose, triangulatePoints).
    ///
    /// Reads rows `x1,y1,x2,y2` (CSV, pixels as recorded: the lens distortion of the camera
    /// files is removed; or `--images A B`: ORB + cross-check) and the camera of each view;
    /// prints JSON `{"F": [9], "E": [9], "R": [9], "t": [3], "inliers": N,
    /// "points": [[X, Y, Z], ..], ..}` with `X₂ = R X₁ + t`, `|t| = 1`, points in view 1's
    /// frame in baselines.
    Twoview(twoview_cmd::TwoviewArgs),
    /// Structure from motion over two or more views: SIFT (default) or ORB matches verified
    /// pair by pair, tracks, the best initial pair's relative pose, triangulation, PnP of each
    /// further view and bundle adjustment; views the data do not determine are refused with a
    /// reason, and no reconstruction at all exits 1.
    ///
    /// Writes DIR/points.ply (points, then the camera centres) and DIR/plot.png (top-down and
    /// side views) and prints a JSON summary.
    Sfm(sfm_cmd::SfmArgs),
    /// Calibrate a camera from images of a chessboard (OpenCV's findChessboardCorners +
    /// calibrateCamera, or fisheye::calibrate with --fisheye).
    ///
    /// Writes the camera to --out as OpenCV FileStorage YAML (as OpenCV's calibration sample
    /// does), a contact sheet of the detected corners and a bar chart of the per-view
    /// reprojection errors (PNG, next to --out or in --pictures), and prints a JSON summary
    /// `{"views_used", "views_rejected", "rms_px", "K", "distortion", "std", "per_view_rms",
    /// "warnings", ..}`. Progress bar on stderr.
    Calibrate(calibrate_cmd::CalibrateArgs),
    /// Remove the lens distortion from an image (OpenCV's getOptimalNewCameraMatrix,
    /// initUndistortRectifyMap and remap; fisheye cameras: estimateNewCameraMatrixForUndistortRectify).
    ///
    /// Writes the image to --out and prints JSON `{"new_camera_matrix": [9], ..}`.
    Undistort(undistort_cmd::UndistortArgs),
    /// Vanishing points of line segments and the horizon (sequential RANSAC over segment
    /// pairs, least squares per point; the horizon from two horizontal points, or from the
    /// vertical one and the camera).
    ///
    /// Reads rows `x1,y1,x2,y2[,group]` (CSV) and prints JSON `{"segments": N,
    /// "vanishing_points": [{"x", "y", "ideal", "direction_deg", "segments", "rms_px",
    /// "vertical", ..}], "horizon": {"line", "from", "roll_deg"} or null, "horizon_reason"}`;
    /// with --intrinsics each point's direction in the camera frame and the angles between
    /// them. --overlay draws the segments coloured by point and the horizon.
    Vanishing(vanishing_cmd::VanishingArgs),
    /// Read a board's record stream: a saved stream file (--replay), a board's socket (--tcp)
    /// or serial port (--serial), one line a frame (state, counts, pose, cost), then the
    /// link's counts; send it commands first (--set, --mode, --save).
    ///
    /// The stream is camgeom's framing (COBS, sequence number, CRC-32) of the board's binary
    /// records; damaged frames are counted and skipped. --json prints one JSON object a line.
    /// The board's answers to commands are printed as they come; a command it refused or did
    /// not answer makes the exit status 1.
    Monitor(monitor_cmd::MonitorArgs),
}

/// A world-to-camera pose as OpenCV gives it (solvePnP, calibrateCamera).
#[derive(Args, Debug)]
struct PoseOpt {
    /// Rotation vector (axis * angle in radians), world to camera. Default 0,0,0.
    #[arg(long, value_name = "RX,RY,RZ", allow_hyphen_values = true, value_parser = parse_vector::<3>)]
    rvec: Option<[f64; 3]>,
    /// Translation, world to camera, in the units of the points. Default 0,0,0.
    #[arg(long, value_name = "TX,TY,TZ", allow_hyphen_values = true, value_parser = parse_vector::<3>)]
    tvec: Option<[f64; 3]>,
}

/// Output options shared by the subcommands that return a point list.
#[derive(Args, Debug)]
struct OutputOpt {
    /// Print JSON (`{"points": [{"u": .., "v": .., "status": "ok"}, ...]}`) instead of CSV.
    #[arg(long)]
    json: bool,
    /// Compute in f32, as the firmware does (default f64). Numbers are printed with the
    /// shortest text that reads back to the same f32.
    #[arg(long)]
    f32: bool,
}

#[derive(Args, Debug)]
struct ProjectArgs {
    #[command(flatten)]
    camera: CameraArg,
    /// World points, CSV rows `X,Y,Z` (optional header); `-` reads stdin.
    #[arg(long, value_name = "FILE.csv")]
    points: PathBuf,
    #[command(flatten)]
    pose: PoseOpt,
    #[command(flatten)]
    output: OutputOpt,
}

#[derive(Args, Debug)]
struct CameraArgs {
    #[command(flatten)]
    camera: CameraArg,
    /// Print TOML instead of JSON.
    #[arg(long)]
    toml: bool,
}

/// The exit status of an error: [`EXIT_OUTPUT`] when an output could not be written or the
/// data determines no result (structure from motion with fewer than two views registered),
/// [`EXIT_INPUT`] for everything else (usage errors, unreadable or malformed input, inputs camgeom
/// rejects).
fn exit_code(e: &Error) -> u8 {
    match e.kind() {
        ErrorKind::Write(_) | ErrorKind::Undetermined(_) => EXIT_OUTPUT,
        _ => EXIT_INPUT,
    }
}

fn main() -> ExitCode {
    let result = match parse_args() {
        // `--help` or `--version`, printed.
        Ok(None) => return ExitCode::SUCCESS,
        Ok(Some(cli)) => run(&cli.command).and_then(|out| write_stdout(&out)),
        Err(e) => Err(e),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("camgeom: error: {e}");
            ExitCode::from(exit_code(&e))
        }
    }
}

/// The command line, or `None` once `--help` or `--version` is printed (to stdout). A usage
/// error becomes one line (clap would print several).
fn parse_args() -> Result<Option<Cli>> {
    let e = match Cli::try_parse() {
        Ok(cli) => return Ok(Some(cli)),
        Err(e) => e,
    };
    use clap::error::ErrorKind as K;
    if matches!(e.kind(), K::DisplayHelp | K::DisplayVersion) {
        let _ = e.print();
        return Ok(None);
    }
    let message = if e.kind() == K::DisplayHelpOnMissingArgumentOrSubcommand {
        // Bare `camgeom`: clap would print the whole help; keep to one line.
        let names: Vec<String> = <Cli as clap::CommandFactory>::command()
            .get_subcommands()
            .map(|c| c.get_name().to_string())
            .filter(|n| n != "help")
            .collect();
        format!("a subcommand is required: {}", names.join(", "))
    } else {
        // clap's message is the paragraph before `Usage:`; join it into one line.
        let text = e.to_string();
        let para: Vec<&str> = text
            .lines()
            .map(str::trim)
            .skip_while(|l| l.is_empty())
            .take_while(|l| !l.is_empty())
            .collect();
        let joined = para.join(" ");
        joined
            .strip_prefix("error: ")
            .unwrap_or(&joined)
            .to_string()
    };
    Err(Error::usage(format!("{message} (see `camgeom --help`)")))
}

/// Runs a subcommand: its standard output, or the error that stopped it.
fn run(command: &Command) -> Result<String> {
    match command {
        Command::Project(a) => project(a),
        Command::Camera(a) => camera(a),
        Command::Homography(a) => homography_cmd::run(a),
        Command::Warp(a) => warp_cmd::run(a),
        Command::Flow(a) => klt_cmd::run_flow(a),
        Command::Track(a) => klt_cmd::run_track(a),
        Command::Pose(a) => pose_cmd::run(a),
        Command::Ar(a) => ar_cmd::run(a),
        Command::Apriltag(a) => apriltag_cmd::run(a),
        Command::Twoview(a) => twoview_cmd::run(a),
        Command::Sfm(a) => sfm_cmd::run(a),
        Command::Calibrate(a) => calibrate_cmd::run(a),
        Command::Undistort(a) => undistort_cmd::run(a),
        Command::Vanishing(a) => vanishing_cmd::run(a),
        Command::Monitor(a) => monitor_cmd::run(a),
    }
}

fn write_stdout(s: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(s.as_bytes()).and_then(|_| out.flush()) {
        Ok(()) => Ok(()),
        // A closed pipe (`camgeom ... | head`) is not an error of ours.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(Error::new("standard output", ErrorKind::Write(e))),
    }
}

fn project(a: &ProjectArgs) -> Result<String> {
    let spec = load_camera(&a.camera.intrinsics)?;
    let points = read_points3(&a.points)?;
    let rvec = a.pose.rvec.unwrap_or([0.0; 3]);
    let tvec = a.pose.tvec.unwrap_or([0.0; 3]);
    if a.output.f32 {
        project_as(spec.camera_f32(), rvec, tvec, &points, a.output.json)
    } else {
        project_as(spec.camera, rvec, tvec, &points, a.output.json)
    }
}

/// One projected point of the JSON output.
#[derive(Serialize)]
struct ProjectedPoint<T> {
    u: Option<T>,
    v: Option<T>,
    status: String,
}

#[derive(Serialize)]
struct Projected<T> {
    points: Vec<ProjectedPoint<T>>,
}

fn project_as<T: Real + Serialize + Debug>(
    camera: Camera<T>,
    rvec: [f64; 3],
    tvec: [f64; 3],
    points: &[Point3<f64>],
    json: bool,
) -> Result<String> {
    let v3 = |a: [f64; 3]| Vector3::new(T::lit(a[0]), T::lit(a[1]), T::lit(a[2]));
    let pose = Pose::<T>::from_rodrigues(v3(rvec), v3(tvec))
        .map_err(|e| Error::camgeom("invalid pose (--rvec, --tvec)", e))?;
    let projected: Vec<ProjectedPoint<T>> = points
        .iter()
        .map(|p| {
            let x = Point3::new(T::lit(p.x), T::lit(p.y), T::lit(p.z));
            match camera.project(&pose, &x) {
                Ok(u) => ProjectedPoint {
                    u: Some(u.x),
                    v: Some(u.y),
                    status: "ok".to_string(),
                },
                Err(e) => ProjectedPoint {
                    u: None,
                    v: None,
                    status: status_name(&e),
                },
            }
        })
        .collect();
    if json {
        return Ok(to_json(&Projected { points: projected }));
    }
    let f = |v: Option<T>| v.map_or_else(|| "nan".to_string(), format_float);
    let rows = projected.iter().map(|p| [f(p.u), f(p.v), p.status.clone()]);
    Ok(format_csv(&["u", "v", "status"], rows))
}

fn camera(a: &CameraArgs) -> Result<String> {
    let spec: CameraSpec = load_camera(&a.camera.intrinsics)?;
    Ok(if a.toml {
        spec.to_toml()
    } else {
        spec.to_json()
    })
}
