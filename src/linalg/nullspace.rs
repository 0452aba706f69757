//! The null space of a few rows by Gauss-Jordan elimination (minimal solvers).

use super::elementary::swap_rows;
use crate::corners::swap_checked;
use crate::scalar::{Real, above};
use crate::{Error, Result};

/// An orthonormal basis of the null space of `R` rows of `C = R + K` (full row rank), the
/// cheap alternative to the last `K` right singular vectors of an SVD for minimal solvers.
///
/// Gauss-Jordan elimination with full pivoting brings the rows to `[I | B]` (columns
/// permuted), whose null space is spanned by the columns of `[-B; I]`; modified Gram-Schmidt
/// then makes those `K` vectors orthonormal. About `R² C` multiply-adds (450 for 7 rows of
/// 9), against a few thousand for a QR and a one-sided Jacobi SVD of the same rows. With full
/// pivoting the elimination is backward stable in practice; scale the rows alike (e.g. unit
/// rows) so that the pivot test means the same for each.
///
/// Errors: [`Error::Degenerate`] when a pivot falls below `rank` times the first (the
/// largest entry), or is not finite: the rows are (nearly) dependent.
pub(crate) fn null_space<T: Real, const R: usize, const C: usize, const K: usize>(
    rows: &[[T; C]; R],
    rank: T,
) -> Result<[[T; C]; K]> {
    const { assert!(R + K == C && K > 0, "null_space: K must be C - R") };
    let mut m = *rows;
    let mut perm: [usize; C] = core::array::from_fn(|j| j);
    let mut first = T::zero();
    for i in 0..R {
        // Largest entry of the trailing block.
        let mut best = (i, i, T::zero());
        for (r, row) in m.iter().enumerate().skip(i) {
            for (c, v) in row.iter().enumerate().skip(i) {
                if v.abs() > best.2 {
                    best = (r, c, v.abs());
                }
            }
        }
        let (pr, pc, mag) = best;
        if i == 0 {
            first = mag;
        }
        if !above(mag, rank * first) || !mag.finite() {
            return Err(Error::Degenerate);
        }
        // `i`, `pr` < rows and `i`, `pc` < columns (the search above).
        swap_rows(&mut m, i, pr);
        for row in m.iter_mut() {
            swap_checked(row, i, pc);
        }
        swap_checked(&mut perm, i, pc);
        // In place, the pivot row borrowed: whole-row copies are `memcpy` calls on a Cortex-M.
        let Some((before, rest)) = m.split_at_mut_checked(i) else {
            return Err(Error::Degenerate);
        };
        let Some((pivot, after)) = rest.split_first_mut() else {
            return Err(Error::Degenerate);
        };
        let inv = T::one() / pivot.get(i).copied().unwrap_or(T::one());
        pivot.iter_mut().for_each(|v| *v *= inv);
        for row in before.iter_mut().chain(after.iter_mut()) {
            let f = row.get(i).copied().unwrap_or(T::zero());
            row.iter_mut()
                .zip(pivot.iter())
                .for_each(|(a, p)| *a -= f * *p);
        }
    }
    // Null vector k (permuted coordinates): -B[:, k] on the pivots, 1 at column R + k.
    let mut basis = [[T::zero(); C]; K];
    for (k, v) in basis.iter_mut().enumerate() {
        for (i, row) in m.iter().enumerate() {
            let (Some(&p), Some(&b)) = (perm.get(i), row.get(R + k)) else {
                continue;
            };
            if let Some(slot) = v.get_mut(p) {
                *slot = -b;
            }
        }
        if let Some(slot) = perm.get(R + k).and_then(|p| v.get_mut(*p)) {
            *slot = T::one();
        }
    }
    // Modified Gram-Schmidt (the vectors are independent: each has its own unit coordinate).
    for k in 0..K {
        let (done, rest) = basis.split_at_mut(k);
        let Some(v) = rest.first_mut() else {
            break;
        };
        for u in done.iter() {
            let d = u
                .iter()
                .zip(v.iter())
                .fold(T::zero(), |a, (p, q)| a + *p * *q);
            v.iter_mut().zip(u.iter()).for_each(|(x, p)| *x -= d * *p);
        }
        let n = v.iter().fold(T::zero(), |a, x| a + *x * *x).sqrt();
        if !above(n, T::zero()) {
            return Err(Error::Degenerate);
        }
        v.iter_mut().for_each(|x| *x /= n);
    }
    Ok(basis)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    #[test]
    fn orthonormal_and_null() {
        let mut g = Pcg32::new(21);
        for _ in 0..200 {
            let rows: [[f64; 9]; 7] =
                core::array::from_fn(|_| core::array::from_fn(|_| g.uniform(-1.0, 1.0)));
            let basis: [[f64; 9]; 2] = null_space(&rows, 1e-10).unwrap();
            for (i, u) in basis.iter().enumerate() {
                for r in &rows {
                    let d: f64 = r.iter().zip(u).map(|(a, b)| a * b).sum();
                    // Rows of norm ~1.7: the residual is at rounding level.
                    assert!(d.abs() < 1e-13, "{d:e}");
                }
                for (j, v) in basis.iter().enumerate() {
                    let d: f64 = u.iter().zip(v).map(|(a, b)| a * b).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((d - want).abs() < 1e-14, "{d}");
                }
            }
            // The same space as the SVD's last two right singular vectors: each basis vector
            // lies in their span.
            let mut qr = crate::linalg::StreamingQr::<f64, 9>::new();
            rows.iter().for_each(|r| qr.push_row(r).unwrap());
            let svd = qr.svd().unwrap();
            for u in &basis {
                let u = nalgebra::SVector::<f64, 9>::from(*u);
                let p = svd.v.column(7) * svd.v.column(7).dot(&u)
                    + svd.v.column(8) * svd.v.column(8).dot(&u);
                assert!((p - u).amax() < 1e-12);
            }
        }
    }

    #[test]
    fn dependent_rows_are_degenerate() {
        let mut rows = [[0.0f32; 4]; 2];
        rows[0] = [1.0, 2.0, 3.0, 4.0];
        rows[1] = [2.0, 4.0, 6.0, 8.0];
        assert_eq!(
            null_space::<f32, 2, 4, 2>(&rows, 1e-4),
            Err(Error::Degenerate)
        );
        rows[1] = [0.0, 1.0, 0.0, 0.0];
        let b: [[f32; 4]; 2] = null_space(&rows, 1e-4).unwrap();
        for u in &b {
            assert!((u[1]).abs() < 1e-6);
        }
        rows[1][2] = f32::NAN;
        assert_eq!(
            null_space::<f32, 2, 4, 2>(&rows, 1e-4),
            Err(Error::Degenerate)
        );
    }
}
