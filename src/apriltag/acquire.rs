//! A planar target acquired from an AprilTag: the detector as the AR loop's
//! [`Acquire`] step.

use nalgebra::Point2;

use super::detector::Detector;
use super::family::Family;
use super::label::Label;
use super::workspace::WorkspaceView;
use crate::Result;
use crate::image::ImageView;
use crate::target::Acquire;

/// Tag `id` of `family` as a planar target (`camgeom::target`): each [`Acquire::acquire`]
/// looks for it in the frame with `detector` in `workspace` and gives its four corners in the
/// target's order ([`super::Detection::target_corners`]), so a target of `s x s` (the tag's
/// black square, AprilTag's `tag_size`) has its origin at the tag's top-left outer corner and
/// its pose is the tag's, moved by `R (s/2, s/2, 0)`.
///
/// With [`crate::target::TargetConfig::reacquire_every`] set, the loop asks again while
/// tracking, so the detection bounds the tracks' drift; after a loss it asks on every frame.
/// `L`: the workspace's label type ([`Label`]).
pub struct TagTarget<'a, L: Label = u16> {
    detector: &'a Detector,
    workspace: WorkspaceView<'a, L>,
    family: &'static Family,
    id: u16,
}

impl<'a, L: Label> TagTarget<'a, L> {
    /// Tag `id` of `family` (one of `detector`'s families), found with `workspace` (a
    /// [`super::Workspace`]'s [`super::Workspace::as_mut_view`]).
    pub fn new(
        detector: &'a Detector,
        workspace: WorkspaceView<'a, L>,
        family: &'static Family,
        id: u16,
    ) -> Self {
        Self {
            detector,
            workspace,
            family,
            id,
        }
    }

    /// The workspace (its [`super::Stats`] after the last detection).
    pub fn workspace(&self) -> &WorkspaceView<'a, L> {
        &self.workspace
    }
}

impl<L: Label> Acquire for TagTarget<'_, L> {
    fn acquire(
        &mut self,
        frame: &ImageView<'_, u8>,
        _lost: u32,
    ) -> Result<Option<[Point2<f32>; 4]>> {
        self.detector
            .find_target(frame, &mut self.workspace, self.family, self.id)
    }
}
