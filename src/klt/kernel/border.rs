//! The levels' copies with a reflected border, as OpenCV keeps its pyramids ([`pad`]), and
//! [`Pixels`], a level with its copy, from which a kernel reads a window's block.

use super::patch::{Rows, block_rows, fetch_patch};
use crate::image::ImageView;

/// A level's pixels, and maybe a copy of them with a reflected border ([`pad`]): a window
/// that leaves the level but not the border reads its rows from the copy, where it would
/// otherwise be copied out pixel row by pixel row ([`fetch_patch`]), at every template and
/// at every mismatch that moves it. The copy is made once a level, so it pays where many
/// windows cross the level's edges (the coarse levels).
#[derive(Clone, Copy)]
pub(in crate::klt) struct Pixels<'a> {
    /// The level.
    pub(in crate::klt) img: ImageView<'a, u8>,
    /// The copy, and the width of its border.
    padded: Option<(ImageView<'a, u8>, i32)>,
}

impl<'a> Pixels<'a> {
    /// The level alone.
    pub(in crate::klt) fn new(img: ImageView<'a, u8>) -> Self {
        Self { img, padded: None }
    }

    /// The level and its copy `padded`, made by [`pad`] with `border`.
    pub(in crate::klt) fn bordered(
        img: ImageView<'a, u8>,
        padded: ImageView<'a, u8>,
        border: usize,
    ) -> Self {
        Self {
            img,
            padded: Some((padded, border as i32)),
        }
    }

    /// The `rows` rows, `cols` wide, of the block at `(x0, y0)`: from the level when it lies
    /// inside, else from the copy when it lies inside that (the same pixels: the copy's
    /// border is the level reflected as [`fetch_patch`] reflects it); `None` otherwise.
    #[inline]
    pub(super) fn block(
        &self,
        (x0, y0): (i32, i32),
        cols: usize,
        rows: usize,
    ) -> Option<Rows<'a, u8>> {
        block_rows(&self.img, (x0, y0), cols, rows).or_else(|| {
            let (p, b) = self.padded.as_ref()?;
            block_rows(
                p,
                (x0.saturating_add(*b), y0.saturating_add(*b)),
                cols,
                rows,
            )
        })
    }
}

/// The border of the copies of [`pad`] for `win x win` windows: every block a window whose
/// centre lies in the level reads (its `win + 1` taps, the vector kernel's rows padded to
/// whole vectors and one tap more, at most `win / 2 + 8` beyond either edge) lies inside it.
pub(in crate::klt) const fn border_width(win: usize) -> usize {
    win / 2 + 8
}

/// Bytes of the bordered copies [`calc_flow`](crate::klt::calc_flow) makes
/// ([`Borders::Copy`](crate::klt::Borders::Copy)) of a `w x h` level of both pyramids (`I`'s
/// and `J`'s) for `win x win` windows: `2 (w + 2b)(h + 2b)` with the border
/// `b = ⌊win / 2⌋ + 8` (`border_width`: every block a window centred in the level reads lies
/// inside it).
pub const fn bordered_len(w: usize, h: usize, win: usize) -> usize {
    let b = 2 * border_width(win);
    2 * (w + b) * (h + b)
}

/// Copies `img` with `border` pixels on every side, reflected as [`fetch_patch`] reflects
/// them (it is one [`fetch_patch`] of the whole bordered block), into the start of `out`;
/// `None` when `out` is too short.
pub(in crate::klt) fn pad<'o>(
    img: &ImageView<'_, u8>,
    border: usize,
    out: &'o mut [u8],
) -> Option<ImageView<'o, u8>> {
    let (w, h) = (img.width() + 2 * border, img.height() + 2 * border);
    let out = out.get_mut(..w.checked_mul(h)?)?;
    let b = i32::try_from(border).ok()?;
    fetch_patch(img, (-b, -b), w, h, out);
    ImageView::packed(out, w, h).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block read from a bordered copy ([`Pixels::block`]) is the block [`fetch_patch`]
    /// copies, at every corner where the copy holds it; where it does not, `block` says so.
    #[test]
    fn bordered_blocks_are_the_patches() {
        let (w, h) = (13usize, 9usize);
        let img: std::vec::Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        let view = ImageView::packed(&img, w, h).unwrap();
        for win in [3usize, 9] {
            let b = border_width(win);
            let mut buf = std::vec![0u8; bordered_len(w, h, win) / 2];
            let padded = pad(&view, b, &mut buf).unwrap();
            assert!(pad(&view, b, &mut [0u8; 10]).is_none());
            let px = Pixels::bordered(view, padded, b);
            let (cols, rows) = (win + 1, win + 1);
            let reach = b as i32 + 4;
            for y0 in -reach..h as i32 + reach {
                for x0 in -reach..w as i32 + reach {
                    let inside = |v: i32, n: usize, len: usize| {
                        v >= -(b as i32) && v + len as i32 <= (n + b) as i32
                    };
                    let fits = inside(x0, w, cols) && inside(y0, h, rows);
                    let got = px.block((x0, y0), cols, rows);
                    assert_eq!(got.is_some(), fits, "win {win} at ({x0}, {y0})");
                    let Some(got) = got else { continue };
                    let mut want = std::vec![0u8; cols * rows];
                    fetch_patch(&view, (x0, y0), cols, rows, &mut want);
                    let got: std::vec::Vec<u8> = got.flat_map(|r| r.iter().copied()).collect();
                    assert_eq!(got, want, "win {win} at ({x0}, {y0})");
                }
            }
        }
    }
}
