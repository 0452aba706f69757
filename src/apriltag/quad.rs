//! Clusters of boundary points and the quads fitted to them (AprilTag's `fit_quad`).
//!
//! **Clusters**: an open-addressing table keyed by (black root, white root), filled by one
//! boundary scan that counts points and keeps the bounding box; the clusters kept (enough
//! points, not more than a frame's perimeter twice over) get ranges of the point buffer, in
//! batches when they do not all fit, and a second scan stores their points.
//!
//! **Quad fit** of one cluster of `n` points:
//! 1. the points are ordered by angle around the bounding box centre (an integer pseudo-angle,
//!    `q + t/(|dx| + |dy|)` per quadrant, 16 bits, by an in-place radix sort); the sign of
//!    `Σ (p - c) · g` (`g` towards white) tells a normal border (white outside) from a
//!    reversed one;
//! 2. each point is weighted by `|∇I| + 1` (the 3-tap central difference,
//!    `|∇| ≈ max + 3/8 min` of the two components); a cluster whose mean weight is below
//!    `min_edge_gradient` is not fitted (not AprilTag's: textured and noisy backgrounds give
//!    thousands of faint boundaries, printed tags a strong one); for a window of `2k + 1` points around
//!    each (`k = min(20, n / 12)`), the weighted covariance gives the line-fit error
//!    `N λ_min`; the errors are low-pass filtered (Gaussian, σ = 1 point, 7 taps) and their
//!    local maxima are corner candidates, the `max_nmaxima` largest kept;
//! 3. every 4 of the candidates split the points into 4 runs; each run's line fit must have
//!    `λ_min ≤ max_line_fit_mse` and neighbouring lines meet at an angle beyond the critical
//!    one; the split with the least total error wins when its mean error is within the bound;
//! 4. the corners are the intersections of consecutive lines; the quad must cover
//!    `0.95 w²` (`w` the narrowest family's border in pixels) and turn the same way at every
//!    corner with `|cos θ| ≤ cos(critical angle)`.
//!
//! All moment sums are exact integers (doubled coordinates relative to the bounding box, `i64`
//! sums and `i128` products for the covariances); the fits convert to `f32` only at the end.

use core::ops::{Add, Sub};

use nalgebra::Point2;

use super::geom::{Line, at4, eigen, eigenvalues, intersect, normal};
use super::label::ClusterKey;
use super::segment::{PairPoints, Sampled, unpack};
use crate::features::offer_best;
use crate::scalar::{above, at_most};

/// A cluster not in the current batch.
pub(crate) const NOT_IN_BATCH: u32 = u32::MAX;

/// One cluster: its key, point count, bounding box (doubled coordinates), the sums of its
/// gradient signs `Σg` and of `Σ p · g`, and its range of the point buffer in the
/// current batch. 32 bytes with the `u32` key of `u16` labels, 40 with the `u64` key of `u32`
/// ones ([`super::label::Label::Key`]). The point count saturates at 65535: clusters of more
/// than 65534 points (a boundary longer than twice the perimeter of a frame of
/// [`super::segment::MAX_SIDE`] a side) are not fitted. The sums are `i32`, saturating: exact
/// for every cluster that can be fitted (`|Σg| ≤ n`, and each `|p · g| < 2^15` in doubled
/// coordinates, so `|Σ p · g| < 2^31` below 65536 points), hence the same in any order of
/// the points.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Cluster<K = u32> {
    pub(crate) key: K,
    pub(crate) n: u16,
    pub(crate) fill: u16,
    pub(crate) start: u32,
    pub(crate) xmin: u16,
    pub(crate) xmax: u16,
    pub(crate) ymin: u16,
    pub(crate) ymax: u16,
    pub(crate) sgx: i32,
    pub(crate) sgy: i32,
    pub(crate) spg: i32,
}

impl Cluster {
    /// A free slot (the `u32` key of `u16` labels; [`Cluster::empty`] for any).
    pub const EMPTY: Self = Self::empty();
}

impl<K: ClusterKey> Cluster<K> {
    /// A free slot of key type `K`.
    pub const fn empty() -> Self {
        Self {
            key: K::EMPTY,
            n: 0,
            fill: 0,
            start: NOT_IN_BATCH,
            xmin: u16::MAX,
            xmax: 0,
            ymin: u16::MAX,
            ymax: 0,
            sgx: 0,
            sgy: 0,
            spg: 0,
        }
    }

    /// `Σ (p - c) · g` about the bounding box centre `c`, in quarter pixels (AprilTag's `dot`
    /// up to scale): positive when the gradient points away from the centre, i.e. white
    /// outside (a normal border).
    pub(crate) fn dot(&self) -> i64 {
        let xs = i64::from(self.xmin) + i64::from(self.xmax);
        let ys = i64::from(self.ymin) + i64::from(self.ymax);
        2 * i64::from(self.spg) - xs * i64::from(self.sgx) - ys * i64::from(self.sgy)
    }

    /// The cluster pre-filter (module docs): `Some(reversed)` for a closed boundary around
    /// its centre, `None` otherwise.
    pub(crate) fn shape(&self) -> Option<bool> {
        let n = i64::from(self.n);
        let (gx, gy) = (i64::from(self.sgx), i64::from(self.sgy));
        // Closed: |Σg| ≤ n / 4 (a straight edge has |Σg| ≈ n, a closed boundary ≈ 0).
        if 16 * (gx * gx + gy * gy) > n * n {
            return None;
        }
        // Around its centre: |dot| ≥ 0.2 n (bw + bh) / 2 in the units of `dot` (a square gives
        // 1, a rectangle of aspect a about 4a / (1 + a)², 0.2 at a = 1/18).
        let dot = self.dot();
        let spread = (i64::from(self.xmax) - i64::from(self.xmin)).max(0)
            + (i64::from(self.ymax) - i64::from(self.ymin)).max(0);
        if 10 * dot.abs() < n * spread {
            return None;
        }
        Some(dot < 0)
    }
}

/// Slot of `key` in a table of `len` slots (Fibonacci hashing).
#[inline]
fn home<K: ClusterKey>(key: K, len: usize) -> usize {
    let h = (key.wide().wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize;
    if len == 0 { 0 } else { h % len }
}

/// The cluster table over a caller slice (module docs). New keys are refused once 3/4 of the
/// slots are used, which bounds every probe sequence.
pub(crate) struct Table<'a, K: ClusterKey> {
    pub(crate) slots: &'a mut [Cluster<K>],
    pub(crate) used: usize,
    /// Points of keys that found no room.
    pub(crate) dropped: u32,
    /// The slot of the last key looked up: consecutive points mostly share a cluster.
    last: (K, usize),
    /// Slots that may be used (3/4 of them).
    limit: usize,
}

impl<'a, K: ClusterKey> Table<'a, K> {
    pub(crate) fn new(slots: &'a mut [Cluster<K>]) -> Self {
        slots.iter_mut().for_each(|c| *c = Cluster::empty());
        Self {
            slots,
            used: 0,
            dropped: 0,
            last: (K::EMPTY, 0),
            limit: 0,
        }
        .with_limit()
    }

    fn with_limit(mut self) -> Self {
        self.limit = self.slots.len() - self.slots.len() / 4;
        self
    }

    /// The slot of `key`: the last one looked up, or found (inserted when new and there is
    /// room, with `ymin = y2`).
    #[inline(always)]
    fn index(&mut self, key: K, y2: u16) -> Option<usize> {
        if self.last.0 == key {
            Some(self.last.1)
        } else {
            self.slot(key, y2)
        }
    }

    /// Adds `m ≥ 1` points `(x2 + 2i, y2)`, `i < m`, of cluster `key`, with gradient signs
    /// `(gx, gy)` (each -1, 0 or 1). The points come row by row down the image (`y2` never
    /// less than the last one's): a cluster's first point is its top (`ymin`, set when the
    /// key is inserted) and its latest point its bottom (`ymax`).
    #[inline]
    pub(crate) fn add_run(&mut self, key: K, x2: u16, y2: u16, m: u16, gx: i32, gy: i32) {
        let Some(i) = self.index(key, y2) else {
            self.dropped = self.dropped.saturating_add(u32::from(m));
            return;
        };
        let Some(c) = self.slots.get_mut(i) else {
            return;
        };
        let mi = i32::from(m);
        c.n = c.n.saturating_add(m);
        c.xmin = c.xmin.min(x2);
        c.xmax = c.xmax.max(x2.saturating_add(2 * m.saturating_sub(1)));
        c.ymax = y2;
        c.sgx = c.sgx.saturating_add(mi * gx);
        c.sgy = c.sgy.saturating_add(mi * gy);
        // Σ x2 over the run: m x2 + m (m - 1), below 2^28 (a run is at most MAX_SIDE wide).
        let sx = mi * i32::from(x2) + mi * (mi - 1);
        c.spg = c
            .spg
            .saturating_add(sx * gx)
            .saturating_add(mi * i32::from(y2) * gy);
    }

    /// Adds the points of a pair of runs ([`PairPoints`], at least one) to cluster `key`: the
    /// same cluster as [`Self::add_run`] for each of its runs of points, summed first (the
    /// sums are exact below 65535 points, module docs of [`Cluster`]; a cluster of more is
    /// never fitted), in the same row order.
    #[inline(always)]
    pub(crate) fn add_pair(&mut self, key: K, p: &PairPoints) {
        let (b0, b1) = p.below;
        let (r0, r1) = p.right;
        let mb = b1.saturating_sub(b0);
        let mr = r1.saturating_sub(r0);
        let m = mb + mr + p.nleft;
        let y2 = p.y2 as u16;
        let Some(i) = self.index(key, y2) else {
            self.dropped = self.dropped.saturating_add(m as u32);
            return;
        };
        let Some(c) = self.slots.get_mut(i) else {
            return;
        };
        // Doubled columns: first and last point, and Σ x2 gx / s over the pair.
        let (mut lo, mut hi, mut sx) = (usize::MAX, 0usize, 0i32);
        if mb > 0 {
            (lo, hi) = (2 * b0, 2 * b1 - 2);
        }
        if mr > 0 {
            (lo, hi) = (lo.min(2 * r0 + 1), hi.max(2 * r1 - 1));
            let mi = mr as i32;
            sx = mi * (2 * r0 as i32 + 1) + mi * (mi - 1);
        }
        for &x in p.left.iter().take(p.nleft) {
            let x2 = 2 * x - 1;
            (lo, hi) = (lo.min(x2), hi.max(x2));
            sx -= x2 as i32;
        }
        let (s, mi) = (p.s, m as i32);
        c.n = c.n.saturating_add(m as u16);
        c.xmin = c.xmin.min(lo as u16);
        c.xmax = c.xmax.max(hi as u16);
        c.ymax = y2;
        c.sgx = c.sgx.saturating_add(s * (mr as i32 - p.nleft as i32));
        c.sgy = c.sgy.saturating_add(s * mi);
        c.spg = c
            .spg
            .saturating_add(s * sx)
            .saturating_add(s * mi * i32::from(y2));
    }

    /// The slot of `key`, inserted with top row `ymin = y2` when new and there is room (and
    /// remembered).
    fn slot(&mut self, key: K, y2: u16) -> Option<usize> {
        let len = self.slots.len();
        let mut i = home(key, len);
        for _ in 0..len {
            let c = self.slots.get_mut(i)?;
            if c.key == key {
                self.last = (key, i);
                return Some(i);
            }
            if c.key == K::EMPTY {
                if self.used >= self.limit {
                    return None;
                }
                c.key = key;
                c.ymin = y2;
                self.used += 1;
                self.last = (key, i);
                return Some(i);
            }
            i = if i + 1 == len { 0 } else { i + 1 };
        }
        None
    }

    /// The cluster of `key`, if it has a slot.
    #[inline]
    pub(crate) fn get_mut(&mut self, key: K) -> Option<&mut Cluster<K>> {
        let len = self.slots.len();
        let mut i = if self.last.0 == key {
            self.last.1
        } else {
            home(key, len)
        };
        for _ in 0..len {
            let k = self.slots.get(i)?.key;
            if k == key {
                self.last = (key, i);
                return self.slots.get_mut(i);
            }
            if k == K::EMPTY {
                return None;
            }
            i = if i + 1 == len { 0 } else { i + 1 };
        }
        None
    }
}

/// Parameters of [`fit_quad`], in the sampled image's pixels.
#[derive(Debug, Clone, Copy)]
pub(crate) struct QuadParams {
    pub(crate) max_nmaxima: usize,
    pub(crate) max_line_fit_mse: f32,
    pub(crate) cos_critical: f32,
    /// AprilTag's `min_tag_width`: the narrowest border of the enabled families, in sampled
    /// pixels (at least 3).
    pub(crate) min_tag_width: u32,
    pub(crate) normal_border: bool,
    pub(crate) reversed_border: bool,
    /// Clusters whose mean gradient weight is below this are not fitted.
    pub(crate) min_edge_gradient: u32,
}

/// A fitted quad in the sampled image: corners in the order of the sorted boundary (clockwise
/// on screen), and the border kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Quad {
    pub(crate) p: [Point2<f32>; 4],
    pub(crate) reversed_border: bool,
}

/// Largest candidate count of the corner search.
pub const MAX_NMAXIMA: usize = 12;

/// Sorts `pts` by `keys` (both moved), in place: an American-flag radix pass on the high byte,
/// then on the low byte inside buckets of more than 16, insertion sort inside smaller ones.
/// `O(n)` with three 256-entry tables on the stack; `n ≤ u16::MAX`.
pub(crate) fn sort_by_key(pts: &mut [u32], keys: &mut [u16]) {
    let n = pts.len().min(keys.len()).min(usize::from(u16::MAX));
    let (Some(pts), Some(keys)) = (pts.get_mut(..n), keys.get_mut(..n)) else {
        return;
    };
    let (mut high, mut low) = (Buckets::new(), Buckets::new());
    let mut next = [0u16; 256];
    flag_pass(pts, keys, 8, &mut high, &mut next);
    let mut start = 0usize;
    high.for_each(|_, c| {
        let e = start + usize::from(c);
        // Most buckets of a cluster's boundary hold one point: nothing to sort.
        if c >= 2
            && let (Some(p), Some(k)) = (pts.get_mut(start..e), keys.get_mut(start..e))
        {
            if c > 16 {
                flag_pass(p, k, 0, &mut low, &mut next);
                low.clear();
            } else {
                insertion(p, k);
            }
        }
        start = e;
    });
}

/// The digit counts of one American-flag pass and the set of the digits present, a bit each:
/// the pass visits only the buckets that hold keys, in increasing digit order (the empty ones
/// do nothing in the textbook pass, so the permutation is the same), and the counts return to
/// zero by the same bits.
struct Buckets {
    count: [u16; 256],
    present: [u32; 8],
}

impl Buckets {
    /// No keys counted.
    fn new() -> Self {
        Self {
            count: [0; 256],
            present: [0; 8],
        }
    }

    /// Counts digit `(k >> shift) & 255` of each of `keys` (at most `u16::MAX` keys).
    fn add(&mut self, keys: &[u16], shift: u32) {
        for &k in keys {
            let d = usize::from((k >> shift) & 255);
            if let Some(c) = self.count.get_mut(d) {
                *c = c.wrapping_add(1);
            }
            if let Some(w) = self.present.get_mut(d >> 5) {
                *w |= 1 << (d & 31);
            }
        }
    }

    /// `f(digit, count)` for each digit present, in increasing order.
    #[inline]
    fn for_each(&self, mut f: impl FnMut(usize, u16)) {
        for (i, &word) in self.present.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                let d = 32 * i + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                f(d, self.count.get(d).copied().unwrap_or(0));
            }
        }
    }

    /// Back to no keys counted (only the counts of the digits present were set).
    fn clear(&mut self) {
        for (i, word) in self.present.iter_mut().enumerate() {
            while *word != 0 {
                let d = 32 * i + word.trailing_zeros() as usize;
                *word &= *word - 1;
                if let Some(c) = self.count.get_mut(d) {
                    *c = 0;
                }
            }
        }
    }
}

/// One American-flag pass on digit `(key >> shift) & 255`, its digits counted into `buckets`
/// (which must hold none) and `next` as scratch (each bucket's next place).
fn flag_pass(
    pts: &mut [u32],
    keys: &mut [u16],
    shift: u32,
    buckets: &mut Buckets,
    next: &mut [u16; 256],
) {
    let digit = |k: u16| usize::from((k >> shift) & 255);
    buckets.add(keys, shift);
    let mut sum = 0u16;
    buckets.for_each(|d, c| {
        if let Some(nd) = next.get_mut(d) {
            *nd = sum;
        }
        sum = sum.wrapping_add(c);
    });
    let n = keys.len().min(pts.len());
    let mut end = 0usize;
    buckets.for_each(|b, c| {
        end += usize::from(c);
        // Each element taken in hand goes to its final place: at most n moves in all.
        loop {
            let i = usize::from(next.get(b).copied().unwrap_or(u16::MAX));
            if i >= end || i >= n {
                break;
            }
            let (Some(&k0), Some(&p0)) = (keys.get(i), pts.get(i)) else {
                break;
            };
            // The element at i in hand: while it belongs elsewhere, put it at its bucket's
            // next place and take the one there (the swaps of the textbook pass, without
            // writing the element in hand back each time: the same permutation).
            let (mut k, mut p) = (k0, p0);
            for _ in 0..n {
                let d = digit(k);
                if d == b {
                    break;
                }
                let Some(nd) = next.get_mut(d) else {
                    break;
                };
                let j = usize::from(*nd);
                *nd += 1;
                if let (Some(kj), Some(pj)) = (keys.get_mut(j), pts.get_mut(j)) {
                    (k, *kj) = (*kj, k);
                    (p, *pj) = (*pj, p);
                }
            }
            if let (Some(ki), Some(pi)) = (keys.get_mut(i), pts.get_mut(i)) {
                (*ki, *pi) = (k, p);
            }
            if let Some(nb) = next.get_mut(b) {
                *nb += 1;
            }
        }
    });
}

/// Insertion sort of `(pts, keys)` by key (stable).
fn insertion(pts: &mut [u32], keys: &mut [u16]) {
    for i in 1..keys.len().min(pts.len()) {
        let mut j = i;
        while j > 0 {
            match (keys.get(j - 1), keys.get(j)) {
                (Some(a), Some(b)) if a > b => {
                    keys.swap(j - 1, j);
                    pts.swap(j - 1, j);
                }
                _ => break,
            }
            j -= 1;
        }
    }
}

/// Pseudo-angle of `(dx, dy)` (both non-zero), increasing with `atan2(dy, dx)` from `-π`:
/// quadrant `q` (`-π..-π/2, -π/2..0, 0..π/2, π/2..π`) times `2^14` plus `2^14 t / (|dx| + |dy|)`
/// with `t` the coordinate that grows across the quadrant.
#[inline]
fn pseudo_angle(dx: i32, dy: i32) -> u16 {
    let (ax, ay) = (dx.unsigned_abs(), dy.unsigned_abs());
    // By signs (dx > 0, dy > 0): (no, no) q 0, t |dy|; (yes, no) 1, |dx|; (yes, yes) 2, |dy|;
    // (no, yes) 3, |dx|: t is |dx| where the signs differ, and q counts them thus.
    let (px, py) = (dx > 0, dy > 0);
    let q = 2 * u32::from(py) + u32::from(px != py);
    let t = if px != py { ax } else { ay };
    let s = ax + ay;
    // |dx|, |dy| < 2^16: t 2^14 < 2^30. Both non-zero: t < s, the fraction below 2^14.
    let frac = (t << 14).checked_div(s).unwrap_or(0);
    ((q << 14) | frac) as u16
}

/// The [`pseudo_angle`] of each of `pts` (in the format `P`) about the centre `(xs, ys) / 2`
/// (doubled coordinates of that format) into `keys`, offset by a quarter unit so that no
/// point sits on an axis. Not inlined, as [`Gradient::weights`].
#[inline(never)]
fn angle_keys<P: Points>(pts: &[u32], keys: &mut [u16], xs: i32, ys: i32) {
    for (p, k) in pts.iter().zip(keys.iter_mut()) {
        let (x, y) = P::coords(*p);
        *k = pseudo_angle(2 * (2 * x - xs) + 1, 2 * (2 * y - ys) - 1);
    }
}

/// The quad fit's points after their weights (the two formats of [`fit_quad`]): point `i` as
/// its doubled coordinates relative to the bounding box corner and its gradient weight.
trait Points {
    /// The doubled coordinates of a point word (absolute or relative, as the format keeps
    /// them).
    fn coords(p: u32) -> (i32, i32);
    /// The number of points.
    fn len(&self) -> usize;
    /// `(u, v, w)`: point `i` relative to the box corner and its weight.
    fn at(&self, i: usize) -> Option<(i32, i32, i32)>;
    /// `f(u, v, w)` for the points `from..to` in order (none when the range is not inside):
    /// one bounds check for the range, not one a point.
    fn each(&self, from: usize, to: usize, f: impl FnMut((i32, i32, i32)));
}

/// Points packed with their weights ([`Gradient::pack`]): `u | v << 11 | w << 22` with `(u, v)`
/// relative to the bounding box corner (boxes below `2^11` doubled pixels a side) and the
/// weight `w ≤ MAX_WEIGHT < 2^9`.
#[derive(Clone, Copy)]
struct Packed<'a>(&'a [u32]);

impl Packed<'_> {
    /// Bits of a relative coordinate.
    const BITS: u32 = 11;
    const MASK: u32 = (1 << Self::BITS) - 1;

    /// Whether a bounding box of extents `(dx, dy)` (doubled) fits the packed coordinates.
    fn fits(dx: i32, dy: i32) -> bool {
        (0..=Self::MASK as i32).contains(&dx) && (0..=Self::MASK as i32).contains(&dy)
    }

    /// `(u, v, w)` of a packed word.
    #[inline]
    fn unpack(p: u32) -> (i32, i32, i32) {
        let (u, v) = <Self as Points>::coords(p);
        (u, v, (p >> (2 * Self::BITS)) as i32)
    }

    /// The packed word of relative `(u, v)` (below `2^11`) and weight `w` (below `2^9`).
    #[inline]
    fn pack(u: i32, v: i32, w: u16) -> u32 {
        (u as u32 & Self::MASK)
            | ((v as u32 & Self::MASK) << Self::BITS)
            | (u32::from(w) << (2 * Self::BITS))
    }
}

impl Points for Packed<'_> {
    #[inline]
    fn coords(p: u32) -> (i32, i32) {
        (
            (p & Self::MASK) as i32,
            ((p >> Self::BITS) & Self::MASK) as i32,
        )
    }
    #[inline]
    fn len(&self) -> usize {
        self.0.len()
    }
    #[inline]
    fn at(&self, i: usize) -> Option<(i32, i32, i32)> {
        self.0.get(i).map(|&p| Self::unpack(p))
    }
    #[inline]
    fn each(&self, from: usize, to: usize, mut f: impl FnMut((i32, i32, i32))) {
        for &p in self.0.get(from..to).unwrap_or(&[]) {
            f(Self::unpack(p));
        }
    }
}

/// Boundary points ([`unpack`]) with their weights beside them, for bounding boxes too large
/// to pack; `(x0, y0)` the box corner.
#[derive(Clone, Copy)]
struct Split<'a> {
    pts: &'a [u32],
    weights: &'a [u16],
    x0: i32,
    y0: i32,
}

impl Points for Split<'_> {
    #[inline]
    fn coords(p: u32) -> (i32, i32) {
        let (x2, y2, _, _) = unpack(p);
        (x2, y2)
    }
    #[inline]
    fn len(&self) -> usize {
        self.pts.len().min(self.weights.len())
    }
    #[inline]
    fn at(&self, i: usize) -> Option<(i32, i32, i32)> {
        let (p, w) = (*self.pts.get(i)?, *self.weights.get(i)?);
        let (x2, y2) = Self::coords(p);
        Some((x2 - self.x0, y2 - self.y0, i32::from(w)))
    }
    #[inline]
    fn each(&self, from: usize, to: usize, mut f: impl FnMut((i32, i32, i32))) {
        let pts = self.pts.get(from..to).unwrap_or(&[]);
        let weights = self.weights.get(from..to).unwrap_or(&[]);
        for (&p, &w) in pts.iter().zip(weights) {
            let (x2, y2) = Self::coords(p);
            f((x2 - self.x0, y2 - self.y0, i32::from(w)));
        }
    }
}

// `add` and `sub` over the six sums of `Moments`, `Window` and `Window32` (one text for all:
// their fields differ in width only), with the integer operations `$add` and `$sub`: `Add::add`
// and `Sub::sub` (`+` and `-`, checked for overflow in debug builds) where the sums never
// overflow, `wrapping_add` and `wrapping_sub` for `Window32`, whose running sums wrap on the way.
macro_rules! sums_add_sub {
    ($t:ty, $add:ident, $sub:ident) => {
        impl $t {
            #[inline]
            fn add(&mut self, o: &Self) {
                self.w = self.w.$add(o.w);
                self.x = self.x.$add(o.x);
                self.y = self.y.$add(o.y);
                self.xx = self.xx.$add(o.xx);
                self.xy = self.xy.$add(o.xy);
                self.yy = self.yy.$add(o.yy);
            }
            #[inline]
            fn sub(&mut self, o: &Self) {
                self.w = self.w.$sub(o.w);
                self.x = self.x.$sub(o.x);
                self.y = self.y.$sub(o.y);
                self.xx = self.xx.$sub(o.xx);
                self.xy = self.xy.$sub(o.xy);
                self.yy = self.yy.$sub(o.yy);
            }
        }
    };
}

sums_add_sub!(Moments, add, sub);
sums_add_sub!(Window, add, sub);
sums_add_sub!(Window32, wrapping_add, wrapping_sub);

/// Weighted moments of a run of points: `Σw`, `Σw u`, `Σw v`, `Σw u²`, `Σw u v`, `Σw v²`
/// (doubled coordinates relative to the bounding box corner; exact).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Moments {
    w: i64,
    x: i64,
    y: i64,
    xx: i64,
    xy: i64,
    yy: i64,
}

impl Moments {
    #[inline]
    fn add_window(&mut self, o: &Window) {
        self.w += i64::from(o.w);
        self.x += i64::from(o.x);
        self.y += i64::from(o.y);
        self.xx += o.xx;
        self.xy += o.xy;
        self.yy += o.yy;
    }
}

/// The running sums of the corner search's window (at most 41 points; [`Moments`] of
/// coordinates relative to the bounding box centre): one point's, their sum and difference,
/// and the exact covariance numerators. The numerators `Σw Σw u² - (Σw u)²` are the same for
/// any origin (the terms in the origin cancel in exact integers), so the centre, which keeps
/// the sums small, gives the numerators of the corner: the same errors.
trait WindowSums: Copy + Default {
    /// One point at `(u, v)` from the centre with weight `w` (at most [`MAX_WEIGHT`]).
    fn of(u: i32, v: i32, w: i32) -> Self;
    fn add(&mut self, o: &Self);
    fn sub(&mut self, o: &Self);
    /// `(Σw, Σw Σw u² - (Σw u)², Σw Σw u v - Σw u Σw v, Σw Σw v² - (Σw v)²)`.
    fn numerators(&self) -> (i32, i64, i64, i64);
}

/// The largest gradient weight ([`Gradient::weight`] of two differences of 255: `255 +
/// 3·255/8 + 1`).
const MAX_WEIGHT: u64 = 351;

/// The window's sums with the first moments in `i32`: a weight is at most [`MAX_WEIGHT`] and a
/// coordinate below `2^14`, so `Σw < 2^14` and `|Σw u| < 2^29` over 41 points; the products
/// of a point are `i32` times `i32` into `i64` (one instruction on a 32-bit core, where `i64`
/// times `i64` takes three).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Window {
    w: i32,
    x: i32,
    y: i32,
    xx: i64,
    xy: i64,
    yy: i64,
}

impl WindowSums for Window {
    #[inline]
    fn of(u: i32, v: i32, w: i32) -> Self {
        let (wu, wv) = (w * u, w * v);
        Self {
            w,
            x: wu,
            y: wv,
            xx: i64::from(wu) * i64::from(u),
            xy: i64::from(wu) * i64::from(v),
            yy: i64::from(wv) * i64::from(v),
        }
    }
    #[inline]
    fn add(&mut self, o: &Self) {
        Window::add(self, o);
    }
    #[inline]
    fn sub(&mut self, o: &Self) {
        Window::sub(self, o);
    }
    /// `i64` products suffice for at most 41 points (`Σw < 2^14`, `Σw u² < 2^43`).
    #[inline]
    fn numerators(&self) -> (i32, i64, i64, i64) {
        let (w, x, y) = (i64::from(self.w), i64::from(self.x), i64::from(self.y));
        (
            self.w,
            w * self.xx - x * x,
            w * self.xy - x * y,
            w * self.yy - y * y,
        )
    }
}

/// The window's sums all in `i32`, for a bounding box whose half extents `h` about its centre
/// keep `count MAX_WEIGHT h² < 2^31` ([`Window32::fits`]): then every second moment of the
/// window is below `2^31` in magnitude (`|Σw u v|` by Cauchy-Schwarz), the sums take one
/// register each and their numerators one `i32` times `i32` product each. The running sums
/// wrap on the way (a window is added before one is taken away), exact when done.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Window32 {
    w: i32,
    x: i32,
    y: i32,
    xx: i32,
    xy: i32,
    yy: i32,
}

impl Window32 {
    /// Whether windows of `count` points of a bounding box with half extents `hx`, `hy`
    /// (doubled coordinates) keep their sums in `i32`.
    fn fits(count: usize, hx: i32, hy: i32) -> bool {
        let h = u64::from(hx.max(hy).unsigned_abs());
        (count as u64)
            .saturating_mul(MAX_WEIGHT)
            .saturating_mul(h * h)
            <= i32::MAX as u64
    }
}

impl WindowSums for Window32 {
    #[inline]
    fn of(u: i32, v: i32, w: i32) -> Self {
        let (wu, wv) = (w.wrapping_mul(u), w.wrapping_mul(v));
        Self {
            w,
            x: wu,
            y: wv,
            xx: wu.wrapping_mul(u),
            xy: wu.wrapping_mul(v),
            yy: wv.wrapping_mul(v),
        }
    }
    #[inline]
    fn add(&mut self, o: &Self) {
        Window32::add(self, o);
    }
    #[inline]
    fn sub(&mut self, o: &Self) {
        Window32::sub(self, o);
    }
    #[inline]
    fn numerators(&self) -> (i32, i64, i64, i64) {
        let (w, x, y) = (i64::from(self.w), i64::from(self.x), i64::from(self.y));
        (
            self.w,
            w * i64::from(self.xx) - x * x,
            w * i64::from(self.xy) - x * y,
            w * i64::from(self.yy) - y * y,
        )
    }
}

/// `v as f32` (round to nearest, ties to even) without the library routine a 32-bit core
/// calls for a 64-bit integer (`__aeabi_l2f`): below `2^32` the `u32` conversion (one
/// instruction); above, the top 32 bits of `|v|` with a sticky bit for the rest in bit 0
/// (below the 8 bits that conversion rounds away, so it rounds exactly as the full value),
/// scaled by the exact power of two.
#[inline]
fn to_f32(v: i64) -> f32 {
    let r = to_f32_unsigned(v.unsigned_abs());
    if v < 0 { -r } else { r }
}

/// `a as f32` ([`to_f32`] of a magnitude).
#[inline]
fn to_f32_unsigned(a: u64) -> f32 {
    let (hi, lo) = ((a >> 32) as u32, a as u32);
    if hi == 0 {
        lo as f32
    } else {
        // 1..=32 bits below the top 32.
        let sh = 32 - hi.leading_zeros();
        let m = (a >> sh) as u32 | u32::from(lo << (32 - sh) != 0);
        (m as f32) * f32::from_bits((127 + sh) << 23)
    }
}

/// The error `N λ_min` (pixels²) of a window fit from its sums. Always inlined: out of line,
/// the window's sums go through memory at every point.
#[inline(always)]
fn window_error<S: WindowSums>(m: &S, count: usize) -> f32 {
    let (w, cxx, cxy, cyy) = m.numerators();
    if w <= 0 {
        return 0.0;
    }
    // `cxx`, `cyy` ≥ 0 (Cauchy-Schwarz on exact integers with positive weights): their bits
    // are their magnitudes, no absolute value to take.
    let cxx = to_f32_unsigned(cxx as u64);
    let cxy = to_f32(cxy);
    let cyy = to_f32_unsigned(cyy as u64);
    // Doubled coordinates: covariances in pixels² are a quarter.
    let wf = w as f32;
    let s = 0.25 / (wf * wf);
    let (small, _) = eigenvalues(cxx * s, cxy * s, cyy * s);
    count as f32 * small
}

/// `w s₂ - a b` exactly (a covariance numerator), in `i64` when it fits (frames up to about
/// 640x480), else `i128`; then as `f32`. `small`: both products are known to be below `2^62`
/// (plain `i64`, no checks).
#[inline]
fn cov(w: i64, s2: i64, a: i64, b: i64, small: bool) -> f32 {
    if small {
        return to_f32(w * s2 - a * b);
    }
    match (w.checked_mul(s2), a.checked_mul(b)) {
        (Some(p), Some(q)) => to_f32(p.wrapping_sub(q)),
        _ => (i128::from(w) * i128::from(s2) - i128::from(a) * i128::from(b)) as f32,
    }
}

/// The covariance of a run in pixels² (`cxx`, `cxy`, `cyy`) and its weight `Σw` as `f32`,
/// from the exact numerators; `None` without weight. `small` as [`cov`] (see [`products_fit`]).
#[inline]
fn covariance(m: &Moments, small: bool) -> Option<(f32, f32, f32, f32)> {
    if m.w <= 0 {
        return None;
    }
    let cxx = cov(m.w, m.xx, m.x, m.x, small);
    let cxy = cov(m.w, m.xy, m.x, m.y, small);
    let cyy = cov(m.w, m.yy, m.y, m.y, small);
    let wf = to_f32(m.w);
    let s = 0.25 / (wf * wf);
    Some((cxx * s, cxy * s, cyy * s, wf))
}

/// Whether every covariance product of a run of the points with moments `total` is below
/// `2^62`: a run's sums are parts of the total's with `w ≥ 0` and `w u² ≥ 0`, so its `Σw ≤ W`,
/// `Σw u² ≤ XX`, and by Cauchy-Schwarz `(Σw u)² ≤ Σw Σw u²`, `|Σw u Σw v|` and `|Σw Σw u v|` at
/// most `W max(XX, YY)`.
fn products_fit(total: &Moments) -> bool {
    total
        .w
        .checked_mul(total.xx.max(total.yy))
        .is_some_and(|b| (0..1 << 62).contains(&b))
}

/// The line fit of a run from its moments (exact covariance numerators: a run can hold a
/// whole cluster) with the bounding box corner `(x0, y0)` in doubled coordinates: the line
/// through the weighted mean (pixels) and its `λ_min` (the mean squared distance, px²).
fn fit_line(m: &Moments, x0: i32, y0: i32, small: bool) -> Option<(Line, f32)> {
    let (cxx, cxy, cyy, wf) = covariance(m, small)?;
    let (small, _, nx, ny) = eigen(cxx, cxy, cyy);
    let line = Line {
        ex: 0.5 * (to_f32(m.x) / wf + x0 as f32),
        ey: 0.5 * (to_f32(m.y) / wf + y0 as f32),
        nx,
        ny,
    };
    Some((line, small))
}

/// The sampled image's pixels by index, for the gradient weights: the offsets of a pixel's
/// four neighbours are the same for every point (no multiplications per pixel).
struct Gradient<'a> {
    data: &'a [u8],
    /// Index step of one sampled pixel along a row (`d`) and down a column (`d` rows).
    step: usize,
    row: usize,
    w: usize,
    h: usize,
}

impl<'a> Gradient<'a> {
    fn new(src: &Sampled<'a>) -> Self {
        Self {
            data: src.img.data(),
            step: src.d,
            row: src.d * src.img.stride(),
            w: src.w,
            h: src.h,
        }
    }

    /// The sum of the weights of `pts` (in order) until it reaches `need` (module docs: the
    /// weights are positive). Not inlined, as [`Self::weights`].
    #[inline(never)]
    fn sum_until(&self, pts: &[u32], need: u32) -> u32 {
        let mut sum = 0u32;
        for &p in pts.iter() {
            if sum >= need {
                break;
            }
            sum += u32::from(self.weight(p));
        }
        sum
    }

    /// Packs each of `pts` with its weight ([`Packed`]; the box corner `(x0, y0)` and its
    /// extents below `2^11`) and returns the sum of the weights (`n < 2^16` weights below
    /// `2^9`: no overflow). Not inlined, as [`Self::weights`].
    #[inline(never)]
    fn pack(&self, pts: &mut [u32], x0: i32, y0: i32) -> u32 {
        let mut sum = 0u32;
        for p in pts.iter_mut() {
            let w = self.weight(*p);
            sum += u32::from(w);
            let (x2, y2, _, _) = unpack(*p);
            *p = Packed::pack(x2 - x0, y2 - y0, w);
        }
        sum
    }

    /// The weight of each of `pts` into `out`. Not inlined: the loop then has the registers
    /// of its own function, not the ones `fit_quad` leaves (its values spill to the stack).
    #[inline(never)]
    fn weights(&self, pts: &[u32], out: &mut [u16]) {
        for (p, k) in pts.iter().zip(out.iter_mut()) {
            *k = self.weight(*p);
        }
    }

    /// The gradient weight of a boundary point in the sampled image (module docs): pixel
    /// `(x, y)` is `data[(y d) stride + x d]`, 0 past the end.
    #[inline]
    fn weight(&self, p: u32) -> u16 {
        let (x2, y2, _, _) = unpack(p);
        let (ix, iy) = (((x2 + 1) >> 1) as usize, ((y2 + 1) >> 1) as usize);
        // Not on the border: 1 ≤ ix ≤ w - 2 and the same for iy (0 wraps to the largest).
        if ix.wrapping_sub(1) >= self.w.saturating_sub(2)
            || iy.wrapping_sub(1) >= self.h.saturating_sub(2)
        {
            return 1;
        }
        // (ix, iy) is inside the sampled image, not on its border: all four neighbours are.
        let c = iy * self.row + ix * self.step;
        let px = |i: usize| i32::from(self.data.get(i).copied().unwrap_or(0));
        let gx = px(c + self.step) - px(c - self.step);
        let gy = px(c + self.row) - px(c - self.row);
        let (a, b) = (gx.unsigned_abs(), gy.unsigned_abs());
        let (hi, lo) = if a > b { (a, b) } else { (b, a) };
        (hi + (3 * lo) / 8 + 1) as u16
    }
}

/// The Gaussian low-pass of the corner search (σ = 1, AprilTag's 5 % cutoff: 7 taps).
const FILTER: [f32; 7] = [
    0.011_108_997,
    0.135_335_28,
    0.606_530_66,
    1.0,
    0.606_530_66,
    0.135_335_28,
    0.011_108_997,
];

/// The corner candidates of step 2 (module docs) of the weighted points `pts` in angle
/// order, `(uc, vc)` the bounding box centre relative to its corner, `ksz` the window's half
/// width and `S` the window's sums: the largest local maxima of the filtered window errors
/// offered to `heap` (as `(error bits, index)`); returns how many the heap holds and how many
/// maxima there were. Not inlined: in a function of its own the window's sums spill less than
/// among `fit_quad`'s values.
#[inline(never)]
fn candidates<S: WindowSums, P: Points>(
    pts: P,
    (uc, vc): (i32, i32),
    ksz: usize,
    heap: &mut [(u32, u32)],
) -> (usize, usize) {
    let n = pts.len();
    let m_at = |i: usize| -> S {
        match pts.at(i) {
            Some((u, v, w)) => S::of(u - uc, v - vc, w),
            None => S::default(),
        }
    };
    // `checked_`: a division by `n` is a panic path for the compiler, which does not know
    // `n > 0` here (the caller's `ksz ≥ 2` needs `n ≥ 24`).
    let wrap = |i: isize| -> usize { i.checked_rem_euclid(n as isize).unwrap_or(0) as usize };
    let count = 2 * ksz + 1;
    let start: isize = -4;
    // The points entering and leaving, in cyclic order.
    let next = |i: usize| if i + 1 >= n { 0 } else { i + 1 };
    let mut leaving = wrap(start - ksz as isize);
    // The window's moments: the first window's points from the first to leave on (stepped
    // as in the loop below, not wrapped by a division each), then each step adds the point
    // entering and subtracts the one leaving.
    let mut win = S::default();
    let mut entering = leaving;
    for _ in 0..count {
        win.add(&m_at(entering));
        entering = next(entering);
    }
    // The last 7 errors (oldest first) and the last three filtered values.
    let mut errs = [0f32; 7];
    let (mut y0, mut y1, mut y2) = (0f32, 0f32, 0f32);
    let mut nbest = 0usize;
    let mut nmaxima = 0usize;
    for t in 0..n + 8 {
        if t > 0 {
            win.add(&m_at(entering));
            win.sub(&m_at(leaving));
            (entering, leaving) = (next(entering), next(leaving));
        }
        let [_, e1, e2, e3, e4, e5, e6] = errs;
        errs = [e1, e2, e3, e4, e5, e6, window_error(&win, count)];
        if t >= 6 {
            let mut y = 0.0;
            for (f, e) in FILTER.iter().zip(errs) {
                y += f * e;
            }
            (y0, y1, y2) = (y1, y2, y);
        }
        if t >= 8 && y1 > y0 && y1 > y2 {
            // The candidate at position t - 8 in [0, n).
            nmaxima += 1;
            // Non-negative f32 bits order as the values.
            let item = (y1.to_bits(), (t - 8) as u32);
            offer_best(heap, &mut nbest, item, |it| i64::from(it.0));
        }
    }
    (nbest, nmaxima)
}

/// Steps 2 and 3 (module docs) on the weighted points `pts` in angle order, with a bounding
/// box of extents `(dx, dy)` (doubled) and windows of half width `ksz`: at most `kmax`
/// candidates into `best` in increasing position and the prefix moments at them into `pre`
/// and `inc`; returns how many candidates and the total moments, `None` with fewer than 4.
fn corner_runs<P: Points + Copy>(
    pts: P,
    (dx, dy): (i32, i32),
    ksz: usize,
    kmax: usize,
    best: &mut [(u32, u32); MAX_NMAXIMA],
    pre: &mut [Moments; MAX_NMAXIMA],
    inc: &mut [Moments; MAX_NMAXIMA],
) -> Option<(usize, Moments)> {
    let heap = best.get_mut(..kmax)?;
    // The window's sums about the bounding box centre, in `i32` when they fit.
    let centre = (dx >> 1, dy >> 1);
    let (nbest, nmaxima) = if Window32::fits(2 * ksz + 1, dx - centre.0, dy - centre.1) {
        candidates::<Window32, P>(pts, centre, ksz, heap)
    } else {
        candidates::<Window, P>(pts, centre, ksz, heap)
    };
    if nmaxima < 4 || nbest < 4 {
        return None;
    }
    let cand = best.get_mut(..nbest)?;
    crate::corners::heapsort_by(cand, |a, b| a.1.cmp(&b.1));
    Some((nbest, prefix_moments(pts, cand, pre, inc)))
}

/// The prefix moments (relative to the box corner) of `pts` just before and at each of the
/// candidates `cand` (distinct positions in increasing order) into `pre` and `inc`; returns
/// the moments of all the points.
fn prefix_moments<P: Points>(
    pts: P,
    cand: &[(u32, u32)],
    pre: &mut [Moments],
    inc: &mut [Moments],
) -> Moments {
    let mut acc = Moments::default();
    let add_range = |acc: &mut Moments, from: usize, to: usize| {
        pts.each(from, to, |(u, v, w)| {
            acc.add_window(&<Window as WindowSums>::of(u, v, w));
        });
    };
    let mut from = 0usize;
    for ((c, p), q) in cand.iter().zip(pre.iter_mut()).zip(inc.iter_mut()) {
        let at = c.1 as usize;
        add_range(&mut acc, from, at);
        *p = acc;
        add_range(&mut acc, at, at + 1);
        *q = acc;
        from = at + 1;
    }
    add_range(&mut acc, from, pts.len());
    acc
}

/// Fits a quad to one cluster's points (module docs). `pts` is left reordered and, for a
/// bounding box below `2^11` doubled pixels a side, rewritten ([`Packed`]); `keys` is scratch
/// of at least `pts.len()` entries. `bbox = (xmin, xmax, ymin, ymax)` in doubled coordinates; `reversed`
/// the border kind ([`Cluster::shape`]).
pub(crate) fn fit_quad(
    src: &Sampled<'_>,
    pts: &mut [u32],
    keys: &mut [u16],
    bbox: (u16, u16, u16, u16),
    reversed: bool,
    prm: &QuadParams,
) -> Option<Quad> {
    let n = pts.len();
    let keys = keys.get_mut(..n)?;
    let (xmin, xmax, ymin, ymax) = (
        i32::from(bbox.0),
        i32::from(bbox.1),
        i32::from(bbox.2),
        i32::from(bbox.3),
    );
    // AprilTag's first test, in its units (doubled coordinates against the width in cells).
    if i64::from(xmax - xmin) * i64::from(ymax - ymin) < i64::from(prm.min_tag_width) {
        return None;
    }
    if (reversed && !prm.reversed_border) || (!reversed && !prm.normal_border) {
        return None;
    }
    let ksz = (n / 12).min(20);
    if ksz < 2 {
        return None;
    }
    // 0. The edge contrast: the mean gradient weight (`n < 2^16` weights below 2^9: no
    //    overflow). 1. Angle keys around the centre, the sort. 2. The weights: packed into
    //    the point words with the coordinates relative to the box when it is small enough
    //    (one pass of weights), else summed first (until the sum reaches the bound: the
    //    weights are positive, the same decision) and computed again after the sort (which
    //    needs the same scratch for its keys) into the keys.
    let grad = Gradient::new(src);
    let need = prm.min_edge_gradient.saturating_mul(n as u32);
    let (dx, dy) = (xmax - xmin, ymax - ymin);
    let mut best = [(0u32, 0u32); MAX_NMAXIMA];
    let mut pre = [Moments::default(); MAX_NMAXIMA];
    let mut inc = [Moments::default(); MAX_NMAXIMA];
    let kmax = prm.max_nmaxima.clamp(4, MAX_NMAXIMA);
    let found = if Packed::fits(dx, dy) {
        if grad.pack(pts, xmin, ymin) < need {
            return None;
        }
        angle_keys::<Packed>(pts, keys, dx, dy);
        sort_by_key(pts, keys);
        corner_runs(
            Packed(pts),
            (dx, dy),
            ksz,
            kmax,
            &mut best,
            &mut pre,
            &mut inc,
        )
    } else {
        if grad.sum_until(pts, need) < need {
            return None;
        }
        angle_keys::<Split>(pts, keys, xmin + xmax, ymin + ymax);
        sort_by_key(pts, keys);
        grad.weights(pts, keys);
        let split = Split {
            pts,
            weights: keys,
            x0: xmin,
            y0: ymin,
        };
        corner_runs(split, (dx, dy), ksz, kmax, &mut best, &mut pre, &mut inc)
    };
    let (nbest, total) = found?;
    let cand = best.get(..nbest)?;
    let small = products_fit(&total);
    let idx = |a: usize| cand.get(a).map_or(0, |c| c.1 as usize);
    // Moments and point count of the run from candidate a to candidate b (inclusive, wrapping).
    let run = |a: usize, b: usize| -> (Moments, usize) {
        let (pa, ia) = (pre.get(a).copied().unwrap_or_default(), idx(a));
        let (ib_inc, ib) = (inc.get(b).copied().unwrap_or_default(), idx(b));
        let mut m = ib_inc;
        if ia <= ib {
            m.sub(&pa);
            (m, ib - ia + 1)
        } else {
            let mut t = total;
            t.sub(&pa);
            t.add(&ib_inc);
            (t, n - ia + ib + 1)
        }
    };
    // The line of a run, its `λ_min` and its error `N λ_min`.
    let fit = |a: usize, b: usize| -> Option<(Line, f32, f32)> {
        let (m, cnt) = run(a, b);
        let (l, mse) = fit_line(&m, xmin, ymin, small)?;
        Some((l, mse, cnt as f32 * mse))
    };
    let mse_max = prm.max_line_fit_mse;
    let k = cand.len();
    // The runs between two candidates, each fitted when the search first asks for it:
    // (normal, N λ_min), `None` when the fit fails or `λ_min` exceeds the bound (the normal
    // is then not needed).
    type Fits = [[Option<(f32, f32, f32)>; MAX_NMAXIMA]; MAX_NMAXIMA];
    let mut fits: Fits = [[None; MAX_NMAXIMA]; MAX_NMAXIMA];
    let mut done = [0u16; MAX_NMAXIMA];
    let get = |fits: &mut Fits, done: &mut [u16; MAX_NMAXIMA], a: usize, b: usize| {
        let asked = done.get_mut(a)?;
        let bit = 1u16.checked_shl(b as u32)?;
        let slot = fits.get_mut(a)?.get_mut(b)?;
        if *asked & bit == 0 {
            *asked |= bit;
            let (m, cnt) = run(a, b);
            *slot = covariance(&m, small).and_then(|(cxx, cxy, cyy, _)| {
                let (small, big) = eigenvalues(cxx, cxy, cyy);
                if !at_most(small, mse_max) {
                    return None;
                }
                let (nx, ny) = normal(cxx, cxy, cyy, big);
                Some((nx, ny, cnt as f32 * small))
            });
        }
        *slot
    };
    let mut best_err = f32::INFINITY;
    let mut best_idx = [0usize; 4];
    // A split's error is `((e01 + e12) + e23) + e30` with every term at least 0, and adding a
    // non-negative float never lowers a sum: a partial sum at or above the best error cannot
    // win, and the runs after it are not fitted (a run's fit does not depend on when it is
    // made: the same splits are compared, with the same errors).
    for m0 in 0..k.saturating_sub(3) {
        for m1 in m0 + 1..k.saturating_sub(2) {
            let Some((nx01, ny01, e01)) = get(&mut fits, &mut done, m0, m1) else {
                continue;
            };
            if at_most(best_err, e01) {
                continue;
            }
            for m2 in m1 + 1..k.saturating_sub(1) {
                let Some((nx12, ny12, e12)) = get(&mut fits, &mut done, m1, m2) else {
                    continue;
                };
                let e012 = e01 + e12;
                if at_most(best_err, e012) || (nx01 * nx12 + ny01 * ny12).abs() > prm.cos_critical {
                    continue;
                }
                for m3 in m2 + 1..k {
                    let Some((_, _, e23)) = get(&mut fits, &mut done, m2, m3) else {
                        continue;
                    };
                    let e0123 = e012 + e23;
                    if at_most(best_err, e0123) {
                        continue;
                    }
                    let Some((_, _, e30)) = get(&mut fits, &mut done, m3, m0) else {
                        continue;
                    };
                    let err = e0123 + e30;
                    if err < best_err {
                        best_err = err;
                        best_idx = [m0, m1, m2, m3];
                    }
                }
            }
        }
    }
    if !above(mse_max, best_err / (n as f32)) {
        return None;
    }
    // 4. Lines, corners, and the shape checks.
    let mut lines = [Line::ZERO; 4];
    for (i, l) in lines.iter_mut().enumerate() {
        let (line, mse, _) = fit(at4(&best_idx, i), at4(&best_idx, i + 1))?;
        if !at_most(mse, mse_max) {
            return None;
        }
        *l = line;
    }
    let mut p = [Point2::origin(); 4];
    for (i, c) in p.iter_mut().enumerate() {
        *c = intersect(&at4(&lines, i), &at4(&lines, i + 1))?;
    }
    let cross = |a: Point2<f32>, b: Point2<f32>, c: Point2<f32>| {
        (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)
    };
    let [p0, p1, p2, p3] = p;
    let area = 0.5 * (cross(p0, p1, p2).abs() + cross(p2, p3, p0).abs());
    let tw = prm.min_tag_width as f32;
    if !at_most(0.95 * tw * tw, area) {
        return None;
    }
    for i in 0..4 {
        let (a, b, c) = (at4(&p, i), at4(&p, i + 1), at4(&p, i + 2));
        let (d1, d2) = (b - a, c - b);
        let den = libm::sqrtf(d1.norm_squared() * d2.norm_squared());
        if !above(den, 0.0) {
            return None;
        }
        let cos = d1.dot(&d2) / den;
        if !at_most(cos.abs(), prm.cos_critical) || d1.x * d2.y < d1.y * d2.x {
            return None;
        }
    }
    Some(Quad {
        p,
        reversed_border: reversed,
    })
}

#[cfg(test)]
mod tests {
    use super::{sort_by_key, to_f32};

    #[test]
    fn sort_by_key_orders_and_keeps_each_point_with_its_key() {
        let mut seed = 12345u32;
        for n in [0usize, 1, 2, 17, 300, 5000] {
            // Few distinct high bytes and many ties: both passes and the insertion sort run.
            let mut keys: std::vec::Vec<u16> = (0..n)
                .map(|_| {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    ((seed >> 16) as u16) & 0x0f3f
                })
                .collect();
            let mut pts: std::vec::Vec<u32> = keys
                .iter()
                .enumerate()
                .map(|(i, &k)| (u32::from(k) << 16) | i as u32)
                .collect();
            let mut want = pts.clone();
            want.sort_unstable();
            sort_by_key(&mut pts, &mut keys);
            assert!(keys.windows(2).all(|w| w[0] <= w[1]));
            assert!(pts.iter().zip(&keys).all(|(&p, &k)| (p >> 16) as u16 == k));
            let mut got = pts.clone();
            got.sort_unstable();
            assert_eq!(got, want);
        }
    }

    /// The textbook American-flag sort (swaps over all 256 buckets, insertion sort in buckets
    /// of at most 16): the permutation [`sort_by_key`] keeps, ties included.
    fn textbook_sort(pts: &mut [u32], keys: &mut [u16]) {
        fn pass(pts: &mut [u32], keys: &mut [u16], shift: u32) -> std::vec::Vec<usize> {
            let digit = |k: u16| usize::from((k >> shift) & 255);
            let mut bounds = std::vec![0usize; 257];
            for &k in keys.iter() {
                bounds[digit(k) + 1] += 1;
            }
            for b in 0..256 {
                bounds[b + 1] += bounds[b];
            }
            let mut next = bounds.clone();
            for b in 0..256 {
                while next[b] < bounds[b + 1] {
                    let i = next[b];
                    let d = digit(keys[i]);
                    if d == b {
                        next[b] += 1;
                    } else {
                        let j = next[d];
                        next[d] += 1;
                        keys.swap(i, j);
                        pts.swap(i, j);
                    }
                }
            }
            bounds
        }
        let bounds = pass(pts, keys, 8);
        for b in 0..256 {
            let (s, e) = (bounds[b], bounds[b + 1]);
            if e - s > 16 {
                pass(&mut pts[s..e], &mut keys[s..e], 0);
            } else {
                for i in s + 1..e {
                    let mut j = i;
                    while j > s && keys[j - 1] > keys[j] {
                        keys.swap(j - 1, j);
                        pts.swap(j - 1, j);
                        j -= 1;
                    }
                }
            }
        }
    }

    #[test]
    fn sort_by_key_permutes_as_the_textbook_sort() {
        let mut seed = 2024u32;
        for (n, mask) in [
            (40usize, 0x0307u16),
            (300, 0x1f3f),
            (2000, 0xffff),
            (5000, 0x0f0f),
        ] {
            let mut keys: std::vec::Vec<u16> = (0..n)
                .map(|_| {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    ((seed >> 16) as u16) & mask
                })
                .collect();
            let mut pts: std::vec::Vec<u32> = (0..n as u32).collect();
            let (mut want_pts, mut want_keys) = (pts.clone(), keys.clone());
            textbook_sort(&mut want_pts, &mut want_keys);
            sort_by_key(&mut pts, &mut keys);
            assert_eq!(pts, want_pts);
            assert_eq!(keys, want_keys);
        }
    }

    #[test]
    fn to_f32_rounds_as_the_cast() {
        let mut edge = std::vec::Vec::new();
        for b in 0..64 {
            let p = 1i64.checked_shl(b).unwrap_or(0);
            for d in [-3i64, -1, 0, 1, 3] {
                edge.push(p.wrapping_add(d));
            }
            // Ties and near-ties at 24 significant bits.
            if b >= 25 {
                let half = 1i64 << (b - 25);
                edge.extend([p + half, p + 3 * half, p + half - 1, p + half + 1]);
            }
        }
        edge.extend([i64::MIN, i64::MAX, i64::MIN + 1]);
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        for i in 0..200_000 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            // All magnitudes: shift a random word right by 0..63.
            edge.push((seed >> (i % 64)) as i64);
        }
        for v in edge.iter().flat_map(|&v| [v, v.wrapping_neg()]) {
            assert_eq!(to_f32(v).to_bits(), (v as f32).to_bits(), "{v}");
        }
    }
}
