//! Colour overlays on the `image` crate's [`RgbImage`]: a grey frame in colour, pixels set
//! with clipping, masks inked with a halo, digit labels, and compact PNG files (the contact
//! sheets are committed). The overlays of `ar`, `apriltag` and `calibrate`, the contact sheets
//! ([`crate::contact_sheet`]) and the main job's overlays are drawn with it.

use std::path::Path;

/// The RGB image of every overlay (re-exported for users without the `image` dependency).
pub use image::RgbImage;
use image::{ImageEncoder, Rgb};

use crate::error::{Error, ErrorKind, Result};
use crate::images::GrayImage;

/// What the overlays do with an [`RgbImage`].
pub trait Overlay: Sized {
    /// The grey image in colour (`r = g = b`).
    fn from_gray(g: &GrayImage) -> Self;

    /// Sets pixel `(x, y)` to `c`; nothing outside the image.
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]);

    /// Paints `colour` where `mask` (of the image's size) is set, with a dark one-pixel halo
    /// around it (the pixel's value divided by 3) so thin lines read on any background.
    fn ink(&mut self, mask: &GrayImage, colour: [u8; 3]);

    /// Writes `text` (digits and `.`; other characters are skipped) in white 3x5 digits at 2x
    /// on a black box whose top-left corner is `(x, y)`, the box clipped to `max_w x max_h`
    /// ([`label_size`] gives its full size).
    fn label(&mut self, x: usize, y: usize, text: &str, max_w: usize, max_h: usize);

    /// Writes the image as PNG with fast compression: with the best one, compressing took
    /// most of `ar`'s and `apriltag --overlay`'s time (BENCHMARKS.md).
    fn save_png(&self, path: impl AsRef<Path>) -> Result<()>;
}

impl Overlay for RgbImage {
    fn from_gray(g: &GrayImage) -> Self {
        RgbImage::from_fn(g.width as u32, g.height as u32, |x, y| {
            let v = g.at(x as usize, y as usize);
            Rgb([v, v, v])
        })
    }

    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if let (Ok(x), Ok(y)) = (u32::try_from(x), u32::try_from(y))
            && x < self.width()
            && y < self.height()
        {
            self.put_pixel(x, y, Rgb(c));
        }
    }

    fn ink(&mut self, mask: &GrayImage, colour: [u8; 3]) {
        let (w, h) = (i64::from(self.width()), i64::from(self.height()));
        let on = |x: i64, y: i64| {
            x >= 0 && y >= 0 && x < w && y < h && mask.at(x as usize, y as usize) != 0
        };
        // Only the mask's bounding box, one pixel wider for the halo: a drawing covers a
        // small part of a large frame (a 1080p overlay inked the whole frame before).
        let Some((x0, y0, x1, y1)) = bounding_box(mask) else {
            return;
        };
        let (xs, ys) = (
            (x0 - 1).max(0)..(x1 + 2).min(w),
            (y0 - 1).max(0)..(y1 + 2).min(h),
        );
        for y in ys.clone() {
            for x in xs.clone() {
                if on(x, y) {
                    continue;
                }
                let near = (-1..=1).any(|dy| (-1..=1).any(|dx| on(x + dx, y + dy)));
                if near {
                    for c in &mut self.get_pixel_mut(x as u32, y as u32).0 {
                        *c /= 3;
                    }
                }
            }
        }
        for y in ys {
            for x in xs.clone() {
                if on(x, y) {
                    self.put(x, y, colour);
                }
            }
        }
    }

    fn label(&mut self, x: usize, y: usize, text: &str, max_w: usize, max_h: usize) {
        let (lw, lh) = label_size(text);
        for dy in 0..lh.min(max_h) {
            for dx in 0..lw.min(max_w) {
                self.put((x + dx) as i64, (y + dy) as i64, [0, 0, 0]);
            }
        }
        for (i, ch) in text.bytes().enumerate() {
            let glyph = match ch {
                b'0'..=b'9' => DIGITS[usize::from(ch - b'0')],
                b'.' => [0, 0, 0, 0, 2],
                _ => continue,
            };
            for (r, bits) in glyph.iter().enumerate() {
                for c in 0..3 {
                    if bits & (4 >> c) != 0 {
                        for (sy, sx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                            let px = x + 2 + i * 8 + c * 2 + sx;
                            let py = y + 2 + r * 2 + sy;
                            self.put(px as i64, py as i64, [255, 255, 255]);
                        }
                    }
                }
            }
        }
    }

    fn save_png(&self, path: impl AsRef<Path>) -> Result<()> {
        use image::codecs::png::{CompressionType, FilterType, PngEncoder};
        let path = path.as_ref();
        let io = |e: std::io::Error| Error::new(path, ErrorKind::Write(e));
        let file = std::fs::File::create(path).map_err(io)?;
        let enc = PngEncoder::new_with_quality(
            std::io::BufWriter::new(file),
            CompressionType::Fast,
            FilterType::Adaptive,
        );
        enc.write_image(
            self.as_raw(),
            self.width(),
            self.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| match e {
            image::ImageError::IoError(e) => io(e),
            other => Error::new(path, ErrorKind::Unsupported(other.to_string())),
        })
    }
}

/// The smallest box `(x0, y0, x1, y1)` (inclusive) holding every set pixel of `mask`; `None`
/// when none is set.
fn bounding_box(mask: &GrayImage) -> Option<(i64, i64, i64, i64)> {
    let w = mask.width.max(1);
    let rows: Vec<usize> = mask
        .data
        .chunks(w)
        .enumerate()
        .filter(|(_, r)| r.iter().any(|&v| v != 0))
        .map(|(y, _)| y)
        .collect();
    let (&y0, &y1) = (rows.first()?, rows.last()?);
    let (mut x0, mut x1) = (w, 0);
    for &y in &rows {
        let row = &mask.data[y * w..(y + 1) * w];
        if let Some(a) = row.iter().position(|&v| v != 0) {
            x0 = x0.min(a);
        }
        if let Some(b) = row.iter().rposition(|&v| v != 0) {
            x1 = x1.max(b);
        }
    }
    Some((x0 as i64, y0 as i64, x1 as i64, y1 as i64))
}

/// Width and height in pixels of [`Overlay::label`]'s box for `text`.
pub fn label_size(text: &str) -> (usize, usize) {
    (text.len() * 8 + 2, 14)
}

/// 3x5 bitmaps of the digits 0-9, one row a `u8` (bit 2 = left column).
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_in_colour_clipped_pixels_and_ink() {
        let mut g = GrayImage::filled(4, 3, 90);
        g.data[5] = 30; // (1, 1)
        let mut img = RgbImage::from_gray(&g);
        assert_eq!(img.get_pixel(1, 1).0, [30, 30, 30]);
        img.put(-1, 0, [1, 2, 3]);
        img.put(4, 0, [1, 2, 3]);
        img.put(3, 2, [1, 2, 3]);
        assert_eq!(img.get_pixel(3, 2).0, [1, 2, 3]);
        let mut mask = GrayImage::filled(4, 3, 0);
        mask.data[0] = 255; // (0, 0)
        img.ink(&mask, [200, 0, 0]);
        assert_eq!(img.get_pixel(0, 0).0, [200, 0, 0]);
        // The halo: the neighbours darkened, the rest untouched.
        assert_eq!(img.get_pixel(1, 1).0, [10, 10, 10]);
        assert_eq!(img.get_pixel(1, 0).0, [30, 30, 30]);
        assert_eq!(img.get_pixel(2, 0).0, [90, 90, 90]);
    }

    #[test]
    fn labels_fit_their_box() {
        let mut img = RgbImage::from_pixel(40, 20, Rgb([100, 100, 100]));
        let (w, h) = label_size("1.5");
        assert_eq!((w, h), (26, 14));
        img.label(1, 1, "1.5", w, h);
        assert_eq!(img.get_pixel(1, 1).0, [0, 0, 0]);
        assert_eq!(img.get_pixel(w as u32, h as u32).0, [0, 0, 0]);
        assert_eq!(img.get_pixel(w as u32 + 1, 1).0, [100, 100, 100]);
        // The `1`'s top row (bits 010): the middle column, 2x.
        assert_eq!(img.get_pixel(1 + 2 + 2, 1 + 2).0, [255, 255, 255]);
    }
}
