//! `camgeom ar`: track a planar target through a folder of frames or a video and draw a cube
//! on it.

use std::path::PathBuf;

use camgeom::apriltag::{Detector, Family};
use camgeom::corners::CornerConfig;
use camgeom::klt::LkConfig;
use camgeom::nalgebra::Point2;
use camgeom::ransac::RansacConfig;
use camgeom::target::{Acquire, GivenCorners, TargetConfig, TargetState};
use camgeom_host::apriltag::{HostTagTarget, check_tag_size, detector, family};
use camgeom_host::ar::{ArOptions, ArTracker, draw_ar_on, evenly_spaced};
use camgeom_host::cli::args::CameraArg;
use camgeom_host::cli::files::{create_dir, write_file};
use camgeom_host::cli::frames::{FrameSource, progress_bar};
use camgeom_host::contact_sheet::contact_sheet;
use camgeom_host::klt::Path;
use camgeom_host::points::{format_csv, format_float, read_csv, to_json};
use camgeom_host::rgb::{Overlay, RgbImage};
use camgeom_host::video::VideoWriter;
use camgeom_host::{Error, ErrorKind, Result, load_camera};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct ArArgs {
    /// The frames: a folder of PNG/JPEG files (file-name order) or a video file (.mp4, .mov,
    /// .avi, .mkv, ..; decoded by ffmpeg one frame at a time). Tracked in grey; the overlays
    /// are drawn on the colour frames.
    #[arg(long, visible_alias = "video", value_name = "DIR|VIDEO")]
    frames: PathBuf,
    /// The target's four corners in the first frame, CSV rows `x,y` in the order
    /// (0,0), (w,0), (w,h), (0,h) of the target.
    #[arg(
        long,
        value_name = "FIRST.csv",
        required_unless_present_any = ["tag", "board"],
        conflicts_with_all = ["tag", "board"],
        requires = "size"
    )]
    corners: Option<PathBuf>,
    /// A tag board file (see `camgeom apriltag --board`): the pose of the board on every frame
    /// from all its tags detected there (no tracking between frames), the cube on it.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["tag", "size"])]
    board: Option<PathBuf>,
    #[command(flatten)]
    camera: CameraArg,
    /// The target's size `W,H` (metres, or the unit the pose should use), or `S` for a square
    /// (with --corners).
    #[arg(long, value_name = "W,H", conflicts_with = "tag")]
    size: Option<String>,
    /// Acquire the target from AprilTag ID (of --family) instead of --corners: the detector
    /// finds it in the first frame it is seen, again after every loss and every
    /// --reacquire-every frames while tracking. The target is the tag's black square.
    #[arg(long, value_name = "ID", requires = "tag_size")]
    tag: Option<u16>,
    /// The tag's family (with --tag): tag36h11, tag25h9, tag16h5, tagStandard41h12.
    #[arg(long, default_value = "tag36h11", value_name = "F")]
    family: String,
    /// The tag's side (the black border's outer edge), in the unit the pose should use
    /// (with --tag).
    #[arg(long, value_name = "S", allow_hyphen_values = true, requires = "tag")]
    tag_size: Option<f32>,
    /// Detector decimation (with --tag; see `camgeom apriltag --help`).
    #[arg(long, default_value_t = 1, value_name = "D")]
    decimate: u8,
    /// While tracking, run the acquisition again every N frames (0: only before the first
    /// acquisition and after a loss). Default 30 with --tag (the board's tag job's guard), 5
    /// with --tag --klt, 0 with --corners (given corners answer once).
    #[arg(long, value_name = "N")]
    reacquire_every: Option<u32>,
    /// With --tag: track the tag with KLT between detections (the loop before tracking by
    /// detection) instead of detecting it where it must be on every frame.
    #[arg(long, requires = "tag")]
    klt: bool,
    /// Edge of the cube drawn on the target (default: the target's smaller side).
    #[arg(long, value_name = "S")]
    cube: Option<f32>,
    /// Output folder: one overlay PNG per frame (see --overlay-every; named after the frame
    /// file, or `000123.png` for a video's frame 123), `poses.csv`, `contact_sheet.png`.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Write the overlay PNG of every N-th frame only (frames 0, N, 2N, ..).
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::value_parser!(u32).range(1..))]
    overlay_every: u32,
    /// Write no overlay PNG (`poses.csv` and the contact sheet are written still).
    #[arg(long, conflicts_with = "overlay_every")]
    no_overlay: bool,
    /// Also write every frame's overlay into a video (.mp4/.mov/.mkv: H.264; .avi: MPEG-4),
    /// at the input video's frame rate (--fps for a folder).
    #[arg(long, value_name = "OUT.mp4")]
    video_out: Option<PathBuf>,
    /// Frame rate of --video-out for a folder of frames (a video keeps its own).
    #[arg(long, default_value_t = 30.0, value_name = "F")]
    fps: f64,
    /// Run the f32 flow instead of the fixed-point (integer) one.
    #[arg(long)]
    f32: bool,
    /// Frames on the contact sheet (evenly spaced, first and last included).
    #[arg(long, default_value_t = 12)]
    sheet_frames: usize,
    /// Contact sheet columns.
    #[arg(long, default_value_t = 4)]
    sheet_cols: usize,
    /// Downscale factor of the contact sheet's tiles.
    #[arg(long, default_value_t = 2)]
    sheet_scale: usize,
    /// KLT window side in pixels (`TargetConfig`'s default).
    #[arg(long, default_value_t = 15)]
    win: usize,
    /// KLT coarsest pyramid level (`TargetConfig`'s default).
    #[arg(long, default_value_t = 2)]
    max_level: usize,
    /// Forward-backward check threshold in pixels (0 disables it).
    #[arg(long, default_value_t = 1.0)]
    fb: f32,
    /// Corner quality level for (re-)detection inside the target.
    #[arg(long, default_value_t = 0.02)]
    quality: f32,
    /// Minimum distance between features, pixels.
    #[arg(long, default_value_t = 8)]
    min_distance: u32,
    /// Re-detect inside the target when fewer tracks than this survive (default 24; with
    /// --tag, --min-inliers: no features are added between detections).
    #[arg(long)]
    min_tracks: Option<usize>,
    /// Fewer homography inliers than this and the target is lost.
    #[arg(long, default_value_t = 8)]
    min_inliers: usize,
    /// RANSAC inlier threshold of the target homography, pixels.
    #[arg(long, default_value_t = 2.0)]
    threshold: f32,
}

/// The columns of `poses.csv`.
const POSES_COLUMNS: [&str; 15] = [
    "frame",
    "state",
    "rx",
    "ry",
    "rz",
    "tx",
    "ty",
    "tz",
    "rms_px",
    "alt_rms_px",
    "outline_px",
    "tracked",
    "inliers",
    "added",
    "partial",
];

/// How the target is found.
enum Acquisition<'a> {
    /// Corners picked in the first frame (a CSV file).
    Corners(&'a PathBuf),
    /// A tag: the detector, the family and the id.
    Tag(Detector, &'static Family, u16),
}

/// The target's corners from a CSV file of 4 rows `x,y`.
fn read_corners(path: &PathBuf) -> Result<[Point2<f32>; 4]> {
    let table = read_csv(path, &["x", "y"])?;
    if table.rows.len() != 4 {
        return Err(Error::new(
            path,
            ErrorKind::Shape(format!(
                "expected the target's 4 corners (x,y rows), found {}",
                table.rows.len()
            )),
        ));
    }
    Ok(std::array::from_fn(|i| {
        Point2::new(table.rows[i][0] as f32, table.rows[i][1] as f32)
    }))
}

/// `W,H` or `S`: finite and positive.
fn parse_size(s: &str) -> Result<[f32; 2]> {
    let expected = || Error::usage(format!("--size: expected W,H or S, got `{s}`"));
    let v: Vec<f32> = s
        .split(',')
        .map(|f| f.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| expected())?;
    let size = match v.as_slice() {
        [s] => [*s, *s],
        [w, h] => [*w, *h],
        _ => return Err(expected()),
    };
    if !size.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(Error::usage(format!("--size must be positive, got `{s}`")));
    }
    Ok(size)
}

#[derive(Serialize)]
struct Summary {
    frames: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    fps: Option<f64>,
    tracking: usize,
    /// Of the frames tracking, those whose pose is from a partly seen target.
    partial: usize,
    lost: usize,
    mean_inliers: f64,
    worst_outline_px: Option<f32>,
    out: String,
    poses: String,
    contact_sheet: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    video_out: Option<String>,
}

/// A tile of the contact sheet: the overlay downscaled by `factor` as
/// [`contact_sheet`] does (box filter on whole blocks), so only the small tiles are kept.
fn shrink(img: &RgbImage, factor: usize) -> RgbImage {
    let f = u32::try_from(factor.max(1)).unwrap_or(u32::MAX);
    let (tw, th) = ((img.width() / f).max(1), (img.height() / f).max(1));
    let blocks = image::imageops::crop_imm(
        img,
        0,
        0,
        (tw * f).min(img.width()),
        (th * f).min(img.height()),
    );
    image::imageops::thumbnail(&*blocks, tw, th)
}

/// The options `camgeom ar` passes to the tracker.
fn target_config(a: &ArArgs) -> Result<TargetConfig> {
    if !(3..=camgeom::klt::MAX_WIN).contains(&a.win) {
        return Err(Error::usage(format!(
            "--win must be 3..={}",
            camgeom::klt::MAX_WIN
        )));
    }
    if !(a.quality > 0.0 && a.quality <= 1.0) {
        return Err(Error::usage(format!(
            "--quality must be in (0, 1], got {}",
            a.quality
        )));
    }
    if !(a.threshold.is_finite() && a.threshold > 0.0 && a.fb.is_finite() && a.fb >= 0.0) {
        return Err(Error::usage(
            "--threshold must be positive and --fb non-negative",
        ));
    }
    let d = TargetConfig::default();
    let tag = a.tag.is_some();
    let min_inliers = a.min_inliers.max(4);
    let cfg = TargetConfig {
        lk: LkConfig {
            win: a.win,
            max_level: a.max_level.min(camgeom::pyramid::MAX_LEVELS - 1),
            fb_threshold: (a.fb > 0.0).then_some(a.fb),
            ..d.lk
        },
        corners: CornerConfig {
            quality: a.quality,
            min_distance: a.min_distance,
            max_corners: 0,
        },
        ransac: RansacConfig {
            threshold: a.threshold,
            ..d.ransac
        },
        min_inliers,
        reacquire_every: a.reacquire_every.unwrap_or(match (tag, a.klt) {
            (false, _) => 0,
            (true, true) => 5,
            (true, false) => 30,
        }),
        ..d
    };
    // With a tag, the board's tag-job policy (`TargetConfig::for_detector`); what the
    // command line sets explicitly still holds.
    let cfg = if tag { cfg.for_detector() } else { cfg };
    Ok(TargetConfig {
        lk: LkConfig {
            fb_threshold: (a.fb > 0.0).then_some(a.fb),
            ..cfg.lk
        },
        min_tracks: a.min_tracks.unwrap_or(cfg.min_tracks),
        ..cfg
    })
}

/// `camgeom ar`: writes the overlays, `poses.csv` and the contact sheet, returns the JSON
/// summary.
pub fn run(a: &ArArgs) -> Result<String> {
    if let Some(board) = &a.board {
        return run_board(a, board);
    }
    // The target's acquisition: given corners, or a tag detector.
    let (size, acquisition) = match (a.tag, a.tag_size, &a.corners, &a.size) {
        (Some(id), Some(s), None, None) => {
            check_tag_size(s)?;
            let family = family(&a.family)?;
            let det = detector(&[family], a.decimate, 2, true)?;
            if u32::from(id) >= family.ncodes() as u32 {
                return Err(Error::usage(format!(
                    "--tag: {} has ids 0..{}, got {id}",
                    family.name(),
                    family.ncodes()
                )));
            }
            ([s, s], Acquisition::Tag(det, family, id))
        }
        (None, None, Some(c), Some(size)) => (parse_size(size)?, Acquisition::Corners(c)),
        _ => {
            return Err(Error::usage(
                "give --corners with --size, or --tag with --tag-size",
            ));
        }
    };
    let cube = a.cube.unwrap_or(size[0].min(size[1]));
    if !(cube.is_finite() && cube > 0.0) {
        return Err(Error::usage(format!("--cube must be positive, got {cube}")));
    }
    let target = target_config(a)?;
    let spec = load_camera(&a.camera.intrinsics)?;
    let camera = spec.camera_f32();
    let mut given;
    let mut tag_target;
    let acquire: &mut dyn Acquire = match &acquisition {
        Acquisition::Corners(path) => {
            given = GivenCorners::new(read_corners(path)?);
            &mut given
        }
        Acquisition::Tag(det, family, id) => {
            tag_target = HostTagTarget::new(det, family, *id).track_by_detection(!a.klt);
            &mut tag_target
        }
    };
    let mut source = FrameSource::open(&a.frames, true)?;
    let n = source.len();
    create_dir(&a.out)?;
    if !(a.fps.is_finite() && a.fps > 0.0) {
        return Err(Error::usage(format!(
            "--fps must be positive, got {}",
            a.fps
        )));
    }
    let fps = source.fps();
    let timed = source.is_video();
    let bar = progress_bar(n as u64);
    let opts = ArOptions {
        size,
        cube,
        path: if a.f32 { Path::F32 } else { Path::Fixed },
        target,
    };
    bar.set_message("tracking");
    let sheet_idx = evenly_spaced(n, a.sheet_frames);
    let mut tiles = Vec::new();
    let mut video: Option<VideoWriter> = None;
    let every = usize::try_from(a.overlay_every).unwrap_or(usize::MAX);
    let mut tracker = ArTracker::new(&camera, &opts)
        .map_err(|e| Error::camgeom(format!("{}: tracking failed", a.frames.display()), e))?;
    let mut rows = Vec::with_capacity(n);
    let mut worst: Option<f32> = None;
    let mut partial = 0usize;
    let (mut count, mut tracking, mut inliers) = (0usize, 0usize, 0usize);
    while let Some(frame) = source.next_frame()? {
        let f = tracker
            .step(&frame.gray, acquire)
            .map_err(|e| Error::camgeom(format!("{}: tracking failed", a.frames.display()), e))?;
        bar.inc(1);
        if f.index == 0
            && f.frame.pose.is_none()
            && let Acquisition::Corners(path) = &acquisition
        {
            return Err(Error::camgeom(
                format!(
                    "{}: the corners enclose too little texture to track",
                    path.display()
                ),
                camgeom::Error::TooFewPoints,
            ));
        }
        let write = !a.no_overlay && f.index.is_multiple_of(every);
        let tile = sheet_idx.contains(&f.index);
        if write || tile || a.video_out.is_some() {
            let name = frame.name.clone();
            let canvas = match frame.rgb {
                Some(rgb) => rgb,
                None => RgbImage::from_gray(&frame.gray),
            };
            let img = draw_ar_on(canvas, &camera, &f, &opts);
            if write {
                img.save_png(a.out.join(format!("{name}.png")))?;
            }
            if tile {
                tiles.push((f.index, shrink(&img, a.sheet_scale)));
            }
            if let Some(path) = &a.video_out {
                if video.is_none() {
                    let rate = fps.unwrap_or(a.fps);
                    video = Some(VideoWriter::create(path, img.width(), img.height(), rate)?);
                }
                if let Some(v) = video.as_mut() {
                    v.write(&img)?;
                }
            }
        }
        count += 1;
        inliers += f.frame.inliers;
        let state = match f.frame.state {
            TargetState::Tracking => {
                tracking += 1;
                "tracking"
            }
            TargetState::Lost => "lost",
            TargetState::Uninitialised => "uninitialised",
        };
        let nums = match f.frame.pose {
            Some(p) => {
                let (r, t) = (p.best.pose.rotation_vector(), p.best.pose.translation());
                [
                    r.x,
                    r.y,
                    r.z,
                    t.x,
                    t.y,
                    t.z,
                    p.best.rms_px,
                    p.alternative.rms_px,
                ]
            }
            None => [f32::NAN; 8],
        };
        let outline = f.outline_error_px(&camera, size);
        if let Some(o) = outline {
            worst = Some(worst.map_or(o, |w| w.max(o)));
        }
        let mut row = vec![f.index.to_string()];
        if timed {
            row.push(
                frame
                    .t
                    .map_or_else(|| "nan".to_string(), |t| format!("{t:.6}")),
            );
        }
        row.push(state.to_string());
        row.extend(nums.iter().map(|v| format_float(*v)));
        row.push(format_float(outline.unwrap_or(f32::NAN)));
        row.extend([f.frame.tracked, f.frame.inliers, f.frame.added].map(|n| n.to_string()));
        row.push(u8::from(f.frame.partial).to_string());
        if f.frame.partial {
            partial += 1;
        }
        rows.push(row);
    }
    bar.finish_and_clear();
    if count == 0 {
        return Err(Error::new(&a.frames, ErrorKind::Shape("no frames".into())));
    }
    let video_out = match (video, &a.video_out) {
        (Some(v), Some(path)) => {
            v.finish()?;
            Some(path.display().to_string())
        }
        _ => None,
    };
    let mut columns: Vec<&str> = POSES_COLUMNS.to_vec();
    if timed {
        columns.insert(1, "t");
    }
    let csv = format_csv(&columns, rows);
    let poses = a.out.join("poses.csv");
    write_file(&poses, csv)?;
    let sheet_path = a.out.join("contact_sheet.png");
    contact_sheet(&tiles, a.sheet_cols, 1).save_png(&sheet_path)?;
    let summary = Summary {
        frames: count,
        fps,
        tracking,
        partial,
        lost: count - tracking,
        mean_inliers: inliers as f64 / count.max(1) as f64,
        worst_outline_px: worst,
        out: a.out.display().to_string(),
        poses: poses.display().to_string(),
        contact_sheet: sheet_path.display().to_string(),
        video_out,
    };
    Ok(to_json(&summary))
}

/// `camgeom ar --board`: on every frame, the board's tags detected (its family, `--decimate`)
/// and the board pose from all of them (`apriltag::board_pose`); the overlay draws the board's
/// outline through the pose (green) and the cube (yellow) centred on the board's extent
/// `[0, max x] x [0, max y]`, a red border when there is no pose. `poses.csv` as with a target:
/// `tracked` is the board tags used, `inliers` their corners, `added` and `outline_px` 0 and
/// nan.
fn run_board(a: &ArArgs, path: &std::path::Path) -> Result<String> {
    use camgeom::pose::{PlanarPose, PoseEstimate};
    use camgeom::target::{TargetFrame, TargetState};
    use camgeom_host::apriltag::{HostWorkspace, detect};
    use camgeom_host::ar::draw_target_on;
    use camgeom_host::board::{board_pose_json, load_board};

    let board = load_board(path)?;
    let det = detector(&[board.family], a.decimate, 2, true)?;
    let corners = board.tags.iter().flat_map(|t| t.corners.iter());
    let (w, h) = corners.fold((0.0f64, 0.0f64), |(w, h), c| (w.max(c[0]), h.max(c[1])));
    let size = [w as f32, h as f32];
    let cube = a.cube.unwrap_or(size[0].min(size[1]) / 2.0);
    if !(cube.is_finite() && cube > 0.0) {
        return Err(Error::usage(format!("--cube must be positive, got {cube}")));
    }
    if !(a.fps.is_finite() && a.fps > 0.0) {
        return Err(Error::usage(format!(
            "--fps must be positive, got {}",
            a.fps
        )));
    }
    let spec = load_camera(&a.camera.intrinsics)?;
    let camera = spec.camera_f32();
    let mut source = FrameSource::open(&a.frames, true)?;
    let n = source.len();
    create_dir(&a.out)?;
    let fps = source.fps();
    let timed = source.is_video();
    let sheet_idx = evenly_spaced(n, a.sheet_frames);
    let every = usize::try_from(a.overlay_every).unwrap_or(usize::MAX);
    let mut ws: Box<HostWorkspace> = Box::default();
    let (mut tiles, mut rows) = (Vec::new(), Vec::with_capacity(n));
    let mut video: Option<VideoWriter> = None;
    let (mut count, mut tracking, mut inliers) = (0usize, 0usize, 0usize);
    while let Some(frame) = source.next_frame()? {
        let at = frame.file.clone().unwrap_or_else(|| a.frames.clone());
        let found: Vec<_> = detect(&det, &mut ws, &frame.gray, &at)?
            .into_iter()
            .collect();
        let (json, pose) = board_pose_json(&board, &found, &spec.camera);
        let estimate = pose.map(|p| PoseEstimate {
            pose: camgeom::transform::Pose::from_isometry(p.isometry().cast()),
            rms_px: json.rms_px.unwrap_or(f64::NAN) as f32,
        });
        let planar = estimate.map(|best| PlanarPose {
            best,
            alternative: PoseEstimate {
                rms_px: json.alternative_rms_px.unwrap_or(f64::NAN) as f32,
                ..best
            },
        });
        let outline = estimate.and_then(|e| {
            let c = [
                [0.0, 0.0],
                [size[0], 0.0],
                [size[0], size[1]],
                [0.0, size[1]],
            ];
            let mut o = [camgeom::nalgebra::Point2::origin(); 4];
            for (o, c) in o.iter_mut().zip(c) {
                *o = camera
                    .project(&e.pose, &camgeom::nalgebra::Point3::new(c[0], c[1], 0.0))
                    .ok()?;
            }
            Some(o)
        });
        let tf = TargetFrame {
            state: if planar.is_some() {
                TargetState::Tracking
            } else {
                TargetState::Lost
            },
            acquired: planar.is_some(),
            pose: planar,
            outline,
            tracked: json.tags.len(),
            partial: false,
            inliers: json.points,
            added: 0,
            features: 0,
        };
        let index = count;
        let write = !a.no_overlay && index.is_multiple_of(every);
        let tile = sheet_idx.contains(&index);
        if write || tile || a.video_out.is_some() {
            let canvas = match frame.rgb {
                Some(rgb) => rgb,
                None => RgbImage::from_gray(&frame.gray),
            };
            let img = draw_target_on(canvas, Some(&camera), &tf, &[], size, cube);
            if write {
                img.save_png(a.out.join(format!("{}.png", frame.name)))?;
            }
            if tile {
                tiles.push((index, shrink(&img, a.sheet_scale)));
            }
            if let Some(path) = &a.video_out {
                if video.is_none() {
                    let rate = fps.unwrap_or(a.fps);
                    video = Some(VideoWriter::create(path, img.width(), img.height(), rate)?);
                }
                if let Some(v) = video.as_mut() {
                    v.write(&img)?;
                }
            }
        }
        count += 1;
        inliers += tf.inliers;
        let mut row = vec![index.to_string()];
        if timed {
            row.push(
                frame
                    .t
                    .map_or_else(|| "nan".to_string(), |t| format!("{t:.6}")),
            );
        }
        let nums = match estimate {
            Some(e) => {
                tracking += 1;
                row.push("tracking".into());
                let (r, t) = (e.pose.rotation_vector(), e.pose.translation());
                [r.x, r.y, r.z, t.x, t.y, t.z, e.rms_px]
            }
            None => {
                row.push("lost".into());
                [f32::NAN; 7]
            }
        };
        row.extend(nums.iter().map(|v| format_float(*v)));
        row.push(format_float(
            json.alternative_rms_px.map_or(f32::NAN, |v| v as f32),
        ));
        row.push(format_float(f32::NAN));
        row.extend([tf.tracked, tf.inliers, 0].map(|n| n.to_string()));
        row.push("0".into());
        rows.push(row);
    }
    if count == 0 {
        return Err(Error::new(&a.frames, ErrorKind::Shape("no frames".into())));
    }
    let video_out = match (video, &a.video_out) {
        (Some(v), Some(path)) => {
            v.finish()?;
            Some(path.display().to_string())
        }
        _ => None,
    };
    let mut columns: Vec<&str> = POSES_COLUMNS.to_vec();
    if timed {
        columns.insert(1, "t");
    }
    let poses = a.out.join("poses.csv");
    write_file(&poses, format_csv(&columns, rows))?;
    let sheet_path = a.out.join("contact_sheet.png");
    contact_sheet(&tiles, a.sheet_cols, 1).save_png(&sheet_path)?;
    Ok(to_json(&Summary {
        frames: count,
        fps,
        tracking,
        partial: 0,
        lost: count - tracking,
        mean_inliers: inliers as f64 / count.max(1) as f64,
        worst_outline_px: None,
        out: a.out.display().to_string(),
        poses: poses.display().to_string(),
        contact_sheet: sheet_path.display().to_string(),
        video_out,
    }))
}
