//! A `#![no_std]` register driver for the OmniVision OV7725 VGA camera sensor, over its SCCB
//! control bus through any [`embedded_hal::i2c::I2c`] (embedded-hal 1.0).
//!
//! The OV7725 is the camera of the OpenMV Cam H7 (and many other boards): a 640x480 sensor
//! with an on-chip DSP that outputs YUV422, RGB or raw Bayer on an 8-bit parallel bus (DCMI on
//! an STM32). This driver only talks to its registers; the pixel bus is the board's business.
//! It sets the sensor up for what camgeom needs: **YUV422 at QVGA (320x240) or QQVGA
//! (160x120)**, of which a board keeps only the luma bytes (the sensor sends `Y U Y V ...`, so
//! every even byte of a line is a grayscale pixel; an STM32 DCMI can drop the odd bytes in
//! hardware).
//!
//! # SCCB over I2C
//!
//! SCCB is OmniVision's I2C-like bus. With 7-bit address [`ADDRESS`] (`0x21`, i.e. `0x42` to
//! write and `0x43` to read on the wire), a register write is one I2C write of
//! `[register, value]`, and a register read is a write of `[register]` **followed by a stop**
//! and a separate one-byte read. The separate read (rather than I2C's repeated-start
//! `write_read`) is what the SCCB specification describes and what every OV sensor accepts.
//!
//! # Clocks and frame rate
//!
//! The sensor runs from an external clock `XCLK` (12 MHz on the OpenMV Cam H7). Its internal
//! clock is
//!
//! ```text
//! f_int = XCLK · PLL / divider      PLL ∈ {1, 4, 6, 8} (COM4[7:6]),
//!                                   divider = 1 (CLKRC[6] set) or 2 (CLKRC[5:0] + 1)
//! ```
//!
//! and every timing of the sensor (pixel clock, line and frame period, exposure) scales with
//! `1 / f_int`: halving `f_int` halves the frame rate. [`Ov7725::init`] leaves `PLL = 4`,
//! `divider = 1` (48 MHz from a 12 MHz `XCLK`); [`Ov7725::set_pll`] and
//! [`Ov7725::set_clock_divider`] lower it, e.g. when the consumer cannot keep up.
//!
//! # Exposure
//!
//! The exposure is counted in row periods, 16 bits: `AEC[15:8]` in register `AECH` (`0x08`),
//! `AEC[7:0]` in register `AEC` (`0x10`). With automatic exposure on (the default) the sensor
//! writes them itself; [`Ov7725::set_exposure`] turns it off and sets them.
#![no_std]
#![deny(missing_docs)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

use embedded_hal::delay::DelayNs;
use embedded_hal::i2c::I2c;

/// The sensor's 7-bit SCCB address.
pub const ADDRESS: u8 = 0x21;

/// Product ID, register [`reg::PID`].
pub const PID_OV7725: u8 = 0x77;
/// Version, register [`reg::VER`] (the OV7720 reads `0x20` here).
pub const VER_OV7725: u8 = 0x21;

/// Register addresses (OV7725 datasheet, "register set"). Only the ones this driver or a
/// user is likely to touch; [`Ov7725::read_register`] and [`Ov7725::write_register`] reach
/// the others.
pub mod reg {
    /// AGC gain (`[7:4]` coarse steps of 2x, `[3:0]` fine `1 + n/16`).
    pub const GAIN: u8 = 0x00;
    /// Exposure `AEC[15:8]`.
    pub const AECH: u8 = 0x08;
    /// Common control 2: soft sleep, output drive.
    pub const COM2: u8 = 0x09;
    /// Product ID MSB (`0x77`).
    pub const PID: u8 = 0x0A;
    /// Product ID LSB, the version (`0x21`).
    pub const VER: u8 = 0x0B;
    /// Common control 3: vertical flip, horizontal mirror, byte swaps, colour bar.
    pub const COM3: u8 = 0x0C;
    /// Common control 4: PLL multiplier `[7:6]`, AEC window `[5:4]`.
    pub const COM4: u8 = 0x0D;
    /// Common control 5: auto frame rate (night mode).
    pub const COM5: u8 = 0x0E;
    /// Common control 6: auto window on format change.
    pub const COM6: u8 = 0x0F;
    /// Exposure `AEC[7:0]`.
    pub const AEC: u8 = 0x10;
    /// Internal clock: `[6]` use `XCLK` directly, `[5:0]` prescaler.
    pub const CLKRC: u8 = 0x11;
    /// Common control 7: reset `[7]`, QVGA `[6]`, output format `[1:0]`.
    pub const COM7: u8 = 0x12;
    /// Common control 8: AEC `[0]`, AWB `[1]`, AGC `[2]`, banding filter, fast AEC/AGC.
    pub const COM8: u8 = 0x13;
    /// Common control 9: gain ceiling `[6:4]`, drop corrupt frames.
    pub const COM9: u8 = 0x14;
    /// Common control 10: sync and pixel-clock polarities, output range.
    pub const COM10: u8 = 0x15;
    /// Sensor window horizontal start, 8 MSBs (units of 4 pixels).
    pub const HSTART: u8 = 0x17;
    /// Sensor window width, 8 MSBs (units of 4 pixels).
    pub const HSIZE: u8 = 0x18;
    /// Sensor window vertical start, 8 MSBs (units of 2 rows).
    pub const VSTART: u8 = 0x19;
    /// Sensor window height, 8 MSBs (units of 2 rows).
    pub const VSIZE: u8 = 0x1A;
    /// Manufacturer ID high byte (`0x7F`).
    pub const MIDH: u8 = 0x1C;
    /// Manufacturer ID low byte (`0xA2`).
    pub const MIDL: u8 = 0x1D;
    /// Banding filter minimum AEC value.
    pub const BDBASE: u8 = 0x22;
    /// Banding filter maximum step.
    pub const BDSTEP: u8 = 0x23;
    /// AEC/AGC stable region, upper limit.
    pub const AEW: u8 = 0x24;
    /// AEC/AGC stable region, lower limit.
    pub const AEB: u8 = 0x25;
    /// AEC/AGC fast-mode region.
    pub const VPT: u8 = 0x26;
    /// Output width, 8 MSBs (units of 4 pixels; 2 LSBs in `EXHCH[1:0]`).
    pub const HOUTSIZE: u8 = 0x29;
    /// Output size LSBs (`[1:0]` width, `[2]` height) and dummy-pixel MSBs.
    pub const EXHCH: u8 = 0x2A;
    /// Dummy pixels LSBs.
    pub const EXHCL: u8 = 0x2B;
    /// Output height, 8 MSBs (units of 2 rows; LSB in `EXHCH[2]`).
    pub const VOUTSIZE: u8 = 0x2C;
    /// Window LSBs: `HSTART[5:4]`, `VSTART[6]`, `VSIZE[2]`, `HSIZE[1:0]`.
    pub const HREF: u8 = 0x32;
    /// Dummy rows, low byte.
    pub const DM_LNL: u8 = 0x33;
    /// Analog DC offset compensation.
    pub const COM12: u8 = 0x3D;
    /// Black-level target, blue channel.
    pub const TGT_B: u8 = 0x42;
    /// Analog fixed-gain amplifier.
    pub const FIXGAIN: u8 = 0x4D;
    /// AWB control 0.
    pub const AWB_CTRL0: u8 = 0x63;
    /// DSP control 1: enables of the DSP blocks.
    pub const DSP_CTRL1: u8 = 0x64;
    /// DSP control 2: down-sampling (DCW) and zoom-out scaling enables.
    pub const DSP_CTRL2: u8 = 0x65;
    /// DSP control 3: UV order, colour bar.
    pub const DSP_CTRL3: u8 = 0x66;
    /// DSP control 4: output select (YUV/RGB or raw).
    pub const DSP_CTRL4: u8 = 0x67;
    /// AWB control 3.
    pub const AWB_CTRL3: u8 = 0x6B;
    /// Gamma curve, first of 15 segment end points (`GAM1..GAM15` = `0x7E..=0x8C`).
    pub const GAM1: u8 = 0x7E;
    /// Gamma curve, highest segment slope.
    pub const SLOP: u8 = 0x8D;
    /// Edge enhancement threshold.
    pub const EDGE1: u8 = 0x90;
    /// Auto de-noise threshold.
    pub const DNSOFF: u8 = 0x91;
    /// Edge enhancement strength upper limit.
    pub const EDGE2: u8 = 0x92;
    /// Edge enhancement strength lower limit.
    pub const EDGE3: u8 = 0x93;
    /// Brightness.
    pub const BRIGHTNESS: u8 = 0x9B;
    /// Contrast gain.
    pub const CONTRAST: u8 = 0x9C;
    /// Special digital effects enables.
    pub const SDE: u8 = 0xA6;
    /// DSP auto functions (automatic scaling factors, ...).
    pub const DSPAUTO: u8 = 0xAC;
}

/// Register bits used by the driver.
pub mod bits {
    /// `COM3`: vertical flip.
    pub const COM3_VFLIP: u8 = 0x80;
    /// `COM3`: horizontal mirror.
    pub const COM3_MIRROR: u8 = 0x40;
    /// `COM4`: PLL multiplier field `[7:6]`.
    pub const COM4_PLL_MASK: u8 = 0xC0;
    /// `CLKRC`: reserved bit 7, reads 1 after reset and is written back as 1.
    pub const CLKRC_RESERVED: u8 = 0x80;
    /// `CLKRC`: use the external clock directly (no prescaler).
    pub const CLKRC_NO_PRESCALE: u8 = 0x40;
    /// `CLKRC`: prescaler field `[5:0]`: divide by `2 (n + 1)`.
    pub const CLKRC_PRESCALER_MASK: u8 = 0x3F;
    /// `COM7`: reset every register to its default (self-clearing).
    pub const COM7_RESET: u8 = 0x80;
    /// `COM7`: QVGA timing (320x240 sensor window, sub-sampled from VGA).
    pub const COM7_QVGA: u8 = 0x40;
    /// `COM7`: output format YUV (`[1:0] = 00`).
    pub const COM7_FMT_YUV: u8 = 0x00;
    /// `COM8`: fast AEC/AGC algorithm.
    pub const COM8_FAST_AUTO: u8 = 0x80;
    /// `COM8`: unlimited AEC step size.
    pub const COM8_AEC_STEP_UNLIMITED: u8 = 0x40;
    /// `COM8`: banding filter on.
    pub const COM8_BANDING: u8 = 0x20;
    /// `COM8`: AEC below the banding value allowed.
    pub const COM8_AEC_BELOW_BANDING: u8 = 0x10;
    /// `COM8`: fine (sub-row) AEC.
    pub const COM8_AEC_FINE: u8 = 0x08;
    /// `COM8`: automatic gain.
    pub const COM8_AGC: u8 = 0x04;
    /// `COM8`: automatic white balance.
    pub const COM8_AWB: u8 = 0x02;
    /// `COM8`: automatic exposure.
    pub const COM8_AEC: u8 = 0x01;
    /// `DSP_CTRL2`: vertical down-sampling, horizontal down-sampling, vertical zoom-out,
    /// horizontal zoom-out (the DSP scales the window to `HOUTSIZE x VOUTSIZE`).
    pub const DSP_CTRL2_SCALE_ALL: u8 = 0x0F;
    /// `SDE`: contrast/brightness enable.
    pub const SDE_CONTRAST_BRIGHTNESS: u8 = 0x04;
    /// `SDE`: saturation enable.
    pub const SDE_SATURATION: u8 = 0x02;
}

/// What went wrong. `E` is the bus's error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error<E> {
    /// The SCCB (I2C) transaction failed: no acknowledge (no sensor, wrong address, no
    /// `XCLK`: the OV7725 does not answer without its clock), arbitration loss, ...
    Bus(E),
    /// Something answered at [`ADDRESS`] but it is not an OV7725: its product ID and version
    /// registers read `pid`, `ver` instead of `0x77`, `0x21`.
    WrongChip {
        /// What register [`reg::PID`] read.
        pid: u8,
        /// What register [`reg::VER`] read.
        ver: u8,
    },
    /// An argument out of the sensor's range (e.g. an odd clock divider).
    InvalidArgument,
}

/// Output sizes the driver sets up. Both use the sensor's QVGA timing; QQVGA is scaled down
/// by the DSP (down-sampling and zoom-out), so the field of view is the same.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Resolution {
    /// 320x240.
    Qvga,
    /// 160x120.
    Qqvga,
}

impl Resolution {
    /// Width in pixels.
    pub const fn width(self) -> u16 {
        match self {
            Self::Qvga => 320,
            Self::Qqvga => 160,
        }
    }

    /// Height in pixels.
    pub const fn height(self) -> u16 {
        match self {
            Self::Qvga => 240,
            Self::Qqvga => 120,
        }
    }

    /// Bytes of one YUV422 frame (2 per pixel); the luma alone is half of it.
    pub const fn yuv_bytes(self) -> usize {
        self.width() as usize * self.height() as usize * 2
    }
}

/// The PLL multiplier in `COM4[7:6]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Pll {
    /// PLL bypassed: `f_int = XCLK / divider`.
    Bypass,
    /// `XCLK x 4`.
    X4,
    /// `XCLK x 6`.
    X6,
    /// `XCLK x 8`.
    X8,
}

impl Pll {
    /// The multiplier.
    pub const fn factor(self) -> u32 {
        match self {
            Self::Bypass => 1,
            Self::X4 => 4,
            Self::X6 => 6,
            Self::X8 => 8,
        }
    }

    const fn bits(self) -> u8 {
        match self {
            Self::Bypass => 0x00,
            Self::X4 => 0x40,
            Self::X6 => 0x80,
            Self::X8 => 0xC0,
        }
    }
}

/// What the identification registers read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChipId {
    /// Product ID ([`reg::PID`]): `0x77`.
    pub pid: u8,
    /// Version ([`reg::VER`]): `0x21`.
    pub ver: u8,
}

/// Wait after a software reset before the registers are written (what the OpenMV firmware
/// waits).
pub const RESET_DELAY_MS: u32 = 2;

/// The register sequence [`Ov7725::init`] writes after the reset, before the output size.
///
/// Values from OmniVision's OV7725 application-note settings as the OpenMV firmware's driver
/// (`drivers/sensors/ov7725.c`) uses them, set here directly for YUV output at QVGA timing:
/// - QVGA sensor window: `HSTART = 0x3F`, `HSIZE = 0x50` (320 / 4), `VSTART = 0x03`,
///   `VSIZE = 0x78` (240 / 2), their LSBs in `HREF` all zero;
/// - clock: `CLKRC = 0xC0` (no prescaler), `COM4 = 0x41` (PLL x4, full AEC window):
///   48 MHz internal from a 12 MHz `XCLK`;
/// - DSP: every block on, scaling on (for QQVGA), YUV output;
/// - AEC, AGC and AWB on with the banding filter, 4x gain ceiling (`COM9 = 0x11`), auto
///   frame rate (night mode) off (`COM5 = 0x65`): the frame rate stays fixed in low light;
/// - the application note's gamma curve, edge enhancement and de-noise settings.
pub const INIT_SEQUENCE: [(u8, u8); 44] = [
    (reg::COM7, bits::COM7_QVGA | bits::COM7_FMT_YUV),
    (reg::COM12, 0x03),
    (reg::HSTART, 0x3F),
    (reg::HSIZE, 0x50),
    (reg::VSTART, 0x03),
    (reg::VSIZE, 0x78),
    (reg::HREF, 0x00),
    (reg::CLKRC, bits::CLKRC_RESERVED | bits::CLKRC_NO_PRESCALE),
    (reg::COM4, 0x41),
    (reg::TGT_B, 0x7F),
    (reg::FIXGAIN, 0x09),
    (reg::AWB_CTRL0, 0xE0),
    (reg::DSP_CTRL1, 0xFF),
    (reg::DSP_CTRL2, 0x20 | bits::DSP_CTRL2_SCALE_ALL),
    (reg::DSP_CTRL3, 0x00),
    (reg::DSP_CTRL4, 0x00),
    (reg::DSPAUTO, 0xFF),
    (reg::COM6, 0xC5),
    (reg::COM9, 0x11),
    (reg::BDBASE, 0x7F),
    (reg::BDSTEP, 0x03),
    (reg::AEW, 0x40),
    (reg::AEB, 0x30),
    (reg::VPT, 0xA1),
    (reg::EXHCL, 0x00),
    (reg::AWB_CTRL3, 0xAA),
    (reg::COM5, 0x65),
    (reg::COM8, 0xFF),
    (reg::EDGE1, 0x05),
    (reg::DNSOFF, 0x01),
    (reg::EDGE2, 0x03),
    (reg::EDGE3, 0x00),
    (reg::BRIGHTNESS, 0x08),
    (reg::CONTRAST, 0x20),
    (
        reg::SDE,
        bits::SDE_CONTRAST_BRIGHTNESS | bits::SDE_SATURATION,
    ),
    (reg::DM_LNL, 0x00),
    // Gamma: segment end points GAM1..GAM8 (the rest follow in `GAMMA_TAIL`).
    (reg::GAM1, 0x0C),
    (reg::GAM1 + 1, 0x16),
    (reg::GAM1 + 2, 0x2A),
    (reg::GAM1 + 3, 0x4E),
    (reg::GAM1 + 4, 0x61),
    (reg::GAM1 + 5, 0x6F),
    (reg::GAM1 + 6, 0x7B),
    (reg::GAM1 + 7, 0x86),
];

/// The end of [`Ov7725::init`]'s sequence: gamma end points GAM9..GAM15 and the slope.
pub const GAMMA_TAIL: [(u8, u8); 8] = [
    (reg::GAM1 + 8, 0x8E),
    (reg::GAM1 + 9, 0x97),
    (reg::GAM1 + 10, 0xA4),
    (reg::GAM1 + 11, 0xAF),
    (reg::GAM1 + 12, 0xC5),
    (reg::GAM1 + 13, 0xD7),
    (reg::GAM1 + 14, 0xE8),
    (reg::SLOP, 0x20),
];

/// An OV7725 on bus `I2C`.
#[derive(Debug)]
pub struct Ov7725<I2C> {
    i2c: I2C,
}

impl<I2C: I2c> Ov7725<I2C> {
    /// Wraps the bus; talks to nothing yet.
    pub const fn new(i2c: I2C) -> Self {
        Self { i2c }
    }

    /// Gives the bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }

    /// Reads one register: an SCCB 2-phase write of the address, a stop, then a 2-phase
    /// read of one byte.
    pub fn read_register(&mut self, register: u8) -> Result<u8, Error<I2C::Error>> {
        let mut value = [0u8];
        self.i2c.write(ADDRESS, &[register]).map_err(Error::Bus)?;
        self.i2c.read(ADDRESS, &mut value).map_err(Error::Bus)?;
        let [v] = value;
        Ok(v)
    }

    /// Writes one register (an SCCB 3-phase write).
    pub fn write_register(&mut self, register: u8, value: u8) -> Result<(), Error<I2C::Error>> {
        self.i2c
            .write(ADDRESS, &[register, value])
            .map_err(Error::Bus)
    }

    /// Read-modify-write: clears the bits of `mask`, then sets those of `value & mask`.
    pub fn modify_register(
        &mut self,
        register: u8,
        mask: u8,
        value: u8,
    ) -> Result<(), Error<I2C::Error>> {
        let old = self.read_register(register)?;
        self.write_register(register, (old & !mask) | (value & mask))
    }

    /// Reads the product ID and version and checks them: [`Error::WrongChip`] unless they are
    /// `0x77`, `0x21`.
    pub fn identify(&mut self) -> Result<ChipId, Error<I2C::Error>> {
        let pid = self.read_register(reg::PID)?;
        let ver = self.read_register(reg::VER)?;
        if pid == PID_OV7725 && ver == VER_OV7725 {
            Ok(ChipId { pid, ver })
        } else {
            Err(Error::WrongChip { pid, ver })
        }
    }

    /// Software reset: every register back to its default (`COM7[7]`), then waits
    /// [`RESET_DELAY_MS`].
    pub fn reset(&mut self, delay: &mut impl DelayNs) -> Result<(), Error<I2C::Error>> {
        self.write_register(reg::COM7, bits::COM7_RESET)?;
        delay.delay_ms(RESET_DELAY_MS);
        Ok(())
    }

    /// Identifies the chip, resets it and sets it up for YUV422 at `resolution`: writes
    /// [`INIT_SEQUENCE`], [`GAMMA_TAIL`], then [`Self::set_resolution`]. Automatic exposure,
    /// gain and white balance are on; no mirror or flip; 48 MHz internal clock from a 12 MHz
    /// `XCLK`.
    ///
    /// The first frames after this are still settling (exposure): the OpenMV firmware waits
    /// 300 ms; a tracker should simply skip a few frames.
    pub fn init(
        &mut self,
        resolution: Resolution,
        delay: &mut impl DelayNs,
    ) -> Result<ChipId, Error<I2C::Error>> {
        let id = self.identify()?;
        self.reset(delay)?;
        for (register, value) in INIT_SEQUENCE.into_iter().chain(GAMMA_TAIL) {
            self.write_register(register, value)?;
        }
        self.set_resolution(resolution)?;
        Ok(id)
    }

    /// Sets the output size: `HOUTSIZE = width / 4`, `VOUTSIZE = height / 2`, and their low
    /// bits in `EXHCH` (zero for both sizes here, which keeps `EXHCH`'s dummy-pixel bits at
    /// zero too). The sensor window stays QVGA; the DSP scales it.
    pub fn set_resolution(&mut self, resolution: Resolution) -> Result<(), Error<I2C::Error>> {
        let (w, h) = (resolution.width(), resolution.height());
        // Both fit: w / 4 <= 80, h / 2 <= 120.
        let [_, w_msb] = (w >> 2).to_be_bytes();
        let [_, h_msb] = (h >> 1).to_be_bytes();
        let [_, lsbs] = ((w & 0x3) | ((h & 0x1) << 2)).to_be_bytes();
        self.write_register(reg::HOUTSIZE, w_msb)?;
        self.write_register(reg::VOUTSIZE, h_msb)?;
        self.write_register(reg::EXHCH, lsbs)
    }

    /// Sets the PLL multiplier (`COM4[7:6]`, read-modify-write).
    pub fn set_pll(&mut self, pll: Pll) -> Result<(), Error<I2C::Error>> {
        self.modify_register(reg::COM4, bits::COM4_PLL_MASK, pll.bits())
    }

    /// Sets the clock divider after the PLL: 1 (no prescaler) or an even number from 2 to
    /// 128 (`CLKRC[5:0] = divider / 2 - 1`); the frame rate scales with `1 / divider`.
    /// [`Error::InvalidArgument`] for any other value.
    pub fn set_clock_divider(&mut self, divider: u8) -> Result<(), Error<I2C::Error>> {
        let value = match divider {
            1 => bits::CLKRC_RESERVED | bits::CLKRC_NO_PRESCALE,
            d if d >= 2 && d % 2 == 0 && d <= 128 => bits::CLKRC_RESERVED | (d / 2 - 1),
            _ => return Err(Error::InvalidArgument),
        };
        self.write_register(reg::CLKRC, value)
    }

    /// Horizontal mirror and vertical flip (`COM3[6]`, `COM3[7]`, read-modify-write).
    pub fn set_mirror_flip(&mut self, mirror: bool, flip: bool) -> Result<(), Error<I2C::Error>> {
        let value =
            if mirror { bits::COM3_MIRROR } else { 0 } | if flip { bits::COM3_VFLIP } else { 0 };
        self.modify_register(reg::COM3, bits::COM3_MIRROR | bits::COM3_VFLIP, value)
    }

    /// Automatic exposure on or off (`COM8[0]`). Off keeps the exposure the sensor last
    /// chose until [`Self::set_exposure`].
    pub fn set_auto_exposure(&mut self, on: bool) -> Result<(), Error<I2C::Error>> {
        self.modify_register(
            reg::COM8,
            bits::COM8_AEC,
            if on { bits::COM8_AEC } else { 0 },
        )
    }

    /// Automatic gain on or off (`COM8[2]`).
    pub fn set_auto_gain(&mut self, on: bool) -> Result<(), Error<I2C::Error>> {
        self.modify_register(
            reg::COM8,
            bits::COM8_AGC,
            if on { bits::COM8_AGC } else { 0 },
        )
    }

    /// Manual exposure of `rows` row periods: turns automatic exposure off, then writes
    /// `AEC[7:0]` to [`reg::AEC`] and `AEC[15:8]` to [`reg::AECH`].
    pub fn set_exposure(&mut self, rows: u16) -> Result<(), Error<I2C::Error>> {
        self.set_auto_exposure(false)?;
        let [hi, lo] = rows.to_be_bytes();
        self.write_register(reg::AEC, lo)?;
        self.write_register(reg::AECH, hi)
    }
}
