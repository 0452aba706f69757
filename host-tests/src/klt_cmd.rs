//! `camgeom flow` and `camgeom track`: camgeom's KLT on image files.

use std::path::PathBuf;

use camgeom::corners::CornerConfig;
use camgeom::klt::{FlowStatus, LkConfig, TrackerConfig};
use camgeom_host::cli::files::{create_dir, write_file};
use camgeom_host::cli::frames::{Frame, FrameSource, progress_bar};
use camgeom_host::images::{load_gray, require_size, save_gray};
use camgeom_host::klt::{Path, TrackRow, flow, overlay, track_stream};
use camgeom_host::points::{format_csv, format_float, read_csv, to_json};
use camgeom_host::{Error, ErrorKind, Result};
use clap::Args;
use serde::Serialize;

/// Flow options shared by `flow` and `track` (OpenCV's calcOpticalFlowPyrLK parameters).
#[derive(Args, Debug)]
pub struct LkOpt {
    /// Window side in pixels (3..63).
    #[arg(long, default_value_t = 21)]
    win: usize,
    /// Coarsest pyramid level (OpenCV's maxLevel; 0 = no pyramid).
    #[arg(long, default_value_t = 3)]
    max_level: usize,
    /// Iteration cap per level (1..100).
    #[arg(long, default_value_t = 30)]
    iters: u32,
    /// Stop when the update is at most this many pixels.
    #[arg(long, default_value_t = 0.01)]
    eps: f32,
    /// Minimum-eigenvalue threshold (OpenCV's minEigThreshold).
    #[arg(long, default_value_t = 1e-4)]
    min_eig: f32,
    /// Forward-backward check: drop points that do not track back within this many pixels.
    #[arg(long, value_name = "PX")]
    fb: Option<f32>,
    /// Run the fixed-point (integer) path instead of f32.
    #[arg(long)]
    fixed: bool,
}

impl LkOpt {
    fn config(&self) -> Result<LkConfig> {
        if !(3..=camgeom::klt::MAX_WIN).contains(&self.win) {
            return Err(Error::usage(format!(
                "--win must be 3..={}, got {}",
                camgeom::klt::MAX_WIN,
                self.win
            )));
        }
        if !(1..=100).contains(&self.iters) {
            return Err(Error::usage(format!(
                "--iters must be 1..=100, got {}",
                self.iters
            )));
        }
        if !(self.eps.is_finite() && self.eps >= 0.0 && self.min_eig.is_finite()) {
            return Err(Error::usage(
                "--eps and --min-eig must be finite, --eps >= 0",
            ));
        }
        Ok(LkConfig {
            win: self.win,
            max_level: self.max_level.min(camgeom::pyramid::MAX_LEVELS - 1),
            max_iter: self.iters,
            epsilon: self.eps,
            min_eigenvalue: self.min_eig,
            use_initial_flow: false,
            fb_threshold: self.fb,
            // The CLI reports each point's error.
            compute_error: true,
        })
    }
    fn path(&self) -> Path {
        if self.fixed { Path::Fixed } else { Path::F32 }
    }
}

#[derive(Args, Debug)]
pub struct FlowArgs {
    /// The first frame (PNG or JPEG; colour is converted to grey).
    #[arg(long, value_name = "A.png")]
    from: PathBuf,
    /// The second frame, same size.
    #[arg(long, value_name = "B.png")]
    to: PathBuf,
    /// Points of the first frame, CSV rows `x,y` (optional header); `-` reads stdin.
    #[arg(long, value_name = "P.csv")]
    points: PathBuf,
    #[command(flatten)]
    lk: LkOpt,
    /// Print JSON (`{"points": [{"x": .., "y": .., "err": .., "status": "ok"}, ...]}`).
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
pub struct TrackArgs {
    /// Folder of frames (PNG/JPEG, tracked in file-name order) or a video file (MP4/AVI/MOV/MKV/WebM,
    /// decoded by ffmpeg one frame at a time).
    #[arg(long, visible_alias = "video", value_name = "DIR|VIDEO")]
    frames: PathBuf,
    /// Output CSV, rows `frame,id,x,y` (frame = 0-based index in name order); from a video
    /// `frame,t,id,x,y` with `t` the frame's time in seconds.
    #[arg(long, value_name = "tracks.csv")]
    out: PathBuf,
    /// Also write one PNG per frame with the tracks drawn (crosses and 10-frame trails), named
    /// for the frame's file (from a video: its index on six digits).
    #[arg(long, value_name = "DIR")]
    overlay: Option<PathBuf>,
    /// Most tracks kept (1..1024).
    #[arg(long, default_value_t = 300)]
    max_tracks: usize,
    /// Detect new features when fewer tracks than this remain (default: --max-tracks).
    #[arg(long)]
    replenish_below: Option<usize>,
    /// Corner quality level (goodFeaturesToTrack's qualityLevel).
    #[arg(long, default_value_t = 0.01)]
    quality: f32,
    /// Minimum distance between features, pixels.
    #[arg(long, default_value_t = 10)]
    min_distance: u32,
    #[command(flatten)]
    lk: LkOpt,
}

#[derive(Serialize)]
struct JsonPoint {
    x: Option<f64>,
    y: Option<f64>,
    err: Option<f64>,
    status: &'static str,
}

#[derive(Serialize)]
struct JsonPoints {
    points: Vec<JsonPoint>,
}

/// `ok` for tracked points, else the status in snake case (CLI.md).
fn status(s: FlowStatus) -> &'static str {
    match s {
        FlowStatus::Tracked => "ok",
        other => other.name(),
    }
}

/// `camgeom flow`: the CSV (or JSON) of the tracked points.
pub fn run_flow(a: &FlowArgs) -> Result<String> {
    let cfg = a.lk.config()?;
    let pts = read_csv(&a.points, &["x", "y"])?;
    let pts: Vec<[f64; 2]> = pts.rows.iter().map(|r| [r[0], r[1]]).collect();
    let from = load_gray(&a.from)?;
    let to = load_gray(&a.to)?;
    require_size(&from, &a.from, a.lk.win, "the tracking window (--win)")?;
    if (from.width, from.height) != (to.width, to.height) {
        return Err(Error::new(
            &a.to,
            ErrorKind::Shape(format!(
                "{}x{} does not match {}: {}x{}",
                to.width,
                to.height,
                a.from.display(),
                from.width,
                from.height
            )),
        ));
    }
    let res = flow(&from, &to, &pts, &cfg, a.lk.path()).map_err(|e| {
        Error::camgeom(
            format!("{} -> {}: flow failed", a.from.display(), a.to.display()),
            e,
        )
    })?;
    let f32_out = a.lk.path() == Path::F32;
    let num = |v: f64| {
        if f32_out {
            format_float(v as f32)
        } else {
            format_float(v)
        }
    };
    if a.json {
        let points = res
            .iter()
            .map(|p| {
                let ok = p.status == FlowStatus::Tracked;
                JsonPoint {
                    x: ok.then_some(p.x),
                    y: ok.then_some(p.y),
                    err: ok.then_some(p.err),
                    status: status(p.status),
                }
            })
            .collect();
        return Ok(to_json(&JsonPoints { points }));
    }
    let rows = res.iter().map(|p| {
        if p.status == FlowStatus::Tracked {
            [num(p.x), num(p.y), "ok".to_string()]
        } else {
            [
                "nan".to_string(),
                "nan".to_string(),
                status(p.status).to_string(),
            ]
        }
    });
    Ok(format_csv(&["x", "y", "status"], rows))
}

#[derive(Serialize)]
struct TrackSummary {
    frames: usize,
    /// The video's frame rate (null for a folder).
    fps: Option<f64>,
    tracks: usize,
    rows: usize,
    out: String,
}

/// Why `track` stopped: reading a frame, or the tracker.
enum Failed {
    Frames(Error),
    Tracker(camgeom::Error),
}

impl From<camgeom::Error> for Failed {
    fn from(e: camgeom::Error) -> Self {
        Self::Tracker(e)
    }
}

/// `camgeom track`: writes the CSV (and overlays), prints a JSON summary.
pub fn run_track(a: &TrackArgs) -> Result<String> {
    let lk = a.lk.config()?;
    if !(1..=1024).contains(&a.max_tracks) {
        return Err(Error::usage(format!(
            "--max-tracks must be 1..=1024, got {}",
            a.max_tracks
        )));
    }
    if !(a.quality > 0.0 && a.quality <= 1.0) {
        return Err(Error::usage(format!(
            "--quality must be in (0, 1], got {}",
            a.quality
        )));
    }
    let mut source = FrameSource::open(&a.frames, false)?;
    let (fps, timed) = (source.fps(), source.is_video());
    let bar = progress_bar(source.len() as u64);
    let cfg = TrackerConfig {
        lk,
        corners: CornerConfig {
            quality: a.quality,
            min_distance: a.min_distance,
            max_corners: a.max_tracks,
        },
        replenish_below: a.replenish_below.unwrap_or(a.max_tracks),
        max_tracks: a.max_tracks,
    };
    if let Some(dir) = &a.overlay {
        create_dir(dir)?;
    }
    bar.set_message("tracking");
    // What each frame's rows need from the frame after the tracker has seen it.
    let names: std::cell::RefCell<Vec<(String, Option<f64>)>> = Default::default();
    let mut history: Vec<Vec<TrackRow>> = Vec::new();
    let mut overlay_err = None;
    let frames = std::iter::from_fn(|| source.next_frame().transpose()).map(|f| {
        f.and_then(|Frame { name, t, gray, .. }| {
            require_size(&gray, &a.frames, a.lk.win, "the tracking window (--win)")?;
            names.borrow_mut().push((name, t));
            Ok(gray)
        })
        .map_err(Failed::Frames)
    });
    let tracked = track_stream(frames, &cfg, a.lk.path(), |_, img, now| {
        bar.inc(1);
        let Some(dir) = &a.overlay else { return };
        history.push(now.to_vec());
        let old = history.len().saturating_sub(11);
        let past = history.get(old).cloned().unwrap_or_default();
        let drawn = overlay(img, now, &past);
        let name = names
            .borrow()
            .last()
            .map_or_else(String::new, |n| n.0.clone());
        if let Err(e) = save_gray(&drawn, dir.join(format!("{name}.png"))) {
            overlay_err.get_or_insert(e);
        }
    });
    bar.finish_and_clear();
    let rows = tracked.map_err(|e| match e {
        Failed::Frames(e) => e,
        Failed::Tracker(e) => Error::camgeom(format!("{}: tracking failed", a.frames.display()), e),
    })?;
    if let Some(e) = overlay_err {
        return Err(e);
    }
    let names = names.into_inner();
    let mut columns = vec!["frame", "id", "x", "y"];
    if timed {
        columns.insert(1, "t");
    }
    let csv = format_csv(
        &columns,
        rows.iter().map(|r| {
            let mut row = vec![r.frame.to_string()];
            if timed {
                let t = names.get(r.frame).and_then(|n| n.1);
                row.push(t.map_or_else(|| "nan".to_string(), |t| format!("{t:.6}")));
            }
            row.extend([r.id.to_string(), format_float(r.x), format_float(r.y)]);
            row
        }),
    );
    write_file(&a.out, csv)?;
    let ids: std::collections::BTreeSet<u32> = rows.iter().map(|r| r.id).collect();
    Ok(to_json(&TrackSummary {
        frames: names.len(),
        fps,
        tracks: ids.len(),
        rows: rows.len(),
        out: a.out.display().to_string(),
    }))
}
