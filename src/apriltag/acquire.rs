//! A planar target acquired from an AprilTag: the detector as the AR loop's
//! [`Acquire`] step.

use nalgebra::Point2;

use super::{Detector, Family, Workspace};
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
pub struct TagTarget<
    'a,
    const W: usize,
    const T: usize,
    const L: usize,
    const C: usize,
    const P: usize,
    const S: usize,
> {
    detector: &'a Detector,
    workspace: &'a mut Workspace<W, T, L, C, P, S>,
    family: &'static Family,
    id: u16,
}

impl<
    'a,
    const W: usize,
    const T: usize,
    const L: usize,
    const C: usize,
    const P: usize,
    const S: usize,
> TagTarget<'a, W, T, L, C, P, S>
{
    /// Tag `id` of `family` (one of `detector`'s families), found with `workspace`.
    pub fn new(
        detector: &'a Detector,
        workspace: &'a mut Workspace<W, T, L, C, P, S>,
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
    pub fn workspace(&self) -> &Workspace<W, T, L, C, P, S> {
        self.workspace
    }
}

impl<const W: usize, const T: usize, const L: usize, const C: usize, const P: usize, const S: usize>
    Acquire for TagTarget<'_, W, T, L, C, P, S>
{
    fn acquire(
        &mut self,
        frame: &ImageView<'_, u8>,
        _lost: u32,
    ) -> Result<Option<[Point2<f32>; 4]>> {
        self.detector
            .find_target(frame, self.workspace, self.family, self.id)
    }
}
