//! `camgeom apriltag`: AprilTag detection (and tag pose) on an image, a folder of frames or a
//! video.

use std::path::PathBuf;

use camgeom::apriltag::{Detection, Detector, PartialView};
use camgeom::nalgebra::Vector2;
use camgeom_host::apriltag::{
    Coords, HostWorkspace, JsonFrame, JsonPartial, JsonTag, detect, detector, draw_tags_on,
    families_list, json_tag, pose_inputs,
};
use camgeom_host::board::{JsonBoardPose, board_pose_json, load_board};
use camgeom_host::cli::files::create_dir;
use camgeom_host::cli::frames::{Frame, FrameSource};
use camgeom_host::images::GrayImage;
use camgeom_host::images::{load_gray_and_rgb, require_size};
use camgeom_host::intrinsics::load_camera;
use camgeom_host::points::to_json;
use camgeom_host::rgb::{Overlay, RgbImage};
use camgeom_host::video::VideoWriter;
use camgeom_host::{Error, Result};
use clap::Args;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["image", "frames"])))]
pub struct ApriltagArgs {
    /// One image (PNG/JPEG; colour is converted to grey).
    #[arg(long, value_name = "FILE")]
    image: Option<PathBuf>,
    /// A sequence: a folder of frames (every PNG/JPEG in it, in file-name order) or a video
    /// file (.mp4, .mov, .avi, .mkv, ..; decoded by ffmpeg one frame at a time).
    #[arg(long, visible_alias = "video", value_name = "DIR|VIDEO")]
    frames: Option<PathBuf>,
    /// Families to decode, comma-separated (at most 4): tag36h11, tag25h9, tag16h5,
    /// tagStandard41h12, and OpenCV's ArUco dictionaries DICT_4X4_50, DICT_4X4_100,
    /// DICT_4X4_250, DICT_4X4_1000, DICT_5X5_*, DICT_6X6_*, DICT_7X7_* (the same sizes),
    /// DICT_ARUCO_ORIGINAL, DICT_ARUCO_MIP_36h12 (OpenCV's ids; corners in OpenCV's order).
    /// Default: tag36h11, or the board's family with --board.
    #[arg(long, value_name = "F[,F..]")]
    family: Option<String>,
    /// Search quads on the frame point-sampled every D pixels (1..=8; decoding uses the full
    /// frame).
    #[arg(long, default_value_t = 1, value_name = "D")]
    decimate: u8,
    /// Bits corrected for AprilTag families (at most 3, and below half the family's
    /// distance: 2 for tag16h5). ArUco dictionaries correct OpenCV's default,
    /// ⌊0.6 maxCorrectionBits⌋.
    #[arg(long, default_value_t = 2, value_name = "N")]
    max_hamming: u8,
    /// Do not snap the quad's edges to the strongest gradient (AprilTag's `refine_edges = 0`,
    /// as its detection test runs).
    #[arg(long)]
    no_refine_edges: bool,
    /// A tag board file (JSON or YAML: an OpenCV GridBoard or a list of tags with their
    /// corners, see CLI.md): with --intrinsics, one pose of the board from every board tag
    /// seen once, under "board" (its family is decoded when --family does not name it).
    #[arg(long, value_name = "FILE", requires = "intrinsics")]
    board: Option<PathBuf>,
    /// Camera file (see `camgeom project --help`); with --tag-size, each tag's pose; with
    /// --board, the board's.
    #[arg(long, value_name = "FILE")]
    intrinsics: Option<PathBuf>,
    /// The tag's side (the black border's outer edge), in the unit the translation should
    /// have (metres, ...).
    #[arg(long, value_name = "S", allow_hyphen_values = true)]
    tag_size: Option<f32>,
    /// Print corners and H in AprilTag's (and pupil_apriltags') pixel coordinates, pixel
    /// centres at i + 0.5, instead of camgeom's (OpenCV's), centres at i.
    #[arg(long)]
    apriltag_coords: bool,
    /// Draw each tag's outline, id and corner 0 over the image (in colour when it is): a PNG
    /// file (with --image) or a folder of `<frame name>.png` (with --frames; `000123.png` for
    /// a video's frame 123), each written as soon as its frame is detected.
    #[arg(long, value_name = "OUT")]
    overlay: Option<PathBuf>,
    /// With --frames and --overlay: the overlay of every N-th frame only (frames 0, N, 2N, ..).
    #[arg(long, value_name = "N", default_value_t = 1, requires = "overlay",
          value_parser = clap::value_parser!(u32).range(1..))]
    overlay_every: u32,
    /// With --frames: every frame's overlay into a video (.mp4/.mov/.mkv: H.264; .avi:
    /// MPEG-4), at the input video's frame rate (--fps for a folder).
    #[arg(long, value_name = "OUT.mp4", requires = "frames")]
    video_out: Option<PathBuf>,
    /// Frame rate of --video-out for a folder of frames (a video keeps its own).
    #[arg(long, default_value_t = 30.0, value_name = "F")]
    fps: f64,
    /// With --frames: track the last frame's tags by detecting them where they must be (the
    /// core's `Detector::refine_detection` from their corners predicted from the last two
    /// frames, else `Detector::refine_partial` for a tag partly seen, reported with
    /// "partial", as the board's tag job tracks its tag); a full detection runs on the first
    /// frame, when a tag is not found again (or none was seen) and every --guard-every frames
    /// (a tracked tag that one misses is looked for where it must be).
    #[arg(long, requires = "frames")]
    track: bool,
    /// With --track: a full detection at least every N frames (new tags are found then).
    #[arg(long, default_value_t = 30, value_name = "N", requires = "track")]
    guard_every: usize,
}

/// The tags of the last frame and each corner's motion since the frame before (--track).
#[derive(Default)]
struct Tracked {
    last: Vec<(Detection, [Vector2<f32>; 4])>,
    since_full: usize,
}

/// A tag of a frame, and what was seen of it when only part was (--track).
type Found = (Detection, Option<PartialView>);

impl Tracked {
    /// This frame's tags: the last frame's found where they must be (whole, else partly
    /// seen), or a full detection (with, on a guard frame, the tracked tags it missed looked
    /// for where they must be).
    fn step(
        &mut self,
        det: &Detector,
        ws: &mut HostWorkspace,
        gray: &GrayImage,
        at: &std::path::Path,
        guard: usize,
    ) -> Result<Vec<Found>> {
        let view = gray.view().ok_or_else(|| {
            Error::camgeom(format!("{}", at.display()), camgeom::Error::InvalidImage)
        })?;
        // Where a tag of the last frame must be: found whole, else partly seen.
        let again = |d: &Detection, motion: &[Vector2<f32>; 4]| -> Option<Found> {
            let mut p = d.target_corners();
            for (p, m) in p.iter_mut().zip(motion) {
                *p += m;
            }
            if let Some(whole) = det.refine_detection(&view, d.family, d.id, &p) {
                return Some((whole, None));
            }
            let part = det.refine_partial(&view, d.family, d.id, &p).ok()?;
            Some((part.detection, Some(part.view)))
        };
        let due = self.since_full + 1 >= guard.max(1);
        let mut found = Vec::new();
        if !self.last.is_empty() && !due {
            for (d, motion) in &self.last {
                match again(d, motion) {
                    Some(f) => found.push(f),
                    None => {
                        found.clear();
                        break;
                    }
                }
            }
        }
        if found.is_empty() {
            found = detect(det, ws, gray, at)?
                .into_iter()
                .map(|d| (d, None))
                .collect();
            // The guard's detection missed a tag that was tracked: it is looked for where it
            // must be (as the AR loop's guard does).
            if due {
                for (d, motion) in &self.last {
                    let seen = found
                        .iter()
                        .any(|(f, _)| std::ptr::eq(f.family, d.family) && f.id == d.id);
                    if !seen && let Some(f) = again(d, motion) {
                        found.push(f);
                    }
                }
            }
            self.since_full = 0;
        } else {
            self.since_full += 1;
        }
        self.last = found
            .iter()
            .map(|(d, _)| {
                let before = self
                    .last
                    .iter()
                    .find(|(o, _)| std::ptr::eq(o.family, d.family) && o.id == d.id);
                let mut motion = [Vector2::zeros(); 4];
                if let Some((o, _)) = before {
                    for ((m, a), b) in motion
                        .iter_mut()
                        .zip(d.target_corners())
                        .zip(o.target_corners())
                    {
                        *m = a - b;
                    }
                }
                (*d, motion)
            })
            .collect();
        Ok(found)
    }
}

/// A frame of the JSON with --frames: the frame's detections, with its index and time for a
/// video (`image` then absent).
#[derive(serde::Serialize)]
struct SeqFrame {
    #[serde(skip_serializing_if = "Option::is_none")]
    frame: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    t: Option<f64>,
    #[serde(flatten)]
    detections: WithBoard,
}

/// A frame's JSON and, with --board, the board pose.
#[derive(serde::Serialize)]
struct WithBoard {
    #[serde(flatten)]
    frame: JsonFrame,
    #[serde(skip_serializing_if = "Option::is_none")]
    board: Option<JsonBoardPose>,
}

/// The smallest image side the detector can find a tag in: tag16h5 is 8 cells across with its
/// black and white borders (the other families have more), at one pixel a cell.
pub const MIN_SIDE: usize = 8;

/// `camgeom apriltag`: the JSON (one object with --image; with --frames, `{"frames": [..]}`
/// holding one of them a frame, and `"fps"` for a video). A sequence is read one frame at a
/// time; the overlay folder is made when the first overlay is written, so an error on the
/// first frame leaves no output.
pub fn run(a: &ApriltagArgs) -> Result<String> {
    let board = a.board.as_deref().map(load_board).transpose()?;
    let mut families = match (&a.family, &board) {
        (Some(list), _) => families_list(list)?,
        (None, Some(b)) => vec![b.family],
        (None, None) => families_list("tag36h11")?,
    };
    if let Some(b) = &board
        && !families.iter().any(|f| f.name() == b.family.name())
    {
        families.push(b.family);
    }
    let det = detector(&families, a.decimate, a.max_hamming, !a.no_refine_edges)?;
    // With --board, --intrinsics alone is the board's camera; --tag-size adds each tag's pose.
    let board = match (board, &a.intrinsics) {
        (Some(b), Some(path)) => Some((b, load_camera(path)?.camera)),
        _ => None,
    };
    let pose = if board.is_some() && a.tag_size.is_none() {
        None
    } else {
        pose_inputs(a.tag_size, a.intrinsics.as_deref())?
    };
    let board_json = |found: &[Detection]| {
        board
            .as_ref()
            .map(|(b, camera)| board_pose_json(b, found, camera).0)
    };
    let coords = if a.apriltag_coords {
        Coords::AprilTag
    } else {
        Coords::Camgeom
    };
    let mut ws: Box<HostWorkspace> = Box::default();
    let colour = a.overlay.is_some() || a.video_out.is_some();
    // One image: its JSON object, its overlay.
    if let (Some(f), None) = (&a.image, &a.frames) {
        let (gray, rgb) = load_gray_and_rgb(f)?;
        require_size(&gray, f, MIN_SIDE, "the smallest tag AprilTag can find")?;
        let found = detect(&det, &mut ws, &gray, f)?;
        if let Some(out) = &a.overlay {
            let canvas = rgb.unwrap_or_else(|| RgbImage::from_gray(&gray));
            draw_tags_on(canvas, &found).save_png(out)?;
        }
        return Ok(to_json(&WithBoard {
            frame: JsonFrame {
                image: None,
                detections: found
                    .iter()
                    .map(|d| json_tag(d, coords, pose.as_ref()))
                    .collect(),
                width: gray.width,
                height: gray.height,
            },
            board: board_json(&found),
        }));
    }
    let Some(input) = &a.frames else {
        return Err(Error::usage("give one of --image and --frames"));
    };
    if !(a.fps.is_finite() && a.fps > 0.0) {
        return Err(Error::usage(format!(
            "--fps must be positive, got {}",
            a.fps
        )));
    }
    // A sequence: frames detected one at a time, each overlay written (and dropped) as soon
    // as it is drawn; only the JSON is kept.
    let mut source = FrameSource::open(input, colour)?.any_size();
    let every = usize::try_from(a.overlay_every).unwrap_or(usize::MAX);
    let rate = source.fps().unwrap_or(a.fps);
    let video = source.is_video();
    let mut writer: Option<VideoWriter> = None;
    let mut frames = Vec::with_capacity(source.len());
    let mut tracked = Tracked::default();
    while let Some(frame) = source.next_frame()? {
        let Frame {
            index,
            name,
            file,
            t,
            gray,
            rgb,
        } = frame;
        let at = file.clone().unwrap_or_else(|| input.clone());
        require_size(&gray, &at, MIN_SIDE, "the smallest tag AprilTag can find")?;
        let (found, views): (Vec<Detection>, Vec<Option<PartialView>>) = if a.track {
            tracked
                .step(&det, &mut ws, &gray, &at, a.guard_every)?
                .into_iter()
                .unzip()
        } else {
            detect(&det, &mut ws, &gray, &at)?
                .into_iter()
                .map(|d| (d, None))
                .unzip()
        };
        let png = a.overlay.as_ref().filter(|_| index.is_multiple_of(every));
        if png.is_some() || a.video_out.is_some() {
            let canvas = rgb.unwrap_or_else(|| RgbImage::from_gray(&gray));
            let img = draw_tags_on(canvas, &found);
            if let Some(dir) = png {
                if index == 0 {
                    create_dir(dir)?;
                }
                img.save_png(dir.join(format!("{name}.png")))?;
            }
            if let Some(path) = &a.video_out {
                if writer.is_none() {
                    writer = Some(VideoWriter::create(path, img.width(), img.height(), rate)?);
                }
                if let Some(w) = writer.as_mut() {
                    w.write(&img)?;
                }
            }
        }
        frames.push(SeqFrame {
            frame: video.then_some(index),
            t,
            detections: WithBoard {
                frame: JsonFrame {
                    image: file.map(|f| f.display().to_string()),
                    detections: found
                        .iter()
                        .zip(&views)
                        .map(|(d, v)| JsonTag {
                            partial: v.as_ref().map(JsonPartial::new),
                            ..json_tag(d, coords, pose.as_ref())
                        })
                        .collect(),
                    width: gray.width,
                    height: gray.height,
                },
                board: board_json(&found),
            },
        });
    }
    if let Some(w) = writer {
        w.finish()?;
    }
    // One top-level object either way (CLI.md's convention): the frames under "frames", and
    // for a video its frame rate.
    #[derive(serde::Serialize)]
    struct Frames<'a> {
        #[serde(skip_serializing_if = "Option::is_none")]
        fps: Option<f64>,
        frames: &'a [SeqFrame],
    }
    Ok(to_json(&Frames {
        fps: video.then_some(rate),
        frames: &frames,
    }))
}
