//! The board calibrates its camera from ChArUco views, the board seen whole or in part.
//!
//! Each frame goes through the ArUco detector ([`camgeom::apriltag::Detector`] with the
//! board's dictionary, in the caller's [`camgeom::apriltag::WorkspaceView`]), then
//! [`camgeom::charuco::interpolate_corners`] (each corner predicted from its two markers and
//! refined as a saddle point); a view of at least [`MIN_CORNERS`] identified corners is kept in
//! fixed RAM ([`CharucoCalibrator`], [`camgeom::calib::Calibrator::add_points`]), and once every
//! frame is in, [`camgeom::calib::Calibrator::solve`] gives the camera. [`calibrate_charuco`] is
//! the whole job, the same on the board and in its host replay, described by a
//! [`crate::calibration::CalibSpec`] whose board is [`SpecBoard::Charuco`]. It reports one
//! [`CharucoViewRecord`] a frame and the [`CalibRecord`] at the end, both [`CHARUCO_RECORD_LEN`]
//! bytes ([`CharucoRecord`]):
//!
//! | bytes | view record (`"CHVW"`) | result record (`"CCAL"`) |
//! |---|---|---|
//! | 0..8 | tag, version ([`crate::wire`]) | tag, version |
//! | 8..24 | `u32` frame, `u32` markers found, `u32` detection cost, `u32` corners | as [`crate::calibration`]'s, zero-padded |
//! | 24.. | each corner: `u32` id, `f32` `x y` ([`CHARUCO_CORNERS`] of them) | |
//!
//! [`SpecBoard::Charuco`]: crate::calibration::SpecBoard::Charuco

use camgeom::Error;
use camgeom::apriltag::{Detection, Detector, Family, Label, WorkspaceView, families};
use camgeom::calib::{CalibrationParams, Calibrator};
use camgeom::charuco::{CharucoBoard, CharucoCorner, CharucoParams, interpolate_corners};
use camgeom::image::{ImageMut, ImageView};
use camgeom::nalgebra::Point2;

use crate::calibration::{CalibError, CalibRecord, CalibSpec, SpecBoard, VIEWS};
use crate::pipeline::Clock;
use crate::source::FrameSource;
use crate::wire::{Reader, WireError, Writer, tag};

/// ChArUco corners of a board at most (OpenCV's 11x8 board has 70).
pub const CHARUCO_CORNERS: usize = 80;
/// Markers kept from a frame's detection (a board of [`CHARUCO_CORNERS`] corners has fewer).
pub const MARKERS: usize = 64;
/// Identified corners a view needs to be kept (a plane's homography needs 4; OpenCV's sample
/// asks for more than 3; `camgeom calibrate --board charuco:` keeps views of 6 or more).
pub const MIN_CORNERS: usize = 6;
/// Bytes of every record of the ChArUco job.
pub const CHARUCO_RECORD_LEN: usize = 24 + 12 * CHARUCO_CORNERS;

const VIEW_TAG: u32 = tag(b"CHVW");
const VERSION: u32 = 1;

/// The board's ChArUco calibrator: f32, [`VIEWS`] x [`CHARUCO_CORNERS`].
pub type CharucoCalibrator = Calibrator<f32, VIEWS, CHARUCO_CORNERS>;

/// The dictionaries the board carries, by OpenCV's `PredefinedDictionaryType` value: the
/// DICT_4X4 group (0..=3: 50, 100, 250, 1000 markers, one table). `None` for any other.
#[doc(alias = "getPredefinedDictionary")]
pub fn dictionary(id: u32) -> Option<&'static Family> {
    match id {
        0 => Some(&families::DICT_4X4_50),
        1 => Some(&families::DICT_4X4_100),
        2 => Some(&families::DICT_4X4_250),
        3 => Some(&families::DICT_4X4_1000),
        _ => None,
    }
}

/// The ChArUco board of `spec`.
///
/// Errors: `InvalidParameter("board")` when `spec` is a chessboard's,
/// `InvalidParameter("dictionary")` for a dictionary [`dictionary`] does not carry, those of
/// [`CharucoBoard::new`], `BufferTooSmall("corners")` for more than [`CHARUCO_CORNERS`]
/// corners.
pub fn board_of(spec: &CalibSpec) -> Result<CharucoBoard, Error> {
    let SpecBoard::Charuco {
        marker,
        dictionary: dict,
    } = spec.board
    else {
        return Err(Error::InvalidParameter("board"));
    };
    let family = dictionary(dict).ok_or(Error::InvalidParameter("dictionary"))?;
    let board = CharucoBoard::new(
        spec.cols as usize,
        spec.rows as usize,
        spec.square,
        marker,
        family,
    )?;
    if board.corners() > CHARUCO_CORNERS {
        return Err(Error::BufferTooSmall("corners"));
    }
    Ok(board)
}

/// A calibrator for `board`'s corners (board frame, OpenCV's ids) in `width x height` frames.
///
/// Errors: `BufferTooSmall("corners")` for more than [`CHARUCO_CORNERS`] corners, those of
/// [`Calibrator::with_points`].
pub fn charuco_calibrator(
    board: &CharucoBoard,
    width: usize,
    height: usize,
) -> Result<CharucoCalibrator, Error> {
    let mut points = [Point2::origin(); CHARUCO_CORNERS];
    let n = board.corners();
    let used = points
        .get_mut(..n)
        .ok_or(Error::BufferTooSmall("corners"))?;
    for (k, p) in used.iter_mut().enumerate() {
        *p = board.corner(k).ok_or(Error::InvalidParameter("board"))?;
    }
    CharucoCalibrator::with_points(used, board.square(), width, height)
}

/// One frame of the ChArUco job.
#[derive(Debug, Clone, PartialEq)]
pub struct CharucoViewRecord {
    /// Frame number.
    pub frame: u32,
    /// Markers of the board's dictionary found (at most [`MARKERS`]).
    pub markers: u32,
    /// The identified corners, id order.
    pub corners: camgeom::heapless::Vec<CharucoCorner, CHARUCO_CORNERS>,
    /// What the detection (markers and corners) cost.
    pub cost: u32,
}

impl CharucoViewRecord {
    /// The [`CHARUCO_RECORD_LEN`] bytes.
    pub fn encode(&self) -> [u8; CHARUCO_RECORD_LEN] {
        Writer::fill(VIEW_TAG, VERSION, |w| {
            w.u32s([
                self.frame,
                self.markers,
                self.cost,
                self.corners.len() as u32,
            ]);
            for c in &self.corners {
                w.u32(u32::from(c.id));
                w.f32s([c.point.x, c.point.y]);
            }
        })
    }
}

/// A decoded record of the ChArUco job.
// No heap to box the view's corners in, and a record is decoded one at a time.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum CharucoRecord {
    /// A frame.
    View(CharucoViewRecord),
    /// The result.
    Result(CalibRecord),
}

impl CharucoRecord {
    /// Decodes one record. Errors: [`WireError`] (length, tag, version, a corner count over
    /// [`CHARUCO_CORNERS`] or an id over `u16`).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let tags = [VIEW_TAG, CalibRecord::TAG];
        let mut r =
            Reader::new_checked("charuco_report", bytes, CHARUCO_RECORD_LEN, &tags, VERSION)?;
        if r.tag() != VIEW_TAG {
            return CalibRecord::decode_fields(&mut r).map(CharucoRecord::Result);
        }
        let [frame, markers, cost, n] = r.u32s();
        if n as usize > CHARUCO_CORNERS {
            return Err(r.invalid("corners"));
        }
        let mut corners = camgeom::heapless::Vec::new();
        for _ in 0..n {
            let id = u16::try_from(r.u32()).map_err(|_| r.invalid("id"))?;
            let [x, y] = r.f32s();
            let _ = corners.push(CharucoCorner {
                id,
                point: Point2::new(x, y),
            });
        }
        Ok(CharucoRecord::View(CharucoViewRecord {
            frame,
            markers,
            corners,
            cost,
        }))
    }
}

/// Where the ChArUco job detects: the marker detector of the board's dictionary and its
/// workspace, and the corners' options.
pub struct CharucoDetection<'a, 'w, L: Label> {
    /// The board.
    pub board: &'a CharucoBoard,
    /// A detector of the board's dictionary.
    pub detector: &'a Detector,
    /// The detector's workspace, for frames of the spec's size.
    pub workspace: &'a mut WorkspaceView<'w, L>,
    /// The corners' interpolation and refinement.
    pub params: &'a CharucoParams,
}

impl<L: Label> CharucoDetection<'_, '_, L> {
    /// The board's corners in `image` (into `out`, id order) and the count of the board's
    /// markers found.
    ///
    /// Errors: those of [`Detector::detect`] and [`interpolate_corners`].
    pub fn detect(
        &mut self,
        image: &ImageView<'_, u8>,
        out: &mut [CharucoCorner],
    ) -> Result<(usize, usize), Error> {
        let dict = self.board.dictionary();
        let markers: camgeom::heapless::Vec<Detection, MARKERS> =
            self.detector.detect(image, self.workspace)?;
        let n = interpolate_corners(self.board, image, &markers, self.params, out)?;
        let on_board = markers
            .iter()
            .filter(|m| m.family.name() == dict.name() && usize::from(m.id) < self.board.markers())
            .count();
        Ok((n, on_board))
    }
}

/// Calibrates from every frame of `source` (`frame` the caller's `width x height` buffer):
/// detects the board's corners in each ([`CharucoDetection::detect`]), keeps the views of at
/// least [`MIN_CORNERS`] corners (at most [`VIEWS`]) and solves once the source has ended.
/// `calibrator` is [`charuco_calibrator`]'s for the board (its views are cleared first).
/// `record` receives one [`CharucoViewRecord`] a frame; the [`CalibRecord`] is returned (its
/// `stack` left 0 for the caller). Costs come from `clock`.
pub fn calibrate_charuco<Src: FrameSource, L: Label>(
    spec: &CalibSpec,
    source: &mut Src,
    frame: &mut [u8],
    detection: &mut CharucoDetection<'_, '_, L>,
    calibrator: &mut CharucoCalibrator,
    clock: &mut impl Clock,
    record: &mut impl FnMut(&CharucoViewRecord),
) -> Result<CalibRecord, CalibError<Src::Error>> {
    let (w, h) = (spec.width as usize, spec.height as usize);
    calibrator.clear();
    let mut corners = [CharucoCorner::default(); CHARUCO_CORNERS];
    for index in 0..spec.frames {
        {
            let mut img = ImageMut::packed(&mut *frame, w, h)?;
            if !source.next_frame(&mut img).map_err(CalibError::Source)? {
                break;
            }
        }
        let view = ImageView::packed(&*frame, w, h)?;
        let t0 = clock.now();
        let (n, markers) = detection.detect(&view, &mut corners)?;
        let cost = u32::try_from(clock.now().saturating_sub(t0)).unwrap_or(u32::MAX);
        let found = corners.get(..n).unwrap_or_default();
        if n >= MIN_CORNERS && calibrator.views() < VIEWS {
            let mut ids = [0usize; CHARUCO_CORNERS];
            let mut px = [Point2::origin(); CHARUCO_CORNERS];
            for ((c, i), p) in found.iter().zip(ids.iter_mut()).zip(px.iter_mut()) {
                *i = usize::from(c.id);
                *p = c.point;
            }
            calibrator.add_points(
                w,
                h,
                ids.get(..n).unwrap_or_default(),
                px.get(..n).unwrap_or_default(),
            )?;
        }
        record(&CharucoViewRecord {
            frame: index,
            markers: markers as u32,
            corners: found.iter().copied().collect(),
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

    fn spec(dictionary: u32) -> CalibSpec {
        CalibSpec {
            width: 320,
            height: 240,
            frames: 10,
            cols: 11,
            rows: 8,
            square: 0.03,
            board: SpecBoard::Charuco {
                marker: 0.022,
                dictionary,
            },
        }
    }

    #[test]
    fn records_round_trip() {
        let view = CharucoViewRecord {
            frame: 2,
            markers: 17,
            corners: (0..70u16)
                .map(|k| CharucoCorner {
                    id: k,
                    point: Point2::new(f32::from(k), -f32::from(k) * 0.5),
                })
                .collect(),
            cost: 4242,
        };
        assert_eq!(
            CharucoRecord::decode(&view.encode()),
            Ok(CharucoRecord::View(view))
        );
        let res = CalibRecord {
            views_used: 10,
            iterations: 7,
            cost: 99,
            warnings: 0,
            intrinsics: [260.0, 258.0, 161.0, 118.75],
            distortion: [-0.3, 0.1, 0.001, -0.0008, -0.015],
            rms_px: 0.05,
            initial_rms_px: 0.6,
            std: [0.1; 9],
            per_view_rms_px: [0.04; VIEWS],
            stack: 0,
        };
        assert_eq!(
            CharucoRecord::decode(&res.encode_n::<CHARUCO_RECORD_LEN>()),
            Ok(CharucoRecord::Result(res))
        );
        // A count over the capacity is refused, not truncated.
        let mut bad = CharucoViewRecord {
            frame: 0,
            markers: 0,
            corners: camgeom::heapless::Vec::new(),
            cost: 0,
        }
        .encode();
        bad[20..24].copy_from_slice(&(CHARUCO_CORNERS as u32 + 1).to_le_bytes());
        assert!(CharucoRecord::decode(&bad).is_err());
        assert!(CharucoRecord::decode(&bad[..100]).is_err());
    }

    #[test]
    fn the_board_of_a_spec() {
        let b = board_of(&spec(0)).unwrap();
        assert_eq!((b.corners(), b.markers()), (70, 44));
        assert_eq!(
            board_of(&spec(4)),
            Err(Error::InvalidParameter("dictionary"))
        );
        let chess = CalibSpec {
            board: SpecBoard::Chessboard,
            ..spec(0)
        };
        assert_eq!(board_of(&chess), Err(Error::InvalidParameter("board")));
        // 12 x 9 squares: 88 corners, over the capacity.
        let big = CalibSpec {
            cols: 12,
            rows: 9,
            board: SpecBoard::Charuco {
                marker: 0.022,
                dictionary: 1,
            },
            ..spec(0)
        };
        assert_eq!(board_of(&big), Err(Error::BufferTooSmall("corners")));
        let cal = charuco_calibrator(&b, 320, 240).unwrap();
        assert_eq!(cal.views(), 0);
    }
}
