//! A dense symmetric positive-definite solve in caller-owned memory, for systems whose size is
//! known only at run time (the reduced camera system of a bundle adjustment over many views).

use crate::scalar::{Real, above};
use crate::{Error, Result};

/// Solves `A x = b` for a symmetric positive-definite `n x n` matrix `A` (row-major in the
/// first `n²` scalars of `a`, the lower triangle read) by Cholesky, `A = L Lᵀ`; `a` is
/// overwritten by `L` and `b` by `x`.
///
/// Errors: [`Error::LengthMismatch`] for `a` shorter than `n²` or `b` than `n`;
/// [`Error::Degenerate`] when a pivot is not positive (not positive definite, or too badly
/// conditioned for the type).
pub(crate) fn cholesky_solve<T: Real>(a: &mut [T], n: usize, b: &mut [T]) -> Result<()> {
    let len = n.checked_mul(n).ok_or(Error::LengthMismatch)?;
    let (a, b) = (
        a.get_mut(..len).ok_or(Error::LengthMismatch)?,
        b.get_mut(..n).ok_or(Error::LengthMismatch)?,
    );
    let bad = Error::LengthMismatch;
    for j in 0..n {
        // L_jj = sqrt(A_jj - Σ_k<j L_jk²)
        let row_j = j * n;
        let mut d = *a.get(row_j + j).ok_or(bad)?;
        for k in 0..j {
            let l = *a.get(row_j + k).ok_or(bad)?;
            d -= l * l;
        }
        if !above(d, T::zero()) || !d.finite() {
            return Err(Error::Degenerate);
        }
        let d = d.sqrt();
        *a.get_mut(row_j + j).ok_or(bad)? = d;
        // L_ij = (A_ij - Σ_k<j L_ik L_jk) / L_jj, i > j
        for i in j + 1..n {
            let row_i = i * n;
            let mut s = *a.get(row_i + j).ok_or(bad)?;
            for k in 0..j {
                s -= *a.get(row_i + k).ok_or(bad)? * *a.get(row_j + k).ok_or(bad)?;
            }
            *a.get_mut(row_i + j).ok_or(bad)? = s / d;
        }
    }
    // L y = b
    for i in 0..n {
        let mut s = *b.get(i).ok_or(bad)?;
        for k in 0..i {
            s -= *a.get(i * n + k).ok_or(bad)? * *b.get(k).ok_or(bad)?;
        }
        *b.get_mut(i).ok_or(bad)? = s / *a.get(i * n + i).ok_or(bad)?;
    }
    // Lᵀ x = y
    for i in (0..n).rev() {
        let mut s = *b.get(i).ok_or(bad)?;
        for k in i + 1..n {
            s -= *a.get(k * n + i).ok_or(bad)? * *b.get(k).ok_or(bad)?;
        }
        *b.get_mut(i).ok_or(bad)? = s / *a.get(i * n + i).ok_or(bad)?;
    }
    if b.iter().all(|x| x.finite()) {
        Ok(())
    } else {
        Err(Error::Degenerate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_and_refuses_indefinite() {
        // A = M Mᵀ + I for a fixed M; x = (1, -2, 3).
        let m = [[2.0, 1.0, 0.0], [0.5, 3.0, 1.0], [1.0, 0.0, 4.0]];
        let mut a = [0.0f64; 9];
        for i in 0..3 {
            for j in 0..3 {
                a[i * 3 + j] =
                    (0..3).map(|k| m[i][k] * m[j][k]).sum::<f64>() + if i == j { 1.0 } else { 0.0 };
            }
        }
        let x = [1.0, -2.0, 3.0];
        let mut b: [f64; 3] = core::array::from_fn(|i| (0..3).map(|j| a[i * 3 + j] * x[j]).sum());
        cholesky_solve(&mut a, 3, &mut b).unwrap();
        for (u, v) in b.iter().zip(x) {
            assert!((u - v).abs() < 1e-12);
        }
        let mut not_pd = [1.0f64, 2.0, 2.0, 1.0];
        assert_eq!(
            cholesky_solve(&mut not_pd, 2, &mut [1.0, 1.0]),
            Err(Error::Degenerate)
        );
        assert_eq!(
            cholesky_solve(&mut [1.0f64; 3], 2, &mut [1.0, 1.0]),
            Err(Error::LengthMismatch)
        );
    }
}
