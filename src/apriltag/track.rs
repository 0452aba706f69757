//! Tracking a tag by detecting it where it must be: the detector's own steps run around a
//! predicted quad only.
//!
//! Given the corners a tag is predicted to have in a frame (from the last frames' corners, or
//! a homography), two searches of increasing cost find it again, and a third finds it partly
//! seen:
//!
//! 1. **Edge refinement from the prediction** ([`Detector::refine_target`]): the detector's
//!    edge refinement ([`super::decode`]) runs on the predicted quad, first across `±4` and
//!    `±3` px of each edge (8 edge points an edge), then across `±2` px (24 points an edge) as
//!    it runs on a fitted quad, until no corner moves more than 0.02 px (at most 4 times); the
//!    quad is kept when the last pass moved no corner more than 0.1 px, every edge's points lie
//!    within 0.05 px² (mean squared) of its line and gave a point at 3 of 4 positions (an
//!    occluder crossing an edge fails this), and the code read is the tag's own in the
//!    predicted orientation within the detector's `max_hamming` bits. A few thousand bilinear
//!    samples: no pass over the frame.
//! 2. **Detection in a region of interest** ([`Detector::find_target_near`]): the whole
//!    pipeline (threshold, components, quad fit, edge refinement, decoding) on the rectangle
//!    around the prediction, widened by a quarter of the tag's side and 8 px, its origin on the
//!    detector's tile grid (a multiple of `4 · decimate`).
//!
//! Both keep the detector's rules (`reject_clipped`, `min_decision_margin`): a corner they give
//! is measured as a detection's is, so a pose from it is as good as a detection's.
//!
//! 3. **A partly seen tag** ([`Detector::refine_partial`]): when something lies over the tag or
//!    the frame's edge cuts it, the same passes from the prediction with a robust fit of each
//!    edge ([`super::robust_edges`]: the points of the hidden or clipped part dropped), the
//!    corners where the fitted lines meet, and only the seen cells read, which must confirm the
//!    tag's code within a budget of bits that follows from the family
//!    ([`super::visible_code`]). Refused when an edge is seen over less than half its length or
//!    by fewer than 8 points, or too few cells are seen; what it gives is flagged as partly
//!    seen ([`PartialView`]), never passed off as a whole detection.

use heapless::Vec;
use nalgebra::Point2;

use super::decode::{read_code, refine_edges_with};
use super::detector::{Detection, Detector};
use super::family::{Family, Kind};
use super::geom::{at4, project};
use super::label::Label;
use super::quad::Quad;
use super::robust_edges::{EdgeSupport, robust_edges, share_in_frame};
use super::visible_code::{Hidden, NotConfirmed, confirm, read_visible};
use super::workspace::WorkspaceView;
use crate::Result;
use crate::homography::Homography;
use crate::image::ImageView;
use crate::scalar::at_most;

/// Edge refinement passes from a prediction, the `decimate` argument of the refinement (its
/// search runs across `±(d + 1)` px of the edge): two wide passes for the prediction's error.
const WIDE: [usize; 2] = [3, 2];

/// Edge points an edge in the wide passes (at least; the narrow passes take AprilTag's 16):
/// they only bring the quad within the narrow passes' reach.
const WIDE_POINTS: usize = 8;

/// Edge points an edge in the narrow passes (at least).
const NARROW_POINTS: usize = 24;

/// Then passes at the detector's own width (`d = 1`, `±2` px) until no corner moves more than
/// [`CONVERGED`] px, at most this many.
const NARROW: usize = 4;

/// A narrow pass that moves no corner more than this (pixels) ends the refinement; the quad is
/// rejected when the last one still moved more than [`UNSETTLED`].
const CONVERGED: f32 = 0.02;

/// See [`CONVERGED`].
const UNSETTLED: f32 = 0.1;

/// An edge whose points lie further from their line than this, mean squared (px²), was not
/// measured on the tag's edge alone (an occluder crosses it): the quad is rejected. On the
/// rendered tag sequence the edges of the frames tracked lie within 0.009 px², those crossed by
/// the bar at 0.22 to 0.49 px².
const MAX_EDGE_MSE: f32 = 0.05;

/// The smallest share of an edge's sample positions that must give an edge point.
const MIN_EDGE_SHARE: f32 = 0.75;

/// A refined corner may move at most this many pixels from the prediction (the wide passes'
/// reach, 4 + 3 px, and a pixel).
const MAX_SHIFT: f32 = 8.0;

/// A partly seen tag's edge must span at least this share of its length with inliers: its
/// line then reaches a corner it does not see over at most as far again as it was measured.
const MIN_PARTIAL_SPAN: f32 = 0.5;

/// A partly seen tag's edge needs at least this many inliers (and a third of its positions).
const MIN_PARTIAL_INLIERS: u8 = 8;

/// Tag coordinates of the target's corners `(0, 0), (w, 0), (w, h), (0, h)`: the upright tag's
/// top-left, top-right, bottom-right, bottom-left ([`Detection::target_corners`]).
const TARGET_TAG_COORDS: [Point2<f32>; 4] = [
    Point2::new(-1.0, -1.0),
    Point2::new(1.0, -1.0),
    Point2::new(1.0, 1.0),
    Point2::new(-1.0, 1.0),
];

/// What the refinement from a prediction found: the corners in the target's order, `H` (tag
/// coordinates to pixels), the Hamming distance to the tag's code and the decision margin.
struct Refined {
    corners: [Point2<f32>; 4],
    homography: Homography<f32>,
    hamming: u8,
    margin: f32,
}

/// A tag found again from a prediction while partly seen ([`Detector::refine_partial`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PartialDetection {
    /// The tag as a detection reports it: `hamming` counts the seen cells that differ from the
    /// tag's code, `decision_margin` is over the seen cells; the corners are the intersections
    /// of the fitted edges, a corner outside the frame or hidden included.
    pub detection: Detection,
    /// What of it was seen.
    pub view: PartialView,
}

/// What of a partly seen tag was measured ([`PartialDetection`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PartialView {
    /// Per edge, in the target's order (top, right, bottom, left of the upright tag: from
    /// [`Detection::target_corners`]`[i]` to `[i + 1]`): the share of its length between its
    /// first and last inlier edge point.
    pub edge_span: [f32; 4],
    /// Per edge: its inlier edge points.
    pub edge_inliers: [u8; 4],
    /// Per edge: the positions sampled.
    pub edge_samples: [u8; 4],
    /// Payload cells seen (in the frame and away from what hides the tag).
    pub cells_seen: u8,
    /// Seen cells allowed to differ from the code (from the family and the cells seen:
    /// [`Detector::refine_partial`]).
    pub cells_budget: u8,
    /// Whether something lay over the tag's edges (not only the frame's edge cutting it).
    pub occluded: bool,
}

/// Why [`Detector::refine_partial`] refused a tag.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum PartialRefusal {
    /// The prediction is not finite, or its quad does not give a homography.
    Prediction,
    /// The id is not one of the family's, or the family is an ArUco dictionary (whose border
    /// cells OpenCV's decision needs whole).
    Unsupported,
    /// The refinement still moved, or moved a corner more than 8 px from the prediction.
    Unsettled,
    /// An edge (its index in the target's order) gave too few inlier points.
    FewEdgePoints(u8),
    /// An edge's inliers span less than half of it.
    ShortEdge(u8),
    /// The seen quiet zone and border do not give the intensity models, or not the family's
    /// polarity.
    NoContrast,
    /// The seen cells' decision margin is below the detector's `min_decision_margin`.
    WeakCode,
    /// Too few payload cells seen to confirm the tag.
    FewCells,
    /// The seen cells differ from the tag's code by more than the budget.
    NotConfirmed,
}

/// The region [`Detector::find_target_near`] searches for `predicted` in a `w x h` frame:
/// `(x, y, width, height)`, `None` when the prediction is not finite or the region is empty.
fn region(
    predicted: &[Point2<f32>; 4],
    w: usize,
    h: usize,
    align: usize,
) -> Option<(usize, usize, usize, usize)> {
    if !predicted.iter().all(|p| p.x.is_finite() && p.y.is_finite()) {
        return None;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    let mut side = 0.0f32;
    for (i, p) in predicted.iter().enumerate() {
        x0 = x0.min(p.x);
        y0 = y0.min(p.y);
        x1 = x1.max(p.x);
        y1 = y1.max(p.y);
        let q = predicted.get((i + 1) % 4).copied().unwrap_or(*p);
        side = side.max((q - p).norm());
    }
    let margin = 0.25 * side + 8.0;
    let (wf, hf) = (w as f32, h as f32);
    // Clamped to the frame before the casts (saturating, and NaN-free from the check above).
    let xa = (x0 - margin).clamp(0.0, wf) as usize;
    let ya = (y0 - margin).clamp(0.0, hf) as usize;
    let xb = libm::ceilf((x1 + margin).clamp(0.0, wf)) as usize;
    let yb = libm::ceilf((y1 + margin).clamp(0.0, hf)) as usize;
    let align = align.max(1);
    let (xa, ya) = (xa - xa % align, ya - ya % align);
    let (xb, yb) = (xb.min(w), yb.min(h));
    if xb <= xa || yb <= ya {
        return None;
    }
    Some((xa, ya, xb - xa, yb - ya))
}

/// The passes of a refinement from `predicted` (module docs): `pass(q, d, points)` runs one
/// (the detector's edge refinement or the robust one) across `±(d + 1)` px with at least
/// `points` edge points an edge. Returns the quad and the last pass's outcome when that pass
/// moved no corner more than [`UNSETTLED`] and every corner is finite and within
/// [`MAX_SHIFT`] of the prediction.
fn settle<F>(
    predicted: &[Point2<f32>; 4],
    reversed_border: bool,
    mut pass: impl FnMut(&mut Quad, usize, usize) -> F,
) -> Option<(Quad, F)> {
    let mut q = Quad {
        p: *predicted,
        reversed_border,
    };
    for d in WIDE {
        let _ = pass(&mut q, d, WIDE_POINTS);
    }
    let mut moved = f32::INFINITY;
    let mut fit = None;
    for _ in 0..NARROW {
        let before = q.p;
        fit = Some(pass(&mut q, 1, NARROW_POINTS));
        moved =
            q.p.iter()
                .zip(before.iter())
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f32::max);
        if moved <= CONVERGED {
            break;
        }
    }
    if !crate::scalar::at_most(moved, UNSETTLED) {
        return None;
    }
    let fit = fit?;
    for (p, o) in q.p.iter().zip(predicted) {
        if !(p.x.is_finite() && p.y.is_finite()) || (p - o).norm() > MAX_SHIFT {
            return None;
        }
    }
    Some((q, fit))
}

impl Detector {
    /// Tag `id` of `family` found again from `predicted`, its four corners predicted for this
    /// frame in a planar target's order ([`Detection::target_corners`]): the detector's edge
    /// refinement run from the prediction, the refined quad decoded (module docs). Returns the
    /// refined corners in the same order when the code read is the tag's own in that
    /// orientation, within the detector's `max_hamming` bits and `min_decision_margin`, with
    /// the quiet zone in view when the detector rejects clipped tags, the edges' fits as the
    /// module docs say, and no corner moved more than 8 px; `None` otherwise (a prediction that
    /// is not finite included).
    ///
    /// Cost: `2 · 4 · max(8, side / 8)` edge points of 33 to 41 bilinear samples, then up to
    /// `4 · 4 · max(24, side / 8)` of 25, and one decoding; no pass over the frame.
    pub fn refine_target(
        &self,
        frame: &ImageView<'_, u8>,
        family: &Family,
        id: u16,
        predicted: &[Point2<f32>; 4],
    ) -> Option<[Point2<f32>; 4]> {
        self.refine(frame, family, id, predicted).map(|r| r.corners)
    }

    /// [`Self::refine_target`] as a [`Detection`]: the tag `id` of `family` found again from
    /// `predicted` (a planar target's corner order, e.g. the last frame's
    /// [`Detection::target_corners`]), with its Hamming distance to the tag's code, the
    /// decision margin, the corners in AprilTag's order, the centre and `H`, as
    /// [`Detector::detect`] reports a tag. `None` as [`Self::refine_target`].
    pub fn refine_detection(
        &self,
        frame: &ImageView<'_, u8>,
        family: &'static Family,
        id: u16,
        predicted: &[Point2<f32>; 4],
    ) -> Option<Detection> {
        let Refined {
            corners: t,
            homography,
            hamming,
            margin: decision_margin,
        } = self.refine(frame, family, id, predicted)?;
        let center = project(homography.matrix(), 0.0, 0.0)?;
        let [a, b, c, d] = t;
        Some(Detection {
            family,
            id,
            hamming,
            decision_margin,
            corners: [d, c, b, a],
            center,
            homography,
        })
    }

    /// The refinement of [`Self::refine_target`].
    fn refine(
        &self,
        frame: &ImageView<'_, u8>,
        family: &Family,
        id: u16,
        predicted: &[Point2<f32>; 4],
    ) -> Option<Refined> {
        if !predicted.iter().all(|p| p.x.is_finite() && p.y.is_finite()) {
            return None;
        }
        let code = family.codes.get(usize::from(id))?;
        let (q, fit) = settle(predicted, family.reversed_border, |q, d, n| {
            refine_edges_with(frame, q, d, n)
        })?;
        if !(fit.worst_mse <= MAX_EDGE_MSE && fit.fewest >= MIN_EDGE_SHARE) {
            return None;
        }
        let h = Homography::from_four_points(&TARGET_TAG_COORDS, &q.p).ok()?;
        let cfg = self.config();
        let reading = read_code(frame, h.matrix(), family, cfg.decode_sharpening)?;
        if cfg.reject_clipped && !reading.ring_in_view {
            return None;
        }
        if !crate::scalar::at_most(cfg.min_decision_margin.max(0.0), reading.margin) {
            return None;
        }
        let lim = self.limits(family);
        if reading.border_errors > lim.max_border_errors
            || !crate::scalar::at_most(lim.min_contrast, reading.contrast)
        {
            return None;
        }
        let hamming = (reading.rcode ^ code).count_ones();
        if hamming > u32::from(lim.max_hamming) {
            return None;
        }
        Some(Refined {
            corners: q.p,
            homography: h,
            hamming: hamming as u8,
            margin: reading.margin,
        })
    }

    /// Tag `id` of `family` found again from `predicted` (a planar target's corner order) when
    /// only part of it is seen: something lies over it, or the frame's edge cuts it (where
    /// [`Self::refine_target`] refuses it).
    ///
    /// - **Edges**: refined from the prediction in the same passes, each fitted robustly:
    ///   edge points whose step is weaker than half the quad's median step (an occluder
    ///   darker than the paper, lighter than the ink) are dropped, and the line is the
    ///   consensus of the others (pairs of points as hypotheses, MSAC), refitted by least
    ///   squares on its inliers (within 0.3 px, three times a seen edge's scatter). The
    ///   corners are the fitted lines' intersections, a corner hidden or outside the frame
    ///   included.
    /// - **Cells**: the parts of the edges that gave no inlier mark what hides the tag; the
    ///   hull of their ends (and each carried a cell outward, over the quiet zone), with 2 px
    ///   around it, and what is outside the frame are not read. The `n` payload cells seen
    ///   must confirm the tag's code in the predicted orientation: at most `b` differ, the
    ///   largest `b ≤ h` (`h` the detector's `max_hamming`) with
    ///   `Σ_{j≤b} C(n, j) / 2ⁿ ≤ 4 K Σ_{j≤h} C(N, j) / 2ᴺ` (a random pattern passes no more
    ///   often than the detector's full decoding of `N` bits against `K` codes in 4
    ///   rotations) and `2 b < d_seen`, the smallest distance on the seen cells from the code
    ///   to any other code or rotation of the family (its uniqueness rule `2 h < d`). For
    ///   tag36h11: 24 cells seen or more allow 2 bits, 20 to 23 one, 16 to 19 none.
    ///
    /// Refused ([`PartialRefusal`], the first rule that fails) when the prediction is not
    /// finite, an edge of it lies less than half in the frame (before any pass), the
    /// refinement does not settle or moves a corner more than 8 px, an edge has
    /// fewer than 8 inliers or a third of its positions, or its inliers span less than half
    /// of it, the seen border does not give the intensity models, the seen cells' margin is
    /// below `min_decision_margin`, too few cells are seen or they differ from the code by
    /// more than the budget. AprilTag families only (ArUco: [`PartialRefusal::Unsupported`]).
    ///
    /// The result must be flagged as a partial view wherever it is used (e.g. the AR loop's
    /// [`crate::target::TargetFrame::partial`]): its corners are extrapolated where the tag is
    /// not seen.
    ///
    /// Cost: as [`Self::refine_target`]'s passes (at most 48 edge points an edge), the
    /// consensus fits, 4 more edge points an edge with a hidden part, one reading and a pass
    /// over the family's codes in 4 rotations.
    pub fn refine_partial(
        &self,
        frame: &ImageView<'_, u8>,
        family: &'static Family,
        id: u16,
        predicted: &[Point2<f32>; 4],
    ) -> core::result::Result<PartialDetection, PartialRefusal> {
        if !predicted.iter().all(|p| p.x.is_finite() && p.y.is_finite()) {
            return Err(PartialRefusal::Prediction);
        }
        let Some(code) = family.codes.get(usize::from(id)) else {
            return Err(PartialRefusal::Unsupported);
        };
        if family.kind != Kind::AprilTag {
            return Err(PartialRefusal::Unsupported);
        }
        // An edge predicted less than half in the frame (its narrow search, 3 px either
        // side, inside) cannot be seen over half its length: refused before any pass.
        for i in 0..4 {
            let (a, b) = (at4(predicted, i), at4(predicted, i + 1));
            if !at_most(
                MIN_PARTIAL_SPAN,
                share_in_frame(a, b, frame.width(), frame.height(), 3.0),
            ) {
                return Err(PartialRefusal::ShortEdge(i as u8));
            }
        }
        let (q, support) = settle(predicted, family.reversed_border, |q, d, n| {
            // The narrow passes locate the hidden parts' ends (the last one's are kept).
            robust_edges(frame, q, d, n, d == 1)
        })
        .ok_or(PartialRefusal::Unsettled)?;
        for (i, s) in support.iter().enumerate() {
            if s.inliers < MIN_PARTIAL_INLIERS || 3 * u32::from(s.inliers) < u32::from(s.samples) {
                return Err(PartialRefusal::FewEdgePoints(i as u8));
            }
            if !at_most(MIN_PARTIAL_SPAN, s.span) {
                return Err(PartialRefusal::ShortEdge(i as u8));
            }
        }
        let h = Homography::from_four_points(&TARGET_TAG_COORDS, &q.p)
            .map_err(|_| PartialRefusal::Prediction)?;
        let hidden = Hidden::new(
            &q.p,
            &support,
            family.width_at_border,
            frame.width(),
            frame.height(),
        );
        let cfg = self.config();
        let reading = read_visible(frame, h.matrix(), family, cfg.decode_sharpening, &hidden)
            .ok_or(PartialRefusal::NoContrast)?;
        if !crate::scalar::at_most(cfg.min_decision_margin.max(0.0), reading.margin) {
            return Err(PartialRefusal::WeakCode);
        }
        let lim = self.limits(family);
        let ok = confirm(family, id, code, &reading, lim.max_hamming).map_err(|e| match e {
            NotConfirmed::TooFew => PartialRefusal::FewCells,
            NotConfirmed::Differs => PartialRefusal::NotConfirmed,
        })?;
        let center = project(h.matrix(), 0.0, 0.0).ok_or(PartialRefusal::Prediction)?;
        let [a, b, c, d] = q.p;
        let pick = |f: fn(&EdgeSupport) -> f32| support.map(|s| f(&s));
        Ok(PartialDetection {
            detection: Detection {
                family,
                id,
                hamming: ok.wrong,
                decision_margin: reading.margin,
                corners: [d, c, b, a],
                center,
                homography: h,
            },
            view: PartialView {
                edge_span: pick(|s| s.span),
                edge_inliers: support.map(|s| s.inliers),
                edge_samples: support.map(|s| s.samples),
                cells_seen: ok.seen,
                cells_budget: ok.budget,
                occluded: hidden.any(),
            },
        })
    }

    /// Tag `id` of `family` detected in the region around `predicted` (its corners predicted
    /// for this frame, in a planar target's order): the whole detection
    /// ([`Detector::detect_into`]) on the prediction's bounding box widened by a quarter of its
    /// longest side and 8 px, clipped to the frame, its origin a multiple of `4 · decimate`
    /// (the threshold's tiles then fall as on the full frame). Returns the corners in the
    /// target's order, in frame coordinates, of the copy whose centre is nearest the
    /// prediction's; `None` when the region holds none (or the prediction is not finite).
    ///
    /// Cost: a detection's per pixel of the region, not of the frame.
    ///
    /// Errors: as [`Detector::detect`] for the region.
    pub fn find_target_near(
        &self,
        frame: &ImageView<'_, u8>,
        ws: &mut WorkspaceView<'_, impl Label>,
        family: &Family,
        id: u16,
        predicted: &[Point2<f32>; 4],
    ) -> Result<Option<[Point2<f32>; 4]>> {
        let align = 4 * usize::from(self.config().decimate);
        let Some((x, y, w, h)) = region(predicted, frame.width(), frame.height(), align) else {
            return Ok(None);
        };
        let roi = frame.sub(x, y, w, h)?;
        let mut out: Vec<Detection, 2> = Vec::new();
        self.detect_into(&roi, ws, &mut (), |f, i| f == family && i == id, &mut out)?;
        let centre = |c: &[Point2<f32>; 4]| {
            c.iter()
                .fold(Point2::origin(), |s: Point2<f32>, p| s + p.coords * 0.25)
        };
        let want = centre(predicted);
        let (dx, dy) = (x as f32, y as f32);
        let best = out
            .iter()
            .map(|d| d.target_corners().map(|p| Point2::new(p.x + dx, p.y + dy)))
            .min_by(|a, b| {
                let (da, db) = ((centre(a) - want).norm(), (centre(b) - want).norm());
                da.total_cmp(&db)
            });
        Ok(best)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::apriltag::{Workspace320x240, families};

    /// A 320x240 frame with tag36h11 `id` drawn `cell` pixels a cell from `(x0, y0)` on a
    /// grey ramp (what falls outside the frame cut off), blurred by a 3x3 box (edges between
    /// pixels, as a camera's).
    fn frame(id: u16, x0: usize, y0: usize, cell: usize) -> std::vec::Vec<u8> {
        let mut px: std::vec::Vec<u8> =
            (0..320 * 240).map(|i| (90 + (i % 320) / 8) as u8).collect();
        for y in -1..9i32 {
            for x in -1..9i32 {
                let white = families::TAG36H11.cell(id, x, y).unwrap();
                for dy in 0..cell {
                    for dx in 0..cell {
                        let u = (x0 as i32 + cell as i32 * x + dx as i32) as usize;
                        let v = (y0 as i32 + cell as i32 * y + dy as i32) as usize;
                        if u < 320 && v < 240 {
                            px[v * 320 + u] = if white { 220 } else { 30 };
                        }
                    }
                }
            }
        }
        let mut out = px.clone();
        for v in 1..239 {
            for u in 1..319 {
                let mut s = 0u32;
                for (du, dv) in [
                    (0, 0),
                    (1, 0),
                    (2, 0),
                    (0, 1),
                    (1, 1),
                    (2, 1),
                    (0, 2),
                    (1, 2),
                    (2, 2),
                ] {
                    s += u32::from(px[(v + dv - 1) * 320 + u + du - 1]);
                }
                out[v * 320 + u] = (s / 9) as u8;
            }
        }
        out
    }

    #[test]
    fn a_shifted_prediction_refines_to_the_detections_corners_and_only_for_its_tag() {
        let px = frame(7, 120, 80, 6);
        let img = ImageView::packed(&px, 320, 240).unwrap();
        let det = Detector::new(Default::default(), &[&families::TAG36H11]).unwrap();
        let mut ws = std::boxed::Box::new(Workspace320x240::new());
        let mut view = ws.as_mut_view();
        let found = det
            .find_target(&img, &mut view, &families::TAG36H11, 7)
            .unwrap()
            .unwrap();
        let full: heapless::Vec<Detection, 2> = det.detect(&img, &mut view).unwrap();
        for (sx, sy) in [(0.0, 0.0), (2.5, -1.5), (-3.0, 2.0)] {
            let predicted = found.map(|p| Point2::new(p.x + sx, p.y + sy));
            // As a detection: AprilTag's corner order, the centre, the same code.
            let again = det
                .refine_detection(&img, &families::TAG36H11, 7, &predicted)
                .unwrap();
            let d = &full[0];
            assert_eq!((again.id, again.hamming), (d.id, d.hamming));
            assert!((again.decision_margin - d.decision_margin).abs() < 2.0);
            for (a, b) in again
                .corners
                .iter()
                .chain([&again.center])
                .zip(d.corners.iter().chain([&d.center]))
            {
                assert!(
                    (a - b).norm() < 0.1,
                    "detection, shift ({sx}, {sy}): {a} vs {b}"
                );
            }
            let refined = det
                .refine_target(&img, &families::TAG36H11, 7, &predicted)
                .unwrap();
            for (a, b) in refined.iter().zip(found.iter()) {
                assert!((a - b).norm() < 0.1, "shift ({sx}, {sy}): {a} vs {b}");
            }
            // Another tag's code, or the tag turned a quarter: not this tag.
            assert!(
                det.refine_target(&img, &families::TAG36H11, 8, &predicted)
                    .is_none()
            );
            let turned = [predicted[1], predicted[2], predicted[3], predicted[0]];
            assert!(
                det.refine_target(&img, &families::TAG36H11, 7, &turned)
                    .is_none()
            );
            // The region search finds it too, in frame coordinates.
            let near = det
                .find_target_near(&img, &mut view, &families::TAG36H11, 7, &predicted)
                .unwrap()
                .unwrap();
            for (a, b) in near.iter().zip(found.iter()) {
                assert!(
                    (a - b).norm() < 0.1,
                    "region, shift ({sx}, {sy}): {a} vs {b}"
                );
            }
        }
        // Too far for the refinement, or nowhere near the tag: nothing.
        let far = found.map(|p| Point2::new(p.x + 30.0, p.y));
        assert!(
            det.refine_target(&img, &families::TAG36H11, 7, &far)
                .is_none()
        );
        let away = found.map(|p| Point2::new(p.x - 110.0, p.y + 100.0));
        let none = det.find_target_near(&img, &mut view, &families::TAG36H11, 7, &away);
        assert_eq!(none.unwrap(), None);
        let nan = found.map(|p| Point2::new(p.x, f32::NAN));
        assert!(
            det.refine_target(&img, &families::TAG36H11, 7, &nan)
                .is_none()
        );
        let none = det.find_target_near(&img, &mut view, &families::TAG36H11, 7, &nan);
        assert_eq!(none.unwrap(), None);
    }

    /// `px` with a dark rectangle (grey 35: an occluder darker than the paper, lighter than
    /// the ink) over columns `x0..x1` and rows `y0..y1`.
    fn occluded(
        mut px: std::vec::Vec<u8>,
        (x0, x1): (usize, usize),
        (y0, y1): (usize, usize),
    ) -> std::vec::Vec<u8> {
        for v in y0..y1.min(240) {
            for u in x0..x1.min(320) {
                px[v * 320 + u] = 35;
            }
        }
        px
    }

    /// The border's outer corners of [`frame`]'s tag in the target's order (its edges lie
    /// between pixels: half a pixel before the first border pixel, after the last).
    fn truth(x0: usize, y0: usize, cell: usize) -> [Point2<f32>; 4] {
        let (a, b) = (x0 as f32 - 0.5, (x0 + 8 * cell) as f32 - 0.5);
        let (c, d) = (y0 as f32 - 0.5, (y0 + 8 * cell) as f32 - 0.5);
        [
            Point2::new(a, c),
            Point2::new(b, c),
            Point2::new(b, d),
            Point2::new(a, d),
        ]
    }

    fn detector() -> Detector {
        Detector::new(Default::default(), &[&families::TAG36H11]).unwrap()
    }

    #[test]
    fn a_tag_crossed_by_a_bar_is_found_partly_seen_within_a_tenth_of_a_pixel() {
        let (x0, y0, cell) = (120, 80, 6);
        // A bar 8 px wide down the whole frame, across the tag's top and bottom edges and
        // two columns of its cells.
        let px = occluded(frame(7, x0, y0, cell), (140, 148), (0, 240));
        let img = ImageView::packed(&px, 320, 240).unwrap();
        let det = detector();
        let truth = truth(x0, y0, cell);
        for (sx, sy) in [(0.0, 0.0), (1.5, -1.0), (-2.5, 2.0)] {
            let predicted = truth.map(|p| Point2::new(p.x + sx, p.y + sy));
            // Refused as a wholly seen tag (the crossed edges' points scatter), and not in the
            // region either.
            assert!(
                det.refine_target(&img, &families::TAG36H11, 7, &predicted)
                    .is_none()
            );
            let p = det
                .refine_partial(&img, &families::TAG36H11, 7, &predicted)
                .unwrap();
            let d = p.detection;
            assert_eq!((d.id, d.hamming), (7, 0));
            for (a, b) in d.target_corners().iter().zip(truth.iter()) {
                assert!((a - b).norm() < 0.1, "shift ({sx}, {sy}): {a} vs {b}");
            }
            let v = p.view;
            assert!(v.occluded, "{v:?}");
            // Columns of cells under the bar are not counted; the rest are enough.
            assert!((16..=30).contains(&v.cells_seen), "{v:?}");
            // The top and bottom edges are crossed but seen at both ends.
            assert!(v.edge_inliers[0] < v.edge_samples[0], "{v:?}");
            assert!(v.edge_span.iter().all(|s| *s > 0.9), "{v:?}");
            // Another tag's code is not what the seen cells show.
            assert_eq!(
                det.refine_partial(&img, &families::TAG36H11, 8, &predicted),
                Err(PartialRefusal::NotConfirmed)
            );
        }
        // Wholly seen, the partial path measures the same tag (nothing hidden).
        let px = frame(7, x0, y0, cell);
        let img = ImageView::packed(&px, 320, 240).unwrap();
        let p = det
            .refine_partial(&img, &families::TAG36H11, 7, &truth)
            .unwrap();
        assert!(!p.view.occluded && p.view.cells_seen == 36, "{:?}", p.view);
        let whole = det
            .refine_target(&img, &families::TAG36H11, 7, &truth)
            .unwrap();
        for (a, b) in p.detection.target_corners().iter().zip(whole.iter()) {
            assert!((a - b).norm() < 0.05, "{a} vs {b}");
        }
    }

    #[test]
    fn a_partly_seen_tag_is_refused_when_the_data_do_not_determine_it() {
        let (x0, y0, cell) = (120, 80, 6);
        let det = detector();
        let truth = truth(x0, y0, cell);
        let tag = &families::TAG36H11;
        // Over the top-left corner: the top edge seen over less than half its length.
        let px = occluded(frame(7, x0, y0, cell), (100, 147), (60, 92));
        let img = ImageView::packed(&px, 320, 240).unwrap();
        assert_eq!(
            det.refine_partial(&img, tag, 7, &truth),
            Err(PartialRefusal::ShortEdge(0))
        );
        // Cut by the frame's edge through its right part: the right edge is outside, refused
        // before any pass.
        let px = frame(7, 290, y0, cell);
        let img = ImageView::packed(&px, 320, 240).unwrap();
        assert_eq!(
            det.refine_partial(&img, tag, 7, &self::truth(290, y0, cell)),
            Err(PartialRefusal::ShortEdge(1))
        );
        // The whole right edge hidden: no inlier on it.
        let px = occluded(frame(7, x0, y0, cell), (160, 180), (0, 240));
        let img = ImageView::packed(&px, 320, 240).unwrap();
        assert_eq!(
            det.refine_partial(&img, tag, 7, &truth),
            Err(PartialRefusal::FewEdgePoints(1))
        );
        // A wide occluder over the middle: too few cells seen to confirm any id.
        let px = occluded(frame(7, x0, y0, cell), (133, 155), (0, 240));
        let img = ImageView::packed(&px, 320, 240).unwrap();
        assert_eq!(
            det.refine_partial(&img, tag, 7, &truth),
            Err(PartialRefusal::FewCells)
        );
        // Not finite, an id the family does not have, an ArUco dictionary.
        let nan = truth.map(|p| Point2::new(p.x, f32::NAN));
        assert_eq!(
            det.refine_partial(&img, tag, 7, &nan),
            Err(PartialRefusal::Prediction)
        );
        assert_eq!(
            det.refine_partial(&img, tag, 60000, &truth),
            Err(PartialRefusal::Unsupported)
        );
        let aruco = Detector::new(Default::default(), &[&families::DICT_4X4_50]).unwrap();
        assert_eq!(
            aruco.refine_partial(&img, &families::DICT_4X4_50, 3, &truth),
            Err(PartialRefusal::Unsupported)
        );
    }

    #[test]
    fn the_region_is_aligned_clipped_and_refuses_non_finite_predictions() {
        let sq = |x: f32, y: f32, s: f32| {
            [
                Point2::new(x, y),
                Point2::new(x + s, y),
                Point2::new(x + s, y + s),
                Point2::new(x, y + s),
            ]
        };
        // 40 px side: margin 18 px.
        let (x, y, w, h) = region(&sq(100.0, 50.0, 40.0), 320, 240, 4).unwrap();
        assert_eq!((x % 4, y % 4), (0, 0));
        assert!(x as f32 <= 82.0 && y as f32 <= 32.0);
        assert!((x + w) as f32 >= 158.0 && (y + h) as f32 >= 108.0);
        // Clipped at the frame's edges.
        let (x, y, w, h) = region(&sq(-30.0, 220.0, 40.0), 320, 240, 4).unwrap();
        assert_eq!((x, y + h), (0, 240));
        assert!(w > 0);
        // Wholly outside, or not finite: nothing.
        assert!(region(&sq(400.0, 50.0, 40.0), 320, 240, 4).is_none());
        assert!(region(&sq(f32::NAN, 50.0, 40.0), 320, 240, 4).is_none());
        assert!(region(&sq(f32::INFINITY, 50.0, 40.0), 320, 240, 4).is_none());
    }
}
