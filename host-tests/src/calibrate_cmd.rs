//! `camgeom calibrate`: calibrate a camera from chessboard images (OpenCV's
//! `findChessboardCorners` + `calibrateCamera` / `fisheye::calibrate`, and its calibration
//! sample's output file).
//!
//! Everything is checked and computed before anything is written: a usage or input error
//! (no board anywhere, too few views, degenerate views, a bad `--board` or `--square`) exits 2
//! with one line and leaves no file behind. Images of another size than most (another camera
//! mode) are skipped with a warning, as OpenCV's users skip them.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use camgeom::calib::{
    CalibrationConfig, CalibrationFlags, CalibrationReport, CalibrationWarning, Calibrator,
};
use camgeom::camera::{Lens, LensModel};
use camgeom::chessboard::{
    BoardSize, Chessboard, ChessboardDetector, DetectParams, Seen, pyramid_len, scratch_len,
};
use camgeom::draw::draw_line;
use camgeom::nalgebra::Point2;
use camgeom_host::cli::files::{create_dir, write_file};
use camgeom_host::cli::frames::progress_bar;
use camgeom_host::contact_sheet::contact_sheet;
use camgeom_host::images::{GrayImage, load_gray};
use camgeom_host::points::to_json;
use camgeom_host::rgb::{Overlay, RgbImage};
use camgeom_host::{Error, ErrorKind, Result, YamlWriter};
use clap::Args;
use serde::Serialize;

mod aprilgrid;
mod charuco;
mod identified;

/// Views a calibration holds at most.
pub const MAX_VIEWS: usize = 64;
/// Inner corners a board has at most (the detector's and the calibrator's capacity).
pub const MAX_CORNERS: usize = 256;
/// Corner candidates the detector keeps per image (4x the largest board, for clutter).
const CANDIDATES: usize = 1024;

#[derive(Args, Debug)]
pub struct CalibrateArgs {
    /// Images of the board (PNG/JPEG, all the same size; colour is converted to grey).
    #[arg(long, value_name = "FILES", num_args = 1.., required = true)]
    images: Vec<PathBuf>,
    /// Inner corners of the board, `COLSxROWS` (OpenCV's pattern size: 9x6 for the usual
    /// 10x7-square board); or a ChArUco board, `charuco:COLSxROWS:SQUARE:MARKER:DICT` with
    /// COLSxROWS its squares (OpenCV's `CharucoBoard` size, e.g. `charuco:11x8:30:22:DICT_4X4_50`),
    /// or a Kalibr AprilGrid, `aprilgrid:COLSxROWS:SIZE:SPACING` (tags, tag side, gap over
    /// the tag side: e.g. `aprilgrid:6x6:0.088:0.3`); both may be seen in part (then --square
    /// is not used).
    #[arg(long, value_name = "COLSxROWS", allow_hyphen_values = true)]
    board: String,
    /// Side of a square, in the unit the poses should use (for example 25 for millimetres);
    /// required with a chessboard `--board COLSxROWS`.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    square: Option<f64>,
    /// Output camera file, OpenCV FileStorage YAML (`.yml` or `.yaml`).
    #[arg(long, value_name = "camera.yml")]
    out: PathBuf,
    /// Folder for the two pictures (default: --out's folder).
    #[arg(long, value_name = "DIR")]
    pictures: Option<PathBuf>,
    /// Fisheye lens (Kannala-Brandt, OpenCV's `fisheye::calibrate`: 4 coefficients).
    #[arg(long)]
    fisheye: bool,
    /// Keep `fx / fy` fixed at RATIO (default 1; `CALIB_FIX_ASPECT_RATIO`).
    #[arg(long, value_name = "RATIO", num_args = 0..=1, default_missing_value = "1",
          allow_negative_numbers = true)]
    fix_aspect: Option<f64>,
    /// Principal point at the image centre (`CALIB_FIX_PRINCIPAL_POINT`).
    #[arg(long)]
    fix_principal_point: bool,
    /// No tangential distortion, `p1 = p2 = 0` (`CALIB_ZERO_TANGENT_DIST`; not with --fisheye).
    #[arg(long)]
    zero_tangent: bool,
    /// `k3 = 0` (`CALIB_FIX_K3`, or `fisheye::CALIB_FIX_K3`).
    #[arg(long)]
    fix_k3: bool,
    /// Fisheye only: `k4 = 0` (`fisheye::CALIB_FIX_K4`).
    #[arg(long)]
    fix_k4: bool,
    /// Also write every used view's detected corners, CSV rows `view,X,Y,Z,u,v` (`view`: the
    /// image's index in `--images`, from 0; `X,Y,Z`: the corner on the board, `(i, j, 0)`
    /// squares in `--square`'s unit; `u,v`: its pixel), which `camgeom pose --view` reads.
    #[arg(long, value_name = "FILE.csv")]
    corners_out: Option<PathBuf>,
}

/// One used view's pose (board to camera, `X_cam = R X_board + t`) and error.
#[derive(Serialize, Debug)]
struct ViewPose {
    image: String,
    /// Index in `--images`.
    view: usize,
    rvec: [f64; 3],
    tvec: [f64; 3],
    rms_px: f64,
}

/// `COLSxROWS`, within the detector's capacity.
pub fn parse_board(s: &str) -> Result<BoardSize> {
    let bad = || {
        Error::usage(format!(
            "--board: expected COLSxROWS inner corners (for example 9x6), got `{s}`"
        ))
    };
    let (c, r) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let cols: usize = c.trim().parse().map_err(|_| bad())?;
    let rows: usize = r.trim().parse().map_err(|_| bad())?;
    if cols.saturating_mul(rows) > MAX_CORNERS {
        return Err(Error::usage(format!(
            "--board {s} has {} inner corners; the detector holds at most {MAX_CORNERS}",
            cols.saturating_mul(rows)
        )));
    }
    BoardSize::new(cols, rows).map_err(|_| {
        Error::usage(format!(
            "--board {s}: each side must have 3 to 64 inner corners"
        ))
    })
}

/// The calibration options of the flags, checked against the lens model.
fn calibration_config(a: &CalibrateArgs) -> Result<CalibrationConfig> {
    if let Some(r) = a.fix_aspect
        && !(r.is_finite() && r > 0.0)
    {
        return Err(Error::usage(format!(
            "--fix-aspect must be a positive ratio fx/fy, got {r}"
        )));
    }
    if a.fisheye && a.zero_tangent {
        return Err(Error::usage(
            "--zero-tangent does not apply to --fisheye (the fisheye model has no tangential terms)",
        ));
    }
    if a.fisheye && a.fix_aspect.is_some() {
        return Err(Error::usage(
            "--fix-aspect does not apply to --fisheye (OpenCV's fisheye calibration has no such flag)",
        ));
    }
    if !a.fisheye && a.fix_k4 {
        return Err(Error::usage("--fix-k4 applies to --fisheye only"));
    }
    Ok(CalibrationConfig {
        model: if a.fisheye {
            LensModel::KannalaBrandt
        } else {
            LensModel::BrownConrady
        },
        flags: CalibrationFlags {
            fix_aspect_ratio: a.fix_aspect,
            fix_principal_point: a.fix_principal_point,
            zero_tangent: a.zero_tangent,
            fix_k3: a.fix_k3,
            fix_k4: a.fix_k4,
        },
        ..CalibrationConfig::default()
    })
}

/// OpenCV's flag word for the options, as its calibration sample writes it (`calibrateCamera`
/// values, or `fisheye::calibrate`'s with `RECOMPUTE_EXTRINSIC | FIX_SKEW`, which camgeom's
/// fisheye calibration always uses), and the sample's comment listing them.
fn opencv_flags(cfg: &CalibrationConfig) -> (i64, String) {
    let f = &cfg.flags;
    let mut names: Vec<&str> = Vec::new();
    let mut word = 0;
    let mut set = |on: bool, bit: i64, name: &'static str| {
        if on {
            word |= bit;
            names.push(name);
        }
    };
    match cfg.model {
        LensModel::BrownConrady => {
            set(f.fix_aspect_ratio.is_some(), 2, "+fix_aspectRatio");
            set(f.fix_principal_point, 4, "+fix_principal_point");
            set(f.zero_tangent, 8, "+zero_tangent_dist");
            set(f.fix_k3, 128, "+fix_k3");
        }
        LensModel::KannalaBrandt => {
            set(true, 1, "+recompute_extrinsic");
            set(true, 8, "+fix_skew");
            set(f.fix_k3, 64, "+fix_k3");
            set(f.fix_k4, 128, "+fix_k4");
            set(f.fix_principal_point, 512, "+fix_principal_point");
        }
    }
    (word, format!("flags: {}", names.join(" ")))
}

/// One image: its name and, when the board was found, its corners.
struct View {
    path: PathBuf,
    image: GrayImage,
    corners: Option<Chessboard<MAX_CORNERS>>,
    /// What the detector saw (why a board was not found).
    seen: Seen,
}

/// What the detector saw in a view without the board, in words.
fn seen_text(s: &Seen, board: BoardSize) -> String {
    let (gc, gr) = (usize::from(s.largest_grid.0), usize::from(s.largest_grid.1));
    if s.x_corners == 0 {
        format!("no chessboard corner among {} candidates", s.candidates)
    } else if gc == 0 {
        format!(
            "{} chessboard corners, but no 2x2 grid of them",
            s.x_corners
        )
    } else if gc * gr < board.corners() {
        format!(
            "a partial grid of {gc}x{gr} corners (part of the board out of view, or its squares \
             too small to resolve)"
        )
    } else {
        format!(
            "a {gc}x{gr} grid that does not verify as a {}x{} board",
            board.cols(),
            board.rows()
        )
    }
}

/// The file name of a path, for messages and the JSON (the path itself when it has none).
fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// A list of names for a one-line message, at most 5 then `...`.
fn name_list(names: &[String]) -> String {
    let mut s = names.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
    if names.len() > 5 {
        s.push_str(&format!(", ... ({} in all)", names.len()));
    }
    s
}

#[derive(Serialize)]
struct StdDev {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    distortion: Vec<f64>,
}

#[derive(Serialize)]
struct Summary {
    views_used: usize,
    views_rejected: Vec<String>,
    /// Images of another size than most views' (another camera mode), not used.
    views_skipped: Vec<String>,
    images_used: Vec<String>,
    rms_px: f64,
    #[serde(rename = "K")]
    k: [f64; 9],
    distortion: Vec<f64>,
    model: &'static str,
    std: StdDev,
    per_view_rms: Vec<f64>,
    /// Each used view's pose, as OpenCV's `rvecs`/`tvecs`.
    views: Vec<ViewPose>,
    warnings: Vec<&'static str>,
    image_width: usize,
    image_height: usize,
    iterations: u8,
    out: String,
    contact_sheet: String,
    error_chart: String,
}

fn warning_name(w: &CalibrationWarning) -> &'static str {
    match w {
        CalibrationWarning::FocalLengthUnconstrained => "focal_length_unconstrained",
        CalibrationWarning::PrincipalPointUnconstrained => "principal_point_unconstrained",
        CalibrationWarning::DistortionUnconstrained => "distortion_unconstrained",
    }
}

/// Lens coefficients in OpenCV's order: 5 (Brown-Conrady) or 4 (fisheye).
fn lens_coefficients(r: &CalibrationReport<f64, MAX_VIEWS>) -> Vec<f64> {
    match &r.camera.lens {
        Lens::KannalaBrandt(f) => f.to_opencv().to_vec(),
        Lens::BrownConrady(d) => d.to_opencv().to_vec(),
    }
}

/// `camgeom calibrate`: writes the camera file and the two pictures, prints a JSON summary.
pub fn run(a: &CalibrateArgs) -> Result<String> {
    if let Some(spec) = a.board.strip_prefix("charuco:") {
        return charuco::run(a, spec);
    }
    if let Some(spec) = a.board.strip_prefix("aprilgrid:") {
        return aprilgrid::run(a, spec);
    }
    // Every option is checked before the images are read.
    let board = parse_board(&a.board)?;
    let square = a.square.ok_or_else(|| {
        Error::usage("--square S is required with a chessboard --board COLSxROWS")
    })?;
    if !(square.is_finite() && square > 0.0) {
        return Err(Error::usage(format!(
            "--square must be a positive length, got {}",
            square
        )));
    }
    let cfg = calibration_config(a)?;
    check_args(a)?;

    let bar = progress_bar(a.images.len() as u64);
    bar.set_message("detecting");
    let views = detect_all(&a.images, board, &bar);
    bar.finish_and_clear();
    let (views, skipped) = views?;

    let board_text = format!("{}x{}", board.cols(), board.rows());
    let found: Vec<&View> = views.iter().filter(|v| v.corners.is_some()).collect();
    let missed: Vec<String> = views
        .iter()
        .filter(|v| v.corners.is_none())
        .map(|v| file_name(&v.path))
        .collect();
    if found.is_empty() {
        // The view that came closest says what was seen.
        let area =
            |v: &&View| usize::from(v.seen.largest_grid.0) * usize::from(v.seen.largest_grid.1);
        let best = views
            .iter()
            .max_by_key(|v| (area(v), v.seen.x_corners))
            .map(|v| {
                format!(
                    "; the most seen: {} in {}",
                    seen_text(&v.seen, board),
                    file_name(&v.path)
                )
            })
            .unwrap_or_default();
        return Err(Error::usage(format!(
            "no {board_text} chessboard found in any of the {} images{best}",
            views.len()
        )));
    }
    if found.len() < 3 {
        return Err(Error::usage(format!(
            "the {board_text} board was found in {} of {} images; calibration needs at least 3 \
             views (not found in: {})",
            found.len(),
            views.len(),
            name_list(&missed)
        )));
    }
    let (width, height) = (views[0].image.width, views[0].image.height);

    // The calibration, in f64.
    let mut cal = Box::new(
        Calibrator::<f64, MAX_VIEWS, MAX_CORNERS>::new(board, square, width, height)
            .map_err(|e| Error::camgeom("calibration setup", e))?,
    );
    for v in &found {
        if let Some(c) = &v.corners {
            cal.add_chessboard(width, height, c)
                .map_err(|e| Error::camgeom(format!("{}: view rejected", v.path.display()), e))?;
        }
    }
    let report = cfg.check().and_then(|p| cal.solve(&p)).map_err(|e| {
        let why = match e {
            camgeom::Error::Degenerate => {
                "the views do not determine the camera (all parallel to each other, e.g. \
                 fronto-parallel: tilt the board between views)"
            }
            camgeom::Error::TooFewPoints => "fewer than 3 views are usable",
            _ => "calibration failed",
        };
        Error::camgeom(
            format!("calibration of {} views failed: {why}", found.len()),
            e,
        )
    })?;

    // Views the calibration itself rejected (no pose found).
    let mut rejected = missed.clone();
    let mut used: Vec<&View> = Vec::new();
    let mut per_view = Vec::new();
    for (k, v) in found.iter().enumerate() {
        match report.per_view_rms_px.get(k).copied().flatten() {
            Some(e) => {
                used.push(v);
                per_view.push(e);
            }
            None => rejected.push(file_name(&v.path)),
        }
    }
    for v in &views {
        if v.corners.is_none() {
            eprintln!(
                "camgeom: note: {}: no {board_text} board found ({}), view not used",
                v.path.display(),
                seen_text(&v.seen, board)
            );
        }
    }

    // Each used view's pose and corners.
    let mut poses = Vec::new();
    let mut corners_csv = String::from("view,X,Y,Z,u,v\n");
    for (k, v) in found.iter().enumerate() {
        let (Some(Some(pose)), Some(Some(rms)), Some(c)) = (
            report.poses.get(k),
            report.per_view_rms_px.get(k),
            v.corners.as_ref(),
        ) else {
            continue;
        };
        let index = views.iter().position(|w| std::ptr::eq(w, *v)).unwrap_or(k);
        let (r, t) = (pose.rotation_vector(), pose.translation());
        poses.push(ViewPose {
            image: file_name(&v.path),
            view: index,
            rvec: [r.x, r.y, r.z],
            tvec: [t.x, t.y, t.z],
            rms_px: *rms,
        });
        let cols = board.cols();
        for (n, p) in c.corners.iter().enumerate() {
            let (i, j) = (n % cols, n / cols);
            let _ = writeln!(
                corners_csv,
                "{index},{},{},0,{},{}",
                i as f64 * square,
                j as f64 * square,
                p.x,
                p.y
            );
        }
    }

    // Outputs, all made before any is written.
    let yaml = camera_yaml(&report, &cfg, board, square, width, height, &per_view);
    let sheet = corners_sheet(&views);
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

/// Checks `--out` and the number of images (before any image is read), whatever the board.
fn check_args(a: &CalibrateArgs) -> Result<()> {
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
    Ok(())
}

/// Views numbered from 1, the numbers of those in `used` (the same objects).
fn used_labels<V>(views: &[V], used: &[&V]) -> Vec<usize> {
    views
        .iter()
        .enumerate()
        .filter(|(_, v)| used.iter().any(|u| std::ptr::eq(*u, *v)))
        .map(|(i, _)| i + 1)
        .collect()
}

/// What a solved calibration writes and prints, whatever the board: everything is made before
/// anything is written.
struct Solved {
    report: CalibrationReport<f64, MAX_VIEWS>,
    /// The camera file.
    yaml: String,
    /// The contact sheet of the views with their corners.
    sheet: RgbImage,
    /// The used views' numbers (from 1), the error chart's bars.
    labels: Vec<usize>,
    images_used: Vec<String>,
    per_view: Vec<f64>,
    poses: Vec<ViewPose>,
    rejected: Vec<String>,
    skipped: Vec<String>,
    corners_csv: String,
    width: usize,
    height: usize,
}

/// Writes the camera file, the contact sheet, the per-view error chart and (`--corners-out`)
/// the corners CSV; the JSON summary.
fn write_outputs(a: &CalibrateArgs, s: Solved) -> Result<String> {
    let Solved {
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
    } = s;
    let chart = error_chart(&labels, &per_view, report.rms_px);

    let dir = match &a.pictures {
        Some(d) => d.clone(),
        None => a
            .out
            .parent()
            .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
    };
    let stem = a.out.file_stem().map_or_else(
        || "camera".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    let sheet_path = dir.join(format!("{stem}_corners.png"));
    let chart_path = dir.join(format!("{stem}_reprojection_errors.png"));
    create_dir(&dir)?;
    write_file(&a.out, &yaml)?;
    sheet.save_png(&sheet_path)?;
    chart.save_png(&chart_path)?;
    if let Some(path) = &a.corners_out {
        write_file(path, &corners_csv)?;
    }

    let k = &report.camera.intrinsics;
    let sd = &report.std;
    let n_lens = lens_coefficients(&report).len();
    Ok(to_json(&Summary {
        views_used: report.views_used,
        views_rejected: rejected,
        views_skipped: skipped,
        images_used,
        rms_px: report.rms_px,
        k: [k.fx(), k.skew(), k.cx(), 0.0, k.fy(), k.cy(), 0.0, 0.0, 1.0],
        distortion: lens_coefficients(&report),
        model: if a.fisheye {
            "kannala_brandt"
        } else {
            "brown_conrady"
        },
        std: StdDev {
            fx: sd[0],
            fy: sd[1],
            cx: sd[2],
            cy: sd[3],
            distortion: sd.iter().skip(4).take(n_lens).copied().collect(),
        },
        per_view_rms: per_view,
        views: poses,
        warnings: report.warnings.iter().map(warning_name).collect(),
        image_width: width,
        image_height: height,
        iterations: report.iterations,
        out: a.out.display().to_string(),
        contact_sheet: sheet_path.display().to_string(),
        error_chart: chart_path.display().to_string(),
    }))
}

/// Reads every image and looks for the board in it at any scale, advancing `bar` by one an
/// image. The calibration's image size is the size most images have (the first of them on a
/// tie); images of another size are skipped with a warning and named in the second list.
/// Errors for an unreadable image or a detector error.
fn detect_all(
    images: &[PathBuf],
    board: BoardSize,
    bar: &indicatif::ProgressBar,
) -> Result<(Vec<View>, Vec<String>)> {
    let loaded = images
        .iter()
        .map(|p| Ok((p, load_gray(p)?)))
        .collect::<Result<Vec<_>>>()?;
    let size = |g: &GrayImage| (g.width, g.height);
    let count = |s: (usize, usize)| loaded.iter().filter(|(_, g)| size(g) == s).count();
    let Some(mode) = loaded
        .iter()
        .map(|(_, g)| size(g))
        .fold(None::<(usize, usize)>, |best, s| match best {
            Some(b) if count(b) >= count(s) => Some(b),
            _ => Some(s),
        })
    else {
        return Ok((Vec::new(), Vec::new()));
    };
    let mut det = Box::new(ChessboardDetector::<CANDIDATES>::new());
    let detect_params = DetectParams::default();
    let mut scratch = vec![0i32; scratch_len(mode.0)];
    let mut pyramid = vec![0u8; pyramid_len(mode.0, mode.1)];
    let mut views: Vec<View> = Vec::with_capacity(images.len());
    let mut skipped = Vec::new();
    for (path, image) in loaded {
        bar.inc(1);
        if size(&image) != mode {
            eprintln!(
                "camgeom: warning: {}: {}x{}, not the {}x{} of most images (another camera \
                 mode): skipped",
                path.display(),
                image.width,
                image.height,
                mode.0,
                mode.1
            );
            skipped.push(file_name(path));
            continue;
        }
        let view = image
            .view()
            .ok_or_else(|| Error::new(path, ErrorKind::Shape("image size not supported".into())))?;
        let corners = det
            .detect_any_scale::<MAX_CORNERS>(
                &view,
                board,
                &detect_params,
                &mut pyramid,
                &mut scratch,
            )
            .map_err(|e| {
                Error::camgeom(
                    format!("{}: chessboard detection failed", path.display()),
                    e,
                )
            })?;
        views.push(View {
            path: path.clone(),
            image,
            corners,
            seen: det.seen(),
        });
    }
    Ok((views, skipped))
}

/// The camera file as OpenCV's calibration sample (`samples/cpp/calibration.cpp`) writes it,
/// with `fisheye_model` as its tutorial (`camera_calibration.cpp`) writes it.
fn camera_yaml(
    r: &CalibrationReport<f64, MAX_VIEWS>,
    cfg: &CalibrationConfig,
    board: BoardSize,
    square: f64,
    width: usize,
    height: usize,
    per_view: &[f64],
) -> String {
    let k = &r.camera.intrinsics;
    let (flags, flag_names) = opencv_flags(cfg);
    let mut w = YamlWriter::new();
    w.int("nframes", r.views_used as i64)
        .int("image_width", width as i64)
        .int("image_height", height as i64)
        .int("board_width", board.cols() as i64)
        .int("board_height", board.rows() as i64)
        .real("square_size", square);
    if let Some(ratio) = cfg.flags.fix_aspect_ratio {
        w.real("aspectRatio", ratio);
    }
    if flags != 0 {
        w.comment(&flag_names);
    }
    w.int("flags", flags)
        .int(
            "fisheye_model",
            i64::from(cfg.model == LensModel::KannalaBrandt),
        )
        .matrix(
            "camera_matrix",
            3,
            3,
            &[k.fx(), k.skew(), k.cx(), 0.0, k.fy(), k.cy(), 0.0, 0.0, 1.0],
        );
    let d = lens_coefficients(r);
    w.matrix("distortion_coefficients", d.len(), 1, &d)
        .real("avg_reprojection_error", r.rms_px)
        .matrix("per_view_reprojection_errors", per_view.len(), 1, per_view);
    w.finish()
}

/// OpenCV's `drawChessboardCorners` colours, one a row (RGB).
const ROW_COLOURS: [[u8; 3]; 7] = [
    [255, 0, 0],
    [255, 128, 0],
    [200, 200, 0],
    [0, 255, 0],
    [0, 200, 200],
    [0, 0, 255],
    [255, 0, 255],
];

/// One tile per image: the detected corners drawn as OpenCV draws them (a circle per corner,
/// the row order joined by lines, one colour a row), or a red border when the board was not
/// found; tiles labelled with the image's position in `--images` (from 1).
fn corners_sheet(views: &[View]) -> RgbImage {
    let tiles: Vec<(usize, RgbImage)> = views
        .iter()
        .enumerate()
        .map(|(i, v)| (i + 1, draw_corners(v)))
        .collect();
    let width = views.first().map_or(1, |v| v.image.width);
    let factor = width.div_ceil(320).max(1);
    contact_sheet(&tiles, 4, factor)
}

fn draw_corners(v: &View) -> RgbImage {
    let img = &v.image;
    let mut out = RgbImage::from_gray(img);
    let Some(board) = &v.corners else {
        let t = (img.width / 100).max(2) as i64;
        for y in 0..img.height as i64 {
            for x in 0..img.width as i64 {
                if x < t || y < t || x >= img.width as i64 - t || y >= img.height as i64 - t {
                    out.put(x, y, [255, 40, 40]);
                }
            }
        }
        return out;
    };
    let cols = board.size.cols();
    let radius = (img.width as f32 / 160.0).max(3.0);
    for (r, row) in board.corners.chunks(cols).enumerate() {
        let mut mask = GrayImage::filled(img.width, img.height, 0);
        if let Some(mut m) = mask.view_mut() {
            // The line from the previous row's last corner, as OpenCV draws it.
            if r > 0
                && let (Some(prev), Some(first)) = (board.corners.get(r * cols - 1), row.first())
            {
                let _ = draw_line(&mut m, prev, first, 255);
            }
            for (k, p) in row.iter().enumerate() {
                if let Some(next) = row.get(k + 1) {
                    let _ = draw_line(&mut m, p, next, 255);
                }
                for s in 0..12 {
                    let a0 = s as f32 * core::f32::consts::TAU / 12.0;
                    let a1 = (s + 1) as f32 * core::f32::consts::TAU / 12.0;
                    let q0 = Point2::new(p.x + radius * a0.cos(), p.y + radius * a0.sin());
                    let q1 = Point2::new(p.x + radius * a1.cos(), p.y + radius * a1.sin());
                    let _ = draw_line(&mut m, &q0, &q1, 255);
                }
            }
        }
        out.ink(&mask, ROW_COLOURS[r % ROW_COLOURS.len()]);
    }
    out
}

/// A bar per used view (its RMS reprojection error, labelled with its position in
/// `--images`), a green line at the overall RMS, grey grid lines labelled in pixels; bars
/// above the overall RMS are orange, the others blue.
fn error_chart(labels: &[usize], per_view: &[f64], rms: f64) -> RgbImage {
    let (left, right, top, bottom) = (48usize, 16usize, 16usize, 24usize);
    let (bar, gap, plot_h) = (24usize, 8usize, 240usize);
    let n = per_view.len().max(1);
    let (w, h) = (left + n * (bar + gap) + gap + right, top + plot_h + bottom);
    let mut img = RgbImage::from_pixel(w as u32, h as u32, image::Rgb([255, 255, 255]));
    let max = per_view.iter().copied().fold(rms, f64::max).max(1e-9) * 1.1;
    // Grid step: 1, 2 or 5 times a power of ten, about 5 lines.
    let raw = max / 5.0;
    let p = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * p);
    let y_of = |v: f64| (top + plot_h) as i64 - ((v / max) * plot_h as f64).round() as i64;
    let hline = |img: &mut RgbImage, y: i64, c: [u8; 3]| {
        for x in left as i64..(w - right) as i64 {
            img.put(x, y, c);
        }
    };
    let mut g = 0.0;
    while g <= max {
        let y = y_of(g);
        hline(&mut img, y, [210, 210, 210]);
        let text = format!("{:.*}", decimals(step), g);
        img.label(2, (y - 7).max(0) as usize, &text, left - 4, 14);
        g += step;
    }
    for (i, (&e, &label)) in per_view.iter().zip(labels).enumerate() {
        let x0 = left + gap + i * (bar + gap);
        let colour = if e > rms {
            [240, 140, 20]
        } else {
            [50, 110, 200]
        };
        for y in y_of(e)..y_of(0.0) {
            for x in x0..x0 + bar {
                img.put(x as i64, y, colour);
            }
        }
        img.label(x0, top + plot_h + 4, &label.to_string(), bar + gap, 14);
    }
    let y = y_of(rms);
    hline(&mut img, y, [20, 170, 40]);
    hline(&mut img, y + 1, [20, 170, 40]);
    // The axes.
    for y in top as i64..=(top + plot_h) as i64 {
        img.put(left as i64, y, [0, 0, 0]);
    }
    hline(&mut img, y_of(0.0), [0, 0, 0]);
    img
}

/// Decimals that show a grid step exactly (0.05 → 2).
fn decimals(step: f64) -> usize {
    (0..6)
        .find(|&d| {
            let s = step * 10f64.powi(d as i32);
            (s - s.round()).abs() < 1e-6
        })
        .unwrap_or(6)
}
