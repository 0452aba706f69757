//! Elementary helpers of the factorisations: a column by value, a row swap that stays in
//! registers, and an overflow-safe `hypot` computed in `T`.

use nalgebra::{SMatrix, SVector};

use crate::scalar::Real;

/// Column `c` of `m` (zeros for `c >= C`, which no caller passes): `m.column(c).into_owned()`
/// without its panic paths (`into_owned` asserts the length of an iterator, and `column` its
/// index, where the optimiser cannot prove them).
#[inline]
pub(crate) fn column<T: Real, const R: usize, const C: usize>(
    m: &SMatrix<T, R, C>,
    c: usize,
) -> SVector<T, R> {
    let mut v = SVector::<T, R>::zeros();
    if c < C {
        v.copy_from(&m.column(c));
    }
    v
}

/// Swaps rows `i < j` of `rows` entry by entry (nothing for `i >= j` or out of range): a
/// whole-array swap of rows this size is a `memcpy` call on a Cortex-M, this stays in registers.
#[inline]
pub(crate) fn swap_rows<T, const N: usize>(rows: &mut [[T; N]], i: usize, j: usize) {
    if i < j
        && let Some((upper, lower)) = rows.split_at_mut_checked(j)
        && let (Some(x), Some(y)) = (upper.get_mut(i), lower.first_mut())
    {
        x.iter_mut()
            .zip(y.iter_mut())
            .for_each(|(u, v)| core::mem::swap(u, v));
    }
}

/// `√(a² + b²)` without intermediate overflow or underflow, computed in `T`.
///
/// Used instead of `hypot` because libm's `hypotf` works in `f64`, which is software-emulated
/// on single-precision FPUs (Cortex-M4F/M7): a few hundred cycles per call in the QR's inner
/// loop. Accurate to a couple of ulps; NaN in, NaN out.
#[inline]
pub(crate) fn hypot<T: Real>(a: T, b: T) -> T {
    let (a, b) = (a.abs(), b.abs());
    let (big, small) = if a >= b { (a, b) } else { (b, a) };
    if big == T::zero() {
        return big;
    }
    let r = small / big;
    big * (T::one() + r * r).sqrt()
}

#[cfg(test)]
mod tests {
    #[test]
    fn hypot_is_safe() {
        use super::hypot;
        assert_eq!(hypot(3.0f32, -4.0), 5.0);
        assert_eq!(hypot(0.0f32, 0.0), 0.0);
        assert_eq!(hypot(-2.0f64, 0.0), 2.0);
        assert!((hypot(3e30f32, 4e30) / 5e30 - 1.0).abs() < 1e-6);
        assert!((hypot(3e-30f32, 4e-30) / 5e-30 - 1.0).abs() < 1e-6);
        assert!(hypot(f32::NAN, 1.0).is_nan());
        assert!(hypot(1.0, f32::NAN).is_nan());
        assert_eq!(hypot(f32::INFINITY, 1.0), f32::INFINITY);
    }
}
