//! `camgeom warp`: paste a logo into a frame inside a quadrilateral (OpenCV's
//! `warpPerspective(logo, getPerspectiveTransform(logo corners, quad), frame size,
//! INTER_LINEAR, BORDER_TRANSPARENT)` over the frame), or into every frame of a sequence.
//!
//! One frame: `--logo L.png`, `--frame F.png` (PNG or JPEG), `--corners C.csv`: four rows
//! `x,y` (optional header), the frame pixels where the logo's corner pixel centres `(0, 0)`,
//! `(w-1, 0)`, `(w-1, h-1)`, `(0, h-1)` go. Output: the frame with the logo warped in, written
//! to `--out O.png`; stdout gets JSON `{"H": [9 numbers, row-major], "written": N,
//! "arithmetic": "float" | "fixed"}`.
//!
//! A sequence: `--frames DIR|VIDEO` (`--video` is the same option) and `--corners-per-frame
//! C.csv`, rows `frame,x0,y0,x1,y1,x2,y2,x3,y3` (optional header; the four corners in the
//! order above, `frame` the 0-based index). Output: `--out` a folder of `<frame name>.png`, or
//! a video file (`.mp4`, `.mov`, `.mkv`, `.avi`) at the input's frame rate. A frame without a
//! row is written unchanged, and counted in the JSON.
//!
//! Colour stays colour: a colour frame or a colour logo gives a colour output, each channel
//! warped by the core's `warp_into_quad` (a grey logo is pasted as grey into a colour frame);
//! grey in both gives grey. A quadrilateral camgeom rejects (NaN, three collinear corners, a
//! fold or a non-convex quadrilateral) is an input error: status 2 and one line naming the
//! error (`degenerate`, `non_finite`, ...) and, in a sequence, the frame.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use camgeom::arith::Fixed;
use camgeom::homography::Homography;
use camgeom::nalgebra::Point2;
use camgeom::warp::{WarpConfig, warp_into_quad};
use camgeom_host::cli::files::create_dir;
use camgeom_host::cli::frames::FrameSource;
use camgeom_host::images::{GrayImage, load_gray_and_rgb, save_gray};
use camgeom_host::points::{read_csv, to_json};
use camgeom_host::rgb::{Overlay, RgbImage};
use camgeom_host::video::{VideoWriter, is_video};
use camgeom_host::{Error, ErrorKind, Result};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["frame", "frames"])))]
pub struct WarpArgs {
    /// The image to paste (PNG or JPEG).
    #[arg(long, value_name = "L.png")]
    pub logo: PathBuf,
    /// The frame to paste it into (PNG or JPEG).
    #[arg(long, value_name = "F.png", requires = "corners")]
    pub frame: Option<PathBuf>,
    /// Four rows `x,y` (optional header): where the logo's top-left, top-right, bottom-right
    /// and bottom-left corner pixel centres go in the frame; `-` reads stdin.
    #[arg(long, value_name = "C.csv", conflicts_with = "frames")]
    pub corners: Option<PathBuf>,
    /// A sequence to paste the logo into, frame by frame: a folder of PNG/JPEG frames
    /// (file-name order) or a video file (decoded by ffmpeg one frame at a time).
    #[arg(
        long,
        visible_alias = "video",
        value_name = "DIR|VIDEO",
        requires = "corners_per_frame"
    )]
    pub frames: Option<PathBuf>,
    /// With --frames: rows `frame,x0,y0,x1,y1,x2,y2,x3,y3` (optional header), the logo's four
    /// corners (in --corners' order) in frame `frame` (0-based); a frame without a row is
    /// written unchanged.
    #[arg(long, value_name = "C.csv", requires = "frames")]
    pub corners_per_frame: Option<PathBuf>,
    /// Output: an image (PNG, or JPEG for .jpg) with --frame; with --frames, a folder of
    /// `<frame name>.png`, or a video (.mp4, .mov, .mkv, .avi).
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
    /// Frame rate of a video --out from a folder of frames (a video keeps its own).
    #[arg(long, default_value_t = 30.0, value_name = "F")]
    pub fps: f64,
    /// Opacity of the logo, 0..=255 (255 replaces the frame's pixels).
    #[arg(long, default_value_t = 255)]
    pub alpha: u8,
    /// Integer per-pixel arithmetic (the FPU-less firmware path) instead of f32.
    #[arg(long)]
    pub fixed: bool,
}

#[derive(Serialize)]
struct WarpOutput {
    #[serde(rename = "H")]
    h: [f64; 9],
    written: u32,
    arithmetic: &'static str,
}

/// The logo, in grey and (when it is in colour) in colour.
struct Logo {
    gray: GrayImage,
    rgb: Option<RgbImage>,
}

/// A frame being warped into: grey, or colour.
enum Canvas {
    Gray(GrayImage),
    Rgb(RgbImage),
}

/// The three channels of `img` as grey planes.
fn planes(img: &RgbImage) -> [GrayImage; 3] {
    let (w, h) = (img.width() as usize, img.height() as usize);
    std::array::from_fn(|c| GrayImage {
        data: img.pixels().map(|p| p.0[c]).collect(),
        width: w,
        height: h,
    })
}

/// Runs the subcommand: writes the image(s), returns the JSON result.
pub fn run(a: &WarpArgs) -> Result<String> {
    let (gray, rgb) = load_gray_and_rgb(&a.logo)?;
    let logo = Logo { gray, rgb };
    match (&a.frame, &a.corners, &a.frames, &a.corners_per_frame) {
        (Some(frame), Some(corners), None, None) => one_frame(a, &logo, frame, corners),
        (None, None, Some(frames), Some(corners)) => sequence(a, &logo, frames, corners),
        _ => Err(Error::usage(
            "give --frame with --corners, or --frames with --corners-per-frame",
        )),
    }
}

/// The homography from the logo's corner pixel centres to `quad`.
fn homography(logo: &GrayImage, quad: &[Point2<f32>; 4]) -> camgeom::Result<Homography<f64>> {
    let (w, h) = ((logo.width - 1) as f64, (logo.height - 1) as f64);
    let src = [
        Point2::new(0.0, 0.0),
        Point2::new(w, 0.0),
        Point2::new(w, h),
        Point2::new(0.0, h),
    ];
    Homography::<f64>::from_four_points(&src, &quad.map(|p| p.cast::<f64>()))
}

/// Warps the logo into `canvas` inside `quad`, channel by channel for a colour canvas; the
/// pixels written (of one channel).
fn paste(
    logo: &Logo,
    canvas: &mut Canvas,
    quad: &[Point2<f32>; 4],
    config: &WarpConfig,
    fixed: bool,
) -> camgeom::Result<u32> {
    let one = |src: &GrayImage, dst: &mut GrayImage| {
        let s = src.view().ok_or(camgeom::Error::InvalidImage)?;
        let mut d = dst.view_mut().ok_or(camgeom::Error::InvalidImage)?;
        if fixed {
            warp_into_quad::<Fixed>(&s, &mut d, quad, config)
        } else {
            warp_into_quad::<f32>(&s, &mut d, quad, config)
        }
        .map(|r| r.written)
    };
    match canvas {
        Canvas::Gray(g) => one(&logo.gray, g),
        Canvas::Rgb(img) => {
            let mut dst = planes(img);
            let src = match &logo.rgb {
                Some(c) => planes(c),
                None => [logo.gray.clone(), logo.gray.clone(), logo.gray.clone()],
            };
            let mut written = 0;
            for (s, d) in src.iter().zip(dst.iter_mut()) {
                written = one(s, d)?;
            }
            for (p, i) in img.pixels_mut().zip(0..) {
                p.0 = [dst[0].data[i], dst[1].data[i], dst[2].data[i]];
            }
            Ok(written)
        }
    }
}

/// `--frame`: one image.
fn one_frame(a: &WarpArgs, logo: &Logo, frame: &Path, corners: &Path) -> Result<String> {
    let (gray, rgb) = load_gray_and_rgb(frame)?;
    let table = read_csv(corners, &["x", "y"])?;
    if table.rows.len() != 4 {
        return Err(Error::new(
            corners,
            ErrorKind::Shape(format!(
                "expected 4 corner rows (x,y), found {}",
                table.rows.len()
            )),
        ));
    }
    let quad: [Point2<f32>; 4] =
        core::array::from_fn(|i| Point2::new(table.rows[i][0] as f32, table.rows[i][1] as f32));
    let fail = |what: &str, e: camgeom::Error| {
        Error::camgeom(format!("{}: {what} failed", corners.display()), e)
    };
    let hom = homography(&logo.gray, &quad).map_err(|e| fail("from_four_points", e))?;
    let config = WarpConfig { alpha: a.alpha };
    let mut canvas = match (rgb, &logo.rgb) {
        (Some(c), _) => Canvas::Rgb(c),
        (None, Some(_)) => Canvas::Rgb(RgbImage::from_gray(&gray)),
        (None, None) => Canvas::Gray(gray),
    };
    let written = paste(logo, &mut canvas, &quad, &config, a.fixed).map_err(|e| fail("warp", e))?;
    match &canvas {
        Canvas::Gray(g) => save_gray(g, &a.out)?,
        Canvas::Rgb(c) => save_rgb(c, &a.out)?,
    }
    let m = hom.matrix();
    let out = WarpOutput {
        h: core::array::from_fn(|k| m[(k / 3, k % 3)]),
        written,
        arithmetic: if a.fixed { "fixed" } else { "float" },
    };
    Ok(to_json(&out))
}

/// A colour image as PNG (fast compression) or, for `.jpg`/`.jpeg`, JPEG.
fn save_rgb(img: &RgbImage, path: &Path) -> Result<()> {
    let jpeg = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "jpg" | "jpeg"));
    if !jpeg {
        return img.save_png(path);
    }
    img.save(path).map_err(|e| match e {
        image::ImageError::IoError(io) => Error::new(path, ErrorKind::Write(io)),
        other => Error::new(path, ErrorKind::Unsupported(other.to_string())),
    })
}

/// The rows of `--corners-per-frame`: frame index to quadrilateral.
fn read_quads(path: &Path) -> Result<BTreeMap<usize, [Point2<f32>; 4]>> {
    let cols = ["frame", "x0", "y0", "x1", "y1", "x2", "y2", "x3", "y3"];
    let table = read_csv(path, &cols)?;
    let mut quads = BTreeMap::new();
    for (row, line) in table.rows.iter().zip(&table.lines) {
        let k = row[0];
        if !(k >= 0.0 && k.fract() == 0.0 && k < u32::MAX as f64) {
            return Err(Error::at_line(
                path,
                *line,
                ErrorKind::Syntax(format!("frame must be a 0-based index, got {k}")),
            ));
        }
        let quad =
            core::array::from_fn(|i| Point2::new(row[1 + 2 * i] as f32, row[2 + 2 * i] as f32));
        if quads.insert(k as usize, quad).is_some() {
            return Err(Error::at_line(
                path,
                *line,
                ErrorKind::Shape(format!("frame {k} has a second row")),
            ));
        }
    }
    Ok(quads)
}

#[derive(Serialize)]
struct SequenceOutput {
    frames: usize,
    warped: usize,
    without_corners: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    fps: Option<f64>,
    /// Rows of the corners file for frames the sequence does not have.
    unused_rows: usize,
    out: String,
    arithmetic: &'static str,
}

/// `--frames`: the logo into every frame that has corners.
fn sequence(a: &WarpArgs, logo: &Logo, frames: &Path, corners: &Path) -> Result<String> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        return Err(Error::usage(format!(
            "--fps must be positive, got {}",
            a.fps
        )));
    }
    let quads = read_quads(corners)?;
    let mut source = FrameSource::open(frames, true)?;
    let rate = source.fps().unwrap_or(a.fps);
    let to_video = is_video(&a.out);
    if !to_video {
        create_dir(&a.out)?;
    }
    let config = WarpConfig { alpha: a.alpha };
    let mut writer: Option<VideoWriter> = None;
    let (mut count, mut warped) = (0usize, 0usize);
    while let Some(frame) = source.next_frame()? {
        let mut canvas = match (frame.rgb, &logo.rgb, to_video) {
            (Some(c), _, _) => Canvas::Rgb(c),
            (None, Some(_), _) | (None, None, true) => {
                Canvas::Rgb(RgbImage::from_gray(&frame.gray))
            }
            (None, None, false) => Canvas::Gray(frame.gray),
        };
        if let Some(quad) = quads.get(&frame.index) {
            paste(logo, &mut canvas, quad, &config, a.fixed).map_err(|e| {
                Error::camgeom(
                    format!("{}: frame {}: warp failed", corners.display(), frame.index),
                    e,
                )
            })?;
            warped += 1;
        }
        count += 1;
        match (&canvas, to_video) {
            (Canvas::Rgb(c), true) => {
                if writer.is_none() {
                    writer = Some(VideoWriter::create(&a.out, c.width(), c.height(), rate)?);
                }
                if let Some(w) = writer.as_mut() {
                    w.write(c)?;
                }
            }
            (Canvas::Rgb(c), false) => c.save_png(a.out.join(format!("{}.png", frame.name)))?,
            (Canvas::Gray(g), _) => save_gray(g, a.out.join(format!("{}.png", frame.name)))?,
        }
    }
    if let Some(w) = writer {
        w.finish()?;
    }
    Ok(to_json(&SequenceOutput {
        frames: count,
        warped,
        without_corners: count - warped,
        fps: source.is_video().then_some(rate),
        unused_rows: quads.range(count..).count(),
        out: a.out.display().to_string(),
        arithmetic: if a.fixed { "fixed" } else { "float" },
    }))
}
