//! Grayscale images from and to files (PNG, JPEG), as owned buffers that lend camgeom views.

use std::path::Path;

use camgeom::image::{ImageMut, ImageView};

use crate::error::{Error, ErrorKind, Result};

/// An owned, tightly packed 8-bit grayscale image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayImage {
    /// Pixels, row-major, `width * height` bytes.
    pub data: Vec<u8>,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

impl GrayImage {
    /// A `width x height` image filled with `value`.
    pub fn filled(width: usize, height: usize, value: u8) -> Self {
        Self {
            data: vec![value; width * height],
            width,
            height,
        }
    }

    /// A camgeom view of the pixels (`None` for a size camgeom rejects).
    pub fn view(&self) -> Option<ImageView<'_, u8>> {
        ImageView::packed(&self.data, self.width, self.height).ok()
    }

    /// A mutable camgeom view of the pixels.
    pub fn view_mut(&mut self) -> Option<ImageMut<'_, u8>> {
        ImageMut::packed(&mut self.data, self.width, self.height).ok()
    }

    /// Pixel `(x, y)`; panics outside (for tests and tools).
    pub fn at(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.width + x]
    }
}

/// Reads a PNG or JPEG file as 8-bit grayscale, by OpenCV's rules for
/// `cv2.imread(path, IMREAD_GRAYSCALE)`:
/// - colour is converted with `cvtColor(BGR2GRAY)`'s weights,
///   `Y = (4899 R + 9617 G + 1868 B + 2¹³) >> 14` (the same pixels up to rounding of ±1);
/// - 16-bit samples keep their high byte, `v >> 8` (as OpenCV's conversion to 8 bits);
/// - an alpha channel is ignored (not composited), as `imread` without `IMREAD_UNCHANGED`.
pub fn load_gray(path: impl AsRef<Path>) -> Result<GrayImage> {
    let path = path.as_ref();
    let img = image::open(path).map_err(|e| match e {
        image::ImageError::IoError(io) => Error::new(path, ErrorKind::Io(io)),
        other => Error::new(path, ErrorKind::Syntax(other.to_string())),
    })?;
    let (width, height) = (img.width() as usize, img.height() as usize);
    let luma = |[r, g, b]: [u32; 3]| ((4899 * r + 9617 * g + 1868 * b + (1 << 13)) >> 14) as u8;
    let data = match img {
        image::DynamicImage::ImageLuma8(g) => g.into_raw(),
        image::DynamicImage::ImageLuma16(g) => g.pixels().map(|p| (p.0[0] >> 8) as u8).collect(),
        image::DynamicImage::ImageLumaA16(g) => g.pixels().map(|p| (p.0[0] >> 8) as u8).collect(),
        image::DynamicImage::ImageRgb16(g) => g
            .pixels()
            .map(|p| luma(p.0.map(|v| u32::from(v >> 8))))
            .collect(),
        image::DynamicImage::ImageRgba16(g) => g
            .pixels()
            .map(|p| luma([p.0[0], p.0[1], p.0[2]].map(|v| u32::from(v >> 8))))
            .collect(),
        other => other
            .to_rgb8()
            .pixels()
            .map(|p| luma(p.0.map(u32::from)))
            .collect(),
    };
    Ok(GrayImage {
        data,
        width,
        height,
    })
}

/// Writes `img` as an 8-bit grayscale PNG (or JPEG for a `.jpg`/`.jpeg` name).
pub fn save_gray(img: &GrayImage, path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    let buf = image::GrayImage::from_raw(img.width as u32, img.height as u32, img.data.clone())
        .ok_or_else(|| {
            Error::new(
                path,
                ErrorKind::Shape("buffer does not match the size".into()),
            )
        })?;
    buf.save(path).map_err(|e| match e {
        image::ImageError::IoError(io) => Error::new(path, ErrorKind::Write(io)),
        other => Error::new(path, ErrorKind::Unsupported(other.to_string())),
    })
}

/// Refuses an image smaller than `min` pixels in either direction, the smallest that `what`
/// can work on (a detector's or a tracker's window): a typed error rather than an empty answer.
pub fn require_size(img: &GrayImage, path: &Path, min: usize, what: &str) -> Result<()> {
    if img.width < min || img.height < min {
        return Err(Error::new(
            path,
            ErrorKind::Unsupported(format!(
                "image {}x{} is smaller than {what} ({min}x{min} px)",
                img.width, img.height
            )),
        ));
    }
    Ok(())
}
