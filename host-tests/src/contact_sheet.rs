//! Contact sheets: overlays downscaled and laid out in a labelled grid (`camgeom ar`,
//! `camgeom calibrate`, the main job's `overlays.png`).

use image::{Rgb, imageops};

use crate::rgb::{Overlay, RgbImage};

/// Pixels between two tiles and around the grid.
const GAP: u32 = 2;

/// Grey of the background between the tiles.
const BACKGROUND: Rgb<u8> = Rgb([32, 32, 32]);

/// A grid of `tiles`, `cols` a row, each downscaled by `factor` with a box filter and labelled
/// with its number in the top-left corner.
///
/// Every tile is made the size of the first one's, `(w / factor, h / factor)`: a pixel is the
/// rounded mean `(Σ + n/2) / n` of its `factor x factor` block (`imageops::thumbnail` on the
/// tile cropped to whole blocks; a tile of another size than the first is resampled to it).
pub fn contact_sheet(tiles: &[(usize, RgbImage)], cols: usize, factor: usize) -> RgbImage {
    let factor = u32::try_from(factor.max(1)).unwrap_or(u32::MAX);
    let cols = u32::try_from(cols.max(1)).unwrap_or(u32::MAX);
    let (tw, th) = tiles
        .first()
        .map_or((1, 1), |(_, t)| (t.width() / factor, t.height() / factor));
    let rows = u32::try_from(tiles.len())
        .unwrap_or(u32::MAX)
        .div_ceil(cols);
    let (w, h) = (cols * tw + (cols + 1) * GAP, rows * th + (rows + 1) * GAP);
    let mut sheet = RgbImage::from_pixel(w, h, BACKGROUND);
    for ((label, tile), k) in tiles.iter().zip(0u32..) {
        let (ox, oy) = (GAP + (k % cols) * (tw + GAP), GAP + (k / cols) * (th + GAP));
        let blocks = imageops::crop_imm(tile, 0, 0, tw * factor, th * factor);
        let small: RgbImage = imageops::thumbnail(&*blocks, tw, th);
        imageops::replace(&mut sheet, &small, i64::from(ox), i64::from(oy));
        sheet.label(
            ox as usize,
            oy as usize,
            &label.to_string(),
            tw as usize,
            th as usize,
        );
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tile of pseudo-random pixels.
    fn noise(w: u32, h: u32, seed: u32) -> RgbImage {
        let mut state = seed;
        RgbImage::from_fn(w, h, |_, _| {
            let mut next = || {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 24) as u8
            };
            Rgb([next(), next(), next()])
        })
    }

    #[test]
    fn tiles_are_box_filtered_into_a_grid() {
        let factor = 3;
        // 121x91 pixels: whole 3x3 blocks to 120x90, the rest left out.
        let tiles: Vec<(usize, RgbImage)> = (0..3).map(|k| (k, noise(121, 91, k as u32))).collect();
        let sheet = contact_sheet(&tiles, 2, factor as usize);
        let (tw, th) = (40, 30);
        assert_eq!(sheet.dimensions(), (2 * tw + 3 * GAP, 2 * th + 3 * GAP));
        assert_eq!(sheet.get_pixel(0, 0), &BACKGROUND);
        // The empty fourth cell.
        assert_eq!(
            sheet.get_pixel(GAP + tw + GAP + 1, GAP + th + GAP + 1),
            &BACKGROUND
        );
        for (k, (_, tile)) in (0u32..).zip(&tiles) {
            let (ox, oy) = (GAP + (k % 2) * (tw + GAP), GAP + (k / 2) * (th + GAP));
            let (lw, _) = label_size_px(k);
            for y in 0..th {
                for x in 0..tw {
                    // Under the label: drawn over.
                    if x < lw && y < 14 {
                        continue;
                    }
                    let mut sum = [0u32; 3];
                    for dy in 0..factor {
                        for dx in 0..factor {
                            let p = tile.get_pixel(x * factor + dx, y * factor + dy).0;
                            for (s, c) in sum.iter_mut().zip(p) {
                                *s += u32::from(c);
                            }
                        }
                    }
                    let n = factor * factor;
                    let mean = sum.map(|s| ((s + n / 2) / n) as u8);
                    assert_eq!(
                        sheet.get_pixel(ox + x, oy + y).0,
                        mean,
                        "tile {k} ({x}, {y})"
                    );
                }
            }
        }
    }

    fn label_size_px(k: u32) -> (u32, u32) {
        let (w, h) = crate::rgb::label_size(&k.to_string());
        (w as u32, h as u32)
    }
}
