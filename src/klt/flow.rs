//! The per-point work arrays of a multi-point flow step ([`FlowBuffers`], seen through
//! [`FlowBuffersView`]) and what they carry from frame to frame ([`FlowItem`]): the flow
//! [`crate::target::PlanarTarget`] and [`super::Tracker`] run each frame, beside the pyramid
//! driver it calls.
//!
//! As `heapless::Vec` and `VecView`: the owner holds the capacity `N` in its type, and the
//! step itself runs on the view, one copy of the code whatever `N`.

use heapless::VecView;

use super::arith::{Coordinate, FlowArith};
use super::cache::{TemplateCache, templates_len};
#[cfg(doc)]
use super::lk::calc_flow;
use super::lk::{Keep, forward_backward_keeping, run_native};
use super::{Borders, Flow, FlowStatus, Gradients, LkParams, Templates};
use crate::pyramid::Pyramid;
use crate::{Error, Result};

/// Something [`FlowBuffersView::track`] moves from frame to frame: where it is, and what its
/// flow does to it.
pub trait FlowItem<C> {
    /// Its position `[x, y]` in the previous frame.
    fn position(&self) -> [C; 2];
    /// Takes the flow that carried it into the next frame (only tracked items get one).
    fn moved(&mut self, flow: &Flow<C>);
}

/// The per-point work arrays of one multi-point flow step, for up to `N` points: their start
/// positions, the forward flows and, for the forward-backward check, the backward flows. The
/// step runs on its [`view`](Self::as_mut_view).
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

    /// The buffers as a view of capacity `N`, what the flow step takes.
    pub fn as_mut_view(&mut self) -> FlowBuffersView<'_, A> {
        FlowBuffersView {
            pts: &mut self.pts,
            flows: &mut self.flows,
            back: &mut self.back,
        }
    }
}

/// [`FlowBuffers`] without its capacity in the type: three borrowed arrays of one length, the
/// capacity.
#[derive(Debug)]
pub struct FlowBuffersView<'a, A: FlowArith> {
    pts: &'a mut [[A::Coord; 2]],
    flows: &'a mut [Flow<A::Coord>],
    back: &'a mut [Flow<A::Coord>],
}

impl<A: FlowArith> FlowBuffersView<'_, A> {
    /// How many points the buffers hold (the owner's `N`).
    pub fn capacity(&self) -> usize {
        self.pts.len()
    }

    /// Tracks `points` from `prev` to `next` with [`calc_flow`] (from the
    /// points themselves: `use_initial_flow` is ignored), then the forward-backward check when
    /// `lk.fb_threshold` is set; returns one flow per point. `templates`: whether the backward
    /// pass's templates are kept for the next call's forward pass ([`Templates::Keep`], the
    /// same flows to the bit); `scratch`: at least [`scratch_len`](super::scratch_len)`(lk.win)`.
    ///
    /// Errors: [`Error::LengthMismatch`] for more points than the capacity;
    /// [`Error::BufferTooSmall`]`("templates")` for a [`Templates::Keep`] buffer shorter than
    /// [`templates_len`]`(lk.win, lk.max_level, capacity)`; as
    /// [`calc_flow`].
    pub fn run(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        points: impl ExactSizeIterator<Item = [A::Coord; 2]>,
        lk: &LkParams,
        templates: Templates<'_>,
        scratch: &mut [i16],
    ) -> Result<&[Flow<A::Coord>]> {
        let (cap, n) = (self.capacity(), points.len());
        let (Some(pts), Some(flows), Some(back)) = (
            self.pts.get_mut(..n),
            self.flows.get_mut(..n),
            self.back.get_mut(..n),
        ) else {
            return Err(Error::LengthMismatch);
        };
        let lk = lk.with_initial_flow(false);
        let cfg = lk.config();
        let mut cache = match templates {
            Templates::Compute => None,
            Templates::Keep(buf) if buf.len() < templates_len(cfg.win, cfg.max_level, cap) => {
                return Err(Error::BufferTooSmall("templates"));
            }
            // `None` only without a slot (no capacity): nothing to keep.
            Templates::Keep(buf) => TemplateCache::new(buf, cfg.win, cfg.max_level + 1, cap),
        };
        for (p, q) in pts.iter_mut().zip(points) {
            *p = q;
        }
        let (grads, p) = (&mut Gradients::PerWindow, |k: usize| pts.get(k).copied());
        let mut keep = cache.as_ref().map_or(Keep::Off, Keep::Use);
        let no = &mut Borders::None;
        run_native::<A>(prev, next, p, flows, &lk, grads, no, scratch, &mut keep)?;
        let mut keep = cache.as_mut().map_or(Keep::Off, Keep::Fill);
        forward_backward_keeping::<A>(
            prev, next, pts, flows, back, &lk, grads, scratch, &mut keep,
        )?;
        Ok(flows)
    }

    /// Moves every item of `items` (at most the capacity) from `prev` to `next`
    /// ([`Self::run`] on their [`FlowItem::position`]s), keeps those [`FlowStatus::Tracked`]
    /// in order and hands each kept one its flow through [`FlowItem::moved`]; the rest are
    /// removed. Returns how many remain. Errors: as [`Self::run`].
    pub fn track<T: FlowItem<A::Coord>>(
        &mut self,
        prev: &Pyramid<'_>,
        next: &Pyramid<'_>,
        items: &mut VecView<T>,
        lk: &LkParams,
        templates: Templates<'_>,
        scratch: &mut [i16],
    ) -> Result<usize> {
        let points = items.iter().map(T::position);
        let flows = self.run(prev, next, points, lk, templates, scratch)?;
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

#[cfg(test)]
mod tests {
    use super::super::{Fixed, LkConfig, Q16, scratch_len};
    use super::*;
    use crate::image::ImageView;
    use std::vec::Vec;

    /// A smooth texture moved by `(dx, dy)`.
    fn scene(w: usize, h: usize, dx: f64, dy: f64) -> Vec<u8> {
        (0..w * h)
            .map(|i| {
                let (u, t) = ((i % w) as f64 - dx, (i / w) as f64 - dy);
                let s =
                    128.0 + 50.0 * (u * 0.21).sin() * (t * 0.17).cos() + 40.0 * (u * 0.07).cos();
                s.round() as u8
            })
            .collect()
    }

    /// [`Templates::Keep`] over frames a -> b -> a -> b gives the flows of
    /// [`Templates::Compute`], flow for flow; a buffer one element short is refused before
    /// anything runs.
    #[test]
    fn kept_templates_are_an_explicit_buffer() {
        let (w, h) = (96, 72);
        let (a, b) = (scene(w, h, 0.0, 0.0), scene(w, h, 1.25, -0.75));
        let mut bufs = [0, 1].map(|_| std::vec![0u8; crate::pyramid::buffer_len(w, h, 2)]);
        let [ba, bb] = &mut bufs;
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), ba, 2).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), bb, 2).unwrap();
        let cfg = LkConfig {
            win: 9,
            max_level: 1,
            fb_threshold: Some(0.5),
            ..LkConfig::default()
        };
        let lk = cfg.check().unwrap();
        let pts: Vec<[Q16; 2]> = (0..12)
            .map(|k| [10 + 7 * k, 12 + 4 * k].map(Q16::from_int))
            .collect();
        let (mut b1, mut b2) = (
            FlowBuffers::<Fixed, 16>::new(),
            FlowBuffers::<Fixed, 16>::new(),
        );
        let (mut v1, mut v2) = (b1.as_mut_view(), b2.as_mut_view());
        assert_eq!(v1.capacity(), 16);
        let mut s = std::vec![0i16; scratch_len(cfg.win)];
        let need = super::super::templates_len(cfg.win, cfg.max_level, 16);
        let mut short = std::vec![0i16; need - 1];
        let t = Templates::Keep(&mut short);
        let r = v2.run(&pa, &pb, pts.iter().copied(), &lk, t, &mut s);
        assert_eq!(r.err(), Some(Error::BufferTooSmall("templates")));
        let mut kept = std::vec![0i16; need];
        let (mut p1, mut p2) = (pts.clone(), pts);
        for (prev, next) in [(&pa, &pb), (&pb, &pa), (&pa, &pb)] {
            let t = Templates::Compute;
            let f1 = v1
                .run(prev, next, p1.iter().copied(), &lk, t, &mut s)
                .unwrap();
            let t = Templates::Keep(&mut kept);
            let f2 = v2
                .run(prev, next, p2.iter().copied(), &lk, t, &mut s)
                .unwrap();
            assert_eq!(f1, f2);
            assert!(
                f1.iter()
                    .filter(|f| f.status == FlowStatus::Tracked)
                    .count()
                    >= 8
            );
            p1 = f1.iter().map(|f| [f.x, f.y]).collect();
            p2 = f2.iter().map(|f| [f.x, f.y]).collect();
        }
        let more = [[Q16::ZERO; 2]; 17].into_iter();
        let r = v1.run(&pa, &pb, more, &lk, Templates::Compute, &mut s);
        assert_eq!(r.err(), Some(Error::LengthMismatch));
    }
}
