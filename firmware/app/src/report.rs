//! The board's run report: fixed-layout binary records, one per frame and one at the end.
//!
//! A board writes them (the emulated board to `report.bin` over semihosting) and the host reads
//! them back with the same code: [`FrameRecord::encode`] / [`Record::decode`] are the only
//! place the layout is written down, so the two sides cannot drift apart. Human-readable logs
//! (defmt) are separate and never parsed.
//!
//! Every record is [`RECORD_LEN`] bytes, little-endian, starting with a tag word and the layout
//! [`VERSION`] (the frame of [`crate::wire`]):
//!
//! | bytes | frame record ([`FRAME_TAG`] `"CFRM"`) | summary record ([`SUMMARY_TAG`] `"CSUM"`) |
//! |---|---|---|
//! | 0..4 | tag | tag |
//! | 4..8 | version | version |
//! | 8..12 | `u32` frame index | `u32` frames run |
//! | 12..16 | `u8` state (0 uninitialised, 1 tracking, 2 lost), `u8` flags (bit 0: acquired, 1: pose, 2: outline, 3: partial), `u8` error ([`ErrorCode`], 0: none), `u8` 0 | `u32` frames tracking |
//! | 16..24 | `u16` tracked, inliers, added, features | `u32` pipeline RAM, `u32` stack used |
//! | 24..28 | `u32` track checksum | `u32` stack size |
//! | 28..56 | best pose: `f32` `t` (3), rotation vector (3), RMS px | `u32` overlays saved, then zeros |
//! | 56..84 | alternative pose, as the best | zeros |
//! | 84..116 | outline: `f32` `x y` of 4 corners | zeros |
//! | 116.. | `u32` stage costs in the order of [`STAGES`](crate::costs::STAGES), the total last | zeros |
//!
//! Absent poses and outlines are zeros with their flag clear. The cost columns follow the
//! stages ([`Cost::COLUMNS`]), so a new stage lengthens every record: bump [`VERSION`] with
//! it.

use camgeom::Error;
use camgeom::pose::{PlanarPose, PoseEstimate};
use camgeom::target::TargetState;

use crate::costs::{Cost, StageCosts};
use crate::pipeline::{AppError, FrameReport};
use crate::wire::{Reader, WireError, Writer, tag};

/// `"CFRM"`: a frame record.
pub const FRAME_TAG: u32 = tag(b"CFRM");
/// `"CSUM"`: the summary record that ends a run.
pub const SUMMARY_TAG: u32 = tag(b"CSUM");
/// Layout version.
pub const VERSION: u32 = 1;
/// Bytes of every record: the fields up to the costs, then one `u32` a cost column.
pub const RECORD_LEN: usize = 116 + 4 * Cost::COLUMNS;

/// Why a frame failed, as one byte: the pipeline's [`AppError`] kind, or the core's
/// [`Error`] kind (its index in [`Error::ALL`], plus [`ErrorCode::CORE`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorCode(pub u8);

impl ErrorCode {
    /// Codes from this one on are core errors.
    pub const CORE: u8 = 16;
    /// The camera delivered a frame of the wrong size.
    pub const WRONG_SIZE: Self = Self(5);
    /// Reading the frame failed.
    pub const READ_FAILED: Self = Self(6);

    /// The code of a pipeline error.
    pub fn of<E>(e: &AppError<E>) -> Self {
        Self(match e {
            AppError::Source(_) => 1,
            AppError::Geometry => 3,
            AppError::Core(c) => Self::of_core(c).0,
        })
    }

    /// The code of a core error.
    pub fn of_core(e: &Error) -> Self {
        let i = Error::ALL
            .iter()
            .position(|k| k.name() == e.name())
            .unwrap_or(Error::ALL.len());
        Self(Self::CORE.saturating_add(i as u8))
    }

    /// The error's snake-case name ([`AppError::name`]), `unknown` for a code no build writes.
    pub fn name(self) -> &'static str {
        match self.0 {
            1 => "source",
            // 2 and 4 were `no_frame` and `not_started`, gone with the separate start step.
            3 => "geometry",
            5 => "wrong_size",
            6 => "read_failed",
            c => Error::ALL
                .get(usize::from(c.wrapping_sub(Self::CORE)))
                .map_or("unknown", Error::name),
        }
    }
}

/// A pose as recorded: translation, rotation vector (axis · angle, radians), RMS reprojection
/// error (pixels).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseRecord {
    /// `t` of `X_cam = R X + t`.
    pub t: [f32; 3],
    /// Rodrigues vector of `R`.
    pub r: [f32; 3],
    /// RMS reprojection error in pixels.
    pub rms_px: f32,
}

impl PoseRecord {
    fn of(p: &PoseEstimate<f32>) -> Self {
        let t = p.pose.translation();
        let r = p.pose.rotation_vector();
        Self {
            t: [t.x, t.y, t.z],
            r: [r.x, r.y, r.z],
            rms_px: p.rms_px,
        }
    }

    /// The seven numbers in record order.
    pub fn to_array(&self) -> [f32; 7] {
        let ([a, b, c], [d, e, f]) = (self.t, self.r);
        [a, b, c, d, e, f, self.rms_px]
    }

    fn from_array(v: [f32; 7]) -> Self {
        let [a, b, c, d, e, f, g] = v;
        Self {
            t: [a, b, c],
            r: [d, e, f],
            rms_px: g,
        }
    }
}

/// One frame as a board reports it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrameRecord {
    /// Frame number in the sequence.
    pub index: u32,
    /// The tracker's state after the frame.
    pub state: TargetState,
    /// The target was acquired on this frame.
    pub acquired: bool,
    /// The pose is from a partly seen target (`TargetFrame::partial`).
    pub partial: bool,
    /// The frame failed with this error (the state is then the last one known).
    pub error: Option<ErrorCode>,
    /// Tracks that survived the flow.
    pub tracked: u16,
    /// Homography inliers.
    pub inliers: u16,
    /// Features added.
    pub added: u16,
    /// Features alive after the frame.
    pub features: u16,
    /// Checksum of the Q16.16 track positions.
    pub checksum: u32,
    /// The best pose and the alternative, when tracking.
    pub pose: Option<(PoseRecord, PoseRecord)>,
    /// The target's outline, when tracking.
    pub outline: Option<[[f32; 2]; 4]>,
    /// What the frame cost.
    pub costs: StageCosts,
}

fn count(n: usize) -> u16 {
    u16::try_from(n).unwrap_or(u16::MAX)
}

impl FrameRecord {
    /// The record of a frame's report.
    pub fn of(r: &FrameReport) -> Self {
        let f = &r.frame;
        Self {
            index: r.index,
            state: f.state,
            acquired: f.acquired,
            partial: f.partial,
            error: None,
            tracked: count(f.tracked),
            inliers: count(f.inliers),
            added: count(f.added),
            features: count(f.features),
            checksum: r.checksum,
            pose: f.pose.map(|p: PlanarPose<f32>| {
                (PoseRecord::of(&p.best), PoseRecord::of(&p.alternative))
            }),
            outline: f.outline.map(|o| o.map(|p| [p.x, p.y])),
            costs: r.costs,
        }
    }

    /// The record of frame `index` that failed with `error` while the tracker was in `state`.
    pub fn failed(index: u32, state: TargetState, error: ErrorCode) -> Self {
        Self {
            index,
            state,
            error: Some(error),
            ..Self::default()
        }
    }

    /// The [`RECORD_LEN`] bytes of the record.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        Writer::fill(FRAME_TAG, VERSION, |w| {
            w.u32(self.index);
            let state = match self.state {
                TargetState::Uninitialised => 0,
                TargetState::Tracking => 1,
                TargetState::Lost => 2,
            };
            let flags = u8::from(self.acquired)
                | (u8::from(self.pose.is_some()) << 1)
                | (u8::from(self.outline.is_some()) << 2)
                | (u8::from(self.partial) << 3);
            w.bytes(&[state, flags, self.error.map_or(0, |e| e.0), 0]);
            for c in [self.tracked, self.inliers, self.added, self.features] {
                w.u16(c);
            }
            w.u32(self.checksum);
            let (best, alt) = self.pose.unwrap_or_default();
            w.f32s(best.to_array().into_iter().chain(alt.to_array()));
            w.f32s(self.outline.unwrap_or_default().into_iter().flatten());
            w.u32s(self.costs.to_array());
        })
    }
}

/// The record that ends a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SummaryRecord {
    /// Frames run (the start frame included).
    pub frames: u32,
    /// Frames that ended tracking.
    pub tracking: u32,
    /// Bytes of the pipeline's static ([`crate::Pipeline::BYTES`]).
    pub pipeline_ram: u32,
    /// Stack high-water mark (bytes).
    pub stack_used: u32,
    /// Stack size (bytes).
    pub stack_size: u32,
    /// Overlay frames written back.
    pub overlays: u32,
}

impl SummaryRecord {
    /// The [`RECORD_LEN`] bytes of the record.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        Writer::fill(SUMMARY_TAG, VERSION, |w| {
            w.u32s([
                self.frames,
                self.tracking,
                self.pipeline_ram,
                self.stack_used,
                self.stack_size,
                self.overlays,
            ]);
        })
    }
}

/// A decoded record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Record {
    /// A frame.
    Frame(FrameRecord),
    /// The end of the run.
    Summary(SummaryRecord),
}

impl Record {
    /// Decodes one record of [`RECORD_LEN`] bytes. Errors: [`WireError`] for bytes that are
    /// not a record of this layout (length, tag, version, or a `state` no record has).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked(
            "report",
            bytes,
            RECORD_LEN,
            &[FRAME_TAG, SUMMARY_TAG],
            VERSION,
        )?;
        if r.tag() == SUMMARY_TAG {
            let [
                frames,
                tracking,
                pipeline_ram,
                stack_used,
                stack_size,
                overlays,
            ] = r.u32s();
            return Ok(Record::Summary(SummaryRecord {
                frames,
                tracking,
                pipeline_ram,
                stack_used,
                stack_size,
                overlays,
            }));
        }
        let index = r.u32();
        let [state, flags, error, _] = r.array::<4>();
        let state = match state {
            0 => TargetState::Uninitialised,
            1 => TargetState::Tracking,
            2 => TargetState::Lost,
            _ => return Err(r.invalid("state")),
        };
        let [tracked, inliers, added, features] = [(); 4].map(|_| r.u16());
        let checksum = r.u32();
        let best = PoseRecord::from_array(r.f32s());
        let alt = PoseRecord::from_array(r.f32s());
        let outline = [(); 4].map(|_| r.f32s());
        let costs = StageCosts::from_array(r.u32s());
        Ok(Record::Frame(FrameRecord {
            index,
            state,
            acquired: flags & 1 != 0,
            partial: flags & 8 != 0,
            error: (error != 0).then_some(ErrorCode(error)),
            tracked,
            inliers,
            added,
            features,
            checksum,
            pose: (flags & 2 != 0).then_some((best, alt)),
            outline: (flags & 4 != 0).then_some(outline),
            costs,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_and_summary_records_round_trip() {
        let rec = FrameRecord {
            index: 41,
            state: TargetState::Lost,
            acquired: true,
            partial: true,
            error: Some(ErrorCode::of_core(&Error::BufferTooSmall("scratch"))),
            tracked: 30,
            inliers: 28,
            added: 3,
            features: 31,
            checksum: 0xdead_beef,
            pose: Some((
                PoseRecord {
                    t: [0.1, -0.2, 0.9],
                    r: [0.01, 0.02, -3.1],
                    rms_px: 0.4,
                },
                PoseRecord {
                    t: [1.0, 2.0, 3.0],
                    r: [4.0, 5.0, 6.0],
                    rms_px: 7.0,
                },
            )),
            outline: Some([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, f32::MAX]]),
            costs: StageCosts::from_array([1, 2, 3, 4, 5, 6, 7, 8, 9]),
        };
        let bytes = rec.encode();
        assert_eq!(bytes.len(), RECORD_LEN);
        assert_eq!(Record::decode(&bytes), Ok(Record::Frame(rec)));
        let empty = FrameRecord::default();
        assert_eq!(Record::decode(&empty.encode()), Ok(Record::Frame(empty)));
        let sum = SummaryRecord {
            frames: 150,
            tracking: 149,
            pipeline_ram: 226_716,
            stack_used: 10_068,
            stack_size: 65_536,
            overlays: 11,
        };
        assert_eq!(Record::decode(&sum.encode()), Ok(Record::Summary(sum)));
    }

    #[test]
    fn error_codes_name_every_error() {
        assert_eq!(ErrorCode::of(&AppError::<()>::Source(())).name(), "source");
        assert_eq!(ErrorCode::of(&AppError::<()>::Geometry).name(), "geometry");
        for e in Error::ALL {
            assert_eq!(ErrorCode::of_core(&e).name(), e.name());
            assert_eq!(ErrorCode::of(&AppError::<()>::Core(e)).name(), e.name());
        }
        assert_eq!(ErrorCode::WRONG_SIZE.name(), "wrong_size");
        assert_eq!(ErrorCode::READ_FAILED.name(), "read_failed");
        assert_eq!(ErrorCode(200).name(), "unknown");
    }

    #[test]
    fn bad_bytes_are_errors() {
        let good = SummaryRecord::default().encode();
        assert!(matches!(
            Record::decode(&good[..100]),
            Err(WireError::Length { got: 100, .. })
        ));
        let mut bad = good;
        bad[0] ^= 1;
        assert!(matches!(Record::decode(&bad), Err(WireError::Tag { .. })));
        let mut bad = good;
        bad[4] = 9;
        assert!(matches!(
            Record::decode(&bad),
            Err(WireError::Version { got: 9, .. })
        ));
        let mut frame = FrameRecord::default().encode();
        frame[12] = 7;
        assert_eq!(
            Record::decode(&frame),
            Err(WireError::Field {
                record: "report",
                field: "state"
            })
        );
    }
}
