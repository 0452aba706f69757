//! The flow of many points through the pyramid levels: the driver that runs the
//! Lucas-Kanade iteration of [`super::lk`] for every point on every level, coarse to fine
//! ([`calc_flow`], [`forward_backward`]), and the per-point work arrays of a multi-point flow
//! step ([`FlowBuffers`], seen through [`FlowBuffersView`]) with what they carry from frame to
//! frame ([`FlowItem`]): the flow [`crate::target::PlanarTarget`] and [`super::Tracker`] run
//! each frame.
//!
//! As `heapless::Vec` and `VecView`: the owner holds the capacity `N` in its type, and the
//! step itself runs on the view, one copy of the code whatever `N`.

use heapless::VecView;

use super::arith::{Coordinate, FlowArith};
use super::cache::{TemplateCache, templates_len};
use super::kernel::{LANES, Lanes, Packed, Pixels, Window, border_width, bordered_len, pad};
use super::lk::{Keep, Level, track_point};
use super::{Borders, Flow, FlowStatus, Gradients, LkConfig, LkParams, Templates};
use crate::image::{ImageMut, ImageView};
use crate::pyramid::Pyramid;
use crate::{Error, Result};

/// The coarsest level OpenCV would use: `cfg.max_level`, capped by both pyramids and by the
/// rule that a level above 0 must be larger than the window in both directions.
fn usable_levels(prev: &Pyramid<'_>, next: &Pyramid<'_>, cfg: &LkConfig) -> usize {
    let mut top = 0;
    while top < cfg.max_level {
        let l = top + 1;
        match (prev.level(l), next.level(l)) {
            (Some(a), Some(_)) if a.width() > cfg.win && a.height() > cfg.win => top = l,
            _ => break,
        }
    }
    top
}

/// The driver: every level from the coarsest down, every point on each level.
#[allow(clippy::too_many_arguments)]
fn run<'s, A: FlowArith, W: Window<'s>>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    pts: impl Fn(usize) -> Option<[A::Coord; 2]>,
    flows: &mut [Flow<A::Coord>],
    params: &LkParams,
    grads: &mut Gradients<'_>,
    borders: &mut Borders<'_>,
    scratch: &'s mut [i16],
    keep: &mut Keep<'_, '_>,
) -> Result<()> {
    let cfg = params.config();
    let mut s = W::new(scratch, cfg.win)?;
    let top = usable_levels(prev, next, cfg);
    // The copies' buffer holds level 1's, the largest copied ([`Borders::Copy`]).
    if let Borders::Copy(buf) = borders
        && top > 0
    {
        let level1 = prev.level(1).map(|l| (l.width(), l.height()));
        let need = level1.map_or(0, |(w, h)| bordered_len(w, h, cfg.win));
        if buf.len() < need {
            return Err(Error::BufferTooSmall("borders"));
        }
    }
    let params = A::params(params, (cfg.win * cfg.win) as u32);
    for f in flows.iter_mut() {
        f.status = FlowStatus::Tracked;
        f.err = A::Coord::default();
    }
    for level in (0..=top).rev() {
        let (Some(i), Some(j)) = (prev.level(level), next.level(level)) else {
            return Err(Error::InvalidImage);
        };
        if (i.width(), i.height()) != (j.width(), j.height()) {
            return Err(Error::InvalidImage);
        }
        let len = i.width() * i.height();
        // Both rules weigh a pass over the level (`w h` pixels) against the windows' work
        // (`n (win + 1)²` for `n` points).
        let windows_outweigh = len <= flows.len().saturating_mul((cfg.win + 1) * (cfg.win + 1));
        let buf = match grads {
            Gradients::PerWindow => None,
            Gradients::PerLevel(buf) => Some(
                buf.get_mut(..len)
                    .ok_or(Error::BufferTooSmall("gradients"))?,
            ),
            Gradients::Auto(buf) => buf.get_mut(..len).filter(|_| windows_outweigh),
        };
        let grad = match buf {
            Some(b) => {
                crate::gradient::scharr_level(
                    &i,
                    &mut ImageMut::packed(b, i.width(), i.height())?,
                )?;
                Some(ImageView::packed(&*b, i.width(), i.height())?)
            }
            None => None,
        };
        // The level's copies with a reflected border, on the levels the rule of
        // `Borders::Copy` picks (the buffer was checked to hold them).
        let (bl, bd) = (
            bordered_len(i.width(), i.height(), cfg.win),
            border_width(cfg.win),
        );
        let copies = match borders {
            Borders::Copy(b) if W::BORDERED && level > 0 && windows_outweigh => {
                b.get_mut(..bl).and_then(|b| {
                    let (bi, bj) = b.split_at_mut(bl / 2);
                    pad(&i, bd, bi).zip(pad(&j, bd, bj))
                })
            }
            _ => None,
        };
        let (i, j) = match copies {
            Some((pi, pj)) => (Pixels::bordered(i, pi, bd), Pixels::bordered(j, pj, bd)),
            None => (Pixels::new(i), Pixels::new(j)),
        };
        let lv = Level::<A> {
            i,
            j,
            grad,
            level: level as u32,
            top: level == top,
            win: cfg.win,
            max_iter: cfg.max_iter,
            use_initial: cfg.use_initial_flow,
            compute_error: cfg.compute_error,
            params,
        };
        for (k, f) in flows.iter_mut().enumerate() {
            match pts(k) {
                Some(p) => track_point(&lv, &mut s, (k, p), f, keep),
                None => f.status = FlowStatus::OutOfBounds,
            }
        }
    }
    Ok(())
}

/// [`run`] with the kernel of this target ([`LANES`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn run_native<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    pts: impl Fn(usize) -> Option<[A::Coord; 2]>,
    flows: &mut [Flow<A::Coord>],
    params: &LkParams,
    grads: &mut Gradients<'_>,
    borders: &mut Borders<'_>,
    scratch: &mut [i16],
    keep: &mut Keep<'_, '_>,
) -> Result<()> {
    if LANES {
        run::<A, Lanes<'_>>(
            prev, next, pts, flows, params, grads, borders, scratch, keep,
        )
    } else {
        run::<A, Packed<'_>>(
            prev, next, pts, flows, params, grads, borders, scratch, keep,
        )
    }
}

/// Tracks `prev_pts` from `prev` to `next` (OpenCV's `calcOpticalFlowPyrLK`).
///
/// `flows[k]` receives the position of `prev_pts[k]` in `next` with its status and error
/// (with [`LkConfig::use_initial_flow`] it must hold the initial guesses on entry). Points are
/// full-resolution pixel coordinates, `(0, 0)` the centre of the top-left pixel. `grads` says
/// where the window derivatives come from and `borders` whether the coarse levels are copied
/// with a reflected border first ([`Borders::Copy`]: which levels, and the buffer's length);
/// neither changes a flow, to the bit. `scratch` holds at least
/// [`scratch_len`](super::scratch_len)`(win)` elements, whatever the number of points.
///
/// Errors: [`Error::LengthMismatch`] when the slices differ in length,
/// [`Error::BufferTooSmall`] for scratch shorter than [`scratch_len`](super::scratch_len)`(win)`,
/// a [`Gradients::PerLevel`] buffer or a [`Borders::Copy`] buffer too short,
/// [`Error::InvalidImage`] when the pyramids' levels differ in size. The configuration was
/// checked once by [`LkConfig::check`].
#[doc(alias = "calcOpticalFlowPyrLK")]
#[allow(clippy::too_many_arguments)]
pub fn calc_flow<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    prev_pts: &[[A::Coord; 2]],
    flows: &mut [Flow<A::Coord>],
    cfg: &LkParams,
    mut grads: Gradients<'_>,
    mut borders: Borders<'_>,
    scratch: &mut [i16],
) -> Result<()> {
    if prev_pts.len() != flows.len() {
        return Err(Error::LengthMismatch);
    }
    run_native::<A>(
        prev,
        next,
        |k| prev_pts.get(k).copied(),
        flows,
        cfg,
        &mut grads,
        &mut borders,
        scratch,
        &mut Keep::Off,
    )
}

/// Forward-backward check: tracks the results `flows` back from `next` to `prev` into `back`
/// and marks [`FlowStatus::Inconsistent`] every tracked point that does not come back within
/// [`LkConfig::fb_threshold`] of `prev_pts` (`|back - prev| > t`). Does nothing when the
/// threshold is `None`. Same errors as [`calc_flow`].
#[allow(clippy::too_many_arguments)]
pub fn forward_backward<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    prev_pts: &[[A::Coord; 2]],
    flows: &mut [Flow<A::Coord>],
    back: &mut [Flow<A::Coord>],
    cfg: &LkParams,
    mut grads: Gradients<'_>,
    scratch: &mut [i16],
) -> Result<()> {
    let (grads, keep) = (&mut grads, &mut Keep::Off);
    forward_backward_keeping::<A>(prev, next, prev_pts, flows, back, cfg, grads, scratch, keep)
}

/// [`forward_backward`], its backward templates kept (or not) by `keep`.
#[allow(clippy::too_many_arguments)]
pub(super) fn forward_backward_keeping<A: FlowArith>(
    prev: &Pyramid<'_>,
    next: &Pyramid<'_>,
    prev_pts: &[[A::Coord; 2]],
    flows: &mut [Flow<A::Coord>],
    back: &mut [Flow<A::Coord>],
    cfg: &LkParams,
    grads: &mut Gradients<'_>,
    scratch: &mut [i16],
    keep: &mut Keep<'_, '_>,
) -> Result<()> {
    if prev_pts.len() != flows.len() || back.len() != flows.len() {
        return Err(Error::LengthMismatch);
    }
    if cfg.config().fb_threshold.is_none() {
        return Ok(());
    }
    let bcfg = cfg.with_initial_flow(false);
    {
        let fw: &[Flow<A::Coord>] = flows;
        let pts = |k: usize| fw.get(k).map(|f| [f.x, f.y]);
        let no = &mut Borders::None;
        run_native::<A>(next, prev, pts, back, &bcfg, grads, no, scratch, keep)?;
    }
    let win = cfg.config().win;
    let params = A::params(cfg, (win * win) as u32);
    for ((f, b), p) in flows.iter_mut().zip(back.iter()).zip(prev_pts) {
        if f.status == FlowStatus::Tracked
            && (b.status != FlowStatus::Tracked || A::beyond([b.x, b.y], *p, &params))
        {
            f.status = FlowStatus::Inconsistent;
        }
    }
    Ok(())
}

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
    use super::super::{Fixed, Q16, bordered_len, scratch_len};
    use super::*;
    use std::vec::Vec;

    /// A smooth textured image: sum of sinusoids, exact at sub-pixel shifts.
    fn scene(w: usize, h: usize, dx: f64, dy: f64) -> Vec<u8> {
        let mut v = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (u, t) = (x as f64 - dx, y as f64 - dy);
                let s = 128.0
                    + 50.0 * (u * 0.21).sin() * (t * 0.17).cos()
                    + 40.0 * (u * 0.07 + t * 0.11).sin()
                    + 20.0 * ((u - t) * 0.31).cos();
                v.push(s.round().clamp(0.0, 255.0) as u8);
            }
        }
        v
    }

    /// Scratch for either window kernel ([`Packed`], [`Lanes`]) with `win x win` windows.
    fn both_len(win: usize) -> usize {
        super::super::kernel::any_scratch_len(win)
    }

    fn run_both(dx: f64, dy: f64) -> (Vec<Flow<f32>>, Vec<Flow<Q16>>) {
        let (w, h) = (160, 120);
        let a = scene(w, h, 0.0, 0.0);
        let b = scene(w, h, dx, dy);
        let mut ba = std::vec![0u8; crate::pyramid::buffer_len(w, h, 3)];
        let mut bb = std::vec![0u8; crate::pyramid::buffer_len(w, h, 3)];
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut ba, 3).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut bb, 3).unwrap();
        let cfg = lk_params(LkConfig::default().win, 2);
        let pts: Vec<[f32; 2]> = (0..5)
            .flat_map(|j| (0..5).map(move |i| [25.0 + 22.0 * i as f32, 20.0 + 20.0 * j as f32]))
            .collect();
        let mut scratch = std::vec![0i16; scratch_len(cfg.config().win)];
        let mut ff = std::vec![Flow::<f32>::default(); pts.len()];
        calc_flow::<f32>(
            &pa,
            &pb,
            &pts,
            &mut ff,
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut scratch,
        )
        .unwrap();
        let qpts: Vec<[Q16; 2]> = pts
            .iter()
            .map(|p| {
                [
                    Q16::saturating_from_f32(p[0]),
                    Q16::saturating_from_f32(p[1]),
                ]
            })
            .collect();
        let mut fq = std::vec![Flow::<Q16>::default(); pts.len()];
        let mut lvl = std::vec![[0i16; 2]; w * h];
        calc_flow::<Fixed>(
            &pa,
            &pb,
            &qpts,
            &mut fq,
            &cfg,
            Gradients::PerLevel(&mut lvl),
            Borders::None,
            &mut scratch,
        )
        .unwrap();
        for ((p, f), q) in pts.iter().zip(&ff).zip(&fq) {
            assert_eq!(f.status, FlowStatus::Tracked, "{p:?}");
            assert_eq!(q.status, FlowStatus::Tracked, "{p:?}");
            let e =
                |x: f32, y: f32| (x as f64 - p[0] as f64 - dx).hypot(y as f64 - p[1] as f64 - dy);
            assert!(e(f.x, f.y) < 0.15, "f32 {p:?} -> {f:?}");
            assert!(e(q.x.to_f32(), q.y.to_f32()) < 0.15, "fixed {p:?} -> {q:?}");
        }
        (ff, fq)
    }

    #[test]
    fn recovers_known_translations() {
        run_both(0.0, 0.0);
        run_both(1.3, -0.6);
        run_both(-4.7, 3.2);
        run_both(9.5, 7.25);
    }

    /// 64x48 frames of the scene and of the scene moved by `(dx, dy)`, and 9x9 windows on
    /// level 0 only.
    fn small_pair(dx: f64, dy: f64) -> (Vec<u8>, Vec<u8>, LkParams) {
        let cfg = LkConfig {
            win: 9,
            max_level: 0,
            ..LkConfig::default()
        };
        (
            scene(64, 48, 0.0, 0.0),
            scene(64, 48, dx, dy),
            cfg.check().unwrap(),
        )
    }

    #[test]
    fn per_level_and_per_window_agree_bit_for_bit() {
        let (w, h) = (64, 48);
        let (a, b, cfg) = small_pair(1.7, 0.4);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        // Including points near and past the border.
        let pts = [
            [0, 0],
            [3 << 16, 40 << 16],
            [(63 << 16) + 5, 47 << 16],
            [30 << 16, (20 << 16) + 999],
        ]
        .map(|p| p.map(Q16::from_bits));
        let mut s = std::vec![0i16; scratch_len(9)];
        let mut f1 = [Flow::<Q16>::default(); 4];
        let mut f2 = [Flow::<Q16>::default(); 4];
        calc_flow::<Fixed>(
            &pa,
            &pb,
            &pts,
            &mut f1,
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut s,
        )
        .unwrap();
        let mut g = std::vec![[0i16; 2]; w * h];
        calc_flow::<Fixed>(
            &pa,
            &pb,
            &pts,
            &mut f2,
            &cfg,
            Gradients::PerLevel(&mut g),
            Borders::None,
            &mut s,
        )
        .unwrap();
        assert_eq!(f1, f2);
    }

    /// [`Gradients::Auto`] gives the per-window numbers bit for bit whichever source it picks:
    /// the level where 40 points' windows (4 000 pixels) outweigh the 3 072-pixel level, the
    /// windows with 4 points or a buffer too short for the level (no error then).
    #[test]
    fn auto_gradients_agree_bit_for_bit() {
        let (w, h) = (64, 48);
        let (a, b, cfg) = small_pair(-0.8, 1.3);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let pts: Vec<[Q16; 2]> = (0..40)
            .map(|k| {
                [(k % 8) * 8 + 2, (k / 8) * 10 - 1].map(|c| Q16::from_bits((c << 16) + 777 * k))
            })
            .collect();
        let mut s = std::vec![0i16; scratch_len(9)];
        for n in [40, 4] {
            let p = &pts[..n];
            let mut want = std::vec![Flow::<Q16>::default(); n];
            calc_flow::<Fixed>(
                &pa,
                &pb,
                p,
                &mut want,
                &cfg,
                Gradients::PerWindow,
                Borders::None,
                &mut s,
            )
            .unwrap();
            for len in [w * h, w * h - 1, 0] {
                let mut g = std::vec![[0i16; 2]; len];
                let mut got = std::vec![Flow::<Q16>::default(); n];
                let grads = Gradients::Auto(&mut g);
                calc_flow::<Fixed>(&pa, &pb, p, &mut got, &cfg, grads, Borders::None, &mut s)
                    .unwrap();
                assert_eq!(got, want, "{n} points, buffer {len}");
            }
        }
    }

    /// The bordered copies ([`Borders::Copy`]) change no flow, status or error, for both
    /// arithmetics, with levels 1 and 2 copied (40 points, whose windows outweigh both levels)
    /// or level 2 only (4 points), from a buffer of exactly the level-1 size or longer; the
    /// points include windows across every edge and one centred outside the image. The vector
    /// kernel reads the copies; the packed one, which makes none ([`Window::BORDERED`]), is run
    /// with the same buffers and is the reference. A buffer one byte short of level 1's copies
    /// is an error for both kernels, never a quiet fallback; without level 1 any buffer does.
    #[test]
    fn bordered_copies_change_nothing() {
        let (w, h) = (64, 48);
        let (a, b, cfg) = small_pair(-0.8, 1.3);
        let mut bufs = [0u8, 0].map(|_| std::vec![0u8; crate::pyramid::buffer_len(w, h, 3)]);
        let [ba, bb] = &mut bufs;
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), ba, 3).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), bb, 3).unwrap();
        let top0 = cfg;
        let cfg = LkConfig {
            max_level: 2,
            ..*cfg.config()
        }
        .check()
        .unwrap();
        let pts: Vec<[Q16; 2]> = (0..40)
            .map(|k| {
                [(k % 8) * 8 + 2, (k / 8) * 10 - 1].map(|c| Q16::from_bits((c << 16) + 777 * k))
            })
            .collect();
        let pf: Vec<[f32; 2]> = pts.iter().map(|p| p.map(Q16::to_f32)).collect();
        let level1 = bordered_len(w / 2, h / 2, 9);
        let mut s = std::vec![0i16; both_len(9)];
        fn go<'s, A: FlowArith, W: Window<'s>>(
            (pa, pb): (&Pyramid<'_>, &Pyramid<'_>),
            pts: &[[A::Coord; 2]],
            cfg: &LkParams,
            mut borders: Borders<'_>,
            s: &'s mut [i16],
        ) -> Result<Vec<Flow<A::Coord>>> {
            let mut f = std::vec![Flow::<A::Coord>::default(); pts.len()];
            let p = |k: usize| pts.get(k).copied();
            let g = &mut Gradients::PerWindow;
            let bd = &mut borders;
            run::<A, W>(pa, pb, p, &mut f, cfg, g, bd, s, &mut Keep::Off).map(|()| f)
        }
        let py = (&pa, &pb);
        for n in [40, 4] {
            let (pts, pf) = (&pts[..n], &pf[..n]);
            let none = || Borders::None;
            let want_q = go::<Fixed, Packed<'_>>(py, pts, &cfg, none(), &mut s).unwrap();
            let want_f = go::<f32, Packed<'_>>(py, pf, &cfg, none(), &mut s).unwrap();
            assert!(want_q.iter().any(|f| f.status == FlowStatus::Tracked));
            let bits = flow_bits(&want_f);
            for len in [level1, bordered_len(w, h, 9)] {
                let mut buf = std::vec![0u8; len];
                let got = go::<Fixed, Packed<'_>>(py, pts, &cfg, Borders::Copy(&mut buf), &mut s);
                assert_eq!(got.unwrap(), want_q, "{n} points, {len}");
                let got = go::<Fixed, Lanes<'_>>(py, pts, &cfg, Borders::Copy(&mut buf), &mut s);
                assert_eq!(got.unwrap(), want_q, "{n} points, {len}");
                let got = go::<f32, Packed<'_>>(py, pf, &cfg, Borders::Copy(&mut buf), &mut s);
                assert_eq!(flow_bits(&got.unwrap()), bits, "{n} points, {len}");
                let got = go::<f32, Lanes<'_>>(py, pf, &cfg, Borders::Copy(&mut buf), &mut s);
                assert_eq!(flow_bits(&got.unwrap()), bits, "{n} points, {len}");
            }
            let mut short = std::vec![0u8; level1 - 1];
            let short_err = Err(Error::BufferTooSmall("borders"));
            let got = go::<Fixed, Packed<'_>>(py, pts, &cfg, Borders::Copy(&mut short), &mut s);
            assert_eq!(got, short_err);
            let got = go::<Fixed, Lanes<'_>>(py, pts, &cfg, Borders::Copy(&mut short), &mut s);
            assert_eq!(got, short_err);
            // Level 0 alone: nothing to copy, so no length is too short.
            let want = go::<Fixed, Packed<'_>>(py, pts, &top0, none(), &mut s).unwrap();
            let got = go::<Fixed, Lanes<'_>>(py, pts, &top0, Borders::Copy(&mut []), &mut s);
            assert_eq!(got.unwrap(), want, "{n} points, level 0 only");
        }
    }

    /// `compute_error: false` moves no point (same positions bit for bit), leaves `err` 0,
    /// and skips only the final range check: a point whose last step leaves the image stays
    /// `Tracked` without it.
    /// Validated parameters for `win x win` windows over `max_level + 1` levels.
    fn lk_params(win: usize, max_level: usize) -> LkParams {
        LkConfig {
            win,
            max_level,
            ..LkConfig::default()
        }
        .check()
        .unwrap()
    }

    /// Each flow's position, status and error as bits, for comparisons to the bit.
    fn flow_bits(v: &[Flow<f32>]) -> Vec<(u32, u32, FlowStatus, u32)> {
        v.iter()
            .map(|f| (f.x.to_bits(), f.y.to_bits(), f.status, f.err.to_bits()))
            .collect()
    }

    /// `prev_pts` tracked by [`Packed`] and by [`Lanes`] (per-window or per-level gradients).
    #[allow(clippy::type_complexity)]
    fn both_kernels<A: FlowArith>(
        pa: &Pyramid<'_>,
        pb: &Pyramid<'_>,
        prev_pts: &[[A::Coord; 2]],
        cfg: &LkParams,
        per_level: bool,
        g: &mut [[i16; 2]],
        s: &mut [i16],
    ) -> (Vec<Flow<A::Coord>>, Vec<Flow<A::Coord>>) {
        fn grads(g: &mut [[i16; 2]], per_level: bool) -> Gradients<'_> {
            match per_level {
                true => Gradients::PerLevel(g),
                false => Gradients::PerWindow,
            }
        }
        let pts = |k: usize| prev_pts.get(k).copied();
        let mut f1 = std::vec![Flow::<A::Coord>::default(); prev_pts.len()];
        let mut f2 = f1.clone();
        run::<A, Packed<'_>>(
            pa,
            pb,
            pts,
            &mut f1,
            cfg,
            &mut grads(g, per_level),
            &mut Borders::None,
            s,
            &mut Keep::Off,
        )
        .unwrap();
        run::<A, Lanes<'_>>(
            pa,
            pb,
            pts,
            &mut f2,
            cfg,
            &mut grads(g, per_level),
            &mut Borders::None,
            s,
            &mut Keep::Off,
        )
        .unwrap();
        (f1, f2)
    }

    /// A forward-backward chain over frames with the backward templates kept
    /// ([`TemplateCache`]) for the next forward pass: every flow, status and error the same to
    /// the bit as without the cache, for both kernels and both arithmetics; the forward passes
    /// did take kept templates, each equal to what the kernel computes; and a kept template is
    /// refused once a pixel it depends on changes.
    #[test]
    fn kept_templates_change_nothing() {
        /// Forward then backward over each pair of frames (the backward pass from the forward
        /// results, as in a forward-backward check), with kernel `Packed` or `Lanes`; the
        /// flows of every pass and the number of level-0 forward templates found kept.
        fn chain<A: FlowArith>(
            frames: &[Pyramid<'_>],
            pts0: &[[A::Coord; 2]],
            cfg: &LkParams,
            lanes: bool,
            cache: Option<&mut [i16]>,
        ) -> (Vec<Vec<Flow<A::Coord>>>, usize) {
            let c = cfg.config();
            let n = pts0.len();
            let mut cache = cache.and_then(|b| TemplateCache::new(b, c.win, c.max_level + 1, n));
            let half = A::Coord::from_half_px(c.win as i32 - 1);
            let mut s = std::vec![0i16; both_len(c.win)];
            let (g, no) = (&mut Gradients::PerWindow, &mut Borders::None);
            let (mut pts, mut out, mut hits) = (pts0.to_vec(), Vec::new(), 0);
            let mut pass = |prev: &Pyramid<'_>,
                            next: &Pyramid<'_>,
                            from: &[[A::Coord; 2]],
                            keep: &mut Keep<'_, '_>| {
                let mut f = std::vec![Flow::<A::Coord>::default(); n];
                let p = |k: usize| from.get(k).copied();
                match lanes {
                    true => run::<A, Lanes<'_>>(prev, next, p, &mut f, cfg, g, no, &mut s, keep),
                    false => run::<A, Packed<'_>>(prev, next, p, &mut f, cfg, g, no, &mut s, keep),
                }
                .unwrap();
                f
            };
            for pair in frames.windows(2) {
                let [prev, next] = pair else { continue };
                if let Some(c) = cache.as_ref() {
                    for (k, q) in pts.iter().enumerate() {
                        let b = A::bilinear(q[0] - half, q[1] - half).unwrap();
                        hits += usize::from(c.find(k, 0, &prev.level(0).unwrap(), &b).is_some());
                    }
                }
                let mut keep = cache.as_ref().map_or(Keep::Off, Keep::Use);
                let fw = pass(prev, next, &pts, &mut keep);
                pts = fw.iter().map(|f| [f.x, f.y]).collect();
                let mut keep = cache.as_mut().map_or(Keep::Off, Keep::Fill);
                let back = pass(next, prev, &pts, &mut keep);
                out.push(fw);
                out.push(back);
            }
            (out, hits)
        }
        let (w, h) = (97, 61);
        let frames: Vec<Vec<u8>> = (0..4)
            .map(|t| scene(w, h, 0.7 * t as f64, -0.45 * t as f64))
            .collect();
        let mut bufs: Vec<Vec<u8>> = (0..4)
            .map(|_| std::vec![0u8; crate::pyramid::buffer_len(w, h, 3)])
            .collect();
        let pyrs: Vec<Pyramid<'_>> = frames
            .iter()
            .zip(bufs.iter_mut())
            .map(|(f, b)| Pyramid::build(ImageView::packed(f, w, h).unwrap(), b, 3).unwrap())
            .collect();
        let pts: Vec<[f32; 2]> = (0..40)
            .map(|k| [3.0 + (k % 8) as f32 * 12.3, 2.0 + (k / 8) as f32 * 13.1])
            .collect();
        let cfg = LkConfig {
            win: 9,
            max_level: 2,
            fb_threshold: Some(0.5),
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        let clen = super::super::cache::cache_len(9, 3, pts.len()) + 64;
        let qpts: Vec<[Q16; 2]> = pts
            .iter()
            .map(|p| p.map(Q16::saturating_from_f32))
            .collect();
        for lanes in [false, true] {
            let mut c = std::vec![0i16; clen];
            let (want, _) = chain::<f32>(&pyrs, &pts, &cfg, lanes, None);
            let (got, hits) = chain::<f32>(&pyrs, &pts, &cfg, lanes, Some(&mut c));
            assert_eq!(got, want);
            // Three forward passes after the first, 40 points each: the grid reaches the
            // border on every side, where the windows' rings leave the image and nothing is
            // kept; the inner half of the points must have found theirs.
            assert!(hits >= 50, "{hits} kept templates found");
            let mut c = std::vec![0i16; clen];
            let (want, _) = chain::<Fixed>(&pyrs, &qpts, &cfg, lanes, None);
            let (got, hits) = chain::<Fixed>(&pyrs, &qpts, &cfg, lanes, Some(&mut c));
            assert_eq!(got, want);
            assert!(hits >= 50, "{hits} kept templates found");
        }

        // Each kept template is the kernel's own; one changed pixel of its ring refuses it.
        let mut cbuf = std::vec![0i16; clen];
        let mut cache = TemplateCache::new(&mut cbuf, 9, 3, 1).unwrap();
        let mut sa = std::vec![0i16; both_len(9)];
        let mut k1 = Packed::new(&mut sa, 9).unwrap();
        let img = pyrs[1].level(0).unwrap();
        let b = Fixed::bilinear(
            Q16::saturating_from_f32(30.3),
            Q16::saturating_from_f32(20.6),
        )
        .unwrap();
        let sums = k1.template(&Pixels::new(img), None, &b);
        let state = k1.state().to_vec();
        cache.keep(0, 0, &img, &b, (&state, sums));
        // (The slot holds the native kernel's state length; Packed's is its first part.)
        let (kept, kept_sums) = cache.find(0, 0, &img, &b).unwrap();
        assert_eq!((&kept[..state.len()], kept_sums), (&state[..], sums));
        assert_eq!(cache.find(0, 1, &img, &b), None, "another level");
        let mut changed = frames[1].clone();
        // The ring's corner: one pixel up and left of the window's.
        let at = (b.y as usize - 1) * w + (b.x as usize - 1);
        changed[at] ^= 1;
        let img2 = ImageView::packed(&changed, w, h).unwrap();
        assert_eq!(
            cache.find(0, 0, &img2, &b),
            None,
            "a pixel of its ring changed"
        );
        changed[at] ^= 1;
        changed[at + 12] ^= 1; // just past the ring's right edge (side win + 3): still kept
        let img3 = ImageView::packed(&changed, w, h).unwrap();
        assert!(cache.find(0, 0, &img3, &b).is_some());
    }

    /// The widest windows on blocks of 0 and 255 (the largest derivatives along every block
    /// edge, so the `i32` lane sums run closest to their bounds): both kernels agree to the
    /// bit, per window and per level.
    #[test]
    fn widest_windows_on_hard_edges_agree_bit_for_bit() {
        let (w, h) = (160, 120);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let blocks: Vec<u8> = (0..(w / 4) * (h / 4))
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                if state & 1 == 0 { 0 } else { 255 }
            })
            .collect();
        let img = |dx: usize| -> Vec<u8> {
            (0..w * h)
                .map(|i| blocks[((i / w) / 4) * (w / 4) + ((i % w + dx) / 4).min(w / 4 - 1)])
                .collect()
        };
        let (a, b) = (img(0), img(1));
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let pts: Vec<[f32; 2]> = (0..24)
            .map(|k| [20.25 + 5.5 * k as f32, 30.5 + 2.75 * k as f32])
            .collect();
        for win in [47, 56, 63] {
            let cfg = lk_params(win, 0);
            let mut s = std::vec![0i16; both_len(win)];
            let mut g = std::vec![[0i16; 2]; w * h];
            for per_level in [false, true] {
                let (f1, f2) = both_kernels::<f32>(&pa, &pb, &pts, &cfg, per_level, &mut g, &mut s);
                let (b1, b2) = (flow_bits(&f1), flow_bits(&f2));
                assert_eq!(b1, b2, "win {win}, per level {per_level}");
                let tracked = f1.iter().filter(|f| f.status == FlowStatus::Tracked);
                assert!(tracked.count() >= 12, "win {win}: most points track");
            }
        }
    }

    /// The two window kernels ([`super::super::kernel`]) compute the same integers: flows,
    /// statuses and errors equal to the bit, for both arithmetics, both gradient sources, odd
    /// and whole-vector windows, on a noisy texture with points inside, near and past every
    /// border (the reflected-patch paths) and moved by up to a few pixels.
    #[test]
    fn both_window_kernels_agree_bit_for_bit() {
        let (w, h) = (97, 61);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let noise: Vec<i32> = (0..w * h).map(|_| (next() % 41) as i32 - 20).collect();
        let textured = |dx: f64, dy: f64| -> Vec<u8> {
            scene(w, h, dx, dy)
                .iter()
                .zip(&noise)
                .map(|(&p, &n)| (i32::from(p) + n).clamp(0, 255) as u8)
                .collect()
        };
        let (a, b) = (textured(0.0, 0.0), textured(2.3, -1.6));
        let mut ba = std::vec![0u8; crate::pyramid::buffer_len(w, h, 2)];
        let mut bb = std::vec![0u8; crate::pyramid::buffer_len(w, h, 2)];
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut ba, 2).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut bb, 2).unwrap();
        let pts: Vec<[f32; 2]> = (0..120)
            .map(|_| {
                let mut u = |m: usize| (next() % (m as u64 * 64)) as f32 / 64.0 - 6.0;
                [u(w + 12), u(h + 12)]
            })
            .collect();
        // And points whose fractions are tiny, where the bilinear weight `w11` comes out as -1.
        let mut pts = pts;
        let tiny: Vec<[f32; 2]> = (1..400)
            .flat_map(|a| (1..400).map(move |b| [a, b]))
            .filter(|&[a, b]| {
                let (x, y) = (
                    Q16::from_bits(a + (40 << 16)),
                    Q16::from_bits(b + (30 << 16)),
                );
                Fixed::bilinear(x, y).is_some_and(|w| w.w[3] < 0)
            })
            .take(20)
            .map(|[a, b]| [40.0 + a as f32 / 65536.0, 30.0 + b as f32 / 65536.0])
            .collect();
        assert!(!tiny.is_empty());
        pts.extend(tiny);
        let qpts: Vec<[Q16; 2]> = pts
            .iter()
            .map(|p| p.map(Q16::saturating_from_f32))
            .collect();
        for win in [3, 8, 9, 16, 21] {
            let cfg = lk_params(win, 2);
            let mut s = std::vec![0i16; both_len(win)];
            let mut g = std::vec![[0i16; 2]; w * h];
            for per_level in [false, true] {
                let (f1, f2) = both_kernels::<f32>(&pa, &pb, &pts, &cfg, per_level, &mut g, &mut s);
                assert_eq!(
                    flow_bits(&f1),
                    flow_bits(&f2),
                    "f32, win {win}, per level {per_level}"
                );
                let tracked = f1
                    .iter()
                    .filter(|f| f.status == FlowStatus::Tracked)
                    .count();
                assert!(tracked > 40, "win {win}: only {tracked} tracked");
                let (q1, q2) =
                    both_kernels::<Fixed>(&pa, &pb, &qpts, &cfg, per_level, &mut g, &mut s);
                assert_eq!(q1, q2, "fixed, win {win}, per level {per_level}");
            }
        }
    }

    #[test]
    fn without_the_error_pass_the_positions_are_the_same() {
        let (w, h) = (64, 48);
        let a = scene(w, h, 0.0, 0.0);
        let b = scene(w, h, 2.6, -1.2);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let pts = [[20, 20], [40, 30], [10, 35], [62, 1], [1, 46]]
            .map(|p: [i32; 2]| p.map(|v| Q16::from_bits(v << 16)));
        let run = |compute_error: bool| {
            let cfg = LkConfig {
                win: 9,
                max_level: 0,
                compute_error,
                ..LkConfig::default()
            }
            .check()
            .unwrap();
            let mut s = std::vec![0i16; scratch_len(9)];
            let mut f = [Flow::<Q16>::default(); 5];
            calc_flow::<Fixed>(
                &pa,
                &pb,
                &pts,
                &mut f,
                &cfg,
                Gradients::PerWindow,
                Borders::None,
                &mut s,
            )
            .unwrap();
            f
        };
        let (with, without) = (run(true), run(false));
        let (mut tracked, mut with_err) = (0, 0);
        for (a, b) in with.iter().zip(&without) {
            assert_eq!((a.x, a.y), (b.x, b.y));
            assert_eq!(b.err, Q16::ZERO);
            if a.status == FlowStatus::Tracked {
                assert_eq!(b.status, FlowStatus::Tracked);
                tracked += 1;
                with_err += usize::from(a.err > Q16::ZERO);
            }
        }
        // The scene moved by a fraction of a pixel: the error pass sees a residual.
        assert!(tracked >= 3 && with_err >= 1, "{with:?}");
    }

    #[test]
    fn far_points_are_lost_and_bad_inputs_are_errors() {
        let (w, h) = (64, 48);
        let a = scene(w, h, 0.0, 0.0);
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let cfg = lk_params(7, 0);
        let pts = [[-50.0f32, 3.0], [f32::NAN, 1.0], [10.0, 1e30]];
        let mut f = [Flow::<f32>::default(); 3];
        let mut s = std::vec![0i16; scratch_len(7)];
        calc_flow::<f32>(
            &pa,
            &pa,
            &pts,
            &mut f,
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut s,
        )
        .unwrap();
        assert!(f.iter().all(|f| f.status == FlowStatus::OutOfBounds));
        let mut short = [0i16; 10];
        assert_eq!(
            calc_flow::<f32>(
                &pa,
                &pa,
                &pts,
                &mut f,
                &cfg,
                Gradients::PerWindow,
                Borders::None,
                &mut short
            ),
            Err(Error::BufferTooSmall("scratch"))
        );
        assert_eq!(
            calc_flow::<f32>(
                &pa,
                &pa,
                &pts[..2],
                &mut f,
                &cfg,
                Gradients::PerWindow,
                Borders::None,
                &mut s
            ),
            Err(Error::LengthMismatch)
        );
        let bad = LkConfig {
            win: 2,
            ..*cfg.config()
        };
        assert_eq!(bad.check(), Err(Error::InvalidParameter("lk.win")));
        // A flat image has no texture.
        let flat = [77u8; 64 * 48];
        let pf = Pyramid::build(ImageView::packed(&flat, w, h).unwrap(), &mut [], 1).unwrap();
        let mut g = [Flow::<f32>::default(); 1];
        calc_flow::<f32>(
            &pf,
            &pf,
            &[[30.0, 20.0]],
            &mut g,
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut s,
        )
        .unwrap();
        assert_eq!(g[0].status, FlowStatus::SmallEigenvalue);
    }

    #[test]
    fn forward_backward_flags_occlusion() {
        let (w, h) = (96, 72);
        let a = scene(w, h, 0.0, 0.0);
        let mut b = scene(w, h, 2.0, 1.0);
        // Paint a flat occluder over the second point in the next frame.
        for y in 40..72 {
            for x in 60..96 {
                b[y * w + x] = ((x * 37 + y * 91) % 256) as u8;
            }
        }
        let pa = Pyramid::build(ImageView::packed(&a, w, h).unwrap(), &mut [], 1).unwrap();
        let pb = Pyramid::build(ImageView::packed(&b, w, h).unwrap(), &mut [], 1).unwrap();
        let cfg = LkConfig {
            win: 11,
            max_level: 0,
            fb_threshold: Some(0.5),
            ..LkConfig::default()
        }
        .check()
        .unwrap();
        let pts = [[30.0f32, 20.0], [78.0, 56.0]];
        let mut f = [Flow::<f32>::default(); 2];
        let mut back = [Flow::<f32>::default(); 2];
        let mut s = std::vec![0i16; scratch_len(11)];
        calc_flow::<f32>(
            &pa,
            &pb,
            &pts,
            &mut f,
            &cfg,
            Gradients::PerWindow,
            Borders::None,
            &mut s,
        )
        .unwrap();
        forward_backward::<f32>(
            &pa,
            &pb,
            &pts,
            &mut f,
            &mut back,
            &cfg,
            Gradients::PerWindow,
            &mut s,
        )
        .unwrap();
        assert_eq!(f[0].status, FlowStatus::Tracked);
        assert_ne!(f[1].status, FlowStatus::Tracked);
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
