//! Shi-Tomasi corners ("good features to track"), integer only, streaming over rows.
//!
//! With Sobel derivatives `dx, dy` (3x3, `BORDER_REFLECT_101`) summed over 3x3 blocks,
//! `A = Σ dx²`, `B = Σ dx dy`, `C = Σ dy²`, the score is twice the smaller eigenvalue of the
//! structure tensor:
//!
//! `S = A + C - √((A - C)² + 4 B²)`  (OpenCV's `cornerMinEigenVal` is `S / (2 (4·3·255)²)`).
//!
//! As OpenCV's `goodFeaturesToTrack`: keep pixels (off the 1-pixel border) with
//! `S > quality · max S` that are maxima of their 3x3 neighbourhood, strongest first, and drop
//! any closer than `min_distance` to one already kept — or to an existing point passed in, so
//! the same call replenishes empty regions of a frame that is already being tracked.
//!
//! Memory: [`scratch_len`]`(width)` `u32` of scratch (three rows of Sobel products, three of
//! scores) and a caller slice of candidates; no full-frame score map. One pass over the rows:
//! each row's Sobel products are computed once, and the square root is taken only where the
//! score can still matter (`S <= A + C`, so pixels whose trace is below the running threshold
//! `quality · max S so far` are skipped; the threshold only rises, so nothing skipped could
//! have been kept).
//!
//! ```
//! use camgeom::corners::{Corner, CornerParams, good_features, scratch_len};
//! use camgeom::heapless::Vec;
//! use camgeom::image::ImageView;
//!
//! // A white square on black, pixels 10..=21: its corners are at 9.5 and 21.5.
//! let mut img = [0u8; 32 * 32];
//! for y in 10..22 {
//!     img[y * 32 + 10..y * 32 + 22].fill(255);
//! }
//! let view = ImageView::packed(&img, 32, 32)?;
//! let cfg = CornerParams::default();
//! let (mut cands, mut scratch) = ([Corner::default(); 64], [0u32; scratch_len(32)]);
//! let mut found: Vec<Corner, 16> = Vec::new();
//! let none = core::iter::empty();
//! assert_eq!(good_features(&view, &cfg, none, &mut found, &mut cands, &mut scratch)?, 4);
//! for [cx, cy] in [[9.5, 9.5], [21.5, 9.5], [9.5, 21.5], [21.5, 21.5]] {
//!     let d = |c: &Corner| (f32::from(c.x) - cx).abs().max((f32::from(c.y) - cy).abs());
//!     assert_eq!(found.iter().filter(|c| d(c) <= 1.0).count(), 1);
//! }
//! // Replenishing: with those four already tracked there is nothing left to add.
//! let tracked = found.clone();
//! let existing = tracked.iter().map(|c| [i32::from(c.x), i32::from(c.y)]);
//! assert_eq!(good_features(&view, &cfg, existing, &mut found, &mut cands, &mut scratch)?, 0);
//! # Ok::<(), camgeom::Error>(())
//! ```

use heapless::Vec;

use crate::gradient::reflect101;
use crate::image::ImageView;
use crate::{Error, Result};

/// A corner: pixel position and score `S` (larger is stronger).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Corner {
    /// Column.
    pub x: u16,
    /// Row.
    pub y: u16,
    /// `A + C - √((A - C)² + 4 B²)`.
    pub score: u32,
}

/// Parameters of [`good_features`] (OpenCV's `qualityLevel`, `minDistance`), as the user
/// writes them; checked by [`Self::check`] into the [`CornerParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CornerConfig {
    /// Keep scores above `quality · max S`, in `(0, 1]`. Default 0.01.
    pub quality: f32,
    /// Minimum Euclidean distance between corners, pixels. Default 10.
    pub min_distance: u32,
    /// Most corners to add in one call (`maxCorners`); 0: up to the output's capacity.
    pub max_corners: usize,
}

impl CornerConfig {
    /// Checks the configuration once: [`good_features`] takes the checked [`CornerParams`].
    /// Errors: [`Error::InvalidParameter`] (`corners.quality`) for a quality outside `(0, 1]`.
    pub fn check(&self) -> Result<CornerParams> {
        if self.quality > 0.0 && self.quality <= 1.0 {
            Ok(CornerParams(*self))
        } else {
            Err(Error::InvalidParameter("corners.quality"))
        }
    }

    /// The same configuration adding at most `free` corners: [`Self::max_corners`] capped by
    /// `free` (0 means no cap of its own, so `free` it is). What a tracker with `free` empty
    /// slots asks for.
    pub const fn up_to(&self, free: usize) -> Self {
        let max_corners = if self.max_corners == 0 || self.max_corners > free {
            free
        } else {
            self.max_corners
        };
        Self {
            max_corners,
            ..*self
        }
    }
}

impl Default for CornerConfig {
    fn default() -> Self {
        Self {
            quality: 0.01,
            min_distance: 10,
            max_corners: 0,
        }
    }
}

/// A [`CornerConfig`] that passed [`CornerConfig::check`] (a quality in `(0, 1]`): what
/// [`good_features`] takes, so that no call checks it again.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CornerParams(CornerConfig);

impl CornerParams {
    /// The checked configuration.
    pub const fn config(&self) -> &CornerConfig {
        &self.0
    }

    /// [`CornerConfig::up_to`] of the checked configuration: at most `free` corners added. Still
    /// checked: only [`CornerConfig::max_corners`] changes, and it has no range to keep.
    pub const fn up_to(&self, free: usize) -> Self {
        Self(self.0.up_to(free))
    }

    /// `config` taken as checked without checking it: only for a holder that checked it when
    /// it was built and keeps the plain [`CornerConfig`] (the KLT tracker, whose size the
    /// board's frame loop counts in its static RAM).
    pub(crate) const fn assume_checked(config: CornerConfig) -> Self {
        Self(config)
    }
}

impl Default for CornerParams {
    /// The checked [`CornerConfig::default`].
    fn default() -> Self {
        Self(CornerConfig::default())
    }
}

impl TryFrom<CornerConfig> for CornerParams {
    type Error = Error;
    fn try_from(c: CornerConfig) -> Result<Self> {
        c.check()
    }
}

/// `u32` elements of scratch [`good_features`] needs for frames `width` pixels wide:
/// `12 width`.
pub const fn scratch_len(width: usize) -> usize {
    12 * width
}

/// Sobel `dx, dy` at the middle column of three-pixel windows of rows `r0, r1, r2`.
#[inline(always)]
fn sobel(r0: [u8; 3], r1: [u8; 3], r2: [u8; 3]) -> (i32, i32) {
    let p = i32::from;
    let dx = (p(r0[2]) - p(r0[0])) + 2 * (p(r1[2]) - p(r1[0])) + (p(r2[2]) - p(r2[0]));
    let dy = (p(r2[0]) + 2 * p(r2[1]) + p(r2[2])) - (p(r0[0]) + 2 * p(r0[1]) + p(r0[2]));
    (dx, dy)
}

/// The three pixels of `row` at columns `x - 1, x, x + 1`, reflected at the ends.
#[inline]
fn triple(row: &[u8], x: usize, w: usize) -> [u8; 3] {
    let at = |c: isize| row.get(reflect101(c, w)).copied().unwrap_or(0);
    let xi = x as isize;
    [at(xi - 1), at(xi), at(xi + 1)]
}

/// The Sobel products of image row `r` into `out = [dx² | dx dy | dy²]` (`3 width`; `dx dy`
/// stored two's complement).
#[inline(never)]
fn sobel_products<const V: bool>(img: &ImageView<'_, u8>, r: usize, out: &mut [u32]) {
    let (w, h) = (img.width(), img.height());
    let ri = r as isize;
    let r0 = img.row_clamped(reflect101(ri - 1, h) as isize);
    let r1 = img.row_clamped(ri);
    let r2 = img.row_clamped(reflect101(ri + 1, h) as isize);
    let (sxx, rest) = out.split_at_mut(w.min(out.len()));
    let (sxy, syy) = rest.split_at_mut(w.min(rest.len()));
    let mut put = |x: usize, (dx, dy): (i32, i32)| {
        // |dx|, |dy| <= 1020: the products and 9-term sums stay far inside u32 / i32.
        if let (Some(a), Some(b), Some(c)) = (sxx.get_mut(x), sxy.get_mut(x), syy.get_mut(x)) {
            *a = (dx * dx) as u32;
            *b = (dx * dy) as u32;
            *c = (dy * dy) as u32;
        }
    };
    if w < 3 {
        for x in 0..w {
            put(
                x,
                sobel(triple(r0, x, w), triple(r1, x, w), triple(r2, x, w)),
            );
        }
        return;
    }
    put(
        0,
        sobel(triple(r0, 0, w), triple(r1, 0, w), triple(r2, 0, w)),
    );
    let last = w - 1;
    put(
        last,
        sobel(
            triple(r0, last, w),
            triple(r1, last, w),
            triple(r2, last, w),
        ),
    );
    // Interior: no reflection.
    let outs = sxx
        .iter_mut()
        .skip(1)
        .zip(sxy.iter_mut().skip(1))
        .zip(syy.iter_mut().skip(1));
    if V {
        // The three rows' pixels at columns x - 1, x, x + 1 as shifted slices, derivatives in
        // `i16` (|dx|, |dy| <= 1020), products widened to `i32`: a straight loop that
        // vectorises (`pmullw`/`pmulhw` on SSE2).
        let n = w - 2;
        fn at(r: &[u8], k: usize, n: usize) -> &[u8] {
            r.get(k..k + n).unwrap_or(&[])
        }
        let top = at(r0, 0, n).iter().zip(at(r0, 1, n)).zip(at(r0, 2, n));
        let mid = at(r1, 0, n).iter().zip(at(r1, 2, n));
        let bot = at(r2, 0, n).iter().zip(at(r2, 1, n)).zip(at(r2, 2, n));
        for (((a, b), c), ((((&t0, &t1), &t2), (&m0, &m2)), ((&d0, &d1), &d2))) in
            outs.zip(top.zip(mid).zip(bot))
        {
            let p = i16::from;
            let dx = (p(t2) - p(t0)) + 2 * (p(m2) - p(m0)) + (p(d2) - p(d0));
            let dy = (p(d0) + 2 * p(d1) + p(d2)) - (p(t0) + 2 * p(t1) + p(t2));
            let (dx, dy) = (i32::from(dx), i32::from(dy));
            *a = (dx * dx) as u32;
            *b = (dx * dy) as u32;
            *c = (dy * dy) as u32;
        }
    } else {
        // Straight 3-wide windows in `i32` (cheaper than `i16` lanes on a 32-bit core).
        let rows = r0.windows(3).zip(r1.windows(3)).zip(r2.windows(3));
        for (((a, b), c), ((t, m), d)) in outs.zip(rows).take(w - 2) {
            let (&[t0, t1, t2], &[m0, _, m2], &[d0, d1, d2]) = (t, m, d) else {
                continue;
            };
            let (dx, dy) = sobel([t0, t1, t2], [m0, 0, m2], [d0, d1, d2]);
            *a = (dx * dx) as u32;
            *b = (dx * dy) as u32;
            *c = (dy * dy) as u32;
        }
    }
}

/// Scores of one row from the product rows above, at and below it (`3 width` each) into
/// `out`: `S = A + C - ⌊√((A - C)² + 4 B²)⌋` over 3x3 blocks (reflected at the ends), or 0
/// where `S <= floor` (no caller tells such a score from 0: the running maximum is above the
/// floor, and candidates must beat it). Returns the row's largest score.
///
/// `S > floor ⟺ ⌊√disc⌋ < A + C - floor ⟺ disc < (A + C - floor)²`: the integer root (a
/// 64-bit routine of a few hundred instructions on a Cortex-M) only for scores that count.
#[inline(never)]
fn score_row<const V: bool>(
    up: &[u32],
    mid: &[u32],
    down: &[u32],
    w: usize,
    floor: u32,
    out: &mut [u32],
) -> u32 {
    let floor = u64::from(floor);
    let score = |[a, b, c]: [u32; 3]| -> u32 {
        let (a, b, c) = (u64::from(a), i64::from(b as i32), u64::from(c));
        let tr = a + c;
        if tr <= floor {
            return 0;
        }
        let d = a.abs_diff(c);
        let disc = d * d + 4 * b.unsigned_abs() * b.unsigned_abs();
        // Sums of 9 products of Sobel values (|·| <= 1020): tr < 2²⁵, so lim² < 2⁵⁰.
        let lim = tr - floor;
        if disc >= lim * lim {
            return 0;
        }
        tr.saturating_sub(crate::fixed::isqrt(disc))
            .min(u64::from(u32::MAX)) as u32
    };
    // Vertical sums of the three channels at column `x` (any column: for the reflected ends).
    let col = |x: usize| -> [u32; 3] {
        core::array::from_fn(|k| {
            let g = |s: &[u32]| s.get(k * w + x).copied().unwrap_or(0);
            g(up).wrapping_add(g(mid)).wrapping_add(g(down))
        })
    };
    let add3 = |[a0, a1, a2]: [u32; 3], [b0, b1, b2]: [u32; 3], [c0, c1, c2]: [u32; 3]| {
        [
            a0.wrapping_add(b0).wrapping_add(c0),
            a1.wrapping_add(b1).wrapping_add(c1),
            a2.wrapping_add(b2).wrapping_add(c2),
        ]
    };
    // Any column, its neighbours reflected: the two ends, or every column of a narrow row.
    let reflected = |x: usize| {
        let (l, r) = (reflect101(x as isize - 1, w), reflect101(x as isize + 1, w));
        score(add3(col(l), col(x), col(r)))
    };
    let out = out.get_mut(..w).unwrap_or(&mut []);
    let mut best = 0u32;
    if w < 3 {
        for (x, o) in out.iter_mut().enumerate() {
            *o = reflected(x);
            best = best.max(*o);
        }
        return best;
    }
    for x in [0, w - 1] {
        if let Some(o) = out.get_mut(x) {
            *o = reflected(x);
            best = best.max(*o);
        }
    }
    fn plane(s: &[u32], k: usize, w: usize) -> &[u32] {
        s.get(k * w..(k + 1) * w).unwrap_or(&[])
    }
    if !V {
        // Interior columns 1 .. w - 1: the vertical sums slide along the row, three loads a
        // channel a column (the 3x3 block read nine, with its index arithmetic).
        let sums = |k: usize| {
            plane(up, k, w)
                .iter()
                .zip(plane(mid, k, w))
                .zip(plane(down, k, w))
                .map(|((a, b), c)| a.wrapping_add(*b).wrapping_add(*c))
        };
        let mut cols = sums(0)
            .zip(sums(1))
            .zip(sums(2))
            .map(|((a, b), c)| [a, b, c]);
        let (Some(mut prev), Some(mut cur)) = (cols.next(), cols.next()) else {
            return best;
        };
        let inner = out.get_mut(1..w - 1).unwrap_or(&mut []);
        for (o, next) in inner.iter_mut().zip(cols) {
            *o = score(add3(prev, cur, next));
            best = best.max(*o);
            (prev, cur) = (cur, next);
        }
        return best;
    }
    // With SIMD: interior columns 1 .. w - 1, `SPAN` at a time: the three channels' vertical
    // sums of the span's columns and their neighbours, then the horizontal sums, each a
    // straight loop over slices (vectorised), then the scores, where most pixels stop at the
    // floor test.
    let mut x0 = 1;
    while x0 + 1 < w {
        let n = (w - 1 - x0).min(SPAN);
        let mut h = [[0u32; SPAN]; 3];
        for (k, hk) in h.iter_mut().enumerate() {
            let cols = x0 - 1..x0 + n + 1;
            let part = |s| plane(s, k, w).get(cols.clone()).unwrap_or(&[]);
            let mut v = [0u32; SPAN + 2];
            for (o, ((a, b), c)) in v
                .iter_mut()
                .zip(part(up).iter().zip(part(mid)).zip(part(down)))
            {
                *o = a.wrapping_add(*b).wrapping_add(*c);
            }
            let (centre, right) = (v.get(1..).unwrap_or(&[]), v.get(2..).unwrap_or(&[]));
            for (o, ((a, b), c)) in hk.iter_mut().zip(v.iter().zip(centre).zip(right)).take(n) {
                *o = a.wrapping_add(*b).wrapping_add(*c);
            }
        }
        let [ha, hb, hc] = &h;
        let span = out.get_mut(x0..x0 + n).unwrap_or(&mut []);
        for (o, ((&a, &b), &c)) in span.iter_mut().zip(ha.iter().zip(hb).zip(hc)) {
            // The floor test inline (most pixels end here), the rest of the score a call.
            *o = if u64::from(a) + u64::from(c) <= floor {
                0
            } else {
                score([a, b, c])
            };
            best = best.max(*o);
        }
        x0 += n;
    }
    best
}

/// Columns of a row [`score_row`] sums and scores in one pass.
const SPAN: usize = 64;

/// Orders candidates strongest first; ties: later in raster order first (as OpenCV).
fn stronger(a: &Corner, b: &Corner) -> core::cmp::Ordering {
    b.score.cmp(&a.score).then((b.y, b.x).cmp(&(a.y, a.x)))
}

/// `v.swap(i, j)` when both are indices of `v`, else nothing: the same for indices known to be
/// in range, without the bounds check's panic path where the optimiser cannot prove it.
pub(crate) fn swap_checked<T>(v: &mut [T], i: usize, j: usize) {
    if i < v.len() && j < v.len() {
        v.swap(i, j);
    }
}

/// Sorts `v` ascending in `order` by heapsort: `O(n log n)`, in place, and without the panic
/// path of `sort_unstable_by` (core's sorts panic on a comparator that is not a total order,
/// which the optimiser cannot rule out; `stronger` is one, so the result is the same).
pub(crate) fn heapsort_by<T>(v: &mut [T], order: impl Fn(&T, &T) -> core::cmp::Ordering) {
    let less = |v: &[T], i: usize, j: usize| match (v.get(i), v.get(j)) {
        (Some(a), Some(b)) => order(a, b) == core::cmp::Ordering::Less,
        _ => false,
    };
    let swap = swap_checked::<T>;
    let (mut start, mut end) = (v.len() / 2, v.len());
    loop {
        // Build the max-heap (start > 0), then move its top behind the shrinking heap.
        if start > 0 {
            start -= 1;
        } else if end > 1 {
            end -= 1;
            swap(v, 0, end);
        } else {
            break;
        }
        let mut root = start;
        loop {
            let mut child = 2 * root + 1;
            if child >= end {
                break;
            }
            if child + 1 < end && less(v, child, child + 1) {
                child += 1;
            }
            if !less(v, root, child) {
                break;
            }
            swap(v, root, child);
            root = child;
        }
    }
}

/// Detects Shi-Tomasi corners of `img` into `out` (up to its capacity), skipping any within
/// `min_distance` of a point of `existing` (pixel positions of features already tracked).
///
/// `candidates` bounds the local maxima considered: when it fills up the weakest half is
/// dropped, so the strongest `candidates.len() / 2` maxima are always exact (OpenCV keeps all).
/// Returns the number of corners added. Errors: [`Error::BufferTooSmall`] for fewer than 2
/// candidates or scratch shorter than [`scratch_len`].
#[doc(alias = "goodFeaturesToTrack")]
pub fn good_features<const K: usize>(
    img: &ImageView<'_, u8>,
    params: &CornerParams,
    existing: impl Iterator<Item = [i32; 2]> + Clone,
    out: &mut Vec<Corner, K>,
    candidates: &mut [Corner],
    scratch: &mut [u32],
) -> Result<usize> {
    let cfg = params.config();
    if candidates.len() < 2 {
        return Err(Error::BufferTooSmall("candidates"));
    }
    let (w, h) = (img.width(), img.height());
    let scratch = scratch
        .get_mut(..scratch_len(w))
        .ok_or(Error::BufferTooSmall("scratch"))?;
    let (prods, ring) = scratch
        .split_at_mut_checked(9 * w)
        .ok_or(Error::BufferTooSmall("scratch"))?;
    // The checked range `(0, 1]`, restated so that the optimiser knows `quality_of(max) <=
    // max` (the redetection's worst frame on the Cortex-M7: BENCHMARKS.md). Not `clamp`: it
    // lets a NaN through, and then the optimiser knows nothing.
    #[allow(clippy::manual_clamp)]
    let q = f64::from(cfg.quality).min(1.0).max(0.0);
    let quality_of = |max: u32| (f64::from(max) * q) as u32;
    // Rows of products and of scores live in rings of three, slot `row % 3`.
    let pslot = |r: usize| ((r % 3) * 3 * w)..((r % 3) + 1) * 3 * w;
    let sslot = |r: usize| ((r % 3) * w)..((r % 3) + 1) * w;
    let mut max = 0u32;
    // Scores at or below `floor` can be dropped: it never exceeds the final threshold
    // `quality · max S` (the running maximum only grows) nor a kept candidate's score.
    let mut floor = 0u32;
    let mut count = 0usize;
    for y in 0..h {
        // Products of rows y - 1 (reflected), y and y + 1 (reflected) must be in the ring.
        if y == 0 {
            for r in 0..h.min(2) {
                if let Some(p) = prods.get_mut(pslot(r)) {
                    sobel_products::<{ crate::SIMD }>(img, r, p);
                }
            }
        } else if y + 1 < h
            && let Some(p) = prods.get_mut(pslot(y + 1))
        {
            sobel_products::<{ crate::SIMD }>(img, y + 1, p);
        }
        let yi = y as isize;
        let (ru, rd) = (reflect101(yi - 1, h), reflect101(yi + 1, h));
        let (Some(up), Some(mid), Some(down)) = (
            prods.get(pslot(ru)),
            prods.get(pslot(y)),
            prods.get(pslot(rd)),
        ) else {
            break;
        };
        let Some(row) = ring.get_mut(sslot(y)) else {
            break;
        };
        // Border pixels count for the maximum (as OpenCV's minMaxLoc), not as candidates.
        let row_max = score_row::<{ crate::SIMD }>(up, mid, down, w, floor, row);
        if row_max > max {
            max = row_max;
            floor = floor.max(quality_of(max));
        }
        // Row y - 1 is complete with its neighbours: collect its 3x3 maxima above the floor.
        if y < 2 || w < 3 {
            continue;
        }
        let c = y - 1;
        let (Some(up), Some(mid), Some(down)) = (
            ring.get(sslot(c - 1)),
            ring.get(sslot(c)),
            ring.get(sslot(y)),
        ) else {
            break;
        };
        for x in 1..w - 1 {
            let v = mid.get(x).copied().unwrap_or(0);
            if v <= floor {
                continue;
            }
            let nb = |r: &[u32]| {
                r.get(x - 1..x + 2)
                    .map_or(0, |s| s.iter().copied().fold(0, u32::max))
            };
            if v < nb(up) || v < nb(mid) || v < nb(down) {
                continue;
            }
            if count == candidates.len() {
                heapsort_by(candidates, stronger);
                count = candidates.len() / 2;
                floor = candidates
                    .get(count - 1)
                    .map_or(floor, |k| k.score.max(floor));
                if v <= floor {
                    continue;
                }
            }
            if let Some(k) = candidates.get_mut(count) {
                *k = Corner {
                    x: x as u16,
                    y: c as u16,
                    score: v,
                };
                count += 1;
            }
        }
    }
    // The final threshold, from the true maximum: drop what the running one let through.
    let thr = quality_of(max);
    let cands = candidates.get_mut(..count).unwrap_or(&mut []);
    heapsort_by(cands, stronger);
    let kept = cands.iter().take_while(|k| k.score > thr).count();
    let cands = cands.get(..kept).unwrap_or(&[]);
    let md = i64::from(cfg.min_distance);
    let md2 = md * md;
    let far = |x: i64, y: i64, px: i64, py: i64| {
        let (dx, dy) = (x - px, y - py);
        dx * dx + dy * dy >= md2
    };
    let mut added = 0;
    for c in cands.iter() {
        if out.is_full() || (cfg.max_corners > 0 && added >= cfg.max_corners) {
            break;
        }
        let (x, y) = (i64::from(c.x), i64::from(c.y));
        if md > 0 {
            let clear_existing = existing
                .clone()
                .all(|p| far(x, y, i64::from(p[0]), i64::from(p[1])));
            let clear_new = out
                .iter()
                .all(|q| far(x, y, i64::from(q.x), i64::from(q.y)));
            if !(clear_existing && clear_new) {
                continue;
            }
        }
        if out.push(*c).is_ok() {
            added += 1;
        }
    }
    Ok(added)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_corners_of_squares() {
        let (w, h) = (64usize, 48usize);
        let mut img = std::vec![20u8; w * h];
        for (x0, y0) in [(10usize, 10usize), (40, 12), (20, 30)] {
            for y in y0..y0 + 8 {
                for x in x0..x0 + 8 {
                    img[y * w + x] = 220;
                }
            }
        }
        let v = ImageView::packed(&img, w, h).unwrap();
        let mut out: Vec<Corner, 32> = Vec::new();
        let mut cands = [Corner::default(); 64];
        let mut scratch = std::vec![0u32; scratch_len(w)];
        let cfg = CornerConfig {
            quality: 0.1,
            min_distance: 4,
            max_corners: 0,
        }
        .check()
        .unwrap();
        let n = good_features(
            &v,
            &cfg,
            core::iter::empty(),
            &mut out,
            &mut cands,
            &mut scratch,
        )
        .unwrap();
        assert_eq!(n, 12, "{out:?}");
        for c in &out {
            let near = [(10, 10), (40, 12), (20, 30)].iter().any(|&(x0, y0)| {
                [(x0, y0), (x0 + 7, y0), (x0, y0 + 7), (x0 + 7, y0 + 7)]
                    .iter()
                    .any(|&(cx, cy)| (c.x as i32 - cx).abs() <= 1 && (c.y as i32 - cy).abs() <= 1)
            });
            assert!(near, "{c:?}");
        }
        // Replenishing around the existing corners of the first square adds only the others.
        let mut more: Vec<Corner, 32> = Vec::new();
        let existing = [[10, 10], [17, 10], [10, 17], [17, 17]];
        let n2 = good_features(
            &v,
            &cfg,
            existing.iter().copied(),
            &mut more,
            &mut cands,
            &mut scratch,
        )
        .unwrap();
        assert_eq!(n2, 8);
        // A tiny candidate buffer still keeps the strongest ones.
        let mut few: Vec<Corner, 32> = Vec::new();
        let mut small = [Corner::default(); 4];
        good_features(
            &v,
            &cfg,
            core::iter::empty(),
            &mut few,
            &mut small,
            &mut scratch,
        )
        .unwrap();
        assert!(!few.is_empty());
        assert_eq!(
            good_features(
                &v,
                &cfg,
                core::iter::empty(),
                &mut few,
                &mut small,
                &mut scratch[..5]
            ),
            Err(Error::BufferTooSmall("scratch"))
        );
    }

    /// The Sobel products of every row against the formula at each pixel with reflected
    /// neighbours ([`triple`], [`sobel`]), random images of widths 1 to 9 and 40, strided.
    #[test]
    fn sobel_products_match_the_formula() {
        let mut g = crate::rng::Pcg32::new(9);
        for (w, h) in (1..=9).map(|w| (w, 4)).chain([(40, 5)]) {
            let stride = w + 3;
            let px: std::vec::Vec<u8> = (0..stride * h)
                .map(|_| g.uniform(0.0, 256.0) as u8)
                .collect();
            let img = ImageView::new(&px, w, h, stride).unwrap();
            for r in 0..h {
                let mut out = std::vec![0u32; 3 * w];
                sobel_products::<true>(&img, r, &mut out);
                let mut board = std::vec![0u32; 3 * w];
                sobel_products::<false>(&img, r, &mut board);
                assert_eq!(out, board, "w {w} row {r}: the two forms");
                let row = |y: isize| img.row(reflect101(y, h)).unwrap();
                let (r0, r1, r2) = (row(r as isize - 1), row(r as isize), row(r as isize + 1));
                for x in 0..w {
                    let (dx, dy) = sobel(triple(r0, x, w), triple(r1, x, w), triple(r2, x, w));
                    let want = [(dx * dx) as u32, (dx * dy) as u32, (dy * dy) as u32];
                    let got = [out[x], out[w + x], out[2 * w + x]];
                    assert_eq!(got, want, "w {w} row {r} x {x}");
                }
            }
        }
    }

    /// The row scores against the 3x3 definition (reflected ends), every width from
    /// 1 to 9 and wide rows (one span of `SPAN` columns, two, two and a part), random
    /// products, with and without a floor.
    #[test]
    fn row_scores_match_the_definition() {
        let mut g = crate::rng::Pcg32::new(5);
        for w in (1..=9).chain([64, 66, 67, 130, 200]) {
            let rows: std::vec::Vec<std::vec::Vec<u32>> = (0..3)
                .map(|_| {
                    (0..3 * w)
                        .map(|i| {
                            let v = g.uniform(0.0, 9.0e6) as u32;
                            // The middle channel is a signed product.
                            if i / w == 1 {
                                (v as i32 - 4_500_000) as u32
                            } else {
                                v
                            }
                        })
                        .collect()
                })
                .collect();
            for floor in [0u32, 20_000_000] {
                let mut out = std::vec![7u32; w];
                let best = score_row::<true>(&rows[0], &rows[1], &rows[2], w, floor, &mut out);
                let mut board = std::vec![0u32; w];
                let best_board =
                    score_row::<false>(&rows[0], &rows[1], &rows[2], w, floor, &mut board);
                assert_eq!((best, &out), (best_board, &board), "w {w}: the two forms");
                let mut want_best = 0;
                for (x, &got) in out.iter().enumerate() {
                    let mut s = [0i64; 3];
                    for dx in [-1isize, 0, 1] {
                        let c = reflect101(x as isize + dx, w);
                        for r in &rows {
                            for (k, sk) in s.iter_mut().enumerate() {
                                let v = r[k * w + c];
                                *sk += if k == 1 {
                                    i64::from(v as i32)
                                } else {
                                    i64::from(v)
                                };
                            }
                        }
                    }
                    let (a, b, c) = (s[0] as f64, s[1] as f64, s[2] as f64);
                    let exact = a + c - ((a - c) * (a - c) + 4.0 * b * b).sqrt();
                    assert!(got == 0 || got > floor, "w {w} x {x}: {got} <= {floor}");
                    // Scores at or below the floor are 0 (the boundary within the unit below).
                    let want = if exact <= f64::from(floor) + 1.0 && got == 0 {
                        0.0
                    } else {
                        exact
                    };
                    // The integer root is the floor of the real one: within one unit.
                    assert!((f64::from(got) - want.floor()).abs() <= 1.0, "w {w} x {x}");
                    want_best = want_best.max(got);
                }
                assert_eq!(best, want_best);
            }
        }
    }

    #[test]
    fn check_names_the_quality_and_capping_keeps_the_check() {
        assert_eq!(CornerConfig::default().check(), Ok(CornerParams::default()));
        for q in [0.0, -0.5, 1.5, f32::NAN] {
            let c = CornerConfig {
                quality: q,
                ..CornerConfig::default()
            };
            assert_eq!(
                CornerParams::try_from(c),
                Err(Error::InvalidParameter("corners.quality"))
            );
        }
        let p = CornerConfig {
            max_corners: 5,
            ..CornerConfig::default()
        }
        .check()
        .unwrap();
        for free in [0, 3, 5, 9] {
            assert_eq!(p.up_to(free).config(), &p.config().up_to(free));
        }
        assert_eq!(p.up_to(3).config().max_corners, 3);
        assert_eq!(p.up_to(9).config().max_corners, 5);
        assert_eq!(CornerParams::default().up_to(7).config().max_corners, 7);
    }

    #[test]
    fn heapsort_matches_the_standard_sort() {
        let mut g = crate::rng::Pcg32::new(7);
        for n in [0usize, 1, 2, 3, 5, 16, 17, 100, 513] {
            let mut a: std::vec::Vec<Corner> = (0..n)
                .map(|_| Corner {
                    x: (g.next_u32() % 8) as u16,
                    y: (g.next_u32() % 8) as u16,
                    score: g.next_u32() % 16,
                })
                .collect();
            let mut b = a.clone();
            heapsort_by(&mut a, stronger);
            b.sort_by(stronger);
            assert_eq!(a, b, "n = {n}");
        }
    }
}
