//! What the examples share: the bundled data's paths and an 8-bit grey PNG reader (each
//! example uses what it needs of it).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use camgeom::camera::{Camera, Distortion, Intrinsics};

/// `host-tests/data/`, the recorded data bundled with camgeom (see its README for provenance).
pub fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("host-tests/data")
}

/// An 8-bit grey PNG: `(width, height, pixels)`.
pub fn read_gray_png(path: &Path) -> Result<(usize, usize, Vec<u8>), Box<dyn std::error::Error>> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info()?;
    let mut buf = vec![0; reader.output_buffer_size().ok_or("PNG too large")?];
    let info = reader.next_frame(&mut buf)?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Eight {
        return Err(format!("{}: not 8-bit grey", path.display()).into());
    }
    buf.truncate(info.buffer_size());
    Ok((info.width as usize, info.height as usize, buf))
}

/// The bundled chessboard camera: OpenCV's calibration of the `left*.jpg` views
/// (`host-tests/data/chessboard/left_intrinsics.yml`: `camera_matrix`, then
/// `distortion_coefficients` k1 k2 p1 p2 k3), in f64 as the file has it, then in f32.
pub fn chessboard_camera() -> camgeom::Result<Camera<f32>> {
    let k = Intrinsics::new(
        535.915_733_961_632,
        535.915_733_961_632,
        342.283_154_733_083_7,
        235.570_829_097_881_7,
    )?;
    let d = Distortion::from_opencv([
        -0.266_372_609_096_606_8,
        -0.038_588_898_922_304_65,
        0.001_783_194_704_285_296,
        -0.000_281_221_004_411_154_7,
        0.238_391_530_808_784_9,
    ])?;
    Ok(Camera::<f64>::new(k, d).cast())
}
