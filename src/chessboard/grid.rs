//! Step 3's bookkeeping: the grid of candidate indices being grown, and adding a row or
//! column to it.

/// Rows and columns of the grid being grown.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid<const N: usize> {
    pub(super) idx: [u16; N],
    pub(super) w: usize,
    pub(super) h: usize,
}

impl<const N: usize> Grid<N> {
    /// The candidate at column `c`, row `r`.
    pub(super) fn at(&self, c: usize, r: usize) -> Option<usize> {
        if c >= self.w || r >= self.h {
            return None;
        }
        self.idx.get(r * self.w + c).map(|&i| i as usize)
    }
}

/// The side of the grid a new row or column goes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Right,
    Left,
    Bottom,
    Top,
}

/// `grid` with the new row or column `new` added on `side`.
pub(super) fn insert<const N: usize>(g: &Grid<N>, side: Side, new: &[u16]) -> Option<Grid<N>> {
    let (w, h) = match side {
        Side::Right | Side::Left => (g.w + 1, g.h),
        Side::Bottom | Side::Top => (g.w, g.h + 1),
    };
    if w * h > N {
        return None;
    }
    let mut out = Grid::<N> { idx: [0; N], w, h };
    for r in 0..h {
        for c in 0..w {
            let v = match side {
                Side::Right if c == g.w => *new.get(r)?,
                Side::Left if c == 0 => *new.get(r)?,
                Side::Left => g.at(c - 1, r)? as u16,
                Side::Bottom if r == g.h => *new.get(c)?,
                Side::Top if r == 0 => *new.get(c)?,
                Side::Top => g.at(c, r - 1)? as u16,
                _ => g.at(c, r)? as u16,
            };
            *out.idx.get_mut(r * w + c)? = v;
        }
    }
    Some(out)
}
