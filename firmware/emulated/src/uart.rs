//! The record stream's transport on the emulated Arm boards: UART0, the CMSDK APB UART of QEMU's
//! `mps2-an500` (Cortex-M7) and `mps2-an385` (Cortex-M3), transmit only.
//!
//! A real board's record stream goes out of its UART or USB; the emulated board's goes out of
//! this one, which QEMU connects to a file or socket (`-serial file:serial.bin`), and the host
//! reads it with the same [`camgeom_fw_app::link::Deframer`] a real board's monitor uses.
//! Semihosting stays for what comes in (the recorded frames, the run description).
//!
//! Registers (CMSDK technical reference manual, ARM DDI 0479C, table 4-3):
//!
//! | offset | register | used |
//! |---|---|---|
//! | 0x00 | DATA | the byte to send |
//! | 0x04 | STATE | bit 0: transmit buffer full |
//! | 0x08 | CTRL | bit 0: transmit enable |
//! | 0x10 | BAUDDIV | at least 16 (QEMU refuses to send below) |

use camgeom_fw_app::link::{LinkError, encode_frame, max_frame_len};
use camgeom_fw_app::report::RECORD_LEN;

/// UART0's base address on `mps2-an385` and `mps2-an500`.
const UART0: usize = 0x4000_4000;
const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
const TX_FULL: u32 = 1;
const TX_ENABLE: u32 = 1;
/// The board's clock over 16: the fastest rate the UART allows (QEMU sends at once anyway).
const DIVIDER: u32 = 16;

fn write(offset: usize, v: u32) {
    // SAFETY: UART0's registers on the mps2 machines this firmware runs on; word writes are
    // what the peripheral takes, and nothing else maps that address.
    unsafe { ((UART0 + offset) as *mut u32).write_volatile(v) }
}

fn read(offset: usize) -> u32 {
    // SAFETY: as in `write`.
    unsafe { ((UART0 + offset) as *const u32).read_volatile() }
}

/// UART0 as the record stream: each record goes out as one frame of
/// [`camgeom_fw_app::link`], numbered in order.
pub struct RecordLink {
    seq: u16,
    frame: [u8; max_frame_len(RECORD_LEN)],
}

impl RecordLink {
    /// Enables UART0's transmitter.
    pub fn open() -> Self {
        write(BAUDDIV, DIVIDER);
        write(CTRL, TX_ENABLE);
        Self {
            seq: 0,
            frame: [0; max_frame_len(RECORD_LEN)],
        }
    }

    /// Sends `record` as the next frame; returns the bytes sent.
    pub fn send(&mut self, record: &[u8]) -> Result<usize, LinkError> {
        let n = encode_frame(self.seq, record, &mut self.frame)?;
        self.seq = self.seq.wrapping_add(1);
        for &b in self.frame.get(..n).unwrap_or(&[]) {
            while read(STATE) & TX_FULL != 0 {}
            write(DATA, u32::from(b));
        }
        Ok(n)
    }
}
