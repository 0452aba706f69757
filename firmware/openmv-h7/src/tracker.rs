//! The per-frame work: a Gaussian pyramid of the new frame, then the planar target tracked
//! from the previous frame's pyramid to it, and its pose logged.
//!
//! Everything lives in statics handed out once (AXI SRAM, `memory.x`):
//!
//! | buffer | bytes |
//! |---|---|
//! | 2 frames, 320x240 (the previous one stays for the flow) | 153 600 |
//! | 2 pyramids, levels 1-2 (160x120 + 80x60) | 48 000 |
//! | corner candidates (512 x 8 B) and corner scratch (12 x 320 x 4 B) | 19 456 |
//! | flow scratch (`klt::scratch_len(15)` `i16`) | 2 886 |

use camgeom::camera::{Camera, Intrinsics};
use camgeom::corners::{self, Corner};
use camgeom::image::{ImageMut, ImageView};
use camgeom::klt::{self, Fixed};
use camgeom::nalgebra::Point2;
use camgeom::pyramid::{self, Pyramid};
use camgeom::target::{PlanarTarget, TargetConfig, TargetFrame, TargetState};
use static_cell::ConstStaticCell;

use crate::camera::{HEIGHT, WIDTH};

/// Pyramid levels, the frame included: the coarsest is 80x60 (`TargetConfig`'s default).
pub const LEVELS: usize = 3;
const PYR_LEN: usize = pyramid::buffer_len(WIDTH, HEIGHT, LEVELS);
/// KLT window (pixels, square; `TargetConfig`'s default).
const WIN: usize = 15;
const CANDIDATES: usize = 512;
/// Tracked features at most.
pub const TRACKS: usize = 32;

/// The target's metric size: a 16 x 12 cm textured card (any planar texture), held so that it
/// fills [`FIRST_CORNERS`] in the first frame.
const TARGET_SIZE_M: (f32, f32) = (0.16, 0.12);
/// The target's corners in the first frame (pixels, the order of
/// `PlanarTarget::target_corners`): the middle half of the image.
const FIRST_CORNERS: [(f32, f32); 4] = [(80.0, 60.0), (240.0, 60.0), (240.0, 180.0), (80.0, 180.0)];

/// Nominal QVGA intrinsics of the OpenMV Cam H7's stock 2.8 mm lens on the OV7725 (image area
/// 3.984 x 2.952 mm): `fx = fy = 2.8 / 3.984 · 320 = 224.9` px, principal point at the
/// centre. Not a calibration: poses are only as good as this guess until the board's camera
/// is calibrated (e.g. with OpenCV on frames it sends) and the numbers put here.
const FX: f32 = 2.8 / 3.984 * WIDTH as f32;
const CX: f32 = (WIDTH as f32 - 1.0) / 2.0;
const CY: f32 = (HEIGHT as f32 - 1.0) / 2.0;

static FRAMES: ConstStaticCell<[[u8; WIDTH * HEIGHT]; 2]> =
    ConstStaticCell::new([[0; WIDTH * HEIGHT]; 2]);
static PYRAMIDS: ConstStaticCell<[[u8; PYR_LEN]; 2]> = ConstStaticCell::new([[0; PYR_LEN]; 2]);
static FLOW_SCRATCH: ConstStaticCell<[i16; klt::scratch_len(WIN)]> =
    ConstStaticCell::new([0; klt::scratch_len(WIN)]);
static CORNER_SCRATCH: ConstStaticCell<[u32; corners::scratch_len(WIDTH)]> =
    ConstStaticCell::new([0; corners::scratch_len(WIDTH)]);
static CANDIDATES_BUF: ConstStaticCell<[Corner; CANDIDATES]> = ConstStaticCell::new(
    [Corner {
        x: 0,
        y: 0,
        score: 0,
    }; CANDIDATES],
);

/// What one frame gave.
#[derive(defmt::Format)]
pub enum Outcome {
    /// First frame: the target was set up from [`FIRST_CORNERS`] with this many features.
    Initialised(usize),
    /// A tracked frame.
    Tracked(TargetFrame),
}

/// The tracking state across frames.
pub struct Tracker {
    frames: &'static mut [[u8; WIDTH * HEIGHT]; 2],
    pyramids: &'static mut [[u8; PYR_LEN]; 2],
    flow_scratch: &'static mut [i16; klt::scratch_len(WIN)],
    corner_scratch: &'static mut [u32; corners::scratch_len(WIDTH)],
    candidates: &'static mut [Corner; CANDIDATES],
    /// Which of `frames` receives the next frame (the other holds the previous one).
    next: usize,
    /// Whether the target holds features to track (false before the first successful
    /// initialisation and after the target was lost).
    initialised: bool,
    target: PlanarTarget<Fixed, TRACKS>,
    camera: Camera<f32>,
    cfg: TargetConfig,
}

impl Tracker {
    /// Takes the static buffers; call once.
    pub fn new() -> Result<Self, camgeom::Error> {
        let mut cfg = TargetConfig::default();
        // The buffers are sized for these: keep the configuration tied to them.
        cfg.lk.win = WIN;
        cfg.lk.max_level = LEVELS - 1;
        Ok(Self {
            frames: FRAMES.take(),
            pyramids: PYRAMIDS.take(),
            flow_scratch: FLOW_SCRATCH.take(),
            corner_scratch: CORNER_SCRATCH.take(),
            candidates: CANDIDATES_BUF.take(),
            next: 0,
            initialised: false,
            target: PlanarTarget::new(TARGET_SIZE_M.0, TARGET_SIZE_M.1)?,
            camera: Camera::pinhole(Intrinsics::new(FX, FX, CX, CY)?),
            cfg,
        })
    }

    /// The buffer the camera writes the next frame into.
    pub fn frame_mut(&mut self) -> Result<ImageMut<'_, u8>, camgeom::Error> {
        let buf = self
            .frames
            .get_mut(self.next)
            .ok_or(camgeom::Error::InvalidImage)?;
        ImageMut::packed(&mut buf[..], WIDTH, HEIGHT)
    }

    /// Processes the frame just written through [`Self::frame_mut`]: builds its pyramid and,
    /// on the first frame (and after a failed initialisation or a lost target) starts the
    /// target from [`FIRST_CORNERS`]; on later frames steps it from the previous frame. The one
    /// place to replace by the shared `firmware/app` pipeline.
    pub fn process(&mut self) -> Result<Outcome, camgeom::Error> {
        let cur = self.next;
        let [frame_a, frame_b] = &*self.frames;
        let [pyr_a, pyr_b] = &mut *self.pyramids;
        let (frame, prev_frame, pyr, prev_pyr) = if cur == 0 {
            (frame_a, frame_b, pyr_a, &*pyr_b)
        } else {
            (frame_b, frame_a, pyr_b, &*pyr_a)
        };
        let view = ImageView::packed(&frame[..], WIDTH, HEIGHT)?;
        let next = Pyramid::build(view, &mut pyr[..], LEVELS)?;
        let outcome = if !self.initialised {
            let corners = FIRST_CORNERS.map(|(x, y)| Point2::new(x, y));
            let n = self.target.init(
                &view,
                &corners,
                &self.cfg,
                &mut self.candidates[..],
                &mut self.corner_scratch[..],
            );
            // Too few features (a blank view): try again on the next frame.
            self.initialised = n.is_ok();
            Outcome::Initialised(n.unwrap_or(0))
        } else {
            let prev_view = ImageView::packed(&prev_frame[..], WIDTH, HEIGHT)?;
            let previous = Pyramid::from_buffer(prev_view, &prev_pyr[..], LEVELS)?;
            let out = self.target.step(
                &previous,
                &next,
                &self.camera,
                &self.cfg,
                &mut self.flow_scratch[..],
                &mut self.candidates[..],
                &mut self.corner_scratch[..],
            )?;
            // Lost: start again from the first-frame corners (the card shown again there).
            self.initialised = out.state == TargetState::Tracking;
            Outcome::Tracked(out)
        };
        self.next = 1 - cur;
        Ok(outcome)
    }
}
