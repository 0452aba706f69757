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

/// One image's identified corners.
struct CharucoView {
    path: PathBuf,
    image: GrayImage,
    corners: Vec<CharucoCorner>,
}

/// Views with fewer corners than this are not used (a plane's homography needs 4; OpenCV's
/// sample needs more than 3).
const MIN_CORNERS: usize = 6;

/// The run of `camgeom calibrate` for a ChArUco board.
pub fn run(a: &CalibrateArgs, spec: &str) -> Result<String> {
    let board = parse_spec(spec)?;
    let cfg = calibration_config(a)?;
    let ext = a
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if !matches!(ext.as_deref(), Some("yml" | "yaml")) {
        return Err(Error::usage(format!(
            "--out {}: the camera file is OpenCV YAML, name it .yml or .yaml",
            a.out.display()
        )));
    }
    if a.images.len() > MAX_VIEWS {
        return Err(Error::usage(format!(
            "--images: at most {MAX_VIEWS} images, got {}",
            a.images.len()
        )));
    }
    let det = Detector::new(DetectorConfig::default(), &[board.dictionary()])
        .map_err(|e| Error::camgeom("detector configuration", e))?;
    let params = CharucoParams::default();
    let mut ws: Box<HostWorkspace> = Box::default();
    let mut views = Vec::new();
    let mut skipped = Vec::new();
    let mut size = None;
    for p in &a.images {
        let image = load_gray(p)?;
        let s = (image.width, image.height);
        if *size.get_or_insert(s) != s {
            eprintln!(
                "camgeom: warning: {}: {}x{} differs from the first image's size, skipped",
                p.display(),
                s.0,
                s.1
            );
            skipped.push(file_name(p));
            continue;
        }
        let view = image
            .view()
            .ok_or_else(|| Error::usage(format!("{}: empty image", p.display())))?;
        let markers = ws
            .detect::<MAX_MARKERS>(&det, &view)
            .map_err(|e| Error::camgeom(format!("{}: marker detection failed", p.display()), e))?;
        let mut out = vec![CharucoCorner::default(); board.corners()];
        let n = interpolate_corners(&board, &view, &markers, &params, &mut out)
            .map_err(|e| Error::camgeom(format!("{}: ChArUco corners", p.display()), e))?;
        out.truncate(n);
        views.push(CharucoView {
            path: p.clone(),
            image,
            corners: out,
        });
    }
    let (width, height) = size.unwrap_or((1, 1));
    let found: Vec<&CharucoView> = views
        .iter()
        .filter(|v| v.corners.len() >= MIN_CORNERS)
        .collect();
    let missed: Vec<String> = views
        .iter()
        .filter(|v| v.corners.len() < MIN_CORNERS)
        .map(|v| file_name(&v.path))
        .collect();
    for v in &views {
        if v.corners.len() < MIN_CORNERS {
            eprintln!(
                "camgeom: note: {}: {} ChArUco corners (fewer than {MIN_CORNERS}), view not used",
                v.path.display(),
                v.corners.len()
            );
        }
    }
    if found.len() < 3 {
        return Err(Error::usage(format!(
            "the ChArUco board gave at least {MIN_CORNERS} corners in {} of {} images; \
             calibration needs at least 3 views (too few in: {})",
            found.len(),
            views.len(),
            name_list(&missed)
        )));
    }
    let points: Vec<Point2<f64>> = (0..board.corners())
        .filter_map(|k| board.corner(k))
        .map(|p| Point2::new(f64::from(p.x), f64::from(p.y)))
        .collect();
    let square = f64::from(board.square());
    let mut cal = Box::new(
        Calibrator::<f64, MAX_VIEWS, MAX_CORNERS>::with_points(&points, square, width, height)
            .map_err(|e| Error::camgeom("calibration setup", e))?,
    );
    for v in &found {
        let ids: Vec<usize> = v.corners.iter().map(|c| usize::from(c.id)).collect();
        let px: Vec<Point2<f64>> = v
            .corners
            .iter()
            .map(|c| Point2::new(f64::from(c.point.x), f64::from(c.point.y)))
            .collect();
        cal.add_points(width, height, &ids, &px)
            .map_err(|e| Error::camgeom(format!("{}: view rejected", v.path.display()), e))?;
    }
    let report = cfg.check().and_then(|p| cal.solve(&p)).map_err(|e| {
        let why = match e {
            camgeom::Error::Degenerate => {
                "the views do not determine the camera (all parallel to each other: tilt the \
                 board between views)"
            }
            camgeom::Error::TooFewPoints => "fewer than 3 views are usable",
            _ => "calibration failed",
        };
        Error::camgeom(
            format!("calibration of {} views failed: {why}", found.len()),
            e,
        )
    })?;

    let mut rejected = missed.clone();
    let mut used: Vec<&CharucoView> = Vec::new();
    let mut per_view = Vec::new();
    let mut poses = Vec::new();
    let mut corners_csv = String::from("view,X,Y,Z,u,v\n");
    for (k, v) in found.iter().enumerate() {
        let (Some(Some(pose)), Some(Some(rms))) =
            (report.poses.get(k), report.per_view_rms_px.get(k))
        else {
            let why = report
                .rejections
                .get(k)
                .copied()
                .flatten()
                .map_or("rejected", |r| r.name());
            eprintln!("camgeom: note: {}: view not used ({why})", v.path.display());
            rejected.push(file_name(&v.path));
            continue;
        };
        used.push(v);
        per_view.push(*rms);
        let index = views.iter().position(|w| std::ptr::eq(w, *v)).unwrap_or(k);
        let (r, t) = (pose.rotation_vector(), pose.translation());
        poses.push(ViewPose {
            image: file_name(&v.path),
            view: index,
            rvec: [r.x, r.y, r.z],
            tvec: [t.x, t.y, t.z],
            rms_px: *rms,
        });
        for c in &v.corners {
            if let Some(b) = board.corner(usize::from(c.id)) {
                let _ = writeln!(
                    corners_csv,
                    "{index},{},{},0,{},{}",
                    b.x, b.y, c.point.x, c.point.y
                );
            }
        }
    }

    let inner = BoardSize::new(board.squares_x() - 1, board.squares_y() - 1)
        .or_else(|_| BoardSize::new(3, 3))
        .map_err(|e| Error::camgeom("board size", e))?;
    let yaml = camera_yaml(&report, &cfg, inner, square, width, height, &per_view);
    let tiles: Vec<(usize, RgbImage)> = views
        .iter()
        .enumerate()
        .map(|(i, v)| (i + 1, draw_ids(v)))
        .collect();
    let sheet = contact_sheet(&tiles, 4, width.div_ceil(320).max(1));
    let labels = used_labels(&views, &used);
    let images_used = used.iter().map(|v| file_name(&v.path)).collect();
    write_outputs(
        a,
        Solved {
            report,
            yaml,
            sheet,
            labels,
            images_used,
            per_view,
            poses,
            rejected,
            skipped,
            corners_csv,
            width,
            height,
        },
    )
}

/// The image with a circle at each identified corner (red border when too few).
fn draw_ids(v: &CharucoView) -> RgbImage {
    let img = &v.image;
    let mut out = RgbImage::from_gray(img);
    let ok = v.corners.len() >= MIN_CORNERS;
    let radius = (img.width as f32 / 160.0).max(3.0);
    let mut mask = GrayImage::filled(img.width, img.height, 0);
    if let Some(mut m) = mask.view_mut() {
        for c in &v.corners {
            let p = c.point;
            for s in 0..12 {
                let a0 = s as f32 * core::f32::consts::TAU / 12.0;
                let a1 = (s + 1) as f32 * core::f32::consts::TAU / 12.0;
                let q0 = Point2::new(p.x + radius * a0.cos(), p.y + radius * a0.sin());
                let q1 = Point2::new(p.x + radius * a1.cos(), p.y + radius * a1.sin());
                let _ = draw_line(&mut m, &q0, &q1, 255);
            }
        }
    }
    out.ink(&mask, if ok { [40, 200, 40] } else { [255, 40, 40] });
    out
}
