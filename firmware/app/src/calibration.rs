//! The board calibrates its camera: chessboard views in, K, distortion and RMS out.
//!
//! Each frame goes through [`camgeom::chessboard::ChessboardDetector::detect`]; a board found
//! is kept in fixed RAM ([`camgeom::calib::Calibrator`], up to [`VIEWS`] views of up to
//! [`CORNERS`] corners), and once every frame is in, [`camgeom::calib::Calibrator::solve`] gives
//! the camera. [`calibrate`] is the whole job, the same on the board and in its host replay; it
//! reports one [`ViewRecord`] per frame and a [`CalibRecord`] at the end, fixed-layout binary
//! records encoded and decoded here only:
//!
//! | bytes | view record (`"CVEW"`) | result record (`"CCAL"`) |
//! |---|---|---|
//! | 0..8 | tag, version ([`crate::wire`]) | tag, version |
//! | 8..20 | `u32` frame, `u32` found (0/1), `u32` detection cost | `u32` views used, `u32` LM steps, `u32` solve cost |
//! | 20..24 | `u32` corners | `u32` warnings (bit 0 focal length, 1 principal point, 2 lens) |
//! | 24.. | `f32` `x y` of each corner, board order ([`CORNERS`] pairs) | `f32` `fx fy cx cy`, `k1 k2 p1 p2 k3`, RMS, initial RMS, 9 standard deviations, then [`VIEWS`] per-view RMS (NaN: rejected), `u32` stack used |
//!
//! The run description is [`CalibSpec`] (`calib.bin`, `"CSPC"`, version 3): tag and version,
//! then `u32` width, height, frames, columns, rows, `f32` square side, and the board: `u32`
//! kind (0 a chessboard of `columns x rows` inner corners, 1 a ChArUco board of
//! `columns x rows` squares), `f32` marker side and `u32` dictionary (OpenCV's
//! `PredefinedDictionaryType`; both 0 for a chessboard). A ChArUco spec is run by
//! [`crate::charuco_calibration`].

use camgeom::Error;
use camgeom::calib::{CalibrationParams, CalibrationReport, CalibrationWarning, Calibrator};
use camgeom::chessboard::{BoardSize, ChessboardDetector, DetectParams};
use camgeom::image::ImageMut;
use camgeom::image::ImageView;

use crate::pipeline::Clock;
use crate::source::FrameSource;
use crate::wire::{Reader, WireError, Writer, tag};

/// Views the board keeps at most.
pub const VIEWS: usize = 16;
/// Inner corners of a board at most (9x6 is 54).
pub const CORNERS: usize = 64;
/// Corner candidates of the detector.
pub const CANDIDATES: usize = 512;
/// Bytes of every calibration record.
pub const RECORD_LEN: usize = 24 + 8 * CORNERS;
/// Bytes of a [`CalibSpec`].
pub const SPEC_LEN: usize = 44;

const VIEW_TAG: u32 = tag(b"CVEW");
const RESULT_TAG: u32 = tag(b"CCAL");
const SPEC_TAG: u32 = tag(b"CSPC");
const VERSION: u32 = 1;
/// The spec's layout version (2: the version word of every record, [`crate::wire`]; 3: the
/// board's kind).
const SPEC_VERSION: u32 = 3;

/// The board's calibrator: f32, [`VIEWS`] x [`CORNERS`].
pub type BoardCalibrator = Calibrator<f32, VIEWS, CORNERS>;
/// The board's chessboard detector.
pub type BoardDetector = ChessboardDetector<CANDIDATES>;

/// `i32` words of detector scratch for frames `width` wide.
pub const fn scratch_len(width: usize) -> usize {
    camgeom::chessboard::scratch_len(width)
}

/// The kind of board a [`CalibSpec`] calibrates from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SpecBoard {
    /// A chessboard: the spec's columns and rows are its inner corners ([`calibrate`]).
    Chessboard,
    /// A ChArUco board: the spec's columns and rows are its squares, as OpenCV's
    /// `CharucoBoard` size ([`crate::charuco_calibration::calibrate_charuco`]).
    Charuco {
        /// Marker side, in the square's unit.
        marker: f32,
        /// OpenCV's `PredefinedDictionaryType` of the markers
        /// ([`crate::charuco_calibration::dictionary`]).
        dictionary: u32,
    },
}

/// What the calibration job is told: frame size, board, square side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibSpec {
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames to read.
    pub frames: u32,
    /// Inner corners along a row.
    pub cols: u32,
    /// Inner corners along a column.
    pub rows: u32,
    /// Square side (any unit: the poses come out in it).
    pub square: f32,
    /// The kind of board.
    pub board: SpecBoard,
}

impl CalibSpec {
    /// The [`SPEC_LEN`] bytes.
    pub fn to_bytes(&self) -> [u8; SPEC_LEN] {
        Writer::fill(SPEC_TAG, SPEC_VERSION, |w| {
            w.u32s([self.width, self.height, self.frames, self.cols, self.rows]);
            w.f32(self.square);
            let (kind, marker, dictionary) = match self.board {
                SpecBoard::Chessboard => (0, 0.0, 0),
                SpecBoard::Charuco { marker, dictionary } => (1, marker, dictionary),
            };
            w.u32(kind);
            w.f32(marker);
            w.u32(dictionary);
        })
    }

    /// Decodes [`SPEC_LEN`] bytes. Errors: [`WireError`] (length, tag, version, a board kind
    /// other than 0 and 1).
    pub fn parse(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked("calib_spec", bytes, SPEC_LEN, &[SPEC_TAG], SPEC_VERSION)?;
        let [width, height, frames, cols, rows] = r.u32s();
        let square = r.f32();
        let kind = r.u32();
        let (marker, dictionary) = (r.f32(), r.u32());
        let board = match kind {
            0 => SpecBoard::Chessboard,
            1 => SpecBoard::Charuco { marker, dictionary },
            _ => return Err(r.invalid("board")),
        };
        Ok(Self {
            width,
            height,
            frames,
            cols,
            rows,
            square,
            board,
        })
    }
}

/// One frame of the calibration job.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewRecord {
    /// Frame number.
    pub frame: u32,
    /// The corners, board order, when the board was found.
    pub corners: Option<camgeom::heapless::Vec<[f32; 2], CORNERS>>,
    /// What the detection cost.
    pub cost: u32,
}

/// The calibration's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibRecord {
    /// Views used.
    pub views_used: u32,
    /// Accepted LM steps.
    pub iterations: u32,
    /// What the solve cost.
    pub cost: u32,
    /// Bit 0: focal length unconstrained, 1: principal point, 2: lens.
    pub warnings: u32,
    /// `fx fy cx cy`.
    pub intrinsics: [f32; 4],
    /// `k1 k2 p1 p2 k3`.
    pub distortion: [f32; 5],
    /// RMS reprojection error (px).
    pub rms_px: f32,
    /// RMS from the closed-form start (px).
    pub initial_rms_px: f32,
    /// Standard deviations of `fx fy cx cy` and the lens coefficients.
    pub std: [f32; 9],
    /// Per added view, its RMS; NaN for a rejected view or no view.
    pub per_view_rms_px: [f32; VIEWS],
    /// Stack high-water mark (bytes; 0 on the host).
    pub stack: u32,
}

impl CalibRecord {
    /// The record of a solve's report that cost `cost`.
    pub(crate) fn of(r: &CalibrationReport<f32, VIEWS>, cost: u32) -> Self {
        let k = &r.camera.intrinsics;
        let mut warnings = 0u32;
        for w in &r.warnings {
            warnings |= match w {
                CalibrationWarning::FocalLengthUnconstrained => 1,
                CalibrationWarning::PrincipalPointUnconstrained => 2,
                CalibrationWarning::DistortionUnconstrained => 4,
            };
        }
        Self {
            views_used: r.views_used as u32,
            iterations: u32::from(r.iterations),
            cost,
            warnings,
            intrinsics: [k.fx(), k.fy(), k.cx(), k.cy()],
            distortion: r.camera.lens.coefficients(),
            rms_px: r.rms_px,
            initial_rms_px: r.initial_rms_px,
            std: r.std,
            per_view_rms_px: r.per_view_rms_px.map(|v| v.unwrap_or(f32::NAN)),
            stack: 0,
        }
    }
}

/// A decoded record.
// No heap to box the view's corners in, and a record is decoded one at a time: the size of
// the larger variant is what each takes.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Record {
    /// A frame.
    View(ViewRecord),
    /// The result.
    Result(CalibRecord),
}

impl ViewRecord {
    /// The [`RECORD_LEN`] bytes.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        Writer::fill(VIEW_TAG, VERSION, |w| {
            let n = self.corners.as_ref().map_or(0, |c| c.len());
            w.u32s([
                self.frame,
                u32::from(self.corners.is_some()),
                self.cost,
                n as u32,
            ]);
            w.f32s(self.corners.iter().flatten().flatten().copied());
        })
    }
}

impl CalibRecord {
    /// The result record's tag.
    pub(crate) const TAG: u32 = RESULT_TAG;

    /// The [`RECORD_LEN`] bytes.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        self.encode_n()
    }

    /// The record in `N` bytes (zero-padded; [`RECORD_LEN`] here,
    /// [`crate::charuco_calibration::CHARUCO_RECORD_LEN`] in the ChArUco job's report).
    pub fn encode_n<const N: usize>(&self) -> [u8; N] {
        Writer::fill(RESULT_TAG, VERSION, |w| {
            w.u32s([self.views_used, self.iterations, self.cost, self.warnings]);
            let rms = [self.rms_px, self.initial_rms_px];
            let floats = self
                .intrinsics
                .iter()
                .chain(&self.distortion)
                .chain(&rms)
                .chain(&self.std)
                .chain(&self.per_view_rms_px);
            w.f32s(floats.copied());
            w.u32(self.stack);
        })
    }
}

impl Record {
    /// Decodes one record. Errors: [`WireError`] (length, tag, version).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked(
            "calib_report",
            bytes,
            RECORD_LEN,
            &[VIEW_TAG, RESULT_TAG],
            VERSION,
        )?;
        if r.tag() == VIEW_TAG {
            let [frame, found, cost, n] = r.u32s();
            let n = (n as usize).min(CORNERS);
            let corners = (found != 0).then(|| {
                (0..n)
                    .map(|_| r.f32s::<2>())
                    .collect::<camgeom::heapless::Vec<_, CORNERS>>()
            });
            return Ok(Record::View(ViewRecord {
                frame,
                corners,
                cost,
            }));
        }
        CalibRecord::decode_fields(&mut r).map(Record::Result)
    }
}

impl CalibRecord {
    /// The fields after the tag and version (the reader's checks done).
    pub(crate) fn decode_fields(r: &mut Reader<'_>) -> Result<Self, WireError> {
        let [views_used, iterations, cost, warnings] = r.u32s();
        Ok(CalibRecord {
            views_used,
            iterations,
            cost,
            warnings,
            intrinsics: r.f32s(),
            distortion: r.f32s(),
            rms_px: r.f32(),
            initial_rms_px: r.f32(),
            std: r.f32s(),
            per_view_rms_px: r.f32s(),
            stack: r.u32(),
        })
    }
}

/// Why the calibration job stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CalibError<E> {
    /// The frame source failed.
    Source(E),
    /// The core rejected the input or found no camera (too few views, degenerate views).
    Core(Error),
}

impl<E> From<Error> for CalibError<E> {
    fn from(e: Error) -> Self {
        Self::Core(e)
    }
}

/// Calibrates from every frame of `source`: detects the board in each (`frame` is the caller's
/// `width x height` buffer, `scratch` [`scratch_len`]`(width)` words), keeps the views found
/// and solves once the source has ended. `record` receives one [`ViewRecord`] a frame; the
/// [`CalibRecord`] is returned (its `stack` left 0 for the caller). Costs come from `clock`.
#[allow(clippy::too_many_arguments)]
pub fn calibrate<Src: FrameSource>(
    spec: &CalibSpec,
    source: &mut Src,
    frame: &mut [u8],
    detector: &mut BoardDetector,
    scratch: &mut [i32],
    calibrator: &mut BoardCalibrator,
    clock: &mut impl Clock,
    record: &mut impl FnMut(&ViewRecord),
) -> Result<CalibRecord, CalibError<Src::Error>> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    if spec.board != SpecBoard::Chessboard {
        return Err(Error::InvalidParameter("board").into());
    }
    let board = BoardSize::new(spec.cols as usize, spec.rows as usize)?;
    let params = DetectParams::default();
    calibrator.clear();
    for index in 0..spec.frames {
        {
            let mut img = ImageMut::packed(&mut *frame, w, h)?;
            if !source.next_frame(&mut img).map_err(CalibError::Source)? {
                break;
            }
        }
        let view = ImageView::packed(&*frame, w, h)?;
        let t0 = clock.now();
        let found = detector.detect::<CORNERS>(&view, board, &params, scratch)?;
        let cost = u32::try_from(clock.now().saturating_sub(t0)).unwrap_or(u32::MAX);
        if let Some(b) = &found
            && calibrator.views() < VIEWS
        {
            calibrator.add_chessboard(w, h, b)?;
        }
        record(&ViewRecord {
            frame: index,
            corners: found.map(|b| b.corners.iter().map(|p| [p.x, p.y]).collect()),
            cost,
        });
    }
    let t0 = clock.now();
    let report = calibrator.solve(&CalibrationParams::default())?;
    let cost = u32::try_from(clock.now().saturating_sub(t0)).unwrap_or(u32::MAX);
    Ok(CalibRecord::of(&report, cost))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip() {
        let spec = CalibSpec {
            width: 320,
            height: 240,
            frames: 13,
            cols: 9,
            rows: 6,
            square: 0.025,
            board: SpecBoard::Chessboard,
        };
        assert_eq!(CalibSpec::parse(&spec.to_bytes()), Ok(spec));
        let charuco = CalibSpec {
            board: SpecBoard::Charuco {
                marker: 0.022,
                dictionary: 0,
            },
            ..spec
        };
        assert_eq!(CalibSpec::parse(&charuco.to_bytes()), Ok(charuco));
        let mut bad = charuco.to_bytes();
        bad[32..36].copy_from_slice(&2u32.to_le_bytes());
        assert!(CalibSpec::parse(&bad).is_err());
        let view = ViewRecord {
            frame: 3,
            corners: Some((0..54).map(|k| [k as f32, -(k as f32) * 0.5]).collect()),
            cost: 12345,
        };
        assert_eq!(Record::decode(&view.encode()), Ok(Record::View(view)));
        let none = ViewRecord {
            frame: 4,
            corners: None,
            cost: 7,
        };
        assert_eq!(Record::decode(&none.encode()), Ok(Record::View(none)));
        let res = CalibRecord {
            views_used: 13,
            iterations: 9,
            cost: 99,
            warnings: 5,
            intrinsics: [266.0, 266.5, 171.0, 117.0],
            distortion: [-0.26, -0.04, 0.001, 0.0, 0.2],
            rms_px: 0.1,
            initial_rms_px: 0.7,
            std: [0.5; 9],
            per_view_rms_px: [0.25; VIEWS],
            stack: 4096,
        };
        assert_eq!(Record::decode(&res.encode()), Ok(Record::Result(res)));
        assert!(Record::decode(&res.encode()[..10]).is_err());
    }

    #[test]
    fn a_charuco_spec_is_not_a_chessboard_run() {
        use crate::recorded::{FaultPlan, RecordedCamera, SliceFrames};
        use std::boxed::Box;
        use std::vec;
        let spec = CalibSpec {
            width: 16,
            height: 16,
            frames: 1,
            cols: 5,
            rows: 4,
            square: 0.03,
            board: SpecBoard::Charuco {
                marker: 0.02,
                dictionary: 0,
            },
        };
        let raw = vec![0u8; 16 * 16];
        let mut camera =
            RecordedCamera::new(SliceFrames::new(&raw, 16, 16), 1, 1, FaultPlan::none());
        let mut frame = vec![0u8; 16 * 16];
        let mut detector: Box<BoardDetector> = Box::default();
        let mut scratch = vec![0i32; scratch_len(16)];
        let board = BoardSize::new(4, 3).unwrap();
        let mut calibrator = Box::new(BoardCalibrator::new(board, 0.03, 16, 16).unwrap());
        let r = calibrate(
            &spec,
            &mut camera,
            &mut frame,
            &mut detector,
            &mut scratch,
            &mut calibrator,
            &mut crate::pipeline::NoClock,
            &mut |_| panic!("no frame is read"),
        );
        assert!(matches!(
            r,
            Err(CalibError::Core(Error::InvalidParameter("board")))
        ));
    }
}
