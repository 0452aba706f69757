//! Chessboard detection: the inner corners of a `cols x rows` board in a grey frame, ordered as
//! OpenCV's `findChessboardCorners` orders them, then refined to sub-pixel accuracy.
//!
//! # Method
//!
//! 1. **Saddle response.** The frame is smoothed by the binomial kernel `[1 4 6 4 1]/16` in
//!    each direction (σ = 1 px) and the Hessian `H` of the smoothed image is taken by second
//!    differences; an x-corner (where two dark and two bright squares meet) is a saddle,
//!    `det H < 0`, so the response is `R = I_xy² - I_xx I_yy` (integers, `i64` products).
//!    Unlike a template or ring detector (ChESS, OpenCV's quads after dilation), the saddle
//!    test does not depend on the angle between the two edges, so strong perspective and any
//!    in-plane rotation keep the same response; it is zero on straight edges and negative on
//!    blobs. The frame is streamed row by row through ring buffers (`11 · width` words of
//!    scratch) and the 3x3 local maxima above [`DetectConfig::min_response`] are kept in a
//!    bounded min-heap of the `K` strongest (`O(pixels · log K)` work whatever the content).
//! 2. **Corner test.** Each candidate's neighbourhood is sampled on a ring (radius 5 px, then
//!    3 px when the larger ring meets other squares): an x-corner shows exactly four
//!    dark/bright transitions, opposite ones about 180° apart. The two edge lines through the
//!    corner come out of the transition angles; anything else (an L-junction at the board's
//!    outline, texture, a blob) is dropped.
//! 3. **Grid growing.** From a seed (strongest first, at most [`DetectConfig::max_seeds`]), the
//!    nearest candidates along its two edge lines give a 2x2 grid; the grid then grows a whole
//!    row or column at a time, each new corner predicted by quadratic extrapolation along its
//!    row or column (exact for the second-order change of spacing that perspective and
//!    moderate lens distortion make), searched within half the local spacing, and accepted
//!    only when the step lies along one of its own edge lines. A side that cannot be completed
//!    (out of view, occluded) stops growing.
//! 4. **Verification.** The grid must have exactly `cols x rows` corners (in either
//!    orientation); a smaller one (board partly out of view) or a larger one (another pattern)
//!    is no detection. The cells between the corners must alternate dark and bright along
//!    every row and column, with a mean contrast of at least [`DetectConfig::min_contrast`].
//! 5. **Order.** OpenCV's order: rows of `cols` corners; the cross product
//!    `(p[cols-1] - p[0]) × (p[cols] - p[cols-1]) ≥ 0` (image `y` down); the first cell
//!    (between corners `0, 1, cols, cols+1`) dark. When the board's colours are symmetric under
//!    a half turn (`cols + rows` even), OpenCV's rule for even boards picks the order whose
//!    last row starts below the first; a square board (`cols == rows`) keeps the first of the
//!    remaining orders.
//! 6. **Refinement** ([`Refinement`]): by default the saddle point of the smoothed image
//!    ([`saddle_subpix`]), or OpenCV's `cornerSubPix` ([`corner_subpix`]) with a fixed or an
//!    adaptive window; see [`subpix`] for why and the measurements.
//!
//! **Any resolution** ([`ChessboardDetector::detect_any_scale`]): the same steps on the levels
//! of a Gaussian pyramid, from the coarsest that can show the board down to the frame, then
//! the refinement carried down level by level (see [`scales`]). The detector's fixed scale
//! (σ = 1 px, rings of 5 and 3 px) then no longer limits the frame size, the blur or the
//! board's size in the view.
//!
//! A board that is absent or only partly visible is `Ok(None)`, never a guess;
//! [`ChessboardDetector::seen`] says what was seen instead.
//!
//! Memory: [`ChessboardDetector::BYTES`] bytes of state (candidates and the heap, fixed by
//! `K`) plus [`scratch_len`]`(width)` `i32` words of scratch. With `K = 512`: 20,496 bytes of
//! state, and 7,040 words (28 KB) of scratch at 640 px width, 3,520 words (14 KB) at 320 px:
//! [`ChessboardDetector::memory`] gives 48,656 bytes at 640x480 and 34,576 at 320x240 (the
//! frame itself is the caller's). The search at any scale adds the pyramid,
//! [`pyramid_len`]`(width, height)` bytes, at most a third of the frame: 409,580 bytes at
//! 1280x960 (with 56 KB of scratch at that width), 4,064,142 at 4032x3024 (177 KB of scratch);
//! the board keeps the one-scale search.
//!
//! ```
//! use camgeom::chessboard::{BoardSize, ChessboardDetector, DetectParams, scratch_len};
//! use camgeom::image::ImageView;
//!
//! // A 4x3 inner-corner board: 5x4 squares of 12 px, dark where (i + j) is even.
//! let (w, h) = (96usize, 80usize);
//! let mut px = [200u8; 96 * 80];
//! for y in 0..h {
//!     for x in 0..w {
//!         let (i, j) = ((x as i32 - 18) / 12, (y as i32 - 16) / 12);
//!         if x >= 18 && y >= 16 && i < 5 && j < 4 && (i + j) % 2 == 0 {
//!             px[y * w + x] = 30;
//!         }
//!     }
//! }
//! let img = ImageView::packed(&px, w, h)?;
//! let mut scratch = [0i32; scratch_len(96)];
//! let mut det = ChessboardDetector::<64>::new();
//! let board = BoardSize::new(4, 3)?;
//! let found = det.detect::<12>(&img, board, &DetectParams::default(), &mut scratch)?;
//! let corners = found.expect("the board is in view");
//! // The first inner corner sits between the first dark square and its neighbours.
//! assert!((corners.corners[0].x - 29.5).abs() < 0.2 && (corners.corners[0].y - 27.5).abs() < 0.2);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod config;
mod grid;
mod response;
mod ring;
pub mod scales;
pub mod subpix;

pub use config::{BoardSize, DetectConfig, DetectParams, Refinement};
pub use response::scratch_len;
pub use scales::pyramid_len;
pub use subpix::{
    SaddleConfig, SaddleParams, SubPixConfig, SubPixParams, corner_subpix, saddle_subpix,
};

use heapless::Vec;
use heapless::binary_heap::{BinaryHeap, Min};
use nalgebra::{Point2, Vector2};

use grid::{Grid, Side, insert};
use response::{Maximum, collect_maxima};
use ring::corner_lines;
use subpix::corner_subpix_adaptive;

use crate::image::ImageView;
use crate::pyramid::Pyramid;
use crate::{Error, Result};

/// The found board: `rows · cols` corners, row-major, OpenCV's order.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Chessboard<const N: usize> {
    /// The board's size.
    pub size: BoardSize,
    /// Corner `(i, j)` (column `i`, row `j`) is `corners[j · cols + i]`, pixels.
    pub corners: Vec<Point2<f32>, N>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    p: Point2<f32>,
    /// The two edge lines through the corner (unit vectors, sign arbitrary).
    lines: [Vector2<f32>; 2],
    /// Passed the corner test.
    ok: bool,
    /// 0 free, 1 in the grid being grown, 2 already part of a failed grid.
    mark: u8,
}

impl Candidate {
    /// Passed the corner test and belongs to no grid yet: may seed or join a grid.
    fn is_free(&self) -> bool {
        self.ok && self.mark == 0
    }
}

const EMPTY: Candidate = Candidate {
    p: Point2::new(0.0, 0.0),
    lines: [Vector2::new(1.0, 0.0), Vector2::new(0.0, 1.0)],
    ok: false,
    mark: 0,
};

/// A chessboard detector keeping at most `K` corner candidates a frame (512 is ample for a
/// 640x480 frame with a 9x6 board and clutter).
#[derive(Debug, Clone)]
pub struct ChessboardDetector<const K: usize> {
    cands: [Candidate; K],
    count: usize,
    heap: BinaryHeap<Maximum, Min, K>,
    seen: Seen,
}

/// What the last detection saw: the most of each over the levels searched. Says why a board
/// was not found (no corner at all, x-corners but no grid, a grid smaller than the board: part
/// of it out of view or too small to resolve, or another board size).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Seen {
    /// Saddle-response maxima kept as candidates.
    pub candidates: u16,
    /// Candidates that passed the corner test (x-corners).
    pub x_corners: u16,
    /// The largest grid grown, `(columns, rows)` of corners as grown (either orientation);
    /// `(0, 0)` when no 2x2 start was found.
    pub largest_grid: (u8, u8),
}

impl Seen {
    fn merge(&mut self, other: Self) {
        self.candidates = self.candidates.max(other.candidates);
        self.x_corners = self.x_corners.max(other.x_corners);
        let area = |g: (u8, u8)| u16::from(g.0) * u16::from(g.1);
        if area(other.largest_grid) > area(self.largest_grid) {
            self.largest_grid = other.largest_grid;
        }
    }
}

impl<const K: usize> Default for ChessboardDetector<K> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const K: usize> ChessboardDetector<K> {
    /// Bytes of the detector's own state (without the caller's scratch).
    pub const BYTES: usize = core::mem::size_of::<Self>();

    /// An empty detector. `K` is at most 65,535 (candidates are indexed by `u16`), checked at
    /// compile time.
    pub const fn new() -> Self {
        const { assert!(K <= u16::MAX as usize, "K must fit in u16") };
        Self {
            cands: [EMPTY; K],
            count: 0,
            heap: BinaryHeap::new(),
            seen: Seen {
                candidates: 0,
                x_corners: 0,
                largest_grid: (0, 0),
            },
        }
    }

    /// Bytes a detection of a `width`-pixel-wide frame uses: the state and the scratch.
    pub const fn memory(width: usize) -> usize {
        Self::BYTES + 4 * scratch_len(width)
    }

    /// Finds the `board` in `image` at the detector's own scale; see the module documentation
    /// for the method, and [`Self::detect_any_scale`] for a frame of any resolution.
    ///
    /// Returns `Ok(None)` when the board is absent or not entirely in view. Errors:
    /// `BufferTooSmall("corners")` when `N < board.corners()`, `BufferTooSmall("scratch")`
    /// when `scratch.len() < scratch_len(width)`, `InvalidImage` for a frame smaller than
    /// 16x16 or wider than 65,535.
    #[doc(alias = "findChessboardCorners")]
    #[doc(alias = "findChessboardCornersSB")]
    pub fn detect<const N: usize>(
        &mut self,
        image: &ImageView<'_, u8>,
        board: BoardSize,
        params: &DetectParams,
        scratch: &mut [i32],
    ) -> Result<Option<Chessboard<N>>> {
        check_frame::<N>(image, board, scratch)?;
        self.seen = Seen::default();
        let cfg = params.config();
        let Some(mut found) = self.find::<N>(image, board, cfg, scratch) else {
            return Ok(None);
        };
        refine(image, &mut found, cfg.refine, 1)?;
        Ok(Some(found))
    }

    /// Finds the `board` in a frame of any resolution: [`Self::detect`]'s search on the levels
    /// of a Gaussian pyramid of `image`, from the coarsest that can show a board down to the
    /// frame itself, the first level that shows the whole board with squares of at least
    /// 10 px winning (the frame itself takes any). Its corners are then refined on every finer
    /// level down to the frame, with a window and a smoothing that widen as the board does
    /// (see [`scales`'s documentation] for why). Where [`Self::detect`] finds the board this
    /// finds it too (the frame itself is the last level searched), usually on a coarser level
    /// and for less work.
    ///
    /// `pyramid` must hold [`pyramid_len`]`(width, height)` bytes, `scratch`
    /// [`scratch_len`]`(width)` words (the frame's width serves every level).
    ///
    /// Returns `Ok(None)` when no level shows the whole board. Errors: those of
    /// [`Self::detect`], and `BufferTooSmall("pyramid")`.
    ///
    /// [`scales`'s documentation]: self::scales
    #[doc(alias = "findChessboardCorners")]
    pub fn detect_any_scale<const N: usize>(
        &mut self,
        image: &ImageView<'_, u8>,
        board: BoardSize,
        params: &DetectParams,
        pyramid: &mut [u8],
        scratch: &mut [i32],
    ) -> Result<Option<Chessboard<N>>> {
        check_frame::<N>(image, board, scratch)?;
        let (w, h) = (image.width(), image.height());
        if pyramid.len() < pyramid_len(w, h) {
            return Err(Error::BufferTooSmall("pyramid"));
        }
        self.seen = Seen::default();
        let cfg = params.config();
        let levels = scales::levels(w, h, board);
        let pyr = Pyramid::build(*image, pyramid, levels)?;
        for l in (0..levels).rev() {
            let Some(level) = pyr.level(l) else { continue };
            let Some(mut found) = self.find::<N>(&level, board, cfg, scratch) else {
                continue;
            };
            if l > 0 && !scales::resolved(&found.corners, board.cols()) {
                continue;
            }
            refine(&level, &mut found, cfg.refine, 1)?;
            for finer in (0..l).rev() {
                let Some(level) = pyr.level(finer) else { break };
                for c in found.corners.iter_mut() {
                    *c = Point2::new(scales::finer(c.x), scales::finer(c.y));
                }
                // The board is `2^(l - finer)` times larger here than where it was found, its
                // edges as much wider: the refinement's window and smoothing widen with them.
                refine(&level, &mut found, cfg.refine, 1 << (l - finer))?;
            }
            return Ok(Some(found));
        }
        Ok(None)
    }

    /// Steps 1 to 5 on one frame (or pyramid level): the verified, ordered board at the
    /// candidates' positions, unrefined.
    fn find<const N: usize>(
        &mut self,
        image: &ImageView<'_, u8>,
        board: BoardSize,
        cfg: &DetectConfig,
        scratch: &mut [i32],
    ) -> Option<Chessboard<N>> {
        self.collect(image, cfg.min_response, scratch);
        let mut seen = Seen {
            candidates: self.count as u16,
            ..Seen::default()
        };
        for c in self.cands.iter_mut().take(self.count) {
            match corner_lines(image, &c.p, cfg.min_contrast) {
                Some(lines) => {
                    c.lines = lines;
                    c.ok = true;
                    seen.x_corners = seen.x_corners.saturating_add(1);
                }
                None => c.ok = false,
            }
        }
        let found = self.search::<N>(image, board, cfg, &mut seen);
        self.seen.merge(seen);
        found
    }

    /// Steps 3 to 5: seeds, grids, verification; the largest grid goes into `seen`.
    fn search<const N: usize>(
        &mut self,
        image: &ImageView<'_, u8>,
        board: BoardSize,
        cfg: &DetectConfig,
        seen: &mut Seen,
    ) -> Option<Chessboard<N>> {
        let mut seeds = 0u8;
        for s in 0..self.count {
            if seeds >= cfg.max_seeds {
                break;
            }
            let Some(c) = self.cands.get(s) else { break };
            if !c.is_free() {
                continue;
            }
            seeds += 1;
            let grid = self.grow::<N>(s, board);
            // Whatever happens, the corners of this grid do not seed again.
            for c in self.cands.iter_mut().take(self.count) {
                if c.mark == 1 {
                    c.mark = 2;
                }
            }
            let Some(grid) = grid else { continue };
            seen.merge(Seen {
                largest_grid: (grid.w as u8, grid.h as u8),
                ..Seen::default()
            });
            if let Some(found) = self.verify_and_order::<N>(image, &grid, board, cfg.min_contrast) {
                return Some(found);
            }
        }
        None
    }

    /// Step 1: the `K` strongest 3x3 maxima of the saddle response, strongest first.
    fn collect(&mut self, image: &ImageView<'_, u8>, min_response: i32, scratch: &mut [i32]) {
        collect_maxima(image, min_response, scratch, &mut self.heap);
        // Drain weakest first into the array from its end: strongest first.
        self.count = self.heap.len().min(K);
        let mut i = self.count;
        while let Some((_, x, y, dx, dy)) = self.heap.pop() {
            i = i.saturating_sub(1);
            if let Some(c) = self.cands.get_mut(i) {
                *c = Candidate {
                    p: Point2::new(x as f32 + dx as f32 / 64.0, y as f32 + dy as f32 / 64.0),
                    ..EMPTY
                };
            }
        }
    }

    /// What the last detection saw (for saying why a board was not found).
    pub fn seen(&self) -> Seen {
        self.seen
    }

    /// The last frame's candidates, strongest first: position and whether it passed the
    /// corner test (for diagnostics and drawing).
    pub fn candidates(&self) -> impl Iterator<Item = (Point2<f32>, bool)> + '_ {
        self.cands.iter().take(self.count).map(|c| (c.p, c.ok))
    }

    fn pos(&self, i: usize) -> Point2<f32> {
        self.cands.get(i).map_or(Point2::origin(), |c| c.p)
    }

    /// The candidates that passed the corner test and belong to no grid yet, with their
    /// indices.
    fn free(&self) -> impl Iterator<Item = (usize, &Candidate)> + '_ {
        self.cands
            .iter()
            .take(self.count)
            .enumerate()
            .filter(|(_, c)| c.is_free())
    }

    /// The nearest free, tested candidate within `radius` of `p`.
    fn nearest(&self, p: &Point2<f32>, radius: f32) -> Option<usize> {
        let r2 = radius * radius;
        let mut best: Option<(f32, usize)> = None;
        for (i, c) in self.free() {
            let d = (c.p - p).norm_squared();
            if d <= r2 && best.is_none_or(|(b, _)| d < b) {
                best = Some((d, i));
            }
        }
        best.map(|(_, i)| i)
    }

    /// `true` when the step `v` lies along one of candidate `i`'s edge lines (within 25°).
    fn along(&self, i: usize, v: &Vector2<f32>) -> bool {
        let n = v.norm();
        let Some(c) = self.cands.get(i) else {
            return false;
        };
        n > 0.0
            && c.lines
                .iter()
                .any(|l| (l.x * v.y - l.y * v.x).abs() < SIN_25 * n)
    }

    fn mark(&mut self, i: usize, m: u8) {
        if let Some(c) = self.cands.get_mut(i) {
            c.mark = m;
        }
    }

    /// Step 3: grows a grid from seed `s`; `None` when no 2x2 start exists or the grid grows
    /// beyond the board.
    fn grow<const N: usize>(&mut self, s: usize, board: BoardSize) -> Option<Grid<N>> {
        let seed = *self.cands.get(s)?;
        self.mark(s, 1);
        // The nearest neighbour along each edge line, either way.
        let mut nb = [None; 2];
        for (k, l) in seed.lines.iter().enumerate() {
            let mut best: Option<(f32, usize)> = None;
            for (i, c) in self.free() {
                let v = c.p - seed.p;
                let d = v.norm();
                if d < 4.0 || (l.x * v.y - l.y * v.x).abs() > SIN_20 * d {
                    continue;
                }
                if self.along(i, &v) && best.is_none_or(|(b, _)| d < b) {
                    best = Some((d, i));
                }
            }
            if let Some(x) = nb.get_mut(k) {
                *x = best.map(|(_, i)| i);
            }
        }
        let [Some(a), Some(b)] = nb else {
            return None;
        };
        let (pa, pb) = (self.pos(a), self.pos(b));
        let (va, vb) = (pa - seed.p, pb - seed.p);
        let diag = self.nearest(&(pa + vb), 0.4 * va.norm().min(vb.norm()))?;
        if diag == a || diag == b {
            return None;
        }
        self.mark(a, 1);
        self.mark(b, 1);
        self.mark(diag, 1);
        let mut grid = Grid::<N> {
            idx: [0; N],
            w: 2,
            h: 2,
        };
        for (slot, v) in grid.idx.iter_mut().zip([s, a, b, diag]) {
            *slot = v as u16;
        }
        let (bc, br) = (board.cols(), board.rows());
        let fits = |gw: usize, gh: usize| (gw <= bc && gh <= br) || (gw <= br && gh <= bc);
        let mut blocked = [false; 4];
        // Each pass adds at least one row or column: bounded by the board's size.
        for _ in 0..(bc + br + 4) {
            let mut grew = false;
            for (k, side) in [Side::Right, Side::Bottom, Side::Left, Side::Top]
                .into_iter()
                .enumerate()
            {
                if blocked.get(k).copied().unwrap_or(true) {
                    continue;
                }
                let (gw, gh) = match side {
                    Side::Right | Side::Left => (grid.w + 1, grid.h),
                    Side::Bottom | Side::Top => (grid.w, grid.h + 1),
                };
                match self.extend(&grid, side) {
                    Some(new) if fits(gw, gh) => {
                        grid = insert(&grid, side, &new)?;
                        for &i in new.iter() {
                            self.mark(i as usize, 1);
                        }
                        grew = true;
                    }
                    // A complete row beyond the board: another, larger pattern.
                    Some(_) => return None,
                    None => {
                        if let Some(b) = blocked.get_mut(k) {
                            *b = true;
                        }
                    }
                }
            }
            if !grew {
                break;
            }
        }
        Some(grid)
    }

    /// The candidates that complete a new row or column on `side`, `None` when one is missing.
    fn extend<const N: usize>(&self, g: &Grid<N>, side: Side) -> Option<Vec<u16, 64>> {
        let (len, depth) = match side {
            Side::Right | Side::Left => (g.h, g.w),
            Side::Bottom | Side::Top => (g.w, g.h),
        };
        let mut out: Vec<u16, 64> = Vec::new();
        for k in 0..len {
            // The grid's nodes along the growth direction, outermost first.
            let node = |m: usize| -> Option<usize> {
                let back = depth.checked_sub(1 + m)?;
                match side {
                    Side::Right => g.at(back, k),
                    Side::Left => g.at(m, k),
                    Side::Bottom => g.at(k, back),
                    Side::Top => g.at(k, m),
                }
            };
            let p0 = self.pos(node(0)?);
            let p1 = self.pos(node(1)?);
            let pred = match node(2) {
                Some(i2) if depth >= 3 => {
                    let p2 = self.pos(i2);
                    Point2::from(p0.coords * 3.0 - p1.coords * 3.0 + p2.coords)
                }
                _ => Point2::from(p0.coords * 2.0 - p1.coords),
            };
            let step = (p0 - p1).norm();
            let q = self.nearest(&pred, 0.5 * step)?;
            let v = self.pos(q) - p0;
            let ratio = v.norm() / step;
            if !(0.5..=2.0).contains(&ratio)
                || !self.along(q, &v)
                || out.iter().any(|&o| o as usize == q)
            {
                return None;
            }
            out.push(q as u16).ok()?;
        }
        Some(out)
    }

    /// Steps 4 and 5: the cell colours alternate; then OpenCV's order.
    fn verify_and_order<const N: usize>(
        &self,
        image: &ImageView<'_, u8>,
        g: &Grid<N>,
        board: BoardSize,
        min_contrast: u8,
    ) -> Option<Chessboard<N>> {
        let (bc, br) = (board.cols(), board.rows());
        if !((g.w == bc && g.h == br) || (g.w == br && g.h == bc)) {
            return None;
        }
        let pos = |c: usize, r: usize| g.at(c, r).map(|i| self.pos(i));
        // Mean grey level around the centre of cell (c, r).
        let cell = |c: usize, r: usize| -> Option<i32> {
            let m = (pos(c, r)?.coords
                + pos(c + 1, r)?.coords
                + pos(c, r + 1)?.coords
                + pos(c + 1, r + 1)?.coords)
                * 0.25;
            let (x, y) = (libm::roundf(m.x) as isize, libm::roundf(m.y) as isize);
            let mut sum = 0i32;
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (sx, sy) = (x + dx, y + dy);
                    if sx < 0 || sy < 0 {
                        return None;
                    }
                    sum += image.get(sx as usize, sy as usize)? as i32;
                }
            }
            Some(sum / 9)
        };
        // Parity-signed differences of neighbouring cells must all share one sign.
        let (cw, ch) = (g.w - 1, g.h - 1);
        let mut sign = 0i32;
        let mut total = 0i64;
        let mut pairs = 0i64;
        for r in 0..ch {
            for c in 0..cw {
                let v = cell(c, r)?;
                let parity = if (c + r).is_multiple_of(2) { 1 } else { -1 };
                for (nc, nr) in [(c + 1, r), (c, r + 1)] {
                    if nc >= cw || nr >= ch {
                        continue;
                    }
                    let d = (v - cell(nc, nr)?) * parity;
                    if d == 0 {
                        return None;
                    }
                    if sign == 0 {
                        sign = d.signum();
                    } else if d.signum() != sign {
                        return None;
                    }
                    total += d.abs() as i64;
                    pairs += 1;
                }
            }
        }
        if pairs == 0 || total < min_contrast as i64 * pairs {
            return None;
        }
        // Cell (c, r) is dark when its parity-signed difference is negative.
        let dark = |c: usize, r: usize| {
            let parity = if (c + r).is_multiple_of(2) { 1 } else { -1 };
            parity * sign < 0
        };
        // The eight symmetries of the grid that give rows of `bc` corners.
        let mut best: Option<(u8, [bool; 3])> = None;
        for t in 0..8u8 {
            let (tr, fx, fy) = (t & 4 != 0, t & 1 != 0, t & 2 != 0);
            let map = |i: usize, j: usize| -> Option<(usize, usize)> {
                let (i2, j2) = (
                    if fx { bc.checked_sub(1 + i)? } else { i },
                    if fy { br.checked_sub(1 + j)? } else { j },
                );
                if tr { Some((j2, i2)) } else { Some((i2, j2)) }
            };
            if (tr && (g.w != br || g.h != bc)) || (!tr && (g.w != bc || g.h != br)) {
                continue;
            }
            let p = |i: usize, j: usize| map(i, j).and_then(|(c, r)| pos(c, r));
            let (p0, p1, p2) = (p(0, 0)?, p(bc - 1, 0)?, p(0, 1)?);
            let cross = (p1.x - p0.x) * (p2.y - p1.y) - (p1.y - p0.y) * (p2.x - p1.x);
            let (c00, c11) = (map(0, 0)?, map(1, 1)?);
            let first_dark = dark(c00.0.min(c11.0), c00.1.min(c11.1));
            let down = p(0, br - 1)?.y - p0.y >= 0.0;
            let key = [cross >= 0.0, first_dark, down];
            let rank = |k: &[bool; 3]| (k[0] as u8) * 4 + (k[1] as u8) * 2 + k[2] as u8;
            if best.is_none_or(|(_, b)| rank(&key) > rank(&b)) {
                best = Some((t, key));
            }
        }
        let (t, key) = best?;
        if !key[0] {
            return None;
        }
        let (tr, fx, fy) = (t & 4 != 0, t & 1 != 0, t & 2 != 0);
        let mut corners: Vec<Point2<f32>, N> = Vec::new();
        for j in 0..br {
            for i in 0..bc {
                let (i2, j2) = (
                    if fx { bc - 1 - i } else { i },
                    if fy { br - 1 - j } else { j },
                );
                let (c, r) = if tr { (j2, i2) } else { (i2, j2) };
                corners.push(pos(c, r)?).ok()?;
            }
        }
        Some(Chessboard {
            size: board,
            corners,
        })
    }
}

/// The checks [`ChessboardDetector::detect`] and
/// [`ChessboardDetector::detect_any_scale`] share: the output's capacity, the frame's size,
/// the scratch's length.
fn check_frame<const N: usize>(
    image: &ImageView<'_, u8>,
    board: BoardSize,
    scratch: &[i32],
) -> Result<()> {
    if N < board.corners() {
        return Err(Error::BufferTooSmall("corners"));
    }
    let (w, h) = (image.width(), image.height());
    if w < 16 || h < 16 || w > u16::MAX as usize || h > u16::MAX as usize {
        return Err(Error::InvalidImage);
    }
    if scratch.len() < scratch_len(w) {
        return Err(Error::BufferTooSmall("scratch"));
    }
    Ok(())
}

/// Step 6: the configured sub-pixel refinement of `found`'s corners on `image`, its window
/// (and smoothing) `scale` times the configured one: the board was found on a level `scale`
/// times coarser than `image`.
fn refine<const N: usize>(
    image: &ImageView<'_, u8>,
    found: &mut Chessboard<N>,
    refinement: Refinement,
    scale: u8,
) -> Result<()> {
    // The refinement's configuration was checked with the detection's parameters.
    match refinement {
        Refinement::None => Ok(()),
        Refinement::CornerSubPix(sp) => {
            let sp = SubPixParams::from_checked(sp).scaled(scale);
            corner_subpix(image, &mut found.corners, &sp)
        }
        Refinement::AdaptiveCornerSubPix(sp) => {
            let sp = SubPixParams::from_checked(sp).scaled(scale);
            corner_subpix_adaptive(image, &mut found.corners, found.size.cols(), &sp)
        }
        Refinement::Saddle(sc) => {
            let sc = SaddleParams::from_checked(sc).scaled(scale);
            saddle_subpix(image, &mut found.corners, &sc)
        }
    }
}

const SIN_20: f32 = 0.342_020_14;
const SIN_25: f32 = 0.422_618_26;
