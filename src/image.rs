//! Borrowed grayscale images with a row stride, validated once at construction.
//!
//! Pixel `(x, y)` of a view is `data[y * stride + x]`, for `x < width`, `y < height`. The
//! constructors check the sizes once (non-zero, within [`MAX_DIM`], `stride >= width`, buffer
//! long enough), so kernels can walk rows without any further failure path: [`ImageView::row`]
//! cannot miss for `y < height`.
//!
//! ```
//! use camgeom::Error;
//! use camgeom::image::{ImageView, buffer_len};
//!
//! // A 3x2 image in rows of 4 (one byte of padding a row, none after the last).
//! let data = [10u8, 11, 12, 0, 20, 21, 22];
//! assert_eq!(buffer_len(3, 2, 4), data.len());
//! let img = ImageView::new(&data, 3, 2, 4)?;
//! assert_eq!(img.get(2, 1), Some(22));
//! assert_eq!(img.get(3, 0), None); // the padding is not a pixel
//! assert_eq!(img.row(1), Some(&[20u8, 21, 22][..]));
//! assert_eq!(img.sub(1, 0, 2, 2)?.get(0, 1), Some(21));
//! // Rejected once, at construction: too short a buffer, a stride below the width, no pixels.
//! assert_eq!(ImageView::new(&data[..6], 3, 2, 4).err(), Some(Error::InvalidImage));
//! assert_eq!(ImageView::new(&data, 3, 2, 2).err(), Some(Error::InvalidImage));
//! assert_eq!(ImageView::packed(&data, 0, 2).err(), Some(Error::InvalidImage));
//! # Ok::<(), camgeom::Error>(())
//! ```

use crate::{Error, Result};

/// Largest width or height accepted (2¹³): keeps every pixel sum of the integer kernels
/// (up to `255 · 2¹⁶` per window, times `x, y < 2¹³`) inside `i32`/`i64` with margin.
pub const MAX_DIM: usize = 8192;

/// Number of elements a buffer needs for a `width x height` image with row `stride`:
/// `stride (height - 1) + width` (the last row need not be padded).
pub const fn buffer_len(width: usize, height: usize, stride: usize) -> usize {
    if width == 0 || height == 0 {
        0
    } else {
        stride
            .saturating_mul(height.saturating_sub(1))
            .saturating_add(width)
    }
}

fn validate(len: usize, width: usize, height: usize, stride: usize) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_DIM || height > MAX_DIM {
        return Err(Error::InvalidImage);
    }
    if stride < width || stride > MAX_DIM.saturating_mul(4) {
        return Err(Error::InvalidImage);
    }
    if len < buffer_len(width, height, stride) {
        return Err(Error::InvalidImage);
    }
    Ok(())
}

/// A read-only `width x height` image of `P` (`u8` pixels, `i16` gradients, ...).
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a, P = u8> {
    data: &'a [P],
    width: usize,
    height: usize,
    stride: usize,
}

/// A mutable `width x height` image of `P`.
#[derive(Debug)]
pub struct ImageMut<'a, P = u8> {
    data: &'a mut [P],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a, P: Copy> ImageView<'a, P> {
    /// A view of `data` with the given geometry. Errors with [`Error::InvalidImage`] for zero
    /// or over-[`MAX_DIM`] sizes, `stride < width`, or a buffer shorter than
    /// [`buffer_len`]`(width, height, stride)`.
    pub fn new(data: &'a [P], width: usize, height: usize, stride: usize) -> Result<Self> {
        validate(data.len(), width, height, stride)?;
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// A tightly packed view (`stride = width`).
    pub fn packed(data: &'a [P], width: usize, height: usize) -> Result<Self> {
        Self::new(data, width, height, width)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Elements from one row to the next.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The whole buffer: pixel `(x, y)` is element `y * stride + x` (at least
    /// [`buffer_len`]`(width, height, stride)` elements), for kernels that index it directly.
    pub fn data(&self) -> &'a [P] {
        self.data
    }

    /// Row `y` (exactly `width` pixels), `None` when `y >= height`.
    #[inline]
    pub fn row(&self, y: usize) -> Option<&'a [P]> {
        if y >= self.height {
            return None;
        }
        let start = y.checked_mul(self.stride)?;
        self.data.get(start..start.checked_add(self.width)?)
    }

    /// Row `y` clamped into `0..height` (replicated border for kernels).
    #[inline]
    pub fn row_clamped(&self, y: isize) -> &'a [P] {
        // `max` then `min`, not `clamp`: `clamp`'s `min <= max` assertion is a panic path the
        // optimiser keeps (it does not know that `height >= 1`).
        let y = y.min(self.height as isize - 1).max(0) as usize;
        // Validated at construction: every y < height has a full row.
        self.row(y).unwrap_or(&[])
    }

    /// Pixel `(x, y)`, `None` outside the image.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<P> {
        if x >= self.width {
            return None;
        }
        self.row(y)?.get(x).copied()
    }

    /// Iterator over the rows, top to bottom.
    pub fn rows(&self) -> impl Iterator<Item = &'a [P]> + '_ {
        (0..self.height).filter_map(move |y| self.row(y))
    }

    /// The sub-image `[x, x + w) x [y, y + h)`; [`Error::InvalidImage`] when it does not fit.
    pub fn sub(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Self> {
        let x_end = x.checked_add(w).ok_or(Error::InvalidImage)?;
        let y_end = y.checked_add(h).ok_or(Error::InvalidImage)?;
        if x_end > self.width || y_end > self.height {
            return Err(Error::InvalidImage);
        }
        let start = y.saturating_mul(self.stride).saturating_add(x);
        let data = self.data.get(start..).ok_or(Error::InvalidImage)?;
        Self::new(data, w, h, self.stride)
    }
}

impl ImageView<'_, u8> {
    /// The image at the real point `(x, y)` by bilinear interpolation (pixel `(i, j)` centred
    /// at `(i, j)`): with `i = ⌊x⌋`, `j = ⌊y⌋`, `a = x - i`, `b = y - j`,
    ///
    /// `v = (1 - a)(1 - b) I(i, j) + a (1 - b) I(i + 1, j) + (1 - a) b I(i, j + 1) + a b I(i + 1, j + 1)`,
    ///
    /// evaluated in `f32` in that order, each weight formed before it multiplies its pixel
    /// (the order fixes the rounding: callers that replay results bit for bit rely on it).
    ///
    /// Border: `Some` exactly on the closed rectangle `0 ≤ x ≤ width - 1`, `0 ≤ y ≤ height - 1`
    /// (AprilTag's `value_for_pixel`): a neighbour is read only when its weight is not zero,
    /// so the last column and row are reached at integer coordinates. `None` outside it and
    /// for NaN; no pixel is ever replicated or read past the edge.
    ///
    /// ```
    /// use camgeom::image::ImageView;
    ///
    /// let img = ImageView::packed(&[0u8, 100, 200, 40], 2, 2)?;
    /// assert_eq!(img.sample_bilinear(0.5, 0.0), Some(50.0));
    /// assert_eq!(img.sample_bilinear(0.5, 0.5), Some(85.0));
    /// assert_eq!(img.sample_bilinear(1.0, 1.0), Some(40.0)); // the last pixel itself
    /// assert_eq!(img.sample_bilinear(1.25, 0.0), None);
    /// assert_eq!(img.sample_bilinear(-0.25, 0.0), None);
    /// # Ok::<(), camgeom::Error>(())
    /// ```
    #[inline]
    pub fn sample_bilinear(&self, x: f32, y: f32) -> Option<f32> {
        // Exact in f32: sizes are at most MAX_DIM.
        let (xmax, ymax) = ((self.width - 1) as f32, (self.height - 1) as f32);
        if !(x >= 0.0 && y >= 0.0 && x <= xmax && y <= ymax) {
            return None;
        }
        // In range and non-negative: truncation is the floor.
        let (i, j) = (x as usize, y as usize);
        let (a, b) = (x - i as f32, y - j as f32);
        let (i1, j1) = (i + usize::from(a > 0.0), j + usize::from(b > 0.0));
        let (r0, r1) = (self.row(j)?, self.row(j1)?);
        let p = |r: &[u8], i: usize| f32::from(r.get(i).copied().unwrap_or(0));
        Some(
            (1.0 - a) * (1.0 - b) * p(r0, i)
                + a * (1.0 - b) * p(r0, i1)
                + (1.0 - a) * b * p(r1, i)
                + a * b * p(r1, i1),
        )
    }
}

impl<'a, P: Copy> ImageMut<'a, P> {
    /// A mutable view, validated as [`ImageView::new`].
    pub fn new(data: &'a mut [P], width: usize, height: usize, stride: usize) -> Result<Self> {
        validate(data.len(), width, height, stride)?;
        Ok(Self {
            data,
            width,
            height,
            stride,
        })
    }

    /// A tightly packed mutable view (`stride = width`).
    pub fn packed(data: &'a mut [P], width: usize, height: usize) -> Result<Self> {
        Self::new(data, width, height, width)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Elements from one row to the next.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// A read-only view of the same pixels.
    pub fn as_view(&self) -> ImageView<'_, P> {
        ImageView {
            data: self.data,
            width: self.width,
            height: self.height,
            stride: self.stride,
        }
    }

    /// Mutable row `y` (exactly `width` pixels), `None` when `y >= height`.
    #[inline]
    pub fn row_mut(&mut self, y: usize) -> Option<&mut [P]> {
        if y >= self.height {
            return None;
        }
        let start = y.checked_mul(self.stride)?;
        let end = start.checked_add(self.width)?;
        self.data.get_mut(start..end)
    }

    /// Sets pixel `(x, y)`; returns `false` (and writes nothing) outside the image.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: P) -> bool {
        if x >= self.width {
            return false;
        }
        match self.row_mut(y).and_then(|r| r.get_mut(x)) {
            Some(p) => {
                *p = v;
                true
            }
            None => false,
        }
    }

    /// Fills the image with `v`.
    pub fn fill(&mut self, v: P) {
        for y in 0..self.height {
            if let Some(r) = self.row_mut(y) {
                r.fill(v);
            }
        }
    }

    /// Copies `src`, row by row (any strides). Errors: [`Error::InvalidImage`] when the sizes
    /// differ.
    #[doc(alias = "copyTo")]
    pub fn copy_from(&mut self, src: &ImageView<'_, P>) -> Result<()> {
        if (src.width(), src.height()) != (self.width, self.height) {
            return Err(Error::InvalidImage);
        }
        for (y, from) in src.rows().enumerate() {
            let to = self.row_mut(y).ok_or(Error::InvalidImage)?;
            to.copy_from_slice(from.get(..to.len()).ok_or(Error::InvalidImage)?);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copy_from_copies_across_strides_and_rejects_other_sizes() {
        let src: std::vec::Vec<u8> = (0..24).collect();
        let view = ImageView::new(&src, 3, 4, 6).unwrap();
        let mut dst = [0u8; 12];
        ImageMut::packed(&mut dst, 3, 4)
            .unwrap()
            .copy_from(&view)
            .unwrap();
        assert_eq!(dst, [0, 1, 2, 6, 7, 8, 12, 13, 14, 18, 19, 20]);
        let mut small = [0u8; 9];
        let mut m = ImageMut::packed(&mut small, 3, 3).unwrap();
        assert_eq!(m.copy_from(&view), Err(Error::InvalidImage));
    }

    #[test]
    fn validation() {
        let buf = [0u8; 100];
        assert!(ImageView::new(&buf, 10, 10, 10).is_ok());
        // The last row need not be padded to the stride.
        assert!(ImageView::new(&buf[..94], 4, 10, 10).is_ok());
        assert_eq!(
            ImageView::new(&buf[..93], 4, 10, 10).err(),
            Some(Error::InvalidImage)
        );
        assert_eq!(
            ImageView::new(&buf, 0, 10, 10).err(),
            Some(Error::InvalidImage)
        );
        assert_eq!(
            ImageView::new(&buf, 10, 0, 10).err(),
            Some(Error::InvalidImage)
        );
        assert_eq!(
            ImageView::new(&buf, 11, 5, 10).err(),
            Some(Error::InvalidImage)
        );
        assert_eq!(
            ImageView::new(&buf, 10, 11, 10).err(),
            Some(Error::InvalidImage)
        );
        assert_eq!(
            ImageView::new(&buf, MAX_DIM + 1, 1, MAX_DIM + 1).err(),
            Some(Error::InvalidImage)
        );
        // Overflowing geometry is rejected, not wrapped.
        assert_eq!(
            ImageView::new(&buf, 1, usize::MAX, usize::MAX).err(),
            Some(Error::InvalidImage)
        );
    }

    #[test]
    fn rows_sub_and_access() {
        let buf: [u8; 30] = core::array::from_fn(|i| i as u8);
        let v = ImageView::new(&buf, 4, 3, 10).unwrap();
        assert_eq!(v.row(1), Some(&buf[10..14]));
        assert_eq!(v.row(3), None);
        assert_eq!(v.get(3, 2), Some(23));
        assert_eq!(v.get(4, 0), None);
        assert_eq!(v.row_clamped(-5), &buf[0..4]);
        assert_eq!(v.row_clamped(99), &buf[20..24]);
        assert_eq!(v.rows().count(), 3);
        let s = v.sub(1, 1, 3, 2).unwrap();
        assert_eq!(s.get(0, 0), Some(11));
        assert_eq!(s.get(2, 1), Some(23));
        assert_eq!(v.sub(2, 0, 3, 1).err(), Some(Error::InvalidImage));
        let mut m = [0u8; 12];
        let mut im = ImageMut::packed(&mut m, 4, 3).unwrap();
        assert!(im.set(3, 2, 7));
        assert!(!im.set(4, 2, 7));
        assert_eq!(im.as_view().get(3, 2), Some(7));
    }
}
