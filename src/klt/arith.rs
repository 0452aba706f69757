//! The two arithmetic paths of the tracker: [`Fixed`] (Q16.16 points, integer solve) and `f32`.
//!
//! Both share the integer inner loops (14-bit bilinear weights, `i16` patches and derivatives,
//! `i64` sums); they differ in how a point is represented, how the bilinear weights are derived
//! from it, and how the 2x2 system `G δ = -b` is solved.

use super::{FlowStatus, LkParams};

/// Bits of the bilinear weights: `w00 + w01 + w10 + w11 = 2¹⁴`.
pub const W_BITS: u32 = 14;
pub use crate::fixed::Q16;

/// One in Q16.16, raw.
const ONE: i32 = Q16::ONE.to_bits();

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::Fixed {}
    impl Sealed for super::Q16 {}
    impl Sealed for f32 {}
}

/// Marker type of the fixed-point path: coordinates are [`Q16`] (Q16.16, saturating), the
/// 2x2 solve and every threshold are integers. For cores without an FPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fixed;

/// A point coordinate of one tracking path, in pixels: [`Q16`] (saturating) or `f32`; what
/// the tracker does with one besides `+` and `-`.
pub trait Coordinate:
    Copy
    + PartialEq
    + core::fmt::Debug
    + Default
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + sealed::Sealed
{
    /// Zero (for `const` initialisers: a tracker in a zeroed `static`).
    const ZERO: Self;
    /// `halves / 2` pixels (`(win - 1) / 2` may be fractional).
    fn from_half_px(halves: i32) -> Self;
    /// `v` whole pixels.
    fn from_px(v: i32) -> Self;
    /// `c / 2^level`: the position on pyramid level `level`.
    fn down(self, level: u32) -> Self;
    /// `2 c`.
    fn twice(self) -> Self;
    /// `c / 2`.
    fn half(self) -> Self;
    /// In pixels (reporting).
    fn to_f32(self) -> f32;
    /// `⌊c + 1/2⌋`, saturated: the nearest pixel.
    fn round(self) -> i32;
}

impl Coordinate for Q16 {
    const ZERO: Q16 = Q16::ZERO;
    fn from_half_px(halves: i32) -> Q16 {
        Q16::from_bits(halves.saturating_mul(ONE / 2))
    }
    fn from_px(v: i32) -> Q16 {
        Q16::from_bits(v.saturating_mul(ONE))
    }
    fn down(self, level: u32) -> Q16 {
        self.shr(level)
    }
    fn twice(self) -> Q16 {
        Q16::from_bits(self.to_bits().saturating_mul(2))
    }
    fn half(self) -> Q16 {
        self.shr(1)
    }
    fn to_f32(self) -> f32 {
        Q16::to_f32(self)
    }
    fn round(self) -> i32 {
        Q16::round(self)
    }
}

impl Coordinate for f32 {
    const ZERO: f32 = 0.0;
    fn from_half_px(halves: i32) -> f32 {
        halves as f32 * 0.5
    }
    fn from_px(v: i32) -> f32 {
        v as f32
    }
    fn down(self, level: u32) -> f32 {
        self * (1.0 / (1u32 << level.min(31)) as f32)
    }
    fn twice(self) -> f32 {
        self * 2.0
    }
    fn half(self) -> f32 {
        self * 0.5
    }
    fn to_f32(self) -> f32 {
        self
    }
    fn round(self) -> i32 {
        libm::floorf(self + 0.5) as i32
    }
}

/// Bilinear weights of a sub-pixel position: integer corner `(x, y)` and
/// `[w00, w01, w10, w11]` summing to `2¹⁴` (`w01` is the right neighbour, `w10` the one below).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bilinear {
    /// `⌊x⌋`.
    pub x: i32,
    /// `⌊y⌋`.
    pub y: i32,
    /// The four weights, Q14.
    pub w: [i32; 4],
}

/// The arithmetic of one tracking path (sealed: implemented for [`Fixed`] and `f32`).
pub trait FlowArith: sealed::Sealed {
    /// A point coordinate.
    type Coord: Coordinate;
    /// Per-call constants derived from the [`LkParams`] (thresholds in this path's units).
    type Params: Copy;
    /// The inverted gradient matrix of one window.
    type Gram: Copy;

    /// Prepares the thresholds of `cfg` for windows of `area` pixels.
    fn params(cfg: &LkParams, area: u32) -> Self::Params;
    /// Integer corner and bilinear weights of `(x, y)`; `None` when not finite or far out of
    /// range.
    fn bilinear(x: Self::Coord, y: Self::Coord) -> Option<Bilinear>;
    /// Inverts the gradient matrix `G = [a11 a12; a12 a22]` (sums of `Ix Iy` products, `Ix` in
    /// Scharr units), or rejects the window: [`FlowStatus::SmallEigenvalue`] when
    /// `λ_min(G) / (2²⁰ area) < min_eigenvalue` or `det G / 2⁴⁰ < 2⁻²³` (OpenCV's tests).
    fn gram(a11: i64, a12: i64, a22: i64, p: &Self::Params) -> Result<Self::Gram, FlowStatus>;
    /// The update `δ = -G⁻¹ b`.
    fn step(g: &Self::Gram, b1: i64, b2: i64) -> [Self::Coord; 2];
    /// `|δ|² <= ε²`.
    fn converged(d: [Self::Coord; 2], p: &Self::Params) -> bool;
    /// `|δ + δ_prev| < 0.01` in both coordinates (the iteration oscillates).
    fn oscillates(d: [Self::Coord; 2], prev: [Self::Coord; 2]) -> bool;
    /// The error measure `Σ |J - I| / (32 area)` (mean absolute difference, grey levels) from
    /// the sum in `1/32` grey levels.
    fn error(sum_abs: u64, area: u32) -> Self::Coord;
    /// `|a - b|² > t²` with `t` the forward-backward threshold of the parameters.
    fn beyond(a: [Self::Coord; 2], b: [Self::Coord; 2], p: &Self::Params) -> bool;
}

/// `1 / d` for `d > 0`, normalised: `d ≈ d₃₂ 2^(32 - ldz)` with `d₃₂` its top 32 bits and
/// `r = ⌊2⁶³ / d₃₂⌋`, so `1 / d ≈ r 2^(ldz - 95)` (relative error below 2⁻³⁰). One division
/// when a window's `G` is inverted; every step of the iteration is then multiplications (a
/// 64-bit division is a library call of a few hundred instructions on a Cortex-M).
#[derive(Debug, Clone, Copy)]
struct Reciprocal {
    r: u64,
    ldz: i32,
}

impl Reciprocal {
    fn new(d: i64) -> Self {
        let d = d.max(1) as u64;
        let ldz = d.leading_zeros() as i32;
        let d32 = ((d << ldz) >> 32).max(1); // in [2³¹, 2³²)
        Self {
            r: (1u64 << 63) / d32,
            ldz,
        }
    }

    /// `round(n · 2^shift / d)` with at least 30 significant bits, saturated to `±limit`:
    /// `n ≈ n₃₂ 2^(32 - lz)`, `q = n₃₂ r < 2⁶⁴`, `n / d ≈ q 2^(ldz - lz - 63)`.
    fn mul(&self, n: i64, shift: i32, limit: i64) -> i64 {
        if n == 0 {
            return 0;
        }
        let an = n.unsigned_abs();
        let lz = an.leading_zeros() as i32;
        let n32 = (an << lz) >> 32; // in [2³¹, 2³²)
        let q = n32 * self.r; // < 2³² · 2³² (r <= 2³²)
        let e = shift + self.ldz - lz - 63;
        let mag: u64 = if e >= 0 {
            if e >= 63 || q > (u64::MAX >> e) {
                u64::MAX
            } else {
                q << e
            }
        } else if -e >= 64 {
            0
        } else {
            let s = (-e) as u32;
            (q >> s) + ((q >> (s - 1)) & 1)
        };
        let mag = mag.min(limit as u64) as i64;
        if n < 0 { -mag } else { mag }
    }
}

fn bit_len(v: u64) -> u32 {
    64 - v.leading_zeros()
}

/// Largest step accepted in one iteration (Q16: 2¹² px), so points cannot overflow.
const MAX_STEP_Q16: i64 = 1 << 28;

/// Thresholds of the fixed path.
#[derive(Debug, Clone, Copy)]
pub struct FixedParams {
    /// `min_eigenvalue · 2²⁰ · area`.
    min_eig: u64,
    /// `ε² · 2³²`.
    eps2: i64,
    /// `(fb threshold)² · 2³²`.
    fb2: i64,
}

/// `G` normalised by `2^s` (entries below 2³⁰) with the reciprocal of its determinant.
#[derive(Debug, Clone, Copy)]
pub struct FixedGram {
    a11: i64,
    a12: i64,
    a22: i64,
    inv_det: Reciprocal,
    shift: i32,
}

impl FlowArith for Fixed {
    type Coord = Q16;
    type Params = FixedParams;
    type Gram = FixedGram;

    fn params(cfg: &LkParams, area: u32) -> FixedParams {
        let cfg = cfg.config();
        let sq = |v: f32| {
            let q = f64::from(v) * f64::from(ONE);
            (q * q).min(i64::MAX as f64) as i64
        };
        FixedParams {
            min_eig: (f64::from(cfg.min_eigenvalue) * (1u64 << 20) as f64 * f64::from(area)) as u64,
            eps2: sq(cfg.epsilon),
            fb2: cfg.fb_threshold.map_or(i64::MAX, sq),
        }
    }
    fn bilinear(x: Q16, y: Q16) -> Option<Bilinear> {
        let (x, y) = (x.to_bits(), y.to_bits());
        let (a, b) = (i64::from(x & 0xFFFF), i64::from(y & 0xFFFF));
        let one = i64::from(ONE);
        // (2¹⁶ - a)(2¹⁶ - b) / 2¹⁸, rounded: Q32 → Q14.
        let r = |p: i64| ((p + (1 << 17)) >> 18) as i32;
        let w00 = r((one - a) * (one - b));
        let w01 = r(a * (one - b));
        let w10 = r((one - a) * b);
        Some(Bilinear {
            x: x >> 16,
            y: y >> 16,
            w: [w00, w01, w10, (1 << W_BITS) - w00 - w01 - w10],
        })
    }
    fn gram(a11: i64, a12: i64, a22: i64, p: &FixedParams) -> Result<FixedGram, FlowStatus> {
        let m = a11
            .unsigned_abs()
            .max(a12.unsigned_abs())
            .max(a22.unsigned_abs());
        let shift = bit_len(m).saturating_sub(30) as i32;
        let (a11, a12, a22) = (a11 >> shift, a12 >> shift, a22 >> shift);
        let diff = (a11 - a22).unsigned_abs();
        let disc = diff * diff + 4 * a12.unsigned_abs() * a12.unsigned_abs();
        let lmin2 = (a11 + a22).max(0) as u64; // 2 λ_min = a11 + a22 - √disc
        let lmin2 = lmin2.saturating_sub(crate::fixed::isqrt(disc));
        // λ_min · 2^shift < min_eig  ⇔  2 λ_min · 2^shift < 2 min_eig.
        if lmin2.saturating_mul(1u64 << shift.clamp(0, 62)) < p.min_eig.saturating_mul(2) {
            return Err(FlowStatus::SmallEigenvalue);
        }
        let det = a11 * a22 - a12 * a12;
        // OpenCV: det / 2⁴⁰ < 2⁻²³  ⇔  det' · 2^(2 shift) < 2¹⁷.
        let small = if 2 * shift >= 17 {
            det < 1
        } else {
            det < (1i64 << (17 - 2 * shift))
        };
        if small {
            return Err(FlowStatus::SmallEigenvalue);
        }
        Ok(FixedGram {
            a11,
            a12,
            a22,
            inv_det: Reciprocal::new(det),
            shift,
        })
    }
    fn step(g: &FixedGram, b1: i64, b2: i64) -> [Q16; 2] {
        let m = b1.unsigned_abs().max(b2.unsigned_abs());
        let sb = bit_len(m).saturating_sub(31) as i32;
        let (b1, b2) = (b1 >> sb, b2 >> sb);
        // δ = -adj(G) b / det, adj(G) = [a22 -a12; -a12 a11].
        let nx = g.a12 * b2 - g.a22 * b1;
        let ny = g.a12 * b1 - g.a11 * b2;
        let e = 16 + sb - g.shift;
        [
            Q16::from_bits(g.inv_det.mul(nx, e, MAX_STEP_Q16) as i32),
            Q16::from_bits(g.inv_det.mul(ny, e, MAX_STEP_Q16) as i32),
        ]
    }
    fn converged(d: [Q16; 2], p: &FixedParams) -> bool {
        let [x, y] = d.map(|c| i64::from(c.to_bits()));
        x * x + y * y <= p.eps2
    }
    fn oscillates(d: [Q16; 2], prev: [Q16; 2]) -> bool {
        let s = |a: Q16, b: Q16| {
            (i64::from(a.to_bits()) + i64::from(b.to_bits())).abs() * 100 < i64::from(ONE)
        };
        s(d[0], prev[0]) && s(d[1], prev[1])
    }
    fn error(sum_abs: u64, area: u32) -> Q16 {
        // Σ / (32 area) in Q16 = (Σ << 11) / area.
        Q16::from_bits(((sum_abs << 11) / u64::from(area.max(1))).min(i32::MAX as u64) as i32)
    }
    fn beyond(a: [Q16; 2], b: [Q16; 2], p: &FixedParams) -> bool {
        let [dx, dy] = [0, 1].map(|k| {
            let c = |v: [Q16; 2]| i64::from(v.get(k).map_or(0, |q| q.to_bits()));
            c(a) - c(b)
        });
        dx * dx + dy * dy > p.fb2
    }
}

/// Thresholds of the `f32` path.
#[derive(Debug, Clone, Copy)]
pub struct FloatParams {
    min_eig: f32,
    eps2: f32,
    fb2: f32,
    area: f32,
}

/// `G` scaled by `2⁻²⁰` and `1 / det`.
#[derive(Debug, Clone, Copy)]
pub struct FloatGram {
    a11: f32,
    a12: f32,
    a22: f32,
    inv_det: f32,
}

/// OpenCV's `FLT_SCALE`.
const FLT_SCALE: f32 = 1.0 / (1u32 << 20) as f32;

impl FlowArith for f32 {
    type Coord = f32;
    type Params = FloatParams;
    type Gram = FloatGram;

    fn params(cfg: &LkParams, area: u32) -> FloatParams {
        let cfg = cfg.config();
        let e = cfg.epsilon;
        let fb = cfg.fb_threshold.unwrap_or(f32::INFINITY);
        FloatParams {
            min_eig: cfg.min_eigenvalue,
            eps2: e * e,
            fb2: fb * fb,
            area: area as f32,
        }
    }
    fn bilinear(x: f32, y: f32) -> Option<Bilinear> {
        // Far outside every image (MAX_DIM = 2¹³) or NaN: not a position.
        let lim = 1.0e6;
        if !(x.abs() < lim && y.abs() < lim) {
            return None;
        }
        // ⌊x⌋ by truncation, one down for negative fractions (exact: |x| < 2²⁴ here, and
        // libm's `floorf` is a call, without SSE4.1's `roundss` on the x86-64 baseline).
        let floor = |v: f32| {
            let t = v as i32 as f32;
            if t > v { t - 1.0 } else { t }
        };
        let (fx, fy) = (floor(x), floor(y));
        let (a, b) = (x - fx, y - fy);
        let s = (1u32 << W_BITS) as f32;
        // cvRound: nearest, ties to even. Adding and taking away 1.5 · 2²³ rounds `v` so in
        // f32's own nearest-even rounding (exact for |v| < 2²², the weights are in
        // 0 ..= 2¹⁴): libm's `rintf` to the bit, without its call.
        let r = |v: f32| {
            const MAGIC: f32 = 12_582_912.0;
            ((v + MAGIC) - MAGIC) as i32
        };
        let w00 = r((1.0 - a) * (1.0 - b) * s);
        let w01 = r(a * (1.0 - b) * s);
        let w10 = r((1.0 - a) * b * s);
        Some(Bilinear {
            x: fx as i32,
            y: fy as i32,
            w: [w00, w01, w10, (1 << W_BITS) - w00 - w01 - w10],
        })
    }
    fn gram(a11: i64, a12: i64, a22: i64, p: &FloatParams) -> Result<FloatGram, FlowStatus> {
        let (a11, a12, a22) = (
            a11 as f32 * FLT_SCALE,
            a12 as f32 * FLT_SCALE,
            a22 as f32 * FLT_SCALE,
        );
        let det = a11 * a22 - a12 * a12;
        let min_eig =
            (a22 + a11 - libm::sqrtf((a11 - a22) * (a11 - a22) + 4.0 * a12 * a12)) / (2.0 * p.area);
        if min_eig.partial_cmp(&p.min_eig).is_none_or(|o| o.is_lt())
            || det.partial_cmp(&f32::EPSILON).is_none_or(|o| o.is_lt())
        {
            return Err(FlowStatus::SmallEigenvalue);
        }
        Ok(FloatGram {
            a11,
            a12,
            a22,
            inv_det: 1.0 / det,
        })
    }
    fn step(g: &FloatGram, b1: i64, b2: i64) -> [f32; 2] {
        let (b1, b2) = (b1 as f32 * FLT_SCALE, b2 as f32 * FLT_SCALE);
        let lim = 4096.0;
        [
            ((g.a12 * b2 - g.a22 * b1) * g.inv_det).max(-lim).min(lim),
            ((g.a12 * b1 - g.a11 * b2) * g.inv_det).max(-lim).min(lim),
        ]
    }
    fn converged(d: [f32; 2], p: &FloatParams) -> bool {
        d[0] * d[0] + d[1] * d[1] <= p.eps2
    }
    fn oscillates(d: [f32; 2], prev: [f32; 2]) -> bool {
        (d[0] + prev[0]).abs() < 0.01 && (d[1] + prev[1]).abs() < 0.01
    }
    fn error(sum_abs: u64, area: u32) -> f32 {
        sum_abs as f32 / (32.0 * area.max(1) as f32)
    }
    fn beyond(a: [f32; 2], b: [f32; 2], p: &FloatParams) -> bool {
        let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
        (dx * dx + dy * dy)
            .partial_cmp(&p.fb2)
            .is_none_or(|o| o.is_gt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n 2^shift / d` by the reciprocal against the exact quotient: within 2⁻²⁹ relative (the
    /// documented 30 significant bits) or one unit of the rounded result.
    #[test]
    fn reciprocal_quotients() {
        let mul_div =
            |n: i64, shift: i32, d: i64, limit: i64| Reciprocal::new(d).mul(n, shift, limit);
        assert_eq!(mul_div(3, 16, 4, i64::MAX), 3 << 14);
        assert_eq!(mul_div(-1, 0, 3, i64::MAX), 0);
        assert_eq!(mul_div(-2, 0, 3, i64::MAX), -1);
        assert_eq!(mul_div(1 << 60, 20, 1, 1000), 1000);
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        for _ in 0..20_000 {
            let n = (next() >> (1 + next() % 62)) as i64 * if next() % 2 == 0 { 1 } else { -1 };
            let d = ((next() >> (4 + next() % 60)) as i64).max(1);
            let shift = (next() % 40) as i32 - 20;
            let want = n as f64 * 2f64.powi(shift) / d as f64;
            if want.abs() > 2e18 {
                continue;
            }
            let got = mul_div(n, shift, d, i64::MAX) as f64;
            assert!(
                (got - want).abs() <= want.abs() * 2f64.powi(-29) + 1.0,
                "{n} 2^{shift} / {d}: {got} vs {want}"
            );
        }
    }

    /// The `f32` path's weights and corner against libm's `floorf` and `rintf` (which the
    /// bilinear split replaced) on positions with every kind of fraction, ties included.
    #[test]
    fn float_weights_match_libm() {
        let s = (1u32 << W_BITS) as f32;
        let mut checked = 0;
        for i in -4000..4000 {
            for frac in [0.0f32, 0.5, 0.25, 0.125, 0.999_99, 1.0 / 3.0, 0.000_03, 0.7] {
                for sign in [1.0f32, -1.0] {
                    let x = sign * (i as f32 * 0.37 + frac);
                    let y = -x * 0.61 + frac;
                    let b = <f32 as FlowArith>::bilinear(x, y).unwrap();
                    let (fx, fy) = (libm::floorf(x), libm::floorf(y));
                    assert_eq!((b.x, b.y), (fx as i32, fy as i32), "{x}, {y}");
                    let (a, c) = (x - fx, y - fy);
                    let r = |v: f32| libm::rintf(v) as i32;
                    let w00 = r((1.0 - a) * (1.0 - c) * s);
                    let w01 = r(a * (1.0 - c) * s);
                    let w10 = r((1.0 - a) * c * s);
                    assert_eq!(b.w[..3], [w00, w01, w10], "{x}, {y}");
                    checked += 1;
                }
            }
        }
        // Exact ties of the rounding: halves round to even.
        for k in 0..(1 << W_BITS) {
            let v = k as f32 + 0.5;
            let want = libm::rintf(v) as i32;
            assert_eq!(((v + 12_582_912.0) - 12_582_912.0) as i32, want, "{v}");
        }
        assert!(checked > 100_000);
    }

    #[test]
    fn weights_sum_and_match_float() {
        for &(x, y) in &[
            (0.0f32, 0.0f32),
            (1.25, 2.5),
            (-0.75, 3.999),
            (100.5, -7.125),
        ] {
            let f = <f32 as FlowArith>::bilinear(x, y).unwrap();
            let q =
                Fixed::bilinear(Q16::saturating_from_f32(x), Q16::saturating_from_f32(y)).unwrap();
            assert_eq!((f.x, f.y), (q.x, q.y));
            for k in 0..4 {
                assert!((f.w[k] - q.w[k]).abs() <= 1, "{x},{y}: {:?} {:?}", f.w, q.w);
            }
            assert_eq!(q.w.iter().sum::<i32>(), 1 << W_BITS);
        }
    }
}
