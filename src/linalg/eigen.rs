//! Real eigenvalues and null vectors of small non-symmetric matrices, without allocation
//! (the action matrix of a minimal solver).
//!
//! - [`real_eigenvalues`]: balancing (Parlett and Reinsch 1969), reduction to upper Hessenberg
//!   form by Gaussian similarity transforms with partial pivoting, then the Francis
//!   double-shift QR iteration on the Hessenberg matrix (the EISPACK `balanc`, `elmhes`,
//!   `hqr` sequence, Wilkinson and Reinsch 1971), eigenvalues only, at most
//!   [`MAX_QR_ITERATIONS`] iterations an eigenvalue;
//! - [`null_vector`]: the null vector of a nearly singular matrix (`A - λ I` for an
//!   eigenvector) by inverse iteration on its LU factors.
//!
//! The eigenvalues of a matrix rather than the roots of its characteristic polynomial, whose
//! coefficients (in `f32` especially) lose the roots that cluster. About 13 QR iterations for
//! the five-point solver's 10x10 action matrix (about 10k flops in all).

use super::elementary::swap_rows;
use crate::scalar::{Real, above, larger};

/// Bound on the QR iterations spent on one eigenvalue (or pair), as EISPACK's `hqr`: with
/// exceptional shifts at 10 and 20, convergence takes 2-4 in practice.
pub(crate) const MAX_QR_ITERATIONS: u32 = 30;

/// Bound on the balancing sweeps (each scales rows and columns by powers of 2; two or three
/// suffice in practice).
const MAX_BALANCE_SWEEPS: u32 = 16;

/// Inverse iteration steps in [`null_vector`]: from a matrix singular to rounding one step gives
/// the null vector nearly to working precision; the second (measured on the five-point noise
/// study: 47 misses in 16 000 minimal samples against 63 with one) makes it so.
const INVERSE_ITERATIONS: u32 = 2;

/// A square matrix with checked element access (no indexing panics in library code).
#[derive(Clone, Copy)]
struct Square<T, const N: usize>([[T; N]; N]);

impl<T: Real, const N: usize> Square<T, N> {
    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> T {
        self.0
            .get(i)
            .and_then(|r| r.get(j))
            .copied()
            .unwrap_or(T::zero())
    }

    #[inline(always)]
    fn set(&mut self, i: usize, j: usize, v: T) {
        if let Some(x) = self.0.get_mut(i).and_then(|r| r.get_mut(j)) {
            *x = v;
        }
    }

    #[inline(always)]
    fn sub(&mut self, i: usize, j: usize, v: T) {
        if let Some(x) = self.0.get_mut(i).and_then(|r| r.get_mut(j)) {
            *x -= v;
        }
    }
}

/// Scales rows and columns by powers of two (exact) so that each row and its column have
/// similar norms: the eigenvalues are unchanged and their computed values far less sensitive
/// to rounding when the matrix mixes large and small entries.
fn balance<T: Real, const N: usize>(a: &mut Square<T, N>) {
    let radix = T::lit(2.0);
    let sq = radix * radix;
    for _ in 0..MAX_BALANCE_SWEEPS {
        let mut done = true;
        for i in 0..N {
            // Off-diagonal norms of column i and row i.
            let mut c = T::zero();
            for (j, row) in a.0.iter().enumerate() {
                if j != i {
                    c += row.get(i).map_or(T::zero(), |v| v.abs());
                }
            }
            let Some(row) = a.0.get(i) else {
                continue;
            };
            let diagonal = row.get(i).map_or(T::zero(), |v| v.abs());
            let r = row.iter().fold(T::zero(), |s, v| s + v.abs()) - diagonal;
            if !above(c, T::zero()) || !above(r, T::zero()) {
                continue;
            }
            let s = c + r;
            let mut f = T::one();
            let mut g = r / radix;
            // Each loop changes the exponent of c by 2: bounded by the exponent range.
            let mut guard = 0u32;
            while c < g && guard < 256 {
                f *= radix;
                c *= sq;
                guard += 1;
            }
            g = r * radix;
            while c > g && guard < 512 {
                f /= radix;
                c /= sq;
                guard += 1;
            }
            if (c + r) / f < T::lit(0.95) * s {
                done = false;
                let g = T::one() / f;
                if let Some(row) = a.0.get_mut(i) {
                    row.iter_mut().for_each(|v| *v *= g);
                }
                for row in a.0.iter_mut() {
                    if let Some(v) = row.get_mut(i) {
                        *v *= f;
                    }
                }
            }
        }
        if done {
            break;
        }
    }
}

/// Reduces `a` to upper Hessenberg form by Gaussian similarity transforms, pivoting on the
/// largest entry of each column below the subdiagonal (EISPACK `elmhes`); the entries below the
/// subdiagonal are set to zero.
fn hessenberg<T: Real, const N: usize>(a: &mut Square<T, N>) {
    for m in 1..N.saturating_sub(1) {
        let (mut x, mut pivot) = (T::zero(), m);
        for j in m..N {
            if a.at(j, m - 1).abs() > x.abs() {
                x = a.at(j, m - 1);
                pivot = j;
            }
        }
        if pivot > m {
            swap_rows(&mut a.0, m, pivot);
            for row in a.0.iter_mut() {
                row.swap(pivot, m);
            }
        }
        if x == T::zero() {
            continue;
        }
        for i in (m + 1)..N {
            let y = a.at(i, m - 1);
            if y == T::zero() {
                continue;
            }
            let y = y / x;
            a.set(i, m - 1, T::zero());
            for j in m..N {
                a.sub(i, j, y * a.at(m, j));
            }
            for j in 0..N {
                a.set(j, m, a.at(j, m) + y * a.at(j, i));
            }
        }
    }
}

/// `|a|` with the sign of `b`.
#[inline(always)]
fn with_sign<T: Real>(a: T, b: T) -> T {
    if b >= T::zero() { a.abs() } else { -a.abs() }
}

/// Applies the reflection `I - v wᵀ` (`v = (1, q, r)`, `w = (x, y, z)`; two rows when
/// `k + 1 = nn`) from the left to rows `k..k+3` of `h`, columns `k..=nn`.
#[inline(always)]
fn reflect_rows<T: Real, const N: usize>(
    h: &mut [[T; N]; N],
    k: usize,
    nn: usize,
    [x, y, z]: [T; 3],
    [q, r]: [T; 2],
) {
    let Some(rows) = h.get_mut(k..(k + 3).min(nn + 1)) else {
        return;
    };
    match rows {
        [a, b, c] => {
            let (Some(a), Some(b), Some(c)) =
                (a.get_mut(k..=nn), b.get_mut(k..=nn), c.get_mut(k..=nn))
            else {
                return;
            };
            for ((a, b), c) in a.iter_mut().zip(b.iter_mut()).zip(c.iter_mut()) {
                let p = *a + q * *b + r * *c;
                *c -= p * z;
                *b -= p * y;
                *a -= p * x;
            }
        }
        [a, b] => {
            let (Some(a), Some(b)) = (a.get_mut(k..=nn), b.get_mut(k..=nn)) else {
                return;
            };
            for (a, b) in a.iter_mut().zip(b.iter_mut()) {
                let p = *a + q * *b;
                *b -= p * y;
                *a -= p * x;
            }
        }
        _ => {}
    }
}

/// Applies the reflection `I - w vᵀ` (`v = (1, q, r)`, `w = (x, y, z)`; two columns when
/// `k + 1 = nn`) from the right to columns `k..k+3` of `h`, the given rows.
#[inline(always)]
fn reflect_columns<T: Real, const N: usize>(
    h: &mut [[T; N]; N],
    rows: core::ops::RangeInclusive<usize>,
    k: usize,
    nn: usize,
    [q, r]: [T; 2],
    [x, y, z]: [T; 3],
) {
    let Some(rows) = h.get_mut(rows) else {
        return;
    };
    for row in rows {
        match row.get_mut(k..(k + 3).min(nn + 1)) {
            Some([a, b, c]) => {
                let p = x * *a + y * *b + z * *c;
                *c -= p * r;
                *b -= p * q;
                *a -= p;
            }
            Some([a, b]) => {
                let p = x * *a + y * *b;
                *b -= p * q;
                *a -= p;
            }
            _ => {}
        }
    }
}

/// The real eigenvalues of `a` (unordered; complex pairs are left out: a double real
/// eigenvalue may come out as a pair with an imaginary part of order `√ε |a|`).
///
/// `None` when the QR iteration does not converge within [`MAX_QR_ITERATIONS`] for some
/// eigenvalue, or when `a` is not finite.
pub(crate) fn real_eigenvalues<T: Real, const N: usize>(
    a: &[[T; N]; N],
) -> Option<heapless::Vec<T, N>> {
    if !a.iter().flatten().all(|v| v.finite()) {
        return None;
    }
    let mut h = Square(*a);
    balance(&mut h);
    hessenberg(&mut h);
    let mut out = heapless::Vec::new();
    let mut norm = T::zero();
    for i in 0..N {
        for j in i.saturating_sub(1)..N {
            norm += h.at(i, j).abs();
        }
    }
    if norm == T::zero() {
        // The zero matrix.
        for _ in 0..N {
            let _ = out.push(T::zero());
        }
        return Some(out);
    }
    // `nn`: the last row of the active block (signed: the loop ends when it passes 0).
    let mut nn = N as isize - 1;
    let mut shift = T::zero();
    let u = |v: isize| v as usize;
    while nn >= 0 {
        let mut its = 0u32;
        loop {
            // Look for a negligible subdiagonal entry: the active block is rows l..=nn.
            let mut l = nn;
            while l >= 1 {
                let mut s = h.at(u(l - 1), u(l - 1)).abs() + h.at(u(l), u(l)).abs();
                if s == T::zero() {
                    s = norm;
                }
                if h.at(u(l), u(l - 1)).abs() + s == s {
                    h.set(u(l), u(l - 1), T::zero());
                    break;
                }
                l -= 1;
            }
            let x = h.at(u(nn), u(nn));
            if l == nn {
                // One eigenvalue.
                let _ = out.push(x + shift);
                nn -= 1;
                break;
            }
            let y = h.at(u(nn - 1), u(nn - 1));
            let w = h.at(u(nn), u(nn - 1)) * h.at(u(nn - 1), u(nn));
            if l == nn - 1 {
                // A 2x2 block: two real eigenvalues or a complex pair.
                let p = T::lit(0.5) * (y - x);
                let q = p * p + w;
                let z = q.abs().sqrt();
                let x = x + shift;
                if q >= T::zero() {
                    let z = p + with_sign(z, p);
                    let _ = out.push(x + z);
                    let _ = out.push(if z != T::zero() { x - w / z } else { x + z });
                }
                nn -= 2;
                break;
            }
            if its == MAX_QR_ITERATIONS {
                return None;
            }
            let (mut x, mut y, mut w) = (x, y, w);
            if its == 10 || its == 20 {
                // Exceptional shift.
                shift += x;
                for i in 0..=u(nn) {
                    h.sub(i, i, x);
                }
                let s = h.at(u(nn), u(nn - 1)).abs() + h.at(u(nn - 1), u(nn - 2)).abs();
                x = T::lit(0.75) * s;
                y = x;
                w = T::lit(-0.4375) * s * s;
            }
            its += 1;
            // Two consecutive small subdiagonal entries: start the double-shift step at m.
            let (mut p, mut q, mut r) = (T::zero(), T::zero(), T::zero());
            let mut m = nn - 2;
            while m >= l {
                let z = h.at(u(m), u(m));
                let rr = x - z;
                let s = y - z;
                p = (rr * s - w) / h.at(u(m + 1), u(m)) + h.at(u(m), u(m + 1));
                q = h.at(u(m + 1), u(m + 1)) - z - rr - s;
                r = h.at(u(m + 2), u(m + 1));
                let s = p.abs() + q.abs() + r.abs();
                p /= s;
                q /= s;
                r /= s;
                if m == l {
                    break;
                }
                let uu = h.at(u(m), u(m - 1)).abs() * (q.abs() + r.abs());
                let v = p.abs()
                    * (h.at(u(m - 1), u(m - 1)).abs() + z.abs() + h.at(u(m + 1), u(m + 1)).abs());
                if uu + v == v {
                    break;
                }
                m -= 1;
            }
            for i in u(m + 2)..=u(nn) {
                h.set(i, i - 2, T::zero());
                if i != u(m + 2) {
                    h.set(i, i - 3, T::zero());
                }
            }
            // The double-shift QR step on rows and columns l..=nn, by 3x3 Householder
            // reflections chasing the bulge.
            let mut k = m;
            while k < nn {
                if k != m {
                    p = h.at(u(k), u(k - 1));
                    q = h.at(u(k + 1), u(k - 1));
                    r = if k + 1 != nn {
                        h.at(u(k + 2), u(k - 1))
                    } else {
                        T::zero()
                    };
                    x = p.abs() + q.abs() + r.abs();
                    if x != T::zero() {
                        p /= x;
                        q /= x;
                        r /= x;
                    }
                }
                let s = with_sign((p * p + q * q + r * r).sqrt(), p);
                if s != T::zero() {
                    if k == m {
                        if l != m {
                            h.set(u(k), u(k - 1), -h.at(u(k), u(k - 1)));
                        }
                    } else {
                        h.set(u(k), u(k - 1), -s * x);
                    }
                    p += s;
                    x = p / s;
                    y = q / s;
                    let z = r / s;
                    q /= p;
                    r /= p;
                    reflect_rows(&mut h.0, u(k), u(nn), [x, y, z], [q, r]);
                    let last = if nn < k + 3 { nn } else { k + 3 };
                    reflect_columns(&mut h.0, u(l)..=u(last), u(k), u(nn), [q, r], [x, y, z]);
                }
                k += 1;
            }
            if l + 1 >= nn {
                break;
            }
        }
    }
    Some(out)
}

/// A null vector of the (nearly) singular `a`, scaled to a largest entry of 1, by inverse
/// iteration with a zero shift: LU factors with partial pivoting (a pivot below `ε |a|`, the
/// singular direction, replaced by `±ε |a|`), then [`INVERSE_ITERATIONS`] solves from
/// `(1, …, 1)`, each normalised. With `a = A - λ I` for an eigenvalue `λ` of `A`: its
/// eigenvector. `None` when `a` is zero or not finite, or a solve overflows.
pub(crate) fn null_vector<T: Real, const N: usize>(a: &[[T; N]; N]) -> Option<[T; N]> {
    let mut lu = Square(*a);
    let scale = a
        .iter()
        .flatten()
        .fold(T::zero(), |m, v| larger(m, v.abs()));
    if !above(scale, T::zero()) || !scale.finite() {
        return None;
    }
    let tiny = T::EPSILON * scale;
    let mut perm: [usize; N] = core::array::from_fn(|i| i);
    for c in 0..N {
        let mut p = c;
        for r in (c + 1)..N {
            if lu.at(r, c).abs() > lu.at(p, c).abs() {
                p = r;
            }
        }
        if p > c {
            swap_rows(&mut lu.0, c, p);
            perm.swap(p, c);
        }
        let mut pivot = lu.at(c, c);
        if pivot.abs() < tiny {
            pivot = if pivot < T::zero() { -tiny } else { tiny };
            lu.set(c, c, pivot);
        }
        let (upper, lower) = lu.0.split_at_mut(c + 1);
        let Some(prow) = upper.last().and_then(|r| r.get(c + 1..)) else {
            continue;
        };
        for row in lower.iter_mut() {
            let Some((head, tail)) = row.get_mut(c..).and_then(|r| r.split_first_mut()) else {
                continue;
            };
            let f = *head / pivot;
            *head = f;
            for (x, p) in tail.iter_mut().zip(prow.iter()) {
                *x -= f * *p;
            }
        }
    }
    let mut v = [T::one(); N];
    for _ in 0..INVERSE_ITERATIONS {
        // Solve L U w = P v.
        let mut w: [T; N] = core::array::from_fn(|i| {
            perm.get(i)
                .and_then(|&k| v.get(k))
                .copied()
                .unwrap_or(T::zero())
        });
        for (i, row) in lu.0.iter().enumerate() {
            let (done, rest) = w.split_at_mut(i);
            let Some(wi) = rest.first_mut() else {
                continue;
            };
            for (l, x) in row.iter().zip(done.iter()) {
                *wi -= *l * *x;
            }
        }
        for (i, row) in lu.0.iter().enumerate().rev() {
            let (head, done) = w.split_at_mut(i + 1);
            let (Some(wi), Some(later)) = (head.last_mut(), row.get(i + 1..)) else {
                continue;
            };
            for (u, x) in later.iter().zip(done.iter()) {
                *wi -= *u * *x;
            }
            *wi /= row.get(i).copied().unwrap_or(T::one());
        }
        let n = w.iter().fold(T::zero(), |m, x| larger(m, x.abs()));
        if !above(n, T::zero()) || !n.finite() {
            return None;
        }
        v = w.map(|x| x / n);
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A matrix with known eigenvalues: a block diagonal one (a 2x2 rotation-scaling block for
    /// a complex pair) under a similarity by a unit lower bidiagonal matrix.
    #[test]
    #[allow(clippy::needless_range_loop)] // Matrix products written as the formulas.
    fn finds_the_real_eigenvalues_of_a_mixed_spectrum() {
        // Block diagonal: 3, -1.5, 0.25, 7, and the pair 1 ± 2i.
        let n = 6;
        let mut d = [[0.0f64; 6]; 6];
        d[0][0] = 3.0;
        d[1][1] = -1.5;
        d[2][2] = 0.25;
        d[3][3] = 7.0;
        d[4][4] = 1.0;
        d[4][5] = 2.0;
        d[5][4] = -2.0;
        d[5][5] = 1.0;
        let mut l = [[0.0f64; 6]; 6];
        let mut li = [[0.0f64; 6]; 6];
        for i in 0..n {
            l[i][i] = 1.0;
            li[i][i] = 1.0;
        }
        for i in 0..n - 1 {
            l[i + 1][i] = 0.5 + i as f64 * 0.1;
        }
        // Inverse of a unit lower bidiagonal matrix.
        for j in 0..n {
            for i in j + 1..n {
                li[i][j] = -l[i][i - 1] * li[i - 1][j];
            }
        }
        let mul = |a: &[[f64; 6]; 6], b: &[[f64; 6]; 6]| {
            let mut c = [[0.0; 6]; 6];
            for i in 0..n {
                for j in 0..n {
                    c[i][j] = (0..n).map(|k| a[i][k] * b[k][j]).sum();
                }
            }
            c
        };
        let a = mul(&mul(&l, &d), &li);
        let mut ev = real_eigenvalues(&a).unwrap();
        ev.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let want = [-1.5, 0.25, 3.0, 7.0];
        assert_eq!(ev.len(), 4, "{ev:?}");
        for (g, w) in ev.iter().zip(want.iter()) {
            // A well-conditioned spectrum: a few ulps of |A| ~ 10.
            assert!((g - w).abs() < 1e-12, "{g} vs {w}");
        }
        for w in want {
            let mut shifted = a;
            for i in 0..n {
                shifted[i][i] -= w;
            }
            let v = null_vector(&shifted).unwrap();
            // A v = λ v to rounding.
            for i in 0..n {
                let av: f64 = (0..n).map(|k| a[i][k] * v[k]).sum();
                assert!((av - w * v[i]).abs() < 1e-12, "{w}: row {i}");
            }
        }
        // f32, the same spectrum.
        let a32 = a.map(|r| r.map(|v| v as f32));
        let mut ev = real_eigenvalues(&a32).unwrap();
        ev.sort_by(|a, b| a.partial_cmp(b).unwrap());
        for (g, w) in ev.iter().zip(want.iter()) {
            assert!((f64::from(*g) - w).abs() < 1e-5, "{g} vs {w}");
        }
    }

    #[test]
    fn degenerate_and_bad_matrices() {
        assert_eq!(
            real_eigenvalues(&[[0.0f32; 3]; 3]).unwrap().as_slice(),
            &[0.0; 3]
        );
        assert!(real_eigenvalues(&[[f32::NAN, 0.0], [0.0, 1.0]]).is_none());
        // A companion matrix with repeated roots (x - 1)²(x + 2): eigenvalues 1, 1, -2.
        let c = [[0.0f64, 0.0, -2.0], [1.0, 0.0, 3.0], [0.0, 1.0, 0.0]];
        let mut ev = real_eigenvalues(&c).unwrap();
        ev.sort_by(|a, b| a.partial_cmp(b).unwrap());
        // -2 to rounding; the double eigenvalue 1 moves by √ε under rounding, into a close
        // real pair or a complex one (then left out).
        assert!((ev[0] + 2.0).abs() < 1e-12, "{ev:?}");
        assert!(
            ev.len() == 1 || ev[1..].iter().all(|v| (v - 1.0).abs() < 1e-7),
            "{ev:?}"
        );
        assert!(null_vector(&[[0.0f32; 2]; 2]).is_none());
        assert!(null_vector(&[[f32::INFINITY, 0.0], [0.0, 1.0]]).is_none());
        // Rotation by 90°: no real eigenvalue.
        assert!(
            real_eigenvalues(&[[0.0f64, -1.0], [1.0, 0.0]])
                .unwrap()
                .is_empty()
        );
    }
}
