//! The record stream over USB: the board's micro-USB port is a CDC-ACM serial port
//! (`/dev/ttyACM0` on Linux, a COM port on Windows) that carries one framed record per frame
//! ([`camgeom_fw_app::link`]: COBS, sequence number, CRC-32), the very frames the emulated
//! board sends over its UART and `camgeom monitor` decodes.
//!
//! The tracking loop never waits for the host. [`RecordStream::send`] frames the record and
//! puts it in a queue of [`QUEUE_FRAMES`] frames; when the queue is full (no host, or one that
//! does not read) the frame is dropped and counted. Every frame takes the next sequence number,
//! sent or not, so the receiver counts the dropped ones as lost. The USB stack ([`usb`]) runs
//! in an interrupt-priority executor and takes frames from the queue as the host reads them;
//! while no program has the port open (DTR low) it discards them (counted too), so a host that
//! opens the port gets current frames, not a queue of old ones.
//!
//! In mode `stream-frames` each frame's pixels go before its record
//! ([`camgeom_fw_app::frame_chunk`], 600 records a 320x240 frame, after the settings the host
//! draws the overlay with): those wait for room in the queue ([`RecordStream::send_waiting`]),
//! so the frame rate drops to what the link carries, and a frame whose chunk could not be
//! queued in time sends no more of its chunks.
//!
//! The other way, the host sends [`Command`] records framed the same way; the USB task
//! deframes and decodes them and queues each ([`COMMAND_QUEUE`] deep, dropped and counted when
//! full) for the tracking loop, which takes them between frames ([`next_command`]) and answers
//! each with an [`camgeom_fw_app::command::Ack`] record on this stream.

use core::sync::atomic::{AtomicU32, Ordering};

use camgeom_fw_app::command::{COMMAND_LEN, Command};
use camgeom_fw_app::link::{Deframer, encode_frame, max_frame_len};
use camgeom_fw_app::report::RECORD_LEN;
use embassy_futures::join::join3;
use embassy_stm32::Peri;
use embassy_stm32::peripherals::{PA11, PA12, USB_OTG_FS};
use embassy_stm32::usb::Driver;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::{Channel, TrySendError};
use embassy_time::{Duration, Instant};
use embassy_usb::Builder;
use embassy_usb::class::cdc_acm::{CdcAcmClass, Receiver, Sender, State};
use embassy_usb::driver::EndpointError;

use crate::Irqs;

/// Bytes on the link of one framed frame record, at most.
pub const FRAME_MAX: usize = max_frame_len(RECORD_LEN);
/// Frames the queue holds between the tracking loop and USB: a quarter of a second at 30 fps.
pub const QUEUE_FRAMES: usize = 8;
/// Commands received and not yet taken by the tracking loop (it takes them every frame).
pub const COMMAND_QUEUE: usize = 4;
/// USB full speed's bulk packet size.
const PACKET: usize = 64;
/// pid.codes' test VID/PID (1209:0001): fine on a development board, not in a product.
const VID_PID: (u16, u16) = (0x1209, 0x0001);

/// One framed record.
struct Frame {
    len: usize,
    bytes: [u8; FRAME_MAX],
}

/// The queue from the tracking loop (thread mode) to the USB task (interrupt priority).
static QUEUE: Channel<CriticalSectionRawMutex, Frame, QUEUE_FRAMES> = Channel::new();
/// Frames the USB task took from the queue and discarded: no program had the port open.
static DISCARDED: AtomicU32 = AtomicU32::new(0);

/// A command frame from the host: its sequence number and the command, `None` when its record
/// did not decode (answered `Invalid`).
#[derive(Debug, Clone, Copy)]
pub struct Incoming {
    /// The frame's sequence number, which the answer repeats.
    pub seq: u16,
    /// The command, checked.
    pub command: Option<Command>,
}

/// The queue from the USB task to the tracking loop.
static COMMANDS: Channel<CriticalSectionRawMutex, Incoming, COMMAND_QUEUE> = Channel::new();
/// Commands dropped because [`COMMANDS`] was full.
static COMMANDS_DROPPED: AtomicU32 = AtomicU32::new(0);

/// The next command from the host, if one came; never waits.
pub fn next_command() -> Option<Incoming> {
    COMMANDS.try_receive().ok()
}

/// Commands dropped so far because the tracking loop had not taken the ones before.
pub fn commands_dropped() -> u32 {
    COMMANDS_DROPPED.load(Ordering::Relaxed)
}

/// The tracking loop's end of the stream.
#[derive(Debug, Default)]
pub struct RecordStream {
    seq: u16,
    queued: u32,
    dropped: u32,
}

impl RecordStream {
    /// Frames `record` (a frame record, or an answer to a command: any record up to
    /// [`RECORD_LEN`] bytes) as the next frame and queues it for USB; never waits. A full queue
    /// drops it ([`Self::dropped`]).
    pub fn send(&mut self, record: &[u8]) {
        let Some(frame) = self.frame(record) else {
            return;
        };
        match QUEUE.try_send(frame) {
            Ok(()) => self.queued = self.queued.wrapping_add(1),
            Err(TrySendError::Full(_)) => self.dropped = self.dropped.wrapping_add(1),
        }
    }

    /// [`Self::send`], waiting up to `patience` for room in the queue (the USB task, at a
    /// higher priority, empties it meanwhile): how a frame's pixels go, hundreds of records at
    /// once. Returns `false` when the queue stayed full (the record dropped and counted).
    pub fn send_waiting(&mut self, record: &[u8], patience: Duration) -> bool {
        let Some(mut frame) = self.frame(record) else {
            return false;
        };
        let deadline = Instant::now() + patience;
        loop {
            match QUEUE.try_send(frame) {
                Ok(()) => {
                    self.queued = self.queued.wrapping_add(1);
                    return true;
                }
                Err(TrySendError::Full(f)) if Instant::now() < deadline => frame = f,
                Err(TrySendError::Full(_)) => {
                    self.dropped = self.dropped.wrapping_add(1);
                    return false;
                }
            }
        }
    }

    /// `record` framed with the next sequence number (taken whether or not it is sent).
    fn frame(&mut self, record: &[u8]) -> Option<Frame> {
        let seq = self.seq;
        self.seq = seq.wrapping_add(1);
        let mut frame = Frame {
            len: 0,
            bytes: [0; FRAME_MAX],
        };
        match encode_frame(seq, record, &mut frame.bytes) {
            Ok(n) => frame.len = n,
            // FRAME_MAX is the longest frame of a record: only a record longer than
            // RECORD_LEN, which this firmware does not send.
            Err(e) => {
                defmt::warn!("record stream: {}", e);
                return None;
            }
        }
        Some(frame)
    }

    /// Frames queued for USB so far.
    pub fn queued(&self) -> u32 {
        self.queued
    }

    /// Frames dropped so far because the queue was full.
    pub fn dropped(&self) -> u32 {
        self.dropped
    }

    /// Queued frames discarded so far because no program had the port open.
    pub fn discarded(&self) -> u32 {
        DISCARDED.load(Ordering::Relaxed)
    }
}

/// The USB device: USB OTG FS on PA12 (D+) and PA11 (D-), VBUS sensed on PA9 (as the OpenMV
/// firmware does), one CDC-ACM function that sends the queued frames and receives commands.
/// Runs forever.
#[embassy_executor::task]
pub async fn usb(otg: Peri<'static, USB_OTG_FS>, dp: Peri<'static, PA12>, dm: Peri<'static, PA11>) {
    // Everything here lives in the task's static storage.
    let mut ep_out = [0u8; 256];
    let mut config_descriptor = [0u8; 256];
    let mut bos_descriptor = [0u8; 256];
    let mut control = [0u8; 64];
    let mut state = State::new();

    let mut otg_config = embassy_stm32::usb::Config::default();
    otg_config.vbus_detection = true;
    let driver = Driver::new_fs(otg, Irqs, dp, dm, &mut ep_out, otg_config);
    let mut config = embassy_usb::Config::new(VID_PID.0, VID_PID.1);
    config.manufacturer = Some("camgeom");
    config.product = Some("camgeom OpenMV Cam H7 record stream");
    config.max_power = 100;
    config.max_packet_size_0 = PACKET as u8;
    let mut builder = Builder::new(
        driver,
        config,
        &mut config_descriptor,
        &mut bos_descriptor,
        &mut [],
        &mut control,
    );
    let class = CdcAcmClass::new(&mut builder, &mut state, PACKET as u16);
    let mut device = builder.build();
    let (mut tx, mut rx) = class.split();
    join3(device.run(), forward(&mut tx), receive(&mut rx)).await;
}

/// Deframes what the host sends and queues the commands for the tracking loop.
async fn receive<'d, D: embassy_usb::driver::Driver<'d>>(rx: &mut Receiver<'d, D>) {
    let mut packet = [0u8; PACKET];
    let mut deframer = Deframer::<{ max_frame_len(COMMAND_LEN) }>::new();
    loop {
        rx.wait_connection().await;
        // Unplugged or reset ends the loop: wait for the host to configure the device again.
        while let Ok(n) = rx.read_packet(&mut packet).await {
            let mut input = packet.get(..n).unwrap_or(&[]);
            while let Some(frame) = deframer.push(&mut input) {
                let command = match Command::decode(frame.record) {
                    Ok(c) => Some(c),
                    Err(e) => {
                        defmt::warn!("command {=u16}: {}", frame.seq, e);
                        None
                    }
                };
                let incoming = Incoming {
                    seq: frame.seq,
                    command,
                };
                if COMMANDS.try_send(incoming).is_err() {
                    COMMANDS_DROPPED.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }
}

/// Sends the queued frames while a program has the port open, discards them otherwise.
async fn forward<'d, D: embassy_usb::driver::Driver<'d>>(class: &mut Sender<'d, D>) {
    loop {
        class.wait_connection().await;
        loop {
            let frame = QUEUE.receive().await;
            if !class.dtr() {
                DISCARDED.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let bytes = frame.bytes.get(..frame.len).unwrap_or(&[]);
            if write(class, bytes).await.is_err() {
                // Unplugged or reset: wait for the host to configure the device again.
                break;
            }
        }
    }
}

/// Writes `bytes` in full-size packets, then a short (possibly empty) one, so that the host
/// hands the frame over at once rather than waiting for more.
async fn write<'d, D: embassy_usb::driver::Driver<'d>>(
    class: &mut Sender<'d, D>,
    bytes: &[u8],
) -> Result<(), EndpointError> {
    for packet in bytes.chunks(PACKET) {
        class.write_packet(packet).await?;
    }
    if bytes.len().is_multiple_of(PACKET) {
        class.write_packet(&[]).await?;
    }
    Ok(())
}
