//! Templates kept from one frame's forward-backward check for the next frame's forward pass.
//!
//! The backward pass of a forward-backward check ([`super::FlowBuffers`]) interpolates, for
//! every point and level, the template of the *new* frame at the point's tracked position:
//! the pixels `I`, the derivatives `Ix`, `Iy` and `G`'s sums. The next frame's forward pass
//! starts every kept point from that same position in that same image, so it needs the same
//! template again. [`TemplateCache`] keeps the templates in the caller's scratch and hands one
//! back only when it is provably the one the kernel would compute:
//!
//! - the window's integer corner and bilinear weights are equal bit for bit (with the level and
//!   the window size), and
//! - the `(win + 3)²` pixels the template depends on are equal byte for byte: the `win + 1`
//!   integer positions of the bilinear window and the one-pixel ring of their 3x3 Scharr
//!   derivatives (whether computed per window or per level: the same integers).
//!
//! Windows whose ring leaves the image (where the derivatives see the border) are not kept.
//! The check does not trust the caller's frame order: any image, any point order.

use super::arith::Bilinear;
use super::kernel::{Rows, block_rows, state_len};
use crate::image::ImageView;

/// `u32` words of a slot's key (flags, corner, four weights) and of its three `i64` sums.
const KEY: usize = 7;
const HEAD: usize = KEY + 6;

/// Side of the block of pixels a template depends on.
const fn side(win: usize) -> usize {
    win + 3
}

/// `u32` words of those pixels.
const fn ring_words(win: usize) -> usize {
    (side(win) * side(win)).div_ceil(4)
}

/// `u32` words of one slot: key, sums, pixels, the kernel's template.
const fn slot_words(win: usize) -> usize {
    HEAD + ring_words(win) + state_len(win).div_ceil(2)
}

/// `i16` elements of a cache of `points` points over `levels` pyramid levels with `win x win`
/// windows (one more for the alignment of its words).
pub const fn cache_len(win: usize, levels: usize, points: usize) -> usize {
    2 * slot_words(win) * levels * points + 1
}

/// `i16` elements of a [`Templates::Keep`](super::Templates::Keep) buffer for `points` points
/// tracked up to level `max_level` with `win x win` windows: one slot a point and level, each
/// the template the kernel computes, the `(win + 3)²` pixels it was made from and its key
/// (`cache_len` of `max_level + 1` levels).
pub const fn templates_len(win: usize, max_level: usize, points: usize) -> usize {
    cache_len(win, max_level + 1, points)
}

/// A template and its `G` sums `(Σ Ix², Σ Ix Iy, Σ Iy²)`.
pub(super) type Kept<'a> = (&'a [i16], (i64, i64, i64));

/// Slots of kept templates, one per point and level, in the caller's scratch.
pub(super) struct TemplateCache<'c> {
    words: &'c mut [u32],
    win: usize,
    levels: usize,
}

impl<'c> TemplateCache<'c> {
    /// The cache over `buf` for `points` points over `levels` levels, `None` when `buf` is
    /// shorter than [`cache_len`] (or holds no slot at all).
    pub(super) fn new(
        buf: &'c mut [i16],
        win: usize,
        levels: usize,
        points: usize,
    ) -> Option<Self> {
        let (_, words, _) = bytemuck::pod_align_to_mut::<i16, u32>(buf);
        let words = words.get_mut(..slot_words(win) * levels * points)?;
        (!words.is_empty()).then_some(Self { words, win, levels })
    }

    /// The key of the template at `b` on `level`.
    fn key(&self, level: usize, b: &Bilinear) -> [u32; KEY] {
        let [w0, w1, w2, w3] = b.w.map(|w| w as u32);
        let flags = 1 | (level as u32) << 8 | (self.win as u32) << 16;
        [flags, b.x as u32, b.y as u32, w0, w1, w2, w3]
    }

    /// The rows of the pixels the template at `b` in `img` depends on, if all are inside.
    fn ring<'a>(&self, img: &ImageView<'a, u8>, b: &Bilinear) -> Option<Rows<'a, u8>> {
        let corner = (b.x.checked_sub(1)?, b.y.checked_sub(1)?);
        block_rows(img, corner, side(self.win), side(self.win))
    }

    /// The template kept for the window at `b` on `level` of `img`, if one is: point `k`'s
    /// slot first (the points usually keep their order from frame to frame), then any.
    pub(super) fn find(
        &self,
        k: usize,
        level: usize,
        img: &ImageView<'_, u8>,
        b: &Bilinear,
    ) -> Option<Kept<'_>> {
        let ring = self.ring(img, b)?;
        let key = self.key(level, b);
        let holds = |slot: &&[u32]| {
            slot.get(..KEY) == Some(&key[..]) && same_pixels(slot, ring.clone(), self.win)
        };
        let mut slots = self.words.chunks_exact(slot_words(self.win).max(1));
        let own = slots.clone().nth(k * self.levels + level).filter(holds);
        let slot = own.or_else(|| slots.find(holds))?;
        let sum = |i: usize| {
            let w = |j: usize| u64::from(slot.get(KEY + 2 * i + j).copied().unwrap_or(0));
            (w(0) | w(1) << 32) as i64
        };
        let state = bytemuck::try_cast_slice(slot.get(HEAD + ring_words(self.win)..)?).ok()?;
        let state = state.get(..state_len(self.win))?;
        Some((state, (sum(0), sum(1), sum(2))))
    }

    /// Keeps the template `state` with its sums for point `k` at `b` on `level` of `img`
    /// (nothing when its pixels leave the image).
    pub(super) fn keep(
        &mut self,
        k: usize,
        level: usize,
        img: &ImageView<'_, u8>,
        b: &Bilinear,
        (state, sums): Kept<'_>,
    ) {
        let (key, ring) = (self.key(level, b), self.ring(img, b));
        let n = slot_words(self.win).max(1);
        let Some(slot) = self.words.chunks_exact_mut(n).nth(k * self.levels + level) else {
            return;
        };
        let Some(ring) = ring else {
            // The slot's old template is still right for its old key: keep it.
            return;
        };
        let Some((head, rest)) = slot.split_at_mut_checked(HEAD) else {
            return;
        };
        let Some((pixels, tmpl)) = rest.split_at_mut_checked(ring_words(self.win)) else {
            return;
        };
        let (a11, a12, a22) = sums;
        let sums = [a11, a12, a22].map(|s| [s as u32, (s as u64 >> 32) as u32]);
        for (h, &v) in head.iter_mut().zip(key.iter().chain(sums.as_flattened())) {
            *h = v;
        }
        // `try_` casts and element loops: `u32` to bytes or to `i16` never fails, and neither
        // the casts nor `copy_from_slice` may leave a panic path in the core.
        let bytes = bytemuck::try_cast_slice_mut::<u32, u8>(pixels).unwrap_or_default();
        for (row, src) in bytes.chunks_exact_mut(side(self.win).max(1)).zip(ring) {
            for (d, &s) in row.iter_mut().zip(src) {
                *d = s;
            }
        }
        let kept = bytemuck::try_cast_slice_mut::<u32, i16>(tmpl).unwrap_or_default();
        for (t, &s) in kept.iter_mut().zip(state) {
            *t = s;
        }
    }
}

/// Whether the pixels kept in `slot` are the rows `ring`.
fn same_pixels(slot: &[u32], ring: Rows<'_, u8>, win: usize) -> bool {
    let kept = slot.get(HEAD..HEAD + ring_words(win)).unwrap_or(&[]);
    let kept = bytemuck::try_cast_slice::<u32, u8>(kept).unwrap_or_default();
    let mut rows = kept.chunks_exact(side(win).max(1));
    ring.zip(rows.by_ref()).all(|(a, b)| a == b) && rows.len() == 0
}
