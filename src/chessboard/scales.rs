//! The scales [`ChessboardDetector::detect_any_scale`](super::ChessboardDetector::detect_any_scale)
//! searches: the levels of a Gaussian pyramid of the frame, and how a corner moves between
//! them.
//!
//! The detector has a fixed scale: the saddle response smooths with σ = 1 px, and the corner
//! test samples rings of 5 and 3 px. Its response falls with the fourth power of the edges'
//! blur, so a view whose edges are spread over several pixels (a sharp board seen by a
//! 1920-px sensor through the same optics as a 640-px one, an upscaled frame, a defocused
//! lens) shows no corner at full resolution, while the same view halved or quartered does.
//! Each pyramid level halves the blur in pixels and the squares' size; the search visits the
//! levels from the coarsest that can still show a board down to the frame itself, and takes
//! the first level where the whole board is found and verified.

use nalgebra::Point2;

use super::config::BoardSize;
use super::ring::OUTER_RADIUS;
use crate::pyramid::{MAX_LEVELS, buffer_len, level_size};

/// The smallest square (pixels) worth searching for: twice the corner test's outer ring, so
/// that the ring around a corner stays inside its four squares with a margin.
pub(super) const MIN_SQUARE: usize = 2 * OUTER_RADIUS as usize;

/// Bytes of the pyramid buffer
/// [`detect_any_scale`](super::ChessboardDetector::detect_any_scale) needs for a
/// `width x height` frame: every level below the frame (at most a third of the frame's
/// pixels).
pub const fn pyramid_len(width: usize, height: usize) -> usize {
    buffer_len(width, height, MAX_LEVELS)
}

/// Levels to build and search for `board` in a `width x height` frame (the frame included):
/// level `l` is searched when the largest board it can show, the board's shorter side across
/// the frame's shorter side, has squares of at least [`MIN_SQUARE`] pixels (so a level
/// searched is at least `4 MIN_SQUARE` pixels each way, above the detector's smallest frame).
/// Always at least 1 (the frame itself).
pub(super) fn levels(width: usize, height: usize, board: BoardSize) -> usize {
    let squares = board.cols().min(board.rows()) + 1;
    let mut n = 1;
    while n < MAX_LEVELS {
        let (w, h) = level_size(width, height, n);
        if w.min(h).checked_div(squares).unwrap_or(0) < MIN_SQUARE {
            break;
        }
        n += 1;
    }
    n
}

/// Whether a board found on a pyramid level is resolved there: every square side (the
/// distance between neighbouring corners along a row or a column of `corners`, row-major with
/// `cols` a row) at least [`MIN_SQUARE`] pixels. A board found with smaller squares on a
/// coarse level is left to the finer levels, where its corners are twice as far apart: on
/// squares of a few pixels the corner test and the refinement mix neighbouring corners.
pub(super) fn resolved(corners: &[Point2<f32>], cols: usize) -> bool {
    if cols == 0 {
        return false;
    }
    let min2 = (MIN_SQUARE * MIN_SQUARE) as f32;
    let far = |a: Option<&Point2<f32>>, b: Option<&Point2<f32>>| match (a, b) {
        (Some(a), Some(b)) => (a - b).norm_squared() >= min2,
        _ => true,
    };
    (0..corners.len()).all(|k| {
        let along = k % cols + 1 == cols || far(corners.get(k), corners.get(k + 1));
        along && far(corners.get(k), corners.get(k + cols))
    })
}

/// Coordinate on level `l` of a point at `c` on level `l + 1`: `pyrDown` centres output pixel
/// `i` on input pixel `2 i`, so the map is `x ↦ 2 x`.
pub(super) fn finer(c: f32) -> f32 {
    2.0 * c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_stop_where_the_largest_board_has_too_small_squares() {
        let board = BoardSize::new(9, 6).unwrap();
        // 7 squares across the shorter side: a level needs 70 px.
        assert_eq!(levels(69, 69, board), 1);
        assert_eq!(levels(140, 140, board), 2);
        assert_eq!(levels(640, 480, board), 3); // 480, 240, 120; 60 < 70
        assert_eq!(levels(4032, 3024, board), 6); // ... 189, 95; 48 < 70
        // Never more than a pyramid holds.
        let small = BoardSize::new(3, 3).unwrap();
        assert_eq!(levels(1 << 15, 1 << 15, small), MAX_LEVELS);
        assert_eq!(levels(128, 128, small), 2); // 4 squares: 128, 64; 32 < 40
    }

    #[test]
    fn resolved_needs_every_square_at_least_min_square() {
        // A 3x2 grid of spacing s (row-major, 3 a row).
        let grid = |s: f32| -> [Point2<f32>; 6] {
            core::array::from_fn(|k| Point2::new((k % 3) as f32 * s, (k / 3) as f32 * s))
        };
        let m = MIN_SQUARE as f32;
        assert!(resolved(&grid(m), 3));
        assert!(!resolved(&grid(m - 0.1), 3));
        // One short step along a row, or down a column, is enough to refuse.
        let mut g = grid(2.0 * m);
        g[1].x = g[0].x + m - 0.5;
        assert!(!resolved(&g, 3));
        let mut g = grid(2.0 * m);
        g[4].y = g[1].y + m - 0.5;
        assert!(!resolved(&g, 3));
        // The end of a row is not a step to the next row's start.
        assert!(resolved(
            &[
                Point2::new(0.0, 0.0),
                Point2::new(m, 0.0),
                Point2::new(0.0, m),
                Point2::new(m, m)
            ],
            2
        ));
    }

    #[test]
    fn the_buffer_holds_every_level() {
        assert_eq!(pyramid_len(64, 48), buffer_len(64, 48, MAX_LEVELS));
        assert!(pyramid_len(4032, 3024) <= 4032 * 3024 / 3);
        // The sizes the module documentation states.
        assert_eq!(pyramid_len(1280, 960), 409_580);
        assert_eq!(pyramid_len(4032, 3024), 4_064_142);
    }
}
