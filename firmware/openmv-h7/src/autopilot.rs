//! MAVLink to an autopilot over UART3: a `HEARTBEAT` a second and a `LANDING_TARGET` for every
//! frame with a pose ([`camgeom_fw_app::mavlink`], the messages the emulated board sends over
//! its UART1), what ArduPilot's and PX4's precision landing read.
//!
//! UART3 is on the OpenMV Cam H7's header: P4 = PB10 (TX), P5 = PB11 (RX), USART3 on alternate
//! function 7. Sources: the openmv/openmv repository, `boards/OPENMV4/board_config.h` (P4 and P5
//! are PB10 and PB11, I2C2 or GPIO there) and its MAVLink examples
//! (`scripts/examples/07-Interface-Library/02-MAVLink/mavlink_apriltags_landing_target.py`:
//! `UART(3, 115200)`, "P4 = TXD"); STM32H743 datasheet (DS12110), alternate functions: PB10
//! `USART3_TX`, PB11 `USART3_RX` on AF7. 115,200 baud, 8N1. Only TX is used.
//!
//! The tracking loop never waits for the UART: [`MavlinkLink::frame`] builds the messages and
//! puts them in a queue of [`QUEUE_MESSAGES`]; a task ([`uart`]) writes them out by DMA. A full
//! queue (the UART behind: at 115,200 baud a 72-byte `LANDING_TARGET` takes 6.25 ms) drops the
//! message and counts it.

use core::sync::atomic::{AtomicU32, Ordering};

use camgeom_fw_app::mavlink::{Mavlink, MavlinkConfig};
use camgeom_fw_app::report::FrameRecord;
use embassy_stm32::mode::Async;
use embassy_stm32::usart::UartTx;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_time::Instant;

/// UART3's rate: what the OpenMV MAVLink examples and ArduPilot's `SERIALn_BAUD = 115` use.
pub const BAUD: u32 = 115_200;
/// Messages queued for the UART: 4 frames' worth.
pub const QUEUE_MESSAGES: usize = 4;
/// A `HEARTBEAT` every this many microseconds.
const HEARTBEAT_US: u64 = 1_000_000;

/// One message's bytes.
struct Message {
    len: usize,
    bytes: [u8; Mavlink::MAX_LEN],
}

/// The queue from the tracking loop to the UART task.
static QUEUE: Channel<CriticalSectionRawMutex, Message, QUEUE_MESSAGES> = Channel::new();
/// Messages the UART failed to send (a DMA or UART error).
static FAILED: AtomicU32 = AtomicU32::new(0);

/// The tracking loop's end of the autopilot link.
pub struct MavlinkLink {
    mavlink: Mavlink,
    next_heartbeat_us: u64,
    heartbeats: u32,
    targets: u32,
    dropped: u32,
}

impl MavlinkLink {
    /// The link with the default configuration ([`MavlinkConfig::default`]: system 1, the
    /// camera component, the camera looking down with the top of the image forward).
    pub fn new() -> Self {
        Self {
            mavlink: Mavlink::new(MavlinkConfig::default()),
            next_heartbeat_us: 0,
            heartbeats: 0,
            targets: 0,
            dropped: 0,
        }
    }

    /// After a frame: the `HEARTBEAT` when one is due, the `LANDING_TARGET` when the frame has
    /// a pose (of a target `size` metres). `time_usec` is the board's clock since boot. Never
    /// waits.
    pub fn frame(&mut self, record: &FrameRecord, size: [f32; 2]) {
        let now = Instant::now().as_micros();
        if now >= self.next_heartbeat_us {
            self.next_heartbeat_us = now.saturating_add(HEARTBEAT_US);
            let sent = queue(self.mavlink.heartbeat());
            self.count(sent, true);
        }
        if let (Some((best, _)), None) = (record.pose, record.error)
            && let Some(bytes) = self.mavlink.landing_target(now, &best, size)
        {
            let sent = queue(bytes);
            self.count(sent, false);
        }
    }

    fn count(&mut self, sent: bool, heartbeat: bool) {
        match (sent, heartbeat) {
            (false, _) => self.dropped = self.dropped.wrapping_add(1),
            (true, true) => self.heartbeats = self.heartbeats.wrapping_add(1),
            (true, false) => self.targets = self.targets.wrapping_add(1),
        }
    }

    /// One defmt line of the counts.
    pub fn log(&self) {
        defmt::info!(
            "mavlink: {=u32} LANDING_TARGET, {=u32} HEARTBEAT queued for UART3, {=u32} dropped (queue full), {=u32} failed",
            self.targets,
            self.heartbeats,
            self.dropped,
            FAILED.load(Ordering::Relaxed)
        );
    }
}

impl Default for MavlinkLink {
    fn default() -> Self {
        Self::new()
    }
}

/// Queues `bytes`; `false` when the queue is full.
fn queue(bytes: &[u8]) -> bool {
    let mut m = Message {
        len: bytes.len(),
        bytes: [0; Mavlink::MAX_LEN],
    };
    match m.bytes.get_mut(..bytes.len()) {
        Some(b) => b.copy_from_slice(bytes),
        None => return false,
    }
    QUEUE.try_send(m).is_ok()
}

/// Writes the queued messages to UART3 by DMA. Runs forever.
#[embassy_executor::task]
pub async fn uart(mut tx: UartTx<'static, Async>) {
    loop {
        // The message lives in this task's static storage (AXI SRAM), where the DMA reads it.
        let m = QUEUE.receive().await;
        let bytes = m.bytes.get(..m.len).unwrap_or(&[]);
        if tx.write(bytes).await.is_err() {
            FAILED.fetch_add(1, Ordering::Relaxed);
        }
    }
}
