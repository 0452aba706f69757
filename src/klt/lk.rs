//! The Lucas-Kanade iteration of one point on one level ([`track_point`], OpenCV's
//! `LKTrackerInvoker` body): the template (computed by the window kernel or taken from the
//! kept ones), the Gauss-Newton steps and the error. The pyramid driver that calls it for every
//! point and level is [`super::flow`].

use super::arith::{Bilinear, Coordinate, FlowArith};
use super::cache::TemplateCache;
use super::kernel::{Pixels, Window};
use super::{Flow, FlowStatus};
use crate::image::ImageView;

/// `true` when the window at integer corner `(x, y)` still touches the image (OpenCV's test).
#[inline]
fn in_range(b: &Bilinear, win: usize, w: usize, h: usize) -> bool {
    let win = win as i32;
    b.x >= -win && b.x < w as i32 && b.y >= -win && b.y < h as i32
}

/// The per-call state shared by every point of a level.
pub(super) struct Level<'a, 'g, A: FlowArith> {
    pub(super) i: Pixels<'a>,
    pub(super) j: Pixels<'a>,
    pub(super) grad: Option<ImageView<'g, [i16; 2]>>,
    pub(super) level: u32,
    pub(super) top: bool,
    pub(super) win: usize,
    pub(super) max_iter: u32,
    pub(super) use_initial: bool,
    pub(super) compute_error: bool,
    pub(super) params: A::Params,
}

/// What a pass does with kept templates ([`TemplateCache`]).
pub(super) enum Keep<'a, 'c> {
    /// Nothing: every template computed.
    Off,
    /// Takes a point's template from the cache when it holds it (a forward pass).
    Use(&'a TemplateCache<'c>),
    /// Keeps every template it computes (a backward pass: the next frame's forward templates).
    Fill(&'a mut TemplateCache<'c>),
}

/// The template of point `k` at `bi` on the level: computed by the kernel, or taken from (or
/// kept in) the cache.
fn template<'s, A: FlowArith, W: Window<'s>>(
    lv: &Level<'_, '_, A>,
    s: &mut W,
    bi: &Bilinear,
    k: usize,
    keep: &mut Keep<'_, '_>,
) -> (i64, i64, i64) {
    let level = lv.level as usize;
    match keep {
        Keep::Off => s.template(&lv.i, lv.grad.as_ref(), bi),
        Keep::Use(cache) => match cache.find(k, level, &lv.i.img, bi) {
            Some((state, sums)) => {
                s.restore(state);
                sums
            }
            None => s.template(&lv.i, lv.grad.as_ref(), bi),
        },
        Keep::Fill(cache) => {
            let sums = s.template(&lv.i, lv.grad.as_ref(), bi);
            cache.keep(k, level, &lv.i.img, bi, (s.state(), sums));
            sums
        }
    }
}

/// One point (number `k`) on one level (OpenCV's `LKTrackerInvoker` body).
pub(super) fn track_point<'s, A: FlowArith, W: Window<'s>>(
    lv: &Level<'_, '_, A>,
    s: &mut W,
    (k, prev_pt): (usize, [A::Coord; 2]),
    f: &mut Flow<A::Coord>,
    keep: &mut Keep<'_, '_>,
) {
    let win = lv.win;
    let area = (win * win) as u32;
    let half = A::Coord::from_half_px(win as i32 - 1);
    let last = lv.level == 0;
    let p = prev_pt.map(|c| c.down(lv.level));
    let mut next = if lv.top {
        if lv.use_initial {
            [f.x.down(lv.level), f.y.down(lv.level)]
        } else {
            p
        }
    } else {
        [f.x.twice(), f.y.twice()]
    };
    f.x = next[0];
    f.y = next[1];
    let (iw, ih) = (lv.i.img.width(), lv.i.img.height());
    let Some(bi) = A::bilinear(p[0] - half, p[1] - half) else {
        f.status = FlowStatus::OutOfBounds;
        return;
    };
    if !in_range(&bi, win, iw, ih) {
        if last {
            f.status = FlowStatus::OutOfBounds;
            f.err = A::Coord::default();
        }
        return;
    }
    let (a11, a12, a22) = template(lv, s, &bi, k, keep);
    let gram = match A::gram(a11, a12, a22, &lv.params) {
        Ok(g) => g,
        Err(status) => {
            if last {
                f.status = status;
            }
            return;
        }
    };
    next = next.map(|c| c - half);
    let mut prev_delta = [A::Coord::default(); 2];
    for it in 0..lv.max_iter {
        let Some(bj) = A::bilinear(next[0], next[1]) else {
            f.status = FlowStatus::OutOfBounds;
            return;
        };
        if !in_range(&bj, win, iw, ih) {
            if last {
                f.status = FlowStatus::OutOfBounds;
            }
            break;
        }
        let (b1, b2) = s.mismatch(&lv.j, &bj, false);
        let delta = A::step(&gram, b1, b2);
        next = [next[0] + delta[0], next[1] + delta[1]];
        f.x = next[0] + half;
        f.y = next[1] + half;
        if A::converged(delta, &lv.params) {
            break;
        }
        if it > 0 && A::oscillates(delta, prev_delta) {
            f.x = f.x - delta[0].half();
            f.y = f.y - delta[1].half();
            break;
        }
        prev_delta = delta;
    }
    if last && lv.compute_error && f.status == FlowStatus::Tracked {
        let Some(bj) = A::bilinear(f.x - half, f.y - half) else {
            f.status = FlowStatus::OutOfBounds;
            return;
        };
        if !in_range(&bj, win, iw, ih) {
            f.status = FlowStatus::OutOfBounds;
            return;
        }
        let (sum, _) = s.mismatch(&lv.j, &bj, true);
        f.err = A::error(sum.unsigned_abs(), area);
    }
}
