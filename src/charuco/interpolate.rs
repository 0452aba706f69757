//! ChArUco corners from detected markers: each inner chessboard corner predicted from its
//! adjacent markers, then refined as the saddle point it is (OpenCV's
//! `interpolateCornersCharuco` / `CharucoDetector::detectBoard` without a camera).

use nalgebra::Point2;

use super::board::CharucoBoard;
use crate::apriltag::Detection;
use crate::chessboard::subpix::saddle_converged;
use crate::chessboard::{SaddleConfig, SaddleParams};
use crate::homography::{Homography, dlt};
use crate::image::ImageView;
use crate::{Error, Result};

/// How ChArUco corners are interpolated and kept.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CharucoConfig {
    /// Adjacent markers a corner needs (`1..=2`; OpenCV's `minMarkers`, default 2: both of
    /// its markers, so that a marker misread elsewhere cannot place a corner alone).
    pub min_markers: u8,
    /// The saddle-point refinement ([`crate::chessboard::saddle_subpix`]); a corner is kept
    /// only when it converges.
    pub saddle: SaddleConfig,
    /// A refined corner is kept when it moved at most this fraction of the local square side
    /// (in pixels) from its prediction (`0 < x ≤ 0.5`): a refinement that ran to another
    /// feature (a marker's corner) is dropped. The same fraction bounds how far the two
    /// markers' homography may miss their own corners.
    pub max_shift: f32,
}

impl Default for CharucoConfig {
    /// Both markers, the default saddle refinement, a shift of at most 0.2 square.
    fn default() -> Self {
        Self {
            min_markers: 2,
            saddle: SaddleConfig::default(),
            max_shift: 0.2,
        }
    }
}

/// A checked [`CharucoConfig`] (the default is the checked [`CharucoConfig::default`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CharucoParams {
    config: CharucoConfig,
    saddle: SaddleParams,
}

impl CharucoConfig {
    /// Checks the options.
    ///
    /// Errors: `InvalidParameter("min_markers")`, `InvalidParameter("max_shift")`, those of
    /// [`SaddleConfig::check`].
    pub fn check(&self) -> Result<CharucoParams> {
        if !(1..=2).contains(&self.min_markers) {
            return Err(Error::InvalidParameter("min_markers"));
        }
        if !(self.max_shift > 0.0 && self.max_shift <= 0.5) {
            return Err(Error::InvalidParameter("max_shift"));
        }
        Ok(CharucoParams {
            config: *self,
            saddle: self.saddle.check()?,
        })
    }
}

impl CharucoParams {
    /// The checked options.
    pub fn config(&self) -> &CharucoConfig {
        &self.config
    }
}

/// One identified ChArUco corner.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CharucoCorner {
    /// OpenCV's ChArUco corner id ([`CharucoBoard::corner`]).
    pub id: u16,
    /// Pixel position (OpenCV's convention: pixel `(i, j)` centred at `(i, j)`).
    pub point: Point2<f32>,
}

/// The one detection of `board`'s marker `id` in `markers`; `None` when it is missing or seen
/// more than once (ambiguous).
fn find(board: &CharucoBoard, markers: &[Detection], id: usize) -> Option<Detection> {
    let mut found = None;
    for m in markers {
        if usize::from(m.id) != id || m.family.name() != board.dictionary().name() {
            continue;
        }
        if found.is_some() {
            return None;
        }
        found = Some(*m);
    }
    found
}

/// The ChArUco corners of `board` in `image` from its detected `markers` (any detections: those
/// of other dictionaries or ids off the board are ignored, a marker id seen twice is not
/// used), written to `out` in id order; their count.
///
/// For each corner:
///
/// 1. **Prediction.** Each adjacent marker found gives the board-to-image homography of its 4
///    corners (board frame, [`CharucoBoard::marker_corners`], to the detection's
///    [`Detection::aruco_corners`]); with both markers found, one homography is fitted to
///    their 8 corners ([`dlt`]), which holds the perspective across the corner. The corner's
///    board point through it, moved by the mean residual of the markers' corners nearest to
///    it (detected minus mapped), is the prediction. On the board the ChArUco corner is the
///    midpoint of those two marker corners, `(s - m) √2` apart (0.38 square side on a
///    board of 30 mm squares and 22 mm markers), so the correction carries the lens's
///    bending at the corner itself, which one homography over both markers cannot (under a
///    fisheye lens near the frame's edge it misses the corner by up to several pixels,
///    beyond the refinement's reach). With
///    both markers' corners exact under a homography the correction is zero. At least
///    [`CharucoConfig::min_markers`] markers are needed. With both, the homography must fit
///    each of their 8 corners within [`CharucoConfig::max_shift`] square sides, else the
///    corner is refused: the two markers are not where the board puts them (an id misread,
///    another board's markers of the same dictionary). On the rendered sets the fit's worst
///    corner is 0.07 side under a fisheye lens at the frame's edge, and at least 0.4 side for
///    pairs of another board's layout (BENCHMARKS.md, "ChArUco calibration").
/// 2. **Refinement** as a saddle point ([`crate::chessboard::saddle_subpix`]): a ChArUco
///    corner is a chessboard corner, point-symmetric up to the markers' corners
///    `(s - m) / 2` away diagonally.
/// 3. **Check.** The corner is kept when the refinement converged (a fixed point of the
///    saddle fit; one that ends on a fit that is not a saddle, a step over a pixel or still
///    moving is refused: its window does not hold one clean saddle, as where a very oblique
///    view brings the markers' corners into it), moved by at most
///    [`CharucoConfig::max_shift`] times the local square side in pixels (the marker's mean
///    side times `s / m`), and lies far enough inside the image that the fit reads no pixel
///    past its border (the window's half side, the smoothing's `⌈3σ⌉` and one pixel).
///
/// Errors: `BufferTooSmall("corners")` when `out` is shorter than the board's corners.
#[doc(alias = "interpolateCornersCharuco")]
#[doc(alias = "detectBoard")]
#[doc(alias = "CharucoDetector")]
pub fn interpolate_corners(
    board: &CharucoBoard,
    image: &ImageView<'_, u8>,
    markers: &[Detection],
    params: &CharucoParams,
    out: &mut [CharucoCorner],
) -> Result<usize> {
    if out.len() < board.corners() {
        return Err(Error::BufferTooSmall("corners"));
    }
    let cfg = params.config;
    let (w, h) = (image.width() as f32, image.height() as f32);
    let reach = params.saddle.reach();
    let mut n = 0;
    for id in 0..board.corners() {
        let Some(([a, b], corner)) = board.corner_markers(id).zip(board.corner(id)) else {
            continue;
        };
        let (ma, mb) = (find(board, markers, a), find(board, markers, b));
        let found = [ma, mb].iter().flatten().count();
        if found < usize::from(cfg.min_markers) || found == 0 {
            continue;
        }
        let Some((pred, side)) = predict(board, corner, (a, ma), (b, mb), cfg.max_shift) else {
            continue;
        };
        let Ok(Some(p)) = saddle_converged(image, pred, &params.saddle) else {
            continue;
        };
        let shift = (p - pred).norm();
        let inside =
            p.x >= reach && p.y >= reach && p.x <= w - 1.0 - reach && p.y <= h - 1.0 - reach;
        if shift > cfg.max_shift * side || !inside {
            continue;
        }
        if let Some(slot) = out.get_mut(n) {
            *slot = CharucoCorner {
                id: id as u16,
                point: p,
            };
            n += 1;
        }
    }
    Ok(n)
}

/// The predicted pixel of the corner at board point `corner` from its markers `(id, found)`,
/// and the local square side in pixels: the markers' homography at `corner`, moved by the mean
/// residual of each marker's corner nearest to `corner` (see [`interpolate_corners`]); `None`
/// when the homography misses one of the markers' corners by more than `max_fit` square sides.
fn predict(
    board: &CharucoBoard,
    corner: Point2<f32>,
    a: (usize, Option<Detection>),
    b: (usize, Option<Detection>),
    max_fit: f32,
) -> Option<(Point2<f32>, f32)> {
    let mut src = [Point2::origin(); 8];
    let mut dst = [Point2::origin(); 8];
    // Each found marker's corner nearest to `corner`: board point and pixel.
    let mut near = [(Point2::origin(), Point2::origin()); 2];
    let mut k = 0;
    let mut m = 0;
    let mut side = 0.0f32;
    for (id, det) in [a, b] {
        let Some(det) = det else { continue };
        let obj = board.marker_corners(id)?;
        let px = det.aruco_corners();
        let mut best = (f32::INFINITY, Point2::origin(), Point2::origin());
        for (o, p) in obj.iter().zip(px.iter()) {
            *src.get_mut(k)? = *o;
            *dst.get_mut(k)? = *p;
            k += 1;
            let d = (o - corner).norm();
            if d < best.0 {
                best = (d, *o, *p);
            }
        }
        *near.get_mut(m)? = (best.1, best.2);
        m += 1;
        let perimeter: f32 = (0..4)
            .map(|i| (px.get((i + 1) % 4)? - px.get(i)?).norm().into())
            .sum::<Option<f32>>()?;
        side = side.max(0.25 * perimeter * board.square() / board.marker());
    }
    let hom: Homography<f32> = dlt(src.get(..k)?, dst.get(..k)?).ok()?;
    // Both markers where the board puts them: one homography fits all their corners.
    for (o, px) in src.iter().zip(dst.iter()).take(k) {
        let miss = (hom.transfer(o).ok()? - px).norm();
        if miss.is_nan() || miss > max_fit * side {
            return None;
        }
    }
    let mut p = hom.transfer(&corner).ok()?;
    let mut correction = nalgebra::Vector2::zeros();
    for (o, px) in near.get(..m)? {
        correction += px - hom.transfer(o).ok()?;
    }
    p += correction / m as f32;
    let ok = side.is_finite() && side > 0.0 && p.x.is_finite() && p.y.is_finite();
    ok.then_some((p, side))
}
