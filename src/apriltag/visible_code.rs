//! The code of a partly seen tag: its visible cells read, and whether they confirm the tag
//! tracked.
//!
//! **What is hidden** ([`Hidden`]): the parts of the edges in the frame that gave no edge
//! point ([`super::robust_edges`]) mark where something lies over the tag; the region they
//! bound inside the tag (the convex hull of their ends: an occluder across two edges, a bar
//! or a finger, covers the band between its crossings) and each of them carried a cell outward
//! over the quiet zone are hidden, with 2 px around them (a reading is one bilinear sample at
//! a cell's centre, the occluder's edge a pixel of blur). A cell whose centre is there, or
//! outside the frame, is not seen: it is not read and not counted. An occluder that reaches
//! further inside than that hull makes cells read wrong, which the confirmation counts.
//!
//! **Reading** ([`read_visible`]): as the detector's decoding ([`super::decode`]): the two
//! intensity models from the seen samples of the quiet zone and of the border, each seen
//! payload cell read at its centre against their mean, sharpened with its seen neighbours (a
//! cell not read counts as its threshold, as the detector's cells outside the payload do).
//!
//! **Confirming** ([`confirm`]): `n` cells seen of the family's `N` bits, `m` of them differ from
//! the tag's code in the tracked orientation. The bits allowed to differ, `b(n)`, follow from
//! the family, not from a sequence:
//! - a random pattern must be no more likely to pass than it is to pass the detector's full
//!   decoding: `Σ_{j≤b} C(n, j) / 2ⁿ ≤ 4 K Σ_{j≤h} C(N, j) / 2ᴺ` (`K` codes in 4 rotations, `h`
//!   the detector's `max_hamming`), `b ≤ h`;
//! - the seen cells must keep the detector's uniqueness rule `2 h < d` with the distance
//!   they leave: `2 b < d_seen`, `d_seen` the smallest distance on the seen cells from the
//!   tag's code to any other code of the family in any rotation (and to the tag's own other
//!   rotations).
//!
//! No `b` at all (too few cells seen) refuses; so does `m > b`. For tag36h11 (`N = 36`,
//! 587 codes, `h = 2`): 24 seen cells or more allow 2 bits, 20 to 23 allow 1, 16 to 19 allow none,
//! fewer refuse.

use nalgebra::{Matrix3, Point2};

use super::decode::{GrayModel, MAX_TOTAL_WIDTH, border_rows, sharpen};
use super::family::{Family, rotate90};
use super::geom::{at4, project};
use super::robust_edges::EdgeSupport;
use crate::image::ImageView;
use crate::scalar::above;

/// Points bounding the hidden region, at most: 4 edges, 2 ends each.
const MAX_HULL: usize = 8;

/// Distance (pixels) from the hidden region within which a point is hidden too: the bilinear
/// reading's pixel and a pixel of blur at the occluder's edge.
const REACH: f32 = 2.0;

/// The hidden part of a tag (module docs) and the frame: which points of the tag are seen.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Hidden {
    /// The hull of the hidden parts' ends on the edges (inside the tag).
    hull: [Point2<f32>; MAX_HULL],
    n: usize,
    /// Each hidden part of an edge and the same part a cell outward (over the quiet zone).
    strips: [Option<[Point2<f32>; 4]>; 4],
    width: f32,
    height: f32,
}

impl Hidden {
    /// The hidden region of the quad `corners` (a tag of `wab` cells across its border, in
    /// the order of its edges' `support`) in a `width x height` frame.
    pub(crate) fn new(
        corners: &[Point2<f32>; 4],
        support: &[EdgeSupport; 4],
        wab: u8,
        width: usize,
        height: usize,
    ) -> Self {
        let centre = corners
            .iter()
            .fold(Point2::origin(), |s: Point2<f32>, p| s + p.coords * 0.25);
        let perimeter: f32 = (0..4)
            .map(|i| (at4(corners, i + 1) - at4(corners, i)).norm())
            .sum();
        let cell = perimeter / (4.0 * f32::from(wab.max(1)));
        let mut pts = [Point2::origin(); MAX_HULL];
        let mut strips = [None; 4];
        let mut n = 0usize;
        for ((i, s), strip) in support.iter().enumerate().zip(strips.iter_mut()) {
            let Some((t0, t1)) = s.hidden else {
                continue;
            };
            let (a, b) = (at4(corners, i), at4(corners, i + 1));
            let d = b - a;
            // The edge's normal away from the tag's centre.
            let mut out = nalgebra::Vector2::new(d.y, -d.x);
            let len = out.norm();
            if !above(len, 0.0) {
                continue;
            }
            out /= len;
            if out.dot(&(a - centre)) < 0.0 {
                out = -out;
            }
            let (p0, p1) = (a + d * t0, a + d * t1);
            *strip = Some([p0, p1, p1 + out * cell, p0 + out * cell]);
            for p in [p0, p1] {
                if let Some(slot) = pts.get_mut(n) {
                    *slot = p;
                    n += 1;
                }
            }
        }
        let (hull, n) = convex_hull(pts, n);
        Self {
            hull,
            n,
            strips,
            width: width as f32,
            height: height as f32,
        }
    }

    /// Whether pixel `p` is seen: in the frame, at least a pixel from its edge, and farther
    /// than [`REACH`] from the hidden region.
    pub(crate) fn sees(&self, p: Point2<f32>) -> bool {
        if !(p.x >= 1.0 && p.y >= 1.0 && p.x <= self.width - 2.0 && p.y <= self.height - 2.0) {
            return false;
        }
        if let Some(h) = self.hull.get(..self.n)
            && !h.is_empty()
            && !above(distance_to_hull(h, p), REACH)
        {
            return false;
        }
        self.strips
            .iter()
            .flatten()
            .all(|q| distance_to_hull(q, p) > REACH)
    }

    /// Whether anything of the tag's edges was hidden (not only cut by the frame).
    pub(crate) fn any(&self) -> bool {
        self.n > 0
    }
}

/// The convex hull of the first `n` of `pts` (Andrew's monotone chain), counter-clockwise in
/// `x` right, `y` up (the order does not matter to [`distance_to_hull`]); its vertices and
/// their number.
fn convex_hull(mut pts: [Point2<f32>; MAX_HULL], n: usize) -> ([Point2<f32>; MAX_HULL], usize) {
    let n = n.min(MAX_HULL);
    let Some(p) = pts.get_mut(..n) else {
        return (pts, 0);
    };
    // Insertion sort by (x, y): at most 8 points.
    for i in 1..p.len() {
        let mut j = i;
        while j > 0 {
            let (Some(&a), Some(&b)) = (p.get(j - 1), p.get(j)) else {
                break;
            };
            if (a.x, a.y) <= (b.x, b.y) || a.x.is_nan() || b.x.is_nan() {
                break;
            }
            p.swap(j - 1, j);
            j -= 1;
        }
    }
    let cross = |o: Point2<f32>, a: Point2<f32>, b: Point2<f32>| {
        (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
    };
    let mut hull = [Point2::origin(); MAX_HULL];
    let mut k = 0usize;
    // Lower chain, then upper chain; each point enters at most once a chain, and the hull of
    // `n ≤ 8` points has at most `n` vertices (the last, equal to the first, dropped).
    let push = |hull: &mut [Point2<f32>; MAX_HULL], k: &mut usize, q: Point2<f32>, min: usize| {
        while *k >= min + 2 {
            let (Some(&a), Some(&b)) = (hull.get(*k - 2), hull.get(*k - 1)) else {
                break;
            };
            if cross(a, b, q) > 0.0 {
                break;
            }
            *k -= 1;
        }
        if let Some(slot) = hull.get_mut(*k) {
            *slot = q;
            *k += 1;
        }
    };
    for &q in p.iter() {
        push(&mut hull, &mut k, q, 0);
    }
    let lower = k.saturating_sub(1);
    for &q in p.iter().rev().skip(1) {
        push(&mut hull, &mut k, q, lower);
    }
    let k = if n > 1 { k.saturating_sub(1) } else { k };
    (hull, k)
}

/// Distance from `p` to the convex polygon `h` (its vertices in order, either way round; a
/// point or a segment when it has one or two): 0 inside.
fn distance_to_hull(h: &[Point2<f32>], p: Point2<f32>) -> f32 {
    let n = h.len();
    let mut inside = n >= 3;
    let mut sign = 0.0f32;
    let mut best = f32::INFINITY;
    for i in 0..n {
        let (Some(&a), Some(&b)) = (h.get(i), h.get((i + 1) % n)) else {
            continue;
        };
        let ab = b - a;
        let ap = p - a;
        let len2 = ab.norm_squared();
        let t = if len2 > 0.0 {
            (ap.dot(&ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        best = best.min((ap - ab * t).norm());
        let c = ab.x * ap.y - ab.y * ap.x;
        if c != 0.0 {
            if sign == 0.0 {
                sign = c.signum();
            } else if c.signum() != sign {
                inside = false;
            }
        }
    }
    if inside { 0.0 } else { best }
}

/// The visible cells' reading (module docs): the word (bit `N - 1 - i` for layout bit `i`, as
/// the detector's), which of its bits were seen, and the decision margin over those.
#[derive(Debug, Clone, Copy)]
pub(crate) struct VisibleReading {
    pub(crate) rcode: u64,
    pub(crate) seen: u64,
    pub(crate) margin: f32,
}

/// Reads the seen payload cells of the quad `h` maps to (tag coordinates `(-1, -1)..(1, 1)`
/// to pixels), `hidden` telling which are seen. `None` when the seen samples of the quiet zone
/// and border do not give the two intensity models, or the border does not fit the family
/// (its polarity).
pub(crate) fn read_visible(
    img: &ImageView<'_, u8>,
    h: &Matrix3<f32>,
    family: &Family,
    sharpening: f32,
    hidden: &Hidden,
) -> Option<VisibleReading> {
    let wab = usize::from(family.width_at_border);
    let wabf = wab as f32;
    let tw = usize::from(family.total_width);
    if tw > MAX_TOTAL_WIDTH || wab < 2 || family.layout.len() > 64 {
        return None;
    }
    let patterns = border_rows(wabf);
    let (mut white, mut black) = (GrayModel::default(), GrayModel::default());
    for &(x0, y0, dx, dy, is_white) in &patterns {
        for i in 0..wab {
            let tx = 2.0 * ((x0 + i as f32 * dx) / wabf - 0.5);
            let ty = 2.0 * ((y0 + i as f32 * dy) / wabf - 0.5);
            let Some(p) = project(h, tx, ty) else {
                continue;
            };
            if !hidden.sees(p) {
                continue;
            }
            // The pixel containing the point, as the detector's models.
            let Some(v) = img.get((p.x + 0.5) as usize, (p.y + 0.5) as usize) else {
                continue;
            };
            let v = f32::from(v);
            if is_white {
                white.add(tx, ty, v);
            } else {
                black.add(tx, ty, v);
            }
        }
    }
    if !white.solve() || !black.solve() {
        return None;
    }
    if (white.at(0.0, 0.0) - black.at(0.0, 0.0) < 0.0) != family.reversed_border {
        return None;
    }
    let min_coord = (wab as i32 - tw as i32) / 2;
    let cell = |x: i8, y: i8| -> Option<usize> {
        let (cx, cy) = (i32::from(x) - min_coord, i32::from(y) - min_coord);
        if cx < 0 || cy < 0 || cx >= tw as i32 || cy >= tw as i32 {
            return None;
        }
        Some(cy as usize * tw + cx as usize)
    };
    let mut values = [0f32; MAX_TOTAL_WIDTH * MAX_TOTAL_WIDTH];
    let mut read = [false; MAX_TOTAL_WIDTH * MAX_TOTAL_WIDTH];
    for b in family.layout {
        let tx = 2.0 * ((f32::from(b.x) + 0.5) / wabf - 0.5);
        let ty = 2.0 * ((f32::from(b.y) + 0.5) / wabf - 0.5);
        let Some(p) = project(h, tx, ty) else {
            continue;
        };
        if !hidden.sees(p) {
            continue;
        }
        let Some(v) = img.sample_bilinear(p.x, p.y) else {
            continue;
        };
        let thresh = 0.5 * (black.at(tx, ty) + white.at(tx, ty));
        if let Some(i) = cell(b.x, b.y)
            && let (Some(slot), Some(r)) = (values.get_mut(i), read.get_mut(i))
        {
            *slot = v - thresh;
            *r = true;
        }
    }
    sharpen(&mut values, tw, sharpening, |i| {
        read.get(i).copied().unwrap_or(false)
    });
    let (mut ws, mut bs, mut wc, mut bc) = (0f32, 0f32, 1f32, 1f32);
    let (mut rcode, mut seen) = (0u64, 0u64);
    for b in family.layout {
        let i = cell(b.x, b.y);
        let r = i.and_then(|i| read.get(i)).copied().unwrap_or(false);
        let v = i.and_then(|i| values.get(i)).copied().unwrap_or(0.0);
        rcode <<= 1;
        seen <<= 1;
        if !r {
            continue;
        }
        seen |= 1;
        if v > 0.0 {
            ws += v;
            wc += 1.0;
            rcode |= 1;
        } else {
            bs -= v;
            bc += 1.0;
        }
    }
    Some(VisibleReading {
        rcode,
        seen,
        margin: (ws / wc).min(bs / bc),
    })
}

/// How the seen cells confirmed a code ([`confirm`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Confirmed {
    /// Cells seen.
    pub(crate) seen: u8,
    /// Seen cells that differ from the code.
    pub(crate) wrong: u8,
    /// Seen cells allowed to differ.
    pub(crate) budget: u8,
}

/// Why [`confirm`] did not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum NotConfirmed {
    /// Too few cells seen for any budget.
    TooFew,
    /// More seen cells differ than the budget allows.
    Differs,
}

/// `Σ_{j ≤ k} C(n, j)` for `k ≤ 3` (the bits a detector corrects at most), exact.
fn ball(n: u32, k: u32) -> u128 {
    let n = u128::from(n);
    let c = [
        1,
        n,
        n * n.saturating_sub(1) / 2,
        n * n.saturating_sub(1) * n.saturating_sub(2) / 6,
    ];
    c.iter().take(k.min(3) as usize + 1).sum()
}

/// Whether the `reading`'s seen bits confirm `code`, tag `id` of `family` in the orientation
/// read, with the detector correcting `max_hamming` bits (module docs).
pub(crate) fn confirm(
    family: &Family,
    id: u16,
    code: u64,
    reading: &VisibleReading,
    max_hamming: u8,
) -> Result<Confirmed, NotConfirmed> {
    let nbits = family.layout.len().min(64) as u32;
    let n = reading.seen.count_ones().min(nbits);
    let h = u32::from(max_hamming.min(3));
    let codes = family.codes.len() as u128;
    // b: the largest count with ball(n, b) / 2^n ≤ 4 K ball(N, h) / 2^N (both sides times
    // 2^N 2^n, exact in u128: ball ≤ C(64, ≤ 3) < 2^16, K < 2^16, 2^64).
    let rhs = (4 * codes * ball(nbits, h)) << n;
    let mut budget = None;
    for b in 0..=h {
        if (ball(n, b) << nbits) <= rhs {
            budget = Some(b);
        }
    }
    let Some(mut budget) = budget else {
        return Err(NotConfirmed::TooFew);
    };
    // The distance the seen cells leave between the code and every other code and rotation.
    let mut d_seen = u32::MAX;
    let (mut rc, mut rm) = (code, reading.seen);
    for k in 0..4 {
        for j in 0..family.codes.len() {
            if k == 0 && j == usize::from(id) {
                continue;
            }
            let Some(other) = family.codes.get(j) else {
                continue;
            };
            d_seen = d_seen.min(((other ^ rc) & rm).count_ones());
        }
        rc = rotate90(rc, nbits);
        rm = rotate90(rm, nbits);
    }
    if d_seen == 0 {
        return Err(NotConfirmed::TooFew);
    }
    budget = budget.min((d_seen - 1) / 2);
    let wrong = ((reading.rcode ^ code) & reading.seen).count_ones();
    let out = Confirmed {
        seen: n as u8,
        wrong: wrong.min(255) as u8,
        budget: budget as u8,
    };
    if wrong > budget {
        return Err(NotConfirmed::Differs);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::apriltag::families;

    #[test]
    fn the_budget_follows_the_family() {
        let f = &families::TAG36H11;
        let code = f.code(42).unwrap();
        let all = (1u64 << 36) - 1;
        let read = |rcode, seen| VisibleReading {
            rcode,
            seen,
            margin: 50.0,
        };
        // Every cell seen: the detector's own 2 bits.
        let c = confirm(f, 42, code, &read(code ^ 0b11, all), 2).unwrap();
        assert_eq!((c.seen, c.wrong, c.budget), (36, 2, 2));
        assert_eq!(
            confirm(f, 42, code, &read(code ^ 0b111, all), 2),
            Err(NotConfirmed::Differs)
        );
        // The budget by cells seen (module docs), the seen ones the lowest bits.
        for (n, b) in [
            (24u32, Some(2u8)),
            (23, Some(1)),
            (20, Some(1)),
            (19, Some(0)),
            (16, Some(0)),
            (15, None),
        ] {
            let seen = (1u64 << n) - 1;
            let got = confirm(f, 42, code, &read(code, seen), 2).map(|c| c.budget);
            match b {
                Some(b) => assert!(got.is_ok_and(|g| g <= b), "{n}: {got:?}"),
                None => assert_eq!(got, Err(NotConfirmed::TooFew), "{n}"),
            }
        }
        // Hidden cells do not count, whatever they read.
        let c = confirm(f, 42, code, &read(!code, 0), 2);
        assert_eq!(c, Err(NotConfirmed::TooFew));
        // Another tag's code on the seen cells: not confirmed.
        let other = f.code(7).unwrap();
        let seen = (1u64 << 30) - 1;
        assert!(confirm(f, 42, code, &read(other, seen), 2).is_err());
    }

    #[test]
    fn the_hull_hides_what_is_near_it() {
        let h = [
            Point2::new(0.0, 0.0),
            Point2::new(10.0, 0.0),
            Point2::new(10.0, 10.0),
            Point2::new(0.0, 10.0),
        ];
        assert_eq!(distance_to_hull(&h, Point2::new(5.0, 5.0)), 0.0);
        assert!((distance_to_hull(&h, Point2::new(13.0, 5.0)) - 3.0).abs() < 1e-6);
        let mut pts = [Point2::origin(); MAX_HULL];
        for (i, p) in [
            (0.0, 0.0),
            (10.0, 0.0),
            (5.0, 5.0),
            (10.0, 10.0),
            (0.0, 10.0),
            (3.0, 2.0),
        ]
        .iter()
        .enumerate()
        {
            pts[i] = Point2::new(p.0, p.1);
        }
        let (hull, n) = convex_hull(pts, 6);
        assert_eq!(n, 4, "{:?}", &hull[..n]);
        // A segment: distance to it.
        let seg = [Point2::new(0.0, 0.0), Point2::new(10.0, 0.0)];
        assert!((distance_to_hull(&seg, Point2::new(5.0, 2.0)) - 2.0).abs() < 1e-6);
    }
}
