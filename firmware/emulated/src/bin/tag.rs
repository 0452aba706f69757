//! The second main job: the AR loop on an AprilTag at 320x240 (the rendered tag sequence that
//! `cargo xtask run` prepares). The target is acquired by the tag detector
//! ([`camgeom::apriltag::TagTarget`], the loop's acquisition step) on the first frame, after a
//! loss and every `reacquire_every` frames, and tracked in between by detecting it where it
//! must be (`TagTarget`'s tracking by detection); the host replays it bit for bit. Its records
//! also stream over UART0 ([`job::Stream`]), as a real board's do over its link, and its poses
//! go to an autopilot as MAVLink over UART1 (`mavlink`). Switched to the calibrate mode
//! (`camgeom_fw_app::calibrate_mode`), it calibrates its camera from the chessboard frames
//! it is fed instead, and stores the camera in its flash.
#![no_std]
#![no_main]

use core::mem::MaybeUninit;

use camgeom::apriltag::{Detector, DetectorConfig, TagTarget, Workspace320x240};
use camgeom_fw_app::calibrate_mode::Buffers;
use camgeom_fw_app::calibration::{BoardCalibrator, BoardDetector, scratch_len};
use camgeom_fw_app::run::{Acquisition, TAG_FAMILIES};
use camgeom_fw_app::sizes::Qvga;
use camgeom_fw_emulated::{board, entry, job};
use static_cell::{ConstStaticCell, StaticCell};

const W: usize = 320;
const H: usize = 240;

/// Every buffer of the pipeline, in `.bss`.
static APP: ConstStaticCell<Qvga> = ConstStaticCell::new(Qvga::new());
/// The tag detector's memory (119 KB at 320x240), in `.bss` too.
static WORKSPACE: ConstStaticCell<Workspace320x240> = ConstStaticCell::new(Workspace320x240::new());
static DETECTOR: StaticCell<Detector> = StaticCell::new();
/// The calibrate mode's chessboard detector (20 KB), its scratch (14 KB at 320 px) and its
/// calibrator (25 KB); its frames go into a frame buffer of the pipeline's.
static BOARD_DETECTOR: ConstStaticCell<BoardDetector> = ConstStaticCell::new(BoardDetector::new());
static BOARD_SCRATCH: ConstStaticCell<[i32; scratch_len(W)]> =
    ConstStaticCell::new([0; scratch_len(W)]);
static CALIBRATOR: ConstStaticCell<MaybeUninit<BoardCalibrator>> =
    ConstStaticCell::new(MaybeUninit::uninit());

/// MAVLink to an autopilot over UART1 (the Cortex-M7 build; the mounting: camera looking
/// down, top of the image toward the nose).
#[cfg(mavlink)]
fn mavlink() -> camgeom_fw_emulated::uart::MavlinkLink {
    let config = camgeom_fw_app::mavlink::MavlinkConfig::default();
    camgeom_fw_emulated::uart::MavlinkLink::open(config)
}

/// No MAVLink where the build has none.
#[cfg(not(mavlink))]
fn mavlink() {}

#[entry]
fn main() -> ! {
    let workspace = WORKSPACE.take();
    let calibrate = Buffers {
        detector: BOARD_DETECTOR.take(),
        scratch: BOARD_SCRATCH.take(),
        calibrator: CALIBRATOR.take(),
    };
    job::run_with_calibrate(
        APP.take(),
        W,
        H,
        job::Stream::Uart0,
        mavlink(),
        |spec| match spec.acquisition {
            Acquisition::Tag { family, id } => {
                let family = *TAG_FAMILIES.get(usize::from(family))?;
                // Decimation 2: the full detections (the first frame, after a loss, the
                // guard) search for quads on a quarter of the pixels; tracking refines edges
                // and decodes in the full frame (xtask's replay makes the same detector).
                let cfg = DetectorConfig {
                    decimate: 2,
                    ..DetectorConfig::default()
                };
                let detector = match Detector::new(cfg, &[family]) {
                    Ok(d) => DETECTOR.init(d),
                    Err(e) => {
                        defmt::error!("tag detector: {}", e);
                        board::exit_failure()
                    }
                };
                Some(TagTarget::new(
                    detector,
                    workspace.as_mut_view(),
                    family,
                    id,
                ))
            }
            Acquisition::Corners => None,
        },
        calibrate,
    )
}
