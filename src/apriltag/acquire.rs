//! A planar target acquired from an AprilTag: the detector as the AR loop's
//! [`Acquire`] step.

use nalgebra::Point2;

use super::detector::Detector;
use super::family::Family;
use super::label::Label;
use super::workspace::WorkspaceView;
use crate::Result;
use crate::image::ImageView;
use crate::target::{Acquire, Tracked};

/// Tag `id` of `family` as a planar target (`camgeom::target`): each [`Acquire::acquire`]
/// looks for it in the frame with `detector` in `workspace` and gives its four corners in the
/// target's order ([`super::Detection::target_corners`]), so a target of `s x s` (the tag's
/// black square, AprilTag's `tag_size`) has its origin at the tag's top-left outer corner and
/// its pose is the tag's, moved by `R (s/2, s/2, 0)`.
///
/// It tracks the tag by detecting it where it must be ([`Acquire::tracks`], on unless
/// [`Self::track_by_detection`] turns it off): each [`Acquire::track`] refines the predicted
/// quad's edges and decodes it ([`Detector::refine_target`]), else (unless
/// [`Self::partial_views`] turns it off) finds it partly seen, hidden in part or cut by the
/// frame's edge ([`Detector::refine_partial`], the frame then flagged
/// [`crate::target::TargetFrame::partial`]), else detects the tag in the region around the
/// prediction ([`Detector::find_target_near`]); the loop falls back to a full detection when
/// all fail, and with
/// [`crate::target::TargetConfig::reacquire_every`] set runs one every that many frames as a
/// guard. Off, the loop tracks the tag with KLT between detections (every `reacquire_every`
/// frames and after a loss). [`Self::counts`] tells which search found the tag how often.
/// `L`: the workspace's label type ([`Label`]).
pub struct TagTarget<'a, L: Label = u16> {
    detector: &'a Detector,
    workspace: WorkspaceView<'a, L>,
    family: &'static Family,
    id: u16,
    by_detection: bool,
    partial: bool,
    counts: TrackCounts,
}

/// How often each search of a [`TagTarget`] found its tag.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackCounts {
    /// Found by refining the predicted quad ([`Detector::refine_target`]).
    pub refined: u32,
    /// Found by a detection in the region around the prediction
    /// ([`Detector::find_target_near`]).
    pub region: u32,
    /// Found partly seen ([`Detector::refine_partial`]).
    pub partial: u32,
    /// Found by a full detection ([`Acquire::acquire`]).
    pub full: u32,
    /// Full detections run.
    pub full_runs: u32,
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
            by_detection: true,
            partial: true,
            counts: TrackCounts {
                refined: 0,
                region: 0,
                partial: 0,
                full: 0,
                full_runs: 0,
            },
        }
    }

    /// Tracks by detection (`true`, the default) or lets the loop track with KLT between
    /// acquisitions (`false`).
    pub fn track_by_detection(mut self, on: bool) -> Self {
        self.by_detection = on;
        self
    }

    /// Tracks a partly seen tag too (`true`, the default: [`Detector::refine_partial`] when the
    /// refinement fails, before the region's detection) or only a wholly seen one (`false`).
    pub fn partial_views(mut self, on: bool) -> Self {
        self.partial = on;
        self
    }

    /// Which search found the tag how often, since [`Self::new`].
    pub fn counts(&self) -> TrackCounts {
        self.counts
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
        let found = self
            .detector
            .find_target(frame, &mut self.workspace, self.family, self.id)?;
        self.counts.full_runs = self.counts.full_runs.saturating_add(1);
        if found.is_some() {
            self.counts.full = self.counts.full.saturating_add(1);
        }
        Ok(found)
    }

    fn tracks(&self) -> bool {
        self.by_detection
    }

    fn track(
        &mut self,
        frame: &ImageView<'_, u8>,
        predicted: &[Point2<f32>; 4],
    ) -> Result<Option<Tracked>> {
        let (det, fam, id) = (self.detector, self.family, self.id);
        if let Some(c) = det.refine_target(frame, fam, id, predicted) {
            self.counts.refined = self.counts.refined.saturating_add(1);
            return Ok(Some(Tracked::whole(c)));
        }
        // Partly seen where it must be (a few thousand samples) before the region's whole
        // detection (a detection's work per pixel of the region): what hides the tag from the
        // refinement hides it from the region's detection too.
        if self.partial
            && let Ok(p) = det.refine_partial(frame, fam, id, predicted)
        {
            self.counts.partial = self.counts.partial.saturating_add(1);
            return Ok(Some(Tracked {
                corners: p.detection.target_corners(),
                partial: true,
            }));
        }
        let found = det.find_target_near(frame, &mut self.workspace, fam, id, predicted)?;
        if found.is_some() {
            self.counts.region = self.counts.region.saturating_add(1);
        }
        Ok(found.map(Tracked::whole))
    }
}
