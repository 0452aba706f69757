//! The per-frame work: the shared `camgeom-fw-app` pipeline at 320x240 (pyramid,
//! planar-target tracking in Q16.16, IPPE + LM pose, outline and cube drawn into the frame),
//! the very code the emulated board runs in CI over the recorded sequence and the host
//! replays bit for bit. This board only adds its camera (a [`camgeom_fw_app::FrameSource`]),
//! its clock (the DWT cycle counter) and its configuration.
//!
//! Everything lives in one static in AXI SRAM (`memory.x`): the pipeline's two frames, two
//! pyramids (levels 1-2), corner candidates and scratch, KLT scratch and the target
//! ([`Qvga::BYTES`] bytes, in `.bss`).

use camgeom::nalgebra::Point2;
use camgeom::target::GivenCorners;
use camgeom_fw_app::pipeline::{AppConfig, AppError, Clock};
use camgeom_fw_app::qvga::Qvga;
use camgeom_fw_app::run::{Acquisition, RunSpec};
use static_cell::ConstStaticCell;

use crate::camera::{HEIGHT, WIDTH};

/// The target's metric size: a 16 x 12 cm textured card (any planar texture), held so that it
/// fills [`FIRST_CORNERS`] when the target starts.
const TARGET_SIZE_M: [f32; 2] = [0.16, 0.12];
/// The target's corners when it starts (pixels, the order of
/// `PlanarTarget::target_corners`): the middle half of the image.
const FIRST_CORNERS: [[f32; 2]; 4] = [[80.0, 60.0], [240.0, 60.0], [240.0, 180.0], [80.0, 180.0]];

/// Nominal QVGA intrinsics of the OpenMV Cam H7's stock 2.8 mm lens on the OV7725 (image area
/// 3.984 x 2.952 mm): `fx = fy = 2.8 / 3.984 · 320 = 224.9` px, principal point at the
/// centre, no distortion. Not a calibration: poses are only as good as this guess until the
/// board's camera is calibrated (e.g. with OpenCV on frames it sends) and the numbers put here.
const FX: f32 = 2.8 / 3.984 * WIDTH as f32;
const CX: f32 = (WIDTH as f32 - 1.0) / 2.0;
const CY: f32 = (HEIGHT as f32 - 1.0) / 2.0;

/// Consecutive lost frames (the pipeline re-detecting around the last outline each time)
/// before the target starts again from [`FIRST_CORNERS`]: about a second at 30 fps.
pub const RESTART_AFTER_LOST: u32 = 30;

/// The pipeline, in `.bss`.
static APP: ConstStaticCell<Qvga> = ConstStaticCell::new(Qvga::new());

/// Takes the pipeline's static; call once.
pub fn pipeline() -> &'static mut Qvga {
    APP.take()
}

/// This board's run: 320x240 from the camera, the nominal camera, the card, and otherwise
/// exactly the emulated board's configuration ([`RunSpec::app_config`]: tracking parameters,
/// pyramid levels, cube).
pub fn config() -> Result<AppConfig, camgeom::Error> {
    RunSpec {
        width: WIDTH as u32,
        height: HEIGHT as u32,
        // A camera never ends; these two only steer recorded runs.
        frames: u32::MAX,
        stride: 1,
        overlay_every: 0,
        intrinsics: [FX, FX, CX, CY],
        distortion: [0.0; 5],
        target_size: TARGET_SIZE_M,
        corners: FIRST_CORNERS,
        acquisition: Acquisition::Corners,
        reacquire_every: 0,
        forward_backward: false,
    }
    .app_config()
}

/// Where the target starts, and starts again after [`RESTART_AFTER_LOST`] lost frames in a
/// row (the core's [`GivenCorners::again_after`]; until then a lost target is looked for
/// around its last outline).
pub fn acquire() -> GivenCorners {
    GivenCorners::new(FIRST_CORNERS.map(|[x, y]| Point2::new(x, y))).again_after(RESTART_AFTER_LOST)
}

/// The core's cycle counter (DWT `CYCCNT`, enabled at start-up), extended to 64 bits: it wraps
/// every 8.9 s at 480 MHz, and the pipeline reads it several times a frame.
#[derive(Debug, Default)]
pub struct DwtClock {
    last: u32,
    wraps: u64,
}

impl Clock for DwtClock {
    fn now(&mut self) -> u64 {
        let c = cortex_m::peripheral::DWT::cycle_count();
        if c < self.last {
            self.wraps = self.wraps.wrapping_add(1);
        }
        self.last = c;
        (self.wraps << 32) | u64::from(c)
    }
}

/// One defmt line for a pipeline error.
pub fn log_error<E: defmt::Format>(what: &str, e: &AppError<E>) {
    match e {
        AppError::Source(e) => defmt::warn!("{=str}: camera: {}", what, e),
        AppError::Core(e) => defmt::warn!("{=str}: {}", what, e),
        AppError::Geometry => defmt::warn!("{=str}: configuration and buffers disagree", what),
    }
}
