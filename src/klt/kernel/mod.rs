//! The per-window work of one tracking step, in the shape that suits the target.
//!
//! Both kernels compute the same integers (tested to agree bit for bit): the template `I`, `Ix`,
//! `Iy` bilinear at a window's weights with `G`'s sums, and the mismatch sums
//! `Σ (J - I) [Ix Iy]` (or `Σ |J - I|`). They differ in memory layout only:
//!
//! - [`Packed`] (Cortex-M, RISC-V without vectors): the template interleaved `[I, Ix, Iy]` a
//!   pixel, rows exactly `win` wide, so the mismatch loop keeps one template pointer, two image
//!   rows, four weights and both sums in the thirteen registers of an M-class core.
//! - [`Lanes`] (targets with 128-bit SIMD: SSE2, NEON, wasm `simd128`): the template in
//!   separate planes, rows padded to a multiple of eight lanes (`Ix`, `Iy` zero in the
//!   padding, so it adds nothing to any sum), so every loop runs on whole vectors of eight
//!   `i16` with products `i16 x i16 -> i32` (`pmaddwd` on x86-64); the window's derivatives
//!   as the level's `[Ix, Iy]` pairs (read in place when the window lies inside the level).
//!   On x86-64 CPUs with AVX2 (found at run time with the `std` feature) its bilinear samples
//!   take 256-bit vectors ([`lanes`]); the integers are the same.
//!
//! The files, each importing only files after it in this list: [`packed`] and [`lanes`] (the
//! two kernels), [`window`] (their trait, which the pyramid driver calls), [`border`] (a level
//! and its bordered copy, [`Pixels`]) and [`patch`] (the blocks a window reads). This file picks
//! the target's kernel ([`LANES`]) and sizes its scratch.

mod border;
mod lanes;
mod packed;
mod patch;
mod window;

pub use border::bordered_len;
pub(in crate::klt) use border::{Pixels, border_width, pad};
pub(in crate::klt) use lanes::Lanes;
pub(in crate::klt) use packed::Packed;
pub(in crate::klt) use patch::{Rows, block_rows};
pub(in crate::klt) use window::Window;

/// Whether this target runs [`Lanes`] (128-bit SIMD) rather than [`Packed`]. A constant: the
/// other kernel is compiled out of every optimised build.
pub(in crate::klt) const LANES: bool = crate::SIMD;

/// `i16` elements of scratch [`calc_flow`](crate::klt::calc_flow) needs for `win x win`
/// windows: the window's derivatives and pixels at integer positions, the interpolated
/// template and its derivatives. On cores without vector units (`Packed`)
/// `3 (win + 1)² + 3 win²`, 2 775 (5.4 KB) for 21x21; on targets with 128-bit SIMD (x86-64,
/// aarch64, ..., `Lanes`) the rows are padded to a multiple of 8 lanes, `s = 8 ⌈win / 8⌉`,
/// and the template's to an even count, `r = 2 ⌈win / 2⌉` (AVX2 holds two rows a vector):
/// `3 (win + 1)(s + 1) + 3 r s`, 3 234 for 21x21.
pub const fn scratch_len(win: usize) -> usize {
    if LANES {
        lanes::scratch_len(win)
    } else {
        packed::scratch_len(win)
    }
}

/// `i16` elements of the target's kernel's [`Window::state`] for `win x win` windows.
pub(in crate::klt) const fn state_len(win: usize) -> usize {
    if LANES {
        lanes::state_len(win)
    } else {
        packed::state_len(win)
    }
}

/// `i16` elements of scratch for either kernel ([`Packed`], [`Lanes`]) with `win x win`
/// windows: the tests run both on one target.
#[cfg(test)]
pub(in crate::klt) const fn any_scratch_len(win: usize) -> usize {
    let (p, l) = (packed::scratch_len(win), lanes::scratch_len(win));
    if p > l { p } else { l }
}
