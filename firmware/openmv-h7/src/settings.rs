//! The settings ([`Settings`]: mode, tag, camera) kept in flash: the last 128 KiB sector of
//! bank 2 (sector 7, `0x081E_0000`), which `memory.x` keeps out of the linker's `FLASH`. At boot
//! [`load`] reads them through embassy-stm32's blocking flash driver (embedded-storage's
//! `NorFlash`); an erased, torn or foreign sector gives the compiled defaults
//! ([`crate::tracker::defaults`]). [`Settings::save`] erases the sector, writes the 64-byte
//! record (two 32-byte flash words) and reads it back.
//!
//! Erasing the sector takes the tracking loop's time (a 128 KiB sector erase can take seconds:
//! the STM32H743 datasheet's `t_ERASE128KB`) but not USB's: the code runs from bank 1, so
//! the interrupt-priority USB executor keeps running while bank 2 erases.
//!
//! Not handled (and untested without a board): a reset in the middle of a flash word's
//! programming can leave a word whose ECC does not check, and the H7 answers the read of such a
//! word with a bus error (RM0433, "Flash memory error protections") rather than bytes that fail
//! the record's CRC; the board would then fault at boot until the sector is erased from the
//! host (a probe, or a full erase over DFU).

use camgeom_fw_app::settings::{SaveError, Settings};
use embassy_stm32::flash::{Blocking, Flash};

/// The sector's offset from the start of flash (`0x0800_0000`): the last 128 KiB of the 2 MiB.
pub const OFFSET: u32 = 0x1E_0000;

/// The settings in flash.
pub struct Store {
    flash: Flash<'static, Blocking>,
}

impl Store {
    /// The store on the flash driver.
    pub fn new(flash: Flash<'static, Blocking>) -> Self {
        Self { flash }
    }

    /// The stored settings, `None` when there are none.
    pub fn load(&mut self) -> Option<Settings> {
        Settings::load(&mut self.flash, OFFSET)
    }

    /// Stores `settings` (erase, write, read back). Errors: [`SaveError`].
    pub fn save(&mut self, settings: &Settings) -> Result<(), SaveError> {
        settings.save(&mut self.flash, OFFSET)
    }
}
