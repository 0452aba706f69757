//! Streaming QR: the `R` factor of a tall matrix absorbed one row at a time.
//!
//! For `A = Q R` (`A` is `m x C`, `m` unbounded), each new row `aᵀ` is folded into the upper
//! triangular `R` by `C` Givens rotations that zero it left to right:
//!
//! `[R; aᵀ] = G₁ … G_C [R'; 0]`,  with `G_k` rotating row `k` of `R` against `a` in the plane
//! that zeroes `a_k`:  `r = hypot(R_kk, a_k)`, `c = R_kk / r`, `s = a_k / r`.
//!
//! Because only orthogonal transforms touch the data, `RᵀR = AᵀA` holds to rounding while the
//! condition number of `R` is that of `A`, not `cond(A)²` as with the normal equations. `A` and
//! `R` share their singular values and right singular vectors, so the least-squares null vector
//! of an arbitrarily tall `A` is the last right singular vector of the `C x C` matrix `R`
//! ([`StreamingQr::svd`]), computed in `C² + 1` words of memory.

use nalgebra::{SMatrix, SVector};

use super::elementary::hypot;
use super::reduction::{solve_lower_transposed, solve_upper};
use super::svd::{Svd, svd_jacobi};
use crate::Result;
use crate::scalar::{Real, above, check_finite};

/// The upper-triangular `R` (`C x C`) of all rows pushed so far, `RᵀR = AᵀA`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StreamingQr<T: Real, const C: usize> {
    r: SMatrix<T, C, C>,
    rows: usize,
}

impl<T: Real, const C: usize> Default for StreamingQr<T, C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, const C: usize> StreamingQr<T, C> {
    /// No rows yet: `R = 0`.
    pub fn new() -> Self {
        Self {
            r: SMatrix::zeros(),
            rows: 0,
        }
    }

    /// Forgets all rows.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// Absorbs the row `aᵀ` (`C` Givens rotations, `~2C²` multiplications).
    ///
    /// Errors with [`crate::Error::NonFinite`] (and leaves `R` unchanged) when the row holds
    /// NaN or an infinity.
    pub fn push_row(&mut self, row: &[T; C]) -> Result<()> {
        check_finite(row)?;
        let mut a = *row;
        // Rotation `k` zeroes `a_k` against `R_kk`; it acts on `(R_kj, a_j)` for `j ≥ k`, and
        // `a_j` sees the rotations in the order `k = 0, 1, …, j - 1`. Sweeping the columns of
        // the (column-major) `R` in order applies exactly that sequence to every entry, so
        // the result is the row-by-row one to the bit (up to the sign of a zero), but each column is one contiguous
        // slice and rotation `j` is formed as soon as column `j` has seen the earlier ones.
        // A skipped rotation (`a_k = 0` when its turn came) stays `(c, s) = (1, 0)`, which
        // leaves its entries unchanged (to the sign of a zero).
        let mut cs = [(T::one(), T::zero()); C];
        for (j, col) in self.r.as_mut_slice().chunks_exact_mut(C).enumerate() {
            let Some(aj) = a.get_mut(j) else {
                break;
            };
            for (r, &(c, s)) in col.iter_mut().zip(cs.iter()).take(j) {
                let (rv, xv) = (*r, *aj);
                *r = c * rv + s * xv;
                *aj = c * xv - s * rv;
            }
            // Entries of `a` left of `j` are now zero; those of row `j` of `R` too.
            let (Some(rjj), Some(slot)) = (col.get_mut(j), cs.get_mut(j)) else {
                break;
            };
            if *aj == T::zero() {
                continue;
            }
            let h = hypot(*rjj, *aj);
            let (c, s) = (*rjj / h, *aj / h);
            let (rv, xv) = (*rjj, *aj);
            *rjj = c * rv + s * xv;
            *aj = c * xv - s * rv;
            *slot = (c, s);
        }
        self.rows = self.rows.saturating_add(1);
        Ok(())
    }

    /// Absorbs the row `w aᵀ`: the row's squared residual is weighted by `w²`.
    pub fn push_row_weighted(&mut self, row: &[T; C], w: T) -> Result<()> {
        let mut a = *row;
        for x in a.iter_mut() {
            *x *= w;
        }
        self.push_row(&a)
    }

    /// Absorbs every row pushed into `other` (its `R`'s rows), as if they had been pushed here:
    /// QR of separately accumulated blocks.
    pub fn absorb(&mut self, other: &Self) -> Result<()> {
        let before = self.rows;
        for row in other.r.row_iter() {
            let mut a = [T::zero(); C];
            for (x, v) in a.iter_mut().zip(row.iter()) {
                *x = *v;
            }
            self.push_row(&a)?;
        }
        // The pushes above counted `C` rows; count the rows `other` really holds.
        self.rows = before.saturating_add(other.rows);
        Ok(())
    }

    /// Rows pushed so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// `R`, upper triangular.
    pub fn r(&self) -> &SMatrix<T, C, C> {
        &self.r
    }

    /// `AᵀA = RᵀR` (for tests and diagnostics; solving with it squares the condition number).
    pub fn gram(&self) -> SMatrix<T, C, C> {
        self.r.transpose() * self.r
    }

    /// The SVD of `R`: the singular values and right singular vectors of every row pushed.
    pub fn svd(&self) -> Result<Svd<T, C, C>> {
        svd_jacobi(&self.r)
    }

    /// The unit `x` minimising `|A x|` (last right singular vector), with `σ_min = |A x|`.
    pub fn null_vector(&self) -> Result<(SVector<T, C>, T)> {
        let s = self.svd()?;
        let smin = s.singular_values.min();
        Ok((s.null_vector(), smin))
    }
}

/// Bound on the inverse iterations of [`StreamingQr::null_vector_of_rank`] (each halves the
/// error at least when `σ_C < 0.7 σ_{C-1}`; slower problems take the SVD).
const MAX_INVERSE_ITERATIONS: usize = 40;

impl<T: Real, const C: usize> StreamingQr<T, C> {
    /// The least-squares null vector of the rows pushed (the unit `x` minimising `|A x|`, as
    /// [`Self::null_vector`]) when they have rank at least `C - 1`, else
    /// [`crate::Error::Degenerate`]: `σ_{C-1} ≤ tol |R|_F` (at most `√C` times stricter than
    /// the `σ_{C-1} ≤ tol σ₁` of a full SVD) or `R = 0`. [`crate::Error::NonFinite`] for a
    /// non-finite `R`.
    ///
    /// By inverse iteration on `RᵀR = AᵀA` without forming it: each step solves `Rᵀ y = x`
    /// and `R z = y` (two triangular solves, `C²` products) and normalises, so the error
    /// shrinks by `(σ_C / σ_{C-1})²` a step; then the same, kept orthogonal to the null vector,
    /// bounds `σ_{C-1}` from above (`min |R x|` over `x ⊥ v` is `σ_{C-1}`), enough for the
    /// rank test. A fraction of the Jacobi SVD's cost; problems it does not settle in 40
    /// steps (close `σ_C`, `σ_{C-1}`, or a zero on `R`'s diagonal) take the SVD.
    pub fn null_vector_of_rank(&self, tol: T) -> Result<SVector<T, C>> {
        const { assert!(C > 1, "a rank test needs two columns") };
        check_finite(self.r.as_slice())?;
        let norm = self.r.norm();
        if norm == T::zero() {
            return Err(crate::Error::Degenerate);
        }
        let settled = T::EPSILON * T::lit(8.0);
        let diagonal_ok = (0..C).all(|k| {
            self.r
                .get((k, k))
                .is_some_and(|d| above(d.abs(), T::EPSILON * norm))
        });
        let inverse = |x: &SVector<T, C>| solve_upper(&self.r, solve_lower_transposed(&self.r, *x));
        if diagonal_ok {
            let mut v = SVector::<T, C>::zeros();
            if let Some(last) = v.get_mut(C - 1) {
                *last = T::one();
            }
            let mut found = false;
            for _ in 0..MAX_INVERSE_ITERATIONS {
                let z = inverse(&v);
                let n = z.norm();
                if !above(n, T::zero()) || !n.finite() {
                    break;
                }
                let next = z / n;
                let change = (next - v).amax();
                v = next;
                if !above(change, settled) {
                    found = true;
                    break;
                }
            }
            if found {
                // σ_{C-1}: a start orthogonal to v, then deflated inverse iteration.
                let mut u = SVector::<T, C>::zeros();
                let k = v.iamin();
                if let Some(e) = u.get_mut(k) {
                    *e = T::one();
                }
                let mut bound = None;
                for _ in 0..MAX_INVERSE_ITERATIONS {
                    u -= v * v.dot(&u);
                    let n = u.norm();
                    if !above(n, T::zero()) || !n.finite() {
                        break;
                    }
                    u /= n;
                    let s = (self.r * u).norm();
                    let settled_s =
                        bound.is_some_and(|b: T| !above((b - s).abs(), T::lit(1e-3) * s));
                    bound = Some(s);
                    if settled_s || !above(s, tol * norm) {
                        break;
                    }
                    u = inverse(&u);
                }
                return match bound {
                    Some(s) if above(s, tol * norm) => Ok(v),
                    Some(_) => Err(crate::Error::Degenerate),
                    None => self.null_vector_by_svd(tol),
                };
            }
        }
        self.null_vector_by_svd(tol)
    }

    /// [`Self::null_vector_of_rank`] by the Jacobi SVD of `R`.
    fn null_vector_by_svd(&self, tol: T) -> Result<SVector<T, C>> {
        let svd = self.svd()?;
        let s = svd.singular_values.as_slice();
        match (s.first(), s.get(C - 2)) {
            (Some(&s1), Some(&s2)) if above(s2, tol * s1) => Ok(svd.null_vector()),
            _ => Err(crate::Error::Degenerate),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;
    use crate::rng::Pcg32;

    #[test]
    fn r_matches_gram_and_householder_qr() {
        let mut g = Pcg32::new(11);
        let a = SMatrix::<f64, 40, 9>::from_fn(|_, _| g.uniform(-1.0, 1.0));
        let mut qr = StreamingQr::<f64, 9>::new();
        for row in a.row_iter() {
            let mut r = [0.0; 9];
            r.iter_mut().zip(row.iter()).for_each(|(x, v)| *x = *v);
            qr.push_row(&r).unwrap();
        }
        assert_eq!(qr.rows(), 40);
        let gram = a.transpose() * a;
        assert!((gram - qr.gram()).amax() < 1e-12 * gram.amax());
        for i in 0..9 {
            for j in 0..i {
                assert_eq!(qr.r()[(i, j)], 0.0);
            }
        }
        // Same R as Householder QR up to the signs of its rows.
        let reference = a.qr().r();
        for i in 0..9 {
            let sign = reference[(i, i)].signum() * qr.r()[(i, i)].signum();
            for j in 0..9 {
                assert!((reference[(i, j)] - sign * qr.r()[(i, j)]).abs() < 1e-12);
            }
        }
        // Singular values of R are those of A.
        let mut sv_a = [0.0; 9];
        sv_a.iter_mut()
            .zip(a.singular_values().iter())
            .for_each(|(o, s)| *o = *s);
        sv_a.sort_by(|x, y| y.partial_cmp(x).unwrap());
        let s = qr.svd().unwrap();
        for (x, y) in s.singular_values.iter().zip(sv_a.iter()) {
            assert!((x - y).abs() < 1e-12);
        }
    }

    /// The row-by-row Givens sweep, as written before the column-ordered one.
    fn push_row_reference<const C: usize>(r: &mut SMatrix<f64, C, C>, row: &[f64; C]) {
        let mut a = *row;
        for k in 0..C {
            if a[k] == 0.0 {
                continue;
            }
            let h = hypot(r[(k, k)], a[k]);
            let (c, s) = (r[(k, k)] / h, a[k] / h);
            for j in k..C {
                let (rv, xv) = (r[(k, j)], a[j]);
                r[(k, j)] = c * rv + s * xv;
                a[j] = c * xv - s * rv;
            }
        }
    }

    #[test]
    fn column_sweep_is_bit_identical_to_the_row_sweep() {
        // Same operations in the same order per entry: equality, not a tolerance (`==` takes
        // -0 for 0, the one difference a skipped rotation applied as `(1, 0)` can make). Rows
        // with zeros exercise the skipped rotations.
        let mut g = Pcg32::new(13);
        let mut qr = StreamingQr::<f64, 12>::new();
        let mut reference = SMatrix::<f64, 12, 12>::zeros();
        for i in 0..60 {
            let row: [f64; 12] = core::array::from_fn(|j| {
                if (i + j) % 5 == 0 {
                    0.0
                } else {
                    g.uniform(-2.0, 2.0)
                }
            });
            qr.push_row(&row).unwrap();
            push_row_reference(&mut reference, &row);
            assert_eq!(*qr.r(), reference);
        }
    }

    #[test]
    fn absorb_equals_pushing_everything() {
        let mut g = Pcg32::new(12);
        let rows: [[f64; 4]; 13] =
            core::array::from_fn(|_| core::array::from_fn(|_| g.uniform(-3.0, 3.0)));
        let mut all = StreamingQr::<f64, 4>::new();
        rows.iter().for_each(|r| all.push_row(r).unwrap());
        let mut a = StreamingQr::<f64, 4>::new();
        let mut b = StreamingQr::<f64, 4>::new();
        rows[..5].iter().for_each(|r| a.push_row(r).unwrap());
        rows[5..].iter().for_each(|r| b.push_row(r).unwrap());
        a.absorb(&b).unwrap();
        assert_eq!(a.rows(), 13);
        assert!((a.gram() - all.gram()).amax() < 1e-12);
    }

    /// The inverse iteration's null vector is the SVD's (to the angle rounding allows,
    /// `1e-12` in `f64`, `1e-4` in `f32` for these well separated `σ`s) on tall random
    /// matrices from well conditioned to nearly rank `C - 1`, and both call the same problems
    /// degenerate (rank `C - 2`, a zero matrix).
    #[test]
    fn inverse_iteration_null_vector_is_the_svds() {
        let mut g = Pcg32::new(11);
        for trial in 0..300 {
            // Rows near a random hyperplane: σ₉ set by the noise, 1e-9 .. 1e-1.
            let normal = SVector::<f64, 9>::from_fn(|_, _| g.uniform(-1.0, 1.0)).normalize();
            let noise = 10f64.powf(g.uniform(-9.0, -1.0));
            let mut qr = StreamingQr::<f64, 9>::new();
            let mut qr32 = StreamingQr::<f32, 9>::new();
            for _ in 0..(9 + trial % 60) {
                let mut row = SVector::<f64, 9>::from_fn(|_, _| g.uniform(-1.0, 1.0));
                row -= normal * normal.dot(&row);
                row += normal * g.uniform(-noise, noise);
                let r: [f64; 9] = row.into();
                qr.push_row(&r).unwrap();
                qr32.push_row(&r.map(|v| v as f32)).unwrap();
            }
            let tol = 1.5e-8;
            let (want, _) = qr.null_vector().unwrap();
            let got = qr.null_vector_of_rank(tol).unwrap();
            let angle = (want - got).amax().min((want + got).amax());
            assert!(angle < 1e-12, "trial {trial}: {angle:e}, noise {noise:e}");
            if noise > 1e-3 {
                let (want32, _) = qr32.null_vector().unwrap();
                let got32 = qr32.null_vector_of_rank(3.5e-4).unwrap();
                let angle = (want32 - got32).amax().min((want32 + got32).amax());
                assert!(
                    angle < 1e-4,
                    "f32 trial {trial}: {angle:e}, noise {noise:e}"
                );
            }
        }
        // Rank 7 of 9 (two null directions): degenerate by either route.
        let mut qr = StreamingQr::<f64, 9>::new();
        for _ in 0..30 {
            let mut row = [0.0; 9];
            for v in row.iter_mut().take(7) {
                *v = g.uniform(-1.0, 1.0);
            }
            qr.push_row(&row).unwrap();
        }
        assert_eq!(qr.null_vector_of_rank(1.5e-8), Err(Error::Degenerate));
        assert_eq!(qr.null_vector_by_svd(1.5e-8), Err(Error::Degenerate));
        assert_eq!(
            StreamingQr::<f64, 9>::new().null_vector_of_rank(1.5e-8),
            Err(Error::Degenerate)
        );
    }

    #[test]
    fn fewer_rows_than_columns_and_bad_rows() {
        let mut qr = StreamingQr::<f32, 3>::new();
        qr.push_row(&[0.0, 2.0, 0.0]).unwrap();
        qr.push_row(&[0.0, 0.0, 0.0]).unwrap();
        assert_eq!(qr.rows(), 2);
        let before = qr;
        assert_eq!(qr.push_row(&[1.0, f32::NAN, 0.0]), Err(Error::NonFinite));
        assert_eq!(qr, before);
        // Rank 1: a 2-dimensional null space, spanned by the last two columns of V.
        let s = qr.svd().unwrap();
        assert_eq!(s.rank(1e-6), 1);
        assert!((s.singular_values[0] - 2.0).abs() < 1e-6);
        let (v, smin) = qr.null_vector().unwrap();
        assert_eq!(smin, 0.0);
        assert!(v[1].abs() < 1e-6);
        qr.push_row_weighted(&[1.0, 0.0, 0.0], 3.0).unwrap();
        assert!((qr.r()[(0, 0)].abs() - 3.0).abs() < 1e-6);
        qr.reset();
        assert_eq!(qr.rows(), 0);
        assert_eq!(*qr.r(), SMatrix::<f32, 3, 3>::zeros());
    }
}
