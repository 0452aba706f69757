//! camgeom on the OpenMV Cam H7 (STM32H743VI, OV7725): captures 320x240 grayscale frames,
//! finds an AprilTag in them (or, with the `card` feature, a card held in the middle of the
//! view) and tracks it, and sends one record per frame (state, pose, per-stage cycles) over
//! the micro-USB port ([`stream`]: a USB serial port, no debug probe needed); the RGB LED shows
//! searching, tracking or lost ([`led`]). With a probe, defmt also logs each frame over RTT.
//!
//! An autopilot on UART3 gets a MAVLink `HEARTBEAT` a second and a `LANDING_TARGET` for every
//! frame with a pose ([`autopilot`]). The host sends commands over the USB port (mode, tag,
//! camera, save; answered on the record stream); the settings they make are kept in a
//! reserved flash sector and loaded at boot ([`settings`]). In mode `stream-frames` each
//! frame's pixels go over USB too, before its record, for the host to show it with its
//! overlay (`camgeom monitor --frames-dir`). In mode `calibrate` the board calibrates its
//! camera from a chessboard shown to it ([`camgeom_fw_app::calibrate_mode`]; progress and
//! result on the record stream), saves a good camera to the flash and tracks with it.
//!
//! Board wiring, from the OpenMV firmware's board description (`boards/OPENMV4/
//! board_config.h` and `board_config.mk` in the openmv/openmv repository):
//!
//! | what | where |
//! |---|---|
//! | HSE crystal | 12 MHz |
//! | core clock | 480 MHz: PLL1 = 12 MHz / 3 x 240 / 2 (VOS0) |
//! | camera `XCLK` | PA8, TIM1 channel 1 PWM at 12 MHz |
//! | camera SCCB | I2C1: SCL PB8, SDA PB9, 100 kHz |
//! | camera power-down (`PWDN`, high = off) | PD7 |
//! | camera reset (`RESETB`, low = reset) | PA10 |
//! | DCMI data D0-D7 | PC6, PC7, PE0, PE1, PE4, PB6, PE5, PE6 |
//! | DCMI HSYNC, VSYNC, PIXCLK | PA4, PB7, PA6 |
//! | USB OTG FS (the micro-USB port) | D+ PA12, D- PA11, VBUS PA9; 48 MHz from HSI48 |
//! | RGB LED (active low; `mpconfigboard.h`) | red PC0, green PC1, blue PC2 |
//! | UART3 to an autopilot (header P4, P5) | TX PB10, RX PB11 (unused); TX by DMA1 stream 1 |
//! | settings | flash bank 2, sector 7 (`0x081E_0000`, 128 KiB), kept out of `memory.x` |
//!
//! (D5 is PB6 on this board, not the PD3 of ST's evaluation boards.)
#![no_std]
#![no_main]

mod autopilot;
mod camera;
mod led;
mod settings;
mod stream;
mod tracker;

use camgeom::apriltag::TagTarget;
use camgeom::image::ImageMut;
use camgeom::target::{Acquire, Stage};
use camgeom_fw_app::FrameSource;
use camgeom_fw_app::calibrate_mode::{Buffers, calibrate_mode};
use camgeom_fw_app::calibration::CalibError;
use camgeom_fw_app::command::{Ack, AckStatus, Mode};
use camgeom_fw_app::frame_chunk::send_frame;
use camgeom_fw_app::report::{ErrorCode, FrameRecord};
use camgeom_fw_app::settings::Settings;
use camgeom_fw_app::{AppError, Cost, FrameLoop, FrameReport};
use defmt_rtt as _;
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_stm32::flash::Flash;
use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::i2c::{self, I2c};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::usart::{self, UartTx};
use embassy_stm32::{Config, bind_interrupts, dcmi, dma, peripherals, usb};
use embassy_time::{Delay, Timer};
use panic_probe as _;
use static_cell::ConstStaticCell;

use crate::autopilot::MavlinkLink;
use crate::camera::{CAPTURE_WORDS, Camera};
use crate::led::Led;
use crate::settings::Store;
use crate::stream::{Incoming, RecordStream};
use crate::tracker::{DwtClock, Unfit};

bind_interrupts!(pub struct Irqs {
    DCMI => dcmi::InterruptHandler<peripherals::DCMI>;
    DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
    DMA1_STREAM1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    OTG_FS => usb::InterruptHandler<peripherals::USB_OTG_FS>;
});

/// The executor of the USB stack ([`stream::usb`]), run from the otherwise unused `UART4`
/// interrupt at a priority above thread mode: the tracking loop, which never yields, runs in
/// thread mode and is preempted whenever USB has work.
static USB_EXECUTOR: InterruptExecutor = InterruptExecutor::new();

#[interrupt]
unsafe fn UART4() {
    // SAFETY: `UART4` is this executor's interrupt (`USB_EXECUTOR.start(UART4)` in `main`)
    // and nothing else; the UART itself is never enabled.
    unsafe { USB_EXECUTOR.on_interrupt() }
}

/// Log the record stream's counts every this many frames (about 10 s at 30 fps).
const STREAM_LOG_EVERY: u32 = 300;

/// The camera's `XCLK`, as the OpenMV firmware drives it for the OV7725.
const XCLK_HZ: u32 = 12_000_000;

/// The DCMI's DMA target (AXI SRAM, see `memory.x`).
static CAPTURE: ConstStaticCell<[u32; CAPTURE_WORDS]> = ConstStaticCell::new([0; CAPTURE_WORDS]);

fn clocks() -> Config {
    use embassy_stm32::rcc::*;
    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse {
        freq: Hertz(12_000_000),
        mode: HseMode::Oscillator,
    });
    // 12 MHz / 3 = 4 MHz into the PLL (input range 4-8 MHz), x 240 = 960 MHz VCO, / 2.
    config.rcc.pll1 = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV3,
        mul: PllMul::MUL240,
        fracn: None,
        divp: Some(PllDiv::DIV2),
        divq: None,
        divr: None,
    });
    config.rcc.sys = Sysclk::PLL1_P; // 480 MHz
    config.rcc.ahb_pre = AHBPrescaler::DIV2; // 240 MHz: AXI, AHB
    config.rcc.apb1_pre = APBPrescaler::DIV2; // 120 MHz (timers 240 MHz)
    config.rcc.apb2_pre = APBPrescaler::DIV2; // 120 MHz (TIM1 at 240 MHz)
    config.rcc.apb3_pre = APBPrescaler::DIV2;
    config.rcc.apb4_pre = APBPrescaler::DIV2;
    // 480 MHz needs VOS0 (revision V silicon, which the OpenMV Cam H7 has); the H743 is
    // powered from its LDO (the reset default, as on the OpenMV Cam H7).
    config.rcc.voltage_scale = VoltageScale::Scale0;
    // USB's 48 MHz: HSI48 trimmed by the clock recovery system to the host's start-of-frame
    // packets, as the OpenMV firmware does (`OMV_OSC_USB_CLKSOURCE`).
    config.rcc.hsi48 = Some(Hsi48Config {
        sync_from_usb: true,
    });
    config.rcc.mux.usbsel = mux::Usbsel::HSI48;
    config
}

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let p = embassy_stm32::init(clocks());
    let mut core = cortex_m::Peripherals::take();
    if let Some(core) = core.as_mut() {
        // Instruction cache on; the data cache stays off, so the DMA-written frames need no
        // cache maintenance.
        core.SCB.enable_icache();
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();
    }
    defmt::info!("camgeom on OpenMV Cam H7: 480 MHz");
    let mut led = Led::new(p.PC0, p.PC1, p.PC2);

    // The settings saved in flash, else the compiled ones.
    let mut store = Store::new(Flash::new_blocking(p.FLASH));
    let mut settings = match store.load() {
        Some(s) if tracker::config(&s).is_ok() => {
            defmt::info!("settings: loaded from flash");
            s
        }
        Some(_) => {
            defmt::warn!("settings: those in flash give no configuration; the defaults");
            tracker::defaults()
        }
        None => tracker::defaults(),
    };

    // The record stream: USB runs from now on, whatever the camera does.
    interrupt::UART4.set_priority(Priority::P6);
    let usb_spawner = USB_EXECUTOR.start(interrupt::UART4);
    match stream::usb(p.USB_OTG_FS, p.PA12, p.PA11) {
        Ok(task) => usb_spawner.spawn(task),
        Err(e) => defmt::panic!("usb task: {}", e),
    }
    // MAVLink to an autopilot: UART3 TX on P4 (PB10), by DMA, on the same executor.
    let mut uart_config = usart::Config::default();
    uart_config.baudrate = autopilot::BAUD;
    match UartTx::new(p.USART3, p.PB10, p.DMA1_CH1, Irqs, uart_config) {
        Ok(tx) => match autopilot::uart(tx) {
            Ok(task) => usb_spawner.spawn(task),
            Err(e) => defmt::panic!("uart task: {}", e),
        },
        Err(e) => defmt::panic!("UART3: {}", e),
    }

    // Camera power and reset: PWDN low (on), RESETB pulsed low.
    let _pwdn = Output::new(p.PD7, Level::Low, Speed::Low);
    let mut reset = Output::new(p.PA10, Level::Low, Speed::Low);
    // XCLK: TIM1 runs at 240 MHz, so 12 MHz is an exact divide by 20.
    let mut xclk = SimplePwm::new(
        p.TIM1,
        Some(PwmPin::new(p.PA8, OutputType::PushPull)),
        None,
        None,
        None,
        Hertz(XCLK_HZ),
        CountingMode::EdgeAlignedUp,
    );
    let mut ch1 = xclk.ch1();
    ch1.set_duty_cycle_fraction(1, 2);
    ch1.enable();
    Timer::after_millis(10).await;
    reset.set_high();
    Timer::after_millis(10).await;

    let mut i2c_config = i2c::Config::default();
    i2c_config.frequency = Hertz(100_000);
    let sccb = I2c::new_blocking(p.I2C1, p.PB8, p.PB9, i2c_config);
    let dcmi = dcmi::Dcmi::new_8bit(
        p.DCMI,
        p.DMA1_CH0,
        Irqs,
        p.PC6,
        p.PC7,
        p.PE0,
        p.PE1,
        p.PE4,
        p.PB6,
        p.PE5,
        p.PE6,
        p.PB7,
        p.PA4,
        p.PA6,
        dcmi::Config::default(),
    );
    let mut cam = match Camera::new(sccb, dcmi, CAPTURE.take(), &mut Delay) {
        Ok(c) => c,
        Err(e) => defmt::panic!("camera set-up failed: {}", e),
    };
    // Let automatic exposure settle (the OpenMV firmware waits 300 ms too).
    Timer::after_millis(300).await;
    let exposure = cam.sensor().read_register(ov7725::reg::AEC).and_then(|lo| {
        let hi = cam.sensor().read_register(ov7725::reg::AECH)?;
        Ok(u16::from_be_bytes([hi, lo]))
    });
    match exposure {
        Ok(rows) => defmt::info!("camera: exposure settled at {=u16} rows", rows),
        Err(e) => defmt::warn!("camera: cannot read the exposure: {}", e),
    }

    let app = tracker::pipeline();
    let workspace = tracker::workspace();
    let (board_detector, board_scratch, calibrator) = tracker::calibrate_buffers();
    let mut clock = DwtClock::default();
    let mut records = RecordStream::default();
    let mut autopilot = MavlinkLink::new();
    // Frames are numbered as the camera is asked for them, across configurations.
    let mut index = 0u32;
    loop {
        if settings.mode == Mode::Calibrate {
            let buffers = Buffers {
                detector: &mut *board_detector,
                scratch: &mut *board_scratch,
                calibrator: &mut *calibrator,
            };
            let pending = calibrate(
                &mut *app,
                &mut cam,
                buffers,
                &mut settings,
                &mut store,
                &mut records,
                &mut clock,
            );
            if let Some(incoming) = pending {
                let mut restart = false;
                let (kind, status) = command(incoming, &mut settings, &mut store, &mut restart);
                records.send(
                    &Ack {
                        seq: incoming.seq,
                        kind,
                        status,
                    }
                    .encode(),
                );
            }
            continue;
        }
        // One configuration, built from the settings (checked before they were taken) and run
        // until a command changes them; then the target starts again on the next frame.
        let (cfg, options) = match tracker::config(&settings) {
            Ok(c) => c,
            Err(e) => defmt::panic!("configuration: {}", e),
        };
        let tag_spec = match tracker::tag(&options) {
            Ok(t) => t,
            Err(e) => defmt::panic!("tag detector: {}", e),
        };
        let (mut tag, mut card);
        let acquire: &mut dyn Acquire = match &tag_spec {
            Some(t) => {
                tag = TagTarget::new(&t.detector, workspace.as_mut_view(), t.family, t.id);
                &mut tag
            }
            None => {
                card = tracker::card();
                &mut card
            }
        };
        defmt::info!("settings: {}", settings);
        // In stream-frames mode each frame's pixels go before its record, after the settings
        // the host draws the overlay with.
        let streaming = settings.mode == Mode::StreamFrames;
        let settings_record = settings.encode();
        app.reset();
        led.show(app.state());
        loop {
            let record = match app.step(&cfg, &mut cam, acquire, &mut clock, &mut |_, _| {}) {
                Ok(Some(r)) => {
                    log(&r);
                    FrameRecord {
                        index,
                        ..FrameRecord::of(&r)
                    }
                }
                // The configuration does not fit the buffers: nothing to run.
                Err(e @ AppError::Geometry) => defmt::panic!("start: {=str}", e.name()),
                // A camera never ends.
                Ok(None) => continue,
                // A failed capture (or a frame the core rejects) leaves the pipeline as it
                // was: go on with the next frame.
                Err(e) => {
                    tracker::log_error("frame", &e);
                    FrameRecord::failed(index, app.state(), ErrorCode::of(&e))
                }
            };
            led.show(record.state);
            if streaming && record.error.is_none() {
                stream_pixels(&mut records, &mut *app, index, &settings_record);
            }
            records.send(&record.encode());
            autopilot.frame(&record, options.target_size);
            index = index.wrapping_add(1);
            if index.is_multiple_of(STREAM_LOG_EVERY) {
                defmt::info!(
                    "record stream: {=u32} frames queued for USB, {=u32} dropped (queue full), {=u32} discarded (port closed); {=u32} commands dropped",
                    records.queued(),
                    records.dropped(),
                    records.discarded(),
                    stream::commands_dropped()
                );
                autopilot.log();
            }
            // Commands, between frames.
            let mut restart = false;
            while let Some(incoming) = stream::next_command() {
                let (kind, status) = command(incoming, &mut settings, &mut store, &mut restart);
                defmt::info!(
                    "command {=u16}: kind {=u32}, {=str}",
                    incoming.seq,
                    kind,
                    status.name()
                );
                let ack = Ack {
                    seq: incoming.seq,
                    kind,
                    status,
                };
                records.send(&ack.encode());
            }
            if restart {
                break;
            }
        }
    }
}

/// How long a record of a streamed frame waits for room in the USB queue before the rest of
/// the frame is dropped (no host reading: the USB task discards, so this is an unplugged cable
/// or a host that stopped reading).
const PIXELS_PATIENCE: embassy_time::Duration = embassy_time::Duration::from_millis(50);

/// Sends the latest frame's pixels (the settings first) before its record: stops at the
/// first record the USB queue did not take in time, and the host counts the frame incomplete.
fn stream_pixels(
    records: &mut RecordStream,
    app: &mut impl FrameLoop,
    index: u32,
    settings: &[u8],
) {
    if !records.send_waiting(settings, PIXELS_PATIENCE) {
        return;
    }
    let mut stalled = false;
    let sent = app.with_latest(|img| {
        send_frame(index, img, |chunk| {
            if !stalled {
                stalled = !records.send_waiting(chunk, PIXELS_PATIENCE);
            }
        })
    });
    if let Some(Err(e)) = sent {
        defmt::warn!("frame {=u32}: {}", index, e);
    }
}

/// Carries out a command from the host: its kind and how it went. A change is checked by
/// building its configuration first (a mode this firmware does not have is `Unsupported`, a
/// camera or target it refuses `Invalid`); a change that takes sets `restart`.
fn command(
    incoming: Incoming,
    settings: &mut Settings,
    store: &mut Store,
    restart: &mut bool,
) -> (u32, AckStatus) {
    let Some(c) = incoming.command else {
        return (0, AckStatus::Invalid);
    };
    let before = *settings;
    let fits = |s: &Settings| match tracker::config(s) {
        Err(Unfit::Mode) if s.mode == Mode::Calibrate => Ok(()),
        Err(Unfit::Mode) => Err(AckStatus::Unsupported),
        Err(Unfit::Config(e)) => {
            defmt::warn!("command {=u16}: {}", incoming.seq, e);
            Err(AckStatus::Invalid)
        }
        Ok(_) => Ok(()),
    };
    let status = settings.carry_out(&c, fits, |s| {
        store.save(s).inspect_err(|e| {
            defmt::error!("settings: not saved: {}", e);
        })
    });
    *restart |= *settings != before;
    (c.kind(), status)
}

/// The camera until a command comes (kept in `pending`): the calibrate mode's frames, so that
/// a command ends a calibration (with no chessboard in view it would never end).
struct UntilCommand<'c, S> {
    camera: &'c mut S,
    pending: Option<Incoming>,
}

impl<S: FrameSource> FrameSource for UntilCommand<'_, S> {
    type Error = S::Error;

    fn size(&self) -> (usize, usize) {
        self.camera.size()
    }

    fn next_frame(&mut self, frame: &mut ImageMut<'_, u8>) -> Result<bool, S::Error> {
        if self.pending.is_none() {
            self.pending = stream::next_command();
        }
        if self.pending.is_some() {
            return Ok(false);
        }
        self.camera.next_frame(frame)
    }
}

/// The calibrate mode ([`calibrate_mode`]) on the camera's frames, in one of the pipeline's
/// frame buffers: progress, result and verdict on the record stream, then the settings in
/// force after it (a good camera replaces the settings' one and is saved; the mode goes back
/// to the compiled tracking mode either way). A command from the host ends it (the frames
/// ended: refused, nothing changed) and is returned to be carried out; so does a failed
/// capture.
fn calibrate<S: FrameSource>(
    app: &mut impl FrameLoop,
    camera: &mut S,
    buffers: Buffers<'_>,
    settings: &mut Settings,
    store: &mut Store,
    records: &mut RecordStream,
    clock: &mut DwtClock,
) -> Option<Incoming>
where
    S::Error: defmt::Format,
{
    defmt::info!("calibrate mode: {}", settings.chessboard);
    let (w, h) = camera.size();
    let Some(mut frame) = app.lend_frame(w, h) else {
        defmt::panic!("calibrate mode: the frames do not fit the pipeline's buffers");
    };
    let mut source = UntilCommand {
        camera,
        pending: None,
    };
    let back = tracker::defaults().mode;
    let outcome = calibrate_mode(
        settings,
        back,
        &mut source,
        &mut frame,
        buffers,
        clock,
        &mut |r| records.send(r),
        |s| {
            store.save(s).inspect_err(|e| {
                defmt::error!("settings: not saved: {}", e);
            })
        },
    );
    match outcome {
        Ok(o) => {
            defmt::info!("calibrate mode: {}", o.verdict);
            *settings = o.settings;
        }
        Err(CalibError::Source(e)) => {
            defmt::warn!("calibrate mode: camera: {}", e);
            settings.mode = back;
        }
        Err(CalibError::Core(e)) => {
            defmt::warn!("calibrate mode: {}", e);
            settings.mode = back;
        }
    }
    records.send(&settings.encode());
    source.pending
}

/// One defmt line per frame: the pose (target frame to camera: `t` in metres, rotation vector
/// in radians), the inliers and the frame's cost in core cycles (pyramid to drawing; the
/// capture, a DMA wait, apart).
fn log(r: &FrameReport) {
    let c = &r.costs;
    let stage = |s: Stage| c[Cost::Step(s)];
    let f = &r.frame;
    match f.pose {
        Some(p) => {
            let pose = p.best;
            let t = pose.pose.translation();
            let rv = pose.pose.rotation_vector();
            defmt::info!(
                "frame {=u32}: {=str}, {=usize} inliers, t = ({=f32}, {=f32}, {=f32}) m, r = ({=f32}, {=f32}, {=f32}) rad, rms {=f32} px, {=u32} cycles (flow {=u32}, homography {=u32}, pose {=u32}, redetect {=u32}, draw {=u32})",
                r.index,
                f.state.name(),
                f.inliers,
                t.x,
                t.y,
                t.z,
                rv.x,
                rv.y,
                rv.z,
                pose.rms_px,
                c.total,
                stage(Stage::Flow),
                stage(Stage::Homography),
                stage(Stage::Pose),
                stage(Stage::Redetect),
                c[Cost::Draw]
            )
        }
        None => defmt::info!(
            "frame {=u32}: {=str}, {=usize} tracked, no pose, {=u32} cycles",
            r.index,
            f.state.name(),
            f.tracked,
            c.total
        ),
    }
}
