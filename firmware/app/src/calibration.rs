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
//! | 0..8 | tag, version | tag, version |
//! | 8..20 | `u32` frame, `u32` found (0/1), `u32` detection cost | `u32` views used, `u32` LM steps, `u32` solve cost |
//! | 20..24 | `u32` corners | `u32` warnings (bit 0 focal length, 1 principal point, 2 lens) |
//! | 24.. | `f32` `x y` of each corner, board order ([`CORNERS`] pairs) | `f32` `fx fy cx cy`, `k1 k2 p1 p2 k3`, RMS, initial RMS, 9 standard deviations, then [`VIEWS`] per-view RMS (NaN: rejected), `u32` stack used |
//!
//! The run description is [`CalibSpec`] (`calib.bin`): the frame size, the board, the square.

use camgeom::Error;
use camgeom::calib::{CalibrationParams, CalibrationReport, CalibrationWarning, Calibrator};
use camgeom::chessboard::{BoardSize, ChessboardDetector, DetectParams};
use camgeom::image::ImageMut;
use camgeom::image::ImageView;

use crate::pipeline::Clock;
use crate::source::FrameSource;

/// Views the board keeps at most.
pub const VIEWS: usize = 16;
/// Inner corners of a board at most (9x6 is 54).
pub const CORNERS: usize = 64;
/// Corner candidates of the detector.
pub const CANDIDATES: usize = 512;
/// Bytes of every calibration record.
pub const RECORD_LEN: usize = 24 + 8 * CORNERS;
/// Bytes of a [`CalibSpec`].
pub const SPEC_LEN: usize = 28;

const VIEW_TAG: u32 = u32::from_le_bytes(*b"CVEW");
const RESULT_TAG: u32 = u32::from_le_bytes(*b"CCAL");
const SPEC_TAG: u32 = u32::from_le_bytes(*b"CSPC");
const VERSION: u32 = 1;

/// The board's calibrator: f32, [`VIEWS`] x [`CORNERS`].
pub type BoardCalibrator = Calibrator<f32, VIEWS, CORNERS>;
/// The board's chessboard detector.
pub type BoardDetector = ChessboardDetector<CANDIDATES>;

/// `i32` words of detector scratch for frames `width` wide.
pub const fn scratch_len(width: usize) -> usize {
    camgeom::chessboard::scratch_len(width)
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
}

fn words<const M: usize>(bytes: &[u8]) -> [u32; M] {
    let mut w = [0u32; M];
    for (o, c) in w.iter_mut().zip(bytes.chunks_exact(4)) {
        let mut b = [0u8; 4];
        b.copy_from_slice(c);
        *o = u32::from_le_bytes(b);
    }
    w
}

fn put(out: &mut [u8], at: &mut usize, w: u32) {
    if let Some(c) = out.get_mut(*at..*at + 4) {
        c.copy_from_slice(&w.to_le_bytes());
    }
    *at += 4;
}

impl CalibSpec {
    /// The [`SPEC_LEN`] bytes.
    pub fn to_bytes(&self) -> [u8; SPEC_LEN] {
        let mut out = [0u8; SPEC_LEN];
        let mut at = 0;
        for w in [
            SPEC_TAG,
            self.width,
            self.height,
            self.frames,
            self.cols,
            self.rows,
            self.square.to_bits(),
        ] {
            put(&mut out, &mut at, w);
        }
        out
    }

    /// Decodes [`SPEC_LEN`] bytes. Errors: [`Error::InvalidParameter`] (`calib_spec`).
    pub fn parse(bytes: &[u8]) -> Result<Self, Error> {
        if bytes.len() != SPEC_LEN {
            return Err(Error::InvalidParameter("calib_spec"));
        }
        let [tag, width, height, frames, cols, rows, square] = words::<7>(bytes);
        if tag != SPEC_TAG {
            return Err(Error::InvalidParameter("calib_spec"));
        }
        Ok(Self {
            width,
            height,
            frames,
            cols,
            rows,
            square: f32::from_bits(square),
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
    fn of(r: &CalibrationReport<f32, VIEWS>, cost: u32) -> Self {
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
        let mut out = [0u8; RECORD_LEN];
        let mut at = 0;
        let n = self.corners.as_ref().map_or(0, |c| c.len());
        for w in [
            VIEW_TAG,
            VERSION,
            self.frame,
            u32::from(self.corners.is_some()),
            self.cost,
            n as u32,
        ] {
            put(&mut out, &mut at, w);
        }
        for [x, y] in self.corners.iter().flatten() {
            put(&mut out, &mut at, x.to_bits());
            put(&mut out, &mut at, y.to_bits());
        }
        out
    }
}

impl CalibRecord {
    /// The [`RECORD_LEN`] bytes.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        let mut out = [0u8; RECORD_LEN];
        let mut at = 0;
        for w in [
            RESULT_TAG,
            VERSION,
            self.views_used,
            self.iterations,
            self.cost,
            self.warnings,
        ] {
            put(&mut out, &mut at, w);
        }
        let rms = [self.rms_px, self.initial_rms_px];
        let floats = self
            .intrinsics
            .iter()
            .chain(&self.distortion)
            .chain(&rms)
            .chain(&self.std)
            .chain(&self.per_view_rms_px);
        for v in floats {
            put(&mut out, &mut at, v.to_bits());
        }
        put(&mut out, &mut at, self.stack);
        out
    }
}

impl Record {
    /// Decodes one record. Errors: [`Error::InvalidParameter`] (`calib_report`).
    pub fn decode(bytes: &[u8]) -> Result<Self, Error> {
        let bad = Error::InvalidParameter("calib_report");
        if bytes.len() != RECORD_LEN {
            return Err(bad);
        }
        let w = words::<{ RECORD_LEN / 4 }>(bytes);
        let f = |i: usize| f32::from_bits(w.get(i).copied().unwrap_or(0));
        if w[1] != VERSION {
            return Err(bad);
        }
        match w[0] {
            VIEW_TAG => {
                let n = (w[5] as usize).min(CORNERS);
                let corners = (w[3] != 0).then(|| {
                    (0..n)
                        .map(|k| [f(6 + 2 * k), f(7 + 2 * k)])
                        .collect::<camgeom::heapless::Vec<_, CORNERS>>()
                });
                Ok(Record::View(ViewRecord {
                    frame: w[2],
                    corners,
                    cost: w[4],
                }))
            }
            RESULT_TAG => {
                let at = |i| f(6 + i);
                Ok(Record::Result(CalibRecord {
                    views_used: w[2],
                    iterations: w[3],
                    cost: w[4],
                    warnings: w[5],
                    intrinsics: [at(0), at(1), at(2), at(3)],
                    distortion: [at(4), at(5), at(6), at(7), at(8)],
                    rms_px: at(9),
                    initial_rms_px: at(10),
                    std: core::array::from_fn(|i| at(11 + i)),
                    per_view_rms_px: core::array::from_fn(|i| at(20 + i)),
                    stack: w.get(6 + 20 + VIEWS).copied().unwrap_or(0),
                }))
            }
            _ => Err(bad),
        }
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
        };
        assert_eq!(CalibSpec::parse(&spec.to_bytes()), Ok(spec));
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
}
