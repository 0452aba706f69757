//! The per-frame work: the shared `camgeom-fw-app` pipeline at 320x240 (pyramid,
//! planar-target tracking in Q16.16, IPPE + LM pose, outline and cube drawn into the frame),
//! the very code the emulated board runs in CI over the recorded sequences and the host
//! replays bit for bit. This board only adds its camera (a [`camgeom_fw_app::FrameSource`]),
//! its clock (the DWT cycle counter), its options and its acquisition.
//!
//! **The target.** By default an AprilTag, found by the detector exactly as the emulated
//! board's tag job finds it ([`camgeom::apriltag::TagTarget`] with a
//! [`camgeom::apriltag::Detector`] in a [`camgeom::apriltag::Workspace320x240`];
//! again after a loss and every [`REACQUIRE_EVERY`] frames while tracking): print tag36h11
//! id [`TAG_ID`] with its black square [`TAG_SIZE_M`] a side. With the cargo feature `card`,
//! a textured card held so that it fills the middle half of the view instead
//! ([`camgeom::target::GivenCorners`]). Change the constants here and rebuild to track
//! something else.
//!
//! Everything lives in statics in AXI SRAM (`memory.x`): the pipeline's two frames, two
//! pyramids (levels 1-2), corner candidates and scratch, KLT scratch and the target
//! ([`Qvga`]), and the tag detector's workspace.

use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom_fw_app::pipeline::{AppConfig, AppError, Clock};
use camgeom_fw_app::qvga::Qvga;
use camgeom_fw_app::{Acquisition, AppOptions};
use static_cell::ConstStaticCell;

use crate::camera::{HEIGHT, WIDTH};

#[cfg(feature = "card")]
pub use card::acquire;
#[cfg(not(feature = "card"))]
pub use tag::{REACQUIRE_EVERY, TAG_ID, TAG_SIZE_M, acquire};

/// Nominal QVGA intrinsics of the OpenMV Cam H7's stock 2.8 mm lens on the OV7725 (image area
/// 3.984 x 2.952 mm): `fx = fy = 2.8 / 3.984 · 320 = 224.9` px, principal point at the
/// centre, no distortion. Not a calibration: poses are only as good as this guess until the
/// board's camera is calibrated (e.g. with OpenCV on frames it sends) and the numbers put here.
const FX: f32 = 2.8 / 3.984 * WIDTH as f32;
const CX: f32 = (WIDTH as f32 - 1.0) / 2.0;
const CY: f32 = (HEIGHT as f32 - 1.0) / 2.0;

/// The pipeline, in `.bss`.
static APP: ConstStaticCell<Qvga> = ConstStaticCell::new(Qvga::new());

/// Takes the pipeline's static; call once.
pub fn pipeline() -> &'static mut Qvga {
    APP.take()
}

/// This board's configuration: 320x240 from the camera (the nominal intrinsics), the
/// target's [`OPTIONS`], through [`AppConfig::new`], the constructor every board and the host
/// replay use.
pub fn config() -> Result<AppConfig, camgeom::Error> {
    let camera = Camera::new(
        Intrinsics::new(FX, FX, CX, CY)?,
        Distortion::from_opencv([0.0; 5])?,
    );
    AppConfig::new(camera, WIDTH, HEIGHT, &OPTIONS)
}

/// What the board tracks (the tag job's options: the tag's family, id and size, a detection
/// every [`REACQUIRE_EVERY`] frames).
#[cfg(not(feature = "card"))]
pub const OPTIONS: AppOptions = AppOptions {
    target_size: [TAG_SIZE_M; 2],
    acquisition: Acquisition::Tag {
        family: tag::FAMILY,
        id: TAG_ID,
    },
    reacquire_every: REACQUIRE_EVERY,
    forward_backward: false,
};

/// What the board tracks: a 16 x 12 cm card, its corners given.
#[cfg(feature = "card")]
pub const OPTIONS: AppOptions = AppOptions {
    target_size: card::TARGET_SIZE_M,
    acquisition: Acquisition::Corners,
    reacquire_every: 0,
    forward_backward: false,
};

#[cfg(not(feature = "card"))]
mod tag {
    use camgeom::apriltag::{Detector, DetectorConfig, TagTarget, Workspace320x240};
    use static_cell::{ConstStaticCell, StaticCell};

    use super::OPTIONS;

    /// The tag's family: tag36h11 (index 0 of [`camgeom_fw_app::run::TAG_FAMILIES`]).
    pub const FAMILY: u8 = 0;
    /// The tag's id (the tag job's).
    pub const TAG_ID: u16 = 42;
    /// The tag's black square, a side (metres; the tag job's 8 cm).
    pub const TAG_SIZE_M: f32 = 0.08;
    /// While tracking, the detector runs again every this many frames, bounding the tracks'
    /// drift (the tag job's period).
    pub const REACQUIRE_EVERY: u32 = 5;

    /// The detector's memory (119 KB at 320x240), in `.bss`.
    static WORKSPACE: ConstStaticCell<Workspace320x240> =
        ConstStaticCell::new(Workspace320x240::new());
    static DETECTOR: StaticCell<Detector> = StaticCell::new();

    /// The tag as the pipeline's acquisition; call once. Errors: as [`Detector::new`].
    pub fn acquire() -> Result<TagTarget<'static>, camgeom::Error> {
        let family = OPTIONS
            .acquisition
            .family()
            .ok_or(camgeom::Error::InvalidParameter("acquisition"))?;
        let detector = DETECTOR.init(Detector::new(DetectorConfig::default(), &[family])?);
        Ok(TagTarget::new(
            detector,
            WORKSPACE.take().as_mut_view(),
            family,
            TAG_ID,
        ))
    }
}

#[cfg(feature = "card")]
mod card {
    use camgeom::nalgebra::Point2;
    use camgeom::target::GivenCorners;

    /// The target's metric size: a 16 x 12 cm textured card (any planar texture), held so
    /// that it fills [`FIRST_CORNERS`] when the target starts.
    pub const TARGET_SIZE_M: [f32; 2] = [0.16, 0.12];
    /// The target's corners when it starts (pixels, the order of
    /// `PlanarTarget::target_corners`): the middle half of the image.
    pub const FIRST_CORNERS: [[f32; 2]; 4] =
        [[80.0, 60.0], [240.0, 60.0], [240.0, 180.0], [80.0, 180.0]];
    /// Consecutive lost frames (the pipeline re-detecting around the last outline each time)
    /// before the target starts again from [`FIRST_CORNERS`]: about a second at 30 fps.
    pub const RESTART_AFTER_LOST: u32 = 30;

    /// Where the target starts, and starts again after [`RESTART_AFTER_LOST`] lost frames in
    /// a row (the core's [`GivenCorners::again_after`]; until then a lost target is looked
    /// for around its last outline). Never fails.
    pub fn acquire() -> Result<GivenCorners, camgeom::Error> {
        Ok(
            GivenCorners::new(FIRST_CORNERS.map(|[x, y]| Point2::new(x, y)))
                .again_after(RESTART_AFTER_LOST),
        )
    }
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
