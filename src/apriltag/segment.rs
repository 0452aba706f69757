//! The per-pixel stages: decimation, adaptive threshold, connected components and the
//! black/white boundary points, all in integers and caller buffers.
//!
//! **Threshold** (AprilTag's `threshold`): the image is cut into 4x4 tiles; each tile's min and
//! max are dilated over its 3x3 tile neighbourhood; a pixel of a tile whose dilated
//! `max - min < min_white_black_diff` is *skipped* (no edge can be there), others are white
//! when `v > min + ⌊(max - min) f⌋`, black otherwise, with `f` the detector's
//! `threshold_fraction` (AprilTag's `1/2`, exactly its `min + (max - min) / 2`, by default). Partial tiles at the right and bottom
//! use the last full tile. Storage: one byte per tile (the threshold, 255 = skipped) and a ring
//! of three tile rows of raw min/max; the thresholded image itself is never stored, each pass
//! recomputes a row (one compare a pixel).
//!
//! **Components** (AprilTag's union-find, 8 bytes a pixel there): white pixels are 8-connected,
//! black ones 4-connected. One raster pass gives every pixel a *provisional label*: that of
//! its first same-class neighbour among left, up (and for white up-left, up-right), or a new
//! one; the other same-class neighbours are united with it (union by smaller index, path
//! halving). Only the labels are stored (a parent, `u16` or `u32` ([`Label`]), and a saturating `u8` pixel count
//! each) plus two rows; as labels are only created where no earlier neighbour has the class,
//! there are far fewer than pixels. Later passes re-derive the same labels row by row (the
//! rule depends only on the classes) and read the root from the flattened parents. When the
//! label capacity runs out, pixels that would need a new label are skipped (reported).
//!
//! **Boundaries** (AprilTag's `gradient_clusters`): for every pixel `p` of a component of at
//! least [`MIN_COMPONENT`] pixels and each of its neighbours `q` right, below, below-left and
//! below-right of the opposite class in such a component, the midpoint `(p + q) / 2` is a
//! boundary point of the cluster keyed by the pair (black root, white root), with the
//! direction towards the white pixel (AprilTag's duplicate suppression of the two diagonals
//! included). Points are packed in a `u32`: doubled coordinates (14 bits each) and the
//! gradient signs.
//!
//! **Run cache**: the labelling pass also writes every row's runs, as it labelled them, into
//! the end of a caller's `u32` buffer (the point buffer, whose points fill it from the start),
//! downwards: per row a word with its run count, then below it a word a run (end column,
//! class, provisional label; `pack_run`).
//! A scan then reads the rows from there (`boundary_scan_cached`) instead of re-deriving
//! them from the pixels, and may start and end at any row (the labels are stored, not
//! re-counted); once it has read a row, the row's words are free for points (the last
//! batch's clusters may take them when they do not all fit below the cache). A frame whose
//! runs do not fit (or, with `u32` labels, with a label of 16 bits
//! or more) has no cache and its scans re-derive the rows (`boundary_scan`): the points are
//! the same either way, in the same order.

use super::label::{ClusterKey, Label};
use crate::image::ImageView;

/// Pixel classes of the thresholded image.
pub(crate) const BLACK: u8 = 0;
pub(crate) const WHITE: u8 = 1;
pub(crate) const SKIP: u8 = 2;

/// Tile threshold value meaning "skipped": a non-skipped tile has `max - min ≥ 1`, so its
/// threshold `min + (max - min) / 2` is at most 254.
const SKIP_TILE: u8 = 255;

/// Tile side in pixels (AprilTag's `tilesz`).
pub const TILE: usize = 4;

/// Components smaller than this (pixels) make no boundary points (AprilTag's 25).
pub const MIN_COMPONENT: u8 = 25;

/// Most labels a frame can use with `u16` labels (a [`super::Workspace`]): every `u16` but the
/// two markers ([`Label::MAX_LABELS`] of `u16`; `u32` labels allow `2^32 - 2`).
pub const MAX_LABELS: usize = <u16 as Label>::MAX_LABELS;

/// Widest and tallest image the detector takes: that of any [`ImageView`]
/// ([`crate::image::MAX_DIM`], 8192), which boundary points hold as doubled coordinates in 14
/// bits (`2 (8192 - 2) + 1 < 2^14`); columns of a [`Run`] and the cluster bounding
/// boxes are `u16`, the pixel counts of a row run `u16` too.
pub const MAX_SIDE: usize = crate::image::MAX_DIM;
const _: () = assert!(2 * (MAX_SIDE - 2) + 1 < 1 << 14);

/// The image the per-pixel stages see: `img` point-sampled every `d` pixels (AprilTag's
/// integer `quad_decimate`), `w x h = ⌈W / d⌉ x ⌈H / d⌉`.
#[derive(Clone, Copy)]
pub(crate) struct Sampled<'a> {
    pub(crate) img: ImageView<'a, u8>,
    pub(crate) d: usize,
    pub(crate) w: usize,
    pub(crate) h: usize,
}

impl<'a> Sampled<'a> {
    pub(crate) fn new(img: ImageView<'a, u8>, d: usize) -> Self {
        let d = d.max(1);
        Self {
            img,
            d,
            w: img.width().div_ceil(d),
            h: img.height().div_ceil(d),
        }
    }

    /// Row `y` of the full image that is row `y` here (`None` past the end).
    #[inline]
    pub(crate) fn full_row(&self, y: usize) -> &'a [u8] {
        self.img.row(y.saturating_mul(self.d)).unwrap_or(&[])
    }
}

/// Tile thresholds of a frame: `tw x th` full tiles.
#[derive(Clone, Copy)]
pub(crate) struct Tiles<'a> {
    pub(crate) thr: &'a [u8],
    pub(crate) tw: usize,
    pub(crate) th: usize,
}

/// Number of tiles of a `w x h` sampled image (`⌊w / 4⌋ ⌊h / 4⌋`).
pub(crate) const fn tile_count(w: usize, h: usize) -> usize {
    (w / TILE) * (h / TILE)
}

/// Bit 7 of every byte of a `u32` (the SWAR helpers' lane tops).
const TOPS: u32 = 0x8080_8080;

/// Bytewise `x ≥ y` of two words of four `u8` lanes: bit 7 of each byte of the result is
/// set where the lane of `x` is at least that of `y` (the other bits are 0).
///
/// Per byte, `(x | 0x80) - (y & 0x7f)` is in `1..=255` (no borrow crosses into the next
/// byte) and its bit 7 is `x mod 128 ≥ y mod 128`; that decides when the lanes' top bits are
/// equal, and `x`'s top bit alone when they differ.
#[inline(always)]
fn ge_bytes(x: u32, y: u32) -> u32 {
    let low = (x | TOPS) - (y & !TOPS);
    ((x & !y) | (low & !(x ^ y))) & TOPS
}

/// The lanes whose bit 7 is set in `b` ([`ge_bytes`]) as `0xff` bytes, the others `0`
/// (`2^(8k+8) - 2^(8k)` a lane, wrapping at the top one).
#[inline(always)]
fn lane_mask(b: u32) -> u32 {
    (b << 1).wrapping_sub(b >> 7)
}

/// Bytewise min and max of two words of four `u8` lanes.
#[inline(always)]
fn minmax_bytes(x: u32, y: u32) -> (u32, u32) {
    let swap = (x ^ y) & lane_mask(ge_bytes(x, y));
    (x ^ swap, y ^ swap)
}

/// Bytewise min of two words of four `u8` lanes.
#[inline(always)]
fn min_bytes(x: u32, y: u32) -> u32 {
    minmax_bytes(x, y).0
}

/// Bytewise max of two words of four `u8` lanes.
#[inline(always)]
fn max_bytes(x: u32, y: u32) -> u32 {
    minmax_bytes(x, y).1
}

/// The four bytes of `s` from `at` as a little-endian word, `pad` for those past its end.
#[inline(always)]
fn load4(s: &[u8], at: usize, pad: u8) -> u32 {
    match s.get(at..at + 4) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => {
            let mut w = [pad; 4];
            for (o, &v) in w.iter_mut().zip(s.get(at..).unwrap_or(&[])) {
                *o = v;
            }
            u32::from_le_bytes(w)
        }
    }
}

/// The min and max of a tile's 16 pixels, its four rows given as little-endian words: the
/// rows bytewise ([`minmax_bytes`]), then the four columns.
#[inline(always)]
fn tile_minmax([a, b, c, d]: [u32; 4]) -> (u8, u8) {
    let (lo_ab, hi_ab) = minmax_bytes(a, b);
    let (lo_cd, hi_cd) = minmax_bytes(c, d);
    let [l0, l1, l2, l3] = min_bytes(lo_ab, lo_cd).to_le_bytes();
    let [h0, h1, h2, h3] = max_bytes(hi_ab, hi_cd).to_le_bytes();
    (l0.min(l1).min(l2.min(l3)), h0.max(h1).max(h2.max(h3)))
}

/// [`tile_minmax`] of four adjacent tiles, their four rows given as 16 bytes each: the
/// mins and the maxes as words of four lanes, tile `i` in lane `i`.
///
/// Each tile's rows bytewise, as [`tile_minmax`]; then, instead of a tile's four lanes one by
/// one, the four tiles' words at once: tiles 0 and 2 (and 1 and 3) paired by their low and
/// high halves ([`across4`]).
#[inline(always)]
fn tiles4_minmax(rows: [&[u8; 16]; 4]) -> (u32, u32) {
    let mut mn = [0u32; 4];
    let mut mx = [0u32; 4];
    for (k, (mn, mx)) in mn.iter_mut().zip(mx.iter_mut()).enumerate() {
        let [a, b, c, d] = rows.map(|r| load4(r, TILE * k, 0));
        let (lo_ab, hi_ab) = minmax_bytes(a, b);
        let (lo_cd, hi_cd) = minmax_bytes(c, d);
        (*mn, *mx) = (min_bytes(lo_ab, lo_cd), max_bytes(hi_ab, hi_cd));
    }
    (across4(mn, min_bytes), across4(mx, max_bytes))
}

/// `op` (a bytewise min or max) over the four lanes of each of four words, word `i`'s result
/// in lane `i`: lanes 0, 1 of word `i` against its lanes 2, 3 (words 0 with 2 and 1 with 3 in
/// one word, their low halves against their high halves), then the two lanes left of each
/// word against each other (the even lanes against the odd ones, interleaved so that word
/// `i` lands in lane `i`).
#[inline(always)]
fn across4(m: [u32; 4], op: impl Fn(u32, u32) -> u32) -> u32 {
    const HALF: u32 = 0x0000_ffff;
    const EVEN: u32 = 0x00ff_00ff;
    let [m0, m1, m2, m3] = m;
    let lo_hi = |a: u32, b: u32| op((a & HALF) | (b << 16), (a >> 16) | (b & !HALF));
    // Lanes 0, 1: word 0 (or 1); lanes 2, 3: word 2 (or 3).
    let (s02, s13) = (lo_hi(m0, m2), lo_hi(m1, m3));
    op(
        (s02 & EVEN) | ((s13 & EVEN) << 8),
        ((s02 >> 8) & EVEN) | (s13 & !EVEN),
    )
}

/// The bytewise min of the four bytes from `at` of three rows of tile mins, and the max of
/// those of three rows of tile maxes (past the rows' end: 255 and 0).
#[inline(always)]
fn vertical3([u, c, d]: [&[u8]; 3], [uu, cc, dd]: [&[u8]; 3], at: usize) -> (u32, u32) {
    let mn = min_bytes(
        min_bytes(load4(u, at, 255), load4(c, at, 255)),
        load4(d, at, 255),
    );
    let mx = max_bytes(
        max_bytes(load4(uu, at, 0), load4(cc, at, 0)),
        load4(dd, at, 0),
    );
    (mn, mx)
}

/// The thresholds ([`build_tiles`]) of four tiles of a row from the bytewise min and max
/// words ([`vertical3`]) of theirs (`cur`) and of the four tiles before and after them: the
/// horizontal part of the dilation, then per lane `SKIP_TILE` when `max - min < min_diff`,
/// else `min + ⌊(max - min) f⌋` with `f = fraction_q8 / 256 < 1` (below `max - min`, and
/// `(max - min) / 2` exactly at 128).
#[inline(always)]
fn thresholds4(
    prev: (u32, u32),
    cur: (u32, u32),
    next: (u32, u32),
    min_diff: u8,
    fraction_q8: u8,
) -> u32 {
    // Each lane with its left and right neighbours' lanes.
    let mn = min_bytes(
        min_bytes(cur.0, (cur.0 << 8) | (prev.0 >> 24)),
        (cur.0 >> 8) | (next.0 << 24),
    );
    let mx = max_bytes(
        max_bytes(cur.1, (cur.1 << 8) | (prev.1 >> 24)),
        (cur.1 >> 8) | (next.1 << 24),
    );
    // Every tile has its 16 pixels, so `mn ≤ mx` in its lane and `mx - mn` borrows from no
    // tile's lane (the lanes past a row's end, min 255 and max 0, borrow from those above
    // them, past the end too, and are not stored); split into 16-bit lanes, the products by
    // `f` and the sums `(mx - mn) + 256 - min_diff` (bit 8: `mx - mn ≥ min_diff`) fit.
    const EVEN: u32 = 0x00ff_00ff;
    let diff = mx.wrapping_sub(mn);
    let (even, odd) = (diff & EVEN, (diff >> 8) & EVEN);
    let f = u32::from(fraction_q8);
    let part = (((even * f) >> 8) & EVEN) | ((odd * f) & !EVEN);
    let room = (256 - u32::from(min_diff)) * 0x0001_0001;
    let wide = (((even + room) >> 8) & 0x0001_0001) | ((odd + room) & 0x0100_0100);
    // Skipped lanes are 255.
    mn.wrapping_add(part) | !(wide * 0xff)
}

/// Computes the tile thresholds into `thr` (`tw th` bytes) with the raw min/max of three tile
/// rows in `ring_min`, `ring_max` (`3 tw` bytes each). `w, h ≥ 4` and the buffers long enough
/// are the caller's checks; short buffers leave tiles skipped.
pub(crate) fn build_tiles<'t>(
    src: &Sampled<'_>,
    min_diff: u8,
    fraction_q8: u8,
    thr: &'t mut [u8],
    ring_min: &mut [u8],
    ring_max: &mut [u8],
) -> Tiles<'t> {
    let (tw, th) = (src.w / TILE, src.h / TILE);
    thr.iter_mut().for_each(|t| *t = SKIP_TILE);
    // Raw min/max of tile row `ty` into ring slot `ty % 3`.
    let raw = |ty: usize, ring_min: &mut [u8], ring_max: &mut [u8]| {
        let slot = (ty % 3) * tw;
        let (Some(mins), Some(maxs)) = (
            ring_min.get_mut(slot..slot + tw),
            ring_max.get_mut(slot..slot + tw),
        ) else {
            return;
        };
        let rows: [&[u8]; TILE] = core::array::from_fn(|dy| src.full_row(ty * TILE + dy));
        if src.d == 1 && rows.iter().all(|r| r.len() >= tw * TILE) {
            // Four tiles at once (their four rows, 16 bytes each), their mins and maxes a word
            // each into the ring; then the tiles left one by one, a word a row.
            let rows = rows.map(|r| r.get(..tw * TILE).unwrap_or(&[]));
            let [r0, r1, r2, r3] = rows.map(|r| r.as_chunks::<16>().0.iter());
            let (mins4, maxs4) = (mins.as_chunks_mut::<4>(), maxs.as_chunks_mut::<4>());
            for ((mn, mx), (((a, b), c), d)) in mins4
                .0
                .iter_mut()
                .zip(maxs4.0.iter_mut())
                .zip(r0.zip(r1).zip(r2).zip(r3))
            {
                let (lo, hi) = tiles4_minmax([a, b, c, d]);
                (*mn, *mx) = (lo.to_le_bytes(), hi.to_le_bytes());
            }
            let [r0, r1, r2, r3] = rows.map(|r| r.as_chunks::<16>().1.chunks_exact(TILE));
            for ((mn, mx), (((a, b), c), d)) in mins4
                .1
                .iter_mut()
                .zip(maxs4.1.iter_mut())
                .zip(r0.zip(r1).zip(r2).zip(r3))
            {
                (*mn, *mx) = tile_minmax([a, b, c, d].map(|p| load4(p, 0, 0)));
            }
            return;
        }
        mins.fill(255);
        maxs.fill(0);
        for row in rows {
            let mut it = row.iter().step_by(src.d.max(1));
            for (mn, mx) in mins.iter_mut().zip(maxs.iter_mut()) {
                for _ in 0..TILE {
                    if let Some(&v) = it.next() {
                        *mn = (*mn).min(v);
                        *mx = (*mx).max(v);
                    }
                }
            }
        }
    };
    if tw == 0 || th == 0 {
        return Tiles { thr, tw, th };
    }
    raw(0, ring_min, ring_max);
    let min_diff = min_diff.max(1);
    for ty in 0..th {
        if ty + 1 < th {
            raw(ty + 1, ring_min, ring_max);
        }
        let Some(out) = thr.get_mut(ty * tw..ty * tw + tw) else {
            break;
        };
        // The 3x3 dilation, four tiles a word: vertical over the (up to) three rows, then
        // horizontal. A missing row above or below is replaced by the row itself (min and max
        // take it twice); a missing tile left or right (and the padding of a last, partial
        // word) is 255 for the min and 0 for the max, which change nothing.
        let slot = |r: usize| {
            let s = (r % 3) * tw;
            Some((ring_min.get(s..s + tw)?, ring_max.get(s..s + tw)?))
        };
        let (Some((umin, umax)), Some((cmin, cmax)), Some((dmin, dmax))) = (
            slot(ty.saturating_sub(1)),
            slot(ty),
            slot(if ty + 1 < th { ty + 1 } else { ty }),
        ) else {
            break;
        };
        // Four tiles a word: the full words, then the last partial one padded (or `none`,
        // the lanes outside the row).
        let none = (u32::MAX, 0u32);
        let tail = match tw % 4 {
            0 => none,
            r => vertical3([umin, cmin, dmin], [umax, cmax, dmax], tw - r),
        };
        let word = |p: &[u8; 4]| u32::from_le_bytes(*p);
        let mut words = umin
            .as_chunks::<4>()
            .0
            .iter()
            .zip(cmin.as_chunks::<4>().0)
            .zip(dmin.as_chunks::<4>().0)
            .zip(
                umax.as_chunks::<4>()
                    .0
                    .iter()
                    .zip(cmax.as_chunks::<4>().0)
                    .zip(dmax.as_chunks::<4>().0),
            )
            .map(|(((u, c), d), ((uu, cc), dd))| {
                (
                    min_bytes(min_bytes(word(u), word(c)), word(d)),
                    max_bytes(max_bytes(word(uu), word(cc)), word(dd)),
                )
            })
            .chain(core::iter::once(tail));
        let mut prev = none;
        let mut cur = words.next().unwrap_or(none);
        let (full, rest) = out.as_chunks_mut::<4>();
        for o in full {
            let next = words.next().unwrap_or(none);
            *o = thresholds4(prev, cur, next, min_diff, fraction_q8).to_le_bytes();
            prev = cur;
            cur = next;
        }
        let t = thresholds4(prev, cur, none, min_diff, fraction_q8).to_le_bytes();
        for (o, v) in rest.iter_mut().zip(t) {
            *o = v;
        }
    }
    Tiles { thr, tw, th }
}

/// The class of a pixel of value `v` in a tile of threshold `t`: `SKIP` (2) for a skipped
/// tile (`t = 255`, where `v > t` is impossible), else white when `v > t`.
#[inline(always)]
fn class(v: u8, t: u8) -> u8 {
    u8::from(v > t) | (u8::from(t == SKIP_TILE) << 1)
}

/// The classes of the four pixels of word `v` (little-endian: the first pixel in the low
/// byte) in a tile of threshold `t`, as two 4-bit masks in bits 28..32 (bit `28 + i` for
/// pixel `i`): white (`v > t`) and skipped (`t = 255`, where `v > t` is impossible).
///
/// `v > t` bytewise is the complement of [`ge_bytes`] of `t` in every byte; the multiply
/// moves bits 7, 15, 23, 31 to 28, 29, 30, 31 (its other products land below bit 28, each on
/// a bit of its own).
#[inline(always)]
fn classes4(v: u32, t: u8) -> (u32, u32) {
    let white = ge_bytes(u32::from(t) * 0x0101_0101, v) ^ TOPS;
    let white = white.wrapping_mul(0x0020_4081) & 0xf000_0000;
    (white, if t == SKIP_TILE { 0xf000_0000 } else { 0 })
}

/// The classes of up to 8 tiles' pixels `px` (4 a tile, thresholds `ts`): white and skipped
/// masks (bit `i` for pixel `i`, [`classes4`]) and the number of pixels.
#[inline(always)]
fn classes_of(px: &[u8], ts: &[u8]) -> (u32, u32, u32) {
    let (mut white, mut skip, mut bits) = (0u32, 0u32, 0u32);
    for (p, &t) in px.chunks_exact(TILE).zip(ts).take(8) {
        let &[a, b, c, d] = p else {
            continue;
        };
        let (white4, skip4) = classes4(u32::from_le_bytes([a, b, c, d]), t);
        white = (white >> 4) | white4;
        skip = (skip >> 4) | skip4;
        bits += 4;
    }
    // The first pixel at bit 0.
    match bits {
        0 => (0, 0, 0),
        _ => (white >> (32 - bits), skip >> (32 - bits), bits),
    }
}

/// Cuts row `y` into runs of one class (module docs: the classes are recomputed from the
/// tile thresholds, one compare a pixel, never stored); `out` holds at most one per column.
/// Returns the count.
pub(crate) fn row_runs<L: Label>(
    src: &Sampled<'_>,
    tiles: &Tiles<'_>,
    y: usize,
    out: &mut [Run<L>],
) -> usize {
    let ty = (y / TILE).min(tiles.th.saturating_sub(1));
    let trow = tiles
        .thr
        .get(ty * tiles.tw..ty * tiles.tw + tiles.tw)
        .unwrap_or(&[]);
    let last = trow.last().copied().unwrap_or(SKIP_TILE);
    let row = src.full_row(y);
    let w = src.w;
    let mut cut = Cutter {
        out,
        n: 0,
        x0: 0,
        cur: u32::MAX,
    };
    let mut x = 0usize;
    if src.d == 1 && row.len() >= w {
        let full = (trow.len() * TILE).min(w);
        let (head, tail) = row.split_at(full);
        // Eight tiles (32 pixels) at a time: a bit a pixel for white and one for skipped, and
        // a run starts at each pixel whose bits differ from its left neighbour's.
        let mut before = (0u32, 0u32);
        let groups = head.chunks_exact(8 * TILE);
        let rest = groups.remainder();
        let tgroups = trow.chunks_exact(8);
        let trest = tgroups.remainder();
        for (px, ts) in groups.zip(tgroups) {
            let (white, skip, bits) = classes_of(px, ts);
            cut.starts(x, (white, skip, bits), &mut before);
            x += bits as usize;
        }
        let (white, skip, bits) = classes_of(rest, trest);
        if bits > 0 {
            cut.starts(x, (white, skip, bits), &mut before);
            x += bits as usize;
        }
        for &v in tail.get(..w - full).unwrap_or(&[]) {
            cut.class_at(x, u32::from(class(v, last)));
            x += 1;
        }
    } else {
        for (i, &v) in row.iter().step_by(src.d.max(1)).take(w).enumerate() {
            let t = trow.get(i / TILE).copied().unwrap_or(last);
            cut.class_at(x, u32::from(class(v, t)));
            x += 1;
        }
    }
    cut.close(x);
    cut.n
}

/// Cuts a row into runs of one class as the classes arrive, column by column.
struct Cutter<'a, L: Label> {
    out: &'a mut [Run<L>],
    /// Runs written.
    n: usize,
    /// First column of the open run.
    x0: usize,
    /// Class of the open run (`u32::MAX` before the first pixel).
    cur: u32,
}

impl<L: Label> Cutter<'_, L> {
    /// Column `x` has class `c`: a new run starts where the class changes.
    #[inline(always)]
    fn class_at(&mut self, x: usize, c: u32) {
        if c != self.cur {
            self.start(x, c);
        }
    }

    /// The runs that start in a group of `bits` pixels from column `x` on (bit `i` of
    /// `white` and `skip`: column `x + i`), after a pixel of bits `before` (the group's last
    /// on return); the first pixel of the row starts a run whatever its class.
    #[inline(always)]
    fn starts(&mut self, x: usize, (white, skip, bits): (u32, u32, u32), before: &mut (u32, u32)) {
        let mut starts = (white ^ ((white << 1) | before.0)) | (skip ^ ((skip << 1) | before.1));
        // Not past the group's last pixel.
        starts &= u32::MAX >> (32 - bits.clamp(1, 32));
        if x == 0 {
            starts |= 1;
        }
        while starts != 0 {
            let i = starts.trailing_zeros();
            self.start(
                x + i as usize,
                ((white >> i) & 1) | (((skip >> i) & 1) << 1),
            );
            starts &= starts - 1;
        }
        let i = bits.saturating_sub(1) & 31;
        *before = ((white >> i) & 1, (skip >> i) & 1);
    }

    /// A run of class `c` starts at column `x`.
    #[inline(always)]
    fn start(&mut self, x: usize, c: u32) {
        self.close(x);
        (self.x0, self.cur) = (x, c);
    }

    /// Ends the open run before column `x1` (dropped when `out` is full: at most one a column).
    #[inline(always)]
    fn close(&mut self, x1: usize) {
        if x1 > self.x0
            && let Some(r) = self.out.get_mut(self.n)
        {
            *r = Run {
                x0: self.x0 as u16,
                x1: x1 as u16,
                c: self.cur as u8,
                lab: L::NONE,
            };
            self.n += 1;
        }
    }
}

/// Root of `x` with path halving (`x` itself when out of range).
#[inline]
fn find<L: Label>(parent: &mut [L], mut x: L) -> L {
    loop {
        let Some(&p) = parent.get(x.index()) else {
            return x;
        };
        if p == x {
            return x;
        }
        let gp = parent.get(p.index()).copied().unwrap_or(p);
        if let Some(slot) = parent.get_mut(x.index()) {
            *slot = gp;
        }
        x = gp;
    }
}

/// Unites the sets of `a` and `b`: the larger root goes under the smaller (so every parent
/// index is below its child's, and one increasing pass flattens the forest).
#[inline]
fn union<L: Label>(parent: &mut [L], a: L, b: L) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
    if lo != hi
        && let Some(slot) = parent.get_mut(hi.index())
    {
        *slot = lo;
    }
}

/// A run of one class in a row: columns `x0..x1`, its class and its label (provisional in the
/// labelling pass; the root, or a marker for small components, in the scans; a marker for
/// skipped pixels), of label type `L` ([`Label`]: `u16` on a board, `u32` for large frames).
/// Columns are `u16`: images are at most [`MAX_SIDE`] wide.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Run<L = u16> {
    pub(crate) x0: u16,
    pub(crate) x1: u16,
    pub(crate) c: u8,
    pub(crate) lab: L,
}

impl<L: Label> Run<L> {
    /// An empty run of label type `L`.
    pub const fn empty() -> Self {
        Self {
            x0: 0,
            x1: 0,
            c: SKIP,
            lab: L::NONE,
        }
    }
}

impl Run {
    /// An empty run (`u16` labels; [`Run::empty`] for any).
    pub const EMPTY: Self = Self::empty();
}

/// The row buffers of a pass: the runs of the previous and the current row (each at most one
/// per column).
pub(crate) struct Rows<'a, L: Label> {
    pub(crate) runs: [&'a mut [Run<L>]; 2],
}

/// Outcome of the labelling pass.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Labelled {
    /// Labels used.
    pub(crate) labels: usize,
    /// Pixels skipped because the label capacity ran out.
    pub(crate) exhausted: u32,
    /// Where the run cache starts in the buffer (module docs: it runs to the buffer's end),
    /// `None` when the runs did not fit.
    pub(crate) cached: Option<usize>,
}

/// Provisional labels the run cache holds: those below 2^16 - 1.
const CACHE_LABELS: usize = 0xffff;

/// A run in the run cache: end column (14 bits: [`MAX_SIDE`]), class (2 bits), provisional
/// label (16 bits; 0 for a skipped run). No masks: `x1 ≤ MAX_SIDE < 2^14` and `c ≤ SKIP < 4`
/// for every run, and a label of `2^16` or more only in a row that leaves the cache
/// ([`label_pass`]).
#[inline(always)]
fn pack_run(x1: u16, c: u8, lab: usize) -> u32 {
    u32::from(x1) | (u32::from(c) << 14) | ((lab as u32) << 16)
}

/// What a pass does with the labels of [`label_runs`].
trait Labels<L: Label> {
    /// Whether [`Labels::join`] does anything (the scans skip the walk over the row above).
    const JOINS: bool;
    /// The label of a run no earlier run passes one to; `None`: no label left, the run is
    /// skipped.
    fn fresh(&mut self) -> Option<L>;
    /// Run label `l` touches label `o` of its class in the previous row.
    fn join(&mut self, l: L, o: L);
    /// A run of `len` pixels was skipped.
    fn skipped(&mut self, len: usize);
}

/// Labels the runs `cur` of a row from the previous row's runs `up` (module docs), in one
/// walk over the runs of `up` each run touches: columns `x0 - 1 ..= x1` for white
/// (8-connected), `x0 .. x1` for black (4-connected).
///
/// A run inherits the label of its first pixel's same-class neighbour up, then (white only)
/// up-left, up-right (the pixel left of a run has another class, so the per-pixel rule of
/// the module docs gives the whole run this label). That neighbour is the first touched
/// same-class run of `up` when it starts at most at `x0` (black) or `x0 + 1` (white):
/// consecutive runs differ in class, so of the runs holding `x0 - 1, x0, x0 + 1` at most
/// the two outer ones are white, and the rule's order then picks the left one. Otherwise the
/// run takes a fresh label; every further touched same-class run is joined to it.
#[inline]
fn label_runs<L: Label, B: Labels<L>>(cur: &mut [Run<L>], up: &[Run<L>], labels: &mut B) {
    let mut j = 0;
    for r in cur.iter_mut() {
        if r.c == SKIP {
            continue;
        }
        // White reaches one column further on each side.
        let wide = usize::from(r.c == WHITE);
        let (x0, x1) = (usize::from(r.x0), usize::from(r.x1));
        // The first run of `up` touched or right of it (`x0` grows from run to run).
        while up.get(j).is_some_and(|o| usize::from(o.x1) + wide <= x0) {
            j += 1;
        }
        let (reach, end) = (x0 + wide, x1 + wide);
        let mut l = L::NONE;
        let mut last = L::NONE;
        for o in up.get(j..).unwrap_or(&[]) {
            if usize::from(o.x0) >= end {
                break;
            }
            if o.c != r.c {
                continue;
            }
            if l == L::NONE {
                if usize::from(o.x0) <= reach {
                    (l, last) = (o.lab, o.lab);
                    if !B::JOINS {
                        break;
                    }
                    continue;
                }
                let Some(n) = labels.fresh() else {
                    break;
                };
                (l, last) = (n, n);
                if !B::JOINS {
                    break;
                }
            }
            if o.lab != last && o.lab != L::NONE {
                labels.join(l, o.lab);
                last = o.lab;
            }
        }
        if l == L::NONE {
            // No touched run passed a label and none was fresh yet (or none was left).
            match labels.fresh() {
                Some(n) => l = n,
                None => {
                    r.c = SKIP;
                    labels.skipped(x1 - x0);
                    continue;
                }
            }
        }
        r.lab = l;
    }
}

/// [`label_runs`] for the labelling pass, with the row's bookkeeping in the same walk: the
/// same labels and the same sets (a fresh label joined to a run's set is put under its
/// root at once, which [`union`] would do), each run's pixels added to its label's count
/// (saturating) and its run cache word ([`pack_run`]) written to `words` (when there is one).
///
/// The walk over `up` resumes where the last one ended, less two runs: `up` and `cur` are
/// sorted and disjoint, so with `k` past a touched run every run before `k - 2` ends at least
/// two columns before the last run's end, left of anything the next run touches.
#[inline(always)]
fn label_row<L: Label>(
    cur: &mut [Run<L>],
    up: &[Run<L>],
    uf: &mut UnionFind<'_, L>,
    words: &mut [u32],
) {
    let mut j = 0;
    // The same walk with and without the cache words (no per-run test of which).
    if words.len() == cur.len() {
        for (r, w) in cur.iter_mut().zip(words) {
            *w = label_one(r, up, &mut j, uf);
        }
    } else {
        for r in cur.iter_mut() {
            label_one(r, up, &mut j, uf);
        }
    }
}

/// One run of [`label_row`]: labels `r` (or skips it when no label is left), adds its pixel
/// count and returns its cache word ([`pack_run`]); `j` is where the walk over `up` resumes.
#[inline(always)]
fn label_one<L: Label>(
    r: &mut Run<L>,
    up: &[Run<L>],
    j: &mut usize,
    uf: &mut UnionFind<'_, L>,
) -> u32 {
    let (x0, x1, c) = (usize::from(r.x0), usize::from(r.x1), r.c);
    if c == SKIP {
        return pack_run(r.x1, SKIP, 0);
    }
    // White reaches one column further on each side.
    let wide = usize::from(c == WHITE);
    // The walk holds the runs of `up` not passed yet as a slice (a pointer stepping over
    // them, not an index into `up`).
    let mut rest = up.get(*j..).unwrap_or(&[]);
    while let [o, tail @ ..] = rest
        && usize::from(o.x1) + wide <= x0
    {
        rest = tail;
    }
    let (reach, end) = (x0 + wide, x1 + wide);
    // The first touched run of the class.
    let mut first = None;
    while let [o, tail @ ..] = rest
        && usize::from(o.x0) < end
    {
        rest = tail;
        if o.c == c {
            first = Some(o);
            break;
        }
    }
    let l = match first {
        Some(o) if usize::from(o.x0) <= reach => Some((o.lab, o.lab)),
        Some(o) => uf.fresh_under(o.lab).map(|n| (n, o.lab)),
        None => uf.fresh().map(|n| (n, n)),
    };
    let Some((l, mut last)) = l else {
        r.c = SKIP;
        uf.skipped(x1 - x0);
        return pack_run(r.x1, SKIP, 0);
    };
    // Every further touched run of the class joins its set.
    if first.is_some() {
        while let [o, tail @ ..] = rest
            && usize::from(o.x0) < end
        {
            rest = tail;
            if o.c == c && o.lab != last {
                union(uf.parent, l, o.lab);
                last = o.lab;
            }
        }
    }
    // Any start at or before the next run's first touched run gives the same walk
    // ([`label_row`]): two runs before the first run not passed is one, even below `j`.
    *j = (up.len() - rest.len()).saturating_sub(2);
    r.lab = l;
    if let Some(s) = uf.size.get_mut(l.index()) {
        *s = s.saturating_add((x1 - x0).min(255) as u8);
    }
    pack_run(r.x1, c, l.index())
}

/// The runs of the previous and the current row for row `y`.
fn run_rows<'r, L: Label>(
    runs: &'r mut [&mut [Run<L>]; 2],
    y: usize,
) -> (&'r [Run<L>], &'r mut [Run<L>]) {
    let [r0, r1] = runs;
    if y.is_multiple_of(2) {
        (&**r1, &mut **r0)
    } else {
        (&**r0, &mut **r1)
    }
}

/// The labelling pass's [`Labels`]: new labels from a counter, unions.
struct UnionFind<'a, L: Label> {
    parent: &'a mut [L],
    size: &'a mut [u8],
    next: usize,
    cap: usize,
    exhausted: u32,
}

impl<L: Label> UnionFind<'_, L> {
    /// A fresh label put under the root of `o` at once (its set joined with `o`'s, as
    /// [`union`] of the new root and `o` would); `None` when no label is left.
    #[inline(always)]
    fn fresh_under(&mut self, o: L) -> Option<L> {
        let n = self.fresh()?;
        let root = find(self.parent, o);
        if let Some(p) = self.parent.get_mut(n.index()) {
            *p = root;
        }
        Some(n)
    }
}

impl<L: Label> Labels<L> for UnionFind<'_, L> {
    const JOINS: bool = true;
    fn fresh(&mut self) -> Option<L> {
        if self.next >= self.cap {
            return None;
        }
        let l = L::from_index(self.next);
        if let (Some(p), Some(s)) = (self.parent.get_mut(self.next), self.size.get_mut(self.next)) {
            *p = l;
            *s = 0;
        }
        self.next += 1;
        Some(l)
    }
    #[inline]
    fn join(&mut self, l: L, o: L) {
        union(self.parent, l, o);
    }
    fn skipped(&mut self, len: usize) {
        self.exhausted = self.exhausted.saturating_add(len as u32);
    }
}

/// The scans' [`Labels`]: the same counter, read as roots (or [`Label::SMALL`]) of the flattened
/// forest.
struct Roots<'a, L: Label> {
    parent: &'a [L],
    size: &'a [u8],
    next: usize,
    labels: usize,
}

impl<L: Label> Labels<L> for Roots<'_, L> {
    const JOINS: bool = false;
    fn fresh(&mut self) -> Option<L> {
        if self.next >= self.labels {
            return None;
        }
        let root = self.parent.get(self.next).copied().unwrap_or(L::NONE);
        self.next += 1;
        let big = self.size.get(root.index()).copied().unwrap_or(0) >= MIN_COMPONENT;
        Some(if big { root } else { L::SMALL })
    }
    #[inline]
    fn join(&mut self, _: L, _: L) {}
    fn skipped(&mut self, _: usize) {}
}

/// The labelling pass (module docs), run by run: unions into `parent`, pixel counts into
/// `size` (saturating), then flattens `parent` to roots and sums the counts into the roots.
/// Capacity: `min(parent.len(), size.len(), L::MAX_LABELS)` labels; a run that needs a new label
/// when none is left is skipped (in every pass alike). The rows' runs go into the run cache
/// `cache` (module docs) when they fit.
pub(crate) fn label_pass<L: Label>(
    src: &Sampled<'_>,
    tiles: &Tiles<'_>,
    rows: &mut Rows<'_, L>,
    parent: &mut [L],
    size: &mut [u8],
    cache: &mut [u32],
) -> Labelled {
    let cap = parent.len().min(size.len()).min(L::MAX_LABELS);
    let mut out = Labelled::default();
    let mut next: usize = 0;
    let mut cached = Some(cache.len());
    let mut n_up = 0;
    for y in 0..src.h {
        let (up, cur) = run_rows(&mut rows.runs, y);
        let n = row_runs(src, tiles, y, cur);
        let up = up.get(..n_up).unwrap_or(&[]);
        let cur = cur.get_mut(..n).unwrap_or(&mut []);
        // The row's words of the run cache: a count, then below it a word a run. Labels
        // grow from 0, so every label of the row fits when `next` does after it (checked
        // below; words written for a row that then does not fit are left unused).
        let mut words: &mut [u32] = &mut [];
        let mut head = None;
        if let Some(top) = cached {
            match top
                .checked_sub(1 + n)
                .and_then(|at| cache.get_mut(at..top))
                .and_then(|c| c.split_last_mut())
            {
                Some((h, row)) => {
                    head = Some(h);
                    words = row;
                }
                None => cached = None,
            }
        }
        let mut uf = UnionFind {
            parent: &mut *parent,
            size: &mut *size,
            next,
            cap,
            exhausted: out.exhausted,
        };
        label_row(cur, up, &mut uf, words);
        next = uf.next;
        out.exhausted = uf.exhausted;
        if let (Some(top), Some(h)) = (cached, head) {
            cached = top.checked_sub(1 + n).filter(|_| next <= CACHE_LABELS);
            if cached.is_some() {
                *h = n as u32;
            }
        }
        n_up = n;
    }
    out.labels = next;
    out.cached = cached;
    // Flatten (parents precede children) and total the counts into the roots.
    for i in 0..next {
        let p = parent.get(i).copied().unwrap_or(L::from_index(i));
        let root = parent.get(p.index()).copied().unwrap_or(p);
        if let Some(slot) = parent.get_mut(i) {
            *slot = root;
        }
        if root.index() != i {
            let add = size.get(i).copied().unwrap_or(0);
            if let Some(s) = size.get_mut(root.index()) {
                *s = s.saturating_add(add);
            }
        }
    }
    out
}

/// Packs a boundary point: doubled coordinates and the signs of the direction to white.
#[inline]
pub(crate) fn pack(x2: usize, y2: usize, gx: i32, gy: i32) -> u32 {
    (x2 as u32 & 0x3fff)
        | (((gx + 1) as u32 & 3) << 14)
        | ((y2 as u32 & 0x3fff) << 16)
        | (((gy + 1) as u32 & 3) << 30)
}

/// The fields of [`pack`]: `(x2, y2, gx, gy)`.
#[inline]
pub(crate) fn unpack(p: u32) -> (i32, i32, i32, i32) {
    (
        (p & 0x3fff) as i32,
        ((p >> 16) & 0x3fff) as i32,
        ((p >> 14) & 3) as i32 - 1,
        ((p >> 30) & 3) as i32 - 1,
    )
}

/// The points one pair of overlapping runs of opposite classes gives ([`boundary_scan`]):
/// upper run in row `y`, lower run in row `y + 1`, all points at doubled row `y2 = 2 y + 1`
/// with `gy = s` towards white. By upper pixel column `x`: below `x ∈ below`, below-right
/// `x ∈ right`, below-left `x = left[i]`, `i < nleft` (half-open ranges, possibly empty).
#[derive(Clone, Copy)]
pub(crate) struct PairPoints {
    pub(crate) y2: usize,
    pub(crate) s: i32,
    pub(crate) below: (usize, usize),
    pub(crate) right: (usize, usize),
    pub(crate) left: [usize; 2],
    pub(crate) nleft: usize,
}

impl PairPoints {
    /// The number of points.
    #[inline(always)]
    pub(crate) fn count(&self) -> usize {
        self.below.1.saturating_sub(self.below.0)
            + self.right.1.saturating_sub(self.right.0)
            + self.nleft
    }
}

/// Where a boundary scan sends its points: runs of points along a row, single points, and
/// the points of a pair of runs ([`PairPoints`]), all of one cluster. `buf` is the buffer the
/// scan was given (the point buffer, which may hold the run cache too: a sink that stores
/// points there writes only where the scan has read).
pub(crate) trait Sink<K: Copy = u32> {
    /// `count` points `(x2 + 2i, y2)`, `i = 0..count`, of cluster `key`, all with direction
    /// `(gx, gy)` towards white.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &mut self,
        buf: &mut [u32],
        key: K,
        x2: usize,
        y2: usize,
        count: usize,
        gx: i32,
        gy: i32,
    );
    /// One point.
    fn point(&mut self, buf: &mut [u32], key: K, x2: usize, y2: usize, gx: i32, gy: i32) {
        self.run(buf, key, x2, y2, 1, gx, gy);
    }
    /// The points of a pair of runs (`p.count() ≥ 1`), in this order: below (direction
    /// `(0, s)`), below-right (`(s, s)`), below-left (`(-s, s)`).
    fn pair(&mut self, buf: &mut [u32], key: K, p: &PairPoints) {
        let (y2, s) = (p.y2, p.s);
        if p.below.1 > p.below.0 {
            self.run(buf, key, 2 * p.below.0, y2, p.below.1 - p.below.0, 0, s);
        }
        if p.right.1 > p.right.0 {
            self.run(buf, key, 2 * p.right.0 + 1, y2, p.right.1 - p.right.0, s, s);
        }
        for &x in p.left.iter().take(p.nleft) {
            self.point(buf, key, 2 * x - 1, y2, -s, s);
        }
    }
}

/// A run's label when it counts for boundaries (in a large component; the scans give
/// skipped runs [`Label::NONE`]).
#[inline(always)]
fn valid<L: Label>(r: &Run<L>) -> bool {
    r.lab < L::SMALL
}

/// The cluster key of a black/white pair and the sign `s` of the direction from `a` to `b`
/// towards white (`+1` when `a` is black). Both labels are read whatever the classes, and
/// the halves exchanged when `a` is white: written as two keys, the compiler chose between
/// the runs' addresses before reading them.
#[inline(always)]
fn key_of<L: Label>(a: &Run<L>, b: &Run<L>) -> (L::Key, i32) {
    let key = L::key(a.lab, b.lab);
    if a.c == BLACK {
        (key, 1)
    } else {
        (key.swapped(), -1)
    }
}

/// A boundary scan (module docs): re-derives the runs and labels of [`label_pass`] (which
/// must have run on the same frame; `parent` flattened, `size[root] ≥ MIN_COMPONENT` marking
/// the components that count) and sends every boundary point to `sink`,
/// `key = L::key(black root, white root)`.
///
/// The points are AprilTag's: for each pixel `p = (x, y)` with `1 ≤ x ≤ w - 2`,
/// `1 ≤ y ≤ h - 2`, its neighbour right, below and below-right when of the opposite class,
/// and below-left unless the below-right pair of `(x - 1, y)` gave the same point. They are
/// found run against run: a pair of overlapping runs of opposite classes gives three runs of
/// points (below, below-right, below-left) and two rows give `O(runs)` work, not `O(pixels)`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn boundary_scan<L: Label>(
    src: &Sampled<'_>,
    tiles: &Tiles<'_>,
    rows: &mut Rows<'_, L>,
    parent: &[L],
    size: &[u8],
    labels: usize,
    buf: &mut [u32],
    sink: &mut impl Sink<L::Key>,
) {
    let mut next: usize = 0;
    let w = src.w;
    let mut n_up = 0;
    for y in 0..src.h {
        let (up, cur) = run_rows(&mut rows.runs, y);
        let n = row_runs(src, tiles, y, cur);
        let up = up.get(..n_up).unwrap_or(&[]);
        let cur = cur.get_mut(..n).unwrap_or(&mut []);
        let mut roots = Roots {
            parent,
            size,
            next,
            labels,
        };
        label_runs(cur, up, &mut roots);
        next = roots.next;
        n_up = n;
        // The upper row y - 1 must be in 1..h - 1 (AprilTag's scan domain).
        if y >= 2 && w >= 3 {
            pairs::<L, false>(up, cur, y - 1, w, buf, sink);
        }
    }
}

/// [`boundary_scan`] from the run cache `cache` of [`label_pass`] (module docs: the buffer
/// from where the cache starts, `buf[at..]`), for the
/// points whose upper pixel is in rows `ylo..=yhi` only: the same points in the same order
/// (all of them for `(0, h)`), without re-deriving the rows. `(w, h)` is the sampled
/// image's size. Only the runs that count (large components) are kept in `rows`: [`pairs`]
/// takes a row with gaps. The points go to `sink` with `buf`: once the points of upper row
/// `y` are sent, the cache's rows `0..=y + 1` have been read and are not read again
/// ([`cache_rows_end`]). With `MARKED` the labels of small components have parent
/// [`Label::SMALL`] ([`mark_small`]) and `size` is not read: a run counts when its root is a
/// label.
#[allow(clippy::too_many_arguments)]
pub(crate) fn boundary_scan_cached<L: Label, const MARKED: bool>(
    buf: &mut [u32],
    at: usize,
    (w, h): (usize, usize),
    (ylo, yhi): (usize, usize),
    rows: &mut Rows<'_, L>,
    parent: &[L],
    size: &[u8],
    sink: &mut impl Sink<L::Key>,
) {
    let mut top = buf.len();
    let mut n_up = 0;
    for y in 0..h.min(yhi.saturating_add(2)) {
        let Some(&n) = top
            .checked_sub(1)
            .filter(|&i| i >= at)
            .and_then(|i| buf.get(i))
        else {
            return;
        };
        let Some(start) = top.checked_sub(1 + n as usize).filter(|&s| s >= at) else {
            return;
        };
        let end = top - 1;
        top = start;
        // Row y is the upper row of the pairs of y (from ylo on) or the lower of y - 1.
        if y < ylo {
            continue;
        }
        let (up, cur) = run_rows(&mut rows.runs, y);
        let words = buf.get(start..end).unwrap_or(&[]);
        let mut x0 = 0u16;
        let mut k = 0;
        for &word in words {
            let (x1, c) = ((word & 0x3fff) as u16, ((word >> 14) & 3) as u8);
            // The scans' label (`Roots`): the root of a large component; others are left out.
            if c != SKIP {
                let root = parent
                    .get((word >> 16) as usize)
                    .copied()
                    .unwrap_or(L::NONE);
                let counts = if MARKED {
                    root < L::SMALL
                } else {
                    size.get(root.index()).copied().unwrap_or(0) >= MIN_COMPONENT
                };
                if counts && let Some(r) = cur.get_mut(k) {
                    *r = Run {
                        x0,
                        x1,
                        c,
                        lab: root,
                    };
                    k += 1;
                }
            }
            x0 = x1;
        }
        let up = up.get(..n_up).unwrap_or(&[]);
        let cur = cur.get(..k).unwrap_or(&[]);
        if y > ylo && y >= 2 && w >= 3 {
            pairs::<L, true>(up, cur, y - 1, w, buf, sink);
        }
        n_up = k;
    }
}

/// Marks the labels of components below [`MIN_COMPONENT`] pixels: their parent (a root, in
/// the flattened forest of [`label_pass`]) becomes [`Label::SMALL`], so that one look-up tells
/// a scan whether a run counts. The scans read the same either way: `size` has no entry at
/// `SMALL` (at most [`Label::MAX_LABELS`] = `SMALL` labels), which reads as a small count.
pub(crate) fn mark_small<L: Label>(parent: &mut [L], size: &[u8]) {
    for p in parent.iter_mut() {
        if size.get(p.index()).copied().unwrap_or(0) < MIN_COMPONENT {
            *p = L::SMALL;
        }
    }
}

/// Where the run cache's rows `0..rows` begin in `buf` (the cache from `at` on, module docs):
/// the lowest word of those rows, `buf.len()` for none; `None` when the cache has fewer.
pub(crate) fn cache_rows_end(buf: &[u32], at: usize, rows: usize) -> Option<usize> {
    let mut top = buf.len();
    for _ in 0..rows {
        let n = *buf.get(top.checked_sub(1).filter(|&i| i >= at)?)?;
        top = top.checked_sub(1 + n as usize).filter(|&s| s >= at)?;
    }
    Some(top)
}

/// The boundary points with upper pixel in row `y` (runs `up`) and lower in `y + 1` (runs
/// `lo`), upper pixels in columns `1..w - 1`. A row may leave out runs that do not count
/// (invalid: skipped or small): a gap between two runs is such a run. With `ALL_COUNT` the
/// rows hold only runs that count (the cached scan's), so no run's label is tested, and two
/// adjacent runs are of opposite classes (runs are maximal and neither is skipped).
///
/// Never inlined: in its row loop the scan's registers would be spilled around it.
#[inline(never)]
fn pairs<L: Label, const ALL_COUNT: bool>(
    up: &[Run<L>],
    lo: &[Run<L>],
    y: usize,
    w: usize,
    buf: &mut [u32],
    sink: &mut impl Sink<L::Key>,
) {
    let (y2, xmin, xmax) = (2 * y, 1usize, w - 1);
    // Right neighbours: one point at each boundary between two runs of the upper row (the
    // boundary column is below `b.x1 <= w`, so `x < w - 1`).
    for pair in up.windows(2) {
        let (Some(a), Some(b)) = (pair.first(), pair.get(1)) else {
            continue;
        };
        let x = usize::from(a.x1) - 1;
        let opposite = ALL_COUNT || (a.c != b.c && valid(a) && valid(b));
        if a.x1 == b.x0 && opposite && x >= xmin {
            let (key, s) = key_of(a, b);
            sink.point(buf, key, 2 * x + 1, y2, s, 0);
        }
    }
    // Run against run: lower runs within one column of each upper run.
    let mut j0 = 0;
    // Where the previous upper run ends when it counts (`usize::MAX` otherwise).
    let mut end = usize::MAX;
    for u in up {
        let (ux0, ux1) = (usize::from(u.x0), usize::from(u.x1));
        let counts = ALL_COUNT || valid(u);
        let left_end = core::mem::replace(&mut end, if counts { ux1 } else { usize::MAX });
        while lo.get(j0).is_some_and(|l| usize::from(l.x1) < ux0) {
            j0 += 1;
        }
        // Every point of u has its upper pixel in u's columns within the scan's.
        let (cx0, cx1) = (ux0.max(xmin), ux1.min(xmax));
        if !counts || cx0 >= cx1 {
            continue;
        }
        let mut j = j0;
        while let Some(l) = lo.get(j) {
            let (lx0, lx1) = (usize::from(l.x0), usize::from(l.x1));
            if lx0 > ux1 {
                break;
            }
            j += 1;
            if l.c == u.c || !(ALL_COUNT || valid(l)) {
                continue;
            }
            // The runs are within one column: l ends where u starts, starts where u ends, or
            // they overlap. Below-left points: x in u, x - 1 in l, unless x ≥ 2 and
            // (x - 1, y), (x, y + 1) are an opposite pair that counts (its below-right point
            // is the same).
            if lx1 == ux0 {
                // Touching at u's start: only the below-left point of x = ux0 (in the scan when
                // ux0 ≥ 1). (ux0 - 1, y) and (ux0, y + 1) are the run left of u and the run
                // right of l, of opposite classes: no point when both count. (Written with
                // lx1 = ux0: from u's columns, the compiler computed these for every upper run.)
                let left = left_end == lx1;
                let right = lo
                    .get(j)
                    .is_some_and(|q| q.x0 == l.x1 && (ALL_COUNT || valid(q)));
                // Mostly no point: the key only when there is one.
                if lx1 == 1 || (lx1 >= 2 && !(left && right)) {
                    let (key, s) = key_of(u, l);
                    sink.point(buf, key, 2 * lx1 - 1, y2 + 1, -s, s);
                }
                continue;
            }
            if lx0 == ux1 {
                // Touching at u's end: only the below-right point of x = ux1 - 1 (in the scan
                // when ux1 ≤ w - 1; x ≥ cx0 as cx0 < cx1). Written with lx0 = ux1, as above.
                if lx0 <= xmax {
                    let (key, s) = key_of(u, l);
                    sink.point(buf, key, 2 * lx0 - 1, y2 + 1, s, s);
                }
                continue;
            }
            let (key, s) = key_of(u, l);
            // They overlap.
            let mut p = PairPoints {
                y2: y2 + 1,
                s,
                // Below: x in u and l.
                below: (cx0.max(lx0), cx1.min(lx1)),
                // Below-right: x in u, x + 1 in l.
                right: (cx0.max(lx0.saturating_sub(1)), cx1.min(lx1 - 1)),
                left: [0; 2],
                nleft: 0,
            };
            // Below-left: inside the overlap (ux0 < x < lx1) (x - 1, y), (x, y + 1) are u and
            // l: no point. At x = lx1 > ux0 they are u and the run right of l, of u's class or
            // not counting: a point; the same at x = ux0 < lx1 (the run left of u and l). So
            // of the range [a, b) only a (when it is 1, ux0 or lx1) and lx1 give points.
            let (a, b) = (cx0.max(lx0 + 1), cx1.min(lx1 + 1));
            if a < b {
                if a < 2 || a == ux0 || a == lx1 {
                    p.left = [a, 0];
                    p.nleft = 1;
                }
                if lx1 > a && lx1 < b {
                    if let Some(slot) = p.left.get_mut(p.nleft) {
                        *slot = lx1;
                    }
                    p.nleft += 1;
                }
            }
            if p.count() > 0 {
                sink.pair(buf, key, &p);
            }
        }
    }
}
