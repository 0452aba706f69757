//! One view's identified AprilGrid corners.

use heapless::Vec;
use nalgebra::Point2;

use super::AprilGrid;
use crate::apriltag::{Detection, Detector, Label, WorkspaceView};
use crate::chessboard::{SaddleParams, saddle_subpix};
use crate::image::ImageView;
use crate::{Error, Result};

/// One identified AprilGrid corner.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridCorner {
    /// The grid point ([`AprilGrid::point`]).
    pub id: u16,
    /// Pixel position (OpenCV's convention: pixel `(i, j)` centred at `(i, j)`).
    pub point: Point2<f32>,
}

/// The identified corners of `grid` from the tag `detections` of one view, written to `out`
/// in point order; their count.
///
/// A detection counts when it is of the grid's family ([`AprilGrid::family`]) and its id is
/// one of the grid's; an id found twice in the view is not used at all (Kalibr stops on it:
/// "wild AprilTag", a tag that is not the grid's; the detector has already merged two
/// detections of one tag). Each kept tag gives its 4 corners, as the detector refined them
/// (the edges of the border's outer square fitted to the image gradient and intersected), at
/// the points [`AprilGrid::tag_points`] names.
///
/// Errors: `BufferTooSmall("corners")` when `out` is shorter than the grid's points.
#[doc(alias = "computeObservation")]
pub fn grid_corners(
    grid: &AprilGrid,
    detections: &[Detection],
    out: &mut [GridCorner],
) -> Result<usize> {
    let points = grid.points();
    let Some(out) = out.get_mut(..points) else {
        return Err(Error::BufferTooSmall("corners"));
    };
    let family = grid.family();
    let ours = |d: &&Detection| d.family == family && usize::from(d.id) < grid.tags();
    // Point `k`'s pixel at `out[k]`, then compacted: the corners come out in point order.
    for slot in out.iter_mut() {
        *slot = GridCorner {
            id: u16::MAX,
            point: Point2::origin(),
        };
    }
    for d in detections.iter().filter(ours) {
        let copies = detections
            .iter()
            .filter(ours)
            .filter(|o| o.id == d.id)
            .count();
        let Some(ids) = grid.tag_points(usize::from(d.id)) else {
            continue;
        };
        if copies != 1 {
            continue;
        }
        for (&k, &p) in ids.iter().zip(d.corners.iter()) {
            if let Some(slot) = out.get_mut(k) {
                *slot = GridCorner {
                    id: k as u16,
                    point: p,
                };
            }
        }
    }
    let mut n = 0;
    for k in 0..points {
        if let Some(c) = out.get(k).copied()
            && c.id != u16::MAX
        {
            if let Some(slot) = out.get_mut(n) {
                *slot = c;
            }
            n += 1;
        }
    }
    Ok(n)
}

/// Largest move of a corner in [`refine_corners`], px: Kalibr's `maxSubpixDisplacement2`
/// (1.5 px²), as a distance.
pub const MAX_REFINE_SHIFT: f32 = 1.224_744_9;

/// Refines the first `n` corners of `corners` in `image` as saddle points
/// ([`saddle_subpix`]), Kalibr's `cornerSubPix` on its tag corners: the black squares Kalibr
/// prints at the tags' corners make each tag corner a chessboard-like crossing, point-
/// symmetric, whose saddle is the corner whatever the perspective and the lens (the tag
/// pipeline's corners are intersections of straight lines fitted to the edges, which the lens
/// bends). A corner is kept when the fit moved it, by at most [`MAX_REFINE_SHIFT`] (Kalibr
/// drops a corner that moves more), and it stays in the image; the kept ones are compacted to
/// the front in their order. Returns their count. A grid printed without the corner squares
/// has no saddle at its corners: refine only Kalibr's grids.
///
/// Errors: none; a corner that cannot be refined (no saddle, non-finite) is dropped.
#[doc(alias = "cornerSubPix")]
pub fn refine_corners(
    image: &ImageView<'_, u8>,
    corners: &mut [GridCorner],
    n: usize,
    params: &SaddleParams,
) -> Result<usize> {
    let (w, h) = (image.width() as f32, image.height() as f32);
    let mut kept = 0;
    for i in 0..n.min(corners.len()) {
        let Some(c) = corners.get(i).copied() else {
            break;
        };
        let mut q = [c.point];
        if saddle_subpix(image, &mut q, params).is_err() {
            continue;
        }
        let [p] = q;
        let shift = (p - c.point).norm();
        let inside = p.x >= 0.0 && p.y >= 0.0 && p.x <= w - 1.0 && p.y <= h - 1.0;
        let near = shift <= MAX_REFINE_SHIFT;
        if p == c.point || !near || !inside {
            continue;
        }
        if let Some(slot) = corners.get_mut(kept) {
            *slot = GridCorner { id: c.id, point: p };
            kept += 1;
        }
    }
    Ok(kept)
}

impl AprilGrid {
    /// Detects the grid's tags in `frame` with `detector` (which must decode
    /// [`AprilGrid::family`]; other families it decodes are ignored) into `tags` (at most `N`
    /// tags of the grid are kept, the best, as [`Detector::detect_into`] keeps them), writes
    /// the view's identified corners to `out` ([`grid_corners`]) and, with `saddle`, refines
    /// them as Kalibr does ([`refine_corners`]); their count.
    ///
    /// Errors: `InvalidParameter("detector")` when the detector does not decode the grid's
    /// family, `BufferTooSmall("corners")` when `out` is shorter than the grid's points, and
    /// the detector's errors (its workspace too small for the frame).
    pub fn detect_corners<const N: usize>(
        &self,
        detector: &Detector,
        frame: &ImageView<'_, u8>,
        ws: &mut WorkspaceView<'_, impl Label>,
        tags: &mut Vec<Detection, N>,
        saddle: Option<&SaddleParams>,
        out: &mut [GridCorner],
    ) -> Result<usize> {
        let family = self.family();
        if !detector.families().contains(&family) {
            return Err(Error::InvalidParameter("detector"));
        }
        if out.len() < self.points() {
            return Err(Error::BufferTooSmall("corners"));
        }
        let n = self.tags();
        detector.detect_into(
            frame,
            ws,
            &mut (),
            |f, id| f == family && usize::from(id) < n,
            tags,
        )?;
        let n = grid_corners(self, tags, out)?;
        match saddle {
            Some(params) => refine_corners(frame, out, n, params),
            None => Ok(n),
        }
    }
}
