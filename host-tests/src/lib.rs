//! camgeom on the host: loaders for recorded data and calibration files, shared by the
//! integration tests, the benchmarks and the `camgeom` command-line tool.
//!
//! | module | what |
//! |---|---|
//! | [`storage`] | OpenCV `FileStorage` files (YAML via saphyr-parser, XML via roxmltree) as a tree and matrices, plain-text matrices; [`storage::YamlWriter`] writes OpenCV YAML (`calibrate`) |
//! | [`intrinsics`] | camera files (OpenCV calibration YAML/XML, camgeom JSON/TOML) to a [`intrinsics::CameraSpec`] |
//! | [`points`] | point lists as CSV, the CLI's number formatting |
//! | [`images`] | grayscale PNG/JPEG images to and from camgeom views |
//! | [`klt`] | camgeom's KLT flow and tracker on owned images (tests, benches, `flow`/`track`) |
//! | [`bench`](mod@bench) | the criterion benches' input files and the answers they leave for the peer harness |
//! | [`known_motion`] | known warps of a frame and an independent bilinear warp, for KLT accuracy |
//! | [`ar`] | the AR loop ([`camgeom::target::PlanarTarget`]) over a sequence and its overlays (`ar`) |
//! | [`rgb`] | colour overlays on `image::RgbImage`: grey in colour, inked masks, digit labels, compact PNG |
//! | [`figures`] | the figures of structure from motion (plotters): the scene from above and the side, correspondences, reprojection errors |
//! | [`contact_sheet`](mod@contact_sheet) | overlays downscaled (box filter) into a labelled grid (`ar`, `calibrate`, the main job) |
//! | [`apriltag`] | AprilTag detection on files: options, a workspace sized for each frame, the JSON form and overlay of detections (`apriltag`, `ar --tag`) |
//! | [`board`] | tag board files (JSON/YAML: an OpenCV GridBoard or a list of tags) and the board pose in the CLI's JSON (`apriltag --board`, `ar --board`) |
//! | [`cli`] | what the `camgeom` subcommands share: argument groups, correspondence input (CSV or ORB matches), frame folders, output files |
//! | [`monitor`] | a board's record stream (link frames of report records) decoded and printed a line a frame (`monitor`, the main job) |
//! | [`monitor_frames`] | the frames a board streams put back together and drawn with their record's overlay (`monitor --frames-dir`) |
//! | [`video`] | video files in and out through the system's ffmpeg: probed, decoded one frame at a time, encoded from frames |
//! | [`error`] | one error type naming the file, the line and what is wrong |
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod apriltag;
pub mod ar;
pub mod bench;
pub mod board;
pub mod cli;
pub mod contact_sheet;
pub mod error;
pub mod figures;
pub mod images;
pub mod intrinsics;
pub mod klt;
pub mod known_motion;
pub mod monitor;
pub mod monitor_frames;
pub mod points;
pub mod rgb;
pub mod storage;
pub mod video;

pub use error::{Error, ErrorKind, Result, describe, status_name};
pub use intrinsics::{CameraSpec, load_camera};
pub use storage::{FileStorage, Matrix, YamlWriter, read_matrix_text};

/// The package root (`host-tests/`), for tests and tools that read the bundled data.
pub fn package_dir() -> &'static std::path::Path {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `host-tests/data/`, the bundled recorded data (see its README for provenance).
pub fn data_dir() -> std::path::PathBuf {
    package_dir().join("data")
}
