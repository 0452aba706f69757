//! The per-frame work: the shared `camgeom-fw-app` pipeline at 320x240 (pyramid,
//! planar-target tracking in Q16.16, IPPE + LM pose, outline and cube drawn into the frame),
//! the very code the emulated board runs in CI over the recorded sequences and the host
//! replays bit for bit. This board only adds its camera (a [`camgeom_fw_app::FrameSource`]),
//! its clock (the DWT cycle counter), its settings and its acquisition.
//!
//! **The target**, as the [`Settings`] say (loaded from flash, changed by commands; see
//! [`defaults`] for the compiled ones). Mode `track-tag` (the default): an AprilTag, found by
//! the detector exactly as the emulated board's tag job finds it
//! ([`camgeom::apriltag::TagTarget`] with a [`camgeom::apriltag::Detector`] in a
//! [`camgeom::apriltag::Workspace320x240`]; again after a loss and every [`REACQUIRE_EVERY`]
//! frames while tracking): by default tag36h11 id [`TAG_ID`] with its black square
//! [`TAG_SIZE_M`] a side. Mode `track-corners` (the default with the cargo feature `card`): a
//! textured card held so that it fills the middle half of the view
//! ([`camgeom::target::GivenCorners`]).
//!
//! Everything lives in statics in AXI SRAM (`memory.x`): the pipeline's two frames, two
//! pyramids (levels 1-2), corner candidates and scratch, KLT scratch and the target
//! ([`Qvga`]), and the tag detector's workspace.

use core::mem::MaybeUninit;

use camgeom::apriltag::{Detector, DetectorConfig, Family, Workspace320x240};
use camgeom::nalgebra::Point2;
use camgeom::target::GivenCorners;
use camgeom_fw_app::calibration::{BoardCalibrator, BoardDetector, scratch_len};
use camgeom_fw_app::command::{ChessboardSettings, Mode};
use camgeom_fw_app::pipeline::{AppConfig, AppError, Clock};
use camgeom_fw_app::qvga::Qvga;
use camgeom_fw_app::settings::Settings;
use camgeom_fw_app::{Acquisition, AppOptions};
use static_cell::ConstStaticCell;

use crate::camera::{HEIGHT, WIDTH};

/// Nominal QVGA intrinsics of the OpenMV Cam H7's stock 2.8 mm lens on the OV7725 (image area
/// 3.984 x 2.952 mm): `fx = fy = 2.8 / 3.984 · 320 = 224.9` px, principal point at the
/// centre, no distortion. Not a calibration: poses are only as good as this guess until the
/// board's camera is calibrated (e.g. with OpenCV on frames it sends) and the numbers sent
/// (`camgeom monitor`'s camera command) and saved.
const FX: f32 = 2.8 / 3.984 * WIDTH as f32;
const CX: f32 = (WIDTH as f32 - 1.0) / 2.0;
const CY: f32 = (HEIGHT as f32 - 1.0) / 2.0;

/// The default tag's family: tag36h11 (index 0 of [`camgeom_fw_app::options::TAG_FAMILIES`]).
pub const FAMILY: u8 = 0;
/// The default tag's id (the tag job's).
pub const TAG_ID: u16 = 42;
/// The default tag's black square, a side (metres; the tag job's 8 cm).
pub const TAG_SIZE_M: f32 = 0.08;
/// While tracking a tag, the detector runs again every this many frames, bounding the tracks'
/// drift (the tag job's period).
pub const REACQUIRE_EVERY: u32 = 5;

/// The card's metric size: a 16 x 12 cm textured card (any planar texture), held so that it
/// fills [`FIRST_CORNERS`] when the target starts.
pub const CARD_SIZE_M: [f32; 2] = [0.16, 0.12];
/// The card's corners when it starts (pixels, the order of `PlanarTarget::target_corners`):
/// the middle half of the image.
pub const FIRST_CORNERS: [[f32; 2]; 4] =
    [[80.0, 60.0], [240.0, 60.0], [240.0, 180.0], [80.0, 180.0]];
/// Consecutive lost frames (the pipeline re-detecting around the last outline each time)
/// before the card starts again from [`FIRST_CORNERS`]: about a second at 30 fps.
pub const RESTART_AFTER_LOST: u32 = 30;

/// The pipeline, in `.bss`.
static APP: ConstStaticCell<Qvga> = ConstStaticCell::new(Qvga::new());
/// The detector's memory (119 KB at 320x240).
static WORKSPACE: ConstStaticCell<Workspace320x240> = ConstStaticCell::new(Workspace320x240::new());

/// The calibrate mode's chessboard detector (20 KB), its scratch (14 KB) and calibrator
/// (25 KB); its frames go into a frame buffer of the pipeline's ([`camgeom_fw_app::FrameLoop::lend_frame`]).
static BOARD_DETECTOR: ConstStaticCell<BoardDetector> = ConstStaticCell::new(BoardDetector::new());
static BOARD_SCRATCH: ConstStaticCell<[i32; scratch_len(WIDTH)]> =
    ConstStaticCell::new([0; scratch_len(WIDTH)]);
static CALIBRATOR: ConstStaticCell<MaybeUninit<BoardCalibrator>> =
    ConstStaticCell::new(MaybeUninit::uninit());

/// The calibrate mode's buffers: the detector, its scratch, room for the calibrator. Call
/// once.
pub fn calibrate_buffers() -> (
    &'static mut BoardDetector,
    &'static mut [i32],
    &'static mut MaybeUninit<BoardCalibrator>,
) {
    (
        BOARD_DETECTOR.take(),
        BOARD_SCRATCH.take(),
        CALIBRATOR.take(),
    )
}

/// Takes the pipeline's static; call once.
pub fn pipeline() -> &'static mut Qvga {
    APP.take()
}

/// Takes the tag detector's workspace; call once.
pub fn workspace() -> &'static mut Workspace320x240 {
    WORKSPACE.take()
}

/// The compiled settings, used when the flash holds none: track the tag (with the cargo
/// feature `card`, the card), the nominal intrinsics.
pub fn defaults() -> Settings {
    Settings {
        mode: if cfg!(feature = "card") {
            Mode::TrackCorners
        } else {
            Mode::TrackTag
        },
        family: FAMILY,
        id: TAG_ID,
        tag_size: TAG_SIZE_M,
        intrinsics: [FX, FX, CX, CY],
        distortion: [0.0; 5],
        chessboard: ChessboardSettings::DEFAULT,
    }
}

/// Why settings give no configuration.
#[derive(Debug, Clone, Copy, PartialEq, defmt::Format)]
pub enum Unfit {
    /// A mode that does not track (calibrate: the main loop runs it apart).
    Mode,
    /// The camera or the target that [`AppConfig::new`] refuses.
    Config(camgeom::Error),
}

/// The configuration of `settings` (320x240, their camera, their target through
/// [`AppConfig::new`], the constructor every board and the host replay use) and their options.
/// Errors: [`Unfit`].
pub fn config(settings: &Settings) -> Result<(AppConfig, AppOptions), Unfit> {
    let mut options = settings
        .options(CARD_SIZE_M, REACQUIRE_EVERY, false)
        .ok_or(Unfit::Mode)?;
    if options.acquisition == Acquisition::Corners {
        // Given corners are given once: nothing to ask again while tracking.
        options.reacquire_every = 0;
    }
    let camera = settings.camera().map_err(Unfit::Config)?;
    let cfg = AppConfig::new(camera, WIDTH, HEIGHT, &options).map_err(Unfit::Config)?;
    Ok((cfg, options))
}

/// The tag to look for: a detector of its family, the family and the id.
pub struct TagSpec {
    /// A detector of [`Self::family`] alone (the tag job's configuration).
    pub detector: Detector,
    /// The tag's family.
    pub family: &'static Family,
    /// The tag's id.
    pub id: u16,
}

/// The tag of `options`; `None` for given corners. Errors: as [`Detector::new`], and
/// [`camgeom::Error::InvalidParameter`]`("family")` for a family index that is not one.
pub fn tag(options: &AppOptions) -> Result<Option<TagSpec>, camgeom::Error> {
    let Acquisition::Tag { id, .. } = options.acquisition else {
        return Ok(None);
    };
    let family = options
        .acquisition
        .family()
        .ok_or(camgeom::Error::InvalidParameter("family"))?;
    Ok(Some(TagSpec {
        detector: Detector::new(DetectorConfig::default(), &[family])?,
        family,
        id,
    }))
}

/// Where the card starts, and starts again after [`RESTART_AFTER_LOST`] lost frames in a row
/// (the core's [`GivenCorners::again_after`]; until then a lost target is looked for around
/// its last outline).
pub fn card() -> GivenCorners {
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
