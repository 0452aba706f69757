//! The AprilGrid layout, as Kalibr defines it.

use core::num::NonZeroUsize;

use nalgebra::Point2;

use crate::apriltag::{DetectorConfig, Family, families};
use crate::{Error, Result};

/// Most tags a grid holds: the codes of tag36h11 (ids `0..587`).
pub const MAX_TAGS: usize = 587;

/// Kalibr's AprilGrid of `cols x rows` tags of side `size`, `spacing · size` apart
/// (`aslam_cameras_april/src/GridCalibrationTargetAprilgrid.cpp` and
/// `kalibr_create_target_pdf`, ethz-asl/kalibr). Kalibr's target file: `tagCols`, `tagRows`,
/// `tagSize`, `tagSpacing` (a ratio of the tag side).
///
/// - **Tags**: tag36h11 with a 2-cell black border ([`families::TAG36H11_B2`]); `size` is the
///   side of the border's outer square (10 cells). Tag `t = cols · y + x` (`x < cols`,
///   `y < rows`) has its outer bottom-left corner at `(x (1 + spacing) size, y (1 + spacing)
///   size)`. Kalibr's pdf also puts a black square of side `spacing · size` at each outer
///   corner of every tag (its `symmCorners`); they touch the tags only at their corners.
/// - **Board frame**: Kalibr's: origin at the outer bottom-left corner of tag 0 as printed,
///   `x` to the right, `y` up the page, `z = 0` on the board (out of the page). The tags are
///   upright on the page (their top row of cells at the top).
/// - **Points**: `4 cols rows` of them, point `k = r · 2 cols + c` (`r < 2 rows`,
///   `c < 2 cols`) at `(⌊c/2⌋ (1 + spacing) size + (c mod 2) size, ⌊r/2⌋ (1 + spacing) size +
///   (r mod 2) size, 0)` (`createGridPoints`).
/// - **A tag's corners**: tag `t`'s bottom-left, bottom-right, top-right, top-left (on the
///   page) are points `b, b + 1, b + 2 cols + 1, b + 2 cols`, `b = ⌊t / cols⌋ 4 cols +
///   (t mod cols) 2` (`computeObservation`'s `pIdx`): the order of AprilTag's corners
///   ([`crate::apriltag::Detection::corners`]), as the AprilTags C++ library's `p[0..4]` that
///   Kalibr stores there.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AprilGrid {
    cols: u16,
    rows: u16,
    size: f32,
    spacing: f32,
}

impl AprilGrid {
    /// A grid of `cols x rows` tags of side `size` (any unit: the calibration's poses come out
    /// in it), `spacing · size` apart (Kalibr's `tagSpacing`).
    ///
    /// Errors: `InvalidParameter("tags")` for no tag, or more than [`MAX_TAGS`];
    /// `InvalidParameter("size")` for a non-finite or non-positive size;
    /// `InvalidParameter("spacing")` for a spacing not in `(0, 1]` (Kalibr's range). A
    /// detector needs at least one white cell around each tag, `spacing ≥ 0.2` (Kalibr's
    /// default is 0.3).
    pub fn new(cols: usize, rows: usize, size: f32, spacing: f32) -> Result<Self> {
        if cols == 0 || rows == 0 || cols.saturating_mul(rows) > MAX_TAGS {
            return Err(Error::InvalidParameter("tags"));
        }
        if !(size.is_finite() && size > 0.0) {
            return Err(Error::InvalidParameter("size"));
        }
        if !(spacing > 0.0 && spacing <= 1.0) {
            return Err(Error::InvalidParameter("spacing"));
        }
        Ok(Self {
            cols: cols as u16,
            rows: rows as u16,
            size,
            spacing,
        })
    }

    /// Tags along `x` (Kalibr's `tagCols`).
    pub fn cols(&self) -> usize {
        usize::from(self.cols)
    }

    /// Tags along `y` (Kalibr's `tagRows`).
    pub fn rows(&self) -> usize {
        usize::from(self.rows)
    }

    /// Tag side (Kalibr's `tagSize`).
    pub fn size(&self) -> f32 {
        self.size
    }

    /// Gap between tags over the tag side (Kalibr's `tagSpacing`).
    pub fn spacing(&self) -> f32 {
        self.spacing
    }

    /// The detector configuration for an AprilGrid: the default with
    /// [`DetectorConfig::threshold_fraction`] `3/8`. Kalibr's corner squares meet the tags at
    /// their corners; at AprilTag's `1/2` a pixel on such a junction (half black) joins tag and
    /// square in about half the junctions and the tag is lost: on the rendered sets of
    /// BENCHMARKS.md ("AprilGrid calibration") most tags. At `3/8` a junction joins only where
    /// the two black corners together span more than `5/8` of the turn (225°, far past a
    /// square's 180° seen head on).
    pub fn detector_config() -> DetectorConfig {
        DetectorConfig {
            threshold_fraction: 0.375,
            ..DetectorConfig::default()
        }
    }

    /// The tag family: tag36h11 with a 2-cell border.
    pub fn family(&self) -> &'static Family {
        &families::TAG36H11_B2
    }

    /// Tags, `cols · rows` (ids `0..tags`).
    pub fn tags(&self) -> usize {
        self.cols() * self.rows()
    }

    /// Points, 4 a tag.
    pub fn points(&self) -> usize {
        4 * self.tags()
    }

    /// Point `k` in the board frame (type docs), `None` past the grid.
    pub fn point(&self, k: usize) -> Option<Point2<f32>> {
        if k >= self.points() {
            return None;
        }
        // Non-zero by construction; the type lets the division carry no panic path.
        let cols = NonZeroUsize::new(2 * self.cols())?;
        let (r, c) = (k / cols, k % cols);
        let pitch = (1.0 + self.spacing) * self.size;
        let at = |i: usize| (i / 2) as f32 * pitch + (i % 2) as f32 * self.size;
        Some(Point2::new(at(c), at(r)))
    }

    /// The points of tag `id`'s corners in AprilTag's corner order (bottom-left,
    /// bottom-right, top-right, top-left of the upright tag; type docs), `None` past the grid.
    pub fn tag_points(&self, id: usize) -> Option<[usize; 4]> {
        if id >= self.tags() {
            return None;
        }
        let cols = NonZeroUsize::new(self.cols())?;
        let b = (id / cols) * 4 * cols.get() + (id % cols) * 2;
        Some([b, b + 1, b + 2 * cols.get() + 1, b + 2 * cols.get()])
    }
}
