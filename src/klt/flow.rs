//! The per-point work arrays of a multi-point flow step ([`FlowBuffers`]) and what they carry
//! from frame to frame ([`FlowItem`]): the flow [`crate::target::PlanarTarget`] and
//! [`super::Tracker`] run each frame, beside the pyramid driver it calls.

use heapless::Vec;

use super::arith::{Coordinate, FlowArith};
use super::cache::{TemplateCache, cache_len};
#[cfg(doc)]
use super::lk::calc_flow;
use super::lk::{Keep, forward_backward_keeping, run_native};
use super::{Borders, Flow, FlowStatus, Gradients, LkParams};
use crate::pyramid::Pyramid;
use crate::{Error, Result};

/// Something [`FlowBuffers::track`] moves from frame to frame: where it is, and what its flow
/// does to it.
pub trait FlowItem<C> {
    /// Its position `[x, y]` in the previous frame.
    fn position(&self) -> [C; 2];
    /// Takes the flow that carried it into the next frame (only tracked items get one).
    fn moved(&mut self, flow: &Flow<C>);
}

/// `i16` elements of scratch for [`FlowBuffers`] of `points` points that keep the templates
/// of each forward-backward check for the next frame's forward pass: the kernel's
/// [`scratch_len`](super::scratch_len)`(win)` and one slot a point and level. With the check
/// on and the points carried from frame to frame, the forward pass then interpolates only the
/// templates of new points and of windows at the image border; the flows are the same to the
/// bit (each kept template is checked against the pixels it was made from).
pub const fn kept_scratch_len(win: usize, max_level: usize, points: usize) -> usize {
    super::scratch_len(win) + cache_len(win, max_level + 1, points)
}

/// The per-point work arrays of one multi-point flow step, for up to `N` points: their start
/// positions, the forward flows and, for the forward-backward check, the backward flows.
#[derive(Debug, Clone)]
pub struct FlowBuffers<A: FlowArith, const N: usize> {
    pts: [[A::Coord; 2]; N],
    flows: [Flow<A::Coord>; N],
    back: [Flow<A::Coord>; N],
}

impl<A: FlowArith, const N: usize> Default for FlowBuffers<A, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<A: FlowArith, const N: usize> FlowBuffers<A, N> {
    /// Zeroed buffers (`const`: they can live in a zero-initialised `static`).
    pub const fn new() -> Self {
        let zero = Flow {
            x: A::Coord::ZERO,
            y: A::Coord::ZERO,
            status: FlowStatus::Tracked,
            err: A::Coord::ZERO,
        };
        Self {
            pts: [[A::Coord::ZERO; 2]; N],
            flows: [zero; N],
            back: [zero; N],
        }
    }

    /// Tracks `points` (the first `n`) from `prev` to `next` with [`calc_flow`] (from the
    /// points themselves: `use_initial_flow` is ignored), then the forward-backward check when
    /// `lk.fb_threshold` is set; returns one flow per point. `scratch`: at least
    /// [`scratch_len`](super::scratch_len)`(lk.win)`; from [`kept_scratch_len`]`(lk.win,
    /// lk.max_level, N)` on, the backward pass's templates are kept for the next call's
    /// forward pass (the same flows, to the bit). Errors: [`Error::LengthMismatch`] when
    /// `n > N`; as [`calc_flow`].
    pub fn run(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        n: usize,
        points: impl Iterator<Item = [A::Coord; 2]>,
        lk: &LkParams,
        scratch: &mut [i16],
    ) -> Result<&[Flow<A::Coord>]> {
        let (Some(pts), Some(flows), Some(back)) = (
            self.pts.get_mut(..n),
            self.flows.get_mut(..n),
            self.back.get_mut(..n),
        ) else {
            return Err(Error::LengthMismatch);
        };
        for (p, q) in pts.iter_mut().zip(points) {
            *p = q;
        }
        let lk = lk.with_initial_flow(false);
        // Scratch beyond the kernel's keeps templates (`kept_scratch_len`).
        let cfg = lk.config();
        let at = super::scratch_len(cfg.win).min(scratch.len());
        let (scratch, rest) = scratch.split_at_mut(at);
        let mut cache = TemplateCache::new(rest, cfg.win, cfg.max_level + 1, N);
        let (grads, p) = (&mut Gradients::PerWindow, |k: usize| pts.get(k).copied());
        let mut keep = cache.as_ref().map_or(Keep::Off, Keep::Use);
        run_native::<A>(
            prev,
            next,
            p,
            flows,
            &lk,
            grads,
            &mut Borders::None,
            scratch,
            &mut keep,
        )?;
        let mut keep = cache.as_mut().map_or(Keep::Off, Keep::Fill);
        forward_backward_keeping::<A>(
            prev, next, pts, flows, back, &lk, grads, scratch, &mut keep,
        )?;
        Ok(flows)
    }

    /// Moves every item of `items` (at most `N`) from `prev` to `next` ([`Self::run`] on their
    /// [`FlowItem::position`]s), keeps those [`FlowStatus::Tracked`] in order and hands each
    /// kept one its flow through [`FlowItem::moved`]; the rest are removed. Returns how many
    /// remain. Errors: as [`Self::run`].
    pub fn track<T: FlowItem<A::Coord>, const M: usize>(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        items: &mut Vec<T, M>,
        lk: &LkParams,
        scratch: &mut [i16],
    ) -> Result<usize> {
        let n = items.len();
        let flows = self.run(prev, next, n, items.iter().map(T::position), lk, scratch)?;
        let mut k = 0usize;
        items.retain_mut(|t| {
            let f = flows.get(k);
            k += 1;
            match f {
                Some(f) if f.status == FlowStatus::Tracked => {
                    t.moved(f);
                    true
                }
                _ => false,
            }
        });
        Ok(items.len())
    }
}
