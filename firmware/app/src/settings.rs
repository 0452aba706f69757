//! What a user has set on the board (mode, tag, camera), changed by [`Command`]s and kept in
//! flash, where the board loads it at boot.
//!
//! # `"CSTG"`, version 2, [`SETTINGS_LEN`] bytes, at the start of a flash sector
//!
//! | bytes | field |
//! |---|---|
//! | 0..8 | tag `"CSTG"`, version (see [`crate::wire`]) |
//! | 8..20 | `u32` [`Mode`], `u32` tag family, `u32` tag id |
//! | 20..24 | `f32` tag side, metres |
//! | 24..40 | `f32` × 4 `fx fy cx cy` |
//! | 40..60 | `f32` × 5 `k1 k2 p1 p2 k3` |
//! | 60..76 | calibrate mode's chessboard: `u32` columns, `u32` rows (inner corners), `f32` square side (metres), `u32` views ([`ChessboardSettings`]) |
//! | 76..92 | zeros |
//! | 92..96 | `u32` CRC-32/ISO-HDLC of bytes 0..92 |
//!
//! (Version 1, 64 bytes, had no chessboard: a board that finds one boots with its defaults.)
//!
//! A sector that is erased, torn by a reset during the write, or written by another layout
//! version reads as no settings ([`Settings::load`] gives `None`, the board keeps its
//! defaults); [`Settings::save`] erases, writes and reads back.

use camgeom::Error;
use camgeom::camera::{Camera, Distortion, Intrinsics};
use crc::{CRC_32_ISO_HDLC, Crc};
use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};

use crate::command::{AckStatus, ChessboardSettings, Command, Mode};
use crate::options::{Acquisition, AppOptions};
use crate::wire::{Reader, WireError, Writer, tag};

/// The record's tag.
pub const SETTINGS_TAG: u32 = tag(b"CSTG");
/// Its layout version.
pub const VERSION: u32 = 2;
/// Its bytes, CRC included (a multiple of 32, the STM32H7's flash word).
pub const SETTINGS_LEN: usize = 96;
/// The bytes the CRC covers.
const BODY_LEN: usize = SETTINGS_LEN - 4;

const CRC: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

// Settings go over the link too (before a streamed frame, after a calibration).
const _: () = assert!(SETTINGS_LEN <= crate::report::RECORD_LEN);

/// A board's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Settings {
    /// What the board does.
    pub mode: Mode,
    /// The tag family (index in [`crate::options::TAG_FAMILIES`]).
    pub family: u8,
    /// The tag's id.
    pub id: u16,
    /// The tag's side (its black square), metres.
    pub tag_size: f32,
    /// `fx, fy, cx, cy`, pixels.
    pub intrinsics: [f32; 4],
    /// OpenCV `k1, k2, p1, p2, k3`.
    pub distortion: [f32; 5],
    /// The chessboard [`Mode::Calibrate`] looks for, and its views.
    pub chessboard: ChessboardSettings,
}

/// What applying a command asks of the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applied {
    /// The settings changed (the board rebuilds its configuration).
    Changed,
    /// Store them ([`Settings::save`]).
    Save,
}

impl Settings {
    /// Applies a (decoded, so checked) command.
    pub fn apply(&mut self, command: &Command) -> Applied {
        match *command {
            Command::SetMode(m) => self.mode = m,
            Command::SetTag { family, id, size } => {
                self.family = family;
                self.id = id;
                self.tag_size = size;
            }
            Command::SetCamera {
                intrinsics,
                distortion,
            } => {
                self.intrinsics = intrinsics;
                self.distortion = distortion;
            }
            Command::Save => return Applied::Save,
            Command::SetChessboard(b) => self.chessboard = b,
        }
        Applied::Changed
    }

    /// Carries out a (decoded, so checked) command the way every board does, and says how it
    /// went: a change is kept only when `fits` accepts the settings it makes (the board can
    /// run them; `Err(status)` says why not, e.g. [`AckStatus::Unsupported`] for a mode the
    /// firmware does not have), a save goes to `save` ([`AckStatus::FlashFailed`] when it
    /// fails).
    pub fn carry_out(
        &mut self,
        command: &Command,
        fits: impl FnOnce(&Settings) -> Result<(), AckStatus>,
        save: impl FnOnce(&Settings) -> Result<(), SaveError>,
    ) -> AckStatus {
        let mut next = *self;
        match next.apply(command) {
            Applied::Changed => match fits(&next) {
                Ok(()) => {
                    *self = next;
                    AckStatus::Done
                }
                Err(status) => status,
            },
            Applied::Save => match save(self) {
                Ok(()) => AckStatus::Done,
                Err(_) => AckStatus::FlashFailed,
            },
        }
    }

    /// The camera. Errors: as [`Intrinsics::new`] and [`Distortion::from_opencv`].
    pub fn camera(&self) -> Result<Camera<f32>, Error> {
        let [fx, fy, cx, cy] = self.intrinsics;
        Ok(Camera::new(
            Intrinsics::new(fx, fy, cx, cy)?,
            Distortion::from_opencv(self.distortion)?,
        ))
    }

    /// The tracking options of a tracking mode: the tag (a square of [`Self::tag_size`]; also
    /// while streaming frames) or given corners of a target `corners_size`; `reacquire_every` and `forward_backward` as
    /// [`AppOptions`] has them. `None` for a mode that does not track.
    pub fn options(
        &self,
        corners_size: [f32; 2],
        reacquire_every: u32,
        forward_backward: bool,
    ) -> Option<AppOptions> {
        let (target_size, acquisition) = match self.mode {
            // Streaming frames tracks the tag too: each frame's record goes with its pixels.
            Mode::TrackTag | Mode::StreamFrames => (
                [self.tag_size; 2],
                Acquisition::Tag {
                    family: self.family,
                    id: self.id,
                },
            ),
            Mode::TrackCorners => (corners_size, Acquisition::Corners),
            Mode::Calibrate => return None,
        };
        Some(AppOptions {
            target_size,
            acquisition,
            reacquire_every,
            forward_backward,
        })
    }

    /// The [`SETTINGS_LEN`] bytes, CRC last.
    pub fn encode(&self) -> [u8; SETTINGS_LEN] {
        let mut b: [u8; SETTINGS_LEN] = Writer::fill(SETTINGS_TAG, VERSION, |w| {
            w.u32s([
                self.mode.to_u32(),
                u32::from(self.family),
                u32::from(self.id),
            ]);
            w.f32(self.tag_size);
            w.f32s(self.intrinsics);
            w.f32s(self.distortion);
            let b = &self.chessboard;
            w.u32s([u32::from(b.cols), u32::from(b.rows)]);
            w.f32(b.square);
            w.u32(u32::from(b.views));
        });
        let crc = CRC.checksum(b.get(..BODY_LEN).unwrap_or(&[]));
        if let Some(tail) = b.get_mut(BODY_LEN..) {
            tail.copy_from_slice(&crc.to_le_bytes());
        }
        b
    }

    /// Decodes and checks stored settings. Errors: [`WireError`] (length, tag, version;
    /// `Field` for `crc` and for values no command could have set).
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked("settings", bytes, SETTINGS_LEN, &[SETTINGS_TAG], VERSION)?;
        let [mode, family, id] = r.u32s();
        let tag_size = r.f32();
        let intrinsics = r.f32s();
        let distortion = r.f32s();
        let [cols, rows] = r.u32s();
        let square = r.f32();
        let views = r.u32();
        let _zeros: [u32; 4] = r.u32s();
        let crc = r.u32();
        if Some(crc) != bytes.get(..BODY_LEN).map(|b| CRC.checksum(b)) {
            return Err(r.invalid("crc"));
        }
        // Each value through the command that sets it: one copy of the checks.
        let mode = Mode::from_u32(mode).ok_or(r.invalid("mode"))?;
        let field = |e: WireError| match e {
            WireError::Field { field, .. } => r.invalid(field),
            other => other,
        };
        let Command::SetTag { family, id, size } = Command::decode(
            &Command::SetTag {
                family: u8::try_from(family).unwrap_or(u8::MAX),
                id: u16::try_from(id).unwrap_or(u16::MAX),
                size: tag_size,
            }
            .encode(),
        )
        .map_err(field)?
        else {
            return Err(r.invalid("family"));
        };
        Command::decode(
            &Command::SetCamera {
                intrinsics,
                distortion,
            }
            .encode(),
        )
        .map_err(field)?;
        let byte = |v: u32| u8::try_from(v).unwrap_or(u8::MAX);
        let chessboard = ChessboardSettings {
            cols: byte(cols),
            rows: byte(rows),
            square,
            views: byte(views),
        };
        chessboard.check().map_err(|f| r.invalid(f))?;
        Ok(Self {
            mode,
            family,
            id,
            tag_size: size,
            intrinsics,
            distortion,
            chessboard,
        })
    }

    /// The settings stored at `offset` of `flash`, `None` when there are none (erased, torn,
    /// another version, unreadable).
    pub fn load<F: ReadNorFlash>(flash: &mut F, offset: u32) -> Option<Self> {
        let mut b = [0u8; SETTINGS_LEN];
        flash.read(offset, &mut b).ok()?;
        Self::decode(&b).ok()
    }

    /// Stores the settings at `offset` of `flash` (the start of an erase sector, which it
    /// erases), then reads them back. Errors: [`SaveError`].
    pub fn save<F: NorFlash>(&self, flash: &mut F, offset: u32) -> Result<(), SaveError> {
        let sector = u32::try_from(F::ERASE_SIZE).map_err(|_| SaveError::Layout)?;
        if !offset.is_multiple_of(sector)
            || !SETTINGS_LEN.is_multiple_of(F::WRITE_SIZE)
            || SETTINGS_LEN > F::ERASE_SIZE
        {
            return Err(SaveError::Layout);
        }
        let end = offset.checked_add(sector).ok_or(SaveError::Layout)?;
        flash.erase(offset, end).map_err(|_| SaveError::Erase)?;
        let bytes = self.encode();
        flash.write(offset, &bytes).map_err(|_| SaveError::Write)?;
        match Self::load(flash, offset) {
            Some(back) if back == *self => Ok(()),
            _ => Err(SaveError::Verify),
        }
    }
}

/// Why the settings were not stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SaveError {
    /// The offset is not a sector's start, or the record does not fit the flash's words.
    Layout,
    /// The sector did not erase.
    Erase,
    /// The record did not write.
    Write,
    /// What reads back is not what was written.
    Verify,
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_storage::nor_flash::{ErrorType, NorFlashError, NorFlashErrorKind};

    /// NOR flash: erased bytes are 0xFF, a write only clears bits, in 32-byte words.
    struct Nor {
        bytes: [u8; 256],
    }

    #[derive(Debug)]
    struct NorError(NorFlashErrorKind);

    impl NorFlashError for NorError {
        fn kind(&self) -> NorFlashErrorKind {
            self.0
        }
    }

    impl ErrorType for Nor {
        type Error = NorError;
    }

    impl ReadNorFlash for Nor {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, out: &mut [u8]) -> Result<(), NorError> {
            let o = offset as usize;
            let src = self
                .bytes
                .get(o..o + out.len())
                .ok_or(NorError(NorFlashErrorKind::OutOfBounds))?;
            out.copy_from_slice(src);
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.bytes.len()
        }
    }

    impl NorFlash for Nor {
        const WRITE_SIZE: usize = 32;
        const ERASE_SIZE: usize = 128;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), NorError> {
            self.bytes
                .get_mut(from as usize..to as usize)
                .ok_or(NorError(NorFlashErrorKind::OutOfBounds))?
                .fill(0xFF);
            Ok(())
        }
        fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), NorError> {
            let o = offset as usize;
            let dst = self
                .bytes
                .get_mut(o..o + data.len())
                .ok_or(NorError(NorFlashErrorKind::OutOfBounds))?;
            for (d, s) in dst.iter_mut().zip(data) {
                *d &= *s;
            }
            Ok(())
        }
    }

    fn settings() -> Settings {
        Settings {
            mode: Mode::TrackTag,
            family: 0,
            id: 7,
            tag_size: 0.16,
            intrinsics: [300.0, 301.0, 159.5, 119.5],
            distortion: [0.1, -0.2, 0.001, -0.002, 0.05],
            chessboard: ChessboardSettings::DEFAULT,
        }
    }

    #[test]
    fn saved_settings_load_back_and_erased_flash_has_none() {
        let mut flash = Nor { bytes: [0xFF; 256] };
        assert_eq!(Settings::load(&mut flash, 128), None);
        // A sector holding other bits: save erases before it writes.
        flash.bytes[128..].fill(0x5A);
        let s = settings();
        assert_eq!(s.save(&mut flash, 128), Ok(()));
        assert_eq!(Settings::load(&mut flash, 128), Some(s));
        assert_eq!(s.save(&mut flash, 64), Err(SaveError::Layout));
    }

    /// A calibrated camera (any f32 values) and the calibrate mode's board come back from
    /// the flash bit for bit; a board no command takes does not load.
    #[test]
    fn a_calibrated_camera_loads_back_bit_for_bit() {
        let mut flash = Nor { bytes: [0xFF; 256] };
        let mut s = settings();
        s.intrinsics = [266.123_46, 266.543_2, 171.000_01, 117.299_995];
        s.distortion = [-0.261_234_5, -0.041_2, 0.001_234_5, -1.2e-5, 0.212_3];
        s.chessboard = ChessboardSettings {
            cols: 7,
            rows: 5,
            square: 0.030_1,
            views: 12,
        };
        s.save(&mut flash, 0).unwrap();
        let back = Settings::load(&mut flash, 0).unwrap();
        let bits = |s: &Settings| {
            (
                s.intrinsics.map(f32::to_bits),
                s.distortion.map(f32::to_bits),
                s.chessboard.square.to_bits(),
            )
        };
        assert_eq!((bits(&back), back), (bits(&s), s));
        s.chessboard.views = 40;
        assert!(matches!(
            Settings::decode(&s.encode()),
            Err(WireError::Field { field: "views", .. })
        ));
    }

    #[test]
    fn torn_or_foreign_records_read_as_none() {
        let mut flash = Nor { bytes: [0xFF; 256] };
        settings().save(&mut flash, 0).unwrap();
        // A reset after the first word: the rest still erased.
        flash.bytes[32..64].fill(0xFF);
        assert_eq!(Settings::load(&mut flash, 0), None);
        let mut b = settings().encode();
        b[20] ^= 1;
        assert!(matches!(
            Settings::decode(&b),
            Err(WireError::Field { field: "crc", .. })
        ));
        let mut bad = settings();
        bad.tag_size = -1.0;
        assert!(matches!(
            Settings::decode(&bad.encode()),
            Err(WireError::Field { field: "size", .. })
        ));
    }

    #[test]
    fn a_change_the_board_cannot_run_is_not_kept() {
        let mut s = settings();
        let before = s;
        let calibrate = Command::SetMode(Mode::Calibrate);
        let refuse = |_: &Settings| Err(AckStatus::Unsupported);
        let no_save = |_: &Settings| -> Result<(), SaveError> { unreachable!() };
        assert_eq!(
            s.carry_out(&calibrate, refuse, no_save),
            AckStatus::Unsupported
        );
        assert_eq!(s, before);
        let accept = |_: &Settings| Ok(());
        assert_eq!(s.carry_out(&calibrate, accept, no_save), AckStatus::Done);
        assert_eq!(s.mode, Mode::Calibrate);
        let fail = |_: &Settings| Err(SaveError::Verify);
        assert_eq!(
            s.carry_out(&Command::Save, accept, fail),
            AckStatus::FlashFailed
        );
    }

    #[test]
    fn commands_change_what_they_name() {
        let mut s = settings();
        assert_eq!(
            s.apply(&Command::SetTag {
                family: 2,
                id: 3,
                size: 0.05
            }),
            Applied::Changed
        );
        assert_eq!((s.family, s.id, s.tag_size), (2, 3, 0.05));
        assert_eq!(s.apply(&Command::Save), Applied::Save);
        s.apply(&Command::SetMode(Mode::TrackCorners));
        let o = s.options([0.2, 0.1], 5, false).unwrap();
        assert_eq!(
            (o.acquisition, o.target_size),
            (Acquisition::Corners, [0.2, 0.1])
        );
        s.apply(&Command::SetMode(Mode::Calibrate));
        assert_eq!(s.options([0.2, 0.1], 5, false), None);
        assert!(s.camera().is_ok());
    }
}
