//! The per-window kernel's interface ([`Window`]), which the pyramid driver calls, and the
//! template's units.

use super::border::Pixels;
use crate::Result;
use crate::image::ImageView;
use crate::klt::arith::{Bilinear, W_BITS};

/// The per-window kernel over its part of the caller's scratch.
pub(in crate::klt) trait Window<'s>: Sized {
    /// Whether the kernel reads blocks from a level's bordered copy ([`Pixels::block`]); the
    /// driver makes the copies only for a kernel that does.
    const BORDERED: bool;
    /// Splits `scratch` for `win x win` windows ([`crate::Error::BufferTooSmall`] when short).
    fn new(scratch: &'s mut [i16], win: usize) -> Result<Self>;
    /// Interpolates the template at the window of `i` with integer corner `(b.x, b.y)` and
    /// weights `b.w` (derivatives from `grad`, the level's, or by Scharr from `i`'s level);
    /// returns `G`'s sums `(Σ Ix², Σ Ix Iy, Σ Iy²)`.
    fn template(
        &mut self,
        i: &Pixels<'_>,
        grad: Option<&ImageView<'_, [i16; 2]>>,
        b: &Bilinear,
    ) -> (i64, i64, i64);
    /// `(Σ (J - I) Ix, Σ (J - I) Iy)` over the window of `j` at `b` against the template
    /// (`(Σ |J - I|, 0)` when `abs`); `J` reflected outside the image.
    fn mismatch(&mut self, j: &Pixels<'_>, b: &Bilinear, abs: bool) -> (i64, i64);
    /// The template as [`Self::template`] left it: all that [`Self::mismatch`] reads of it,
    /// the target's kernel's `state_len(win)` elements.
    fn state(&self) -> &[i16];
    /// Puts back a template [`Self::state`] returned for the same `win` (as if
    /// [`Self::template`] had just computed it).
    fn restore(&mut self, state: &[i16]);
}

/// Shift from Q14-weighted pixels to the template's 1/32 grey levels.
pub(super) const PIX_SHIFT: u32 = W_BITS - 5;
