//! Relative pose from an essential matrix: the cheirality test over the four candidates.

use nalgebra::Point2;

use super::{Essential, RelativePose, lift};
use crate::camera::Intrinsics;
use crate::scalar::{Real, above};
use crate::{Error, Result};

/// The pose [`recover_pose`] chose and its support.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecoveredPose<T: Real = f32> {
    /// View 1 to view 2, `|t| = 1` (the scale is not observable).
    pub pose: RelativePose<T>,
    /// Pairs in front of both cameras (and nearer than the distance bound) under `pose`.
    pub supporting: usize,
    /// The same count for the runner-up candidate (a margin for confidence).
    pub runner_up: usize,
}

/// Depths `(λ₁, λ₂)` of the closest points of the two rays, `λ₁ x̂₁` in view 1 and `λ₂ x̂₂` in
/// view 2: `min |λ₁ R x̂₁ + t - λ₂ x̂₂|²` (the midpoint method's depths; `x̂` has `z = 1`, so
/// `λ` is the depth); `None` for parallel rays.
pub(crate) fn ray_depths<T: Real>(
    pose: &RelativePose<T>,
    n1: &Point2<T>,
    n2: &Point2<T>,
) -> Option<(T, T)> {
    let a = pose.apply_vector(&lift(n1));
    let b = lift(n2);
    let t = pose.translation();
    // min |λ₁ a - λ₂ b + t|²: [a·a  -a·b; a·b  -b·b] [λ₁ λ₂]ᵀ = [-a·t; -b·t].
    let (aa, ab, bb) = (a.dot(&a), a.dot(&b), b.dot(&b));
    let (at, bt) = (a.dot(&t), b.dot(&t));
    let det = ab * ab - aa * bb;
    if !above(det.abs(), T::EPSILON * aa * bb) {
        return None;
    }
    let l1 = (at * bb - ab * bt) / det;
    let l2 = (ab * at - aa * bt) / det;
    Some((l1, l2))
}

/// Picks among the four decompositions of `e` ([`Essential::decompose`]) the one that puts
/// the most pairs in front of both cameras (OpenCV's `recoverPose`).
///
/// Pairs are pixel coordinates (undistorted) converted by `k1`, `k2`. A pair supports a
/// candidate when the closest points of its two rays have positive depths in both views,
/// below `max_distance` baselines (OpenCV's `distanceThresh`, 50 by default: far points have
/// unreliable cheirality). Only pairs with `mask[i]` are tested; on return `mask`
/// holds the supporting pairs of the chosen pose.
///
/// Errors: [`Error::LengthMismatch`]; [`Error::InvalidParameter`] for a `max_distance` that
/// is not positive; [`Error::Degenerate`] when no candidate has support.
#[doc(alias = "recoverPose")]
pub fn recover_pose<T: Real>(
    e: &Essential<T>,
    k1: &Intrinsics<T>,
    k2: &Intrinsics<T>,
    x1: &[Point2<T>],
    x2: &[Point2<T>],
    max_distance: T,
    mask: &mut [bool],
) -> Result<RecoveredPose<T>> {
    if x1.len() != x2.len() || x1.len() != mask.len() {
        return Err(Error::LengthMismatch);
    }
    if !above(max_distance, T::zero()) {
        return Err(Error::InvalidParameter("max_distance"));
    }
    let candidates = e.decompose()?;
    let supports = |pose: &RelativePose<T>, i: usize| -> bool {
        let (Some(a), Some(b)) = (x1.get(i), x2.get(i)) else {
            return false;
        };
        let (Ok(n1), Ok(n2)) = (k1.pixel_to_normalized(a), k2.pixel_to_normalized(b)) else {
            return false;
        };
        let Some((l1, l2)) = ray_depths(pose, &n1, &n2) else {
            return false;
        };
        l1 > T::zero() && l2 > T::zero() && l1 < max_distance && l2 < max_distance
    };
    let mut counts = [0usize; 4];
    for (count, pose) in counts.iter_mut().zip(candidates.iter()) {
        *count = mask
            .iter()
            .enumerate()
            .filter(|(i, m)| **m && supports(pose, *i))
            .count();
    }
    let mut order = [0usize, 1, 2, 3];
    order.sort_unstable_by_key(|i| core::cmp::Reverse(counts.get(*i).copied().unwrap_or(0)));
    let [best, second, ..] = order;
    let (Some(pose), Some(&supporting), Some(&runner_up)) =
        (candidates.get(best), counts.get(best), counts.get(second))
    else {
        return Err(Error::Degenerate);
    };
    if supporting == 0 {
        return Err(Error::Degenerate);
    }
    for (i, m) in mask.iter_mut().enumerate() {
        *m = *m && supports(pose, i);
    }
    Ok(RecoveredPose {
        pose: *pose,
        supporting,
        runner_up,
    })
}
