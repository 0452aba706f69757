//! Helpers of the 128-bit vector kernels (the KLT window kernel, the Scharr rows): `wide`'s
//! vectors, with the few shuffles it does not name.

use wide::{i16x8, u8x16};

/// Eight bytes in the low half of a vector (one 8-byte load), the high half zero.
#[inline(always)]
pub(crate) fn low(h: &[u8; 8]) -> u8x16 {
    let mut v = [0u8; 16];
    if let Some(lo) = v.first_chunk_mut::<8>() {
        *lo = *h;
    }
    u8x16::new(v)
}

/// `(a0, b0, a1, b1, a2, b2, a3, b3)` and `(a4, b4, ..., a7, b7)`: SSE2's `punpcklwd` and
/// `punpckhwd` (`wide` has no 16-bit interleave; LLVM did not find it in the lane-by-lane
/// form below, which the other targets use).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn interleave(a: i16x8, b: i16x8) -> (i16x8, i16x8) {
    use safe_arch::{m128i, unpack_high_i16_m128i, unpack_low_i16_m128i};
    let (a, b): (m128i, m128i) = (bytemuck::cast(a), bytemuck::cast(b));
    (
        bytemuck::cast(unpack_low_i16_m128i(a, b)),
        bytemuck::cast(unpack_high_i16_m128i(a, b)),
    )
}

/// `(a0, b0, a1, b1, a2, b2, a3, b3)` and `(a4, b4, ..., a7, b7)`.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(crate) fn interleave(a: i16x8, b: i16x8) -> (i16x8, i16x8) {
    let [a0, a1, a2, a3, a4, a5, a6, a7] = a.to_array();
    let [b0, b1, b2, b3, b4, b5, b6, b7] = b.to_array();
    (
        i16x8::new([a0, b0, a1, b1, a2, b2, a3, b3]),
        i16x8::new([a4, b4, a5, b5, a6, b6, a7, b7]),
    )
}
