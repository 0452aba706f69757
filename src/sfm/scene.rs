//! What the incremental reconstruction fills in: each view's pose and state, each track's point,
//! which observations it used, and why a view or the whole reconstruction was refused.

use nalgebra::{Point2, Point3};

use super::bundle_views::BundleScratch;
use crate::scalar::Real;
use crate::transform::Pose;
use crate::{Error, Result};

/// Why a view has no pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ViewRefusal {
    /// The reconstruction never started (no initial pair).
    NotReached,
    /// Too few of its observations see reconstructed points.
    TooFewCorrespondences {
        /// 2D-3D correspondences found.
        found: u32,
        /// The least a registration needs.
        needed: u32,
    },
    /// PnP-RANSAC found no pose.
    NoPose,
    /// The best pose explains too few correspondences (count or ratio).
    TooFewInliers {
        /// Inliers of the best pose.
        inliers: u32,
        /// 2D-3D correspondences tried.
        correspondences: u32,
    },
    /// Registered, then too few of its observations survived the refinement.
    LostInRefinement {
        /// Observations kept.
        inliers: u32,
    },
}

impl ViewRefusal {
    /// The refusal in snake case, stable (for JSON and logs).
    pub const fn name(&self) -> &'static str {
        match self {
            Self::NotReached => "not_reached",
            Self::TooFewCorrespondences { .. } => "too_few_correspondences",
            Self::NoPose => "no_pose",
            Self::TooFewInliers { .. } => "too_few_inliers",
            Self::LostInRefinement { .. } => "lost_in_refinement",
        }
    }
}

/// The state of a view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ViewState {
    /// Has a pose.
    Registered,
    /// Has none, and why.
    Refused(ViewRefusal),
}

/// One view's outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ViewResult<T: Real = f32> {
    /// Registered or refused.
    pub state: ViewState,
    /// Observations used by the final reconstruction.
    pub inliers: u32,
    /// RMS reprojection error of those observations, pixels (0 without any).
    pub rms_px: T,
}

impl<T: Real> Default for ViewResult<T> {
    fn default() -> Self {
        Self {
            state: ViewState::Refused(ViewRefusal::NotReached),
            inliers: 0,
            rms_px: T::zero(),
        }
    }
}

/// Why no pair of views could start the reconstruction (the best candidate's reason).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum InitialRefusal<T: Real = f32> {
    /// No pair of views shares a track.
    NoSharedTracks,
    /// The essential matrix explains too few correspondences.
    TooFewInliers {
        /// The views.
        pair: (u16, u16),
        /// Inliers in front of both cameras.
        inliers: u32,
        /// The least needed.
        needed: u32,
    },
    /// A homography explains the correspondences about as well: a planar scene or a camera
    /// that turned without moving, so the relative pose is not determined.
    Planar {
        /// The views.
        pair: (u16, u16),
        /// Homography inliers over essential inliers (1 when no essential matrix exists).
        ratio: T,
    },
    /// The rays meet at too small an angle for depth.
    LowParallax {
        /// The views.
        pair: (u16, u16),
        /// Median triangulation angle, radians.
        median_angle: T,
    },
    /// The solvers found no model (degenerate correspondences).
    NoModel {
        /// The views.
        pair: (u16, u16),
    },
}

impl<T: Real> InitialRefusal<T> {
    /// The refusal in snake case, stable (for JSON and logs).
    pub const fn name(&self) -> &'static str {
        match self {
            Self::NoSharedTracks => "no_shared_tracks",
            Self::TooFewInliers { .. } => "too_few_inliers",
            Self::Planar { .. } => "planar_or_pure_rotation",
            Self::LowParallax { .. } => "low_parallax",
            Self::NoModel { .. } => "no_model",
        }
    }
}

/// The caller-owned outputs of [`reconstruct`](super::reconstruct) for `views` views, `tracks`
/// tracks and `observations` observations (one slot each).
#[derive(Debug)]
pub struct Scene<'a, T: Real = f32> {
    /// World-to-camera pose of each registered view (`X_cam = R X_world + t`); the world is
    /// the first view of the initial pair, the unit its distance to the second.
    pub poses: &'a mut [Option<Pose<T>>],
    /// Each view's outcome.
    pub views: &'a mut [ViewResult<T>],
    /// Each track's point, `None` when not reconstructed.
    pub points: &'a mut [Option<Point3<T>>],
    /// Whether each observation is used (an inlier of the reconstruction).
    pub used: &'a mut [bool],
}

/// The caller-owned scratch of [`reconstruct`](super::reconstruct): per observation, per track,
/// per view (each field says its length).
#[derive(Debug)]
pub struct Workspace<'a, T: Real = f32> {
    /// One per observation: undistorted normalised coordinates.
    pub normalized: &'a mut [Option<Point2<T>>],
    /// `views²` counts of shared tracks.
    pub covisibility: &'a mut [u32],
    /// One per view: 2D-3D count at the last failed registration.
    pub tried: &'a mut [u32],
    /// One per view: 2D-3D counts of the next registration.
    pub counts: &'a mut [u32],
    /// One per track (each of the next six).
    pub first: &'a mut [Point2<T>],
    /// Second pixels of a pair; PnP's normalised scratch.
    pub second: &'a mut [Point2<T>],
    /// 3D points of a registration.
    pub world: &'a mut [Point3<T>],
    /// Observation index of each correspondence.
    pub index: &'a mut [u32],
    /// RANSAC inlier mask.
    pub mask: &'a mut [bool],
    /// Second mask (the homography's).
    pub mask2: &'a mut [bool],
    /// Triangulation angles (median of the initial pair).
    pub angles: &'a mut [T],
    /// The bundle adjustment's.
    pub bundle: BundleScratch<'a, T>,
}

impl<T: Real> Workspace<'_, T> {
    pub(crate) fn check(&self, views: usize, tracks: usize, observations: usize) -> Result<()> {
        let ok = self.normalized.len() >= observations
            && self.covisibility.len() >= views * views
            && self.tried.len() >= views
            && self.counts.len() >= views
            && self.first.len() >= tracks
            && self.second.len() >= tracks
            && self.world.len() >= tracks
            && self.index.len() >= tracks
            && self.mask.len() >= tracks
            && self.mask2.len() >= tracks
            && self.angles.len() >= tracks;
        if ok {
            Ok(())
        } else {
            Err(Error::BufferTooSmall("sfm workspace"))
        }
    }
}

impl<T: Real> Scene<'_, T> {
    pub(crate) fn check(&self, views: usize, tracks: usize, observations: usize) -> Result<()> {
        if self.poses.len() == views
            && self.views.len() == views
            && self.points.len() == tracks
            && self.used.len() == observations
        {
            Ok(())
        } else {
            Err(Error::LengthMismatch)
        }
    }
}
