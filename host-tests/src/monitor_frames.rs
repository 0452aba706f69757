//! The frames a board streams (mode `stream-frames`): its pixels in
//! [`camgeom_fw_app::frame_chunk`] records put back together, and each complete frame drawn
//! with the overlay its frame record describes (`camgeom monitor --frames-dir`).
//!
//! Before each frame's record the board sends its settings ([`Settings`]: the camera and the
//! tag, what the overlay is drawn with) and the frame's chunks. A frame is complete when every
//! chunk of it came; a frame of which some chunks came but not all, or whose record never
//! came, is counted ([`FrameAssembler::incomplete`]) and not drawn. A frame none of whose
//! chunks came is not seen at all (its record says nothing about pixels).

use std::path::Path;

use camgeom::nalgebra::{Point2, Vector3};
use camgeom::pose::{PlanarPose, PoseEstimate};
use camgeom::target::TargetFrame;
use camgeom::transform::Pose;
use camgeom_fw_app::frame_chunk::FrameChunk;
use camgeom_fw_app::options::CUBE_SHARE;
use camgeom_fw_app::report::{FrameRecord, PoseRecord};
use camgeom_fw_app::settings::Settings;

use crate::ar::draw_target_on;
use crate::error::Result;
use crate::images::GrayImage;
use crate::rgb::{Overlay, RgbImage};

/// A frame whose chunks are arriving.
struct Partial {
    index: u32,
    image: GrayImage,
    got: Vec<bool>,
    missing: usize,
}

/// Puts streamed frames back together, chunk by chunk, in the order they come.
#[derive(Default)]
pub struct FrameAssembler {
    current: Option<Partial>,
    settings: Option<Settings>,
    complete: u32,
    incomplete: u32,
}

impl FrameAssembler {
    /// An assembler that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// The board's settings, which the next frames are drawn with.
    pub fn settings(&mut self, s: Settings) {
        self.settings = Some(s);
    }

    /// A chunk: a chunk of another frame than the one being assembled ends that one
    /// (incomplete: its record did not come in between).
    pub fn chunk(&mut self, c: &FrameChunk) {
        let (w, h) = (usize::from(c.width), usize::from(c.height));
        let same = self
            .current
            .as_ref()
            .is_some_and(|p| p.index == c.index && (p.image.width, p.image.height) == (w, h));
        if !same {
            if self.current.take().is_some() {
                self.incomplete += 1;
            }
            self.current = Some(Partial {
                index: c.index,
                image: GrayImage::filled(w, h, 0),
                got: vec![false; c.count()],
                missing: c.count(),
            });
        }
        let Some(p) = self.current.as_mut() else {
            return;
        };
        if let Some(seen) = p.got.get_mut(c.number())
            && !*seen
        {
            *seen = true;
            p.missing -= 1;
            let at = c.offset as usize;
            if let Some(d) = p.image.data.get_mut(at..at + c.pixels().len()) {
                d.copy_from_slice(c.pixels());
            }
        }
    }

    /// Frame `index`'s record came: its pixels and the settings to draw it with when all its
    /// chunks came, else `None` (counted incomplete when some came).
    pub fn record(&mut self, index: u32) -> Option<(GrayImage, Option<Settings>)> {
        let p = self.current.take_if(|p| p.index == index)?;
        if p.missing > 0 {
            self.incomplete += 1;
            return None;
        }
        self.complete += 1;
        Some((p.image, self.settings))
    }

    /// The stream ended: a frame still being assembled is incomplete.
    pub fn finish(&mut self) {
        if self.current.take().is_some() {
            self.incomplete += 1;
        }
    }

    /// Frames put back together whole, with their record.
    pub fn complete(&self) -> u32 {
        self.complete
    }

    /// Frames of which some chunks came but not all, or whose record did not come.
    pub fn incomplete(&self) -> u32 {
        self.incomplete
    }
}

fn pose(p: &PoseRecord) -> Option<PoseEstimate<f32>> {
    let v = |a: [f32; 3]| Vector3::new(a[0], a[1], a[2]);
    Some(PoseEstimate {
        pose: Pose::from_rodrigues(v(p.r), v(p.t)).ok()?,
        rms_px: p.rms_px,
    })
}

/// What the record says the loop found, as the core's [`TargetFrame`] (the host's overlays
/// draw that).
fn target_frame(f: &FrameRecord) -> TargetFrame {
    TargetFrame {
        state: f.state,
        acquired: f.acquired,
        pose: f.pose.and_then(|(best, alt)| {
            Some(PlanarPose {
                best: pose(&best)?,
                alternative: pose(&alt)?,
            })
        }),
        outline: f.outline.map(|o| o.map(|[x, y]| Point2::new(x, y))),
        tracked: usize::from(f.tracked),
        partial: f.partial,
        inliers: usize::from(f.inliers),
        added: usize::from(f.added),
        features: usize::from(f.features),
    }
}

/// Frame `img` with the overlay of its record `f` (the host's AR overlay,
/// [`crate::ar::draw_target_on`]: the tag's outline, the cube the board draws on it, a red
/// border when the tag is lost). Without the board's `settings` (their record was damaged)
/// there is no camera to draw the cube through: only the outline.
pub fn draw_frame(img: &GrayImage, f: &FrameRecord, settings: Option<&Settings>) -> RgbImage {
    let camera = settings.and_then(|s| s.camera().ok());
    let size = settings.map_or(0.0, |s| s.tag_size);
    draw_target_on(
        RgbImage::from_gray(img),
        camera.as_ref(),
        &target_frame(f),
        &[],
        [size; 2],
        CUBE_SHARE * size,
    )
}

/// Writes frame `img` with its overlay as `dir/frame-NNNNNN.png` (the record's index).
pub fn save_frame(
    dir: &Path,
    img: &GrayImage,
    f: &FrameRecord,
    settings: Option<&Settings>,
) -> Result<()> {
    draw_frame(img, f, settings).save_png(dir.join(format!("frame-{:06}.png", f.index)))
}
