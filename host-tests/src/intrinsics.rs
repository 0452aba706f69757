//! Camera files: OpenCV calibration output (YAML or XML `FileStorage`) and camgeom's own small
//! JSON / TOML form, all read into a [`CameraSpec`].
//!
//! camgeom's form (JSON shown; TOML has the same keys):
//!
//! ```json
//! {"fx": 535.9, "fy": 535.9, "cx": 342.3, "cy": 235.6, "skew": 0.0,
//!  "distortion": [k1, k2, p1, p2, k3], "width": 640, "height": 480}
//! ```
//!
//! `skew` (default 0), `distortion` (default none) and `width`/`height` (given together) are
//! optional; unknown keys are errors, so a typo does not silently fall back to a default.
//!
//! Distortion coefficients follow OpenCV's order. 4 (`k3 = 0`) and 5 coefficients are read as
//! they are; OpenCV's 8-, 12- and 14-coefficient forms (rational `k4..k6`, thin prism `s1..s4`,
//! tilt `tx, ty`) are accepted only when every coefficient past the fifth is zero, because
//! camgeom models only `k1 k2 p1 p2 k3`.
//!
//! Fisheye (Kannala-Brandt, OpenCV's `cv::fisheye`) cameras: an OpenCV file with
//! `fisheye_model: 1` (as OpenCV's calibration tutorial and `camgeom calibrate --fisheye`
//! write it) holds the 4 coefficients `k1 k2 k3 k4` in `distortion_coefficients`; camgeom's
//! form gives them as `"fisheye": [k1, k2, k3, k4]` (and no `distortion`).

use std::path::Path;

use camgeom::camera::{Camera, Distortion, Fisheye, Intrinsics, Lens};
use serde::{Deserialize, Serialize};

use crate::error::{Error, ErrorKind, Result};
use crate::storage::{FileStorage, ext_display, extension, read_text};

/// A calibrated camera as read from a file: the camgeom camera (in `f64`, the precision of the
/// files) and the image size when the file gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSpec {
    /// The camera, `f64`.
    pub camera: Camera<f64>,
    /// `(width, height)` in pixels.
    pub image_size: Option<(u32, u32)>,
}

impl CameraSpec {
    /// The camera in `f32`, as the firmware holds it (each parameter rounded to nearest).
    pub fn camera_f32(&self) -> Camera<f32> {
        self.camera.cast()
    }

    /// camgeom's JSON/TOML form of this camera (all five distortion coefficients written, or
    /// the four fisheye coefficients for a fisheye camera).
    pub fn to_file(&self) -> CameraFile {
        let k = &self.camera.intrinsics;
        let (distortion, fisheye) = match &self.camera.lens {
            Lens::KannalaBrandt(f) => (Vec::new(), f.to_opencv().to_vec()),
            Lens::BrownConrady(d) => (d.to_opencv().to_vec(), Vec::new()),
        };
        CameraFile {
            fx: k.fx(),
            fy: k.fy(),
            cx: k.cx(),
            cy: k.cy(),
            skew: k.skew(),
            distortion,
            fisheye,
            width: self.image_size.map(|s| s.0),
            height: self.image_size.map(|s| s.1),
        }
    }

    /// Pretty-printed JSON of [`Self::to_file`] (ends with a newline). Floats are written with
    /// the shortest text that reads back to the same `f64`.
    pub fn to_json(&self) -> String {
        crate::points::to_json(&self.to_file())
    }

    /// TOML of [`Self::to_file`].
    pub fn to_toml(&self) -> String {
        toml::to_string(&self.to_file()).unwrap_or_default()
    }
}

/// camgeom's camera file, as serialised to JSON and TOML.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// Focal length along `x`, pixels.
    pub fx: f64,
    /// Focal length along `y`, pixels.
    pub fy: f64,
    /// Principal point `x`, pixels.
    pub cx: f64,
    /// Principal point `y`, pixels.
    pub cy: f64,
    /// Skew `K[0][1]`.
    #[serde(default)]
    pub skew: f64,
    /// OpenCV-order distortion coefficients (`k1 k2 p1 p2 [k3 ...]`); empty for none.
    #[serde(default)]
    pub distortion: Vec<f64>,
    /// Fisheye (Kannala-Brandt) coefficients `k1 k2 k3 k4`; empty for a Brown-Conrady camera.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fisheye: Vec<f64>,
    /// Image width, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Image height, pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
}

impl CameraFile {
    /// Validates and builds the camera; `path` is only used in messages.
    pub fn to_spec(&self, path: &Path) -> Result<CameraSpec> {
        let intrinsics = Intrinsics::with_skew(self.fx, self.fy, self.cx, self.cy, self.skew)
            .map_err(|e| Error::new(path, ErrorKind::Camera(e)))?;
        let camera = if !self.fisheye.is_empty() {
            if !self.distortion.is_empty() {
                return Err(Error::new(
                    path,
                    ErrorKind::Shape(
                        "`distortion` and `fisheye` exclude each other (one lens model)".into(),
                    ),
                ));
            }
            Camera::fisheye(
                intrinsics,
                fisheye_from_coefficients(&self.fisheye, "fisheye")
                    .map_err(|k| Error::new(path, k))?,
            )
        } else if self.distortion.is_empty() {
            Camera::new(intrinsics, Distortion::none())
        } else {
            Camera::new(
                intrinsics,
                distortion_from_coefficients(&self.distortion, "distortion")
                    .map_err(|k| Error::new(path, k))?,
            )
        };
        let image_size = match (self.width, self.height) {
            (Some(w), Some(h)) => Some((w, h)),
            (None, None) => None,
            _ => {
                return Err(Error::new(
                    path,
                    ErrorKind::MissingKey(
                        if self.width.is_none() {
                            "width"
                        } else {
                            "height"
                        }
                        .to_string()
                            + " (width and height go together)",
                    ),
                ));
            }
        };
        Ok(CameraSpec { camera, image_size })
    }
}

/// Builds a fisheye lens from OpenCV's 4 coefficients `k1 k2 k3 k4`. `name` is used in
/// messages.
pub fn fisheye_from_coefficients(
    c: &[f64],
    name: &str,
) -> std::result::Result<Fisheye<f64>, ErrorKind> {
    let four: [f64; 4] = c.try_into().map_err(|_| {
        ErrorKind::Shape(format!(
            "`{name}` has {} coefficients; a fisheye camera has 4 (k1 k2 k3 k4)",
            c.len()
        ))
    })?;
    Fisheye::from_opencv(four).map_err(ErrorKind::Camera)
}

/// Builds camgeom's distortion from OpenCV-order coefficients (see the module docs for the
/// accepted counts). `name` is used in messages.
pub fn distortion_from_coefficients(
    c: &[f64],
    name: &str,
) -> std::result::Result<Distortion<f64>, ErrorKind> {
    let five = match c.len() {
        4 => [c[0], c[1], c[2], c[3], 0.0],
        5 => [c[0], c[1], c[2], c[3], c[4]],
        8 | 12 | 14 => {
            if let Some((i, v)) = c.iter().enumerate().skip(5).find(|(_, v)| **v != 0.0) {
                let what = match i {
                    5..=7 => "rational model (k4, k5, k6)",
                    8..=11 => "thin-prism model (s1..s4)",
                    _ => "tilted-sensor model (tx, ty)",
                };
                return Err(ErrorKind::Unsupported(format!(
                    "`{name}` has {} coefficients and coefficient {} is {v}: the {what} is not \
                     supported (camgeom models k1 k2 p1 p2 k3; the extra coefficients must be 0)",
                    c.len(),
                    i + 1
                )));
            }
            [c[0], c[1], c[2], c[3], c[4]]
        }
        n => {
            return Err(ErrorKind::Shape(format!(
                "`{name}` has {n} coefficients; expected 4, 5, 8, 12 or 14 (OpenCV's order \
                 k1 k2 p1 p2 [k3 ...])"
            )));
        }
    };
    Distortion::from_opencv(five).map_err(ErrorKind::Camera)
}

/// The keys OpenCV tools use for the camera matrix, first the one of OpenCV's calibration sample.
pub const CAMERA_MATRIX_KEYS: &[&str] = &["camera_matrix", "cameraMatrix"];
/// The keys OpenCV tools use for the distortion coefficients.
pub const DISTORTION_KEYS: &[&str] = &["distortion_coefficients", "distCoeffs", "dist_coeffs"];

/// Reads a camera from a file, choosing the format by extension: `.yml`/`.yaml` (OpenCV YAML),
/// `.xml` (OpenCV XML), `.json`, `.toml` (camgeom's form).
pub fn load_camera(path: impl AsRef<Path>) -> Result<CameraSpec> {
    let path = path.as_ref();
    match extension(path).as_str() {
        "yml" | "yaml" | "xml" => camera_from_storage(&FileStorage::open(path)?),
        "json" => camera_from_json(&read_text(path)?, path),
        "toml" => camera_from_toml(&read_text(path)?, path),
        ext => Err(Error::new(
            path,
            ErrorKind::Unsupported(format!(
                "camera file extension `{}`: use .yml/.yaml or .xml (OpenCV calibration), \
                 .json or .toml (camgeom)",
                ext_display(ext)
            )),
        )),
    }
}

/// The camera of an OpenCV calibration file: `camera_matrix` (3x3) and `distortion_coefficients`
/// (4, 5, 8, 12 or 14 values; 4 fisheye coefficients with `fisheye_model: 1`) are required,
/// `image_width`/`image_height` optional.
pub fn camera_from_storage(fs: &FileStorage) -> Result<CameraSpec> {
    let path = fs.path();
    let (k_key, k_node) = fs
        .get_any(CAMERA_MATRIX_KEYS)
        .ok_or_else(|| Error::new(path, ErrorKind::MissingKey(CAMERA_MATRIX_KEYS[0].into())))?;
    let k = fs.node_matrix(k_node, k_key)?;
    let k3 = k.to_matrix3().ok_or_else(|| {
        Error::at_line(
            path,
            k_node.line,
            ErrorKind::Shape(format!(
                "`{k_key}` must be a single-channel 3x3 matrix, found {}x{}{}",
                k.rows,
                k.cols,
                if k.channels > 1 {
                    format!(" with {} channels", k.channels)
                } else {
                    String::new()
                }
            )),
        )
    })?;
    let intrinsics = Intrinsics::from_matrix(&k3)
        .map_err(|e| Error::at_line(path, k_node.line, ErrorKind::Camera(e)))?;

    let (d_key, d_node) = fs
        .get_any(DISTORTION_KEYS)
        .ok_or_else(|| Error::new(path, ErrorKind::MissingKey(DISTORTION_KEYS[0].into())))?;
    let d = fs.node_matrix(d_node, d_key)?;
    if !d.is_vector() {
        return Err(Error::at_line(
            path,
            d_node.line,
            ErrorKind::Shape(format!(
                "`{d_key}` must be a 1xN or Nx1 single-channel matrix, found {}x{}",
                d.rows, d.cols
            )),
        ));
    }
    // OpenCV's calibration tutorial writes `fisheye_model: 0|1`.
    let camera = match fs.integer("fisheye_model")? {
        None | Some(0) => Camera::new(
            intrinsics,
            distortion_from_coefficients(&d.data, d_key)
                .map_err(|kind| Error::at_line(path, d_node.line, kind))?,
        ),
        Some(1) => Camera::fisheye(
            intrinsics,
            fisheye_from_coefficients(&d.data, d_key)
                .map_err(|kind| Error::at_line(path, d_node.line, kind))?,
        ),
        Some(v) => {
            return Err(Error::new(
                path,
                ErrorKind::Syntax(format!("`fisheye_model` must be 0 or 1, found {v}")),
            ));
        }
    };

    let dim = |key: &str| -> Result<Option<u32>> {
        match fs.integer(key)? {
            None => Ok(None),
            Some(v) => u32::try_from(v).map(Some).map_err(|_| {
                Error::new(path, ErrorKind::Syntax(format!("`{key}` is out of range")))
            }),
        }
    };
    let image_size = match (dim("image_width")?, dim("image_height")?) {
        (Some(w), Some(h)) => Some((w, h)),
        _ => None,
    };
    Ok(CameraSpec { camera, image_size })
}

/// Parses camgeom's JSON camera; `path` is only used in messages.
pub fn camera_from_json(text: &str, path: impl AsRef<Path>) -> Result<CameraSpec> {
    let path = path.as_ref();
    let file: CameraFile = serde_json::from_str(text).map_err(|e| {
        let line = e.line();
        // serde_json's message ends with " at line L column C": the line is reported by us.
        let msg = e.to_string();
        let msg = msg
            .rfind(" at line ")
            .map_or(msg.as_str(), |i| &msg[..i])
            .to_string();
        if line > 0 {
            Error::at_line(path, line, serde_kind(msg))
        } else {
            Error::new(path, serde_kind(msg))
        }
    })?;
    file.to_spec(path)
}

/// Parses camgeom's TOML camera; `path` is only used in messages.
pub fn camera_from_toml(text: &str, path: impl AsRef<Path>) -> Result<CameraSpec> {
    let path = path.as_ref();
    let file: CameraFile = toml::from_str(text).map_err(|e| {
        let msg = e.message().trim().to_string();
        match e.span() {
            Some(span) => {
                let line = text[..span.start.min(text.len())]
                    .bytes()
                    .filter(|&c| c == b'\n')
                    .count()
                    + 1;
                Error::at_line(path, line, serde_kind(msg))
            }
            None => Error::new(path, serde_kind(msg)),
        }
    })?;
    file.to_spec(path)
}

/// serde reports an absent field as "missing field `name`": keep that as [`ErrorKind::MissingKey`].
fn serde_kind(msg: String) -> ErrorKind {
    match msg
        .strip_prefix("missing field `")
        .and_then(|r| r.strip_suffix('`'))
    {
        Some(key) => ErrorKind::MissingKey(key.to_string()),
        None => ErrorKind::Syntax(msg),
    }
}
