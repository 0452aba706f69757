//! The choice of the two views that start an incremental reconstruction, and the refusal when
//! no pair determines a relative pose.
//!
//! Candidates are the pairs sharing the most tracks. For each: the essential matrix (5-point
//! RANSAC) and its cheirality-checked pose; a homography on the same correspondences; the
//! triangulation angles of the inliers. A pair is refused when the essential matrix explains
//! too few correspondences, when the homography explains nearly as many (a planar scene or a
//! camera that only turned: `E` is then not determined), or when the median triangulation
//! angle is too small for depth. Of the pairs that pass, the one with the most inliers wins.

use nalgebra::Point2;

use super::incremental_config::IncrementalParams;
use super::scene::{InitialRefusal, Workspace};
use super::track_set::TrackSet;
use crate::camera::Camera;
use crate::homography::find_homography;
use crate::scalar::Real;
use crate::transform::Pose;
use crate::twoview::{find_essential, recover_pose, triangulate_optimal};

/// A pair that passed: its views, the second's pose (the first is the world), its inliers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct InitialPair<T: Real> {
    pub views: (u16, u16),
    pub pose: Pose<T>,
    pub inliers: u32,
}

/// Counts the tracks shared by each pair of views into `covisibility[a * views + b]`, `a < b`.
pub(crate) fn covisibility<T: Real>(
    tracks: &TrackSet<'_, T>,
    normalized: &[Option<Point2<T>>],
    covisibility: &mut [u32],
) {
    let v = tracks.views();
    covisibility.iter_mut().for_each(|c| *c = 0);
    for i in 0..tracks.len() {
        let range = tracks.range(i);
        let obs = tracks.track(i);
        let ok = normalized.get(range).unwrap_or(&[]);
        for (ka, (a, na)) in obs.iter().zip(ok).enumerate() {
            for (b, nb) in obs.iter().zip(ok).skip(ka + 1) {
                if na.is_none() || nb.is_none() {
                    continue;
                }
                let (lo, hi) = if a.view < b.view {
                    (a.view, b.view)
                } else {
                    (b.view, a.view)
                };
                if let Some(c) = covisibility.get_mut(usize::from(lo) * v + usize::from(hi)) {
                    *c = c.saturating_add(1);
                }
            }
        }
    }
}

/// The best pair of the `initial_pair_trials` most covisible ones (module docs), or the
/// reason of the most promising refusal.
pub(crate) fn choose<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    params: &IncrementalParams<T>,
    ws: &mut Workspace<'_, T>,
) -> Result<InitialPair<T>, InitialRefusal<T>> {
    let v = tracks.views();
    let mut best: Option<InitialPair<T>> = None;
    let mut refusal: Option<(u32, InitialRefusal<T>)> = None;
    // Pairs in decreasing covisibility: take the largest count not taken yet, each time
    // (trials × views² work, no sorting memory).
    let mut ceiling = u32::MAX;
    let mut tried = 0u16;
    let mut taken_at_ceiling = 0usize;
    while tried < params.config().initial_pair_trials {
        // The next pair: the largest count `< ceiling`, or `== ceiling` after the ones taken.
        let mut next: Option<(usize, u32)> = None;
        let mut seen_at_ceiling = 0usize;
        for (k, &c) in ws.covisibility.iter().enumerate().take(v * v) {
            if c == 0 || c > ceiling {
                continue;
            }
            if c == ceiling {
                seen_at_ceiling += 1;
                if seen_at_ceiling <= taken_at_ceiling {
                    continue;
                }
            }
            if next.is_none_or(|(_, n)| c > n) {
                next = Some((k, c));
            }
        }
        let Some((k, c)) = next else { break };
        if c == ceiling {
            taken_at_ceiling += 1;
        } else {
            ceiling = c;
            taken_at_ceiling = 1;
        }
        tried += 1;
        let pair = ((k / v) as u16, (k % v) as u16);
        match try_pair(camera, tracks, params, ws, pair) {
            Ok(p) => {
                if best.is_none_or(|b| p.inliers > b.inliers) {
                    best = Some(p);
                }
            }
            Err((score, r)) => {
                if refusal.is_none_or(|(s, _)| score > s) {
                    refusal = Some((score, r));
                }
            }
        }
    }
    match (best, refusal) {
        (Some(b), _) => Ok(b),
        (None, Some((_, r))) => Err(r),
        (None, None) => Err(InitialRefusal::NoSharedTracks),
    }
}

/// Tries one pair; a refusal carries a score (its inliers) to rank refusals by.
fn try_pair<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    params: &IncrementalParams<T>,
    ws: &mut Workspace<'_, T>,
    pair: (u16, u16),
) -> Result<InitialPair<T>, (u32, InitialRefusal<T>)> {
    let config = params.config();
    let k = camera.intrinsics;
    let needed = config.min_initial_inliers;
    let too_few = |inliers: u32| {
        (
            inliers,
            InitialRefusal::TooFewInliers {
                pair,
                inliers,
                needed,
            },
        )
    };
    // Undistorted pixels of the tracks both views see.
    let mut m = 0usize;
    for i in 0..tracks.len() {
        let range = tracks.range(i);
        let obs = tracks.track(i);
        let norm = ws.normalized.get(range).unwrap_or(&[]);
        let find = |view: u16| {
            obs.iter()
                .zip(norm)
                .find_map(|(o, n)| if o.view == view { *n } else { None })
        };
        if let (Some(a), Some(b)) = (find(pair.0), find(pair.1))
            && let (Some(x1), Some(x2), Some(idx)) = (
                ws.first.get_mut(m),
                ws.second.get_mut(m),
                ws.index.get_mut(m),
            )
        {
            *x1 = k.normalized_to_pixel(&a);
            *x2 = k.normalized_to_pixel(&b);
            *idx = i as u32;
            m += 1;
        }
    }
    if (m as u64) < u64::from(needed).max(8) {
        return Err(too_few(m as u32));
    }
    let no_model = (0, InitialRefusal::NoModel { pair });
    let (Some(x1), Some(x2), Some(mask), Some(mask2)) = (
        ws.first.get(..m),
        ws.second.get(..m),
        ws.mask.get_mut(..m),
        ws.mask2.get_mut(..m),
    ) else {
        return Err(no_model);
    };
    let h_inliers = find_homography(x1, x2, params.essential(), mask2)
        .map(|(_, r)| r.inliers as u32)
        .unwrap_or(0);
    let Ok((e, report)) = find_essential(&k, &k, x1, x2, params.essential(), mask) else {
        // No essential matrix (e.g. no motion at all): if a homography explains most of the
        // correspondences, that is why.
        return Err(if 2 * u64::from(h_inliers) >= m as u64 {
            (
                h_inliers,
                InitialRefusal::Planar {
                    pair,
                    ratio: T::one(),
                },
            )
        } else {
            no_model
        });
    };
    let essential_inliers = report.inliers as u32;
    let Ok(rel) = recover_pose(&e, &k, &k, x1, x2, config.max_depth, mask) else {
        return Err(too_few(0));
    };
    let inliers = mask.iter().filter(|&&b| b).count() as u32;
    if inliers < needed {
        return Err(too_few(inliers));
    }
    let ratio = T::lit(f64::from(h_inliers)) / T::lit(f64::from(essential_inliers.max(1)));
    if ratio > config.max_homography_ratio {
        return Err((inliers, InitialRefusal::Planar { pair, ratio }));
    }
    // Median triangulation angle of the inliers.
    let pose = Pose::from_isometry(*rel.pose.isometry());
    let world = Pose::identity();
    let centre = pose.camera_center();
    let mut n = 0usize;
    for (j, &inlier) in mask.iter().enumerate() {
        if !inlier {
            continue;
        }
        let (Some(a), Some(b)) = (x1.get(j), x2.get(j)) else {
            continue;
        };
        let (Ok(na), Ok(nb)) = (k.pixel_to_normalized(a), k.pixel_to_normalized(b)) else {
            continue;
        };
        let Ok(t) = triangulate_optimal(&world, &pose, &na, &nb) else {
            continue;
        };
        let (ra, rb) = (t.point.coords, t.point - centre);
        let cos = ra.dot(&rb) / (ra.norm() * rb.norm());
        if let Some(slot) = ws.angles.get_mut(n)
            && cos.finite()
        {
            *slot = cos.clamp(-T::one(), T::one()).acos();
            n += 1;
        }
    }
    let median = median(ws.angles.get(..n).unwrap_or(&[]));
    if median < config.min_initial_angle {
        return Err((
            inliers,
            InitialRefusal::LowParallax {
                pair,
                median_angle: median,
            },
        ));
    }
    Ok(InitialPair {
        views: pair,
        pose,
        inliers,
    })
}

/// The median (lower middle element) of `values`, by bisection on the value: 60 halvings of
/// `[min, max]` counting the elements below, without sorting (no scratch, no panic path);
/// 0 for an empty slice.
fn median<T: Real>(values: &[T]) -> T {
    let (Some(lo), Some(hi)) = (
        values.iter().copied().reduce(|a, b| a.min(b)),
        values.iter().copied().reduce(|a, b| a.max(b)),
    ) else {
        return T::zero();
    };
    // The smallest value `m` with at least `⌊n/2⌋ + 1` elements `≤ m`.
    let rank = values.len() / 2 + 1;
    let (mut lo, mut hi) = (lo, hi);
    for _ in 0..60 {
        let mid = (lo + hi) * T::lit(0.5);
        if values.iter().filter(|&&x| x <= mid).count() >= rank {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_is_the_middle_element() {
        assert_eq!(median::<f64>(&[]), 0.0);
        assert!((median(&[3.0f64, 1.0, 2.0]) - 2.0).abs() < 1e-12);
        assert!((median(&[4.0f64, 1.0, 3.0, 2.0]) - 3.0).abs() < 1e-12);
    }
}
