//! `camgeom undistort`: remove the lens distortion from an image (OpenCV's
//! `getOptimalNewCameraMatrix` / `fisheye::estimateNewCameraMatrixForUndistortRectify`, then
//! `initUndistortRectifyMap` (`CV_16SC2`) and `remap` (`INTER_LINEAR`, `BORDER_CONSTANT` 0)).

use std::path::PathBuf;

use camgeom::camera::LensModel;
use camgeom::remap::{MAX_MAP_DIM, build_map, map_len, new_camera_matrix, remap};
use camgeom_host::cli::args::CameraArg;
use camgeom_host::images::{GrayImage, load_gray, save_gray};
use camgeom_host::points::to_json;
use camgeom_host::{Error, ErrorKind, Result, load_camera};
use clap::Args;
use serde::Serialize;

#[derive(Args, Debug)]
pub struct UndistortArgs {
    #[command(flatten)]
    camera: CameraArg,
    /// The image (PNG/JPEG, converted to grey), of the size the camera was calibrated at.
    #[arg(long, value_name = "IMAGE")]
    image: PathBuf,
    /// The undistorted image (PNG; `.jpg` writes JPEG).
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
    model: &'static str,
    alpha: Option<f64>,
    balance: Option<f64>,
    out: String,
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
    let img = load_gray(&a.image)?;
    let (w, h) = (img.width, img.height);
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
    if w > MAX_MAP_DIM || h > MAX_MAP_DIM {
        return Err(Error::new(
            &a.image,
            ErrorKind::Unsupported(format!(
                "image is {w}x{h}; the fixed-point map addresses at most {MAX_MAP_DIM} pixels \
                 each way"
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
    let mut map = vec![[0i16; 2]; map_len(w, h)];
    build_map(camera, &k_new, w, h, &mut map)
        .map_err(|e| Error::camgeom(format!("{}: undistortion map", a.image.display()), e))?;
    let mut out = GrayImage::filled(w, h, 0);
    let (Some(src), Some(mut dst)) = (img.view(), out.view_mut()) else {
        return Err(Error::new(
            &a.image,
            ErrorKind::Shape("image size not supported".into()),
        ));
    };
    remap(&src, &map, &mut dst, 0)
        .map_err(|e| Error::camgeom(format!("{}: remap", a.image.display()), e))?;
    save_gray(&out, &a.out)?;
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
        model: if fisheye {
            "kannala_brandt"
        } else {
            "brown_conrady"
        },
        alpha: (!fisheye).then_some(value),
        balance: fisheye.then_some(value),
        out: a.out.display().to_string(),
    }))
}
