//! Tracks over any number of views, stored as one compressed row per track: the input of the
//! incremental reconstruction ([`super::reconstruct`]).
//!
//! Track `i` is `observations[starts[i] .. starts[i + 1]]`: each observation a view index and
//! the raw pixel where the track's scene point appears in that view. A track is seen at most
//! once per view and by at least two views (a track seen once constrains nothing).

use core::ops::Range;

use nalgebra::Point2;

use crate::scalar::Real;
use crate::{Error, Result};

/// Most views a [`TrackSet`] may name (view indices are `u16`).
pub const MAX_VIEWS: usize = u16::MAX as usize;

/// One observation of a track: the raw pixel (distortion not removed) in view `view`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Observation<T: Real = f32> {
    /// The view, `0..views`.
    pub view: u16,
    /// The pixel, `(column, row)`.
    pub pixel: Point2<T>,
}

/// A checked view of tracks over `views` views (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackSet<'a, T: Real = f32> {
    starts: &'a [u32],
    observations: &'a [Observation<T>],
    views: usize,
}

impl<'a, T: Real> TrackSet<'a, T> {
    /// Checks the layout once: `starts` non-empty, starting at 0, non-decreasing, ending at
    /// `observations.len()`; every track with at least two observations in distinct views, each
    /// `< views`; every pixel finite; `2 ≤ views ≤` [`MAX_VIEWS`].
    ///
    /// Errors: [`Error::InvalidParameter`]`("tracks.views")` for the view count,
    /// [`Error::LengthMismatch`] for a `starts` that does not index `observations` as stated,
    /// [`Error::InvalidParameter`]`("tracks.observations")` for a track seen fewer than twice,
    /// twice in one view, or in a view out of range, [`Error::NonFinite`] for a pixel.
    pub fn new_checked(
        starts: &'a [u32],
        observations: &'a [Observation<T>],
        views: usize,
    ) -> Result<Self> {
        if !(2..=MAX_VIEWS).contains(&views) {
            return Err(Error::InvalidParameter("tracks.views"));
        }
        let (Some(&first), Some(&last)) = (starts.first(), starts.last()) else {
            return Err(Error::LengthMismatch);
        };
        if first != 0 || usize::try_from(last).ok() != Some(observations.len()) {
            return Err(Error::LengthMismatch);
        }
        for w in starts.windows(2) {
            let [a, b] = w else { continue };
            if b < a {
                return Err(Error::LengthMismatch);
            }
            let track = observations
                .get(*a as usize..*b as usize)
                .ok_or(Error::LengthMismatch)?;
            if track.len() < 2 {
                return Err(Error::InvalidParameter("tracks.observations"));
            }
            for (k, o) in track.iter().enumerate() {
                if usize::from(o.view) >= views || track.iter().take(k).any(|p| p.view == o.view) {
                    return Err(Error::InvalidParameter("tracks.observations"));
                }
                if !(o.pixel.x.is_finite() && o.pixel.y.is_finite()) {
                    return Err(Error::NonFinite);
                }
            }
        }
        Ok(Self {
            starts,
            observations,
            views,
        })
    }

    /// Number of tracks.
    pub fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// No track at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of views.
    pub const fn views(&self) -> usize {
        self.views
    }

    /// Every observation, track after track.
    pub const fn observations(&self) -> &'a [Observation<T>] {
        self.observations
    }

    /// The range of track `i` in [`Self::observations`] (empty for an `i` out of range).
    pub fn range(&self, i: usize) -> Range<usize> {
        match (self.starts.get(i), self.starts.get(i + 1)) {
            (Some(&a), Some(&b)) => a as usize..b as usize,
            _ => 0..0,
        }
    }

    /// The observations of track `i` (empty for an `i` out of range).
    pub fn track(&self, i: usize) -> &'a [Observation<T>] {
        self.observations.get(self.range(i)).unwrap_or(&[])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(view: u16) -> Observation<f64> {
        Observation {
            view,
            pixel: Point2::new(1.0, 2.0),
        }
    }

    #[test]
    fn layout_is_checked() {
        let o = [obs(0), obs(1), obs(1), obs(2), obs(0)];
        let t = TrackSet::new_checked(&[0, 2, 5], &o, 3).unwrap();
        assert_eq!((t.len(), t.track(1).len(), t.range(7)), (2, 3, 0..0));
        fn bad<'a>(
            starts: &'a [u32],
            o: &'a [Observation<f64>],
            v: usize,
        ) -> Result<TrackSet<'a, f64>> {
            TrackSet::new_checked(starts, o, v)
        }
        assert_eq!(
            bad(&[0, 2, 5], &o, 1),
            Err(Error::InvalidParameter("tracks.views"))
        );
        assert_eq!(bad(&[0, 2, 4], &o, 3), Err(Error::LengthMismatch));
        assert_eq!(bad(&[0, 2, 1, 5], &o, 3), Err(Error::LengthMismatch));
        assert_eq!(bad(&[], &o, 3), Err(Error::LengthMismatch));
        let dup = [obs(0), obs(0)];
        let e = Err(Error::InvalidParameter("tracks.observations"));
        assert_eq!(bad(&[0, 2], &dup, 3), e);
        assert_eq!(bad(&[0, 1, 2], &[obs(0), obs(1)], 3), e);
        assert_eq!(bad(&[0, 2], &[obs(0), obs(3)], 3), e);
        let mut nan = [obs(0), obs(1)];
        nan[1].pixel.x = f64::NAN;
        assert_eq!(bad(&[0, 2], &nan, 3), Err(Error::NonFinite));
    }
}
