//! `camgeom apriltag`: AprilTag detection (and tag pose) on an image or a folder of frames.

use std::path::{Path, PathBuf};

use camgeom_host::apriltag::{
    Coords, HostWorkspace, JsonFrame, detect, detector, draw_tags, families_list, json_tag,
    pose_inputs,
};
use camgeom_host::cli::files::create_dir;
use camgeom_host::cli::frames::frame_files;
use camgeom_host::images::{load_gray, require_size};
use camgeom_host::points::to_json;
use camgeom_host::rgb::Overlay;
use camgeom_host::{Error, Result};
use clap::Args;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["image", "frames"])))]
pub struct ApriltagArgs {
    /// One image (PNG/JPEG; colour is converted to grey).
    #[arg(long, value_name = "FILE")]
    image: Option<PathBuf>,
    /// A folder of frames: every PNG/JPEG in it, in file-name order.
    #[arg(long, value_name = "DIR")]
    frames: Option<PathBuf>,
    /// Families to decode, comma-separated: tag36h11, tag25h9, tag16h5, tagStandard41h12.
    #[arg(long, default_value = "tag36h11", value_name = "F[,F..]")]
    family: String,
    /// Search quads on the frame point-sampled every D pixels (1..=8; decoding uses the full
    /// frame).
    #[arg(long, default_value_t = 1, value_name = "D")]
    decimate: u8,
    /// Bits corrected (at most 3, and below half the family's distance: 2 for tag16h5).
    #[arg(long, default_value_t = 2, value_name = "N")]
    max_hamming: u8,
    /// Do not snap the quad's edges to the strongest gradient (AprilTag's `refine_edges = 0`,
    /// as its detection test runs).
    #[arg(long)]
    no_refine_edges: bool,
    /// Camera file (see `camgeom project --help`); with --tag-size, each tag's pose.
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
    /// Draw each tag's outline, id and corner 0 over the image: a PNG file (with --image) or
    /// a folder of `<frame name>.png` (with --frames).
    #[arg(long, value_name = "OUT")]
    overlay: Option<PathBuf>,
}

/// `camgeom apriltag`: the JSON (one object with --image; with --frames, `{"frames": [..]}`
/// holding one of them a frame).
/// Every frame is detected before anything is written.
/// The smallest image side the detector can find a tag in: tag16h5 is 8 cells across with its
/// black and white borders (the other families have more), at one pixel a cell.
pub const MIN_SIDE: usize = 8;

pub fn run(a: &ApriltagArgs) -> Result<String> {
    let families = families_list(&a.family)?;
    let det = detector(&families, a.decimate, a.max_hamming, !a.no_refine_edges)?;
    let pose = pose_inputs(a.tag_size, a.intrinsics.as_deref())?;
    let coords = if a.apriltag_coords {
        Coords::AprilTag
    } else {
        Coords::Camgeom
    };
    let (files, single) = match (&a.image, &a.frames) {
        (Some(f), None) => (vec![f.clone()], true),
        (None, Some(dir)) => (frame_files(dir)?, false),
        _ => return Err(Error::usage("give one of --image and --frames")),
    };
    let mut ws: Box<HostWorkspace> = Box::default();
    let mut frames = Vec::with_capacity(files.len());
    let mut overlays = Vec::new();
    for f in &files {
        let img = load_gray(f)?;
        require_size(&img, f, MIN_SIDE, "the smallest tag AprilTag can find")?;
        let found = detect(&det, &mut ws, &img, f)?;
        if a.overlay.is_some() {
            overlays.push(draw_tags(&img, &found));
        }
        frames.push(JsonFrame {
            image: (!single).then(|| f.display().to_string()),
            detections: found
                .iter()
                .map(|d| json_tag(d, coords, pose.as_ref()))
                .collect(),
            width: img.width,
            height: img.height,
        });
    }
    if let Some(out) = &a.overlay {
        if single {
            overlays[0].save_png(out)?;
        } else {
            create_dir(out)?;
            for (f, img) in files.iter().zip(&overlays) {
                img.save_png(out.join(overlay_name(f)))?;
            }
        }
    }
    // One top-level object either way (CLI.md's convention): the frames under "frames".
    #[derive(serde::Serialize)]
    struct Frames<'a> {
        frames: &'a [JsonFrame],
    }
    Ok(if single {
        to_json(&frames[0])
    } else {
        to_json(&Frames { frames: &frames })
    })
}

/// `<stem>.png` of a frame.
fn overlay_name(f: &Path) -> String {
    let stem = f
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!("{stem}.png")
}
