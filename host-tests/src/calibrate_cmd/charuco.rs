//! `camgeom calibrate --board charuco:COLSxROWS:SQUARE:MARKER:DICT`: calibration from ChArUco
//! views, the board seen whole or in part (OpenCV's `CharucoDetector::detectBoard` +
//! `calibrateCamera` / `fisheye::calibrate` on the identified corners).

use super::*;
use camgeom::apriltag::{Detector, DetectorConfig, families};
use camgeom::charuco::{CharucoBoard, CharucoCorner, CharucoParams, interpolate_corners};
use camgeom_host::apriltag::HostWorkspace;

/// Markers kept per image.
const MAX_MARKERS: usize = 256;

/// `COLSxROWS:SQUARE:MARKER:DICT` (squares, as OpenCV's `CharucoBoard` size).
pub fn parse_spec(spec: &str) -> Result<CharucoBoard> {
    let bad = |why: &str| {
        Error::usage(format!(
            "--board charuco:{spec}: expected charuco:COLSxROWS:SQUARE:MARKER:DICT (squares, as \
             OpenCV's CharucoBoard: for example charuco:11x8:30:22:DICT_4X4_50){why}"
        ))
    };
    let f: Vec<&str> = spec.split(':').collect();
    let [size, square, marker, dict] = f.as_slice() else {
        return Err(bad(""));
    };
    let (c, r) = size.split_once(['x', 'X']).ok_or_else(|| bad(""))?;
    let cols: usize = c.trim().parse().map_err(|_| bad(""))?;
    let rows: usize = r.trim().parse().map_err(|_| bad(""))?;
    let square: f32 = square.trim().parse().map_err(|_| bad(""))?;
    let marker: f32 = marker.trim().parse().map_err(|_| bad(""))?;
    let family = families::by_name(dict.trim())
        .filter(|f| f.is_aruco())
        .ok_or_else(|| {
            bad(&format!(
                "; `{dict}` is not an OpenCV ArUco dictionary (DICT_*)"
            ))
        })?;
    let board = CharucoBoard::new(cols, rows, square, marker, family).map_err(|e| {
        bad(&format!(
            "; {}",
            match e {
                camgeom::Error::InvalidParameter("squares") =>
                    "each side must have 2 to 128 squares".to_string(),
                camgeom::Error::InvalidParameter("dictionary") => format!(
                    "the dictionary has fewer markers than the board's {}",
                    cols * rows / 2
                ),
                _ => "the square and the marker must be positive, the marker smaller".to_string(),
            }
        ))
    })?;
    if board.corners() > MAX_CORNERS {
        return Err(bad(&format!(
            "; {} corners, at most {MAX_CORNERS}",
            board.corners()
        )));
    }
    Ok(board)
}

/// Views with fewer corners than this are not used (a plane's homography needs 4; OpenCV's
/// sample needs more than 3).
const MIN_CORNERS: usize = 6;

/// The run of `camgeom calibrate` for a ChArUco board.
pub fn run(a: &CalibrateArgs, spec: &str) -> Result<String> {
    let board = parse_spec(spec)?;
    calibration_config(a)?;
    check_args(a)?;
    let det = Detector::new(DetectorConfig::default(), &[board.dictionary()])
        .map_err(|e| Error::camgeom("detector configuration", e))?;
    let params = CharucoParams::default();
    let mut ws: Box<HostWorkspace> = Box::default();
    let (views, skipped, size) = identified::load_views(a, |p, view| {
        let markers = ws
            .detect::<MAX_MARKERS>(&det, view)
            .map_err(|e| Error::camgeom(format!("{}: marker detection failed", p.display()), e))?;
        let mut out = vec![CharucoCorner::default(); board.corners()];
        let n = interpolate_corners(&board, view, &markers, &params, &mut out)
            .map_err(|e| Error::camgeom(format!("{}: ChArUco corners", p.display()), e))?;
        Ok(out.iter().take(n).map(|c| (c.id, c.point)).collect())
    })?;
    let points: Vec<Point2<f64>> = (0..board.corners())
        .filter_map(|k| board.corner(k))
        .map(|p| Point2::new(f64::from(p.x), f64::from(p.y)))
        .collect();
    let inner = BoardSize::new(board.squares_x() - 1, board.squares_y() - 1)
        .or_else(|_| BoardSize::new(3, 3))
        .map_err(|e| Error::camgeom("board size", e))?;
    let id_board = identified::IdBoard {
        name: "ChArUco",
        points,
        scale: f64::from(board.square()),
        size: inner,
        min_corners: MIN_CORNERS,
    };
    identified::calibrate(a, &id_board, views, skipped, size)
}
