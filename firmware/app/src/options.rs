//! What a board is told to track, and the one place it becomes an [`AppConfig`].
//!
//! [`AppOptions`] are the choices a user makes (the target's size, how it is found, how often
//! the detector runs again, the forward-backward check); [`AppConfig::new`] checks them once,
//! with the camera and the frame size, into the configuration the pipeline runs with. Every
//! board builds its configuration here: the OpenMV Cam H7 from its constants, the emulated
//! board and the host replay from a recorded run's description
//! ([`crate::run::RunSpec::app_config`]), so the same options give the same tracking
//! everywhere.

use camgeom::Error;
use camgeom::apriltag::Family;
use camgeom::camera::Camera;
use camgeom::draw::WireframeParams;
use camgeom::target::{TargetConfig, TargetParams};

use crate::pipeline::{AppConfig, CubePlacement};

/// Pyramid levels the application uses (`TargetConfig`'s default coarsest level is 2).
pub const LEVELS: usize = 3;
/// Side of the AR cube as a share of the target's shorter side (a host drawing a board's
/// frame draws the same cube).
pub const CUBE_SHARE: f32 = 0.4;

/// The tag families a target can name, by index ([`Acquisition::Tag`]).
pub const TAG_FAMILIES: [&Family; 4] = [
    &camgeom::apriltag::families::TAG36H11,
    &camgeom::apriltag::families::TAG25H9,
    &camgeom::apriltag::families::TAG16H5,
    &camgeom::apriltag::families::TAG_STANDARD41H12,
];

/// How the target is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Acquisition {
    /// From corners given for the first frame ([`camgeom::target::GivenCorners`]).
    Corners,
    /// From an AprilTag ([`camgeom::apriltag::TagTarget`]): the target is the tag's black
    /// square, [`AppOptions::target_size`]`[0]` a side.
    Tag {
        /// Index in [`TAG_FAMILIES`].
        family: u8,
        /// The tag's id.
        id: u16,
    },
}

impl Acquisition {
    /// The tag's family, `None` for given corners or an index [`TAG_FAMILIES`] does not have.
    pub fn family(self) -> Option<&'static Family> {
        match self {
            Acquisition::Corners => None,
            Acquisition::Tag { family, .. } => TAG_FAMILIES.get(usize::from(family)).copied(),
        }
    }
}

/// What to track and how: the user's choices, checked by [`AppConfig::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AppOptions {
    /// The target's width and height (metres; for a tag, its black square: both the side).
    pub target_size: [f32; 2],
    /// How the target is found.
    pub acquisition: Acquisition,
    /// Ask the acquisition again every this many frames while tracking (0: never).
    pub reacquire_every: u32,
    /// Check each flow by tracking it back (`fb_threshold` 1 px). Off by default for given
    /// corners (see [`AppConfig::new`]); a tag target always has it.
    pub forward_backward: bool,
}

impl AppConfig {
    /// The application's configuration for `width x height` frames from `camera`, tracking
    /// what `options` say: the default tracking parameters ([`TargetConfig::for_detector`]'s
    /// for a tag), [`LEVELS`] pyramid levels, and a cube of side 0.4 x the target's shorter
    /// side standing in the target's middle, all checked once.
    ///
    /// No forward-backward check unless `options` ask for it: it tracks every feature twice
    /// and on the recorded box sequence it rejected nothing the homography's RANSAC did not
    /// (the host `camgeom ar --fb 0` run gives the same poses on all 150 frames). A caller who
    /// expects occlusions turns it on (about +2.8M instructions a frame at 320x240; +2.1M with
    /// kept templates, the forward-backward job of `cargo xtask run`). The defaults are for
    /// 320x240; a narrower frame shows the target smaller, so the corner spacing and the
    /// border margin shrink with the width (not below 3 and 2 px).
    ///
    /// Errors: [`Error::InvalidParameter`]`("acquisition")` for a tag family
    /// [`TAG_FAMILIES`] does not have; as [`TargetParams::new`] for the size and the tracking
    /// parameters.
    pub fn new(
        camera: Camera<f32>,
        width: usize,
        height: usize,
        options: &AppOptions,
    ) -> Result<Self, Error> {
        let mut target = TargetConfig::default();
        target.lk.fb_threshold = options.forward_backward.then_some(1.0);
        target.reacquire_every = options.reacquire_every;
        if let Acquisition::Tag { .. } = options.acquisition {
            if options.acquisition.family().is_none() {
                return Err(Error::InvalidParameter("acquisition"));
            }
            target = target.for_detector();
        }
        let scale = width as f32 / 320.0;
        if scale < 1.0 {
            target.corners.min_distance =
                ((target.corners.min_distance as f32 * scale) as u32).max(3);
            target.border = (target.border * scale).max(2.0);
        }
        let [tw, th] = options.target_size;
        let size = CUBE_SHARE * tw.min(th);
        Ok(AppConfig {
            width,
            height,
            levels: LEVELS,
            target: TargetParams::new(&target, camera, options.target_size)?,
            cube: CubePlacement {
                x: 0.5 * (tw - size),
                y: 0.5 * (th - size),
                size,
            },
            wire: WireframeParams::default(),
            outline_value: 255,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use camgeom::camera::{Distortion, Intrinsics};

    fn camera() -> Camera<f32> {
        Camera::new(
            Intrinsics::new(300.0, 301.0, 159.5, 119.5).unwrap(),
            Distortion::from_opencv([0.1, -0.2, 0.001, -0.002, 0.05]).unwrap(),
        )
    }

    fn options(acquisition: Acquisition) -> AppOptions {
        AppOptions {
            target_size: [0.2, 0.15],
            acquisition,
            reacquire_every: 7,
            forward_backward: false,
        }
    }

    /// The options reach the tracking parameters: a tag target takes the detector's
    /// parameters (forward-backward on, no relocation), given corners the defaults; the cube
    /// stands in the middle.
    #[test]
    fn options_reach_the_configuration() {
        let corners = AppConfig::new(camera(), 320, 240, &options(Acquisition::Corners)).unwrap();
        let c = corners.target.config();
        assert!(c.lk.fb_threshold.is_none());
        assert!(c.relocate);
        assert_eq!(c.reacquire_every, 7);
        assert_eq!(
            (corners.width, corners.height, corners.levels),
            (320, 240, LEVELS)
        );
        assert!((corners.cube.size - 0.06).abs() < 1e-6);
        assert!((corners.cube.x - 0.07).abs() < 1e-6 && (corners.cube.y - 0.045).abs() < 1e-6);
        let tag = Acquisition::Tag { family: 0, id: 42 };
        let tag = AppConfig::new(camera(), 320, 240, &options(tag)).unwrap();
        assert!(tag.target.config().lk.fb_threshold.is_some());
        assert!(!tag.target.config().relocate);
    }

    /// Options no board can run are errors, not a guess: an unknown tag family, a target of
    /// no size.
    #[test]
    fn bad_options_are_errors() {
        let family = Acquisition::Tag {
            family: TAG_FAMILIES.len() as u8,
            id: 0,
        };
        assert_eq!(
            AppConfig::new(camera(), 320, 240, &options(family)),
            Err(Error::InvalidParameter("acquisition"))
        );
        let mut flat = options(Acquisition::Corners);
        flat.target_size = [0.0, 0.1];
        assert!(AppConfig::new(camera(), 320, 240, &flat).is_err());
    }
}
