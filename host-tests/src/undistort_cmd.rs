//! `camgeom undistort`: remove the lens distortion from an image (OpenCV's
//! `getOptimalNewCameraMatrix` / `fisheye::estimateNewCameraMatrixForUndistortRectify`, then
//! `initUndistortRectifyMap` (`CV_16SC2`) and `remap` (`INTER_LINEAR`, `BORDER_CONSTANT` 0)),
//! at any frame size, grey or colour.
//!
//! The map is camgeom's [`WideEntry`] map (OpenCV's own `CV_16SC2` + `CV_16UC1` form, frames
//! up to 32767 px, 6 bytes a pixel) at every size: on frames the board's Q10.5 map addresses
//! (up to 1023 px) it gives the same pixels (the core's tests) at the same speed. A colour
//! image is remapped one channel plane at a time through the one map.

use std::path::PathBuf;
use std::time::Instant;

use camgeom::camera::LensModel;
use camgeom::image::{ImageMut, ImageView};
use camgeom::remap::{MapEntry, WideEntry, build_map, map_len, new_camera_matrix, remap};
use camgeom_host::cli::args::CameraArg;
use camgeom_host::images::{GrayImage, GrayOrRgb, load_gray_or_rgb, save_gray, save_rgb};
use camgeom_host::points::to_json;
use camgeom_host::{Error, ErrorKind, Result, load_camera};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct UndistortArgs {
    #[command(flatten)]
    camera: CameraArg,
    /// The image (PNG/JPEG; grey or colour, 16-bit read by the high byte, alpha ignored), of
    /// the size the camera was calibrated at.
    #[arg(long, value_name = "IMAGE")]
    image: PathBuf,
    /// The undistorted image, grey or colour as the input (PNG; `.jpg` writes JPEG).
    #[arg(long, value_name = "OUT.png")]
    out: PathBuf,
    /// Brown-Conrady cameras: 0 keeps only valid pixels, 1 keeps every source pixel
    /// (`getOptimalNewCameraMatrix`'s alpha). Default 0.
    #[arg(long, value_name = "A", allow_negative_numbers = true)]
    alpha: Option<f64>,
    /// Fisheye cameras: 0 the focal length that keeps only valid pixels, 1 the one that keeps
    /// the whole field (`estimateNewCameraMatrixForUndistortRectify`'s balance). Default 0.
    #[arg(long, value_name = "B", allow_negative_numbers = true)]
    balance: Option<f64>,
}

#[derive(Serialize)]
struct Summary {
    new_camera_matrix: [f64; 9],
    width: usize,
    height: usize,
    /// 1 (grey) or 3 (colour), as the input and the output.
    channels: usize,
    model: &'static str,
    alpha: Option<f64>,
    balance: Option<f64>,
    out: String,
    /// Wall time, seconds: building the map, then remapping (every channel).
    seconds: [f64; 2],
}

/// `camgeom undistort`: writes the image, prints the new camera matrix as JSON.
pub fn run(a: &UndistortArgs) -> Result<String> {
    let spec = load_camera(&a.camera.intrinsics)?;
    let fisheye = spec.camera.lens.model() == LensModel::KannalaBrandt;
    let (name, value) = match (fisheye, a.alpha, a.balance) {
        (false, _, Some(_)) => {
            return Err(Error::usage(
                "--balance is for fisheye cameras; this camera is Brown-Conrady: use --alpha",
            ));
        }
        (true, Some(_), _) => {
            return Err(Error::usage(
                "--alpha is for Brown-Conrady cameras; this camera is a fisheye: use --balance",
            ));
        }
        (false, alpha, None) => ("--alpha", alpha.unwrap_or(0.0)),
        (true, None, balance) => ("--balance", balance.unwrap_or(0.0)),
    };
    if !(0.0..=1.0).contains(&value) {
        return Err(Error::usage(format!(
            "{name} must be in [0, 1], got {value}"
        )));
    }
    let img = load_gray_or_rgb(&a.image)?;
    let (w, h) = match &img {
        GrayOrRgb::Gray(g) => (g.width, g.height),
        GrayOrRgb::Rgb(c) => (c.width() as usize, c.height() as usize),
    };
    if let Some((cw, ch)) = spec.image_size
        && (cw as usize, ch as usize) != (w, h)
    {
        return Err(Error::new(
            &a.image,
            ErrorKind::Shape(format!(
                "image is {w}x{h} but {} was calibrated at {cw}x{ch}",
                a.camera.intrinsics.display()
            )),
        ));
    }
    if w > WideEntry::MAX_DIM || h > WideEntry::MAX_DIM {
        return Err(Error::new(
            &a.image,
            ErrorKind::Unsupported(format!(
                "image is {w}x{h}; the map addresses at most {} pixels each way",
                WideEntry::MAX_DIM
            )),
        ));
    }
    let camera = &spec.camera;
    let k_new = new_camera_matrix(camera, w, h, value).map_err(|e| {
        Error::camgeom(
            format!("{}: new camera matrix", a.camera.intrinsics.display()),
            e,
        )
    })?;
    let t0 = Instant::now();
    let mut map = vec![WideEntry::INVALID; map_len(w, h)];
    build_map(camera, &k_new, w, h, &mut map)
        .map_err(|e| Error::camgeom(format!("{}: undistortion map", a.image.display()), e))?;
    let t_map = t0.elapsed().as_secs_f64();
    let remap_err = |e| Error::camgeom(format!("{}: remap", a.image.display()), e);
    let t1 = Instant::now();
    let out = match img {
        GrayOrRgb::Gray(g) => GrayOrRgb::Gray(remap_plane(&g, &map).map_err(remap_err)?),
        GrayOrRgb::Rgb(c) => {
            let mut out = vec![0u8; 3 * w * h];
            let (src, _) = c.as_raw().as_chunks::<3>();
            let (dst, _) = out.as_chunks_mut::<3>();
            let view = ImageView::packed(src, w, h).map_err(remap_err)?;
            let mut dview = ImageMut::packed(dst, w, h).map_err(remap_err)?;
            remap(&view, &map, &mut dview, 0).map_err(remap_err)?;
            GrayOrRgb::Rgb(
                image::RgbImage::from_raw(w as u32, h as u32, out).ok_or_else(|| {
                    Error::new(
                        &a.image,
                        ErrorKind::Shape("image size not supported".into()),
                    )
                })?,
            )
        }
    };
    let t_remap = t1.elapsed().as_secs_f64();
    let channels = match &out {
        GrayOrRgb::Gray(g) => {
            save_gray(g, &a.out)?;
            1
        }
        GrayOrRgb::Rgb(c) => {
            save_rgb(c, &a.out)?;
            3
        }
    };
    Ok(to_json(&Summary {
        new_camera_matrix: [
            k_new.fx(),
            k_new.skew(),
            k_new.cx(),
            0.0,
            k_new.fy(),
            k_new.cy(),
            0.0,
            0.0,
            1.0,
        ],
        width: w,
        height: h,
        channels,
        model: if fisheye {
            "kannala_brandt"
        } else {
            "brown_conrady"
        },
        alpha: (!fisheye).then_some(value),
        balance: fisheye.then_some(value),
        out: a.out.display().to_string(),
        seconds: [t_map, t_remap],
    }))
}

/// One grey plane through the map, border 0.
fn remap_plane<E: MapEntry>(src: &GrayImage, map: &[E]) -> camgeom::Result<GrayImage> {
    let mut out = GrayImage::filled(src.width, src.height, 0);
    let view = src.view().ok_or(camgeom::Error::InvalidImage)?;
    let mut dst = out.view_mut().ok_or(camgeom::Error::InvalidImage)?;
    remap(&view, map, &mut dst, 0)?;
    Ok(out)
}
