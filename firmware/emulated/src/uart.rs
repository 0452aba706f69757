//! The emulated Arm boards' serial ports: the CMSDK APB UARTs of QEMU's `mps2-an500`
//! (Cortex-M7) and `mps2-an385` (Cortex-M3), transmit only. UART0 carries the record stream,
//! UART1 the MAVLink messages to an autopilot.
//!
//! A real board's record stream goes out of its UART or USB; the emulated board's goes out of
//! UART0, which QEMU connects to a file or socket (the first `-serial file:serial.bin`), and
//! the host reads it with the same [`camgeom_fw_app::link::Deframer`] a real board's monitor
//! uses; UART1 goes to the second `-serial` (`mavlink.bin`). Semihosting stays for what comes
//! in (the recorded frames, the run description).
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

/// UART0's and UART1's base addresses on `mps2-an385` and `mps2-an500` (the AN385 and AN500
/// application notes' memory maps).
const UART0: usize = 0x4000_4000;
#[cfg(mavlink)]
const UART1: usize = 0x4000_5000;
const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
const TX_FULL: u32 = 1;
const TX_ENABLE: u32 = 1;
/// The board's clock over 16: the fastest rate the UART allows (QEMU sends at once anyway).
const DIVIDER: u32 = 16;

/// One UART, by its base address.
struct Uart(usize);

impl Uart {
    fn write(&self, offset: usize, v: u32) {
        // SAFETY: the registers of a UART of the mps2 machines this firmware runs on (`self.0`
        // is one of the constants above); word writes are what the peripheral takes, and
        // nothing else maps that address.
        unsafe { ((self.0 + offset) as *mut u32).write_volatile(v) }
    }

    fn read(&self, offset: usize) -> u32 {
        // SAFETY: as in `write`.
        unsafe { ((self.0 + offset) as *const u32).read_volatile() }
    }

    /// Enables the transmitter.
    fn open(base: usize) -> Self {
        let uart = Self(base);
        uart.write(BAUDDIV, DIVIDER);
        uart.write(CTRL, TX_ENABLE);
        uart
    }

    /// Sends `bytes`, waiting while the transmit buffer is full.
    fn send(&self, bytes: &[u8]) {
        for &b in bytes {
            while self.read(STATE) & TX_FULL != 0 {}
            self.write(DATA, u32::from(b));
        }
    }
}

/// UART0 as the record stream: each record goes out as one frame of
/// [`camgeom_fw_app::link`], numbered in order.
pub struct RecordLink {
    uart: Uart,
    seq: u16,
    frame: [u8; max_frame_len(RECORD_LEN)],
}

impl RecordLink {
    /// Enables UART0's transmitter.
    pub fn open() -> Self {
        Self {
            uart: Uart::open(UART0),
            seq: 0,
            frame: [0; max_frame_len(RECORD_LEN)],
        }
    }

    /// Sends `record` as the next frame; returns the bytes sent.
    pub fn send(&mut self, record: &[u8]) -> Result<usize, LinkError> {
        let n = encode_frame(self.seq, record, &mut self.frame)?;
        self.seq = self.seq.wrapping_add(1);
        self.uart.send(self.frame.get(..n).unwrap_or(&[]));
        Ok(n)
    }
}

/// UART1 as the autopilot's link: MAVLink 2 messages ([`camgeom_fw_app::mavlink`]), a
/// `HEARTBEAT` a second and a `LANDING_TARGET` for every frame with a pose.
#[cfg(mavlink)]
pub struct MavlinkLink {
    uart: Uart,
    mavlink: camgeom_fw_app::mavlink::Mavlink,
    heartbeats: u32,
    targets: u32,
    bytes: u32,
    next_heartbeat_us: u64,
}

#[cfg(mavlink)]
impl MavlinkLink {
    /// Enables UART1's transmitter.
    pub fn open(config: camgeom_fw_app::mavlink::MavlinkConfig) -> Self {
        Self {
            uart: Uart::open(UART1),
            mavlink: camgeom_fw_app::mavlink::Mavlink::new(config),
            heartbeats: 0,
            targets: 0,
            bytes: 0,
            next_heartbeat_us: 0,
        }
    }
}

#[cfg(mavlink)]
impl crate::job::RecordSink for MavlinkLink {
    fn record(&mut self, r: &camgeom_fw_app::report::FrameRecord, size: [f32; 2]) {
        let now = crate::job::now_us();
        if now >= self.next_heartbeat_us {
            let hb = self.mavlink.heartbeat();
            self.uart.send(hb);
            self.bytes += hb.len() as u32;
            self.heartbeats += 1;
            self.next_heartbeat_us = now + 1_000_000;
        }
        if let (Some((best, _)), None) = (r.pose, r.error) {
            let sent = match self.mavlink.landing_target(now, &best, size) {
                Some(b) => {
                    self.uart.send(b);
                    self.bytes += b.len() as u32;
                    true
                }
                None => false,
            };
            self.targets += u32::from(sent);
        }
    }

    fn finish(&self) {
        defmt::info!(
            "mavlink: {=u32} LANDING_TARGET, {=u32} HEARTBEAT, {=u32} bytes over UART1",
            self.targets,
            self.heartbeats,
            self.bytes
        );
    }
}
