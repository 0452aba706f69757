//! Real roots of small univariate polynomials, without allocation.
//!
//! The roots of `p` are isolated by those of its derivatives (Rolle): between two consecutive
//! real roots of `p'` (and the Cauchy bound `B = 1 + maxᵢ |aᵢ / a_d|` outside them) `p` is
//! monotone, so it has at most one root there, found by a safeguarded Newton iteration (a
//! Newton step when it stays inside the sign-change bracket, else bisection). Starting from
//! the linear `p^(d-1)` and climbing back to `p` gives every simple real root; a root of even
//! multiplicity (no sign change) is missed, which the minimal solvers tolerate (RANSAC draws
//! another sample). Cost: `O(d³)` evaluations of `O(d)` each, bounded.

use heapless::Vec;

use crate::scalar::Real;

/// Highest degree handled (the 5-point solver's 10).
pub(crate) const MAX_DEGREE: usize = 10;

/// Bound on the iterations spent on one root (bisection alone halves the bracket each time).
const MAX_ROOT_ITERATIONS: u32 = 200;

/// `p(x)` for ascending coefficients `p = Σ aᵢ xⁱ` (Horner).
pub(crate) fn eval<T: Real>(coeffs: &[T], x: T) -> T {
    coeffs.iter().rev().fold(T::zero(), |acc, a| acc * x + *a)
}

/// `(p(x), p'(x))` (Horner on both).
fn eval_with_derivative<T: Real>(coeffs: &[T], x: T) -> (T, T) {
    let mut p = T::zero();
    let mut d = T::zero();
    for a in coeffs.iter().rev() {
        d = d * x + p;
        p = p * x + *a;
    }
    (p, d)
}

/// Every simple real root of `Σ coeffs[i] xⁱ` (degree ≤ [`MAX_DEGREE`]), ascending.
///
/// Leading coefficients below `ε max|aᵢ|` are dropped (the degree falls). Empty for a
/// constant, an all-zero or a non-finite polynomial.
pub(crate) fn real_roots<T: Real>(coeffs: &[T]) -> Vec<T, MAX_DEGREE> {
    let mut out = Vec::new();
    let amax = coeffs.iter().fold(T::zero(), |m, a| m.max(a.abs()));
    if !coeffs.iter().all(|a| a.finite()) || !amax.finite() || amax == T::zero() {
        return out;
    }
    // Scaled copy, trimmed to the effective degree.
    let mut p = [T::zero(); MAX_DEGREE + 1];
    let mut degree = 0usize;
    for (i, (dst, a)) in p.iter_mut().zip(coeffs.iter()).enumerate() {
        *dst = *a / amax;
        if dst.abs() > T::EPSILON {
            degree = i;
        }
    }
    if degree == 0 {
        return out;
    }
    let lead = p.get(degree).copied().unwrap_or(T::one());
    let mut bound = T::one()
        + p.iter()
            .take(degree)
            .fold(T::zero(), |m, a| m.max((*a / lead).abs()));
    let top = p.get(..=degree).unwrap_or(&[]);
    // Where `p` overflows at the Cauchy bound (a small leading coefficient in `f32`:
    // `1e6¹⁰ > 3.4e38`), its brackets would hold no finite sign.
    if !eval(top, bound).finite() || !eval(top, -bound).finite() {
        bound = tight_bound(top, bound);
    }
    // derivative k of p, ascending: coefficient i is a_{i+k} (i+k)! / i!.
    let derivative = |k: usize| {
        let mut d = [T::zero(); MAX_DEGREE + 1];
        for (i, di) in d.iter_mut().enumerate().take(degree + 1 - k) {
            let mut c = p.get(i + k).copied().unwrap_or(T::zero());
            for f in (i + 1)..=(i + k) {
                c *= T::lit(f as f64);
            }
            *di = c;
        }
        d
    };
    // Roots of the (degree - 1)-th derivative, a linear polynomial: c0 + c1 x.
    let mut roots: Vec<T, MAX_DEGREE> = Vec::new();
    {
        let d = derivative(degree - 1);
        let (c0, c1) = (d.first().copied(), d.get(1).copied());
        if let (Some(c0), Some(c1)) = (c0, c1)
            && c1 != T::zero()
        {
            let _ = roots.push(-c0 / c1);
        }
    }
    for k in (0..degree - 1).rev() {
        let q = derivative(k);
        let q = q.get(..=(degree - k)).unwrap_or(&[]);
        let mut next: Vec<T, MAX_DEGREE> = Vec::new();
        let mut lo = -bound;
        for hi in roots.iter().copied().chain(core::iter::once(bound)) {
            let found = bracketed_root(q, lo, hi);
            if hi > lo
                && let Some(r) = found
            {
                let _ = next.push(r);
            }
            lo = lo.max(hi);
        }
        roots = next;
    }
    out = roots;
    out
}

/// Bound on the doublings of [`tight_bound`] (`2⁶⁴` is past any root bound met in practice).
const MAX_BOUND_DOUBLINGS: u32 = 64;

/// A root bound within a factor 2 of the smallest: the first `B = 2ᵏ` with
/// `|a_d| > Σ_{i<d} |aᵢ| B^(i-d)` (then `|p(x)| ≥ |x|^d (|a_d| - Σ |aᵢ| B^(i-d)) > 0` for
/// `|x| ≥ B`), evaluated with non-positive powers of `B` so nothing overflows. Returns
/// `cauchy` (always a bound) if no power of two below it passes.
fn tight_bound<T: Real>(p: &[T], cauchy: T) -> T {
    let Some((lead, rest)) = p.split_last() else {
        return cauchy;
    };
    let lead = lead.abs();
    let two = T::lit(2.0);
    let mut b = T::one();
    for _ in 0..MAX_BOUND_DOUBLINGS {
        if b >= cauchy {
            break;
        }
        let inv = T::one() / b;
        let tail = rest
            .iter()
            .rev()
            .fold((T::zero(), inv), |(acc, w), a| (acc + a.abs() * w, w * inv))
            .0;
        if lead > tail {
            return b;
        }
        b *= two;
    }
    cauchy
}

/// The root of `q` in `[lo, hi]` when `q` changes sign there (it is monotone inside).
fn bracketed_root<T: Real>(q: &[T], lo: T, hi: T) -> Option<T> {
    let (flo, fhi) = (eval(q, lo), eval(q, hi));
    if flo == T::zero() {
        return Some(lo);
    }
    if fhi == T::zero() {
        return Some(hi);
    }
    if (flo > T::zero()) == (fhi > T::zero()) || !flo.finite() || !fhi.finite() {
        return None;
    }
    // Orient so that q(a) < 0 < q(b).
    let (mut a, mut b) = if flo < T::zero() { (lo, hi) } else { (hi, lo) };
    let mut x = (a + b) * T::lit(0.5);
    let two = T::lit(2.0);
    for _ in 0..MAX_ROOT_ITERATIONS {
        let (f, df) = eval_with_derivative(q, x);
        if f == T::zero() {
            return Some(x);
        }
        if f < T::zero() {
            a = x;
        } else {
            b = x;
        }
        let newton = x - f / df;
        let inside = (newton - a) * (newton - b) < T::zero();
        let next = if inside && newton.finite() {
            newton
        } else {
            (a + b) / two
        };
        let tol = T::EPSILON * two * (T::one() + next.abs());
        if (next - x).abs() <= tol || (a - b).abs() <= tol {
            return Some(next);
        }
        x = next;
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_roots(roots: &[f64]) -> [f64; MAX_DEGREE + 1] {
        let mut p = [0.0; MAX_DEGREE + 1];
        p[0] = 1.0;
        for (n, r) in roots.iter().enumerate() {
            for i in (0..=n + 1).rev() {
                let prev = if i > 0 { p[i - 1] } else { 0.0 };
                p[i] = prev - r * p[i];
            }
        }
        p
    }

    #[test]
    fn finds_every_simple_real_root() {
        let roots = [-7.5, -1.0, -0.3, 0.01, 0.2, 1.5, 2.0, 3.25, 40.0, 100.0];
        let p = from_roots(&roots);
        let found = real_roots(&p);
        assert_eq!(found.len(), 10, "{found:?}");
        for (a, b) in found.iter().zip(roots.iter()) {
            assert!((a - b).abs() < 1e-8 * (1.0 + b.abs()), "{a} vs {b}");
        }
        // A cubic with one real root (x² + 1)(x - 2).
        let c = [-2.0f64, 1.0, -2.0, 1.0];
        let r = real_roots(&c);
        assert_eq!(r.len(), 1);
        assert!((r[0] - 2.0).abs() < 1e-12);
        // f32 too.
        let r = real_roots(&[-2.0f32, 1.0, -2.0, 1.0]);
        assert!((r[0] - 2.0).abs() < 1e-5);
        // Vanishing leading coefficients lower the degree.
        let r = real_roots(&[-1.0, 1.0, 0.0, 0.0]);
        assert_eq!(r.as_slice(), &[1.0]);
        assert!(real_roots(&[1.0, 0.0]).is_empty());
        assert!(real_roots::<f64>(&[]).is_empty());
        assert!(real_roots(&[f64::NAN, 1.0]).is_empty());
        assert!(real_roots(&[1.0, 0.0, 1.0]).is_empty());
    }
}
