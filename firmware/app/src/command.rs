//! Commands from the host to the board, and the board's answer to each.
//!
//! A command travels as a [`crate::link`] frame on the same link as the records, the other
//! way: `camgeom monitor --set tag-size=0.08 --mode track-tag --save` builds them. The board
//! checks each against what it can do ([`Command::decode`] rejects a value no board takes),
//! applies it to its [`crate::settings::Settings`], and answers with an [`Ack`] record on the
//! record stream.
//!
//! # `"CCMD"`, version 1, [`COMMAND_LEN`] bytes
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | tag `"CCMD"`, version (see [`crate::wire`]) |
//! | 8..12 | `u32` kind: 1 mode, 2 tag, 3 camera, 4 save, 5 chessboard |
//! | 12..48 | the kind's fields, zeros after them |
//!
//! | kind | fields |
//! |---|---|
//! | mode | `u32` [`Mode`] |
//! | tag | `u32` family (index in [`crate::options::TAG_FAMILIES`]), `u32` id, `f32` side (metres) |
//! | camera | `f32` × 4 `fx fy cx cy` (pixels), `f32` × 5 OpenCV `k1 k2 p1 p2 k3` |
//! | save | none |
//! | chessboard | `u32` inner corners along a row, `u32` along a column, `f32` square side (metres), `u32` views to calibrate from (see [`crate::calibrate_mode`]) |
//!
//! # `"CACK"`, version 1, [`ACK_LEN`] bytes
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | tag `"CACK"`, version |
//! | 8..12 | `u32` the command frame's sequence number |
//! | 12..16 | `u32` the command's kind (0 when it did not decode) |
//! | 16..20 | `u32` [`AckStatus`] |

use camgeom::camera::{Distortion, Intrinsics};

use crate::calibration::{CORNERS, VIEWS};
use crate::options::TAG_FAMILIES;
use crate::wire::{Reader, WireError, Writer, tag};

/// The command record's tag.
pub const COMMAND_TAG: u32 = tag(b"CCMD");
/// The answer's tag.
pub const ACK_TAG: u32 = tag(b"CACK");
/// Layout version of both.
pub const VERSION: u32 = 1;
/// Bytes of a command record.
pub const COMMAND_LEN: usize = 48;
/// Bytes of an answer.
pub const ACK_LEN: usize = 20;

/// What the board does with its frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// Find the configured AprilTag and track it.
    TrackTag,
    /// Track the target from given corners (the middle of the view on a camera board).
    TrackCorners,
    /// Calibrate the camera from chessboard views.
    Calibrate,
    /// Track the tag as [`Mode::TrackTag`] does, and send each frame's pixels to the host
    /// ([`crate::frame_chunk`]) before its record.
    StreamFrames,
}

impl Mode {
    /// Every mode, by wire value (its index).
    pub const ALL: [Mode; 4] = [
        Mode::TrackTag,
        Mode::TrackCorners,
        Mode::Calibrate,
        Mode::StreamFrames,
    ];

    /// The wire value.
    pub fn to_u32(self) -> u32 {
        match self {
            Mode::TrackTag => 0,
            Mode::TrackCorners => 1,
            Mode::Calibrate => 2,
            Mode::StreamFrames => 3,
        }
    }

    /// The mode of a wire value.
    pub fn from_u32(v: u32) -> Option<Self> {
        Self::ALL.get(usize::try_from(v).ok()?).copied()
    }

    /// The name `camgeom monitor --mode` takes.
    pub fn name(self) -> &'static str {
        match self {
            Mode::TrackTag => "track-tag",
            Mode::TrackCorners => "track-corners",
            Mode::Calibrate => "calibrate",
            Mode::StreamFrames => "stream-frames",
        }
    }
}

/// One command, its values checked.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Switch to this mode.
    SetMode(Mode),
    /// Track this tag.
    SetTag {
        /// Index in [`TAG_FAMILIES`].
        family: u8,
        /// The tag's id.
        id: u16,
        /// The side of its black square, metres.
        size: f32,
    },
    /// The camera's intrinsics `fx fy cx cy` and OpenCV distortion `k1 k2 p1 p2 k3`.
    SetCamera {
        /// `fx, fy, cx, cy`, pixels.
        intrinsics: [f32; 4],
        /// `k1, k2, p1, p2, k3`.
        distortion: [f32; 5],
    },
    /// Store the settings in flash, where the board loads them at boot.
    Save,
    /// The chessboard calibrate mode looks for ([`Mode::Calibrate`]).
    SetChessboard(ChessboardSettings),
}

/// The chessboard of [`Mode::Calibrate`] and how many views it takes: checked by
/// [`ChessboardSettings::check`] (every decoded command and stored setting is).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChessboardSettings {
    /// Inner corners along a row.
    pub cols: u8,
    /// Inner corners along a column.
    pub rows: u8,
    /// Side of a square, metres (the calibrated camera does not depend on it; the views'
    /// poses are in its unit).
    pub square: f32,
    /// Views kept before the calibration is solved.
    pub views: u8,
}

impl ChessboardSettings {
    /// OpenCV's sample board: 9x6 inner corners, 25 mm squares; 10 views (Zhang's method
    /// needs 3; more views average the corner noise down, and 10 leave room below
    /// [`VIEWS`]).
    pub const DEFAULT: Self = Self {
        cols: 9,
        rows: 6,
        square: 0.025,
        views: 10,
    };

    /// Whether a board can calibrate with it: 3 to 64 corners each way, at most [`CORNERS`]
    /// in all ([`camgeom::chessboard::BoardSize::new`]), a finite positive square, 3 to
    /// [`VIEWS`] views. Errors: the name of the first field that fails.
    pub fn check(&self) -> Result<(), &'static str> {
        let (c, r) = (usize::from(self.cols), usize::from(self.rows));
        if camgeom::chessboard::BoardSize::new(c, r).is_err() || c * r > CORNERS {
            return Err("board");
        }
        if !(self.square.is_finite() && self.square > 0.0) {
            return Err("square");
        }
        if !(3..=VIEWS).contains(&usize::from(self.views)) {
            return Err("views");
        }
        Ok(())
    }
}

impl Command {
    /// The wire kind.
    pub fn kind(&self) -> u32 {
        match self {
            Command::SetMode(_) => 1,
            Command::SetTag { .. } => 2,
            Command::SetCamera { .. } => 3,
            Command::Save => 4,
            Command::SetChessboard(_) => 5,
        }
    }

    /// The name of a wire kind ([`Command::kind`]; `"unknown"` for another, e.g. the 0 of
    /// an answer to a command that did not decode).
    pub fn kind_name(kind: u32) -> &'static str {
        match kind {
            1 => "mode",
            2 => "tag",
            3 => "camera",
            4 => "save",
            5 => "chessboard",
            _ => "unknown",
        }
    }

    /// The [`COMMAND_LEN`] bytes.
    pub fn encode(&self) -> [u8; COMMAND_LEN] {
        Writer::fill(COMMAND_TAG, VERSION, |w| {
            w.u32(self.kind());
            match *self {
                Command::SetMode(m) => w.u32(m.to_u32()),
                Command::SetTag { family, id, size } => {
                    w.u32s([u32::from(family), u32::from(id)]);
                    w.f32(size);
                }
                Command::SetCamera {
                    intrinsics,
                    distortion,
                } => {
                    w.f32s(intrinsics);
                    w.f32s(distortion);
                }
                Command::Save => {}
                Command::SetChessboard(b) => {
                    w.u32s([u32::from(b.cols), u32::from(b.rows)]);
                    w.f32(b.square);
                    w.u32(u32::from(b.views));
                }
            }
        })
    }

    /// Decodes and checks a command. Errors: [`WireError`] for the length, tag or version,
    /// and `Field` for a kind or a value no board takes (`kind`, `mode`, `family`, `id`,
    /// `size`: finite and positive, `camera`: as [`Intrinsics::new`] and
    /// [`Distortion::from_opencv`] check them; `board`, `square`, `views`: as
    /// [`ChessboardSettings::check`]).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked("command", bytes, COMMAND_LEN, &[COMMAND_TAG], VERSION)?;
        match r.u32() {
            1 => Mode::from_u32(r.u32())
                .map(Command::SetMode)
                .ok_or(r.invalid("mode")),
            2 => {
                let [family, id] = r.u32s();
                let size = r.f32();
                let family = u8::try_from(family)
                    .ok()
                    .filter(|f| usize::from(*f) < TAG_FAMILIES.len())
                    .ok_or(r.invalid("family"))?;
                let id = u16::try_from(id).map_err(|_| r.invalid("id"))?;
                if !(size.is_finite() && size > 0.0) {
                    return Err(r.invalid("size"));
                }
                Ok(Command::SetTag { family, id, size })
            }
            3 => {
                let intrinsics = r.f32s();
                let distortion = r.f32s();
                let [fx, fy, cx, cy] = intrinsics;
                if Intrinsics::new(fx, fy, cx, cy).is_err()
                    || Distortion::from_opencv(distortion).is_err()
                {
                    return Err(r.invalid("camera"));
                }
                Ok(Command::SetCamera {
                    intrinsics,
                    distortion,
                })
            }
            4 => Ok(Command::Save),
            5 => {
                let [cols, rows] = r.u32s();
                let square = r.f32();
                let views = r.u32();
                let byte = |v: u32| u8::try_from(v).unwrap_or(u8::MAX);
                let b = ChessboardSettings {
                    cols: byte(cols),
                    rows: byte(rows),
                    square,
                    views: byte(views),
                };
                b.check().map_err(|f| r.invalid(f))?;
                Ok(Command::SetChessboard(b))
            }
            _ => Err(r.invalid("kind")),
        }
    }
}

/// How the board took a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AckStatus {
    /// Applied (for [`Command::Save`]: stored and read back).
    Done,
    /// Not a command this board reads (damaged, another version, a value out of range).
    Invalid,
    /// A valid command this board cannot carry out (a mode it does not have).
    Unsupported,
    /// The flash did not take the settings.
    FlashFailed,
}

impl AckStatus {
    const ALL: [AckStatus; 4] = [
        AckStatus::Done,
        AckStatus::Invalid,
        AckStatus::Unsupported,
        AckStatus::FlashFailed,
    ];

    /// The name the monitor prints.
    pub fn name(self) -> &'static str {
        match self {
            AckStatus::Done => "done",
            AckStatus::Invalid => "invalid",
            AckStatus::Unsupported => "unsupported",
            AckStatus::FlashFailed => "flash_failed",
        }
    }

    fn to_u32(self) -> u32 {
        match self {
            AckStatus::Done => 0,
            AckStatus::Invalid => 1,
            AckStatus::Unsupported => 2,
            AckStatus::FlashFailed => 3,
        }
    }
}

/// The board's answer to a command frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ack {
    /// The command frame's sequence number.
    pub seq: u16,
    /// The command's kind ([`Command::kind`]; 0 when it did not decode).
    pub kind: u32,
    /// What came of it.
    pub status: AckStatus,
}

impl Ack {
    /// The [`ACK_LEN`] bytes.
    pub fn encode(&self) -> [u8; ACK_LEN] {
        Writer::fill(ACK_TAG, VERSION, |w| {
            w.u32s([u32::from(self.seq), self.kind, self.status.to_u32()]);
        })
    }

    /// Decodes an answer. Errors: [`WireError`] (length, tag, version; `Field` for `seq` or
    /// `status`).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked("ack", bytes, ACK_LEN, &[ACK_TAG], VERSION)?;
        let [seq, kind, status] = r.u32s();
        Ok(Self {
            seq: u16::try_from(seq).map_err(|_| r.invalid("seq"))?,
            kind,
            status: usize::try_from(status)
                .ok()
                .and_then(|s| AckStatus::ALL.get(s).copied())
                .ok_or(r.invalid("status"))?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_round_trip() {
        let all = [
            Command::SetMode(Mode::Calibrate),
            Command::SetTag {
                family: 3,
                id: 586,
                size: 0.08,
            },
            Command::SetCamera {
                intrinsics: [300.0, 301.0, 159.5, 119.5],
                distortion: [0.1, -0.2, 0.001, -0.002, 0.05],
            },
            Command::Save,
            Command::SetChessboard(ChessboardSettings {
                cols: 7,
                rows: 5,
                square: 0.03,
                views: 16,
            }),
        ];
        for c in all {
            assert_eq!(Command::decode(&c.encode()), Ok(c));
        }
        for m in Mode::ALL {
            assert_eq!(Mode::from_u32(m.to_u32()), Some(m));
        }
    }

    #[test]
    fn values_no_board_takes_are_named() {
        let field = |f| {
            Err(WireError::Field {
                record: "command",
                field: f,
            })
        };
        let tag = |family, size| Command::SetTag {
            family,
            id: 0,
            size,
        };
        assert_eq!(Command::decode(&tag(9, 0.1).encode()), field("family"));
        assert_eq!(Command::decode(&tag(0, -0.1).encode()), field("size"));
        assert_eq!(Command::decode(&tag(0, f32::NAN).encode()), field("size"));
        let camera = Command::SetCamera {
            intrinsics: [0.0, 300.0, 160.0, 120.0],
            distortion: [0.0; 5],
        };
        assert_eq!(Command::decode(&camera.encode()), field("camera"));
        let board = |cols, rows, square, views| {
            Command::decode(
                &Command::SetChessboard(ChessboardSettings {
                    cols,
                    rows,
                    square,
                    views,
                })
                .encode(),
            )
        };
        assert_eq!(board(2, 6, 0.025, 10), field("board"));
        assert_eq!(board(9, 8, 0.025, 10), field("board"));
        assert_eq!(board(9, 6, 0.0, 10), field("square"));
        assert_eq!(board(9, 6, 0.025, 2), field("views"));
        assert_eq!(board(9, 6, 0.025, 17), field("views"));
        assert!(board(8, 8, 0.025, 3).is_ok());
        let mut b = Command::Save.encode();
        b[8] = 7;
        assert_eq!(Command::decode(&b), field("kind"));
        let mut b = Command::SetMode(Mode::TrackTag).encode();
        b[12] = 4;
        assert_eq!(Command::decode(&b), field("mode"));
        assert!(matches!(
            Command::decode(&b[..20]),
            Err(WireError::Length { .. })
        ));
    }

    #[test]
    fn acks_round_trip() {
        for status in AckStatus::ALL {
            let a = Ack {
                seq: 65535,
                kind: 2,
                status,
            };
            assert_eq!(Ack::decode(&a.encode()), Ok(a));
        }
    }
}
