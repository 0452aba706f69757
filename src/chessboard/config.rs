//! What a detection looks for and how: the board's size, the detector's thresholds and the
//! sub-pixel refinement.

use super::subpix::{SaddleConfig, SubPixConfig};
use crate::{Error, Result};

/// The inner-corner count of a chessboard: `cols` corners per row (OpenCV's
/// `patternSize.width`), `rows` rows (`patternSize.height`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BoardSize {
    cols: u8,
    rows: u8,
}

impl BoardSize {
    /// At least 3 corners each way (OpenCV's minimum), at most 64. Errors with
    /// `InvalidParameter("board.cols")` / `("board.rows")`.
    pub fn new(cols: usize, rows: usize) -> Result<Self> {
        if !(3..=64).contains(&cols) {
            return Err(Error::InvalidParameter("board.cols"));
        }
        if !(3..=64).contains(&rows) {
            return Err(Error::InvalidParameter("board.rows"));
        }
        Ok(Self {
            cols: cols as u8,
            rows: rows as u8,
        })
    }
    /// Corners per row.
    pub fn cols(&self) -> usize {
        self.cols as usize
    }
    /// Rows.
    pub fn rows(&self) -> usize {
        self.rows as usize
    }
    /// `cols · rows`.
    pub fn corners(&self) -> usize {
        self.cols() * self.rows()
    }
}

/// Detection parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectConfig {
    /// Smallest saddle response kept, `(I_xy² - I_xx I_yy) / 2²⁰` with the derivatives of the
    /// smoothed image in 1/256 grey levels. It falls with the square of the contrast and the
    /// fourth power of the blur: the weakest corners of the bundled 640x480 views (a thin,
    /// blurred row of squares seen at a grazing angle) reach 14..15, so the default `6` keeps
    /// them with a margin of two. `>= 1`.
    pub min_response: i32,
    /// Smallest mean grey-level difference between neighbouring cells (`>= 1`).
    pub min_contrast: u8,
    /// Seeds tried before giving up (`1..=64`).
    pub max_seeds: u8,
    /// Sub-pixel refinement of the found corners.
    pub refine: Refinement,
}

/// How [`super::ChessboardDetector::detect`] refines the corners it found.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Refinement {
    /// The detector's own estimate (the response maximum with a parabola fit, about 0.2 px).
    None,
    /// OpenCV's `cornerSubPix` ([`super::corner_subpix`]) with one window for every corner: for
    /// results that compare one to one with OpenCV's.
    CornerSubPix(SubPixConfig),
    /// [`super::corner_subpix`] with the window shrunk per corner to fit its squares: half window
    /// `min(half_window, max(2, ⌊d / 2⌋))`, `d` the distance to the corner's nearest grid
    /// neighbour, so a large window never reaches the next corner where perspective makes
    /// the squares small.
    AdaptiveCornerSubPix(SubPixConfig),
    /// The saddle point of the smoothed image ([`super::saddle_subpix`]): the most accurate on
    /// the rendered boards, ahead of `cornerSubPix` and OpenCV's `findChessboardCornersSB`
    /// (BENCHMARKS.md, "Corner error against rendered truth").
    Saddle(SaddleConfig),
}

impl Default for DetectConfig {
    fn default() -> Self {
        Self {
            min_response: 6,
            min_contrast: 20,
            max_seeds: 16,
            refine: Refinement::Saddle(SaddleConfig::default()),
        }
    }
}

impl DetectConfig {
    /// Checks every field once, the refinement's included: [`super::ChessboardDetector::detect`]
    /// takes the checked [`DetectParams`].
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field: `min_response` below 1,
    /// `min_contrast` 0, `max_seeds` outside 1 ..= 64, and the refinement's fields
    /// ([`SubPixConfig::check`], [`SaddleConfig::check`]).
    pub fn check(&self) -> Result<DetectParams> {
        if self.min_response < 1 {
            return Err(Error::InvalidParameter("min_response"));
        }
        if self.min_contrast == 0 {
            return Err(Error::InvalidParameter("min_contrast"));
        }
        if self.max_seeds == 0 || self.max_seeds > 64 {
            return Err(Error::InvalidParameter("max_seeds"));
        }
        match &self.refine {
            Refinement::CornerSubPix(s) | Refinement::AdaptiveCornerSubPix(s) => {
                s.check()?;
            }
            Refinement::Saddle(s) => {
                s.check()?;
            }
            Refinement::None => {}
        }
        Ok(DetectParams(*self))
    }
}

/// A [`DetectConfig`] that passed [`DetectConfig::check`]: what
/// [`super::ChessboardDetector::detect`] takes, so that no frame validates it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DetectParams(DetectConfig);

impl DetectParams {
    /// The checked configuration.
    pub const fn config(&self) -> &DetectConfig {
        &self.0
    }
}

impl Default for DetectParams {
    /// The checked [`DetectConfig::default`].
    fn default() -> Self {
        Self(DetectConfig::default())
    }
}

impl TryFrom<DetectConfig> for DetectParams {
    type Error = Error;
    fn try_from(c: DetectConfig) -> Result<Self> {
        c.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each `Default` of a checked type is its configuration's default, checked.
    #[test]
    fn the_defaults_pass_their_checks() {
        assert_eq!(DetectConfig::default().check(), Ok(DetectParams::default()));
        assert_eq!(
            SubPixConfig::default().check(),
            Ok(super::super::SubPixParams::default())
        );
        assert_eq!(
            SaddleConfig::default().check(),
            Ok(super::super::SaddleParams::default())
        );
    }
}
