//! The scalar bound shared by the floating-point code.

use nalgebra::RealField;

/// A floating-point scalar: `f32` (the default everywhere) or `f64`.
///
/// A thin alias of [`RealField`] + [`Copy`] with the few constants camgeom's tolerances use.
pub trait Real: RealField + Copy {
    /// Machine epsilon of the type.
    const EPSILON: Self;
    /// Converts an `f64` literal (exact for `f64`, rounded for `f32`).
    fn lit(v: f64) -> Self;
    /// Converts to `f64` (for reporting and fixed-point quantisation).
    fn to_f64(self) -> f64;
    /// `true` when neither NaN nor infinite.
    fn finite(self) -> bool;
    /// The nearest integer (halves away from zero) when `lo <= self <= hi`, else `None` (and
    /// for NaN). In the type itself: no conversion to `f64`, which is software on a core with
    /// a single-precision FPU.
    fn round_within(self, lo: i32, hi: i32) -> Option<i32>;
}

impl Real for f32 {
    const EPSILON: Self = f32::EPSILON;
    #[inline]
    fn lit(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn round_within(self, lo: i32, hi: i32) -> Option<i32> {
        (self >= lo as f32 && self <= hi as f32).then(|| libm::roundf(self) as i32)
    }
}

impl Real for f64 {
    const EPSILON: Self = f64::EPSILON;
    #[inline]
    fn lit(v: f64) -> Self {
        v
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn round_within(self, lo: i32, hi: i32) -> Option<i32> {
        (self >= f64::from(lo) && self <= f64::from(hi)).then(|| libm::round(self) as i32)
    }
}

/// `Ok(())` when every value is finite, else [`crate::Error::NonFinite`].
#[inline]
pub(crate) fn check_finite<T: Real>(values: &[T]) -> crate::Result<()> {
    if values.iter().all(|v| v.finite()) {
        Ok(())
    } else {
        Err(crate::Error::NonFinite)
    }
}

/// `x > bound`, false for NaN: the form of every "not degenerate" test, so that NaN is always
/// degenerate.
#[inline]
pub(crate) fn above<T: Real>(x: T, bound: T) -> bool {
    x > bound
}

/// The larger of `a` and `b` by one comparison (`a` when `b` is NaN): for a running maximum
/// that starts finite, the value `a.max(b)` gives, without the `fmaxf` library call that
/// becomes on cores with no float maximum instruction (Cortex-M4/M7 call it for every entry of
/// a scan).
#[inline]
pub(crate) fn larger<T: Real>(a: T, b: T) -> T {
    if b > a { b } else { a }
}

/// `x ≤ bound`, false for NaN: the form of every "within tolerance" test, so that NaN never is.
#[inline]
pub(crate) fn at_most<T: Real>(x: T, bound: T) -> bool {
    x <= bound
}
