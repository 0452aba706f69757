//! The emulated board's settings flash: one sector of NOR flash, kept between boots in the
//! host file [`FLASH_FILE`] (QEMU's `mps2` machines have no flash controller to program).
//!
//! It behaves as the STM32H7's flash does where the settings code could get it wrong: erased
//! bytes read 0xFF, a write goes in whole 32-byte flash words at word-aligned offsets, and a
//! write can only clear bits (writing a word that is not erased fails, as the H7's
//! programming error does), so [`camgeom_fw_app::settings::Settings::save`] must erase first.
//! `cargo xtask run` checks the file after the commands job.

use camgeom_fw_app::settings::{SETTINGS_LEN, Settings};
use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use static_cell::ConstStaticCell;

use crate::semihost::{HostError, HostFile};

/// The host file holding the sector.
pub const FLASH_FILE: &str = "flash.bin";
/// The sector's bytes (the H7's sectors are 128 KiB; the settings need one word pair).
pub const SECTOR: usize = 4096;
/// The flash word: the unit of a write.
pub const WORD: usize = 32;

/// A flash operation the model refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// Outside the sector.
    OutOfBounds,
    /// Not on a word (write) or sector (erase) boundary.
    NotAligned,
    /// A write to bytes that were not erased.
    NotErased,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::NotErased => NorFlashErrorKind::Other,
        }
    }
}

/// The sector's bytes: a static (in `.bss`, erased at boot), not on the stack.
static BYTES: ConstStaticCell<[u8; SECTOR]> = ConstStaticCell::new([0; SECTOR]);

/// The sector, with what was done to it.
pub struct FlashModel {
    bytes: &'static mut [u8; SECTOR],
    /// Erases and word writes since boot.
    pub erases: u32,
    /// Words written since boot.
    pub writes: u32,
}

impl FlashModel {
    /// The sector as [`FLASH_FILE`] holds it, erased when there is no such file (a new
    /// board). Errors: a file of another size, or one that does not read; `None` when called
    /// twice (there is one sector).
    pub fn boot() -> Option<Result<Self, HostError>> {
        let model = Self {
            bytes: BYTES.try_take()?,
            erases: 0,
            writes: 0,
        };
        model.bytes.fill(0xFF);
        if let Ok(mut f) = HostFile::open_read(FLASH_FILE)
            && let Err(e) = f.read_exact(&mut model.bytes[..])
        {
            return Some(Err(e));
        }
        Some(Ok(model))
    }

    /// Writes the sector back to [`FLASH_FILE`] (what survives a reset).
    pub fn persist(&self) -> Result<(), HostError> {
        HostFile::create(FLASH_FILE)?.write_all(&self.bytes[..])
    }

    /// The settings stored at the sector's start, if any.
    pub fn settings(&mut self) -> Option<Settings> {
        Settings::load(self, 0)
    }
}

const _: () = assert!(SETTINGS_LEN <= SECTOR && SETTINGS_LEN.is_multiple_of(WORD));

impl ErrorType for FlashModel {
    type Error = FlashError;
}

impl FlashModel {
    fn range(&self, offset: u32, len: usize) -> Result<core::ops::Range<usize>, FlashError> {
        let start = offset as usize;
        let end = start.checked_add(len).ok_or(FlashError::OutOfBounds)?;
        if end > SECTOR {
            return Err(FlashError::OutOfBounds);
        }
        Ok(start..end)
    }
}

impl ReadNorFlash for FlashModel {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let r = self.range(offset, bytes.len())?;
        bytes.copy_from_slice(self.bytes.get(r).ok_or(FlashError::OutOfBounds)?);
        Ok(())
    }

    fn capacity(&self) -> usize {
        SECTOR
    }
}

impl NorFlash for FlashModel {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = SECTOR;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let r = self.range(from, (to as usize).saturating_sub(from as usize))?;
        if !r.start.is_multiple_of(SECTOR) || !r.end.is_multiple_of(SECTOR) {
            return Err(FlashError::NotAligned);
        }
        self.bytes
            .get_mut(r)
            .ok_or(FlashError::OutOfBounds)?
            .fill(0xFF);
        self.erases += 1;
        Ok(())
    }

    fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), FlashError> {
        let r = self.range(offset, data.len())?;
        if !r.start.is_multiple_of(WORD) || !data.len().is_multiple_of(WORD) {
            return Err(FlashError::NotAligned);
        }
        let dst = self.bytes.get_mut(r).ok_or(FlashError::OutOfBounds)?;
        if dst.iter().any(|&b| b != 0xFF) {
            return Err(FlashError::NotErased);
        }
        dst.copy_from_slice(data);
        self.writes += (data.len() / WORD) as u32;
        Ok(())
    }
}
