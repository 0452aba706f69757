//! Tracks across frames: ids, ages, removal of lost tracks, replenishment from new corners.
//!
//! The tracker holds no image. Each frame the caller builds the new pyramid into one of two
//! buffers and re-wraps the previous frame's (already built) pyramid with
//! [`Pyramid::from_buffer`](crate::pyramid::Pyramid::from_buffer), swapping the two buffers
//! after the update: nothing is copied or recomputed. Nor does it hold its configuration:
//! [`TrackerConfig::check`] gives the [`TrackerParams`] that every call takes.

use heapless::Vec;

#[cfg(doc)]
use super::FlowStatus;
use super::arith::{Coordinate, FlowArith};
#[cfg(doc)]
use super::flow::FlowBuffersView;
use super::flow::{FlowBuffers, FlowItem};
use super::{Flow, LkConfig, LkParams, Templates};
use crate::corners::{Corner, CornerConfig, CornerParams, good_features};
use crate::image::ImageView;
use crate::pyramid::Pyramid;
use crate::{Error, Result};

/// One tracked feature.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Track<C> {
    /// Unique id, increasing from 0 in order of creation.
    pub id: u32,
    /// Column in the latest frame.
    pub x: C,
    /// Row in the latest frame.
    pub y: C,
    /// Frames tracked since detection (0 in the frame it was detected in).
    pub age: u32,
    /// Error of the last flow step (mean absolute difference, grey levels).
    pub err: C,
}

impl<C: Copy> FlowItem<C> for Track<C> {
    fn position(&self) -> [C; 2] {
        [self.x, self.y]
    }

    /// The new position and flow error; one frame older.
    fn moved(&mut self, flow: &Flow<C>) {
        self.x = flow.x;
        self.y = flow.y;
        self.err = flow.err;
        self.age = self.age.saturating_add(1);
    }
}

/// Parameters of a [`Tracker`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerConfig {
    /// The flow between consecutive frames (its `fb_threshold` enables the
    /// forward-backward check).
    pub lk: LkConfig,
    /// Detection of new features.
    pub corners: CornerConfig,
    /// Detect new features when fewer tracks than this remain.
    pub replenish_below: usize,
    /// Never hold more tracks than this (0: the capacity `N`).
    pub max_tracks: usize,
}

impl TrackerConfig {
    /// Checks every field once: the tracker's calls take the checked [`TrackerParams`].
    ///
    /// Errors: as [`LkConfig::check`] and [`CornerConfig::check`].
    pub fn check(&self) -> Result<TrackerParams> {
        self.lk.check()?;
        self.corners.check()?;
        Ok(TrackerParams(*self))
    }
}

/// A [`TrackerConfig`] that passed [`TrackerConfig::check`]: what [`Tracker::update`] and
/// [`Tracker::replenish`] take, kept beside the tracker's state rather than in it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerParams(TrackerConfig);

impl TrackerParams {
    /// The checked configuration.
    pub const fn config(&self) -> &TrackerConfig {
        &self.0
    }

    /// The checked flow parameters ([`TrackerConfig::lk`]).
    pub const fn lk(&self) -> LkParams {
        // Checked with the rest by `TrackerConfig::check`.
        LkParams(self.0.lk)
    }

    /// The most tracks held: `max_tracks`, at most (and when 0) the capacity `n`.
    fn cap(&self, n: usize) -> usize {
        match self.0.max_tracks {
            0 => n,
            m => m.min(n),
        }
    }
}

impl Default for TrackerParams {
    /// The checked [`TrackerConfig::default`].
    fn default() -> Self {
        Self(TrackerConfig::default())
    }
}

impl TryFrom<TrackerConfig> for TrackerParams {
    type Error = Error;
    fn try_from(c: TrackerConfig) -> Result<Self> {
        c.check()
    }
}

impl Default for TrackerConfig {
    fn default() -> Self {
        Self {
            lk: LkConfig::default(),
            corners: CornerConfig::default(),
            replenish_below: usize::MAX,
            max_tracks: 0,
        }
    }
}

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerStats {
    /// Tracks carried into the new frame.
    pub tracked: usize,
    /// Tracks removed (lost, textureless, inconsistent).
    pub lost: usize,
    /// New tracks from detection.
    pub added: usize,
}

/// Up to `N` tracks and their per-point work buffers (no allocation; `size_of` is all of its
/// RAM). The configuration is apart: each call takes the [`TrackerParams`].
#[derive(Debug, Clone)]
pub struct Tracker<A: FlowArith, const N: usize> {
    tracks: Vec<Track<A::Coord>, N>,
    buffers: FlowBuffers<A, N>,
    next_id: u32,
}

impl<A: FlowArith, const N: usize> Default for Tracker<A, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<A: FlowArith, const N: usize> Tracker<A, N> {
    /// An empty tracker (`const`: it can live in a zero-initialised `static`).
    pub const fn new() -> Self {
        Self {
            tracks: Vec::new(),
            buffers: FlowBuffers::new(),
            next_id: 0,
        }
    }

    /// The live tracks.
    pub fn tracks(&self) -> &[Track<A::Coord>] {
        &self.tracks
    }

    /// Forgets every track (ids keep increasing).
    pub fn clear(&mut self) {
        self.tracks.clear();
    }

    /// Moves every track from `prev` to `next`; removes those not [`FlowStatus::Tracked`].
    /// `templates` and `scratch`: as [`FlowBuffersView::run`] (for `N` points). Errors as
    /// [`FlowBuffersView::run`].
    pub fn update(
        &mut self,
        params: &TrackerParams,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        templates: Templates<'_>,
        scratch: &mut [i16],
    ) -> Result<TrackerStats> {
        let n = self.tracks.len();
        let tracks = self.tracks.as_mut_view();
        let (lk, mut buffers) = (params.lk(), self.buffers.as_mut_view());
        let tracked = buffers.track(prev, next, tracks, &lk, templates, scratch)?;
        Ok(TrackerStats {
            tracked,
            lost: n - tracked,
            added: 0,
        })
    }

    /// When fewer than `replenish_below` tracks remain, detects corners of `frame` away from
    /// the live tracks (`corners.min_distance`) and adds them as new tracks, up to
    /// `corners.max_corners` per call and `max_tracks` (at most `N`) in all. `candidates` and
    /// `scratch` as [`good_features`]. Returns the number added.
    pub fn replenish(
        &mut self,
        params: &TrackerParams,
        frame: &ImageView<'_, u8>,
        candidates: &mut [Corner],
        scratch: &mut [u32],
    ) -> Result<usize> {
        let (cfg, cap) = (params.config(), params.cap(N));
        if self.tracks.len() >= cfg.replenish_below.min(cap) {
            return Ok(0);
        }
        let mut found: Vec<Corner, N> = Vec::new();
        // `params` holds the corner configuration checked (`TrackerConfig::check`).
        let ccfg = CornerParams::assume_checked(cfg.corners).up_to(cap - self.tracks.len());
        let existing = self.tracks.iter().map(|t| [t.x.round(), t.y.round()]);
        good_features(frame, &ccfg, existing, &mut found, candidates, scratch)?;
        let mut added = 0;
        for c in &found {
            let t = Track {
                id: self.next_id,
                x: A::Coord::from_px(i32::from(c.x)),
                y: A::Coord::from_px(i32::from(c.y)),
                age: 0,
                err: A::Coord::default(),
            };
            if self.tracks.push(t).is_err() {
                break;
            }
            self.next_id = self.next_id.wrapping_add(1);
            added += 1;
        }
        Ok(added)
    }
}

#[cfg(test)]
mod tests {
    use super::super::Fixed;
    use super::*;

    #[test]
    fn tracks_a_shifting_scene_and_replenishes() {
        let (w, h) = (120usize, 90usize);
        let frame = |dx: f64| -> std::vec::Vec<u8> {
            (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f64 - dx, (i / w) as f64);
                    let v = 128.0
                        + 60.0 * (x * 0.3).sin() * (y * 0.25).cos()
                        + 40.0 * ((x + y) * 0.13).sin();
                    v.round() as u8
                })
                .collect()
        };
        let f0 = frame(0.0);
        let f1 = frame(1.5);
        let cfg = TrackerConfig {
            lk: LkConfig {
                win: 11,
                max_level: 1,
                fb_threshold: Some(1.0),
                ..LkConfig::default()
            },
            corners: CornerConfig {
                quality: 0.05,
                min_distance: 8,
                max_corners: 0,
            },
            replenish_below: 20,
            max_tracks: 0,
        };
        let params = cfg.check().unwrap();
        let mut t: Tracker<Fixed, 32> = Tracker::new();
        let mut cands = [Corner::default(); 256];
        let mut cs = std::vec![0u32; crate::corners::scratch_len(w)];
        let v0 = ImageView::packed(&f0, w, h).unwrap();
        let added = t.replenish(&params, &v0, &mut cands, &mut cs).unwrap();
        assert!(added >= 20, "{added}");
        let before: std::vec::Vec<_> = t.tracks().to_vec();
        let mut b0 = std::vec![0u8; crate::pyramid::buffer_len(w, h, 2)];
        let mut b1 = std::vec![0u8; crate::pyramid::buffer_len(w, h, 2)];
        Pyramid::build(v0, &mut b0, 2).unwrap();
        let p1 = Pyramid::build(ImageView::packed(&f1, w, h).unwrap(), &mut b1, 2).unwrap();
        let p0 = Pyramid::from_buffer(v0, &b0, 2).unwrap();
        let mut s = std::vec![0i16; super::super::scratch_len(11)];
        let st = t
            .update(&params, &p0, &p1, Templates::Compute, &mut s)
            .unwrap();
        assert_eq!(st.tracked + st.lost, before.len());
        assert!(st.tracked * 10 >= before.len() * 8, "{st:?}");
        for tr in t.tracks() {
            let b = before.iter().find(|b| b.id == tr.id).unwrap();
            assert_eq!(tr.age, 1);
            let dx = (tr.x - b.x).to_f32();
            let dy = (tr.y - b.y).to_f32();
            // Content enters at the right edge: judge only windows inside the frame.
            let bx = b.x.to_f32();
            if bx > 8.0 && bx < (w - 10) as f32 {
                assert!((dx - 1.5).abs() < 0.1 && dy.abs() < 0.1, "{b:?}: {dx} {dy}");
            }
        }
    }
}

#[cfg(test)]
mod params {
    use super::*;

    /// The default configuration passes its check; a bad field fails it, named.
    #[test]
    fn checked_once_into_params() {
        let cfg = TrackerConfig::default();
        assert_eq!(cfg.check(), Ok(TrackerParams::default()));
        assert_eq!(TrackerParams::try_from(cfg), Ok(TrackerParams::default()));
        assert_eq!(TrackerParams::default().lk(), LkParams::default());
        let mut bad = cfg;
        bad.lk.win = 2;
        assert_eq!(bad.check(), Err(Error::InvalidParameter("lk.win")));
        let mut bad = cfg;
        bad.corners.quality = 0.0;
        assert_eq!(bad.check(), Err(Error::InvalidParameter("corners.quality")));
    }
}
