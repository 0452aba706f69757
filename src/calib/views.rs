//! The views a calibration is made from: the board's points, the image size and each view's
//! identified observations, normalised so that every unknown and every residual is of order
//! one.
//!
//! A view holds any subset of the board's points (a ChArUco or AprilGrid board partly out of
//! frame): `ids[v][..len[v]]` are indices into the board's points and `obs[v][..len[v]]` their
//! pixels, in the order added. A full chessboard view is the subset `0, 1, …, n - 1`, so its
//! sums run in the same order as before the subsets existed.

use nalgebra::{Point2, Point3};

use super::report::ViewRejection;
use crate::camera::{CAMERA_PARAMETERS, Camera};
use crate::chessboard::{BoardSize, Chessboard};
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Up to `V` views of a board of at most `P` points, in fixed memory. Pixels are held as
/// `u' = (u - c₀) / s`, `c₀` the image centre and `s = max(width, height)`; board points are
/// held in units of the board's scale (the square of a chessboard: corner `(i, j, 0)`).
#[derive(Debug, Clone)]
pub(super) struct Views<T: Real, const V: usize, const P: usize> {
    /// The chessboard the points are the corners of, `None` for a general point set.
    board: Option<BoardSize>,
    /// Board points in units of `square`, the first `points` set.
    plane: [Point2<T>; P],
    points: usize,
    /// The board's unit (a chessboard's square side) in the caller's unit.
    pub(super) square: T,
    pub(super) width: usize,
    pub(super) height: usize,
    /// Views added.
    pub(super) count: usize,
    /// Observations per view.
    len: [u16; V],
    /// Per view: the board point of each observation.
    ids: [[u16; P]; V],
    /// Normalised observations `(u - c₀) / s`, in the order of `ids`.
    pub(super) obs: [[Point2<T>; P]; V],
}

/// Checks of a board's scale and an image size.
fn check_common<T: Real>(square: T, width: usize, height: usize) -> Result<()> {
    if !(square.finite() && above(square, T::zero())) {
        return Err(Error::InvalidParameter("square"));
    }
    if width == 0 || height == 0 || width > crate::image::MAX_DIM || height > crate::image::MAX_DIM
    {
        return Err(Error::InvalidImage);
    }
    Ok(())
}

impl<T: Real, const V: usize, const P: usize> Views<T, V, P> {
    /// No views yet of `board` with squares of side `square` in `width x height` images.
    ///
    /// Errors: `InvalidParameter("square")` for a zero, negative or non-finite square,
    /// `BufferTooSmall("corners")` when the board has more than `P` corners,
    /// [`Error::InvalidImage`] for a zero-sized image.
    pub(super) fn new(board: BoardSize, square: T, width: usize, height: usize) -> Result<Self> {
        check_common(square, width, height)?;
        if board.corners() > P || board.corners() > usize::from(u16::MAX) {
            return Err(Error::BufferTooSmall("corners"));
        }
        let cols = board.cols().max(1);
        let mut plane = [Point2::origin(); P];
        for (k, m) in plane.iter_mut().take(board.corners()).enumerate() {
            *m = Point2::new(T::lit((k % cols) as f64), T::lit((k / cols) as f64));
        }
        Ok(Self::empty(
            Some(board),
            plane,
            board.corners(),
            square,
            width,
            height,
        ))
    }

    /// No views yet of the planar board points `points` (caller's unit, `z = 0`), held in units
    /// of `scale`, in `width x height` images.
    ///
    /// Errors: `InvalidParameter("square")` for a zero, negative or non-finite scale,
    /// `BufferTooSmall("corners")` for more than `P` points, [`Error::TooFewPoints`] for fewer
    /// than 4, [`Error::NonFinite`], [`Error::InvalidImage`] for a zero-sized image.
    pub(super) fn with_points(
        points: &[Point2<T>],
        scale: T,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        check_common(scale, width, height)?;
        if points.len() > P || points.len() > usize::from(u16::MAX) {
            return Err(Error::BufferTooSmall("corners"));
        }
        if points.len() < 4 {
            return Err(Error::TooFewPoints);
        }
        let mut plane = [Point2::origin(); P];
        for (m, p) in plane.iter_mut().zip(points) {
            check_finite(&[p.x, p.y])?;
            *m = Point2::from(p.coords / scale);
            check_finite(&[m.x, m.y])?;
        }
        Ok(Self::empty(None, plane, points.len(), scale, width, height))
    }

    fn empty(
        board: Option<BoardSize>,
        plane: [Point2<T>; P],
        points: usize,
        square: T,
        width: usize,
        height: usize,
    ) -> Self {
        Self {
            board,
            plane,
            points,
            square,
            width,
            height,
            count: 0,
            len: [0; V],
            ids: [[0; P]; V],
            obs: [[Point2::origin(); P]; V],
        }
    }

    /// Points of the board.
    pub(super) fn corners(&self) -> usize {
        self.points
    }

    /// Observations of view `v`.
    pub(super) fn len(&self, v: usize) -> usize {
        self.len.get(v).map_or(0, |&n| usize::from(n))
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

    /// Adds one view of every board point in the board's order (see `Calibrator::add_view`);
    /// its index.
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
        self.add_subset(width, height, 0..corners.len(), corners)
    }

    /// Adds one view of the board points `ids` seen at `pixels` (see
    /// `Calibrator::add_points`); its index.
    pub(super) fn add_points(
        &mut self,
        width: usize,
        height: usize,
        ids: &[usize],
        pixels: &[Point2<T>],
    ) -> Result<usize> {
        if width != self.width || height != self.height {
            return Err(Error::InvalidImage);
        }
        if ids.len() != pixels.len() {
            return Err(Error::LengthMismatch);
        }
        for (k, &id) in ids.iter().enumerate() {
            if id >= self.points || ids.iter().take(k).any(|&j| j == id) {
                return Err(Error::InvalidParameter("ids"));
            }
        }
        self.add_subset(width, height, ids.iter().copied(), pixels)
    }

    /// Stores a view of checked, distinct ids.
    fn add_subset(
        &mut self,
        width: usize,
        height: usize,
        ids: impl Iterator<Item = usize>,
        pixels: &[Point2<T>],
    ) -> Result<usize> {
        if width != self.width || height != self.height {
            return Err(Error::InvalidImage);
        }
        if pixels.len() > P {
            return Err(Error::LengthMismatch);
        }
        for c in pixels {
            check_finite(&[c.x, c.y])?;
        }
        let (c0, s) = (self.centre(), self.scale());
        let v = self.count;
        let (Some(slot), Some(slot_ids), Some(slot_len)) = (
            self.obs.get_mut(v),
            self.ids.get_mut(v),
            self.len.get_mut(v),
        ) else {
            return Err(Error::BufferTooSmall("views"));
        };
        for ((o, i), (c, id)) in slot
            .iter_mut()
            .zip(slot_ids.iter_mut())
            .zip(pixels.iter().zip(ids))
        {
            *o = Point2::from((c - c0) / s);
            *i = u16::try_from(id).map_err(|_| Error::InvalidParameter("ids"))?;
        }
        *slot_len = u16::try_from(pixels.len()).map_err(|_| Error::LengthMismatch)?;
        self.count += 1;
        Ok(v)
    }

    /// [`Self::add`] of a detected board (its corners converted to `T`).
    pub(super) fn add_chessboard<const N: usize>(
        &mut self,
        width: usize,
        height: usize,
        board: &Chessboard<N>,
    ) -> Result<usize> {
        match self.board {
            Some(b) if b.cols() == board.size.cols() && b.rows() == board.size.rows() => {}
            _ => return Err(Error::LengthMismatch),
        }
        let mut pts = [Point2::origin(); P];
        let n = board.corners.len();
        for (o, c) in pts.iter_mut().zip(board.corners.iter()) {
            *o = Point2::new(T::lit(c.x as f64), T::lit(c.y as f64));
        }
        self.add(width, height, pts.get(..n).ok_or(Error::LengthMismatch)?)
    }

    /// Board point `k` in board units, `(x, y, 0)`.
    pub(super) fn board_point(&self, k: usize) -> Point3<T> {
        let p = self.plane.get(k).copied().unwrap_or(Point2::origin());
        Point3::new(p.x, p.y, T::zero())
    }

    /// View `v`'s observations as `(board point, normalised pixel)` pairs.
    pub(super) fn pairs(&self, v: usize) -> impl Iterator<Item = (Point3<T>, Point2<T>)> + '_ {
        let n = self.len(v);
        let ids = self.ids.get(v).and_then(|i| i.get(..n)).unwrap_or_default();
        let obs = self.obs.get(v).and_then(|o| o.get(..n)).unwrap_or_default();
        ids.iter()
            .zip(obs)
            .map(|(&k, &o)| (self.board_point(usize::from(k)), o))
    }

    /// View `v`'s board points `(x, y)` (the first [`Self::len`] set) and its normalised
    /// observations.
    pub(super) fn view_plane(&self, v: usize) -> ([Point2<T>; P], &[Point2<T>]) {
        let mut model = [Point2::origin(); P];
        for (m, (b, _)) in model.iter_mut().zip(self.pairs(v)) {
            *m = Point2::new(b.x, b.y);
        }
        let n = self.len(v);
        (
            model,
            self.obs.get(v).and_then(|o| o.get(..n)).unwrap_or_default(),
        )
    }

    /// Why view `v` cannot be used whatever the camera: fewer than 4 points, or its board
    /// points on a line (the smaller eigenvalue of their 2x2 scatter matrix below `10⁻⁶` of
    /// the larger: a homography needs two independent directions). `None` for a usable view.
    pub(super) fn check_view(&self, v: usize) -> Option<ViewRejection> {
        let n = self.len(v);
        if n < 4 {
            return Some(ViewRejection::TooFewPoints);
        }
        let nf = T::lit(n as f64);
        let (mut mx, mut my) = (T::zero(), T::zero());
        for (b, _) in self.pairs(v) {
            mx += b.x;
            my += b.y;
        }
        let (mx, my) = (mx / nf, my / nf);
        let (mut a, mut b, mut c) = (T::zero(), T::zero(), T::zero());
        for (p, _) in self.pairs(v) {
            let (dx, dy) = (p.x - mx, p.y - my);
            a += dx * dx;
            b += dx * dy;
            c += dy * dy;
        }
        let half = (a + c) * T::lit(0.5);
        let r = ((a - c) * (a - c) * T::lit(0.25) + b * b).sqrt();
        let (small, large) = (half - r, half + r);
        if !above(small, T::lit(1e-6) * large) {
            return Some(ViewRejection::Degenerate);
        }
        None
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
