//! Tag boards: several tags at known places, one pose from all the visible ones (apriltag_ros'
//! tag bundles, OpenCV's `aruco::Board` and `GridBoard` with `matchImagePoints` and
//! `solvePnP`).
//!
//! A [`TagBoard`] is a view over a table of [`BoardTag`]s (the caller's, or a `const`): each an
//! id of the board's family and its four corners in board coordinates, in the order of
//! [`Detection::target_corners`] — the tag's top-left, top-right, bottom-right, bottom-left as
//! drawn, which is OpenCV's marker corner order, so `board.getObjPoints()` is such a table as
//! it is. [`GridBoard`] lays out OpenCV's `GridBoard`; [`grid_tags`] does it at compile time.
//!
//! [`board_pose`] matches the detections to the board by family and id, gathers the
//! `4 k` correspondences `Xᵢ ↔ uᵢ` of the `k` matched tags into [`BoardBuffers`], starts from
//! IPPE when the board is planar (every corner at `Z = 0`: [`solve_planar`], both solutions
//! refined when close) or from EPnP otherwise ([`solve_pnp`]), and minimises
//! `Σ |u(R Xᵢ + t) - uᵢ|²` over all the points by Levenberg-Marquardt. With several tags
//! spread over the board the planar ambiguity of a single small tag is gone (the second
//! solution's error is many times the best's); [`BoardPose::ambiguous`] says when it is not.
//!
//! A tag seen twice in one frame (two detections of one id) is not used at all: which of the
//! two is the board's cannot be told from the detections, and the other tags give the pose.
//! Detections of other families, or of ids not on the board, are ignored.

use nalgebra::{Point2, Point3};

use super::detector::Detection;
use super::family::Family;
use crate::camera::Camera;
use crate::pose::{PlanarConfig, PoseEstimate, solve_planar, solve_pnp};
use crate::scalar::{Real, above};
use crate::{Error, Result};

/// One tag of a board: its id in the board's family and its four corners in board
/// coordinates, `[x, y, z]`, in [`Detection::target_corners`]' order (OpenCV's: the tag's
/// top-left, top-right, bottom-right, bottom-left).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardTag<T: Real = f32> {
    /// Tag id in the board's family.
    pub id: u16,
    /// Corners in board coordinates.
    pub corners: [[T; 3]; 4],
}

/// A board: the tags of one family at known places. Built by [`TagBoard::new`], which checks
/// the table once so that [`board_pose`] need not.
#[derive(Debug, Clone, Copy)]
#[doc(alias = "Board")]
pub struct TagBoard<'a, T: Real = f32> {
    family: &'static Family,
    tags: &'a [BoardTag<T>],
    planar: bool,
}

impl<'a, T: Real> TagBoard<'a, T> {
    /// A board of `tags` of `family`. It is planar (IPPE start) when every corner has `z = 0`.
    ///
    /// Errors: [`Error::TooFewPoints`] for no tag; [`Error::InvalidParameter`]`("tags")` when an
    /// id is not in the family, appears twice, or a tag's corners are not finite or are
    /// (nearly) collinear — a tag whose image could not give a homography.
    pub fn new(family: &'static Family, tags: &'a [BoardTag<T>]) -> Result<Self> {
        if tags.is_empty() {
            return Err(Error::TooFewPoints);
        }
        let mut planar = true;
        for (k, t) in tags.iter().enumerate() {
            if usize::from(t.id) >= family.ncodes()
                || tags
                    .get(..k)
                    .is_some_and(|s| s.iter().any(|o| o.id == t.id))
                || !t.corners.iter().flatten().all(|v| v.finite())
                || !non_degenerate(&t.corners)
            {
                return Err(Error::InvalidParameter("tags"));
            }
            planar &= t.corners.iter().all(|c| c[2] == T::zero());
        }
        Ok(Self {
            family,
            tags,
            planar,
        })
    }

    /// The family of the board's tags.
    pub fn family(&self) -> &'static Family {
        self.family
    }

    /// The tags.
    pub fn tags(&self) -> &'a [BoardTag<T>] {
        self.tags
    }

    /// `true` when every corner is in the board's `z = 0` plane.
    pub fn is_planar(&self) -> bool {
        self.planar
    }

    /// The tag of id `id`, if it is on the board.
    pub fn tag(&self, id: u16) -> Option<&'a BoardTag<T>> {
        self.tags.iter().find(|t| t.id == id)
    }
}

/// The tag's quad spans an area: twice the area of its corners' polygon (the shoelace sum of
/// the cross products of consecutive corners about corner 0, as a 3-vector) against the
/// squared longest side, so that the test does not depend on the unit.
fn non_degenerate<T: Real>(c: &[[T; 3]; 4]) -> bool {
    let p = c.map(|v| Point3::new(v[0], v[1], v[2]));
    let (a, b, d) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let area = (a.cross(&b) + b.cross(&d)).norm();
    let side = [a, p[2] - p[1], p[3] - p[2], d]
        .iter()
        .fold(T::zero(), |m, s| m.max(s.norm_squared()));
    above(area, T::lit(1e-3) * side)
}

/// OpenCV's `aruco::GridBoard(size = (markers_x, markers_y), markerLength, markerSeparation,
/// dictionary, ids)` with `ids = first_id, first_id + 1, ..`: tag `k` (row-major, `k = y
/// markers_x + x`) has id `first_id + k` and its top-left corner at `(x (L + S), y (L + S), 0)`,
/// the others `+ (L, 0)`, `+ (L, L)`, `+ (0, L)` — the board's `x` right and `y` down the
/// printed board (`generateImage`), `z` into it; the same numbers as OpenCV's `getObjPoints()`
/// (its sums are in `f32`, so are these for `f32`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridBoard<T: Real = f32> {
    /// Tags across (OpenCV's `size.width`).
    pub markers_x: u16,
    /// Tags down (`size.height`).
    pub markers_y: u16,
    /// Side of each tag, the black border's outer edge (`markerLength`).
    pub marker_length: T,
    /// Gap between neighbouring tags (`markerSeparation`).
    pub marker_separation: T,
    /// Id of the top-left tag; the others follow row by row.
    pub first_id: u16,
}

impl<T: Real> GridBoard<T> {
    /// Number of tags, `markers_x · markers_y`.
    pub fn len(&self) -> usize {
        usize::from(self.markers_x) * usize::from(self.markers_y)
    }

    /// `true` for a grid without tags.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Tag `k` (row-major), if `k < len()`.
    pub fn tag(&self, k: usize) -> Option<BoardTag<T>> {
        if k >= self.len() {
            return None;
        }
        let id = u16::try_from(usize::from(self.first_id) + k).ok()?;
        let nx = usize::from(self.markers_x);
        let step = self.marker_length + self.marker_separation;
        let (col, row) = (k.checked_rem(nx)?, k.checked_div(nx)?);
        let (x, y) = (T::lit(col as f64) * step, T::lit(row as f64) * step);
        let l = self.marker_length;
        let z = T::zero();
        Some(BoardTag {
            id,
            corners: [[x, y, z], [x + l, y, z], [x + l, y + l, z], [x, y + l, z]],
        })
    }

    /// Writes the tags into `out` (at least [`Self::len`] entries) and returns the board over
    /// them.
    ///
    /// Errors: [`Error::InvalidParameter`] for a side or gap that is not finite, a side that is
    /// not positive or a negative gap (`"marker_length"`, `"marker_separation"`), or ids past
    /// `u16` (`"first_id"`); [`Error::BufferTooSmall`]`("out")`; as [`TagBoard::new`].
    pub fn fill<'a>(
        &self,
        family: &'static Family,
        out: &'a mut [BoardTag<T>],
    ) -> Result<TagBoard<'a, T>> {
        if !(self.marker_length.finite() && above(self.marker_length, T::zero())) {
            return Err(Error::InvalidParameter("marker_length"));
        }
        if !(self.marker_separation.finite() && self.marker_separation >= T::zero()) {
            return Err(Error::InvalidParameter("marker_separation"));
        }
        let n = self.len();
        let out = out.get_mut(..n).ok_or(Error::BufferTooSmall("out"))?;
        for (k, slot) in out.iter_mut().enumerate() {
            *slot = self.tag(k).ok_or(Error::InvalidParameter("first_id"))?;
        }
        TagBoard::new(family, out)
    }
}

/// [`GridBoard`] in `f32` at compile time, for a board's `const` table:
/// `const TAGS: [BoardTag; 6] = grid_tags(3, 0.04, 0.01, 0);` is OpenCV's
/// `GridBoard((3, 2), 0.04, 0.01, dict)`. `N / markers_x` rows; a partial last row when
/// `markers_x` does not divide `N`; all at the origin for `markers_x = 0`. Ids wrap past
/// `u16::MAX` (then [`TagBoard::new`] refuses the table).
#[doc(alias = "GridBoard")]
pub const fn grid_tags<const N: usize>(
    markers_x: u16,
    marker_length: f32,
    marker_separation: f32,
    first_id: u16,
) -> [BoardTag<f32>; N] {
    let mut out = [BoardTag {
        id: 0,
        corners: [[0.0; 3]; 4],
    }; N];
    let nx = if markers_x == 0 {
        1
    } else {
        markers_x as usize
    };
    let step = marker_length + marker_separation;
    let l = marker_length;
    let mut k = 0;
    let mut rest: &mut [BoardTag<f32>] = &mut out;
    while let Some((slot, tail)) = rest.split_first_mut() {
        let x = (k % nx) as f32 * step;
        let y = (k / nx) as f32 * step;
        *slot = BoardTag {
            id: first_id.wrapping_add(k as u16),
            corners: [
                [x, y, 0.0],
                [x + l, y, 0.0],
                [x + l, y + l, 0.0],
                [x, y + l, 0.0],
            ],
        };
        rest = tail;
        k += 1;
    }
    out
}

/// Options of [`board_pose`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardConfig {
    /// The planar solver's options (planar boards).
    pub planar: PlanarConfig,
    /// A planar board's pose is [`BoardPose::ambiguous`] when the second IPPE solution's RMS
    /// error is at most this many times the best's (1.5: [`crate::pose::PlanarPose::is_ambiguous`]'s
    /// suggestion).
    pub ambiguity_ratio: f32,
    /// Largest RMS reprojection error (pixels) of an accepted pose: above it the corners do
    /// not fit one board (a wrong board file, a wrong camera, a misread id).
    pub max_rms_px: f32,
}

impl Default for BoardConfig {
    fn default() -> Self {
        Self {
            planar: PlanarConfig::default(),
            ambiguity_ratio: 1.5,
            max_rms_px: 3.0,
        }
    }
}

/// The correspondences of one frame, `N` points at most (4 a tag): the caller's memory
/// (`36 N` bytes in `f32`).
#[derive(Debug, Clone)]
pub struct BoardBuffers<T: Real, const N: usize> {
    world: [Point3<T>; N],
    model: [Point2<T>; N],
    pixels: [Point2<T>; N],
    scratch: [Point2<T>; N],
}

impl<T: Real, const N: usize> BoardBuffers<T, N> {
    /// Zeroed buffers.
    pub fn new() -> Self {
        Self {
            world: [Point3::origin(); N],
            model: [Point2::origin(); N],
            pixels: [Point2::origin(); N],
            scratch: [Point2::origin(); N],
        }
    }

    /// The board points and their pixels of the last [`board_pose`] (`points` of them).
    pub fn correspondences(&self, points: usize) -> (&[Point3<T>], &[Point2<T>]) {
        let n = points.min(N);
        (
            self.world.get(..n).unwrap_or(&[]),
            self.pixels.get(..n).unwrap_or(&[]),
        )
    }
}

impl<T: Real, const N: usize> Default for BoardBuffers<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

/// The board's pose and what it was made from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardPose<T: Real = f32> {
    /// Board-to-camera pose (`X_c = R X_board + t`) and its RMS reprojection error over all
    /// the points used.
    pub estimate: PoseEstimate<T>,
    /// A planar board's second solution's RMS error (refined when close, see
    /// [`PlanarConfig::alternative_ratio`]); NaN for a non-planar board.
    pub alternative_rms_px: T,
    /// `true` when the second solution fits almost as well
    /// ([`BoardConfig::ambiguity_ratio`]): one small tag, or tags close together, nearly
    /// fronto-parallel.
    pub ambiguous: bool,
    /// Board tags used.
    pub tags: u16,
    /// Corner correspondences used (4 a tag).
    pub points: u16,
    /// Board ids seen more than once in the frame, left out.
    pub duplicates: u16,
}

/// The board's pose from one frame's detections (OpenCV's `matchImagePoints` then `solvePnP`,
/// or apriltag_ros' bundle pose): see the module docs.
///
/// Errors: [`Error::TooFewPoints`] when no board tag is matched (one tag, 4 points, is enough
/// for a planar board: check [`BoardPose::ambiguous`]); [`Error::BufferTooSmall`]`("buffers")`
/// when the matched tags have more than `N` corners; [`Error::NoConvergence`] when the RMS
/// error is above [`BoardConfig::max_rms_px`] (or not finite); as [`solve_planar`] (planar
/// board, e.g. [`Error::Degenerate`] for corners seen edge-on) or [`solve_pnp`] (e.g. a
/// non-planar board of which only coplanar corners are seen).
#[doc(alias = "matchImagePoints")]
#[doc(alias = "estimatePoseBoard")]
pub fn board_pose<T: Real, const N: usize>(
    board: &TagBoard<'_, T>,
    detections: &[Detection],
    camera: &Camera<T>,
    cfg: &BoardConfig,
    buffers: &mut BoardBuffers<T, N>,
) -> Result<BoardPose<T>> {
    let (mut n, mut tags, mut duplicates) = (0usize, 0u16, 0u16);
    let same = |a: &Detection, b: &Detection| a.id == b.id && a.family.name() == b.family.name();
    for (k, d) in detections.iter().enumerate() {
        if d.family.name() != board.family.name() {
            continue;
        }
        let Some(tag) = board.tag(d.id) else {
            continue;
        };
        // Seen before in this frame: counted then. Seen again later: left out.
        if detections
            .get(..k)
            .is_some_and(|s| s.iter().any(|o| same(o, d)))
        {
            continue;
        }
        if detections
            .get(k + 1..)
            .is_some_and(|s| s.iter().any(|o| same(o, d)))
        {
            duplicates = duplicates.saturating_add(1);
            continue;
        }
        for (c, u) in tag.corners.iter().zip(d.target_corners()) {
            let w = buffers
                .world
                .get_mut(n)
                .ok_or(Error::BufferTooSmall("buffers"))?;
            *w = Point3::new(c[0], c[1], c[2]);
            if let (Some(m), Some(p)) = (buffers.model.get_mut(n), buffers.pixels.get_mut(n)) {
                *m = Point2::new(c[0], c[1]);
                *p = Point2::new(T::lit(f64::from(u.x)), T::lit(f64::from(u.y)));
            }
            n += 1;
        }
        tags = tags.saturating_add(1);
    }
    if tags == 0 {
        return Err(Error::TooFewPoints);
    }
    let model = buffers.model.get(..n).ok_or(Error::LengthMismatch)?;
    let world = buffers.world.get(..n).ok_or(Error::LengthMismatch)?;
    let pixels = buffers.pixels.get(..n).ok_or(Error::LengthMismatch)?;
    let (estimate, alternative_rms_px, ambiguous) = if board.planar {
        let p = solve_planar(camera, model, pixels, &mut buffers.scratch, &cfg.planar)?;
        let ambiguous = p.is_ambiguous(T::lit(f64::from(cfg.ambiguity_ratio)));
        (p.best, p.alternative.rms_px, ambiguous)
    } else {
        let p = solve_pnp(camera, world, pixels, &mut buffers.scratch)?;
        (p, T::lit(f64::NAN), false)
    };
    if !(estimate.rms_px.finite() && estimate.rms_px <= T::lit(f64::from(cfg.max_rms_px))) {
        return Err(Error::NoConvergence);
    }
    Ok(BoardPose {
        estimate,
        alternative_rms_px,
        ambiguous,
        tags,
        points: u16::try_from(n).unwrap_or(u16::MAX),
        duplicates,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::apriltag::families::{DICT_4X4_50, TAG36H11};
    use crate::camera::{Distortion, Intrinsics};
    use crate::homography::Homography;
    use crate::transform::Pose;
    use nalgebra::Vector3;

    fn camera() -> Camera<f64> {
        Camera::new(
            Intrinsics::new(600.0, 600.0, 320.0, 240.0).unwrap(),
            Distortion::from_opencv([-0.2, 0.05, 0.0, 0.0, 0.0]).unwrap(),
        )
    }

    fn truth() -> Pose<f64> {
        Pose::from_rodrigues(Vector3::new(0.3, -0.4, 0.1), Vector3::new(-0.1, -0.06, 0.5)).unwrap()
    }

    /// A detection of `tag` as `camera` sees it at `pose` (exact corners).
    fn detect(tag: &BoardTag<f64>, family: &'static Family, pose: &Pose<f64>) -> Detection {
        let cam = camera();
        let u = tag.corners.map(|c| {
            let p = cam.project(pose, &Point3::new(c[0], c[1], c[2])).unwrap();
            Point2::new(p.x as f32, p.y as f32)
        });
        Detection {
            family,
            id: tag.id,
            hamming: 0,
            decision_margin: 50.0,
            // `target_corners` is corners 3, 2, 1, 0.
            corners: [u[3], u[2], u[1], u[0]],
            center: u[0],
            homography: Homography::identity(),
        }
    }

    const GRID: GridBoard<f64> = GridBoard {
        markers_x: 4,
        markers_y: 3,
        marker_length: 0.04,
        marker_separation: 0.01,
        first_id: 2,
    };

    #[test]
    fn grid_matches_opencv_layout_and_the_const_table() {
        let mut out = [BoardTag {
            id: 0,
            corners: [[0.0; 3]; 4],
        }; 12];
        let b = GRID.fill(&DICT_4X4_50, &mut out).unwrap();
        assert!(b.is_planar());
        // Tag 5 is row 1, column 1: top-left at (0.05, 0.05).
        let t = b.tag(7).unwrap();
        assert_eq!(t.corners[0], [0.05, 0.05, 0.0]);
        assert_eq!(t.corners[2], [0.09, 0.09, 0.0]);
        const TAGS: [BoardTag; 12] = grid_tags(4, 0.04, 0.01, 2);
        let g32 = GridBoard::<f32> {
            markers_x: 4,
            markers_y: 3,
            marker_length: 0.04,
            marker_separation: 0.01,
            first_id: 2,
        };
        for (k, c) in TAGS.iter().enumerate() {
            assert_eq!(Some(*c), g32.tag(k));
        }
    }

    #[test]
    fn pose_from_all_and_from_some_tags() {
        let mut out = [BoardTag {
            id: 0,
            corners: [[0.0; 3]; 4],
        }; 12];
        let b = GRID.fill(&DICT_4X4_50, &mut out).unwrap();
        let pose = truth();
        let all: std::vec::Vec<Detection> = b
            .tags()
            .iter()
            .map(|t| detect(t, &DICT_4X4_50, &pose))
            .collect();
        let mut buf = BoardBuffers::<f64, 48>::new();
        for keep in [12usize, 6, 3, 1] {
            let seen: std::vec::Vec<Detection> = all.iter().step_by(12 / keep).copied().collect();
            let p = board_pose(&b, &seen, &camera(), &BoardConfig::default(), &mut buf).unwrap();
            assert_eq!(usize::from(p.tags), keep);
            assert_eq!(usize::from(p.points), 4 * keep);
            let dr =
                (p.estimate.pose.isometry().rotation * pose.isometry().rotation.inverse()).angle();
            assert!(dr < 1e-5, "{keep}: {dr}");
            assert!((p.estimate.pose.translation() - pose.translation()).norm() < 1e-5);
            assert!(p.estimate.rms_px < 1e-3);
            if keep > 1 {
                assert!(!p.ambiguous, "{keep}: {p:?}");
            }
        }
    }

    #[test]
    fn duplicates_other_families_and_unknown_ids_are_left_out() {
        let mut out = [BoardTag {
            id: 0,
            corners: [[0.0; 3]; 4],
        }; 12];
        let b = GRID.fill(&DICT_4X4_50, &mut out).unwrap();
        let pose = truth();
        let mut seen: std::vec::Vec<Detection> = b
            .tags()
            .iter()
            .take(4)
            .map(|t| detect(t, &DICT_4X4_50, &pose))
            .collect();
        // Id 3 again, somewhere else; id 40 (not on the board); a tag36h11 id 4.
        let mut dup = seen[1];
        dup.corners = seen[3].corners;
        seen.push(dup);
        let mut stranger = seen[2];
        stranger.id = 40;
        seen.push(stranger);
        let mut other = seen[2];
        other.family = &TAG36H11;
        seen.push(other);
        let mut buf = BoardBuffers::<f64, 48>::new();
        let p = board_pose(&b, &seen, &camera(), &BoardConfig::default(), &mut buf).unwrap();
        assert_eq!((p.tags, p.points, p.duplicates), (3, 12, 1));
        assert!(p.estimate.rms_px < 1e-3);
    }

    #[test]
    fn refusals() {
        let mut out = [BoardTag {
            id: 0,
            corners: [[0.0; 3]; 4],
        }; 12];
        let b = GRID.fill(&DICT_4X4_50, &mut out).unwrap();
        let cam = camera();
        let cfg = BoardConfig::default();
        let mut buf = BoardBuffers::<f64, 8>::new();
        assert_eq!(
            board_pose(&b, &[], &cam, &cfg, &mut buf),
            Err(Error::TooFewPoints)
        );
        let all: std::vec::Vec<Detection> = b
            .tags()
            .iter()
            .map(|t| detect(t, &DICT_4X4_50, &truth()))
            .collect();
        assert_eq!(
            board_pose(&b, &all, &cam, &cfg, &mut buf),
            Err(Error::BufferTooSmall("buffers"))
        );
        // Detections of another board (ids shifted): the corners do not fit.
        let mut wrong = all.clone();
        for (d, t) in wrong.iter_mut().zip(all.iter().rev()) {
            d.corners = t.corners;
        }
        let mut big = BoardBuffers::<f64, 48>::new();
        assert_eq!(
            board_pose(&b, &wrong, &cam, &cfg, &mut big).err(),
            Some(Error::NoConvergence)
        );
        // Bad tables.
        let t = *b.tags().first().unwrap();
        assert!(TagBoard::<f64>::new(&DICT_4X4_50, &[]).is_err());
        assert!(TagBoard::new(&DICT_4X4_50, &[t, t]).is_err());
        let mut far = t;
        far.id = 50;
        assert!(TagBoard::new(&DICT_4X4_50, &[far]).is_err());
        let mut line = t;
        line.corners = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
        ];
        assert!(TagBoard::new(&DICT_4X4_50, &[line]).is_err());
        let mut nan = t;
        nan.corners[1][2] = f64::NAN;
        assert!(TagBoard::new(&DICT_4X4_50, &[nan]).is_err());
        let g = GridBoard {
            marker_length: -1.0,
            ..GRID
        };
        assert!(g.fill(&DICT_4X4_50, &mut out).is_err());
        let g = GridBoard {
            first_id: u16::MAX - 3,
            ..GRID
        };
        assert!(g.fill(&TAG36H11, &mut out).is_err());
    }

    #[test]
    fn non_planar_board_uses_pnp() {
        // Two tags on two faces of a box: one in z = 0, one in the plane x = 0.
        let tags = [
            BoardTag {
                id: 0,
                corners: [
                    [0.01, 0.0, 0.0],
                    [0.05, 0.0, 0.0],
                    [0.05, 0.04, 0.0],
                    [0.01, 0.04, 0.0],
                ],
            },
            BoardTag {
                id: 1,
                corners: [
                    [0.0, 0.0, -0.05],
                    [0.0, 0.0, -0.01],
                    [0.0, 0.04, -0.01],
                    [0.0, 0.04, -0.05],
                ],
            },
        ];
        let b = TagBoard::new(&DICT_4X4_50, &tags).unwrap();
        assert!(!b.is_planar());
        let pose = Pose::from_rodrigues(
            Vector3::new(0.2, 0.7, 0.05),
            Vector3::new(-0.02, -0.02, 0.3),
        )
        .unwrap();
        let seen: std::vec::Vec<Detection> = tags
            .iter()
            .map(|t| detect(t, &DICT_4X4_50, &pose))
            .collect();
        let mut buf = BoardBuffers::<f64, 8>::new();
        let p = board_pose(&b, &seen, &camera(), &BoardConfig::default(), &mut buf).unwrap();
        assert!(p.alternative_rms_px.is_nan() && !p.ambiguous);
        assert!((p.estimate.pose.translation() - pose.translation()).norm() < 1e-5);
    }
}
