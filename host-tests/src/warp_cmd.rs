//! `camgeom warp`: paste a logo into a frame inside a quadrilateral (OpenCV's
//! `warpPerspective(logo, getPerspectiveTransform(logo corners, quad), frame size,
//! INTER_LINEAR, BORDER_TRANSPARENT)` over the frame).
//!
//! Input: `--logo L.png`, `--frame F.png` (PNG or JPEG; colour is converted to grey with
//! OpenCV's weights), `--corners C.csv`: four rows `x,y` (optional header), the frame pixels
//! where the logo's corner pixel centres `(0, 0)`, `(w-1, 0)`, `(w-1, h-1)`, `(0, h-1)` go.
//! Output: the grey frame with the logo warped in, written to `--out O.png`; stdout gets JSON
//! `{"H": [9 numbers, row-major], "written": N, "arithmetic": "float" | "fixed"}`. A quadrilateral
//! camgeom rejects (NaN, three collinear corners, a fold or a non-convex quadrilateral) is an
//! input error: status 2 and one line naming the error (`degenerate`, `non_finite`, ...).

use std::path::PathBuf;

use camgeom::arith::Fixed;
use camgeom::homography::Homography;
use camgeom::nalgebra::Point2;
use camgeom::warp::{WarpConfig, warp_into_quad};
use camgeom_host::images::{load_gray, save_gray};
use camgeom_host::points::{read_csv, to_json};
use camgeom_host::{Error, ErrorKind, Result};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct WarpArgs {
    /// The image to paste (PNG or JPEG).
    #[arg(long, value_name = "L.png")]
    pub logo: PathBuf,
    /// The frame to paste it into (PNG or JPEG).
    #[arg(long, value_name = "F.png")]
    pub frame: PathBuf,
    /// Four rows `x,y` (optional header): where the logo's top-left, top-right, bottom-right
    /// and bottom-left corner pixel centres go in the frame; `-` reads stdin.
    #[arg(long, value_name = "C.csv")]
    pub corners: PathBuf,
    /// Output image (PNG, or JPEG for .jpg).
    #[arg(long, value_name = "O.png")]
    pub out: PathBuf,
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

/// Runs the subcommand: writes the image, returns the JSON result.
pub fn run(a: &WarpArgs) -> Result<String> {
    let logo = load_gray(&a.logo)?;
    let mut frame = load_gray(&a.frame)?;
    let table = read_csv(&a.corners, &["x", "y"])?;
    if table.rows.len() != 4 {
        return Err(Error::new(
            &a.corners,
            ErrorKind::Shape(format!(
                "expected 4 corner rows (x,y), found {}",
                table.rows.len()
            )),
        ));
    }
    let quad: [Point2<f32>; 4] =
        core::array::from_fn(|i| Point2::new(table.rows[i][0] as f32, table.rows[i][1] as f32));
    let fail = |what: &str, e: camgeom::Error| {
        Error::camgeom(format!("{}: {what} failed", a.corners.display()), e)
    };
    let (w, h) = ((logo.width - 1) as f64, (logo.height - 1) as f64);
    let src = [
        Point2::new(0.0, 0.0),
        Point2::new(w, 0.0),
        Point2::new(w, h),
        Point2::new(0.0, h),
    ];
    let hom = Homography::<f64>::from_four_points(&src, &quad.map(|p| p.cast::<f64>()))
        .map_err(|e| fail("from_four_points", e))?;
    let config = WarpConfig { alpha: a.alpha };
    let too_big = |p: &PathBuf| Error::new(p, ErrorKind::Unsupported("the image size".into()));
    let logo_view = logo.view().ok_or_else(|| too_big(&a.logo))?;
    let mut frame_view = frame.view_mut().ok_or_else(|| too_big(&a.frame))?;
    let report = if a.fixed {
        warp_into_quad::<Fixed>(&logo_view, &mut frame_view, &quad, &config)
    } else {
        warp_into_quad::<f32>(&logo_view, &mut frame_view, &quad, &config)
    }
    .map_err(|e| fail("warp", e))?;
    save_gray(&frame, &a.out)?;
    let m = hom.matrix();
    let out = WarpOutput {
        h: core::array::from_fn(|k| m[(k / 3, k % 3)]),
        written: report.written,
        arithmetic: if a.fixed { "fixed" } else { "float" },
    };
    Ok(to_json(&out))
}
