//! A ChArUco board's layout, as OpenCV's `aruco::CharucoBoard` (not its legacy pattern).

use nalgebra::Point2;

use crate::apriltag::Family;
use crate::{Error, Result};

/// A chessboard of `squares_x x squares_y` squares of side `square` whose white squares hold
/// ArUco markers of side `marker` from `dictionary`, laid out as OpenCV ≥ 4.6's
/// `cv2.aruco.CharucoBoard((squares_x, squares_y), square, marker, dictionary)` (its default,
/// non-legacy pattern).
///
/// Board frame: `x` along the columns, `y` down the rows (the board image as
/// `generateImage` draws it), `z` into the board, origin at the outer top-left corner;
/// square `(c, r)` spans `[c s, (c + 1) s] x [r s, (r + 1) s]`.
///
/// - Square `(c, r)` is black when `c + r` is even (the top-left square is black); each white
///   square holds a marker, centred, numbered `0, 1, …` row-major (row `r` first, then column
///   `c`): OpenCV's `getIds()`. Marker corners are OpenCV's `getObjPoints()` order: top-left,
///   top-right, bottom-right, bottom-left.
/// - The ChArUco corners are the inner chessboard corners, id `k = j (X - 1) + i` at
///   `((i + 1) s, (j + 1) s, 0)` for `i < X - 1`, `j < Y - 1` (OpenCV's
///   `getChessboardCorners()`); corner `(i, j)` touches squares `(i, j)`, `(i + 1, j)`,
///   `(i, j + 1)`, `(i + 1, j + 1)`, two of them white: its two adjacent markers.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CharucoBoard {
    squares_x: u16,
    squares_y: u16,
    square: f32,
    marker: f32,
    dictionary: &'static Family,
}

/// Largest squares per side (OpenCV has no limit; this keeps every id in `u16`).
pub const MAX_SQUARES: usize = 128;

impl CharucoBoard {
    /// A board of `squares_x x squares_y` squares (OpenCV's `size`), `square` and `marker`
    /// sides in any unit (the calibration's poses come out in it).
    ///
    /// Errors: `InvalidParameter("squares")` for fewer than 2 or more than [`MAX_SQUARES`]
    /// squares a side, `InvalidParameter("square")` / `("marker")` for a non-finite or
    /// non-positive side, or a marker not smaller than the square,
    /// `InvalidParameter("dictionary")` when the dictionary has fewer codes than the board's
    /// markers.
    pub fn new(
        squares_x: usize,
        squares_y: usize,
        square: f32,
        marker: f32,
        dictionary: &'static Family,
    ) -> Result<Self> {
        let side = 2..=MAX_SQUARES;
        if !side.contains(&squares_x) || !side.contains(&squares_y) {
            return Err(Error::InvalidParameter("squares"));
        }
        if !(square.is_finite() && square > 0.0) {
            return Err(Error::InvalidParameter("square"));
        }
        if !(marker.is_finite() && marker > 0.0 && marker < square) {
            return Err(Error::InvalidParameter("marker"));
        }
        let b = Self {
            squares_x: squares_x as u16,
            squares_y: squares_y as u16,
            square,
            marker,
            dictionary,
        };
        if b.markers() > dictionary.ncodes() {
            return Err(Error::InvalidParameter("dictionary"));
        }
        Ok(b)
    }

    /// Squares along `x` (columns).
    pub fn squares_x(&self) -> usize {
        usize::from(self.squares_x)
    }

    /// Squares along `y` (rows).
    pub fn squares_y(&self) -> usize {
        usize::from(self.squares_y)
    }

    /// Side of a square.
    pub fn square(&self) -> f32 {
        self.square
    }

    /// Side of a marker.
    pub fn marker(&self) -> f32 {
        self.marker
    }

    /// The markers' dictionary.
    pub fn dictionary(&self) -> &'static Family {
        self.dictionary
    }

    /// Markers on the board: the white squares, `⌊X Y / 2⌋`.
    pub fn markers(&self) -> usize {
        self.squares_x() * self.squares_y() / 2
    }

    /// ChArUco corners: `(X - 1)(Y - 1)`.
    pub fn corners(&self) -> usize {
        self.squares_x().saturating_sub(1) * self.squares_y().saturating_sub(1)
    }

    /// Corner `id` in the board frame, `((i + 1) s, (j + 1) s)`; `None` out of range.
    #[doc(alias = "getChessboardCorners")]
    pub fn corner(&self, id: usize) -> Option<Point2<f32>> {
        // `max(1)`: a board has 2 squares a side at least, but the optimiser cannot see it.
        let cols = self.squares_x().saturating_sub(1).max(1);
        (id < self.corners()).then(|| {
            Point2::new(
                ((id % cols) + 1) as f32 * self.square,
                ((id / cols) + 1) as f32 * self.square,
            )
        })
    }

    /// The marker in square `(c, r)`, `None` for a black square or one off the board.
    pub fn marker_at(&self, c: usize, r: usize) -> Option<usize> {
        let x = self.squares_x();
        if c >= x || r >= self.squares_y() || (c + r).is_multiple_of(2) {
            return None;
        }
        // White squares before (c, r) in row-major order.
        let before = r * x + c;
        // In a row starting black (r even) the white squares are the odd columns.
        Some(before / 2)
    }

    /// The square `(c, r)` holding marker `id`; `None` out of range.
    pub fn marker_square(&self, id: usize) -> Option<(usize, usize)> {
        if id >= self.markers() {
            return None;
        }
        // Row-major cell index of the id-th white cell: white cells are those with c + r odd,
        // i.e. every other cell of the row-major order starting from cell 1.
        let cell = 2 * id + 1;
        let x = self.squares_x().max(1);
        let (c, r) = (cell % x, cell / x);
        // With an even X, rows alternate their parity: in odd rows the white squares are the
        // even columns.
        if x.is_multiple_of(2) && !r.is_multiple_of(2) {
            Some((c.saturating_sub(1), r))
        } else {
            Some((c, r))
        }
    }

    /// Marker `id`'s corners in the board frame, OpenCV's `getObjPoints()` order (top-left,
    /// top-right, bottom-right, bottom-left); `None` out of range.
    pub fn marker_corners(&self, id: usize) -> Option<[Point2<f32>; 4]> {
        let (c, r) = self.marker_square(id)?;
        let d = 0.5 * (self.square - self.marker);
        let (x0, y0) = (c as f32 * self.square + d, r as f32 * self.square + d);
        let (x1, y1) = (x0 + self.marker, y0 + self.marker);
        Some([
            Point2::new(x0, y0),
            Point2::new(x1, y0),
            Point2::new(x1, y1),
            Point2::new(x0, y1),
        ])
    }

    /// The two markers adjacent to corner `id` (the white squares among the four it touches),
    /// `None` out of range.
    pub fn corner_markers(&self, id: usize) -> Option<[usize; 2]> {
        if id >= self.corners() {
            return None;
        }
        let cols = self.squares_x().saturating_sub(1).max(1);
        let (i, j) = (id % cols, id / cols);
        let mut out = [0usize; 2];
        let mut n = 0;
        for (c, r) in [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)] {
            if let (Some(m), Some(slot)) = (self.marker_at(c, r), out.get_mut(n)) {
                *slot = m;
                n += 1;
            }
        }
        (n == 2).then_some(out)
    }
}
