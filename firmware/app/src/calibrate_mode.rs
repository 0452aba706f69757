//! The board's calibrate mode ([`Mode::Calibrate`]): the camera calibrates itself from a
//! chessboard shown to it, and keeps the result.
//!
//! Every frame goes through the chessboard detector ([`crate::calibration::BoardDetector`],
//! the board of [`Settings::chessboard`]). A board found is kept as a view
//! ([`camgeom::calib::Calibrator`]) when it differs from every view kept so far
//! ([`ViewShape::differs`]): a board held still gives the same view frame after frame and is
//! kept once. Each frame is answered with a [`ProgressRecord`] (views kept / needed). Once
//! [`ChessboardSettings::views`] views are in, the calibration is solved and reported (a
//! [`CalibRecord`] as [`encode_result`] sends it, then a last [`ProgressRecord`] with the
//! verdict).
//! A result is taken only when it is good ([`judge`]: no warning, RMS at most
//! [`MAX_RMS_PX`]): then the calibrated camera replaces the settings' camera, the settings are
//! saved to flash at once (a calibration is minutes of work with a board in hand; a reset
//! before a separate `save` would lose it) and the board goes back to tracking with the new
//! camera. A refused calibration (a warning, a large RMS, a solve that fails, frames that end
//! first) is reported with its reason and changes nothing but the mode.
//!
//! # `"CCPG"`, version 1, [`PROGRESS_LEN`] bytes
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | tag, version ([`crate::wire`]) |
//! | 8..16 | `u32` frame (since the mode started), `u32` flags: bit 0 board found, bit 1 view kept |
//! | 16..24 | `u32` views kept, `u32` views needed |
//! | 24..28 | `u32` [`Status`]: 0 collecting, 1 calibrated (camera replaced, saved), 2 calibrated but not saved (the flash failed; the camera is in use), 3 refused |
//! | 28..32 | `u32` why refused: bits 0..2 the [`CalibRecord`]'s warnings, bit 3 RMS above [`MAX_RMS_PX`], bit 4 the solve failed, bit 5 the frames ended first, bit 6 a camera no command takes |
//! | 32..36 | `u32` the solve's error ([`ErrorCode`]; 0 none) |
//! | 36..40 | `u32` the frame's detection cost (the clock's unit) |
//!
//! # `"CCRS"`, version 1, [`RESULT_LEN`] bytes: the solve's result
//!
//! The calibration job's [`CalibRecord`] without its per-view RMS and stack (it must fit the
//! link's frame, [`crate::report::RECORD_LEN`]):
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | tag, version |
//! | 8..24 | `u32` views used, LM steps, warnings (bit 0 focal length, 1 principal point, 2 lens), solve cost |
//! | 24..60 | `f32` `fx fy cx cy`, `k1 k2 p1 p2 k3` |
//! | 60..68 | `f32` RMS, initial RMS (px) |
//! | 68..104 | `f32` × 9 standard deviations of `fx fy cx cy` and the lens coefficients |

use core::mem::MaybeUninit;

use camgeom::Error;
use camgeom::calib::CalibrationParams;
use camgeom::chessboard::{BoardSize, DetectParams};
use camgeom::image::{ImageMut, ImageView};
use camgeom::nalgebra::Point2;

use crate::calibration::{BoardCalibrator, BoardDetector, CORNERS, CalibError, CalibRecord, VIEWS};
use crate::command::{ChessboardSettings, Command, Mode};
use crate::pipeline::Clock;
use crate::report::ErrorCode;
use crate::settings::{SaveError, Settings};
use crate::source::FrameSource;
use crate::wire::{Reader, WireError, Writer, tag};

/// The progress record's tag.
pub const PROGRESS_TAG: u32 = tag(b"CCPG");
/// Its layout version.
pub const VERSION: u32 = 1;
/// Its bytes.
pub const PROGRESS_LEN: usize = 40;
/// The result record's tag.
pub const RESULT_TAG: u32 = tag(b"CCRS");
/// Its bytes.
pub const RESULT_LEN: usize = 104;

// Every record of the mode goes through the link's frames.
const _: () =
    assert!(PROGRESS_LEN <= crate::report::RECORD_LEN && RESULT_LEN <= crate::report::RECORD_LEN);

/// The [`RESULT_LEN`] bytes of a result.
pub fn encode_result(r: &CalibRecord) -> [u8; RESULT_LEN] {
    Writer::fill(RESULT_TAG, VERSION, |w| {
        w.u32s([r.views_used, r.iterations, r.warnings, r.cost]);
        w.f32s(r.intrinsics);
        w.f32s(r.distortion);
        w.f32s([r.rms_px, r.initial_rms_px]);
        w.f32s(r.std);
    })
}

/// Decodes a result ([`encode_result`]): per-view RMS NaN, stack 0. Errors: [`WireError`]
/// (length, tag, version).
pub fn decode_result(bytes: &[u8]) -> Result<CalibRecord, WireError> {
    let mut r = Reader::new_checked(
        "calibrate_result",
        bytes,
        RESULT_LEN,
        &[RESULT_TAG],
        VERSION,
    )?;
    let [views_used, iterations, warnings, cost] = r.u32s();
    let intrinsics = r.f32s();
    let distortion = r.f32s();
    let [rms_px, initial_rms_px] = r.f32s();
    Ok(CalibRecord {
        views_used,
        iterations,
        cost,
        warnings,
        intrinsics,
        distortion,
        rms_px,
        initial_rms_px,
        std: r.f32s(),
        per_view_rms_px: [f32::NAN; VIEWS],
        stack: 0,
    })
}

/// The largest RMS reprojection error (pixels) of a calibration the board takes. Corners
/// found to a tenth of a pixel on a flat board give an RMS of a few tenths; OpenCV's
/// documentation calls an RMS under a pixel a good calibration, and one above it means
/// corners in the wrong place, a bent board or a lens model that does not fit.
pub const MAX_RMS_PX: f32 = 1.0;

/// Why refused ([`ProgressRecord::reason`]): bits 0..2 are the [`CalibRecord`]'s warnings.
pub mod reason {
    /// The RMS is above [`super::MAX_RMS_PX`].
    pub const RMS: u32 = 1 << 3;
    /// The solve failed ([`super::ProgressRecord::error`] says how).
    pub const SOLVE: u32 = 1 << 4;
    /// The frames ended before enough views were kept.
    pub const ENDED: u32 = 1 << 5;
    /// The calibrated camera is one no `camera` command takes.
    pub const CAMERA: u32 = 1 << 6;
}

/// Where a calibration stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status {
    /// Views are being kept.
    Collecting,
    /// Solved, good, the camera replaced and saved.
    Calibrated,
    /// Solved, good, the camera replaced, but the flash did not take it.
    Unsaved,
    /// Solved badly or not at all: the camera is unchanged.
    Refused,
}

impl Status {
    const ALL: [Status; 4] = [
        Status::Collecting,
        Status::Calibrated,
        Status::Unsaved,
        Status::Refused,
    ];

    /// The name the monitor prints.
    pub fn name(self) -> &'static str {
        match self {
            Status::Collecting => "collecting",
            Status::Calibrated => "calibrated",
            Status::Unsaved => "calibrated_not_saved",
            Status::Refused => "refused",
        }
    }
}

/// One frame of the calibrate mode, or its verdict.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProgressRecord {
    /// Frames since the mode started (the verdict: the frames it took).
    pub frame: u32,
    /// The board was found in the frame.
    pub found: bool,
    /// ... and kept as a view.
    pub kept: bool,
    /// Views kept.
    pub views: u32,
    /// Views needed.
    pub needed: u32,
    /// Where the calibration stands.
    pub status: Status,
    /// Why refused ([`reason`]; the [`CalibRecord`] warnings in bits 0..2).
    pub reason: u32,
    /// The solve's error code ([`ErrorCode::of_core`]; 0 none).
    pub error: u32,
    /// The detection's cost (the clock's unit).
    pub cost: u32,
}

impl ProgressRecord {
    /// The [`PROGRESS_LEN`] bytes.
    pub fn encode(&self) -> [u8; PROGRESS_LEN] {
        let status = Status::ALL
            .iter()
            .position(|s| *s == self.status)
            .unwrap_or(0) as u32;
        Writer::fill(PROGRESS_TAG, VERSION, |w| {
            w.u32s([
                self.frame,
                u32::from(self.found) | u32::from(self.kept) << 1,
                self.views,
                self.needed,
                status,
                self.reason,
                self.error,
                self.cost,
            ]);
        })
    }

    /// Decodes a progress record. Errors: [`WireError`] (length, tag, version; `Field` for
    /// `flags` or `status`).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked(
            "calibrate_progress",
            bytes,
            PROGRESS_LEN,
            &[PROGRESS_TAG],
            VERSION,
        )?;
        let [frame, flags, views, needed, status, reason, error, cost] = r.u32s();
        if flags > 3 {
            return Err(r.invalid("flags"));
        }
        Ok(Self {
            frame,
            found: flags & 1 != 0,
            kept: flags & 2 != 0,
            views,
            needed,
            status: usize::try_from(status)
                .ok()
                .and_then(|s| Status::ALL.get(s).copied())
                .ok_or(r.invalid("status"))?,
            reason,
            error,
            cost,
        })
    }
}

/// What tells one view of the board from another: where the board is, how large, and how
/// tilted, from the four outer corners of the detected board.
///
/// - `centre`: the mean of the four outer corners (pixels);
/// - `size`: `ln √area` of the outer quadrilateral (its change is the relative change of the
///   board's apparent size, i.e. of its distance);
/// - `tilt`: `ln(top / bottom)` and `ln(left / right)` of the outer edges' lengths: 0 for a
///   board facing the camera, and the perspective foreshortening of a board turned about its
///   horizontal or vertical axis (the views' plane normals are what Zhang's method needs to
///   differ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewShape {
    /// Mean of the outer corners, pixels.
    pub centre: [f32; 2],
    /// `ln √area` of the outer quadrilateral.
    pub size: f32,
    /// `ln(top / bottom)`, `ln(left / right)`.
    pub tilt: [f32; 2],
}

/// A view is new when its centre moved by this fraction of the image diagonal (16 px at
/// 320x240) from a kept view's ...
pub const MIN_SHIFT: f32 = 0.05;
/// ... or its apparent size changed by 10 % ...
pub const MIN_SCALE: f32 = 0.1;
/// ... or an edge ratio changed by 5 % (a turn of the board of roughly 10° at arm's length).
pub const MIN_TILT: f32 = 0.05;

impl ViewShape {
    /// The shape of a board of `cols x rows` corners (row-major, as the detector gives
    /// them); `None` for too few corners or a degenerate outline.
    pub fn of(corners: &[Point2<f32>], cols: usize, rows: usize) -> Option<Self> {
        let c = |i: usize| corners.get(i).copied();
        let last = cols.checked_mul(rows)?.checked_sub(1)?;
        let (a, b) = (c(0)?, c(cols.checked_sub(1)?)?);
        let (d, e) = (c((rows.checked_sub(1)?).checked_mul(cols)?)?, c(last)?);
        // a b (top), d e (bottom).
        let len = |p: Point2<f32>, q: Point2<f32>| libm::hypotf(q.x - p.x, q.y - p.y);
        let (top, bottom, left, right) = (len(a, b), len(d, e), len(a, d), len(b, e));
        // Shoelace area of a, b, e, d.
        let pts = [a, b, e, d];
        let mut twice = 0.0f32;
        for (k, p) in pts.iter().enumerate() {
            let q = pts.get((k + 1) % 4)?;
            twice += p.x * q.y - q.x * p.y;
        }
        let area = 0.5 * twice.abs();
        let shape = Self {
            centre: [(a.x + b.x + d.x + e.x) / 4.0, (a.y + b.y + d.y + e.y) / 4.0],
            size: 0.5 * libm::logf(area),
            tilt: [libm::logf(top / bottom), libm::logf(left / right)],
        };
        let finite = shape
            .centre
            .iter()
            .chain(&shape.tilt)
            .all(|v| v.is_finite());
        (finite && shape.size.is_finite() && area > 0.0).then_some(shape)
    }

    /// Whether this view differs from `kept` enough to be worth keeping too: its centre
    /// moved by [`MIN_SHIFT`] of the image `diagonal`, or its size changed by
    /// [`MIN_SCALE`], or either tilt by [`MIN_TILT`]. Corner noise (a tenth of a pixel)
    /// moves none of them by a thousandth of that: a still board is kept once.
    pub fn differs(&self, kept: &Self, diagonal: f32) -> bool {
        let [dx, dy] = [
            self.centre[0] - kept.centre[0],
            self.centre[1] - kept.centre[1],
        ];
        libm::sqrtf(dx * dx + dy * dy) >= MIN_SHIFT * diagonal
            || (self.size - kept.size).abs() >= MIN_SCALE
            || (self.tilt[0] - kept.tilt[0]).abs() >= MIN_TILT
            || (self.tilt[1] - kept.tilt[1]).abs() >= MIN_TILT
    }
}

/// Why a solved calibration is not taken: 0 when it is good (no warning, RMS at most
/// [`MAX_RMS_PX`]), else the [`reason`] bits.
pub fn judge(r: &CalibRecord) -> u32 {
    let mut why = r.warnings & 7;
    if !(r.rms_px.is_finite() && r.rms_px <= MAX_RMS_PX) {
        why |= reason::RMS;
    }
    // The camera must be one a `camera` command could set (the settings hold only such).
    let camera = Command::SetCamera {
        intrinsics: r.intrinsics,
        distortion: r.distortion,
    };
    if Command::decode(&camera.encode()).is_err() {
        why |= reason::CAMERA;
    }
    why
}

/// One calibration in progress: the views kept so far (their shapes; the calibrator holds
/// their corners).
#[derive(Debug, Clone)]
pub struct Session {
    board: BoardSize,
    needed: usize,
    width: usize,
    height: usize,
    diagonal: f32,
    shapes: camgeom::heapless::Vec<ViewShape, VIEWS>,
    frames: u32,
}

/// How a calibration ended: the records it sent last and the settings in force after it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    /// The solve's result, when it solved.
    pub result: Option<CalibRecord>,
    /// The verdict ([`ProgressRecord::status`] not [`Status::Collecting`]).
    pub verdict: ProgressRecord,
    /// The settings now: the calibrated camera when taken, the mode back to tracking.
    pub settings: Settings,
}

impl Session {
    /// A calibration of the chessboard `board` in `width x height` frames, and the
    /// calibrator made for it in `slot` (the board's, a `static`: 25 KB). Errors: as
    /// [`BoardSize::new`] and [`camgeom::calib::Calibrator::new`].
    pub fn new<'c>(
        board: &ChessboardSettings,
        width: usize,
        height: usize,
        slot: &'c mut MaybeUninit<BoardCalibrator>,
    ) -> Result<(Self, &'c mut BoardCalibrator), Error> {
        let size = BoardSize::new(usize::from(board.cols), usize::from(board.rows))?;
        let calibrator = slot.write(BoardCalibrator::new(size, board.square, width, height)?);
        let (w, h) = (width as f32, height as f32);
        let session = Self {
            board: size,
            needed: usize::from(board.views).clamp(3, VIEWS),
            width,
            height,
            diagonal: libm::sqrtf(w * w + h * h),
            shapes: camgeom::heapless::Vec::new(),
            frames: 0,
        };
        Ok((session, calibrator))
    }

    /// Views kept.
    pub fn views(&self) -> usize {
        self.shapes.len()
    }

    /// Enough views are kept to solve.
    pub fn ready(&self) -> bool {
        self.shapes.len() >= self.needed
    }

    /// Whether a view of this shape would be kept now (not ready, and it differs from every
    /// kept view).
    pub fn keeps(&self, shape: &ViewShape) -> bool {
        !self.ready() && self.shapes.iter().all(|k| shape.differs(k, self.diagonal))
    }

    fn progress(&self, found: bool, kept: bool, cost: u32) -> ProgressRecord {
        ProgressRecord {
            frame: self.frames,
            found,
            kept,
            views: self.shapes.len() as u32,
            needed: self.needed as u32,
            status: Status::Collecting,
            reason: 0,
            error: 0,
            cost,
        }
    }

    /// One frame: detects the board (`scratch`: [`crate::calibration::scratch_len`] of the
    /// width), keeps it as a view when [`Self::keeps`] says so. Errors: from the detector or
    /// the calibrator (a frame of another size).
    pub fn frame(
        &mut self,
        img: &ImageView<'_, u8>,
        detector: &mut BoardDetector,
        scratch: &mut [i32],
        calibrator: &mut BoardCalibrator,
        clock: &mut impl Clock,
    ) -> Result<ProgressRecord, Error> {
        let t0 = clock.now();
        let found =
            detector.detect::<CORNERS>(img, self.board, &DetectParams::default(), scratch)?;
        let cost = u32::try_from(clock.now().saturating_sub(t0)).unwrap_or(u32::MAX);
        self.frames = self.frames.saturating_add(1);
        let Some(b) = found else {
            return Ok(self.progress(false, false, cost));
        };
        let shape = ViewShape::of(&b.corners, self.board.cols(), self.board.rows());
        let keep = shape.filter(|s| self.keeps(s));
        if let Some(s) = keep {
            calibrator.add_chessboard(self.width, self.height, &b)?;
            // `keeps` said the views are fewer than `needed`, at most VIEWS.
            let _ = self.shapes.push(s);
        }
        Ok(self.progress(true, keep.is_some(), cost))
    }

    /// Solves from the views kept and judges the result ([`judge`]): with `settings` (those
    /// in force, mode [`Mode::Calibrate`]) the [`Outcome`], whose settings have the
    /// calibrated camera when it is good, and mode `back` either way. `save` stores good
    /// settings. Frames that ended before [`Self::ready`] refuse without solving.
    pub fn finish(
        &mut self,
        calibrator: &mut BoardCalibrator,
        settings: &Settings,
        back: Mode,
        clock: &mut impl Clock,
        save: impl FnOnce(&Settings) -> Result<(), SaveError>,
    ) -> Outcome {
        let mut verdict = self.progress(false, false, 0);
        verdict.status = Status::Refused;
        let mut next = Settings {
            mode: back,
            ..*settings
        };
        if !self.ready() {
            verdict.reason = reason::ENDED;
            return Outcome {
                result: None,
                verdict,
                settings: next,
            };
        }
        let t0 = clock.now();
        let solved = calibrator.solve(&CalibrationParams::default());
        let cost = u32::try_from(clock.now().saturating_sub(t0)).unwrap_or(u32::MAX);
        let result = match solved {
            Ok(report) => CalibRecord::of(&report, cost),
            Err(e) => {
                verdict.reason = reason::SOLVE;
                verdict.error = u32::from(ErrorCode::of_core(&e).0);
                return Outcome {
                    result: None,
                    verdict,
                    settings: next,
                };
            }
        };
        verdict.reason = judge(&result);
        if verdict.reason == 0 {
            next.intrinsics = result.intrinsics;
            next.distortion = result.distortion;
            verdict.status = match save(&next) {
                Ok(()) => Status::Calibrated,
                Err(_) => Status::Unsaved,
            };
        }
        Outcome {
            result: Some(result),
            verdict,
            settings: next,
        }
    }
}

/// The buffers of the calibrate mode besides its frame, each the caller's (a board's
/// `static`s).
pub struct Buffers<'a> {
    /// The chessboard detector.
    pub detector: &'a mut BoardDetector,
    /// Its scratch ([`crate::calibration::scratch_len`] of the width).
    pub scratch: &'a mut [i32],
    /// Room for the calibrator (made for the board by [`Session::new`]).
    pub calibrator: &'a mut MaybeUninit<BoardCalibrator>,
}

/// The calibrate mode over the frames of `source`, the same on a board and in its host
/// replay: each frame into `frame` (of the source's size; a board lends one of its
/// pipeline's, [`crate::pipeline::FrameLoop::lend_frame`]), a [`Session`] of `settings`'
/// chessboard, each frame's [`ProgressRecord`] to
/// `send`, until enough views are kept or the source ends; then [`Session::finish`]
/// (`back`, `save` as there), whose [`CalibRecord`] (when it solved) and verdict go to
/// `send` too. Errors: the source's, or the core's for buffers that do not fit the frames.
#[allow(clippy::too_many_arguments)]
pub fn calibrate_mode<Src: FrameSource>(
    settings: &Settings,
    back: Mode,
    source: &mut Src,
    frame: &mut ImageMut<'_, u8>,
    buffers: Buffers<'_>,
    clock: &mut impl Clock,
    send: &mut impl FnMut(&[u8]),
    save: impl FnOnce(&Settings) -> Result<(), SaveError>,
) -> Result<Outcome, CalibError<Src::Error>> {
    let (w, h) = source.size();
    if (frame.width(), frame.height()) != (w, h) {
        return Err(CalibError::Core(Error::InvalidImage));
    }
    let (mut session, calibrator) = Session::new(&settings.chessboard, w, h, buffers.calibrator)?;
    while !session.ready() {
        if !source.next_frame(frame).map_err(CalibError::Source)? {
            break;
        }
        let img = frame.as_view();
        let p = session.frame(&img, buffers.detector, buffers.scratch, calibrator, clock)?;
        send(&p.encode());
    }
    let outcome = session.finish(calibrator, settings, back, clock, save);
    if let Some(r) = &outcome.result {
        send(&encode_result(r));
    }
    send(&outcome.verdict.encode());
    Ok(outcome)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::NoClock;
    use std::vec::Vec;

    /// The corners of a `cols x rows` board of `step` px seen under the homography-like map
    /// `f`.
    fn board(cols: usize, rows: usize, f: impl Fn(f32, f32) -> (f32, f32)) -> Vec<Point2<f32>> {
        let mut v = Vec::new();
        for j in 0..rows {
            for i in 0..cols {
                let (x, y) = f(i as f32, j as f32);
                v.push(Point2::new(x, y));
            }
        }
        v
    }

    fn facing(x0: f32, y0: f32, step: f32) -> impl Fn(f32, f32) -> (f32, f32) {
        move |i, j| (x0 + step * i, y0 + step * j)
    }

    /// A board turned about its vertical axis: the right side farther (smaller).
    fn turned(k: f32) -> impl Fn(f32, f32) -> (f32, f32) {
        move |i, j| {
            let w = 1.0 + k * i;
            (60.0 + 20.0 * i / w, 70.0 + 20.0 * (j - 2.5) / w + 50.0)
        }
    }

    #[test]
    fn a_still_board_is_kept_once_and_moved_or_turned_boards_again() {
        let diag = (320.0f32 * 320.0 + 240.0 * 240.0).sqrt();
        let a = ViewShape::of(&board(9, 6, facing(60.0, 60.0, 20.0)), 9, 6).unwrap();
        assert!(a.tilt.iter().all(|t| t.abs() < 1e-6));
        // The same board, its corners jittered by a tenth of a pixel.
        let jitter = board(9, 6, |i, j| {
            let (x, y) = facing(60.0, 60.0, 20.0)(i, j);
            (x + 0.1 * (i * 7.0 + j).sin(), y - 0.1 * (j * 3.0 + i).cos())
        });
        let still = ViewShape::of(&jitter, 9, 6).unwrap();
        assert!(!still.differs(&a, diag));
        // Moved by 20 px: a new view; by 10 px: not.
        let moved = ViewShape::of(&board(9, 6, facing(80.0, 60.0, 20.0)), 9, 6).unwrap();
        let near = ViewShape::of(&board(9, 6, facing(70.0, 60.0, 20.0)), 9, 6).unwrap();
        assert!(moved.differs(&a, diag) && !near.differs(&a, diag));
        // Closer (squares 15 % larger, same centre): new.
        let closer = ViewShape::of(&board(9, 6, facing(48.0, 52.5, 23.0)), 9, 6).unwrap();
        assert!((closer.centre[0] - a.centre[0]).abs() < 1.0);
        assert!(closer.differs(&a, diag));
        // Turned: the far side shorter, a tilt of the board's left/right edges.
        let t = ViewShape::of(&board(9, 6, turned(0.02)), 9, 6).unwrap();
        assert!(t.tilt[1] > MIN_TILT);
        let t0 = ViewShape::of(&board(9, 6, turned(0.0)), 9, 6).unwrap();
        assert!((t.tilt[1] - t0.tilt[1]).abs() >= MIN_TILT && t.differs(&t0, diag));
        // Too few corners, or all in one point: no shape.
        assert_eq!(
            ViewShape::of(&board(9, 5, facing(0.0, 0.0, 1.0)), 9, 6),
            None
        );
        assert_eq!(
            ViewShape::of(&board(9, 6, facing(5.0, 5.0, 0.0)), 9, 6),
            None
        );
    }

    #[test]
    fn a_session_keeps_only_new_views_up_to_the_count() {
        let mut slot = MaybeUninit::uninit();
        let b = ChessboardSettings {
            views: 3,
            ..ChessboardSettings::DEFAULT
        };
        let (mut s, cal) = Session::new(&b, 320, 240, &mut slot).unwrap();
        assert_eq!(cal.views(), 0);
        let shape = |x| ViewShape::of(&board(9, 6, facing(x, 60.0, 20.0)), 9, 6).unwrap();
        for x in [60.0, 61.0, 62.0] {
            let keep = s.keeps(&shape(x));
            assert_eq!(keep, x == 60.0);
            if keep {
                s.shapes.push(shape(x)).unwrap();
            }
        }
        for x in [90.0, 120.0] {
            assert!(s.keeps(&shape(x)));
            s.shapes.push(shape(x)).unwrap();
        }
        assert!(s.ready() && !s.keeps(&shape(150.0)));
    }

    fn settings() -> Settings {
        Settings {
            mode: Mode::Calibrate,
            family: 0,
            id: 0,
            tag_size: 0.1,
            intrinsics: [300.0, 300.0, 160.0, 120.0],
            distortion: [0.0; 5],
            chessboard: ChessboardSettings {
                views: 3,
                ..ChessboardSettings::DEFAULT
            },
        }
    }

    fn result(warnings: u32, rms_px: f32) -> CalibRecord {
        CalibRecord {
            views_used: 10,
            iterations: 5,
            cost: 0,
            warnings,
            intrinsics: [266.0, 266.5, 161.0, 118.0],
            distortion: [-0.26, 0.1, 0.001, 0.0, -0.02],
            rms_px,
            initial_rms_px: 0.7,
            std: [0.5; 9],
            per_view_rms_px: [0.2; VIEWS],
            stack: 0,
        }
    }

    #[test]
    fn only_a_good_calibration_is_taken() {
        assert_eq!(judge(&result(0, 0.2)), 0);
        assert_eq!(judge(&result(4, 0.2)), 4);
        assert_eq!(judge(&result(0, 1.5)), reason::RMS);
        assert_eq!(judge(&result(0, f32::NAN)), reason::RMS);
        let mut bad = result(0, 0.2);
        bad.intrinsics[0] = -1.0;
        assert_eq!(judge(&bad), reason::CAMERA);
    }

    #[test]
    fn a_calibration_that_cannot_solve_is_refused_and_changes_no_camera() {
        let start = settings();
        let mut slot = MaybeUninit::uninit();
        let (mut s, cal) = Session::new(&start.chessboard, 320, 240, &mut slot).unwrap();
        let no_save = |_: &Settings| -> Result<(), SaveError> { panic!("saved") };
        // No view: the frames ended first.
        let o = s.finish(cal, &start, Mode::TrackTag, &mut NoClock, no_save);
        assert_eq!(
            (o.verdict.status, o.verdict.reason),
            (Status::Refused, reason::ENDED)
        );
        assert_eq!(o.result, None);
        assert_eq!(
            o.settings,
            Settings {
                mode: Mode::TrackTag,
                ..start
            }
        );
        // Three views of a board facing the camera, only moved: parallel planes, which do
        // not determine the camera. The solve fails or is judged bad; the camera stays.
        for x in [40.0, 80.0, 120.0] {
            let c = board(9, 6, facing(x, 60.0, 15.0));
            cal.add_view(320, 240, &c).unwrap();
            s.shapes.push(ViewShape::of(&c, 9, 6).unwrap()).unwrap();
        }
        assert!(s.ready());
        let o = s.finish(cal, &start, Mode::TrackTag, &mut NoClock, no_save);
        assert_eq!(o.verdict.status, Status::Refused);
        assert_ne!(o.verdict.reason, 0);
        assert_eq!(
            (o.settings.intrinsics, o.settings.distortion),
            (start.intrinsics, start.distortion)
        );
        assert_eq!(ProgressRecord::decode(&o.verdict.encode()), Ok(o.verdict));
    }

    #[test]
    fn progress_records_round_trip() {
        for status in Status::ALL {
            let p = ProgressRecord {
                frame: 12,
                found: true,
                kept: false,
                views: 4,
                needed: 10,
                status,
                reason: reason::RMS | 4,
                error: 17,
                cost: 123_456,
            };
            assert_eq!(ProgressRecord::decode(&p.encode()), Ok(p));
        }
        let r = result(3, 0.25);
        let back = decode_result(&encode_result(&r)).unwrap();
        assert_eq!(
            (back.intrinsics, back.distortion, back.std, back.warnings),
            (r.intrinsics, r.distortion, r.std, r.warnings)
        );
        assert!(back.per_view_rms_px.iter().all(|v| v.is_nan()));
        let mut b = ProgressRecord::decode(&[0; PROGRESS_LEN]);
        assert!(b.is_err());
        let mut slot = MaybeUninit::uninit();
        let mut bytes = Session::new(&ChessboardSettings::DEFAULT, 320, 240, &mut slot)
            .unwrap()
            .0
            .progress(true, true, 0)
            .encode();
        bytes[12] = 4;
        b = ProgressRecord::decode(&bytes);
        assert!(matches!(b, Err(WireError::Field { field: "flags", .. })));
    }
}
