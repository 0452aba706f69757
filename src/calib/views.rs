//! The views a calibration is made from: the board, the image size and each view's corners,
//! normalised so that every unknown and every residual is of order one.

use nalgebra::{Point2, Point3};

use crate::camera::{CAMERA_PARAMETERS, Camera};
use crate::chessboard::{BoardSize, Chessboard};
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Up to `V` views of a board of at most `P` inner corners, in fixed memory. Pixels are held
/// as `u' = (u - c₀) / s`, `c₀` the image centre and `s = max(width, height)`; board corners
/// are `(i, j, 0)` in squares.
#[derive(Debug, Clone)]
pub(super) struct Views<T: Real, const V: usize, const P: usize> {
    cols: usize,
    rows: usize,
    /// The side of a square, in the caller's unit.
    pub(super) square: T,
    pub(super) width: usize,
    pub(super) height: usize,
    /// Views added.
    pub(super) count: usize,
    /// Normalised observations `(u - c₀) / s`, row-major board order.
    pub(super) obs: [[Point2<T>; P]; V],
}

impl<T: Real, const V: usize, const P: usize> Views<T, V, P> {
    /// No views yet of `board` with squares of side `square` in `width x height` images.
    ///
    /// Errors: `InvalidParameter("square")` for a zero, negative or non-finite square,
    /// `BufferTooSmall("corners")` when the board has more than `P` corners,
    /// [`Error::InvalidImage`] for a zero-sized image.
    pub(super) fn new(board: BoardSize, square: T, width: usize, height: usize) -> Result<Self> {
        if !(square.finite() && above(square, T::zero())) {
            return Err(Error::InvalidParameter("square"));
        }
        if board.corners() > P {
            return Err(Error::BufferTooSmall("corners"));
        }
        if width == 0
            || height == 0
            || width > crate::image::MAX_DIM
            || height > crate::image::MAX_DIM
        {
            return Err(Error::InvalidImage);
        }
        Ok(Self {
            cols: board.cols(),
            rows: board.rows(),
            square,
            width,
            height,
            count: 0,
            obs: [[Point2::origin(); P]; V],
        })
    }

    /// Corners of the board.
    pub(super) fn corners(&self) -> usize {
        self.cols * self.rows
    }

    /// `s = max(width, height)`.
    pub(super) fn scale(&self) -> T {
        T::lit(self.width.max(self.height) as f64)
    }

    /// `c₀ = ((w - 1)/2, (h - 1)/2)`.
    pub(super) fn centre(&self) -> Point2<T> {
        Point2::new(
            T::lit((self.width as f64 - 1.0) * 0.5),
            T::lit((self.height as f64 - 1.0) * 0.5),
        )
    }

    /// Adds one view (see `Calibrator::add_view`); its index.
    pub(super) fn add(
        &mut self,
        width: usize,
        height: usize,
        corners: &[Point2<T>],
    ) -> Result<usize> {
        if width != self.width || height != self.height {
            return Err(Error::InvalidImage);
        }
        if corners.len() != self.corners() {
            return Err(Error::LengthMismatch);
        }
        for c in corners {
            check_finite(&[c.x, c.y])?;
        }
        let (c0, s) = (self.centre(), self.scale());
        let slot = self
            .obs
            .get_mut(self.count)
            .ok_or(Error::BufferTooSmall("views"))?;
        for (o, c) in slot.iter_mut().zip(corners) {
            *o = Point2::from((c - c0) / s);
        }
        self.count += 1;
        Ok(self.count - 1)
    }

    /// [`Self::add`] of a detected board (its corners converted to `T`).
    pub(super) fn add_chessboard<const N: usize>(
        &mut self,
        width: usize,
        height: usize,
        board: &Chessboard<N>,
    ) -> Result<usize> {
        if board.size.cols() != self.cols || board.size.rows() != self.rows {
            return Err(Error::LengthMismatch);
        }
        let mut pts = [Point2::origin(); P];
        let n = board.corners.len();
        for (o, c) in pts.iter_mut().zip(board.corners.iter()) {
            *o = Point2::new(T::lit(c.x as f64), T::lit(c.y as f64));
        }
        self.add(width, height, pts.get(..n).ok_or(Error::LengthMismatch)?)
    }

    /// Board corner `k` in squares, `(i, j, 0)`.
    pub(super) fn board_point(&self, k: usize) -> Point3<T> {
        Point3::new(
            // `max(1)`: `BoardSize` has at least one column, but the optimiser cannot see it.
            T::lit((k % self.cols.max(1)) as f64),
            T::lit((k / self.cols.max(1)) as f64),
            T::zero(),
        )
    }

    /// The board's corners `(i, j)` in squares, the first [`Self::corners`] of them set.
    pub(super) fn board_plane(&self) -> [Point2<T>; P] {
        let mut model = [Point2::origin(); P];
        for (k, m) in model.iter_mut().take(self.corners()).enumerate() {
            let b = self.board_point(k);
            *m = Point2::new(b.x, b.y);
        }
        model
    }

    /// View `v`'s normalised corners.
    pub(super) fn view_obs(&self, v: usize) -> &[Point2<T>] {
        let n = self.corners();
        self.obs.get(v).and_then(|o| o.get(..n)).unwrap_or_default()
    }

    /// A camera as the normalised parameter vector `(fx, fy, cx, cy) / s` (the principal
    /// point from `c₀`) and its lens coefficients.
    pub(super) fn normalised(&self, camera: &Camera<T>) -> [T; CAMERA_PARAMETERS] {
        let (s, c0) = (self.scale(), self.centre());
        let k = &camera.intrinsics;
        let [c1, c2, c3, c4, c5] = camera.lens.coefficients();
        [
            k.fx() / s,
            k.fy() / s,
            (k.cx() - c0.x) / s,
            (k.cy() - c0.y) / s,
            c1,
            c2,
            c3,
            c4,
            c5,
        ]
    }
}
