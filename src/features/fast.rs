//! FAST-9 corners (Rosten and Drummond, "Machine learning for high-speed corner detection",
//! 2006) with OpenCV's score and 3x3 non-maximum suppression, and the integer Harris response
//! ORB ranks them by.
//!
//! Pixel `p` with intensity `I_p` is a corner for threshold `t` when 9 contiguous pixels of the
//! 16-pixel Bresenham circle of radius 3 ([`CIRCLE`]) are all brighter than `I_p + t` or all
//! darker than `I_p - t`. Its score is the largest threshold for which it stays a corner:
//!
//! `score = max over the 16 arcs A of 9 pixels of max(min_{q∈A}(I_p - I_q), min_{q∈A}(I_q - I_p)) - 1`,
//!
//! which is OpenCV's `cornerScore<16>` (so a corner has `score >= t`). With non-maximum
//! suppression a corner is kept when its score is strictly above the scores of its 8 neighbours
//! (non-corners score 0), as in `cv::FAST(..., nonmaxSuppression = true)`.
//!
//! Work: the compass test (4 circle pixels) on 16 pixels of a row at once; on SIMD targets the
//! segment test too (one bit a lane and polarity in 16 words, windowed ANDs over the circle),
//! elsewhere one candidate at a time; the score only for corners; the suppression 16 columns at
//! a time. Memory: [`scratch_len`] bytes (three rows of scores) and a few 16-byte arrays on the
//! stack.

use core::ops::Range;

use crate::image::ImageView;
use crate::{Error, Result};

/// The 16 circle offsets `(dx, dy)`, clockwise from straight below (OpenCV's order).
pub const CIRCLE: [(i8, i8); 16] = [
    (0, 3),
    (1, 3),
    (2, 2),
    (3, 1),
    (3, 0),
    (3, -1),
    (2, -2),
    (1, -3),
    (0, -3),
    (-1, -3),
    (-2, -2),
    (-3, -1),
    (-3, 0),
    (-3, 1),
    (-2, 2),
    (-1, 3),
];

/// Length of the contiguous arc that makes a corner (FAST-9).
pub const ARC: usize = 9;

/// Radius of the circle: corners are never closer than this to the image border.
pub const RADIUS: usize = 3;

/// Parameters of [`fast_detect`], as the user writes them; checked by [`Self::check`] into the
/// [`FastParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FastConfig {
    /// Intensity threshold `t`, `≥ 1` (OpenCV's `threshold`, default 20).
    pub threshold: u8,
    /// 3x3 non-maximum suppression on the score (default on).
    pub nonmax: bool,
    /// Corners closer than this to the border are not reported (raised to [`RADIUS`]).
    pub border: u16,
}

impl Default for FastConfig {
    fn default() -> Self {
        Self {
            threshold: 20,
            nonmax: true,
            border: RADIUS as u16,
        }
    }
}

impl FastConfig {
    /// Checks the threshold once: [`fast_detect`] takes the checked [`FastParams`].
    ///
    /// Errors: [`Error::InvalidParameter`]`("fast.threshold")` for a zero threshold (every
    /// pixel of a flat image would be a corner).
    pub const fn check(&self) -> Result<FastParams> {
        if self.threshold == 0 {
            return Err(Error::InvalidParameter("fast.threshold"));
        }
        Ok(FastParams(*self))
    }
}

/// A [`FastConfig`] that passed [`FastConfig::check`]: a threshold `≥ 1`. What [`fast_detect`]
/// takes, so that no call checks it again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FastParams(FastConfig);

impl FastParams {
    /// The checked configuration.
    pub const fn config(&self) -> &FastConfig {
        &self.0
    }

    /// `config` taken as checked without checking it: only for ORB, whose own checked
    /// parameters hold a threshold `≥ 1`.
    pub(crate) const fn assume_checked(config: FastConfig) -> Self {
        Self(config)
    }
}

impl Default for FastParams {
    /// The checked [`FastConfig::default`].
    fn default() -> Self {
        Self(FastConfig::default())
    }
}

impl TryFrom<FastConfig> for FastParams {
    type Error = Error;
    fn try_from(c: FastConfig) -> Result<Self> {
        c.check()
    }
}

/// A FAST corner at pixel `(x, y)` with its score (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Corner {
    /// Column.
    pub x: u16,
    /// Row.
    pub y: u16,
    /// FAST score, `>= threshold`.
    pub score: u8,
}

/// Bytes of scratch [`fast_detect`] needs for an image `width` pixels wide: `3 width`.
pub const fn scratch_len(width: usize) -> usize {
    3 * width
}

/// The 16 circle pixels around column `x` of the middle row of `rows` (rows `y-3 ..= y+3`); 0
/// for a row that does not hold columns `x-3 ..= x+3`.
#[inline]
fn ring(rows: &[&[u8]; 7], x: usize) -> [u8; 16] {
    let x0 = x.wrapping_sub(RADIUS);
    let mut w = [&[0u8; 7]; 7];
    for (o, r) in w.iter_mut().zip(rows) {
        if let Some(c) = r.get(x0..).and_then(|r| r.first_chunk::<7>()) {
            *o = c;
        }
    }
    // Spelled out so that every offset is a constant.
    macro_rules! circle {
        ($($k:literal)*) => {[$({
            let (dx, dy) = CIRCLE[$k];
            w.get((3 + dy) as usize)
                .and_then(|r| r.get((3 + dx) as usize))
                .copied()
                .unwrap_or(0)
        }),*]};
    }
    circle!(0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15)
}

/// The FAST score of a pixel of intensity `v` with circle `ring` (module docs), `-1` when no
/// arc differs at all.
///
/// OpenCV's `cornerScore<16>` as straight-line lane code: the differences `v - q` over the
/// circle doubled to 25 entries, the minimum and the maximum of every 9-arc by doubling
/// windows (2, 4, 8, then the ninth entry), then the best arc of either sign. Fixed-size
/// arrays only, so LLVM keeps it in vector registers (`pminsw`/`pmaxsw` on SSE2).
#[inline]
pub fn score(v: u8, ring: &[u8; 16]) -> i16 {
    let d: [i16; 16] = ring.map(|q| i16::from(v) - i16::from(q));
    let mut dd = [0i16; 25];
    if let Some((head, tail)) = dd.split_first_chunk_mut::<16>() {
        *head = d;
        for (o, &x) in tail.iter_mut().zip(&d) {
            *o = x;
        }
    }
    let lo: [i16; 16] = arc_fold(&dd, i16::min);
    let hi: [i16; 16] = arc_fold(&dd, i16::max);
    let mut best = [0i16; 16];
    for ((b, &l), &h) in best.iter_mut().zip(&lo).zip(&hi) {
        // -h: h >= -255, no overflow.
        *b = l.max(-h);
    }
    best.iter().fold(i16::MIN, |m, &b| m.max(b)) - 1
}

/// `f` over each window `dd[k .. k + 9]`, `k < 16`, by windows of 2, 4, 8 and 9.
#[inline(always)]
fn arc_fold(dd: &[i16; 25], f: impl Fn(i16, i16) -> i16 + Copy) -> [i16; 16] {
    let w2: [i16; 24] = window(dd, 1, f);
    let w4: [i16; 22] = window(&w2, 2, f);
    let w8: [i16; 18] = window(&w4, 4, f);
    let mut w9 = [0i16; 16];
    for ((o, &a), &b) in w9.iter_mut().zip(&w8).zip(dd.iter().skip(8)) {
        *o = f(a, b);
    }
    w9
}

/// `out[k] = f(a[k], a[k + s])` (`M + s <= N`).
#[inline(always)]
fn window<const N: usize, const M: usize>(
    a: &[i16; N],
    s: usize,
    f: impl Fn(i16, i16) -> i16,
) -> [i16; M] {
    let mut out = [0i16; M];
    for ((o, &x), &y) in out.iter_mut().zip(a).zip(a.iter().skip(s)) {
        *o = f(x, y);
    }
    out
}

/// Quick rejection: a 9-arc holds at least two of the four compass pixels (0, 4, 8, 12), all
/// brighter or all darker. `false` means "certainly not a corner".
#[inline]
fn may_be_corner(rows: &[&[u8]; 7], x: usize, v: u8, t: u8) -> bool {
    let px = |dx: isize, dy: usize| {
        rows.get(dy)
            .and_then(|r| r.get(x.wrapping_add_signed(dx)))
            .copied()
            .unwrap_or(0)
    };
    let c = [px(0, 6), px(3, 3), px(0, 0), px(-3, 3)];
    let hi = v.saturating_add(t);
    let lo = v.saturating_sub(t);
    // Saturation makes the tests impossible, not wrong: nothing is above 255 or below 0.
    let bright = c.iter().filter(|&&q| q > hi).count();
    let dark = c.iter().filter(|&&q| q < lo).count();
    bright >= 2 || dark >= 2
}

/// The segment test itself: 9 contiguous circle pixels all above `v + t` or all below `v - t`,
/// on 16-bit masks (a run of 9 set bits in the mask doubled to 32 bits). The score is only
/// computed for pixels that pass.
#[inline]
fn segment_test(v: u8, ring: &[u8; 16], t: u8) -> bool {
    let (hi, lo) = (v.saturating_add(t), v.saturating_sub(t));
    let (mut bright, mut dark) = (0u32, 0u32);
    for (k, &q) in ring.iter().enumerate() {
        bright |= u32::from(q > hi) << k;
        dark |= u32::from(q < lo) << k;
    }
    let run9 = |m: u32| {
        let mut r = m | (m << 16);
        for _ in 0..ARC - 1 {
            r &= r >> 1;
        }
        r & 0xffff != 0
    };
    run9(bright) || run9(dark)
}

/// Pixels per chunk of the row-wide tests in [`score_row`].
const CHUNK: usize = 16;

/// Whether a chunk's candidates take the segment test all at once ([`chunk_corners`]: about
/// 170 min/max steps over the 16 lanes, SIMD on these targets) or one candidate at a time
/// ([`segment_test`], cheaper without SIMD, where the 16 lanes would cost 16 times as much).
const LANE_SEGMENT_TEST: bool = cfg!(any(
    target_arch = "x86_64",
    target_arch = "x86",
    target_arch = "aarch64"
));

/// Scores of row `rows[3]` over the columns `xs` into `out` (0 where not a corner): the compass
/// test ([`may_be_corner`]) for [`CHUNK`] pixels at once, then the segment test and the score
/// for the pixels that pass (segment test per chunk with `LANE_TEST`, per pixel without; see
/// [`LANE_SEGMENT_TEST`]). `xs` must keep [`RADIUS`] columns from both image borders.
fn score_row<const LANE_TEST: bool>(rows: &[&[u8]; 7], xs: Range<usize>, t: u8, out: &mut [u8]) {
    let (x0, x1) = (xs.start, xs.end);
    // The rows cut to one length: with the chunk tests inlined, LLVM then bounds-checks a
    // chunk's 7 row windows once rather than row by row.
    let n = rows.iter().map(|r| r.len()).min().unwrap_or(0);
    let mut cut = [&[][..]; 7];
    for (c, r) in cut.iter_mut().zip(rows) {
        match r.get(..n) {
            Some(r) => *c = r,
            None => return,
        }
    }
    let rows = &cut;
    let mut x = x0;
    while x < x1 {
        // The last chunk overlaps its predecessor rather than leaving a scalar tail; rows
        // narrower than a chunk go pixel by pixel.
        let xc = if x + CHUNK <= x1 {
            x
        } else if x1 - x0 >= CHUNK {
            x1 - CHUNK
        } else {
            for x in x..x1 {
                let v = rows[3].get(x).copied().unwrap_or(0);
                if may_be_corner(rows, x, v, t) {
                    score_pixel(rows, x, v, t, out);
                }
            }
            return;
        };
        let cand = if LANE_TEST {
            chunk_corners(rows, xc, t)
        } else {
            chunk_candidates(rows, xc, t)
        };
        // One bit per lane: visit the set ones.
        let mut bits = cand;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let x = xc + i;
            let v = rows[3].get(x).copied().unwrap_or(0);
            if LANE_TEST {
                score_corner(rows, x, v, t, out);
            } else {
                score_pixel(rows, x, v, t, out);
            }
        }
        x = xc + CHUNK;
    }
}

/// The segment test, then the score, of one pixel that passed the compass test.
#[inline]
fn score_pixel(rows: &[&[u8]; 7], x: usize, v: u8, t: u8, out: &mut [u8]) {
    let circle = ring(rows, x);
    if segment_test(v, &circle, t) {
        write_score(v, &circle, t, x, out);
    }
}

/// The score of a pixel known to be a corner.
#[inline]
fn score_corner(rows: &[&[u8]; 7], x: usize, v: u8, t: u8, out: &mut [u8]) {
    write_score(v, &ring(rows, x), t, x, out);
}

#[inline]
fn write_score(v: u8, circle: &[u8; 16], t: u8, x: usize, out: &mut [u8]) {
    let s = score(v, circle);
    if s >= i16::from(t)
        && let Some(c) = out.get_mut(x)
    {
        // s <= 254: the differences are at most 255.
        *c = s.clamp(1, 255) as u8;
    }
}

/// `f` lane by lane.
#[inline(always)]
fn map2(a: &[u8; CHUNK], b: &[u8; CHUNK], f: impl Fn(u8, u8) -> u8) -> [u8; CHUNK] {
    let mut out = [0u8; CHUNK];
    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
        *o = f(a, b);
    }
    out
}

/// Columns `x - 3 .. x + 3 + CHUNK` of the 7 rows, if inside.
const WIDE: usize = CHUNK + 2 * RADIUS;

#[inline(always)]
fn wide_rows<'r>(rows: &[&'r [u8]; 7], x: usize) -> Option<[&'r [u8; WIDE]; 7]> {
    let x0 = x.checked_sub(RADIUS)?;
    let mut out = [&[0u8; WIDE]; 7];
    for (o, r) in out.iter_mut().zip(rows) {
        *o = r.get(x0..)?.first_chunk::<WIDE>()?;
    }
    Some(out)
}

/// The lanes of circle offset `(dx, dy)` from wide rows (`dy` row `3 + dy`, column `3 + dx`).
#[inline(always)]
fn at<'r>(w: &[&'r [u8; WIDE]; 7], dx: i8, dy: i8) -> &'r [u8; CHUNK] {
    let row = w.get((3 + dy) as usize).copied().unwrap_or(&[0; WIDE]);
    row.get((3 + dx) as usize..)
        .and_then(|r| r.first_chunk::<CHUNK>())
        .unwrap_or(&[0; CHUNK])
}

/// Whether two neighbouring compass pixels of the four (circle pixels 0, 4, 8, 12, cyclically)
/// are both set, with `and` and `or` of the mask type: any 9-arc holds such a pair.
#[inline(always)]
fn pair<T: Copy>(m: [T; 4], and: impl Fn(T, T) -> T, or: impl Fn(T, T) -> T) -> T {
    let [m0, m1, m2, m3] = m;
    or(or(and(m0, m1), and(m1, m2)), or(and(m2, m3), and(m3, m0)))
}

/// Lane `i` nonzero when `q[i] > h[i]`.
#[inline(always)]
fn gt(q: &[u8; CHUNK], h: &[u8; CHUNK]) -> [u8; CHUNK] {
    map2(q, h, u8::saturating_sub)
}

/// Lane `i` nonzero when `q[i] < l[i]`.
#[inline(always)]
fn lt(q: &[u8; CHUNK], l: &[u8; CHUNK]) -> [u8; CHUNK] {
    map2(l, q, u8::saturating_sub)
}

/// Bit `i` set when lane `i` is nonzero (`pcmpeqb`, `pmovmskb` on SSE2).
#[inline(always)]
fn lane_bits(m: &[u8; CHUNK]) -> u16 {
    use wide::u8x16;
    // One bit per zero lane (`to_bitmask` reads each lane's top bit), inverted.
    !(u8x16::from(*m).simd_eq(u8x16::ZERO).to_bitmask() as u16)
}

/// The compass candidates of the chunk at `x` (bit `i`: pixel `x + i`) for cores without
/// vector units: lane masks are "nonzero or zero" (AND is `min`, OR is `max`), the test in
/// its sharp form (two neighbouring compass pixels both brighter or both darker).
#[inline(always)]
fn chunk_candidates(rows: &[&[u8]; 7], x: usize, t: u8) -> u16 {
    let Some(w) = wide_rows(rows, x) else {
        return 0;
    };
    let v = at(&w, 0, 0);
    let hi = v.map(|p| p.saturating_add(t));
    let lo = v.map(|p| p.saturating_sub(t));
    let c = [CIRCLE[0], CIRCLE[4], CIRCLE[8], CIRCLE[12]].map(|(dx, dy)| at(&w, dx, dy));
    let and = |a: [u8; CHUNK], b: [u8; CHUNK]| map2(&a, &b, u8::min);
    let or = |a: [u8; CHUNK], b: [u8; CHUNK]| map2(&a, &b, u8::max);
    let bright = pair(c.map(|q| gt(q, &hi)), and, or);
    let dark = pair(c.map(|q| lt(q, &lo)), and, or);
    lane_bits(&or(bright, dark))
}

/// `out[k] = f(a[k], b[(k + s) % 16])`: one step of the windows over the circle.
#[inline(always)]
fn shifted(a: &[u32; 16], b: &[u32; 16], s: usize, f: impl Fn(u32, u32) -> u32) -> [u32; 16] {
    core::array::from_fn(|k| {
        let (x, y) = (a.get(k), b.get((k + s) & 15));
        f(x.copied().unwrap_or(0), y.copied().unwrap_or(0))
    })
}

/// The corners of the chunk at `x` (bit `i`: pixel `x + i` passes the segment test), on
/// targets with 128-bit vectors.
///
/// Each circle pixel's comparisons for the 16 lanes go to one word (`pcmpgtb`, `pmovmskb` on
/// SSE2): bit `i` for "lane `i` brighter than `v + t`", bit `16 + i` for "darker than
/// `v - t`". The segment test is then scalar bit arithmetic on the 16 words, both polarities
/// and all lanes at once: a lane passes when some 9 cyclically contiguous words all have its
/// bit, the AND of windows of 2, 4, 8 and 9 words, ORed over the 16 starts (79 word
/// operations). Filters first: the compass test (4 words), then "one of each opposite pair
/// `(k, k + 8)`", which any 9-arc holds (OpenCV's scalar FAST uses the same). (With the
/// windows on the 32 lane masks themselves, the 16 brighter and 16 darker vectors did not
/// fit the 16 registers: a third of the instructions were spills.)
#[inline(always)]
fn chunk_corners(rows: &[&[u8]; 7], x: usize, t: u8) -> u16 {
    use wide::u8x16;
    let Some(w) = wide_rows(rows, x) else {
        return 0;
    };
    let lanes = |dx: i8, dy: i8| u8x16::from(*at(&w, dx, dy));
    let v = lanes(0, 0);
    let (hi, lo) = (
        v.saturating_add(u8x16::splat(t)),
        v.saturating_sub(u8x16::splat(t)),
    );
    let sides = |(dx, dy): (i8, i8)| {
        let q = lanes(dx, dy);
        q.simd_gt(hi).to_bitmask() | (q.simd_lt(lo).to_bitmask() << 16)
    };
    let compass = [CIRCLE[0], CIRCLE[4], CIRCLE[8], CIRCLE[12]].map(sides);
    if pair(compass, |a, b| a & b, |a, b| a | b) == 0 {
        return 0;
    }
    // Spelled out so that every offset is a constant (a loop over CIRCLE was not unrolled).
    macro_rules! circle {
        ($($k:literal)*) => { [$( sides(CIRCLE[$k]) ),*] };
    }
    let m: [u32; 16] = circle!(0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15);
    let opposite = (0..8).fold(u32::MAX, |a, k| {
        a & (m.get(k).copied().unwrap_or(0) | m.get(k + 8).copied().unwrap_or(0))
    });
    if opposite == 0 {
        return 0;
    }
    let and = |a: u32, b: u32| a & b;
    let w2 = shifted(&m, &m, 1, and);
    let w4 = shifted(&w2, &w2, 2, and);
    let w8 = shifted(&w4, &w4, 4, and);
    let w9 = shifted(&w8, &m, 8, and);
    let any = w9.iter().fold(0, |a, &b| a | b);
    (any | (any >> 16)) as u16
}

/// FAST-9 corners of `img`, reported through `emit` in row-major order.
///
/// Corners lie in `b <= x < width - b`, `b <= y < height - b` with
/// `b = max(config.border, 3)`. `scratch` must hold [`scratch_len`]`(width)` bytes.
///
/// Errors: [`Error::BufferTooSmall`] when `scratch` is too short.
#[doc(alias = "FAST")]
#[doc(alias = "FastFeatureDetector")]
pub fn fast_detect(
    img: &ImageView<'_, u8>,
    params: &FastParams,
    scratch: &mut [u8],
    mut emit: impl FnMut(Corner),
) -> Result<()> {
    let config = params.config();
    let (w, h) = (img.width(), img.height());
    if scratch.len() < scratch_len(w) {
        return Err(Error::BufferTooSmall("scratch"));
    }
    let b = usize::from(config.border).max(RADIUS);
    if w <= 2 * b || h <= 2 * b {
        return Ok(());
    }
    let t = config.threshold;
    let (x0, x1) = (b, w - b);
    // Checked splits: the length check above covers them, but the optimiser cannot see it.
    let too_small = Error::BufferTooSmall("scratch");
    let (s0, rest) = scratch.split_at_mut_checked(w).ok_or(too_small)?;
    let (s1, rest) = rest.split_at_mut_checked(w).ok_or(too_small)?;
    let s2 = rest.get_mut(..w).ok_or(Error::BufferTooSmall("scratch"))?;
    let mut bufs: [&mut [u8]; 3] = [s0, s1, s2];
    for buf in bufs.iter_mut() {
        buf.fill(0);
    }
    // Scores of row y go to bufs[y % 3]; row y - 1 is decided once row y is scored.
    for y in b..=h - b {
        let scoring = y < h - b;
        if scoring {
            let rows: [&[u8]; 7] =
                core::array::from_fn(|j| img.row_clamped(y as isize + j as isize - 3));
            let cur = bufs
                .get_mut(y % 3)
                .ok_or(Error::BufferTooSmall("scratch"))?;
            cur.fill(0);
            score_row::<LANE_SEGMENT_TEST>(&rows, x0..x1, t, cur);
        } else if let Some(cur) = bufs.get_mut(y % 3) {
            cur.fill(0);
        }
        if !config.nonmax {
            if scoring && let Some(cur) = bufs.get(y % 3) {
                for (x, &s) in cur.iter().enumerate().take(x1).skip(x0) {
                    if s > 0 {
                        emit(Corner {
                            x: x as u16,
                            y: y as u16,
                            score: s,
                        });
                    }
                }
            }
            continue;
        }
        // Decide row y - 1 (rows before b were never scored: all zero).
        let yd = y - 1;
        if yd < b {
            continue;
        }
        let prev = bufs.get((yd + 2) % 3).map(|r| &**r).unwrap_or(&[]);
        let mid = bufs.get(yd % 3).map(|r| &**r).unwrap_or(&[]);
        let next = bufs.get(y % 3).map(|r| &**r).unwrap_or(&[]);
        suppress(prev, mid, next, x0..x1, |x, s| {
            emit(Corner {
                x: x as u16,
                y: yd as u16,
                score: s,
            })
        });
    }
    Ok(())
}

/// 3x3 non-maximum suppression of the scores `mid` (rows `prev` and `next` around it) over the
/// columns `xs`: `keep(x, s)` for each `s = mid[x]` strictly above its 8 neighbours (so `s > 0`).
/// [`CHUNK`] columns at a time: the largest neighbour of each lane by `max` over the three
/// rows' shifted windows, one comparison, one bit a lane; the few set bits are then visited.
/// (Column by column with early exits, the branches mispredicted on every textured row: a
/// fifth of [`fast_detect`]'s time on the host.)
fn suppress(
    prev: &[u8],
    mid: &[u8],
    next: &[u8],
    xs: Range<usize>,
    mut keep: impl FnMut(usize, u8),
) {
    let mut x = xs.start;
    while x < xs.end {
        // As in `score_row`: the last chunk overlaps its predecessor (the columns before `x`
        // masked off); a row narrower than a chunk goes column by column.
        let xc = if x + CHUNK <= xs.end {
            x
        } else if xs.len() >= CHUNK {
            xs.end - CHUNK
        } else {
            for x in x..xs.end {
                let s = mid.get(x).copied().unwrap_or(0);
                let n =
                    |r: &[u8], dx: isize| r.get(x.wrapping_add_signed(dx)).copied().unwrap_or(0);
                let most = [-1, 0, 1]
                    .iter()
                    .map(|&dx| n(prev, dx).max(n(next, dx)))
                    .fold(n(mid, -1).max(n(mid, 1)), u8::max);
                if s > most {
                    keep(x, s);
                }
            }
            return;
        };
        let wide = |r: &[u8]| {
            xc.checked_sub(1)
                .and_then(|x0| r.get(x0..))
                .and_then(|r| r.first_chunk::<{ CHUNK + 2 }>())
                .copied()
                .unwrap_or([0; CHUNK + 2])
        };
        let lanes = |r: &[u8; CHUNK + 2], o: usize| -> [u8; CHUNK] {
            r.get(o..)
                .and_then(|r| r.first_chunk::<CHUNK>())
                .copied()
                .unwrap_or([0; CHUNK])
        };
        let m = wide(mid);
        let s = lanes(&m, 1);
        // Columns before `x` were decided by the previous chunk.
        let mut bits = lane_bits(&s) & u16::MAX.checked_shl((x - xc) as u32).unwrap_or(0);
        if bits != 0 {
            let (p, n) = (wide(prev), wide(next));
            let mut most = map2(&lanes(&m, 0), &lanes(&m, 2), u8::max);
            for o in 0..3 {
                most = map2(&most, &map2(&lanes(&p, o), &lanes(&n, o), u8::max), u8::max);
            }
            // Lane nonzero when s > most.
            bits &= lane_bits(&map2(&s, &most, u8::saturating_sub));
        }
        while bits != 0 {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            keep(xc + i, s.get(i).copied().unwrap_or(0));
        }
        x = xc + CHUNK;
    }
}

/// Harris block size of [`harris_response`] (OpenCV ORB's `HARRIS_BLOCK_SIZE`).
pub const HARRIS_BLOCK: usize = 7;

/// Harris `k` in Q10: `41 / 1024 = 0.0400` (OpenCV ORB uses 0.04).
pub const HARRIS_K_Q10: i64 = 41;

/// The Harris corner response at `(x, y)`, in integers:
///
/// `R = a b - c² - k (a + b)²`, `a = Σ Ix²`, `b = Σ Iy²`, `c = Σ Ix Iy` over the 7x7 block
/// centred on the pixel, `Ix`, `Iy` the 3x3 Sobel derivatives (OpenCV ORB's `HarrisResponses`
/// before its constant scale factor `(4 · 7 · 255)⁻⁴`). `|R| < 2⁶⁰`.
///
/// `None` unless the block and its Sobel taps fit in the image (`4 <= x < width - 4`, same in y).
pub fn harris_response(img: &ImageView<'_, u8>, x: usize, y: usize) -> Option<i64> {
    const R: usize = HARRIS_BLOCK / 2 + 1;
    const N: usize = HARRIS_BLOCK + 2;
    if x < R || y < R || x + R >= img.width() || y + R >= img.height() {
        return None;
    }
    // The 9 rows of the block and its taps, each as its 9 columns: per row, the horizontal
    // difference `p[k + 2] - p[k]` and smoothing `p[k] + 2 p[k + 1] + p[k + 2]`; the Sobel
    // derivatives are then `Ix = d₀ + 2 d₁ + d₂` and `Iy = s₂ - s₀` down three rows. Fixed
    // sizes throughout, so the loops unroll without bounds checks.
    let mut d = [[0i32; HARRIS_BLOCK]; N];
    let mut s = [[0i32; HARRIS_BLOCK]; N];
    for (j, (dr, sr)) in d.iter_mut().zip(s.iter_mut()).enumerate() {
        let row: &[u8; N] = img.row(y - R + j)?.get(x - R..x + R + 1)?.try_into().ok()?;
        let p = row.map(i32::from);
        for (k, (dv, sv)) in dr.iter_mut().zip(sr.iter_mut()).enumerate() {
            let [a, b, c] = [k, k + 1, k + 2].map(|i| p.get(i).copied().unwrap_or(0));
            *dv = c - a;
            *sv = a + 2 * b + c;
        }
    }
    // |Ix|, |Iy| <= 4 · 255, so each of the 49 products is below 2²⁰ and the sums fit `i32`.
    let (mut a, mut b, mut c) = (0i32, 0i32, 0i32);
    for ((d3, s0), s2) in d.windows(3).zip(s.iter()).zip(s.iter().skip(2)) {
        let [d0, d1, d2] = [0, 1, 2].map(|i| d3.get(i).copied().unwrap_or_default());
        for k in 0..HARRIS_BLOCK {
            let at = |r: &[i32; HARRIS_BLOCK]| r.get(k).copied().unwrap_or(0);
            let ix = at(&d0) + 2 * at(&d1) + at(&d2);
            let iy = at(s2) - at(s0);
            a += ix * ix;
            b += iy * iy;
            c += ix * iy;
        }
    }
    let (a, b, c) = (i64::from(a), i64::from(b), i64::from(c));
    Some(a * b - c * c - ((HARRIS_K_Q10 * (a + b) * (a + b)) >> 10))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn detect(img: &ImageView<'_, u8>, cfg: &FastConfig) -> Vec<Corner> {
        let mut scratch = std::vec![0u8; scratch_len(img.width())];
        let mut out = Vec::new();
        fast_detect(img, &cfg.check().unwrap(), &mut scratch, |c| out.push(c)).unwrap();
        out
    }

    /// Brute force from the definition: every arc, every pixel.
    fn reference(img: &ImageView<'_, u8>, t: u8) -> Vec<(usize, usize, u8)> {
        let mut out = Vec::new();
        for y in 3..img.height() - 3 {
            for x in 3..img.width() - 3 {
                let v = i16::from(img.get(x, y).unwrap());
                let ring: Vec<i16> = CIRCLE
                    .iter()
                    .map(|&(dx, dy)| {
                        i16::from(
                            img.get(
                                (x as isize + dx as isize) as usize,
                                (y as isize + dy as isize) as usize,
                            )
                            .unwrap(),
                        )
                    })
                    .collect();
                let mut best = 0i16;
                for k in 0..16 {
                    let arc: Vec<i16> = (0..9).map(|j| ring[(k + j) % 16]).collect();
                    best = best.max(arc.iter().map(|q| q - v).min().unwrap());
                    best = best.max(arc.iter().map(|q| v - q).min().unwrap());
                }
                if best > i16::from(t) {
                    out.push((x, y, (best - 1) as u8));
                }
            }
        }
        out
    }

    fn noise(w: usize, h: usize, seed: u32) -> Vec<u8> {
        let mut s = seed;
        (0..w * h)
            .map(|i| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                // Blocky noise so that corners exist at every threshold.
                if (i / w / 3 + i % w / 3).is_multiple_of(2) {
                    (s >> 24) as u8
                } else {
                    (s >> 26) as u8
                }
            })
            .collect()
    }

    /// The score as first written (one arc at a time, modular indices).
    fn score_by_arcs(v: u8, ring: &[u8; 16]) -> i16 {
        let d: [i16; 16] = ring.map(|q| i16::from(v) - i16::from(q));
        let mut best = i16::MIN;
        for k in 0..16 {
            let (mut lo, mut hi) = (i16::MAX, i16::MIN);
            for j in 0..ARC {
                lo = lo.min(d[(k + j) % 16]);
                hi = hi.max(d[(k + j) % 16]);
            }
            best = best.max(lo).max(-hi);
        }
        best - 1
    }

    #[test]
    fn lane_score_matches_the_arc_by_arc_score() {
        let mut s = 12_345u32;
        let mut next = || {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 24) as u8
        };
        for case in 0..200_000u32 {
            let v = next();
            // Full-range rings, narrow rings around v (ties, small scores) and extremes.
            let ring: [u8; 16] = core::array::from_fn(|_| match case % 4 {
                0 => next(),
                1 => v.wrapping_add(next() % 7).wrapping_sub(3),
                2 => [0, 255, v][usize::from(next() % 3)],
                _ => {
                    if next() < 64 {
                        next()
                    } else {
                        v.wrapping_add(40)
                    }
                }
            });
            assert_eq!(score(v, &ring), score_by_arcs(v, &ring), "{v} {ring:?}");
        }
        for v in [0u8, 255] {
            for q in [0u8, 255] {
                assert_eq!(score(v, &[q; 16]), score_by_arcs(v, &[q; 16]));
            }
        }
    }

    #[test]
    fn matches_the_definition_without_nonmax() {
        let (w, h) = (61, 43);
        let data = noise(w, h, 3);
        let img = ImageView::packed(&data, w, h).unwrap();
        for t in [1u8, 10, 20, 40, 80] {
            let cfg = FastConfig {
                threshold: t,
                nonmax: false,
                border: 3,
            };
            let got: Vec<(usize, usize, u8)> = detect(&img, &cfg)
                .iter()
                .map(|c| (c.x as usize, c.y as usize, c.score))
                .collect();
            assert_eq!(got, reference(&img, t), "t = {t}");
        }
    }

    #[test]
    fn both_row_paths_match_the_definition_at_chunk_edges() {
        // Widths below, at and around the chunk (pixel by pixel, whole chunks, an overlapping
        // last chunk), both segment-test paths, against the brute-force scores.
        for w in (7..=2 * CHUNK + 8).chain([5 * CHUNK + 3]) {
            let h = 12;
            let data = noise(w, h, w as u32);
            let img = ImageView::packed(&data, w, h).unwrap();
            for t in [1u8, 12, 30] {
                let want: Vec<(usize, usize, u8)> = reference(&img, t);
                for lane_test in [false, true] {
                    let mut got = Vec::new();
                    for y in 3..h - 3 {
                        let rows: [&[u8]; 7] =
                            core::array::from_fn(|j| img.row(y + j - 3).unwrap());
                        let mut out = std::vec![0u8; w];
                        if lane_test {
                            score_row::<true>(&rows, 3..w - 3, t, &mut out);
                        } else {
                            score_row::<false>(&rows, 3..w - 3, t, &mut out);
                        }
                        got.extend(
                            out.iter()
                                .enumerate()
                                .filter(|c| *c.1 > 0)
                                .map(|(x, &s)| (x, y, s)),
                        );
                    }
                    assert_eq!(got, want, "w = {w}, t = {t}, lane_test = {lane_test}");
                }
            }
        }
    }

    #[test]
    fn nonmax_keeps_strict_local_maxima() {
        // Widths round the suppression's 16-column chunks (columns 3 .. w - 3): narrower than
        // one (21), exactly one and two (22, 38), an overlapping last chunk (50, 41), and a
        // wider border.
        for (w, border) in [(50, 3), (21, 3), (22, 3), (38, 3), (41, 3), (50, 7)] {
            let h = 40;
            let data = noise(w, h, 11 + w as u32);
            let img = ImageView::packed(&data, w, h).unwrap();
            let all = reference(&img, 15);
            // Only pixels inside the border are scored, so only they can suppress.
            let (bx, by) = (border..w - border, border..h - border);
            let score_at = |x: usize, y: usize| {
                let inside = bx.contains(&x) && by.contains(&y);
                let c = all.iter().find(|c| inside && c.0 == x && c.1 == y);
                c.map_or(0, |c| c.2)
            };
            let expected: Vec<(usize, usize, u8)> = all
                .iter()
                .copied()
                .filter(|&(x, y, s)| {
                    bx.contains(&x)
                        && by.contains(&y)
                        && (-1isize..=1).all(|dy| {
                            (-1isize..=1).all(|dx| {
                                (dx == 0 && dy == 0)
                                    || s > score_at(
                                        (x as isize + dx) as usize,
                                        (y as isize + dy) as usize,
                                    )
                            })
                        })
                })
                .collect();
            let cfg = FastConfig {
                threshold: 15,
                border: border as u16,
                ..Default::default()
            };
            let got: Vec<(usize, usize, u8)> = detect(&img, &cfg)
                .iter()
                .map(|c| (c.x as usize, c.y as usize, c.score))
                .collect();
            assert_eq!(got, expected, "width {w}, border {border}");
            assert!(!got.is_empty());
        }
    }

    #[test]
    fn border_tiny_images_and_errors() {
        let data = noise(40, 30, 5);
        let img = ImageView::packed(&data, 40, 30).unwrap();
        let cfg = FastConfig {
            threshold: 10,
            nonmax: true,
            border: 12,
        };
        assert!(
            detect(&img, &cfg)
                .iter()
                .all(|c| (12..28).contains(&c.x) && (12..18).contains(&c.y))
        );
        let tiny = ImageView::packed(&data[..36], 6, 6).unwrap();
        assert!(detect(&tiny, &FastConfig::default()).is_empty());
        let mut short = [0u8; 10];
        assert_eq!(
            fast_detect(&img, &FastParams::default(), &mut short, |_| {}),
            Err(Error::BufferTooSmall("scratch"))
        );
        let zero = FastConfig {
            threshold: 0,
            ..Default::default()
        };
        assert_eq!(zero.check(), Err(Error::InvalidParameter("fast.threshold")));
        assert_eq!(
            FastParams::try_from(FastConfig::default()),
            Ok(FastParams::default())
        );
    }

    #[test]
    fn harris_prefers_corners_to_edges() {
        // A bright square on dark: its corner beats the middle of its edge, flat is zero.
        let (w, h) = (40, 40);
        let mut data = std::vec![20u8; w * h];
        for y in 10..30 {
            for x in 10..30 {
                data[y * w + x] = 200;
            }
        }
        let img = ImageView::packed(&data, w, h).unwrap();
        let corner = harris_response(&img, 10, 10).unwrap();
        let edge = harris_response(&img, 20, 10).unwrap();
        let flat = harris_response(&img, 20, 20).unwrap();
        assert!(
            corner > 0 && edge < 0 && flat == 0,
            "{corner} {edge} {flat}"
        );
        assert_eq!(harris_response(&img, 3, 20), None);
        assert_eq!(harris_response(&img, 20, 36), None);
    }

    #[test]
    fn harris_matches_the_sobel_definition() {
        // Every position of a random image (strided view, extreme values included) against
        // the 3x3 Sobel sums written out per pixel: equal, and `None` exactly where the block
        // or its taps leave the image.
        let (w, h, stride) = (23usize, 17usize, 29usize);
        let mut g = crate::rng::Pcg32::new(5);
        let data: Vec<u8> = (0..stride * h)
            .map(|_| match g.below(8) {
                0 => 0,
                1 => 255,
                _ => g.below(256) as u8,
            })
            .collect();
        let img = ImageView::new(&data, w, h, stride).unwrap();
        let p = |x: usize, y: usize| i64::from(data[y * stride + x]);
        for y in 0..h {
            for x in 0..w {
                let inside = (4..w - 4).contains(&x) && (4..h - 4).contains(&y);
                let want = inside.then(|| {
                    let (mut a, mut b, mut c) = (0i64, 0i64, 0i64);
                    for yy in y - 3..=y + 3 {
                        for xx in x - 3..=x + 3 {
                            let ix = 2 * (p(xx + 1, yy) - p(xx - 1, yy))
                                + (p(xx + 1, yy - 1) - p(xx - 1, yy - 1))
                                + (p(xx + 1, yy + 1) - p(xx - 1, yy + 1));
                            let iy = 2 * (p(xx, yy + 1) - p(xx, yy - 1))
                                + (p(xx - 1, yy + 1) - p(xx - 1, yy - 1))
                                + (p(xx + 1, yy + 1) - p(xx + 1, yy - 1));
                            a += ix * ix;
                            b += iy * iy;
                            c += ix * iy;
                        }
                    }
                    a * b - c * c - ((HARRIS_K_Q10 * (a + b) * (a + b)) >> 10)
                });
                assert_eq!(harris_response(&img, x, y), want, "at {x},{y}");
            }
        }
    }
}
