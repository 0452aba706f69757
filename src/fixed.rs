//! Integer-only projective transfer for cores without an FPU.
//!
//! Coordinates are [`Q16`] (Q16.16, `value = raw / 2¹⁶`, range ±32768, step 1.5e-5). A
//! projective map `P` (3 x (D+1): a homography for `D = 2`, a camera matrix `K [R | t]` for
//! `D = 3`) is quantised once, in floating point, into a [`FixedProjective`]; every transfer
//! after that is integer arithmetic only:
//!
//! `u = (Σ m₀ⱼ xⱼ + c₀) / (Σ m₂ⱼ xⱼ + c₂)`, `v = (Σ m₁ⱼ xⱼ + c₁) / (Σ m₂ⱼ xⱼ + c₂)`.
//!
//! Quantisation: each row of `P` is scaled by its own power of two `2^e_r` that brings its
//! largest coordinate coefficient just below 2 (and its constant below 2¹⁶). The coordinate
//! coefficients are then stored as Q2.29 `i32` (relative error ≤ 2⁻³⁰ of the row's largest)
//! and the constant column as Q.45 `i64`, so that a coefficient times a Q16.16 coordinate and
//! the constant share 45 fractional bits and add exactly in `i64`. The division undoes the row
//! scales with one shift, `u = (num 2^(16 + e₂ - e₀)) / den`, in `i64` with pre-shifts that
//! keep at least 30 significant bits in the divisor whenever the result fits Q16.16.
//!
//! Error bound (tested against `f64` in `tests`): for coordinates and results within ±4096 px,
//! `|fixed - exact| ≤ 2⁻¹⁵ px` (3.1e-5) for the image of the Q16.16 input; rounding the input
//! itself to Q16.16 adds at most 2⁻¹⁷ times the local scale of the map. All arithmetic is checked: values out of
//! range give [`Error::Overflow`], never a wrapped result.
//!
//! ```
//! use camgeom::fixed::{FixedHomography, Q16};
//! use camgeom::nalgebra::{Matrix3, Vector3};
//!
//! let h = Matrix3::new(1.2f64, 0.1, 30.0, -0.05, 0.9, 12.0, 2e-4, -1e-4, 1.0);
//! let fh = FixedHomography::from_matrix(&h)?; // quantised once, in floating point
//! for (x, y) in [(0i16, 0i16), (319, 0), (-40, 239), (160, 120), (1000, -700)] {
//!     // Integer arithmetic only from here on.
//!     let [u, v] = fh.transfer(&[Q16::from_int(x), Q16::from_int(y)])?;
//!     // The same transfer in f64: whole-pixel inputs are exact in Q16.16, so the bound is 2⁻¹⁵.
//!     let p = h * Vector3::new(f64::from(x), f64::from(y), 1.0);
//!     assert!((u.to_f64() - p.x / p.z).abs() <= 1.0 / 32768.0);
//!     assert!((v.to_f64() - p.y / p.z).abs() <= 1.0 / 32768.0);
//! }
//! // Out of range is an error, never a wrapped coordinate.
//! let far = FixedHomography::from_matrix(&Matrix3::from_diagonal(&Vector3::new(1e4, 1.0, 1.0)))?;
//! assert_eq!(far.transfer(&[Q16::from_int(100), Q16::ZERO]), Err(camgeom::Error::Overflow));
//! # Ok::<(), camgeom::Error>(())
//! ```
#![deny(clippy::arithmetic_side_effects)]

use nalgebra::Matrix3;

use crate::camera::Intrinsics;
use crate::scalar::Real;
use crate::transform::Pose;
use crate::{Error, Result};

/// A Q16.16 fixed-point number: `value = raw / 65536`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(transparent)]
pub struct Q16(i32);

impl Q16 {
    /// Fractional bits.
    pub const FRAC_BITS: u32 = 16;
    /// 1.0
    pub const ONE: Q16 = Q16(1 << 16);
    /// 0.0
    pub const ZERO: Q16 = Q16(0);

    /// From the raw two's-complement bits.
    pub const fn from_bits(raw: i32) -> Self {
        Q16(raw)
    }
    /// The raw bits.
    pub const fn to_bits(self) -> i32 {
        self.0
    }
    /// From a whole number (every `i16` is exact).
    pub const fn from_int(v: i16) -> Self {
        Q16((v as i32) << 16)
    }
    /// Rounds a float to the nearest Q16.16. Errors: NaN/inf, or outside ±32768.
    pub fn from_float<T: Real>(v: T) -> Result<Self> {
        if !v.finite() {
            return Err(Error::NonFinite);
        }
        let scaled = libm::round(v.to_f64() * 65536.0);
        if !(-2_147_483_648.0..=2_147_483_647.0).contains(&scaled) {
            return Err(Error::Overflow);
        }
        Ok(Q16(scaled as i32))
    }
    /// To `f32` (exact below 2⁸ and within 2⁻¹⁶·2⁻⁸ relative otherwise).
    pub fn to_f32(self) -> f32 {
        self.0 as f32 / 65536.0
    }
    /// To `f64` (exact).
    pub fn to_f64(self) -> f64 {
        f64::from(self.0) / 65536.0
    }
    /// `round(v 2¹⁶)` saturated to the range, NaN to zero: the conversion for positions that
    /// must not fail (tracker input).
    pub fn saturating_from_f32(v: f32) -> Self {
        let s = v * 65536.0;
        // `as` saturates (and takes NaN to 0).
        Q16(libm::roundf(s) as i32)
    }
    /// `⌊self / 2ⁿ⌋` (arithmetic shift).
    pub const fn shr(self, n: u32) -> Self {
        Q16(self.0 >> if n > 31 { 31 } else { n })
    }
    /// `⌊self + 1/2⌋`, saturated: the nearest whole number.
    pub const fn round(self) -> i32 {
        self.0.saturating_add(1 << 15) >> 16
    }
}

/// Saturating: a position never wraps to the other side of the range.
impl core::ops::Add for Q16 {
    type Output = Q16;
    fn add(self, rhs: Q16) -> Q16 {
        Q16(self.0.saturating_add(rhs.0))
    }
}

/// Saturating, as [`Q16`]'s `Add`.
impl core::ops::Sub for Q16 {
    type Output = Q16;
    fn sub(self, rhs: Q16) -> Q16 {
        Q16(self.0.saturating_sub(rhs.0))
    }
}

/// Fractional bits of the coordinate coefficients (Q2.29 in `i32`, before the row scale).
const COEF_BITS: i32 = 29;
/// Fractional bits of the constant column and of every product (`COEF_BITS + 16`).
const SUM_BITS: i32 = COEF_BITS + 16;

/// A projective map from `D`-dimensional Q16.16 points to the image plane, quantised for
/// integer-only evaluation (see the module documentation for the format and its error bound).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FixedProjective<const D: usize> {
    /// Coordinate coefficients `m[row][col] 2^e_row`, Q2.29.
    m: [[i32; D]; 3],
    /// Constant column `c[row] 2^e_row`, Q.45.
    c: [i64; 3],
    /// Output shifts `16 + e_2 - e_r` for `u` and `v`, undoing the row scales.
    k: [i32; 2],
}

/// Integer homography transfer `x' ~ H x`.
pub type FixedHomography = FixedProjective<2>;
/// Integer pinhole projection `u ~ K [R | t] X` (no lens distortion).
pub type FixedProjection = FixedProjective<3>;

/// Exponent `x` with `|v| = f 2^x`, `f` in `[0.5, 1)`; `None` for zero.
fn exponent(v: f64) -> Option<i32> {
    if v == 0.0 {
        None
    } else {
        Some(libm::frexp(v).1)
    }
}

impl<const D: usize> FixedProjective<D> {
    /// Quantises the map with rows `[m_r0 .. m_r(D-1) | c_r]` given as coordinate coefficients
    /// `m` and constant column `c`.
    ///
    /// Each row `r` is scaled by its own power of two `2^e_r` (the largest with
    /// `max_j |m_rj| 2^e_r < 2` and `|c_r| 2^e_r < 2^16`), so every row keeps 30 significant
    /// bits however different the rows' magnitudes are (the projective row of a homography is
    /// typically 10⁻³ of the others); the output shifts undo the scales exactly.
    ///
    /// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when the denominator row is zero.
    pub fn from_parts<T: Real>(m: &[[T; D]; 3], c: &[T; 3]) -> Result<Self> {
        if !m.iter().flatten().chain(c.iter()).all(|v| v.finite()) {
            return Err(Error::NonFinite);
        }
        let mut out = Self {
            m: [[0; D]; 3],
            c: [0; 3],
            k: [0; 2],
        };
        let mut e = [0i32; 3];
        for (((row_in, c_in), (row_out, c_out)), e_r) in m
            .iter()
            .zip(c.iter())
            .zip(out.m.iter_mut().zip(out.c.iter_mut()))
            .zip(e.iter_mut())
        {
            let max_m = row_in
                .iter()
                .fold(0.0f64, |a, v| a.max(libm::fabs(v.to_f64())));
            let from_m = exponent(max_m).map(|x| 1i32.saturating_sub(x));
            let from_c = exponent(c_in.to_f64()).map(|x| 16i32.saturating_sub(x));
            *e_r = match (from_m, from_c) {
                (Some(a), Some(b)) => a.min(b),
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => 0,
            };
            for (v, o) in row_in.iter().zip(row_out.iter_mut()) {
                // |v 2^e| < 2, so the quantised value is below 2^30 in magnitude.
                *o = libm::round(libm::ldexp(v.to_f64(), e_r.saturating_add(COEF_BITS))) as i32;
            }
            // |c 2^e| < 2^16, so the quantised value is below 2^61 in magnitude.
            *c_out = libm::round(libm::ldexp(c_in.to_f64(), e_r.saturating_add(SUM_BITS))) as i64;
        }
        if out.m[2].iter().all(|v| *v == 0) && out.c[2] == 0 {
            return Err(Error::Degenerate);
        }
        let [e0, e1, e2] = e;
        out.k = [
            16i32.saturating_add(e2).saturating_sub(e0),
            16i32.saturating_add(e2).saturating_sub(e1),
        ];
        Ok(out)
    }

    /// The three sums `Σ m_rj x_j + c_r`, with 45 fractional bits.
    fn sums(&self, x: &[Q16; D]) -> Result<[i64; 3]> {
        let mut s = self.c;
        for (acc, row) in s.iter_mut().zip(self.m.iter()) {
            for (m, xj) in row.iter().zip(x.iter()) {
                // |m| < 2^30 and |x| <= 2^31: the product is below 2^61 and cannot overflow.
                let p = i64::from(*m)
                    .checked_mul(i64::from(xj.0))
                    .ok_or(Error::Overflow)?;
                *acc = acc.checked_add(p).ok_or(Error::Overflow)?;
            }
        }
        Ok(s)
    }

    /// Evaluates the map at `x`. Errors: [`Error::AtInfinity`] when the denominator is zero at
    /// the working precision; [`Error::Overflow`] when the image falls outside Q16.16.
    pub fn transfer(&self, x: &[Q16; D]) -> Result<[Q16; 2]> {
        let [nu, nv, den] = self.sums(x)?;
        if den == 0 {
            return Err(Error::AtInfinity);
        }
        let [ku, kv] = self.k;
        Ok([div_shift(nu, den, ku)?, div_shift(nv, den, kv)?])
    }
}

/// Significant bits of `|v|`.
fn bits(v: i64) -> i32 {
    64i32.saturating_sub(v.unsigned_abs().leading_zeros() as i32)
}

/// `v / 2^s` rounded to nearest (ties up), for `s` in `0..63`.
fn shr_round(v: i64, s: i32) -> i64 {
    if s <= 0 {
        return v;
    }
    let s = s.min(62) as u32;
    (v >> s).saturating_add(i64::from((v >> (s.saturating_sub(1))) & 1 != 0))
}

/// `round(n 2^k / d)` as Q16.16 bits, in `i64` only: operands are pre-shifted so that the
/// shifted numerator fits 62 bits. A result that fits `i32` leaves the divisor at least 30
/// significant bits (`|n 2^k / d| < 2^31`), so the pre-shift costs no accuracy that matters.
fn div_shift(n: i64, d: i64, k: i32) -> Result<Q16> {
    let (mut n, mut d) = (n, d);
    if k >= 0 {
        let s = bits(n).saturating_add(k).saturating_sub(62).max(0);
        n = shr_round(n, s);
        d = shr_round(d, s);
        if d == 0 {
            return Err(Error::Overflow);
        }
        n = n.checked_shl(k as u32).ok_or(Error::Overflow)?;
    } else {
        let want = k.saturating_neg();
        let room = 62i32.saturating_sub(bits(d)).clamp(0, want);
        d = d.checked_shl(room as u32).ok_or(Error::Overflow)?;
        n = shr_round(n, want.saturating_sub(room));
    }
    let q = n.checked_div(d).ok_or(Error::Overflow)?;
    let r = n.checked_rem(d).ok_or(Error::Overflow)?;
    // Round half away from zero: compare 2|r| with |d|.
    let q = if r.unsigned_abs().saturating_mul(2) >= d.unsigned_abs() {
        if (n < 0) != (d < 0) {
            q.checked_sub(1)
        } else {
            q.checked_add(1)
        }
        .ok_or(Error::Overflow)?
    } else {
        q
    };
    i32::try_from(q).map(Q16).map_err(|_| Error::Overflow)
}

impl FixedHomography {
    /// Quantises a homography `H` (any scale).
    pub fn from_matrix<T: Real>(h: &Matrix3<T>) -> Result<Self> {
        Self::from_parts(
            &[[h.m11, h.m12], [h.m21, h.m22], [h.m31, h.m32]],
            &[h.m13, h.m23, h.m33],
        )
    }
}

impl FixedProjection {
    /// Quantises the pinhole projection `P = K [R | t]` (lens distortion is not modelled).
    // Floating-point set-up, done once per pose: the integer-overflow lint does not apply.
    #[allow(clippy::arithmetic_side_effects)]
    pub fn from_camera<T: Real>(k: &Intrinsics<T>, pose: &Pose<T>) -> Result<Self> {
        let r = pose.rotation();
        let p = k.matrix() * r.matrix();
        let c = k.matrix() * pose.translation();
        Self::from_parts(
            &[
                [p.m11, p.m12, p.m13],
                [p.m21, p.m22, p.m23],
                [p.m31, p.m32, p.m33],
            ],
            &[c.x, c.y, c.z],
        )
    }

    /// Projects a world point given in Q16.16 world units. Errors: [`Error::BehindCamera`] when
    /// the point is on or behind the camera plane; [`Error::Overflow`] outside the Q16.16 range.
    pub fn project(&self, x: &[Q16; 3]) -> Result<[Q16; 2]> {
        let [_, _, den] = self.sums(x)?;
        // The row scale 2^e is positive, so the sign of `den` is the sign of the depth Z_c.
        if den <= 0 {
            return Err(Error::BehindCamera);
        }
        self.transfer(x)
    }
}

/// `⌊√v⌋`. Out of line on purpose: a 64-bit root is a few hundred instructions on a Cortex-M,
/// called once a KLT level per track ([`crate::klt`]'s minimum eigenvalue) and once a corner
/// candidate (Shi-Tomasi); when LLVM inlines core's `isqrt` into the KLT's `track_point`
/// (which it does once fewer functions call it) the M7 main job's flow costs 2.5 % more
/// (2.81M -> 2.88M instructions a frame, measured), so each caller's code does not depend
/// on the other's.
///
/// On x86-64 and aarch64 the root comes from the hardware's correctly rounded `f64` square
/// root and one integer correction (a `v` of up to 64 bits rounds to 53 in `f64`, so the
/// rounded root is within one of `⌊√v⌋`; checked against core's at every edge in the tests):
/// a few instructions where core's is a few dozen dependent steps (a fifth of the host's
/// Shi-Tomasi, measured). The boards keep core's integer root: most have no double-precision
/// unit.
#[inline(never)]
pub(crate) fn isqrt(v: u64) -> u64 {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    {
        // Saturating cast: at most 2^32 (√(2^64 - 1) rounds up to it).
        let r = libm::sqrt(v as f64) as u64;
        // `r <= 2^32 + 1`: its square cannot wrap in 128 bits.
        let sq = |r: u64| u128::from(r).wrapping_mul(u128::from(r));
        if sq(r) > u128::from(v) {
            r.saturating_sub(1)
        } else if sq(r.saturating_add(1)) <= u128::from(v) {
            r.saturating_add(1)
        } else {
            r
        }
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        v.isqrt()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::arithmetic_side_effects)]
    use super::*;
    use crate::camera::Camera;
    use nalgebra::{Point2, Point3, Vector3};

    /// xorshift64*: a small deterministic generator for test inputs.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * self.next()
        }
    }

    fn q(v: f64) -> Q16 {
        Q16::from_float(v).unwrap()
    }

    /// The host's root through `f64` equals core's integer root at every square, one either
    /// side of it (where a rounding to 53 bits could tip the floor), the ends of the range, and
    /// random values at every bit length.
    #[test]
    fn isqrt_matches_core() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let check = |v: u64| assert_eq!(isqrt(v), v.isqrt(), "v = {v}");
        for v in [
            0,
            1,
            2,
            3,
            4,
            u64::MAX,
            u64::MAX - 1,
            1 << 63,
            (1 << 53) + 1,
        ] {
            check(v);
        }
        for bits in 1..=32u32 {
            for _ in 0..2000 {
                let r = (rng.next() * (1u64 << bits) as f64) as u64 | (1 << (bits - 1));
                let s = r * r;
                for v in [s - 1, s, s.saturating_add(1), s.saturating_add(2 * r)] {
                    check(v);
                }
            }
        }
        for bits in 1..=64u32 {
            for _ in 0..2000 {
                check((rng.next() * 2f64.powi(bits as i32)) as u64);
            }
        }
    }

    #[test]
    fn q16_conversions() {
        assert_eq!(Q16::from_float(1.5f32).unwrap().to_bits(), 3 << 15);
        assert_eq!(Q16::from_int(-3).to_f64(), -3.0);
        assert_eq!(Q16::from_float(f32::NAN), Err(Error::NonFinite));
        assert_eq!(Q16::from_float(40000.0f32), Err(Error::Overflow));
        assert_eq!(Q16::from_float(-32768.0f64).unwrap().to_bits(), i32::MIN);
    }

    /// Random homographies from a plane seen by two cameras: the error bound of the module docs.
    #[test]
    fn homography_transfer_matches_f64_within_bound() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let (mut worst, mut worst_f32) = (0.0f64, 0.0f64);
        for _ in 0..200 {
            let h = Matrix3::new(
                rng.range(0.5, 1.5),
                rng.range(-0.3, 0.3),
                rng.range(-200.0, 200.0),
                rng.range(-0.3, 0.3),
                rng.range(0.5, 1.5),
                rng.range(-200.0, 200.0),
                rng.range(-5e-4, 5e-4),
                rng.range(-5e-4, 5e-4),
                1.0,
            ) * rng.range(0.01, 100.0);
            let fh = FixedHomography::from_matrix(&h).unwrap();
            for _ in 0..50 {
                let (x, y) = (rng.range(0.0, 640.0), rng.range(0.0, 480.0));
                let (xq, yq) = (q(x), q(y));
                // Exact image of the quantised input, so only the transfer's own error remains.
                let p = h * Vector3::new(xq.to_f64(), yq.to_f64(), 1.0);
                let (u, v) = (p.x / p.z, p.y / p.z);
                if u.abs() > 4096.0 || v.abs() > 4096.0 {
                    continue;
                }
                let [uq, vq] = fh.transfer(&[xq, yq]).unwrap();
                worst = worst
                    .max((uq.to_f64() - u).abs())
                    .max((vq.to_f64() - v).abs());
                // The f32 path on the same input, for comparison.
                let hf = h.cast::<f32>();
                let pf = hf * Vector3::new(xq.to_f32(), yq.to_f32(), 1.0);
                let (uf, vf) = (f64::from(pf.x / pf.z), f64::from(pf.y / pf.z));
                worst_f32 = worst_f32.max((uf - u).abs()).max((vf - v).abs());
            }
        }
        // Bound of the module docs: 2^-15 px = half the Q16.16 output step (2^-17) for the
        // rounding, plus coefficient quantisation (2^-30 relative per row, < 2^-17 at 4096 px).
        std::println!(
            "homography transfer worst error: Q16.16 {worst:.3e} px, f32 {worst_f32:.3e} px"
        );
        // The integer path is at least as accurate as the f32 one (whose step at 4096 px is
        // 2.4e-4): it carries 45 fractional bits until the final division.
        assert!(worst <= worst_f32, "fixed {worst} vs f32 {worst_f32}");
        assert!(worst <= 1.0 / 32768.0, "worst {worst}");
    }

    #[test]
    fn projection_matches_float_camera() {
        let k = Intrinsics::new(535.9f64, 535.9, 342.3, 235.6).unwrap();
        let cam = Camera::pinhole(k);
        let pose = Pose::from_rodrigues(
            Vector3::new(0.1687, 0.2757, 0.0135),
            Vector3::new(-0.0752, -0.1090, 0.3997),
        )
        .unwrap();
        let fp = FixedProjection::from_camera(&k, &pose).unwrap();
        let mut worst = 0.0f64;
        for i in 0..9 {
            for j in 0..6 {
                let xq = [q(0.025 * i as f64), q(0.025 * j as f64), Q16::ZERO];
                let x = Point3::new(xq[0].to_f64(), xq[1].to_f64(), 0.0);
                let u: Point2<f64> = cam.project(&pose, &x).unwrap();
                let [uq, vq] = fp.project(&xq).unwrap();
                worst = worst
                    .max((uq.to_f64() - u.x).abs())
                    .max((vq.to_f64() - u.y).abs());
            }
        }
        assert!(worst <= 1.0 / 32768.0, "worst {worst}");
        // A point behind the camera is a typed error, as on the float path.
        let behind = [Q16::ZERO, Q16::ZERO, Q16::from_int(-2)];
        assert_eq!(fp.project(&behind), Err(Error::BehindCamera));
    }

    #[test]
    fn bad_maps_and_points_are_errors() {
        let nan = Matrix3::new(f32::NAN, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
        assert_eq!(FixedHomography::from_matrix(&nan), Err(Error::NonFinite));
        let zero = Matrix3::<f32>::zeros();
        assert_eq!(FixedHomography::from_matrix(&zero), Err(Error::Degenerate));
        // A translation far beyond the Q16.16 range quantises (rows are scaled independently)
        // but its images cannot be represented: an error, not a wrapped coordinate.
        let far = Matrix3::new(1e-6f64, 0.0, 1e6, 0.0, 1e-6, 0.0, 0.0, 0.0, 1.0);
        let ff = FixedHomography::from_matrix(&far).unwrap();
        assert_eq!(ff.transfer(&[Q16::ZERO, Q16::ZERO]), Err(Error::Overflow));
        let denless = Matrix3::new(1.0f32, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        assert_eq!(
            FixedHomography::from_matrix(&denless),
            Err(Error::Degenerate)
        );
        // Points on the vanishing line map to infinity.
        // (h31 = 1/64 is exact in binary, so x = -64 is exactly on the vanishing line.)
        let h = Matrix3::new(1.0f64, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0 / 64.0, 0.0, 1.0);
        let fh = FixedHomography::from_matrix(&h).unwrap();
        assert_eq!(
            fh.transfer(&[Q16::from_int(-64), Q16::ZERO]),
            Err(Error::AtInfinity)
        );
        // Near the vanishing line the image leaves the Q16.16 range: an error, not a wrap.
        assert_eq!(
            fh.transfer(&[q(-63.99), Q16::from_int(10)]),
            Err(Error::Overflow)
        );
        // Extreme inputs never panic.
        let ext = [Q16::from_bits(i32::MIN), Q16::from_bits(i32::MAX)];
        let _ = fh.transfer(&ext);
    }
}
