//! The per-pixel stages: decimation, adaptive threshold, connected components and the
//! black/white boundary points, all in integers and caller buffers.
//!
//! **Threshold** (AprilTag's `threshold`): the image is cut into 4x4 tiles; each tile's min and
//! max are dilated over its 3x3 tile neighbourhood; a pixel of a tile whose dilated
//! `max - min < min_white_black_diff` is *skipped* (no edge can be there), others are white
//! when `v > min + (max - min) / 2`, black otherwise. Partial tiles at the right and bottom
//! use the last full tile. Storage: one byte per tile (the threshold, 255 = skipped) and a ring
//! of three tile rows of raw min/max; the thresholded image itself is never stored, each pass
//! recomputes a row (one compare a pixel).
//!
//! **Components** (AprilTag's union-find, 8 bytes a pixel there): white pixels are 8-connected,
//! black ones 4-connected. One raster pass gives every pixel a *provisional label*: that of
//! its first same-class neighbour among left, up (and for white up-left, up-right), or a new
//! one; the other same-class neighbours are united with it (union by smaller index, path
//! halving). Only the labels are stored (a `u16` parent and a saturating `u8` pixel count
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

/// A label value for "no component": a skipped pixel.
pub(crate) const NONE: u16 = u16::MAX;
/// A label value for a component below [`MIN_COMPONENT`] pixels (boundary scans only).
pub(crate) const SMALL: u16 = u16::MAX - 1;
/// Most labels a frame can use: every `u16` but the two markers.
pub const MAX_LABELS: usize = SMALL as usize;

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
    fn full_row(&self, y: usize) -> &'a [u8] {
        self.img.row(y.saturating_mul(self.d)).unwrap_or(&[])
    }

    /// Pixel `(x, y)` of the sampled image, 0 outside.
    #[inline]
    pub(crate) fn get(&self, x: usize, y: usize) -> u8 {
        self.full_row(y)
            .get(x.saturating_mul(self.d))
            .copied()
            .unwrap_or(0)
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

/// Computes the tile thresholds into `thr` (`tw th` bytes) with the raw min/max of three tile
/// rows in `ring_min`, `ring_max` (`3 tw` bytes each). `w, h ≥ 4` and the buffers long enough
/// are the caller's checks; short buffers leave tiles skipped.
pub(crate) fn build_tiles<'t>(
    src: &Sampled<'_>,
    min_diff: u8,
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
        mins.fill(255);
        maxs.fill(0);
        for dy in 0..TILE {
            let row = src.full_row(ty * TILE + dy);
            let d = src.d;
            let mut it = row.iter().step_by(d);
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
    for ty in 0..th {
        if ty + 1 < th {
            raw(ty + 1, ring_min, ring_max);
        }
        let rows = [ty.checked_sub(1), Some(ty), (ty + 1 < th).then_some(ty + 1)];
        let Some(out) = thr.get_mut(ty * tw..ty * tw + tw) else {
            break;
        };
        for (tx, t) in out.iter_mut().enumerate() {
            let (mut mn, mut mx) = (255u8, 0u8);
            for r in rows.iter().flatten() {
                let slot = (r % 3) * tw;
                for x in tx.saturating_sub(1)..(tx + 2).min(tw) {
                    mn = mn.min(ring_min.get(slot + x).copied().unwrap_or(255));
                    mx = mx.max(ring_max.get(slot + x).copied().unwrap_or(0));
                }
            }
            *t = if mx.saturating_sub(mn) < min_diff.max(1) {
                SKIP_TILE
            } else {
                mn + (mx - mn) / 2
            };
        }
    }
    Tiles { thr, tw, th }
}

/// The classes of row `y` into `out` (`w` entries).
#[inline]
pub(crate) fn class_row(src: &Sampled<'_>, tiles: &Tiles<'_>, y: usize, out: &mut [u8]) {
    let ty = (y / TILE).min(tiles.th.saturating_sub(1));
    let trow = tiles
        .thr
        .get(ty * tiles.tw..ty * tiles.tw + tiles.tw)
        .unwrap_or(&[]);
    let last = trow.last().copied().unwrap_or(SKIP_TILE);
    let row = src.full_row(y);
    let mut px = row.iter().step_by(src.d);
    for (x4, chunk) in out.chunks_mut(TILE).enumerate() {
        let t = trow.get(x4).copied().unwrap_or(last);
        for c in chunk.iter_mut() {
            let v = px.next().copied().unwrap_or(0);
            *c = if t == SKIP_TILE {
                SKIP
            } else if v > t {
                WHITE
            } else {
                BLACK
            };
        }
    }
}

/// Root of `x` with path halving (`x` itself when out of range).
#[inline]
fn find(parent: &mut [u16], mut x: u16) -> u16 {
    loop {
        let Some(&p) = parent.get(usize::from(x)) else {
            return x;
        };
        if p == x {
            return x;
        }
        let gp = parent.get(usize::from(p)).copied().unwrap_or(p);
        if let Some(slot) = parent.get_mut(usize::from(x)) {
            *slot = gp;
        }
        x = gp;
    }
}

/// Unites the sets of `a` and `b`: the larger root goes under the smaller (so every parent
/// index is below its child's, and one increasing pass flattens the forest).
#[inline]
fn union(parent: &mut [u16], a: u16, b: u16) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
    if lo != hi
        && let Some(slot) = parent.get_mut(usize::from(hi))
    {
        *slot = lo;
    }
}

/// The two row buffers of a pass: classes and labels of the previous and current row.
pub(crate) struct Rows<'a> {
    pub(crate) cls: [&'a mut [u8]; 2],
    pub(crate) lab: [&'a mut [u16]; 2],
}

/// The same-class neighbours of pixel `x` (class `c`) that a label can come from, in the
/// order the rule of the module docs takes them: left, up, up-left, up-right (the last two for
/// white only). Each is `NONE` when absent.
#[inline]
fn neighbours(
    c: u8,
    x: usize,
    cur_cls: &[u8],
    cur_lab: &[u16],
    prev: Option<(&[u8], &[u16])>,
) -> [u16; 4] {
    let at = |cls: &[u8], lab: &[u16], i: Option<usize>| -> u16 {
        match i {
            Some(i) if cls.get(i) == Some(&c) => lab.get(i).copied().unwrap_or(NONE),
            _ => NONE,
        }
    };
    let left = at(cur_cls, cur_lab, x.checked_sub(1));
    let Some((pc, pl)) = prev else {
        return [left, NONE, NONE, NONE];
    };
    let up = at(pc, pl, Some(x));
    if c == WHITE {
        [
            left,
            up,
            at(pc, pl, x.checked_sub(1)),
            at(pc, pl, Some(x + 1)),
        ]
    } else {
        [left, up, NONE, NONE]
    }
}

/// Outcome of the labelling pass.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Labelled {
    /// Labels used.
    pub(crate) labels: usize,
    /// Pixels skipped because the label capacity ran out.
    pub(crate) exhausted: u32,
}

/// The labelling pass (module docs): unions into `parent`, pixel counts into `size`
/// (saturating), then flattens `parent` to roots and sums the counts into the roots.
/// Capacity: `min(parent.len(), size.len(), MAX_LABELS)` labels.
pub(crate) fn label_pass(
    src: &Sampled<'_>,
    tiles: &Tiles<'_>,
    rows: &mut Rows<'_>,
    parent: &mut [u16],
    size: &mut [u8],
) -> Labelled {
    let cap = parent.len().min(size.len()).min(MAX_LABELS);
    let mut out = Labelled::default();
    let mut next: usize = 0;
    for y in 0..src.h {
        let [c0, c1] = &mut rows.cls;
        let [l0, l1] = &mut rows.lab;
        let (prev_cls, cur_cls, prev_lab, cur_lab) = if y % 2 == 0 {
            (&**c1, &mut **c0, &**l1, &mut **l0)
        } else {
            (&**c0, &mut **c1, &**l0, &mut **l1)
        };
        class_row(src, tiles, y, cur_cls);
        // The last union made: along runs the same pair comes up pixel after pixel.
        let mut last = (NONE, NONE);
        for x in 0..src.w {
            let c = cur_cls.get(x).copied().unwrap_or(SKIP);
            if c == SKIP {
                if let Some(l) = cur_lab.get_mut(x) {
                    *l = NONE;
                }
                continue;
            }
            let prev = (y > 0).then_some((prev_cls, prev_lab));
            let nb = neighbours(c, x, cur_cls, cur_lab, prev);
            let mut l = nb.iter().copied().find(|&v| v != NONE).unwrap_or(NONE);
            if l == NONE {
                if next < cap {
                    l = next as u16;
                    if let (Some(p), Some(s)) = (parent.get_mut(next), size.get_mut(next)) {
                        *p = l;
                        *s = 0;
                    }
                    next += 1;
                } else {
                    if let Some(cc) = cur_cls.get_mut(x) {
                        *cc = SKIP;
                    }
                    if let Some(cl) = cur_lab.get_mut(x) {
                        *cl = NONE;
                    }
                    out.exhausted = out.exhausted.saturating_add(1);
                    continue;
                }
            }
            if let Some(s) = size.get_mut(usize::from(l)) {
                *s = s.saturating_add(1);
            }
            for &o in &nb[1..] {
                if o != NONE && o != l && (l, o) != last {
                    union(parent, l, o);
                    last = (l, o);
                }
            }
            if let Some(cl) = cur_lab.get_mut(x) {
                *cl = l;
            }
        }
    }
    out.labels = next;
    // Flatten (parents precede children) and total the counts into the roots.
    for i in 0..next {
        let p = parent.get(i).copied().unwrap_or(i as u16);
        let root = parent.get(usize::from(p)).copied().unwrap_or(p);
        if let Some(slot) = parent.get_mut(i) {
            *slot = root;
        }
        if usize::from(root) != i {
            let add = size.get(i).copied().unwrap_or(0);
            if let Some(s) = size.get_mut(usize::from(root)) {
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

/// A boundary scan (module docs): re-derives the labels of [`label_pass`] (which must have run
/// on the same frame with the same buffers' `parent`/`size`) and calls `emit(key, point)` for
/// every boundary point, `key = black root << 16 | white root`.
pub(crate) fn boundary_scan(
    src: &Sampled<'_>,
    tiles: &Tiles<'_>,
    rows: &mut Rows<'_>,
    parent: &[u16],
    size: &[u8],
    labels: usize,
    mut emit: impl FnMut(u32, u32),
) {
    let mut next: usize = 0;
    for y in 0..src.h {
        let [c0, c1] = &mut rows.cls;
        let [l0, l1] = &mut rows.lab;
        let (prev_cls, cur_cls, prev_lab, cur_lab) = if y % 2 == 0 {
            (&**c1, &mut **c0, &**l1, &mut **l0)
        } else {
            (&**c0, &mut **c1, &**l0, &mut **l1)
        };
        class_row(src, tiles, y, cur_cls);
        for x in 0..src.w {
            let c = cur_cls.get(x).copied().unwrap_or(SKIP);
            if c == SKIP {
                if let Some(l) = cur_lab.get_mut(x) {
                    *l = NONE;
                }
                continue;
            }
            let prev = (y > 0).then_some((prev_cls, prev_lab));
            let nb = neighbours(c, x, cur_cls, cur_lab, prev);
            let mut l = nb.iter().copied().find(|&v| v != NONE).unwrap_or(NONE);
            if l == NONE {
                if next < labels {
                    let root = parent.get(next).copied().unwrap_or(NONE);
                    let big = size.get(usize::from(root)).copied().unwrap_or(0) >= MIN_COMPONENT;
                    l = if big { root } else { SMALL };
                    next += 1;
                } else {
                    if let Some(cc) = cur_cls.get_mut(x) {
                        *cc = SKIP;
                    }
                    if let Some(cl) = cur_lab.get_mut(x) {
                        *cl = NONE;
                    }
                    continue;
                }
            }
            if let Some(cl) = cur_lab.get_mut(x) {
                *cl = l;
            }
        }
        // AprilTag's scan: the upper pixel is never in the outermost rows or columns.
        if y < 2 {
            continue;
        }
        // Pairs with the upper pixel in row y - 1 (AprilTag's DO_CONN from (x, y - 1)).
        let y2 = 2 * (y - 1);
        let cur_cls = &*cur_cls;
        let cur_lab = &*cur_lab;
        let mut connected_last = false;
        for x in 1..src.w.saturating_sub(1) {
            let v0 = prev_cls.get(x).copied().unwrap_or(SKIP);
            let r0 = prev_lab.get(x).copied().unwrap_or(NONE);
            if v0 == SKIP || r0 >= SMALL {
                connected_last = false;
                continue;
            }
            let mut conn = |v1: Option<&u8>, r1: Option<&u16>, dx: i32, dy: i32| -> bool {
                let (Some(&v1), Some(&r1)) = (v1, r1) else {
                    return false;
                };
                if v1 == SKIP || v1 == v0 || r1 >= SMALL {
                    return false;
                }
                let key = if v0 == BLACK {
                    u32::from(r0) << 16 | u32::from(r1)
                } else {
                    u32::from(r1) << 16 | u32::from(r0)
                };
                let s = if v1 == WHITE { 1 } else { -1 };
                let px = (2 * x as i32 + dx) as usize;
                emit(key, pack(px, y2 + dy as usize, dx * s, dy * s));
                true
            };
            conn(prev_cls.get(x + 1), prev_lab.get(x + 1), 1, 0);
            conn(cur_cls.get(x), cur_lab.get(x), 0, 1);
            if !connected_last {
                conn(cur_cls.get(x - 1), cur_lab.get(x - 1), -1, 1);
            }
            connected_last = conn(cur_cls.get(x + 1), cur_lab.get(x + 1), 1, 1);
        }
    }
}
