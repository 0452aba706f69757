//! The OpenMV Cam H7's camera: an OV7725 set up over I2C1, its luma captured by DCMI.
//!
//! The sensor sends YUV422 as `Y0 U0 Y1 V0 Y2 U1 ...`, one byte per pixel clock. The DCMI's
//! byte-select mode (`CR.BSM = 01`, `CR.OEBS = 0`: keep the first byte of every pair, from the
//! start of each line) drops the chroma in hardware, so the DMA writes exactly one luma byte
//! per pixel: a 320x240 grayscale frame is 76 800 bytes, 19 200 words of the DCMI's 32-bit
//! data register. In 8-bit mode that register packs four consecutive bytes, the first in bits
//! `[7:0]`, so the little-endian words are the pixels in raster order.
//!
//! Luma first, and the sync polarities (VSYNC high during vertical blanking, HREF high on
//! valid data, data sampled on PIXCLK's rising edge, which is `dcmi::Config::default()`) are
//! as the OpenMV firmware sets them for this sensor (`drivers/sensors/ov7725.c`: `vsync_pol =
//! 1`, `hsync_pol = 0`, `pixck_pol = 1`, no YUV byte swap; its grayscale path keeps the first
//! byte of every pixel).

use camgeom::image::ImageMut;
use camgeom_fw_app::FrameSource;
use embassy_stm32::dcmi::{self, Dcmi};
use embassy_stm32::peripherals::DCMI;
use embedded_hal::i2c::I2c;
use ov7725::Ov7725;

/// Frame width (QVGA).
pub const WIDTH: usize = 320;
/// Frame height (QVGA).
pub const HEIGHT: usize = 240;
/// 32-bit words of one captured luma frame.
pub const CAPTURE_WORDS: usize = WIDTH * HEIGHT / 4;

/// `DCMI_CR.BSM` (bits 17:16) = `01`: capture every other byte. The DCMI driver has no
/// setting for it (nor does the register description of the PAC, which follows the older
/// DCMI without it), so it is set on the raw register value (RM0433, "DCMI control register").
const CR_BSM_EVERY_OTHER_BYTE: u32 = 0b01 << 16;
/// `DCMI_CR.OEBS` (bit 18): 0 = keep the first byte of each pair (the luma).
const CR_OEBS: u32 = 1 << 18;

/// What can go wrong reading a frame.
#[derive(Debug, defmt::Format)]
pub enum CameraError<E> {
    /// The sensor's control bus.
    Sensor(ov7725::Error<E>),
    /// The capture: DCMI overrun (the DMA fell behind) or a synchronisation error.
    Capture(dcmi::Error),
    /// The caller's frame is not [`WIDTH`] x [`HEIGHT`].
    FrameSize,
}

/// The camera as a [`FrameSource`] of 320x240 grayscale frames.
pub struct Camera<'d, I2C> {
    sensor: Ov7725<I2C>,
    dcmi: Dcmi<'d, DCMI>,
    capture: &'d mut [u32; CAPTURE_WORDS],
}

impl<'d, I2C: I2c> Camera<'d, I2C> {
    /// Sets the sensor up for QVGA YUV422 and the DCMI for luma-only capture into `capture`
    /// (which must be DMA-reachable: AXI SRAM, see `memory.x`). `XCLK` must already run: the
    /// sensor does not answer on I2C without it.
    pub fn new(
        i2c: I2C,
        dcmi: Dcmi<'d, DCMI>,
        capture: &'d mut [u32; CAPTURE_WORDS],
        delay: &mut impl embedded_hal::delay::DelayNs,
    ) -> Result<Self, CameraError<I2C::Error>> {
        let mut sensor = Ov7725::new(i2c);
        let id = sensor
            .init(ov7725::Resolution::Qvga, delay)
            .map_err(CameraError::Sensor)?;
        defmt::info!(
            "camera: OV7725 (PID {=u8:#x}, VER {=u8:#x}), QVGA YUV422",
            id.pid,
            id.ver
        );
        embassy_stm32::pac::DCMI.cr().modify(|w| {
            w.0 = (w.0 & !(0b11 << 16) & !CR_OEBS) | CR_BSM_EVERY_OTHER_BYTE;
        });
        Ok(Self {
            sensor,
            dcmi,
            capture,
        })
    }

    /// The sensor, for exposure, gain, mirror/flip, clock changes.
    pub fn sensor(&mut self) -> &mut Ov7725<I2C> {
        &mut self.sensor
    }
}

impl<I2C: I2c> FrameSource for Camera<'_, I2C> {
    type Error = CameraError<I2C::Error>;

    fn size(&self) -> (usize, usize) {
        (WIDTH, HEIGHT)
    }

    /// Captures the next whole frame (waits for its VSYNC; at most two frame periods) and
    /// copies it into `frame` (76 800 bytes: tens of microseconds at 480 MHz).
    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, Self::Error> {
        if (frame.width(), frame.height()) != (WIDTH, HEIGHT) {
            return Err(CameraError::FrameSize);
        }
        // Nothing else runs meanwhile: the DCMI and DMA interrupts wake this future.
        embassy_futures::block_on(self.dcmi.capture(&mut self.capture[..]))
            .map_err(CameraError::Capture)?;
        for (y, words) in self.capture.chunks_exact(WIDTH / 4).enumerate() {
            let row = frame.row_mut(y).ok_or(CameraError::FrameSize)?;
            for (px, word) in row.chunks_exact_mut(4).zip(words) {
                px.copy_from_slice(&word.to_le_bytes());
            }
        }
        Ok(true)
    }
}
