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
//! Memory: [`scratch_len`]`(width)` `u32` of scratch (three rows of sums, three of scores) and
//! a caller slice of candidates; no full-frame score map. Two passes (the maximum, then the
//! candidates), each evaluating the Sobel rows three times.

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

/// Parameters of [`good_features`] (OpenCV's `qualityLevel`, `minDistance`).
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

impl Default for CornerConfig {
    fn default() -> Self {
        Self {
            quality: 0.01,
            min_distance: 10,
            max_corners: 0,
        }
    }
}

/// `u32` elements of scratch [`good_features`] needs for frames `width` pixels wide: `6 width`.
pub const fn scratch_len(width: usize) -> usize {
    6 * width
}

/// `⌊√v⌋` (bit by bit).
fn isqrt(v: u64) -> u64 {
    let (mut rem, mut root, mut bit) = (v, 0u64, 1u64 << 62);
    while bit > rem {
        bit >>= 2;
    }
    while bit != 0 {
        if rem >= root + bit {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
}

/// Adds the Sobel products of image row `r` into the column sums `sums = [Σdx², Σdxdy, Σdy²]`.
fn add_sobel_products(img: &ImageView<'_, u8>, r: usize, sums: &mut [u32]) {
    let (w, h) = (img.width(), img.height());
    let ri = r as isize;
    let r0 = img.row_clamped(reflect101(ri - 1, h) as isize);
    let r1 = img.row_clamped(ri);
    let r2 = img.row_clamped(reflect101(ri + 1, h) as isize);
    let p = |row: &[u8], c: usize| i32::from(row.get(c).copied().unwrap_or(0));
    let (sxx, rest) = sums.split_at_mut(w.min(sums.len()));
    let (sxy, syy) = rest.split_at_mut(w.min(rest.len()));
    for (x, ((a, b), c)) in sxx
        .iter_mut()
        .zip(sxy.iter_mut())
        .zip(syy.iter_mut())
        .enumerate()
    {
        let xm = reflect101(x as isize - 1, w);
        let xp = reflect101(x as isize + 1, w);
        let dx = (p(r0, xp) - p(r0, xm)) + 2 * (p(r1, xp) - p(r1, xm)) + (p(r2, xp) - p(r2, xm));
        let dy = (p(r2, xm) + 2 * p(r2, x) + p(r2, xp)) - (p(r0, xm) + 2 * p(r0, x) + p(r0, xp));
        // |dx|, |dy| <= 1020: 9 products per pixel stay far inside u32 / i32.
        *a = a.wrapping_add((dx * dx) as u32);
        *b = b.wrapping_add((dx * dy) as u32);
        *c = c.wrapping_add((dy * dy) as u32);
    }
}

/// Scores of row `y` into `out` (`width` values), using `sums` (`3 width`) as work space.
fn score_row(img: &ImageView<'_, u8>, y: usize, sums: &mut [u32], out: &mut [u32]) {
    let (w, h) = (img.width(), img.height());
    sums.fill(0);
    for dy in [-1isize, 0, 1] {
        add_sobel_products(img, reflect101(y as isize + dy, h), sums);
    }
    let (sxx, rest) = sums.split_at(w.min(sums.len()));
    let (sxy, syy) = rest.split_at(w.min(rest.len()));
    let at = |s: &[u32], x: isize| s.get(reflect101(x, w)).copied().unwrap_or(0);
    for (x, o) in out.iter_mut().take(w).enumerate() {
        let xi = x as isize;
        let box3 = |s: &[u32]| {
            at(s, xi - 1)
                .wrapping_add(at(s, xi))
                .wrapping_add(at(s, xi + 1))
        };
        let a = i64::from(box3(sxx));
        let b = i64::from(box3(sxy) as i32);
        let c = i64::from(box3(syy));
        let d = (a - c).unsigned_abs();
        let disc = d * d + 4 * b.unsigned_abs() * b.unsigned_abs();
        let s = (a + c) as u64;
        *o = s.saturating_sub(isqrt(disc)).min(u64::from(u32::MAX)) as u32;
    }
}

/// Orders candidates strongest first; ties: later in raster order first (as OpenCV).
fn stronger(a: &Corner, b: &Corner) -> core::cmp::Ordering {
    b.score.cmp(&a.score).then((b.y, b.x).cmp(&(a.y, a.x)))
}

/// Sorts `v` ascending in `order` by heapsort: `O(n log n)`, in place, and without the panic
/// path of `sort_unstable_by` (core's sorts panic on a comparator that is not a total order,
/// which the optimiser cannot rule out; `stronger` is one, so the result is the same).
fn heapsort_by<T>(v: &mut [T], order: impl Fn(&T, &T) -> core::cmp::Ordering) {
    let less = |v: &[T], i: usize, j: usize| match (v.get(i), v.get(j)) {
        (Some(a), Some(b)) => order(a, b) == core::cmp::Ordering::Less,
        _ => false,
    };
    let swap = |v: &mut [T], i: usize, j: usize| {
        if i < v.len() && j < v.len() {
            v.swap(i, j);
        }
    };
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
/// Returns the number of corners added. Errors: [`Error::InvalidParameter`] for a quality
/// outside `(0, 1]`, fewer than 2 candidates or scratch shorter than [`scratch_len`].
pub fn good_features<const K: usize>(
    img: &ImageView<'_, u8>,
    cfg: &CornerConfig,
    existing: impl Iterator<Item = [i32; 2]> + Clone,
    out: &mut Vec<Corner, K>,
    candidates: &mut [Corner],
    scratch: &mut [u32],
) -> Result<usize> {
    if !(cfg.quality > 0.0 && cfg.quality <= 1.0) || candidates.len() < 2 {
        return Err(Error::InvalidParameter);
    }
    let (w, h) = (img.width(), img.height());
    let scratch = scratch
        .get_mut(..scratch_len(w))
        .ok_or(Error::InvalidParameter)?;
    let (sums, ring) = scratch
        .split_at_mut_checked(3 * w)
        .ok_or(Error::InvalidParameter)?;
    // Pass 1: the largest score (border pixels included, as OpenCV's minMaxLoc).
    let mut max = 0u32;
    for y in 0..h {
        let row = ring.get_mut(..w).unwrap_or(&mut []);
        score_row(img, y, sums, row);
        max = row.iter().copied().fold(max, u32::max);
    }
    let thr = (f64::from(max) * f64::from(cfg.quality)) as u32;
    // Pass 2: 3x3 maxima above the threshold, rows y - 1, y, y + 1 in a ring.
    let mut count = 0usize;
    let mut floor = thr;
    if h >= 3 && w >= 3 {
        for y in 0..2 {
            if let Some(r) = ring.get_mut(y * w..(y + 1) * w) {
                score_row(img, y, sums, r);
            }
        }
        for y in 1..h - 1 {
            let slot = |r: usize| ((r % 3) * w)..((r % 3) + 1) * w;
            if let Some(r) = ring.get_mut(slot(y + 1)) {
                score_row(img, y + 1, sums, r);
            }
            let (Some(up), Some(mid), Some(down)) = (
                ring.get(slot(y - 1)),
                ring.get(slot(y)),
                ring.get(slot(y + 1)),
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
                        .map_or(floor, |c| c.score.max(thr));
                    if v <= floor {
                        continue;
                    }
                }
                if let Some(c) = candidates.get_mut(count) {
                    *c = Corner {
                        x: x as u16,
                        y: y as u16,
                        score: v,
                    };
                    count += 1;
                }
            }
        }
    }
    let cands = candidates.get_mut(..count).unwrap_or(&mut []);
    heapsort_by(cands, stronger);
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
        };
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
            Err(Error::InvalidParameter)
        );
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
