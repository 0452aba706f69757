//! The exact SCCB transactions of every driver call, against a mocked bus.
//!
//! Expected register addresses and values are spelled out as literal numbers (from the OV7725
//! datasheet's register table), not taken from the driver's constants, so a wrong constant
//! fails here. Run on the host:
//! `cargo test -p ov7725 --target x86_64-unknown-linux-gnu --features host-tests`.

use embedded_hal::i2c::ErrorKind;
use embedded_hal_mock::eh1::delay::{CheckedDelay, NoopDelay, Transaction as Delay};
use embedded_hal_mock::eh1::i2c::{Mock, Transaction as T};
use ov7725::{ChipId, Error, Ov7725, Pll, Resolution};

const A: u8 = 0x21;

/// A register write: one I2C write of `[register, value]`.
fn w(register: u8, value: u8) -> T {
    T::write(A, vec![register, value])
}

/// A register read: write `[register]`, stop, read one byte.
fn r(register: u8, value: u8) -> [T; 2] {
    [T::write(A, vec![register]), T::read(A, vec![value])]
}

fn check(expected: &[T], f: impl FnOnce(&mut Ov7725<Mock>)) {
    let mock = Mock::new(expected);
    let mut cam = Ov7725::new(mock);
    f(&mut cam);
    cam.release().done();
}

/// Identification of a real OV7725: PID 0x77 at 0x0A, VER 0x21 at 0x0B.
fn ident() -> Vec<T> {
    [r(0x0A, 0x77), r(0x0B, 0x21)].concat()
}

#[test]
fn identify_ov7725() {
    check(&ident(), |cam| {
        assert_eq!(
            cam.identify(),
            Ok(ChipId {
                pid: 0x77,
                ver: 0x21
            })
        );
    });
}

#[test]
fn identify_wrong_chip() {
    // An OV7670 (PID 0x76, VER 0x73) answering at the same address.
    let t = [r(0x0A, 0x76), r(0x0B, 0x73)].concat();
    check(&t, |cam| {
        assert_eq!(
            cam.identify(),
            Err(Error::WrongChip {
                pid: 0x76,
                ver: 0x73
            })
        );
    });
    // The OV7720 differs only in its version byte.
    let t = [r(0x0A, 0x77), r(0x0B, 0x20)].concat();
    check(&t, |cam| {
        assert_eq!(
            cam.identify(),
            Err(Error::WrongChip {
                pid: 0x77,
                ver: 0x20
            })
        );
    });
}

#[test]
fn identify_no_acknowledge() {
    // Nothing on the bus (or no XCLK): the address write is not acknowledged, and the driver
    // stops there.
    let t = [T::write(A, vec![0x0A]).with_error(ErrorKind::Other)];
    check(&t, |cam| {
        assert_eq!(cam.identify(), Err(Error::Bus(ErrorKind::Other)));
    });
}

#[test]
fn reset_writes_com7_and_waits() {
    check(&[w(0x12, 0x80)], |cam| {
        let mut delay = CheckedDelay::new(&[Delay::delay_ms(2)]);
        assert_eq!(cam.reset(&mut delay), Ok(()));
        delay.done();
    });
}

/// Everything `init` writes after the reset, before the output size.
fn init_body() -> Vec<T> {
    [
        (0x12, 0x40), // COM7: QVGA, YUV
        (0x3D, 0x03), // COM12
        (0x17, 0x3F), // HSTART
        (0x18, 0x50), // HSIZE: 320 / 4
        (0x19, 0x03), // VSTART
        (0x1A, 0x78), // VSIZE: 240 / 2
        (0x32, 0x00), // HREF
        (0x11, 0xC0), // CLKRC: no prescaler
        (0x0D, 0x41), // COM4: PLL x4
        (0x42, 0x7F), // TGT_B
        (0x4D, 0x09), // FIXGAIN
        (0x63, 0xE0), // AWB_CTRL0
        (0x64, 0xFF), // DSP_CTRL1
        (0x65, 0x2F), // DSP_CTRL2: DCW and zoom-out on
        (0x66, 0x00), // DSP_CTRL3
        (0x67, 0x00), // DSP_CTRL4: YUV/RGB output
        (0xAC, 0xFF), // DSPAUTO
        (0x0F, 0xC5), // COM6
        (0x14, 0x11), // COM9: 4x gain ceiling
        (0x22, 0x7F), // BDBASE
        (0x23, 0x03), // BDSTEP
        (0x24, 0x40), // AEW
        (0x25, 0x30), // AEB
        (0x26, 0xA1), // VPT
        (0x2B, 0x00), // EXHCL
        (0x6B, 0xAA), // AWB_CTRL3
        (0x0E, 0x65), // COM5: auto frame rate off
        (0x13, 0xFF), // COM8: AEC, AGC, AWB, banding on
        (0x90, 0x05), // EDGE1
        (0x91, 0x01), // DNSOFF
        (0x92, 0x03), // EDGE2
        (0x93, 0x00), // EDGE3
        (0x9B, 0x08), // BRIGHTNESS
        (0x9C, 0x20), // CONTRAST
        (0xA6, 0x06), // SDE
        (0x33, 0x00), // DM_LNL
        (0x7E, 0x0C), // GAM1 ..
        (0x7F, 0x16),
        (0x80, 0x2A),
        (0x81, 0x4E),
        (0x82, 0x61),
        (0x83, 0x6F),
        (0x84, 0x7B),
        (0x85, 0x86),
        (0x86, 0x8E),
        (0x87, 0x97),
        (0x88, 0xA4),
        (0x89, 0xAF),
        (0x8A, 0xC5),
        (0x8B, 0xD7),
        (0x8C, 0xE8), // .. GAM15
        (0x8D, 0x20), // SLOP
    ]
    .into_iter()
    .map(|(reg, val)| w(reg, val))
    .collect()
}

#[test]
fn init_qvga() {
    let mut t = ident();
    t.push(w(0x12, 0x80));
    t.extend(init_body());
    // HOUTSIZE = 320 >> 2 = 0x50, VOUTSIZE = 240 >> 1 = 0x78, no LSBs.
    t.extend([w(0x29, 0x50), w(0x2C, 0x78), w(0x2A, 0x00)]);
    check(&t, |cam| {
        let mut delay = CheckedDelay::new(&[Delay::delay_ms(2)]);
        assert_eq!(
            cam.init(Resolution::Qvga, &mut delay),
            Ok(ChipId {
                pid: 0x77,
                ver: 0x21
            })
        );
        delay.done();
    });
}

#[test]
fn init_qqvga() {
    let mut t = ident();
    t.push(w(0x12, 0x80));
    t.extend(init_body());
    // HOUTSIZE = 160 >> 2 = 0x28, VOUTSIZE = 120 >> 1 = 0x3C.
    t.extend([w(0x29, 0x28), w(0x2C, 0x3C), w(0x2A, 0x00)]);
    check(&t, |cam| {
        assert!(cam.init(Resolution::Qqvga, &mut NoopDelay::new()).is_ok());
    });
}

#[test]
fn init_stops_at_wrong_chip_without_writing() {
    // Nothing is written to a chip that is not an OV7725.
    let t = [r(0x0A, 0x26), r(0x0B, 0x42)].concat();
    check(&t, |cam| {
        assert_eq!(
            cam.init(Resolution::Qvga, &mut NoopDelay::new()),
            Err(Error::WrongChip {
                pid: 0x26,
                ver: 0x42
            })
        );
    });
}

#[test]
fn init_stops_at_first_bus_error() {
    // The tenth register write fails: nothing after it is attempted.
    let mut t = ident();
    t.push(w(0x12, 0x80));
    let body = init_body();
    t.extend(body.iter().take(9).cloned());
    t.push(body[9].clone().with_error(ErrorKind::NoAcknowledge(
        embedded_hal::i2c::NoAcknowledgeSource::Data,
    )));
    check(&t, |cam| {
        assert_eq!(
            cam.init(Resolution::Qvga, &mut NoopDelay::new()),
            Err(Error::Bus(ErrorKind::NoAcknowledge(
                embedded_hal::i2c::NoAcknowledgeSource::Data
            )))
        );
    });
}

#[test]
fn set_resolution_writes_output_size() {
    check(&[w(0x29, 0x28), w(0x2C, 0x3C), w(0x2A, 0x00)], |cam| {
        assert_eq!(cam.set_resolution(Resolution::Qqvga), Ok(()));
    });
}

#[test]
fn mirror_and_flip_modify_com3() {
    // COM3 reads 0x10 (YUV swap bit set by someone): kept, bits 6 and 7 set.
    let t = [r(0x0C, 0x10).to_vec(), vec![w(0x0C, 0xD0)]].concat();
    check(&t, |cam| {
        assert_eq!(cam.set_mirror_flip(true, true), Ok(()))
    });
    // Mirror only: bit 7 cleared.
    let t = [r(0x0C, 0xD0).to_vec(), vec![w(0x0C, 0x50)]].concat();
    check(&t, |cam| {
        assert_eq!(cam.set_mirror_flip(true, false), Ok(()))
    });
    // Neither.
    let t = [r(0x0C, 0xD0).to_vec(), vec![w(0x0C, 0x10)]].concat();
    check(&t, |cam| {
        assert_eq!(cam.set_mirror_flip(false, false), Ok(()))
    });
}

#[test]
fn auto_exposure_and_gain_toggle_com8_bits() {
    let t = [r(0x13, 0xFF).to_vec(), vec![w(0x13, 0xFE)]].concat();
    check(&t, |cam| assert_eq!(cam.set_auto_exposure(false), Ok(())));
    let t = [r(0x13, 0xFE).to_vec(), vec![w(0x13, 0xFF)]].concat();
    check(&t, |cam| assert_eq!(cam.set_auto_exposure(true), Ok(())));
    let t = [r(0x13, 0xFF).to_vec(), vec![w(0x13, 0xFB)]].concat();
    check(&t, |cam| assert_eq!(cam.set_auto_gain(false), Ok(())));
    let t = [r(0x13, 0xFB).to_vec(), vec![w(0x13, 0xFF)]].concat();
    check(&t, |cam| assert_eq!(cam.set_auto_gain(true), Ok(())));
}

#[test]
fn manual_exposure_disables_aec_then_writes_both_halves() {
    // 0x1234 rows: AEC (0x10) = 0x34, AECH (0x08) = 0x12.
    let t = [
        r(0x13, 0xFF).to_vec(),
        vec![w(0x13, 0xFE), w(0x10, 0x34), w(0x08, 0x12)],
    ]
    .concat();
    check(&t, |cam| assert_eq!(cam.set_exposure(0x1234), Ok(())));
}

#[test]
fn pll_modifies_com4_top_bits() {
    // COM4 = 0x41 (x4, with bit 0 set): x8 keeps bit 0.
    let t = [r(0x0D, 0x41).to_vec(), vec![w(0x0D, 0xC1)]].concat();
    check(&t, |cam| assert_eq!(cam.set_pll(Pll::X8), Ok(())));
    let t = [r(0x0D, 0xC1).to_vec(), vec![w(0x0D, 0x01)]].concat();
    check(&t, |cam| assert_eq!(cam.set_pll(Pll::Bypass), Ok(())));
}

#[test]
fn clock_divider_values() {
    check(&[w(0x11, 0xC0)], |cam| {
        assert_eq!(cam.set_clock_divider(1), Ok(()))
    });
    // Divide by 2 (n + 1): 2 -> 0, 4 -> 1, 128 -> 63; bit 7 kept set.
    check(&[w(0x11, 0x80)], |cam| {
        assert_eq!(cam.set_clock_divider(2), Ok(()))
    });
    check(&[w(0x11, 0x81)], |cam| {
        assert_eq!(cam.set_clock_divider(4), Ok(()))
    });
    check(&[w(0x11, 0xBF)], |cam| {
        assert_eq!(cam.set_clock_divider(128), Ok(()))
    });
    // Out of range: nothing on the bus.
    for bad in [0, 3, 5, 127, 130, 255] {
        check(&[], |cam| {
            assert_eq!(cam.set_clock_divider(bad), Err(Error::InvalidArgument));
        });
    }
}

#[test]
fn read_error_on_data_phase() {
    // The address write succeeds, the read fails: the modify does not write.
    let t = [
        T::write(A, vec![0x13]),
        T::read(A, vec![0x00]).with_error(ErrorKind::ArbitrationLoss),
    ];
    check(&t, |cam| {
        assert_eq!(
            cam.set_auto_gain(true),
            Err(Error::Bus(ErrorKind::ArbitrationLoss))
        );
    });
}
