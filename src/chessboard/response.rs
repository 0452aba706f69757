//! Step 1 of the detection: the saddle response of the smoothed frame, streamed row by row
//! through ring buffers, and its strongest 3x3 maxima.

use heapless::binary_heap::{BinaryHeap, Min};

use crate::image::ImageView;

/// Rows of the smoothing, smoothed and response ring buffers.
const RING_ROWS: usize = 5 + 3 + 3;

/// `i32` words of scratch [`super::ChessboardDetector::detect`] needs for a frame `width`
/// pixels wide.
pub const fn scratch_len(width: usize) -> usize {
    RING_ROWS * width
}

/// Pixels at the frame's border where no corner is looked for (smoothing, second differences
/// and the 3x3 maximum reach that far).
const MARGIN: usize = 4;

/// A maximum of the response: `(response, x, y, dx, dy)`, the parabola-vertex offsets `dx`,
/// `dy` in 1/64 px. Ordered by the response first, so a min-heap drops the weakest.
pub(super) type Maximum = (i32, u16, u16, i8, i8);

/// The `K` strongest 3x3 maxima of the saddle response of `image` that reach
/// `min_response`, into `heap` (cleared first); `scratch` holds [`scratch_len`]`(width)`
/// words (the callers check it for the frame, and a pyramid level is never wider); with less,
/// no maximum.
pub(super) fn collect_maxima<const K: usize>(
    image: &ImageView<'_, u8>,
    min_response: i32,
    scratch: &mut [i32],
    heap: &mut BinaryHeap<Maximum, Min, K>,
) {
    let (w, h) = (image.width(), image.height());
    heap.clear();
    let Some((hring, rest)) = scratch.split_at_mut_checked(5 * w) else {
        return;
    };
    let Some((sring, rring)) = rest.split_at_mut_checked(3 * w) else {
        return;
    };
    let rring = rring.get_mut(..3 * w).unwrap_or_default();
    // Logical row `y` of the frame sits in slot `(y + 2) % 5` of the first ring.
    let hrow = |ring: &mut [i32], logical: isize| {
        let out = ring_row_mut(ring, 5, (logical + 2) as usize, w);
        hblur(image.row_clamped(logical), out);
    };
    for r in -2..=1isize {
        hrow(hring, r);
    }
    for ys in 0..h {
        hrow(hring, ys as isize + 2);
        // Vertical smoothing of rows ys-2 ..= ys+2 into the smoothed ring.
        {
            let out = ring_row_mut(sring, 3, ys, w);
            let row = |k: usize| ring_row(hring, 5, ys + k, w);
            let (a, b, c, d, e) = (row(0), row(1), row(2), row(3), row(4));
            let taps = a.iter().zip(b).zip(c).zip(d).zip(e);
            for (o, ((((a, b), c), d), e)) in out.iter_mut().zip(taps) {
                *o = a + 4 * (b + d) + 6 * c + e;
            }
        }
        if ys < 2 {
            continue;
        }
        // Response of row yr = ys - 1 from smoothed rows yr-1, yr, yr+1.
        let yr = ys - 1;
        let s = |k: usize| ring_row(sring, 3, k, w);
        let (up, mid, dn) = (s(yr + 2), s(yr), s(yr + 1));
        {
            let out = ring_row_mut(rring, 3, yr, w);
            out.fill(0);
            if yr >= MARGIN - 1 && yr + MARGIN - 1 < h {
                saddle_row(up, mid, dn, out);
                for x in 0..MARGIN - 1 {
                    if let Some(v) = out.get_mut(x) {
                        *v = 0;
                    }
                    if let Some(v) = out.get_mut(w - 1 - x) {
                        *v = 0;
                    }
                }
            }
        }
        if yr < 2 {
            continue;
        }
        // Maxima of row yn = yr - 1.
        let yn = yr - 1;
        if yn < MARGIN || yn + MARGIN >= h {
            continue;
        }
        let r = |k: usize| ring_row(rring, 3, k, w);
        let (ru, rm, rd) = (r(yn + 2), r(yn), r(yn + 1));
        for x in MARGIN..w - MARGIN {
            let g = |row: &[i32], x: usize| row.get(x).copied().unwrap_or(0);
            let v = g(rm, x);
            if v < min_response {
                continue;
            }
            // Maximum of the 3x3 block: ≥ the earlier neighbours, > the later ones.
            let earlier = [g(ru, x - 1), g(ru, x), g(ru, x + 1), g(rm, x - 1)];
            let later = [g(rm, x + 1), g(rd, x - 1), g(rd, x), g(rd, x + 1)];
            if earlier.iter().any(|&e| e > v) || later.iter().any(|&l| l >= v) {
                continue;
            }
            // Parabola vertex through the three values each way, in 1/64 px.
            let vertex = |a: i32, c: i32| -> i8 {
                let den = (a as i64) - 2 * (v as i64) + (c as i64);
                if den >= 0 {
                    return 0;
                }
                let off = 32 * ((a as i64) - (c as i64)) / den;
                off.clamp(-32, 32) as i8
            };
            let dx = vertex(g(rm, x - 1), g(rm, x + 1));
            let dy = vertex(g(ru, x), g(rd, x));
            let item = (v, x as u16, yn as u16, dx, dy);
            if heap.len() < K {
                let _ = heap.push(item);
            } else if heap.peek().is_some_and(|m| m.0 < v) {
                let _ = heap.pop();
                let _ = heap.push(item);
            }
        }
    }
}

/// Row `k mod rows` of a ring buffer of `rows` rows `w` long (empty when the ring is short).
fn ring_row(ring: &[i32], rows: usize, k: usize, w: usize) -> &[i32] {
    let slot = k % rows;
    ring.get(slot * w..(slot + 1) * w).unwrap_or_default()
}

/// [`ring_row`], to write.
fn ring_row_mut(ring: &mut [i32], rows: usize, k: usize, w: usize) -> &mut [i32] {
    let slot = k % rows;
    ring.get_mut(slot * w..(slot + 1) * w).unwrap_or_default()
}

/// `[1 4 6 4 1]` along a row, border replicated.
fn hblur(row: &[u8], out: &mut [i32]) {
    let n = row.len().min(out.len());
    let g = |i: isize| {
        row.get(i.min(n as isize - 1).max(0) as usize)
            .copied()
            .unwrap_or(0) as i32
    };
    let edge = |i: usize| {
        let i = i as isize;
        g(i - 2) + 4 * g(i - 1) + 6 * g(i) + 4 * g(i + 1) + g(i + 2)
    };
    for (i, o) in out.iter_mut().enumerate().take(n.min(2)) {
        *o = edge(i);
    }
    // Interior: no clamping.
    if let Some(inner) = out.get_mut(2..n.saturating_sub(2)) {
        for (o, w) in inner.iter_mut().zip(row.windows(5)) {
            if let [a, b, c, d, e] = *w {
                *o = a as i32 + 4 * (b as i32 + d as i32) + 6 * c as i32 + e as i32;
            }
        }
    }
    for i in n.saturating_sub(2).max(2)..n {
        if let Some(o) = out.get_mut(i) {
            *o = edge(i);
        }
    }
}

/// The saddle response `(I_xy² - I_xx I_yy)`, scaled by `2⁻²⁰` and clamped at zero, of the
/// middle of three smoothed rows.
fn saddle_row(up: &[i32], mid: &[i32], dn: &[i32], out: &mut [i32]) {
    let rows = up.windows(3).zip(mid.windows(3)).zip(dn.windows(3));
    for (o, ((u, m), d)) in out.iter_mut().skip(1).zip(rows) {
        if let (&[u0, u1, u2], &[m0, m1, m2], &[d0, d1, d2]) = (u, m, d) {
            let c = m1 as i64;
            let ixx = m0 as i64 - 2 * c + m2 as i64;
            let iyy = u1 as i64 - 2 * c + d1 as i64;
            let ixy4 = u0 as i64 + d2 as i64 - u2 as i64 - d0 as i64;
            let r = (ixy4 * ixy4 - 16 * ixx * iyy) >> 24;
            *o = r.clamp(0, i32::MAX as i64) as i32;
        }
    }
}
