//! Tracks from pairwise feature matches: union-find over the features of every view, in
//! caller-owned memory.
//!
//! The features of all views are numbered one after another (`node = offset(view) + feature`).
//! Each verified match joins two nodes ([`TrackBuilder::join`]); a connected component is a
//! track. A component that holds two features of one view (matches that disagree, e.g. on
//! repeated texture) is inconsistent: it is dropped whole rather than split by guesswork, as
//! COLMAP's track builder does with conflicting tracks. [`TrackBuilder::label`] numbers the
//! consistent components seen by at least two views.
//!
//! Memory: two `u32` per feature ([`TrackBuilder::words`]).

use crate::{Error, Result};

/// A node's label when it is in no kept track.
pub const NO_TRACK: u32 = u32::MAX;

/// Union-find over `nodes` features (see the module docs).
#[derive(Debug)]
pub struct TrackBuilder<'a> {
    parent: &'a mut [u32],
    scratch: &'a mut [u32],
}

impl<'a> TrackBuilder<'a> {
    /// `u32` words each of `parent` and `scratch` must hold for `nodes` features.
    pub const fn words(nodes: usize) -> usize {
        nodes
    }

    /// Starts with every node alone. `parent` and `scratch` must be of equal length, the node
    /// count, at most `u32::MAX` (which is [`NO_TRACK`]).
    ///
    /// Errors: [`Error::LengthMismatch`] for slices of different lengths or too many nodes.
    pub fn new(parent: &'a mut [u32], scratch: &'a mut [u32]) -> Result<Self> {
        if parent.len() != scratch.len() || u32::try_from(parent.len()).is_err() {
            return Err(Error::LengthMismatch);
        }
        for (i, p) in parent.iter_mut().enumerate() {
            *p = i as u32;
        }
        Ok(Self { parent, scratch })
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.parent.len()
    }

    /// No node.
    pub fn is_empty(&self) -> bool {
        self.parent.is_empty()
    }

    /// The root of `node`'s component, halving the path on the way.
    fn root(&mut self, node: u32) -> Option<u32> {
        let mut x = node;
        // A parent chain is at most `len` long; the bound keeps the loop finite on any input.
        for _ in 0..=self.parent.len() {
            let p = *self.parent.get(x as usize)?;
            if p == x {
                return Some(x);
            }
            let gp = *self.parent.get(p as usize)?;
            *self.parent.get_mut(x as usize)? = gp;
            x = gp;
        }
        None
    }

    /// Joins the components of nodes `a` and `b` (a match).
    ///
    /// Errors: [`Error::InvalidParameter`]`("tracks.node")` for a node out of range.
    pub fn join(&mut self, a: u32, b: u32) -> Result<()> {
        let bad = Error::InvalidParameter("tracks.node");
        let (ra, rb) = (self.root(a).ok_or(bad)?, self.root(b).ok_or(bad)?);
        // The smaller root wins, so that the labels do not depend on the order of the joins
        // more than the components do.
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        if lo != hi {
            *self.parent.get_mut(hi as usize).ok_or(bad)? = lo;
        }
        Ok(())
    }

    /// Labels every node with its track, `0..tracks` in order of each track's first node, or
    /// [`NO_TRACK`] (alone, or in an inconsistent component); returns the number of tracks.
    /// `offsets` are the first node of each view and the node count at the end
    /// (`offsets = [0, n₀, n₀ + n₁, ..., len]`); `labels` has one word per node.
    ///
    /// Errors: [`Error::LengthMismatch`] when `labels` is not one per node or `offsets` does not
    /// run from 0 to the node count without decreasing.
    pub fn label(mut self, offsets: &[u32], labels: &mut [u32]) -> Result<usize> {
        let n = self.parent.len();
        if labels.len() != n
            || offsets.first() != Some(&0)
            || offsets.last().map(|&l| l as usize) != Some(n)
            || offsets.windows(2).any(|w| w.first() > w.get(1))
        {
            return Err(Error::LengthMismatch);
        }
        // Pass 1: flatten, and find components seen twice in one view. `scratch[root]` holds
        // the last view that saw the component, plus one (0: none yet); views go in order, so
        // a repeat is the same value again. `labels[root]` counts the members (saturating).
        self.scratch.iter_mut().for_each(|s| *s = 0);
        labels.iter_mut().for_each(|l| *l = 0);
        const CONFLICT: u32 = u32::MAX;
        for (view, w) in offsets.windows(2).enumerate() {
            let [a, b] = w else { continue };
            for node in *a..*b {
                let r = self.root(node).ok_or(Error::LengthMismatch)?;
                if let Some(p) = self.parent.get_mut(node as usize) {
                    *p = r;
                }
                let mark = self
                    .scratch
                    .get_mut(r as usize)
                    .ok_or(Error::LengthMismatch)?;
                let v = view as u32 + 1;
                if *mark == v || *mark == CONFLICT {
                    *mark = CONFLICT;
                } else {
                    *mark = v;
                }
                let count = labels.get_mut(r as usize).ok_or(Error::LengthMismatch)?;
                *count = count.saturating_add(1);
            }
        }
        // Pass 2: a root keeps its component when consistent and of two or more nodes; its
        // track number goes into `scratch[root]` (shifted by one so that 0 means "none").
        for r in 0..n {
            let (Some(mark), Some(&count)) = (self.scratch.get_mut(r), labels.get(r)) else {
                continue;
            };
            let root = self.parent.get(r).is_some_and(|&p| p as usize == r);
            *mark = u32::from(root && *mark != CONFLICT && count >= 2);
        }
        let mut tracks = 0u32;
        for r in 0..n {
            if let Some(mark) = self.scratch.get_mut(r)
                && *mark == 1
            {
                tracks += 1;
                *mark = tracks;
            }
        }
        // Pass 3: every node takes its root's track (roots are set, so one lookup).
        for (node, label) in labels.iter_mut().enumerate() {
            let r = self.parent.get(node).copied().unwrap_or(node as u32);
            *label = match self.scratch.get(r as usize) {
                Some(&t) if t > 0 => t - 1,
                _ => NO_TRACK,
            };
        }
        Ok(tracks as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_become_tracks_and_conflicts_are_dropped() {
        // Views of 3, 2 and 3 features: nodes 0..3, 3..5, 5..8.
        let offsets = [0, 3, 5, 8];
        let (mut parent, mut scratch, mut labels) = ([0u32; 8], [0u32; 8], [0u32; 8]);
        let mut b = TrackBuilder::new(&mut parent, &mut scratch).unwrap();
        // Track: 0-3-5. Conflict: 1-4, 4-6, 6-2 (view 0 twice). Alone: 7.
        for (x, y) in [(0, 3), (5, 3), (1, 4), (4, 6), (2, 6)] {
            b.join(x, y).unwrap();
        }
        assert_eq!(b.join(0, 8), Err(Error::InvalidParameter("tracks.node")));
        let n = b.label(&offsets, &mut labels).unwrap();
        assert_eq!(n, 1);
        assert_eq!(
            labels,
            [0, NO_TRACK, NO_TRACK, 0, NO_TRACK, 0, NO_TRACK, NO_TRACK]
        );
    }

    #[test]
    fn bad_layout_is_an_error() {
        let (mut parent, mut scratch, mut labels) = ([0u32; 4], [0u32; 3], [0u32; 4]);
        assert!(TrackBuilder::new(&mut parent, &mut scratch).is_err());
        let mut scratch = [0u32; 4];
        let b = TrackBuilder::new(&mut parent, &mut scratch).unwrap();
        assert_eq!(b.label(&[0, 5], &mut labels), Err(Error::LengthMismatch));
    }
}
