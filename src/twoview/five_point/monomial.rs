//! The polynomial algebra of the five-point solvers: polynomials of degree ≤ 3 in `(x, y, z)`
//! over twenty monomials, their products, the ten cubic constraints of an essential matrix
//! `E = x X + y Y + z Z + W`, and the elimination of their leading monomials.

use nalgebra::Matrix3;

use crate::linalg::swap_rows;
use crate::scalar::{Real, above, larger};
use crate::{Error, Result};

/// A polynomial of degree ≤ 3 in `(x, y, z)` over the monomials of [`EXPONENTS`].
pub(super) type Poly<T> = [T; 20];

/// A linear polynomial `a x + b y + c z + d`: `[a, b, c, d]`.
pub(super) type Linear<T> = [T; 4];

/// A quadratic over the monomials [`QUADRATIC`] (the degree-2-or-less ones of
/// [`EXPONENTS`], in that order).
pub(super) type Quadratic<T> = [T; 10];

/// Exponents `(x, y, z)` of the twenty monomials, in elimination order (module docs).
pub(super) const EXPONENTS: [[u8; 3]; 20] = [
    [3, 0, 0],
    [0, 3, 0],
    [2, 1, 0],
    [1, 2, 0],
    [2, 0, 1],
    [2, 0, 0],
    [0, 2, 1],
    [0, 2, 0],
    [1, 1, 1],
    [1, 1, 0],
    [1, 0, 2],
    [1, 0, 1],
    [1, 0, 0],
    [0, 1, 2],
    [0, 1, 1],
    [0, 1, 0],
    [0, 0, 3],
    [0, 0, 2],
    [0, 0, 1],
    [0, 0, 0],
];

/// Exponents of the four monomials of a [`Linear`]: `x y z 1`.
const LINEAR: [[u8; 3]; 4] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]];

/// The monomial index of each exponent triple (`u8::MAX` for degree > 3).
pub(super) const INDEX: [[[u8; 4]; 4]; 4] = build_index();

/// Where each [`Quadratic`] monomial sits in [`EXPONENTS`].
const QUADRATIC: [u8; 10] = build_quadratic();

/// `LL[i][j]`: the [`Quadratic`] slot of `LINEAR[i] · LINEAR[j]`.
const LL: [[u8; 4]; 4] = build_ll();

/// `QL[i][j]`: the [`EXPONENTS`] slot of `QUADRATIC[i] · LINEAR[j]`.
const QL: [[u8; 4]; 10] = build_ql();

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_index() -> [[[u8; 4]; 4]; 4] {
    let mut t = [[[u8::MAX; 4]; 4]; 4];
    let mut i = 0;
    while i < EXPONENTS.len() {
        let e = EXPONENTS[i];
        t[e[0] as usize][e[1] as usize][e[2] as usize] = i as u8;
        i += 1;
    }
    t
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_quadratic() -> [u8; 10] {
    let mut q = [u8::MAX; 10];
    let (mut i, mut k) = (0, 0);
    while i < EXPONENTS.len() {
        let e = EXPONENTS[i];
        if e[0] + e[1] + e[2] <= 2 {
            q[k] = i as u8;
            k += 1;
        }
        i += 1;
    }
    assert!(k == 10);
    q
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_ll() -> [[u8; 4]; 4] {
    let mut t = [[u8::MAX; 4]; 4];
    let mut i = 0;
    while i < 4 {
        let mut j = 0;
        while j < 4 {
            let (a, b) = (LINEAR[i], LINEAR[j]);
            let slot =
                INDEX[(a[0] + b[0]) as usize][(a[1] + b[1]) as usize][(a[2] + b[2]) as usize];
            let mut k = 0;
            while k < 10 {
                if QUADRATIC[k] == slot {
                    t[i][j] = k as u8;
                }
                k += 1;
            }
            assert!(t[i][j] != u8::MAX);
            j += 1;
        }
        i += 1;
    }
    t
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_ql() -> [[u8; 4]; 10] {
    let mut t = [[u8::MAX; 4]; 10];
    let mut i = 0;
    while i < 10 {
        let mut j = 0;
        while j < 4 {
            let (a, b) = (EXPONENTS[QUADRATIC[i] as usize], LINEAR[j]);
            t[i][j] = INDEX[(a[0] + b[0]) as usize][(a[1] + b[1]) as usize][(a[2] + b[2]) as usize];
            assert!(t[i][j] != u8::MAX);
            j += 1;
        }
        i += 1;
    }
    t
}

#[cfg(test)]
fn index_of(e: [u8; 3]) -> Option<usize> {
    let [a, b, c] = e;
    let i = *INDEX
        .get(usize::from(a))?
        .get(usize::from(b))?
        .get(usize::from(c))?;
    (usize::from(i) < EXPONENTS.len()).then_some(usize::from(i))
}

/// `a b` of two linear polynomials.
///
/// Every product of this module accumulates its terms in the order of the operands' monomials
/// in [`EXPONENTS`] (first operand outer), the order of a dense 20x20 product: the `f64`
/// results depend on that order to the bit.
fn mul_ll<T: Real>(a: &Linear<T>, b: &Linear<T>) -> Quadratic<T> {
    let mut out = [T::zero(); 10];
    for (ca, slots) in a.iter().zip(LL.iter()) {
        for (cb, k) in b.iter().zip(slots.iter()) {
            if let Some(o) = out.get_mut(usize::from(*k)) {
                *o += *ca * *cb;
            }
        }
    }
    out
}

/// `a b` of a quadratic and a linear polynomial (first operand outer, see [`mul_ll`]).
fn mul_ql<T: Real>(a: &Quadratic<T>, b: &Linear<T>) -> Poly<T> {
    let mut out = [T::zero(); 20];
    for (ca, slots) in a.iter().zip(QL.iter()) {
        for (cb, k) in b.iter().zip(slots.iter()) {
            if let Some(o) = out.get_mut(usize::from(*k)) {
                *o += *ca * *cb;
            }
        }
    }
    out
}

/// `a b` of a linear and a quadratic polynomial (first operand outer, see [`mul_ll`]).
fn mul_lq<T: Real>(a: &Linear<T>, b: &Quadratic<T>) -> Poly<T> {
    let mut out = [T::zero(); 20];
    for (ca, j) in a.iter().zip(0..4) {
        for (cb, slots) in b.iter().zip(QL.iter()) {
            if let Some(o) = slots.get(j).and_then(|k| out.get_mut(usize::from(*k))) {
                *o += *ca * *cb;
            }
        }
    }
    out
}

pub(super) fn sub<T: Real, const N: usize>(a: &[T; N], b: &[T; N]) -> [T; N] {
    let mut out = *a;
    out.iter_mut().zip(b.iter()).for_each(|(o, b)| *o -= *b);
    out
}

pub(super) fn add_assign<T: Real, const N: usize>(acc: &mut [T; N], b: &[T; N]) {
    acc.iter_mut().zip(b.iter()).for_each(|(a, b)| *a += *b);
}

fn axpy<T: Real>(acc: &mut Poly<T>, s: T, b: &Poly<T>) {
    acc.iter_mut().zip(b.iter()).for_each(|(a, b)| *a += s * *b);
}

/// `E` as linear polynomials in `(x, y, z, 1)`, row-major, for `basis = [X, Y, Z, W]`.
pub(super) fn linear_entries<T: Real>(basis: &[Matrix3<T>; 4]) -> [[Linear<T>; 3]; 3] {
    let [bx, by, bz, bw] = basis;
    core::array::from_fn(|i| {
        core::array::from_fn(|j| {
            let at = |m: &Matrix3<T>| m.get((i, j)).copied().unwrap_or(T::zero());
            [at(bx), at(by), at(bz), at(bw)]
        })
    })
}

/// The ten cubics (module docs, step 2) of `E` given as linear polynomials: `det E` and the
/// nine entries of `2 E Eᵀ E - tr(E Eᵀ) E`.
pub(super) fn constraints<T: Real>(e: &[[Linear<T>; 3]; 3]) -> [Poly<T>; 10] {
    // E Eᵀ (symmetric: a sum of three two-term products per monomial is exact in either
    // operand order) and its trace.
    let mut eet = [[[T::zero(); 10]; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let (Some(ri), Some(rj)) = (e.get(i), e.get(j)) else {
                continue;
            };
            let mut acc = [T::zero(); 10];
            for (a, b) in ri.iter().zip(rj.iter()) {
                add_assign(&mut acc, &mul_ll(a, b));
            }
            for (r, c) in [(i, j), (j, i)] {
                if let Some(slot) = eet.get_mut(r).and_then(|row| row.get_mut(c)) {
                    *slot = acc;
                }
            }
        }
    }
    let mut trace = [T::zero(); 10];
    for (i, row) in eet.iter().enumerate() {
        if let Some(d) = row.get(i) {
            add_assign(&mut trace, d);
        }
    }
    let mut a = [[T::zero(); 20]; 10];
    let mut rows = a.iter_mut();
    if let Some(r) = rows.next() {
        let [[e11, e12, e13], [e21, e22, e23], [e31, e32, e33]] = e;
        let c1 = sub(&mul_ll(e22, e33), &mul_ll(e23, e32));
        let c2 = sub(&mul_ll(e21, e33), &mul_ll(e23, e31));
        let c3 = sub(&mul_ll(e21, e32), &mul_ll(e22, e31));
        *r = sub(&mul_lq(e11, &c1), &mul_lq(e12, &c2));
        add_assign(r, &mul_lq(e13, &c3));
    }
    let two = T::lit(2.0);
    for (eet_row, e_row) in eet.iter().zip(e.iter()) {
        for (j, e_ij) in e_row.iter().enumerate() {
            if let Some(r) = rows.next() {
                // (E Eᵀ E)_ij = Σₖ (E Eᵀ)_ik E_kj.
                let mut d = [T::zero(); 20];
                for (q, e_k) in eet_row.iter().zip(e.iter()) {
                    if let Some(l) = e_k.get(j) {
                        add_assign(&mut d, &mul_ql(q, l));
                    }
                }
                *r = [T::zero(); 20];
                axpy(r, two, &d);
                axpy(r, -T::one(), &mul_ql(&trace, e_ij));
            }
        }
    }
    a
}

/// Reduces the first ten columns of `a` to the identity (partial pivoting). Errors with
/// [`Error::Degenerate`] when a pivot is below `tol` times the largest entry.
pub(super) fn gauss_jordan<T: Real>(a: &mut [Poly<T>; 10], tol: T) -> Result<()> {
    let scale = a
        .iter()
        .flat_map(|r| r.iter())
        .fold(T::zero(), |m, v| larger(m, v.abs()));
    if !above(scale, T::zero()) || !scale.finite() {
        return Err(Error::Degenerate);
    }
    for c in 0..10 {
        let mut p = c;
        let mut pmax = T::zero();
        for (i, r) in a.iter().enumerate().skip(c) {
            let v = r.get(c).map_or(T::zero(), |v| v.abs());
            // `>=`: the last of equal maxima (as `Iterator::max_by` picks).
            if v >= pmax {
                p = i;
                pmax = v;
            }
        }
        // In place: whole-row copies of these 80-byte rows are `memcpy` calls on a Cortex-M.
        swap_rows(a, c, p);
        let Some((before, rest)) = a.split_at_mut_checked(c) else {
            return Err(Error::Degenerate);
        };
        let Some((pivot, after)) = rest.split_first_mut() else {
            return Err(Error::Degenerate);
        };
        let pv = pivot.get(c).copied().unwrap_or(T::zero());
        if !above(pv.abs(), tol * scale) {
            return Err(Error::Degenerate);
        }
        pivot.iter_mut().for_each(|v| *v /= pv);
        for row in before.iter_mut().chain(after.iter_mut()) {
            let f = row.get(c).copied().unwrap_or(T::zero());
            if f != T::zero() {
                axpy(row, -f, pivot);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monomial_table_is_consistent() {
        for (i, e) in EXPONENTS.iter().enumerate() {
            assert_eq!(index_of(*e), Some(i));
        }
        assert_eq!(index_of([2, 2, 0]), None);
        // (x + 1)(y + z) = xy + xz + y + z.
        let p = mul_ll(&[1.0, 0.0, 0.0, 1.0], &[0.0, 1.0, 1.0, 0.0]);
        let at = |e: [u8; 3]| {
            let i = index_of(e).unwrap() as u8;
            p[QUADRATIC.iter().position(|q| *q == i).unwrap()]
        };
        assert_eq!(at([1, 1, 0]), 1.0);
        assert_eq!(at([1, 0, 1]), 1.0);
        assert_eq!(at([0, 1, 0]), 1.0);
        assert_eq!(at([0, 0, 1]), 1.0);
        assert_eq!(p.iter().filter(|c| **c != 0.0).count(), 4);
        // (x² + 2 yz + 3)(z - 1) and (z - 1)(x² + 2 yz + 3), term by term.
        let mut q = [0.0; 10];
        q[QUADRATIC.iter().position(|i| *i == 5).unwrap()] = 1.0; // x²
        q[QUADRATIC.iter().position(|i| *i == 14).unwrap()] = 2.0; // yz
        q[9] = 3.0; // 1
        let l = [0.0, 0.0, 1.0, -1.0];
        let (a, b) = (mul_ql(&q, &l), mul_lq(&l, &q));
        assert_eq!(a, b);
        let expect = [
            ([2, 0, 1], 1.0),
            ([2, 0, 0], -1.0),
            ([0, 1, 2], 2.0),
            ([0, 1, 1], -2.0),
            ([0, 0, 1], 3.0),
            ([0, 0, 0], -3.0),
        ];
        for (e, c) in expect {
            assert_eq!(a[index_of(e).unwrap()], c, "{e:?}");
        }
        assert_eq!(a.iter().filter(|c| **c != 0.0).count(), 6);
    }
}
