//! The description of a recorded run: what a board is told before it replays a sequence.
//!
//! `cargo xtask run` writes it (`run.bin`) next to the raw frames; the emulated board reads it
//! over semihosting and the host replay reads the same bytes, so both build the same
//! [`AppConfig`] from it. Layout: [`RUN_SPEC_LEN`] bytes, 31 little-endian 32-bit words (the
//! frame of [`crate::wire`]):
//!
//! | words | what |
//! |---|---|
//! | 0, 1 | magic [`MAGIC`] (`"CRUN"`), version [`VERSION`] |
//! | 2..7 | `u32`: width, height, frames to run (at most), stride (every `stride`-th recorded frame), overlay period (every `n`-th frame's overlay is saved; 0: none) |
//! | 7..16 | `f32`: `fx fy cx cy` and OpenCV's distortion `k1 k2 p1 p2 k3` |
//! | 16, 17 | `f32`: the target's width and height (metres) |
//! | 18..26 | `f32`: the target's corners in the start frame, `x y` of `(0, 0), (w, 0), (w, h), (0, h)` (given corners only) |
//! | 26..30 | `u32`: how the target is acquired ([`Acquisition`]: 0 given corners, 1 an AprilTag), the tag's family ([`TAG_FAMILIES`] index), its id, and `reacquire_every` ([`camgeom::target::TargetConfig::reacquire_every`]) |
//! | 30 | `u32`: 1 for the forward-backward check ([`RunSpec::forward_backward`]), else 0 |

use camgeom::Error;
use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::nalgebra::Point2;

use camgeom::image::ImageView;
use camgeom::target::Acquire;

use crate::command::{ChessboardSettings, Mode};
pub use crate::options::{Acquisition, AppOptions, LEVELS, TAG_FAMILIES};
use crate::pipeline::{AppConfig, AppError, Clock, FrameLoop};
use crate::recorded::{CameraError, RecordedCamera, RecordedFrames};
use crate::report::{ErrorCode, FrameRecord};
use crate::settings::Settings;
use crate::wire::{Reader, WireError, Writer, tag};

/// `"CRUN"`.
pub const MAGIC: u32 = tag(b"CRUN");
/// Layout version.
pub const VERSION: u32 = 3;
/// Bytes of a run description.
pub const RUN_SPEC_LEN: usize = 31 * 4;
/// KLT window side of the main job ([`camgeom::target::TargetConfig`]'s default).
pub const WIN: usize = 15;
/// Candidate corners the detector may hold (before its minimum-distance selection).
pub const CANDIDATES: usize = 512;
/// Tracks of the main job's target.
pub const TRACKS: usize = 32;

/// A decoded run description.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSpec {
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames to run at most (the start frame included).
    pub frames: u32,
    /// Every `stride`-th recorded frame is delivered.
    pub stride: u32,
    /// Every `overlay_every`-th frame's overlay is saved (0: none).
    pub overlay_every: u32,
    /// `fx fy cx cy`.
    pub intrinsics: [f32; 4],
    /// `k1 k2 p1 p2 k3`.
    pub distortion: [f32; 5],
    /// The target's width and height (metres).
    pub target_size: [f32; 2],
    /// The target's corners in the start frame.
    pub corners: [[f32; 2]; 4],
    /// How the target is found.
    pub acquisition: Acquisition,
    /// Ask the acquisition again every this many frames while tracking (0: never).
    pub reacquire_every: u32,
    /// Check each flow by tracking it back (`fb_threshold` 1 px): off by default on the board
    /// (see [`AppConfig::new`]); on for the forward-backward job.
    pub forward_backward: bool,
}

impl RunSpec {
    /// Decodes [`RUN_SPEC_LEN`] bytes. Errors: [`WireError`] for a wrong length, magic or
    /// version, or an `acquisition` or `forward_backward` word no run has.
    pub fn parse(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = Reader::new_checked("run_spec", bytes, RUN_SPEC_LEN, &[MAGIC], VERSION)?;
        let [width, height, frames, stride, overlay_every] = r.u32s();
        let intrinsics = r.f32s();
        let distortion = r.f32s();
        let target_size = r.f32s();
        let corners = [(); 4].map(|_| r.f32s());
        let [kind, family, id, reacquire_every, fb] = r.u32s();
        Ok(Self {
            width,
            height,
            frames,
            stride,
            overlay_every,
            intrinsics,
            distortion,
            target_size,
            corners,
            acquisition: match kind {
                0 => Acquisition::Corners,
                1 if (family as usize) < TAG_FAMILIES.len() && id <= u32::from(u16::MAX) => {
                    Acquisition::Tag {
                        family: family as u8,
                        id: id as u16,
                    }
                }
                _ => return Err(r.invalid("acquisition")),
            },
            reacquire_every,
            forward_backward: match fb {
                0 => false,
                1 => true,
                _ => return Err(r.invalid("forward_backward")),
            },
        })
    }

    /// Encodes into [`RUN_SPEC_LEN`] bytes (the inverse of [`Self::parse`]).
    pub fn to_bytes(&self) -> [u8; RUN_SPEC_LEN] {
        Writer::fill(MAGIC, VERSION, |w| {
            w.u32s([
                self.width,
                self.height,
                self.frames,
                self.stride,
                self.overlay_every,
            ]);
            w.f32s(self.intrinsics);
            w.f32s(self.distortion);
            w.f32s(self.target_size);
            w.f32s(self.corners.into_iter().flatten());
            let (kind, family, id) = match self.acquisition {
                Acquisition::Corners => (0, 0, 0),
                Acquisition::Tag { family, id } => (1, u32::from(family), u32::from(id)),
            };
            w.u32s([
                kind,
                family,
                id,
                self.reacquire_every,
                u32::from(self.forward_backward),
            ]);
        })
    }

    /// The start corners as points.
    pub fn start_corners(&self) -> [Point2<f32>; 4] {
        self.corners.map(|[x, y]| Point2::new(x, y))
    }

    /// What the run tracks: its target's size, its acquisition, `reacquire_every` and the
    /// forward-backward check.
    pub fn options(&self) -> AppOptions {
        AppOptions {
            target_size: self.target_size,
            acquisition: self.acquisition,
            reacquire_every: self.reacquire_every,
            forward_backward: self.forward_backward,
        }
    }

    /// The run's description as board settings (the defaults a board without stored settings
    /// starts from): its mode, tag and camera.
    pub fn settings(&self) -> Settings {
        let (mode, family, id) = match self.acquisition {
            Acquisition::Corners => (Mode::TrackCorners, 0, 0),
            Acquisition::Tag { family, id } => (Mode::TrackTag, family, id),
        };
        Settings {
            mode,
            family,
            id,
            tag_size: self.target_size[0],
            intrinsics: self.intrinsics,
            distortion: self.distortion,
            chessboard: ChessboardSettings::DEFAULT,
        }
    }

    /// The run with `settings` in force: their camera, and their target when they track one
    /// (a tag: a square of their side; given corners: this run's corners and size). `None`
    /// for a mode that does not track.
    pub fn with_settings(&self, settings: &Settings) -> Option<Self> {
        let options = settings.options(
            self.target_size,
            self.reacquire_every,
            self.forward_backward,
        )?;
        Some(Self {
            intrinsics: settings.intrinsics,
            distortion: settings.distortion,
            target_size: options.target_size,
            acquisition: options.acquisition,
            ..*self
        })
    }

    /// The application's configuration for this run: [`AppConfig::new`] with its camera, its
    /// frame size and its [`Self::options`], the constructor every board uses. Errors: as
    /// [`Intrinsics::new`], [`Distortion::from_opencv`] and [`AppConfig::new`].
    pub fn app_config(&self) -> Result<AppConfig, Error> {
        let [fx, fy, cx, cy] = self.intrinsics;
        let camera = Camera::new(
            Intrinsics::new(fx, fy, cx, cy)?,
            Distortion::from_opencv(self.distortion)?,
        );
        AppConfig::new(
            camera,
            self.width as usize,
            self.height as usize,
            &self.options(),
        )
    }
}

/// Runs `pipeline` over every frame of `camera`, the same way on the board and in its host
/// replay: every frame steps it ([`FrameLoop::step`]; the first one that arrives starts it),
/// and the last overlay is drawn at the end. Each delivered frame gives `record` one
/// [`FrameRecord`], numbered by delivery ([`RecordedCamera::delivered`]): the frame's report
/// with its pixels as delivered ([`FrameLoop::with_latest`]), or the error it met with the
/// tracker's state (no pixels). A frame that fails does not end the run (a
/// faulty camera is what the fault job tests); `overlay` receives the overlays as
/// [`FrameLoop::step`] draws them. Errors: only [`AppError::Core`] from drawing the last
/// overlay.
pub fn drive<R: RecordedFrames>(
    pipeline: &mut impl FrameLoop,
    cfg: &AppConfig,
    camera: &mut RecordedCamera<R>,
    acquire: &mut (impl Acquire + ?Sized),
    clock: &mut impl Clock,
    record: &mut impl FnMut(&FrameRecord, Option<&ImageView<'_, u8>>),
    overlay: &mut impl FnMut(u32, &ImageView<'_, u8>),
) -> Result<(), AppError<CameraError<R::Error>>> {
    pipeline.reset();
    loop {
        let k = camera.delivered();
        match pipeline.step(cfg, camera, acquire, clock, overlay) {
            Ok(Some(r)) => {
                let mut rec = FrameRecord::of(&r);
                rec.index = k;
                if pipeline
                    .with_latest(|img| record(&rec, Some(img)))
                    .is_none()
                {
                    record(&rec, None);
                }
            }
            Ok(None) => break,
            Err(e) => {
                let code = match e {
                    AppError::Source(CameraError::WrongSize) => ErrorCode::WRONG_SIZE,
                    AppError::Source(CameraError::Read(_)) => ErrorCode::READ_FAILED,
                    other => ErrorCode::of(&other),
                };
                record(&FrameRecord::failed(k, pipeline.state(), code), None);
            }
        }
        if camera.delivered() == k {
            // Nothing was delivered (a bad configuration): the same would happen again.
            break;
        }
    }
    pipeline.finish(cfg, overlay)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(acquisition: Acquisition, forward_backward: bool) -> RunSpec {
        RunSpec {
            width: 320,
            height: 240,
            frames: 150,
            stride: 1,
            overlay_every: 15,
            intrinsics: [300.0, 301.0, 159.5, 119.5],
            distortion: [0.1, -0.2, 0.001, -0.002, 0.05],
            target_size: [0.2, 0.15],
            corners: [[70.0, 50.0], [250.0, 52.0], [249.0, 185.0], [71.0, 184.0]],
            acquisition,
            reacquire_every: 30,
            forward_backward,
        }
    }

    /// A run's own settings give the run back; a stored tag of another side changes the
    /// target and nothing else; a mode that does not track gives no run.
    #[test]
    fn settings_give_the_run_they_set() {
        let tag = Acquisition::Tag { family: 1, id: 7 };
        // A tag is square: its run's target is.
        let square = |s: RunSpec| RunSpec {
            target_size: [0.2, 0.2],
            ..s
        };
        for s in [spec(Acquisition::Corners, false), square(spec(tag, true))] {
            assert_eq!(s.with_settings(&s.settings()), Some(s));
        }
        let s = square(spec(tag, false));
        let mut stored = s.settings();
        stored.tag_size = 0.3;
        let run = s.with_settings(&stored).unwrap();
        assert_eq!(run.target_size, [0.3, 0.3]);
        assert_eq!(
            RunSpec {
                target_size: s.target_size,
                ..run
            },
            s
        );
        stored.mode = Mode::Calibrate;
        assert_eq!(s.with_settings(&stored), None);
        // Streaming frames tracks the tag as track-tag does.
        stored.mode = Mode::StreamFrames;
        assert_eq!(s.with_settings(&stored), Some(run));
    }

    /// Every field survives the bytes, the forward-backward flag both ways; a wrong length,
    /// version, acquisition or flag word is an error, not a guess.
    #[test]
    fn specs_round_trip_and_bad_bytes_are_errors() {
        let tag = Acquisition::Tag { family: 1, id: 7 };
        for s in [spec(Acquisition::Corners, false), spec(tag, true)] {
            assert_eq!(RunSpec::parse(&s.to_bytes()), Ok(s));
        }
        let good = spec(Acquisition::Corners, true).to_bytes();
        assert!(matches!(
            RunSpec::parse(&good[..RUN_SPEC_LEN - 4]),
            Err(WireError::Length { .. })
        ));
        let word = |i: usize, v: u32| {
            let mut b = good;
            b[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
            RunSpec::parse(&b)
        };
        assert!(matches!(
            word(1, VERSION - 1),
            Err(WireError::Version { .. })
        ));
        let field = |field| {
            Err(WireError::Field {
                record: "run_spec",
                field,
            })
        };
        assert_eq!(word(26, 2), field("acquisition"));
        assert_eq!(word(30, 2), field("forward_backward"));
        assert_eq!(word(30, 0).map(|s| s.forward_backward), Ok(false));
        // The flag reaches the tracking parameters.
        let on = spec(Acquisition::Corners, true).app_config().unwrap();
        let off = spec(Acquisition::Corners, false).app_config().unwrap();
        assert!(on.target.config().lk.fb_threshold.is_some());
        assert!(off.target.config().lk.fb_threshold.is_none());
    }
}
