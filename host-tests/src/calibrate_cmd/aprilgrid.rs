//! `camgeom calibrate --board aprilgrid:COLSxROWS:SIZE:SPACING`: calibration from Kalibr
//! AprilGrid views, the board seen whole or in part (Kalibr's `GridCalibrationTargetAprilgrid`
//! observations: tag corners refined as saddle points at its corner squares, as Kalibr's
//! `cornerSubPix`; calibrated as OpenCV's `calibrateCamera` / `fisheye::calibrate` on them).

use super::*;
use camgeom::aprilgrid::{AprilGrid, GridCorner, MAX_TAGS};
use camgeom::apriltag::{Detection, Detector};
use camgeom::chessboard::SaddleConfig;
use camgeom_host::apriltag::HostWorkspace;

/// Views with fewer corners than this are not used: the 4 corners of 2 tags (one tag's 4 give
/// a homography and nothing to check it).
const MIN_CORNERS: usize = 8;

/// `COLSxROWS:SIZE:SPACING` (Kalibr's `tagCols`, `tagRows`, `tagSize`, `tagSpacing`).
pub fn parse_spec(spec: &str) -> Result<AprilGrid> {
    let bad = |why: &str| {
        Error::usage(format!(
            "--board aprilgrid:{spec}: expected aprilgrid:COLSxROWS:SIZE:SPACING (tags, Kalibr's \
             tagCols x tagRows, tagSize, tagSpacing as a ratio of the tag: for example \
             aprilgrid:6x6:0.088:0.3){why}"
        ))
    };
    let f: Vec<&str> = spec.split(':').collect();
    let [size, tag, spacing] = f.as_slice() else {
        return Err(bad(""));
    };
    let (c, r) = size.split_once(['x', 'X']).ok_or_else(|| bad(""))?;
    let cols: usize = c.trim().parse().map_err(|_| bad(""))?;
    let rows: usize = r.trim().parse().map_err(|_| bad(""))?;
    let tag: f32 = tag.trim().parse().map_err(|_| bad(""))?;
    let spacing: f32 = spacing.trim().parse().map_err(|_| bad(""))?;
    let grid = AprilGrid::new(cols, rows, tag, spacing).map_err(|e| {
        bad(&match e {
            camgeom::Error::InvalidParameter("tags") => {
                format!("; 1 to {MAX_TAGS} tags (tag36h11's ids)")
            }
            camgeom::Error::InvalidParameter("spacing") => {
                "; the spacing is a ratio of the tag side, in (0, 1]".to_string()
            }
            _ => "; the tag size must be positive".to_string(),
        })
    })?;
    if grid.points() > MAX_CORNERS {
        return Err(bad(&format!(
            "; {} tag corners, at most {MAX_CORNERS}",
            grid.points()
        )));
    }
    Ok(grid)
}

/// The run of `camgeom calibrate` for an AprilGrid.
pub fn run(a: &CalibrateArgs, spec: &str) -> Result<String> {
    let grid = parse_spec(spec)?;
    calibration_config(a)?;
    check_args(a)?;
    let det = Detector::new(AprilGrid::detector_config(), &[grid.family()])
        .map_err(|e| Error::camgeom("detector configuration", e))?;
    let mut ws: Box<HostWorkspace> = Box::default();
    let mut tags: camgeom::heapless::Vec<Detection, MAX_TAGS> = camgeom::heapless::Vec::new();
    let mut out = vec![GridCorner::default(); grid.points()];
    // Kalibr's refinement of the tag corners at its corner squares.
    let saddle = SaddleConfig::default()
        .check()
        .map_err(|e| Error::camgeom("saddle refinement", e))?;
    let (views, skipped, size) = identified::load_views(a, |p, view| {
        let n = ws
            .run(view, det.config().decimate, |w| {
                grid.detect_corners(&det, view, w, &mut tags, Some(&saddle), &mut out)
            })
            .map_err(|e| {
                Error::camgeom(format!("{}: AprilGrid detection failed", p.display()), e)
            })?;
        Ok(out.iter().take(n).map(|c| (c.id, c.point)).collect())
    })?;
    let points: Vec<Point2<f64>> = (0..grid.points())
        .filter_map(|k| grid.point(k))
        .map(|p| Point2::new(f64::from(p.x), f64::from(p.y)))
        .collect();
    // The camera file's board size: the grid's points a side (2 a tag).
    let size_pts = BoardSize::new(2 * grid.cols(), 2 * grid.rows())
        .or_else(|_| BoardSize::new(3, 3))
        .map_err(|e| Error::camgeom("board size", e))?;
    let board = identified::IdBoard {
        name: "AprilGrid",
        points,
        scale: f64::from(grid.size()),
        size: size_pts,
        min_corners: MIN_CORNERS,
    };
    identified::calibrate(a, &board, views, skipped, size)
}
