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
/// - colour is converted with `cvtColor(BGR2GRAY)`'s weights ([`luma`]),
///   `Y = (4899 R + 9617 G + 1868 B + 2¹³) >> 14` (the same pixels up to rounding of ±1);
/// - 16-bit samples keep their high byte, `v >> 8` (as OpenCV's conversion to 8 bits);
/// - an alpha channel is ignored (not composited), as `imread` without `IMREAD_UNCHANGED`.
pub fn load_gray(path: impl AsRef<Path>) -> Result<GrayImage> {
    let path = path.as_ref();
    Ok(gray_of(decode(path)?))
}

/// Reads a PNG or JPEG file as 8-bit grayscale and, when the file is in colour, as 8-bit RGB
/// too: `(grey, Some(rgb))` for a colour file, `(grey, None)` for a grey one. Both by the
/// rules of [`load_gray`] (16-bit samples keep their high byte, alpha is ignored), the grey
/// being [`gray_of_rgb`] of the colour one; for the overlays that draw on the colour frame.
pub fn load_gray_and_rgb(path: impl AsRef<Path>) -> Result<(GrayImage, Option<image::RgbImage>)> {
    let path = path.as_ref();
    let img = decode(path)?;
    let rgb = rgb_of(&img);
    let gray = match &rgb {
        Some(c) => gray_of_rgb(c),
        None => gray_of(img),
    };
    Ok((gray, rgb))
}

/// Reads a PNG or JPEG file as 8-bit RGB (a grey file as `r = g = b`), by the rules of
/// [`load_gray`]: 16-bit samples keep their high byte, alpha is ignored.
pub fn load_rgb(path: impl AsRef<Path>) -> Result<image::RgbImage> {
    let path = path.as_ref();
    let img = decode(path)?;
    Ok(match rgb_of(&img) {
        Some(c) => c,
        None => {
            let g = gray_of(img);
            image::RgbImage::from_fn(g.width as u32, g.height as u32, |x, y| {
                let v = g.at(x as usize, y as usize);
                image::Rgb([v, v, v])
            })
        }
    })
}

/// A file's pixels as they are, 8 bits a sample: grey or colour.
#[derive(Debug, Clone)]
pub enum GrayOrRgb {
    /// A grey file (with or without alpha).
    Gray(GrayImage),
    /// A colour file (with or without alpha).
    Rgb(image::RgbImage),
}

/// Reads a PNG or JPEG file as 8-bit grey when it is grey and 8-bit RGB when it is in colour,
/// by the rules of [`load_gray`] (16-bit samples keep their high byte, alpha is ignored); for
/// the commands whose output keeps the input's colour.
pub fn load_gray_or_rgb(path: impl AsRef<Path>) -> Result<GrayOrRgb> {
    let img = decode(path.as_ref())?;
    Ok(match rgb_of(&img) {
        Some(c) => GrayOrRgb::Rgb(c),
        None => GrayOrRgb::Gray(gray_of(img)),
    })
}

/// OpenCV's `cvtColor(RGB2GRAY)` in fixed point: `(4899 r + 9617 g + 1868 b + 2¹³) >> 14`.
pub fn luma([r, g, b]: [u8; 3]) -> u8 {
    ((4899 * u32::from(r) + 9617 * u32::from(g) + 1868 * u32::from(b) + (1 << 13)) >> 14) as u8
}

/// The grey image of an RGB one, by [`luma`].
pub fn gray_of_rgb(img: &image::RgbImage) -> GrayImage {
    GrayImage {
        data: img.pixels().map(|p| luma(p.0)).collect(),
        width: img.width() as usize,
        height: img.height() as usize,
    }
}

/// The file decoded by `image`, errors naming it.
fn decode(path: &Path) -> Result<image::DynamicImage> {
    image::open(path).map_err(|e| match e {
        image::ImageError::IoError(io) => Error::new(path, ErrorKind::Io(io)),
        other => Error::new(path, ErrorKind::Syntax(other.to_string())),
    })
}

/// The RGB pixels of a colour image (`None` for a grey one): 16-bit samples keep their high
/// byte, alpha is dropped.
fn rgb_of(img: &image::DynamicImage) -> Option<image::RgbImage> {
    use image::DynamicImage as D;
    let (w, h) = (img.width(), img.height());
    let high = |v: &[u16]| -> Vec<u8> { v.iter().map(|v| (v >> 8) as u8).collect() };
    match img {
        D::ImageLuma8(_) | D::ImageLumaA8(_) | D::ImageLuma16(_) | D::ImageLumaA16(_) => None,
        D::ImageRgb16(c) => image::RgbImage::from_raw(w, h, high(c.as_raw())),
        D::ImageRgba16(c) => image::RgbImage::from_raw(
            w,
            h,
            c.pixels()
                .flat_map(|p| [p.0[0], p.0[1], p.0[2]].map(|v| (v >> 8) as u8))
                .collect(),
        ),
        other => Some(other.to_rgb8()),
    }
}

/// The grey pixels of a decoded image by the rules of [`load_gray`].
fn gray_of(img: image::DynamicImage) -> GrayImage {
    let (width, height) = (img.width() as usize, img.height() as usize);
    let data = match img {
        image::DynamicImage::ImageLuma8(g) => g.into_raw(),
        image::DynamicImage::ImageLumaA8(g) => g.pixels().map(|p| p.0[0]).collect(),
        image::DynamicImage::ImageLuma16(g) => g.pixels().map(|p| (p.0[0] >> 8) as u8).collect(),
        image::DynamicImage::ImageLumaA16(g) => g.pixels().map(|p| (p.0[0] >> 8) as u8).collect(),
        other => match rgb_of(&other) {
            Some(c) => return gray_of_rgb(&c),
            None => other.to_luma8().into_raw(),
        },
    };
    GrayImage {
        data,
        width,
        height,
    }
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

/// Writes `img` as an 8-bit RGB PNG (or JPEG for a `.jpg`/`.jpeg` name).
pub fn save_rgb(img: &image::RgbImage, path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    img.save(path).map_err(|e| match e {
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
