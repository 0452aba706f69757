//! One-sided Jacobi SVD (Hestenes, 1958) of small static matrices.
//!
//! Orthogonalise the columns of `A` by plane rotations applied on the right: `W ← W J`,
//! `V ← V J`, starting from `W = A`, `V = I`, so `W = A V` throughout. Each rotation acts on
//! one column pair `(w_p, w_q)` with `α = |w_p|²`, `β = |w_q|²`, `γ = w_p·w_q`:
//!
//! `ζ = (β - α) / 2γ`,  `t = sign(ζ) / (|ζ| + √(1 + ζ²))`,  `c = 1/√(1 + t²)`,  `s = c t`,
//! `w_p ← c w_p - s w_q`,  `w_q ← s w_p + c w_q`,
//!
//! which makes the pair exactly orthogonal. When every pair passes the relative test
//! `|γ| ≤ tol √α √β` (`tol = R ε`), `W = U Σ` with `σ_i = |w_i|` and `u_i = w_i / σ_i`.
//!
//! Why this one: it touches only columns (cache- and register-friendly, no bidiagonalisation),
//! needs no workspace beyond `W` and `V`, its accuracy is that of the columns themselves (small
//! singular values get small *relative* errors, Demmel & Veselić 1992), and `V` stays orthogonal
//! to rounding because it is a product of rotations — which is what a null vector needs.

use nalgebra::{Const, SMatrix, SVector, VectorViewMut};

use super::elementary::hypot;
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Bound on the sweeps (passes over all `C(C-1)/2` column pairs) of [`svd_jacobi`].
///
/// Convergence is quadratic once the off-diagonal mass is small: random 9x9 matrices and the
/// `R` of DLT systems take 6..8 sweeps in `f32` and `f64` (counting the last sweep, which only
/// verifies), so 30 only guards against pathological input. A 9x9 sweep is 36 pair rotations,
/// ~1.3k multiply-adds.
pub const MAX_SWEEPS: u8 = 30;

/// Thin singular value decomposition `A = U Σ Vᵀ` of an `R x C` matrix, `R ≥ C`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Svd<T: Real, const R: usize, const C: usize> {
    /// `U` (`R x C`), orthonormal columns; the column of a singular value that is exactly zero
    /// is zero (it is not determined by `A`).
    pub u: SMatrix<T, R, C>,
    /// `σ₁ ≥ σ₂ ≥ … ≥ σ_C ≥ 0`.
    pub singular_values: SVector<T, C>,
    /// `V` (`C x C`), orthogonal; column `i` is the right singular vector of `σ_i`.
    pub v: SMatrix<T, C, C>,
    /// Sweeps used (at most [`MAX_SWEEPS`]).
    pub sweeps: u8,
}

impl<T: Real, const R: usize, const C: usize> Svd<T, R, C> {
    /// The right singular vector of the smallest singular value, the last column of `V`: the
    /// unit `x` minimising `|A x|` (the least-squares null vector, `|A x| = σ_C`).
    pub fn null_vector(&self) -> SVector<T, C> {
        const { assert!(C > 0, "a null vector needs at least one column") };
        super::elementary::column(&self.v, C - 1)
    }

    /// `U Σ Vᵀ`.
    pub fn recompose(&self) -> SMatrix<T, R, C> {
        let mut us = self.u;
        for (mut col, s) in us.column_iter_mut().zip(self.singular_values.iter()) {
            col *= *s;
        }
        us * self.v.transpose()
    }

    /// The number of singular values above `tol σ₁` (0 for the zero matrix).
    pub fn rank(&self, tol: T) -> usize {
        let s1 = self.singular_values.max();
        self.singular_values
            .iter()
            .filter(|s| **s > tol * s1 && **s > T::zero())
            .count()
    }
}

/// The SVD of `a` by one-sided Jacobi rotations (see the module docs).
///
/// The matrix is first scaled by `1 / max|a_ij|` so no squared column norm can overflow, and
/// the singular values are scaled back. Column pairs whose norms' product is below `ε⁴`
/// (relative to that scale) are left alone: their inner product is at the level of underflow.
///
/// `R ≥ C` is checked at compile time. Errors: [`Error::NonFinite`] for NaN/inf entries (or
/// singular values that overflow), [`Error::NoConvergence`] when [`MAX_SWEEPS`] sweeps end
/// with a pair still failing the orthogonality test.
pub fn svd_jacobi<T: Real, const R: usize, const C: usize>(
    a: &SMatrix<T, R, C>,
) -> Result<Svd<T, R, C>> {
    const {
        assert!(
            R >= C && C > 0,
            "svd_jacobi needs R >= C >= 1 (pad wide matrices)"
        )
    };
    check_finite(a.as_slice())?;
    let mut v = SMatrix::<T, C, C>::identity();
    let scale = a.amax();
    if scale == T::zero() {
        return Ok(Svd {
            u: SMatrix::zeros(),
            singular_values: SVector::zeros(),
            v,
            sweeps: 0,
        });
    }
    let mut w = a / scale;
    let tol = T::EPSILON * T::lit(R as f64);
    let e2 = T::EPSILON * T::EPSILON;
    let tiny = e2 * e2;

    // Each column's squared norm and norm, kept from its last change: a pair that needs no
    // rotation (most of them in the last sweeps) then costs one dot product, not three and
    // two square roots. The same values, to the bit, as recomputing them at every visit.
    let mut norms = [(T::zero(), T::zero()); C];
    for (n, col) in norms.iter_mut().zip(w.column_iter()) {
        let a = col.norm_squared();
        *n = (a, a.sqrt());
    }
    let mut sweeps = 0u8;
    let mut converged = false;
    while sweeps < MAX_SWEEPS {
        sweeps += 1;
        let mut rotated = false;
        for p in 0..C {
            for q in (p + 1)..C {
                let Some((mut wp, mut wq)) = column_pair(&mut w, p, q) else {
                    continue;
                };
                let (Some(&(alpha, ra)), Some(&(beta, rb))) = (norms.get(p), norms.get(q)) else {
                    continue;
                };
                let gamma = wp.dot(&wq);
                let bound = ra * rb;
                if gamma.abs() <= tol * bound || bound <= tiny {
                    continue;
                }
                rotated = true;
                let zeta = (beta - alpha) / (gamma + gamma);
                let t = zeta.signum() / (zeta.abs() + hypot(T::one(), zeta));
                let c = T::one() / hypot(T::one(), t);
                let s = c * t;
                rotate(wp.iter_mut().zip(wq.iter_mut()), c, s);
                let (a, b) = (wp.norm_squared(), wq.norm_squared());
                if let Some(n) = norms.get_mut(p) {
                    *n = (a, a.sqrt());
                }
                if let Some(n) = norms.get_mut(q) {
                    *n = (b, b.sqrt());
                }
                if let Some((mut vp, mut vq)) = column_pair(&mut v, p, q) {
                    rotate(vp.iter_mut().zip(vq.iter_mut()), c, s);
                }
            }
        }
        if !rotated {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(Error::NoConvergence);
    }

    let mut sigma = SVector::<T, C>::zeros();
    for (mut col, s) in w.column_iter_mut().zip(sigma.iter_mut()) {
        let n = col.norm();
        *s = n * scale;
        if n > T::zero() {
            col /= n;
        }
    }
    check_finite(sigma.as_slice())?;
    // Selection sort, descending, moving the columns of U and V along.
    for i in 0..C {
        let mut best = i;
        for (j, s) in sigma.iter().enumerate().skip(i + 1) {
            if sigma.get(best).is_some_and(|b| *s > *b) {
                best = j;
            }
        }
        if best != i && best < C {
            if let (Some(a), Some(b)) = (sigma.get(i).copied(), sigma.get(best).copied()) {
                if let Some(x) = sigma.get_mut(i) {
                    *x = b;
                }
                if let Some(y) = sigma.get_mut(best) {
                    *y = a;
                }
            }
            swap_columns(&mut w, i, best);
            swap_columns(&mut v, i, best);
        }
    }
    Ok(Svd {
        u: w,
        singular_values: sigma,
        v,
        sweeps,
    })
}

/// Columns `p < q` of `m` as two slices of `R` entries, `None` out of range. Taken from the
/// column-major storage with checked slicing: nalgebra's `columns_range_pair_mut` and
/// `swap_columns` assert their ranges, a panic path the optimiser keeps when the sweep loops
/// are not unrolled.
fn column_slices<T: Real, const R: usize, const C: usize>(
    m: &mut SMatrix<T, R, C>,
    p: usize,
    q: usize,
) -> Option<(&mut [T], &mut [T])> {
    if p >= q {
        return None;
    }
    let (left, right) = m.as_mut_slice().split_at_mut_checked(q.checked_mul(R)?)?;
    let cp = left.get_mut(p.checked_mul(R)?..)?.get_mut(..R)?;
    let cq = right.get_mut(..R)?;
    Some((cp, cq))
}

/// [`column_slices`] as nalgebra column views (same arithmetic as the matrix's own columns).
#[allow(clippy::type_complexity)]
fn column_pair<T: Real, const R: usize, const C: usize>(
    m: &mut SMatrix<T, R, C>,
    p: usize,
    q: usize,
) -> Option<(
    VectorViewMut<'_, T, Const<R>>,
    VectorViewMut<'_, T, Const<R>>,
)> {
    let (cp, cq) = column_slices(m, p, q)?;
    Some((
        VectorViewMut::<T, Const<R>>::from_slice_generic(cp, Const::<R>, Const::<1>),
        VectorViewMut::<T, Const<R>>::from_slice_generic(cq, Const::<R>, Const::<1>),
    ))
}

/// Swaps columns `i` and `j` of `m` (nothing when out of range).
fn swap_columns<T: Real, const R: usize, const C: usize>(
    m: &mut SMatrix<T, R, C>,
    i: usize,
    j: usize,
) {
    if let Some((a, b)) = column_slices(m, i.min(j), i.max(j)) {
        for (x, y) in a.iter_mut().zip(b.iter_mut()) {
            core::mem::swap(x, y);
        }
    }
}

/// `(x, y) ← (c x - s y, s x + c y)` over paired entries.
fn rotate<'a, T: Real + 'a>(pairs: impl Iterator<Item = (&'a mut T, &'a mut T)>, c: T, s: T) {
    for (x, y) in pairs {
        let (a, b) = (*x, *y);
        *x = c * a - s * b;
        *y = s * a + c * b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use nalgebra::{Matrix3, SMatrix, Vector3};

    fn random<const R: usize, const C: usize>(g: &mut Pcg32) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| g.uniform(-1.0, 1.0))
    }

    /// Sorted descending copy (nalgebra does not sort its singular values).
    fn sorted<const C: usize>(v: &SVector<f64, C>) -> [f64; C] {
        let mut out = [0.0; C];
        out.iter_mut().zip(v.iter()).for_each(|(o, s)| *o = *s);
        out.sort_by(|x, y| y.partial_cmp(x).unwrap());
        out
    }

    fn check_decomposition<const R: usize, const C: usize>(
        a: &SMatrix<f64, R, C>,
        reference: &SVector<f64, C>,
        tol: f64,
    ) {
        let s = svd_jacobi(a).unwrap();
        assert!((s.recompose() - a).amax() <= tol * a.amax(), "recompose");
        let vtv = s.v.transpose() * s.v;
        assert!((vtv - SMatrix::<f64, C, C>::identity()).amax() < tol);
        let utu = s.u.transpose() * s.u;
        assert!((utu - SMatrix::<f64, C, C>::identity()).amax() < tol);
        for w in s.singular_values.as_slice().windows(2) {
            assert!(w[0] >= w[1] && w[1] >= 0.0);
        }
        let reference = sorted(reference);
        for (x, y) in s.singular_values.iter().zip(reference.iter()) {
            assert!((x - y).abs() <= tol * reference[0], "{x} vs {y}");
        }
    }

    macro_rules! check {
        ($g:expr, $r:literal, $c:literal, $tol:expr) => {{
            let a = random::<$r, $c>($g);
            check_decomposition(&a, &a.singular_values(), $tol);
        }};
    }

    #[test]
    fn random_matrices_match_nalgebra() {
        let mut g = Pcg32::new(1);
        for _ in 0..50 {
            check!(&mut g, 9, 9, 1e-13);
            check!(&mut g, 12, 9, 1e-13);
            check!(&mut g, 3, 3, 1e-14);
            check!(&mut g, 5, 2, 1e-14);
            check!(&mut g, 1, 1, 1e-15);
        }
    }

    #[test]
    fn singular_vectors_match_nalgebra() {
        let mut g = Pcg32::new(2);
        for _ in 0..20 {
            let a = random::<10, 6>(&mut g);
            let s = svd_jacobi(&a).unwrap();
            let r = a.svd(true, true);
            let vt = r.v_t.unwrap();
            let ut = r.u.unwrap();
            // Match each of our (sorted) singular triplets to nalgebra's by singular value.
            for k in 0..6 {
                let i = r
                    .singular_values
                    .iter()
                    .enumerate()
                    .min_by(|a, b| {
                        let da = (a.1 - s.singular_values[k]).abs();
                        let db = (b.1 - s.singular_values[k]).abs();
                        da.partial_cmp(&db).unwrap()
                    })
                    .unwrap()
                    .0;
                // Distinct singular values: vectors agree up to sign, |cos| = 1.
                let cv = s.v.column(k).dot(&vt.row(i).transpose()).abs();
                let cu = s.u.column(k).dot(&ut.column(i)).abs();
                assert!((1.0 - cv).abs() < 1e-12 && (1.0 - cu).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn rank_deficient_matrices() {
        let mut g = Pcg32::new(3);
        for rank in 0..=9 {
            // A = B Cᵀ with B, C of size 9 x rank (zero columns beyond the rank).
            let b =
                SMatrix::<f64, 9, 9>::from_fn(
                    |_, j| {
                        if j < rank { g.uniform(-1.0, 1.0) } else { 0.0 }
                    },
                );
            let c = random::<9, 9>(&mut g);
            let a = b * c.transpose();
            let s = svd_jacobi(&a).unwrap();
            assert_eq!(s.rank(1e-10), rank);
            assert!((s.recompose() - a).amax() < 1e-13);
            // The trailing V columns span the null space of A.
            for k in rank..9 {
                assert!((a * s.v.column(k)).amax() < 1e-13);
            }
            let vtv = s.v.transpose() * s.v;
            assert!((vtv - SMatrix::<f64, 9, 9>::identity()).amax() < 1e-13);
            // The U columns of non-zero singular values are orthonormal.
            let utu = s.u.transpose() * s.u;
            for i in 0..rank {
                for j in 0..rank {
                    let e = if i == j { 1.0 } else { 0.0 };
                    assert!((utu[(i, j)] - e).abs() < 1e-12);
                }
            }
            // Also in f32.
            let s32 = svd_jacobi(&a.cast::<f32>()).unwrap();
            assert_eq!(s32.rank(1e-4), rank);
            assert!(s32.sweeps < MAX_SWEEPS);
        }
    }

    #[test]
    fn graded_columns_keep_relative_accuracy() {
        // A = B D, D = diag(1, 1e-3, …, 1e-24): one-sided Jacobi gets the tiny singular values
        // to relative accuracy ~ ε cond(B) (Demmel & Veselić).
        let mut g = Pcg32::new(4);
        let d = SMatrix::<f64, 9, 9>::from_diagonal(&SVector::from_fn(|i, _| {
            10f64.powi(-3 * i as i32)
        }));
        let a = random::<9, 9>(&mut g) * d;
        let s = svd_jacobi(&a).unwrap();
        assert!((s.recompose() - a).amax() < 1e-14);
        let s_small = s.singular_values[8];
        assert!(s_small > 0.0 && s_small < 1e-23);
        // |A v| = σ for the last singular vector, to relative accuracy.
        let av = (a * s.v.column(8)).norm();
        assert!(((av - s_small) / s_small).abs() < 1e-6, "{av} {s_small}");
    }

    #[test]
    fn special_inputs() {
        let z = Matrix3::<f32>::zeros();
        let s = svd_jacobi(&z).unwrap();
        assert_eq!(s.singular_values, SVector::<f32, 3>::zeros());
        assert_eq!(s.v, Matrix3::identity());
        assert_eq!(s.rank(1e-6), 0);
        let mut a = Matrix3::<f32>::identity();
        a[(1, 2)] = f32::NAN;
        assert_eq!(svd_jacobi(&a), Err(Error::NonFinite));
        a[(1, 2)] = f32::INFINITY;
        assert_eq!(svd_jacobi(&a), Err(Error::NonFinite));
        // Huge and tiny entries do not overflow or underflow the column norms.
        let big = Matrix3::new(3e37f32, 1e37, 0.0, 0.0, 2e37, 1e37, 1e37, 0.0, 1e37);
        let s = svd_jacobi(&big).unwrap();
        let r = (s.recompose() - big).amax() / big.amax();
        assert!(r < 1e-6, "{r}");
        let small = big * 1e-37f32 * 1e-37f32; // entries ~1e-37, near the smallest normal
        let s = svd_jacobi(&small).unwrap();
        let r = (s.recompose() - small).amax() / small.amax();
        assert!(r < 1e-5, "{r}");
        // The identity needs one sweep (no rotation).
        let s = svd_jacobi(&Matrix3::<f64>::identity()).unwrap();
        assert_eq!(s.sweeps, 1);
        assert_eq!(s.singular_values, SVector::<f64, 3>::from_element(1.0));
        // Diagonal input comes back sorted with V a permutation.
        let d = Matrix3::from_diagonal(&Vector3::new(1.0f64, 5.0, 3.0));
        let s = svd_jacobi(&d).unwrap();
        assert_eq!(s.singular_values.as_slice(), &[5.0, 3.0, 1.0]);
        assert_eq!(s.null_vector().abs(), Vector3::new(1.0, 0.0, 0.0));
    }
}
