//! The action-matrix solve of the ten cubics (Stewénius, Engels and Nistér 2006; the `f32`
//! solver): multiplication by `x` on the ten monomials of degree ≤ 2, its real eigenvalues and
//! eigenvectors.

use heapless::Vec;
use nalgebra::Matrix3;

use super::accept::{MAX_FIVE_POINT_SOLUTIONS, keep};
use super::monomial::{INDEX, Poly, constraints, gauss_jordan, linear_entries};
use super::polish::polish_direct;
use super::precision::Tolerances;
use crate::linalg::{null_vector, real_eigenvalues};
use crate::scalar::{Real, above};
use crate::twoview::Essential;
use crate::{Error, Result};

/// The monomials of [`action_matrix`]'s elimination, as exponents `(x, y, z)`: the ten of
/// degree 3, eliminated, then its basis `b`, the ten of degree ≤ 2.
const ACTION_MONOMIALS: [[u8; 3]; 20] = [
    [3, 0, 0],
    [2, 1, 0],
    [2, 0, 1],
    [1, 2, 0],
    [1, 1, 1],
    [1, 0, 2],
    [0, 3, 0],
    [0, 2, 1],
    [0, 1, 2],
    [0, 0, 3],
    [2, 0, 0],
    [1, 1, 0],
    [1, 0, 1],
    [0, 2, 0],
    [0, 1, 1],
    [0, 0, 2],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [0, 0, 0],
];

/// Where each of [`ACTION_MONOMIALS`] sits in [`EXPONENTS`](super::monomial::EXPONENTS) (the
/// column order of [`constraints`]).
const ACTION_COLUMNS: [u8; 20] = build_action_columns();

/// `x b_j` for each monomial `b_j` of the action basis: `(true, i)` for the eliminated
/// monomial `i`, `(false, k)` for the basis monomial `k`.
const X_TIMES_BASIS: [(bool, u8); 10] = build_x_times_basis();

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_action_columns() -> [u8; 20] {
    let mut t = [u8::MAX; 20];
    let mut i = 0;
    while i < 20 {
        let e = ACTION_MONOMIALS[i];
        t[i] = INDEX[e[0] as usize][e[1] as usize][e[2] as usize];
        assert!(t[i] != u8::MAX);
        i += 1;
    }
    t
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_x_times_basis() -> [(bool, u8); 10] {
    let mut t = [(false, u8::MAX); 10];
    let mut j = 0;
    while j < 10 {
        let e = ACTION_MONOMIALS[10 + j];
        let mut k = 0;
        while k < 20 {
            let f = ACTION_MONOMIALS[k];
            if f[0] == e[0] + 1 && f[1] == e[1] && f[2] == e[2] {
                t[j] = if k < 10 {
                    (true, k as u8)
                } else {
                    (false, (k - 10) as u8)
                };
            }
            k += 1;
        }
        assert!(t[j].1 != u8::MAX);
        j += 1;
    }
    t
}

/// The action-matrix solve with `E = x X + y Y + z Z + W` for `basis = [X, Y, Z, W]`,
/// appending the solutions to `out`.
///
/// 1. The ten cubics (module docs, step 2), their columns ordered as [`ACTION_COLUMNS`]: the
///    ten monomials of degree 3 first, then the basis `b = (x², xy, xz, y², yz, z², x, y,
///    z, 1)`. Gauss-Jordan elimination of the first ten columns gives each cubic monomial as
///    a combination of `b` at every solution.
/// 2. Multiplication by `x` maps each monomial of `b` to a cubic one (six of them: a row of
///    the eliminated system) or to one of `b` (four: a unit row): `M b = x b` at every
///    solution, so the solutions' `x` are the real eigenvalues of the 10x10 `M`, and `b` its
///    eigenvectors (Stewénius, Engels and Nistér 2006).
/// 3. For each real eigenvalue `x`: `(x : y : z : 1)` from the eigenvector
///    ([`eigenvector_point`]), then the chord polish on `E` ([`polish_direct`]) and the checks
///    of [`keep`].
pub(super) fn action_matrix<T: Real>(
    basis: &[Matrix3<T>; 4],
    rows5: &[[T; 9]; 5],
    tol: &Tolerances<T>,
    out: &mut Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>,
) -> Result<()> {
    let a = constraints(&linear_entries(basis));
    let mut p: [Poly<T>; 10] =
        a.map(|row| ACTION_COLUMNS.map(|c| row.get(usize::from(c)).copied().unwrap_or(T::zero())));
    gauss_jordan(&mut p, tol.pivot)?;
    // Row j of M: x b_j as a combination of b.
    let m: [[T; 10]; 10] = X_TIMES_BASIS.map(|(eliminated, i)| {
        let i = usize::from(i);
        if eliminated {
            let row = p.get(i).copied().unwrap_or([T::zero(); 20]);
            core::array::from_fn(|k| -row.get(10 + k).copied().unwrap_or(T::zero()))
        } else {
            core::array::from_fn(|k| if k == i { T::one() } else { T::zero() })
        }
    });
    let Some(eigenvalues) = real_eigenvalues(&m) else {
        return Err(Error::Degenerate);
    };
    let [bx, by, bz, bw] = basis;
    for &lambda in eigenvalues.iter() {
        let Some(h) = eigenvector_point(&m, lambda) else {
            continue;
        };
        let [hx, hy, hz, hw] = h;
        let size = (hx * hx + hy * hy + hz * hz + hw * hw).sqrt();
        if !above(hw.abs(), tol.homogeneous * size) {
            continue;
        }
        // The polished E meets the ten constraints to rounding: it is on the manifold to
        // that accuracy, scaled to |E| = √2 (unit translation); a root whose constraint
        // residual stays above `solution` |E|³ is not a solution.
        let (x, y, z, cost) = polish_direct(basis, hx / hw, hy / hw, hz / hw);
        let e: Matrix3<T> = *bx * x + *by * y + *bz * z + *bw;
        let n = e.norm();
        let bound = tol.solution * n * n * n;
        if !above(bound * bound, cost) || !above(n, T::zero()) {
            continue;
        }
        let e = e * (T::lit(core::f64::consts::SQRT_2) / n);
        if !e.iter().all(|v| v.finite()) {
            continue;
        }
        keep(Essential { e }, rows5, tol, out);
    }
    Ok(())
}

/// `(x, y, z, 1)` up to scale at the solution whose `x` is the eigenvalue `lambda` of the
/// action matrix `m` ([`action_matrix`]), from its eigenvector `b`.
///
/// The four unit rows of `M b = x b` say `b₀ = x b₆`, `b₁ = x b₇`, `b₂ = x b₈`, `b₆ = x b₉`
/// (`x² = x·x`, `xy = x·y`, `xz = x·z`, `x = x·1`); substituted into the six other rows they
/// leave a 6x6 system whose null vector ([`crate::linalg`]'s `null_vector`: LU, inverse
/// iteration) costs about a fifth of the 10x10 one. For `|x| ≤ 1` the unknowns are the low
/// monomials `(y², yz, z², y, z, 1)` (factors `x`, `x²` in the substitution); above, the
/// high ones `(x², xy, xz, y², yz, z²)` (factors `1/x`, `1/x²`), as partial pivoting would
/// choose: one way only, the `x²`, `x³` of a solution far from the origin cost its digits
/// (noise-study misses 0.4-0.6 % against 0.2-0.45 %). The point is read from the multiple of
/// `(y, z, 1)` or of `(x, y, z)` with the largest factor; `x` itself is the eigenvalue.
fn eigenvector_point<T: Real>(m: &[[T; 10]; 10], lambda: T) -> Option<[T; 4]> {
    let l = lambda;
    // Entry (r, k) of M - λ I.
    let d = |r: usize, k: usize| {
        let v = m
            .get(r)
            .and_then(|row| row.get(k))
            .copied()
            .unwrap_or(T::zero());
        if k == r { v - l } else { v }
    };
    if l.abs() <= T::one() {
        // Unknowns (y², yz, z², y, z, 1): b₀ = x² b₉, b₁ = x b₇, b₂ = x b₈, b₆ = x b₉.
        let a: [[T; 6]; 6] = core::array::from_fn(|r| {
            [
                d(r, 3),
                d(r, 4),
                d(r, 5),
                d(r, 7) + l * d(r, 1),
                d(r, 8) + l * d(r, 2),
                d(r, 9) + l * (d(r, 6) + l * d(r, 0)),
            ]
        });
        let [y2, yz, z2, y, z, one] = null_vector(&a)?;
        // (y, z, 1) times 1, y or z: the one with the largest factor (its last entry).
        let [hy, hz, hw] = largest_at([[y, z, one], [y2, yz, y], [yz, z2, z]], 2);
        Some([l * hw, hy, hz, hw])
    } else {
        // |x| > 1, the substitution the other way (as partial pivoting would take it):
        // unknowns (x², xy, xz, y², yz, z²) with b₆ = b₀ / x, b₇ = b₁ / x, b₈ = b₂ / x,
        // b₉ = b₀ / x².
        let u = T::one() / l;
        let a: [[T; 6]; 6] = core::array::from_fn(|r| {
            [
                d(r, 0) + u * (d(r, 6) + u * d(r, 9)),
                d(r, 1) + u * d(r, 7),
                d(r, 2) + u * d(r, 8),
                d(r, 3),
                d(r, 4),
                d(r, 5),
            ]
        });
        let [x2, xy, xz, y2, yz, z2] = null_vector(&a)?;
        // (x, y, z) times x, y or z: the one with the largest factor (its first entry over x).
        let [hx, hy, hz] = largest_at([[x2, xy, xz], [xy, y2, yz], [xz, yz, z2]], 0);
        // (hx, hy, hz) = s (x, y, z) with s = hx / x.
        Some([hx, hy, hz, hx * u])
    }
}

/// The candidate with the largest `|c[at]|` (the first of equal ones).
fn largest_at<T: Real>(candidates: [[T; 3]; 3], at: usize) -> [T; 3] {
    let key = |c: &[T; 3]| c.get(at).map_or(T::zero(), |v| v.abs());
    candidates.into_iter().fold(
        [T::zero(); 3],
        |best, c| if key(&c) > key(&best) { c } else { best },
    )
}
