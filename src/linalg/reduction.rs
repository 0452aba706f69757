//! Harker and O'Leary's reduction of paired linear systems (BMVC 2005): the least-squares null
//! vectors of a system whose equations come in pairs sharing one coefficient vector.
//!
//! The homography DLT and EPnP both solve `min |M x|` over stacked pairs of equations
//!
//! `aᵢ·p = uᵢ aᵢ·r`,  `aᵢ·q = vᵢ aᵢ·r`,
//!
//! with unknowns `x = (p, q, r)` in three blocks of `K` (the DLT: the rows `h₁, h₂, h₃` of
//! `H`, `aᵢ = (x, y, 1)`; EPnP: the control points' `x`, `y` and `z` coordinates, `aᵢ` the
//! barycentric weights). With `A` the matrix of the `aᵢ` and `D_u = diag(uᵢ)` the error is
//! `|A p - D_u A r|² + |A q - D_v A r|²`. One row `[aᵢᵀ, uᵢ aᵢᵀ, vᵢ aᵢᵀ]` a pair into a
//! `3K`-column [`super::StreamingQr`] gives `R` with `K x K` blocks `R_ij`. For any `r` the best
//! `p` and `q` are
//!
//! `p = R₁₁⁻¹ R₁₂ r`,  `q = R₁₁⁻¹ R₁₃ r`,
//!
//! and what is left is `|B r|²`, `B = [R₂₂; R₂₃; R₃₃]` (`3K x K`): the smallest right singular
//! vectors of `B` give the `r` (with `|r| = 1` instead of `|x| = 1`), lifted to `x` by the
//! two back substitutions. Half the rows of the stacked system go into the QR, and the SVD is
//! `3K x K` instead of `3K x 3K`. The null space of `B` is that of `M` under the lift, so exact
//! (or rank-deficient) systems keep their solutions; with noise the constraint on `r` instead
//! of `x` moves the least-squares answer by a second-order amount.

use nalgebra::{SMatrix, SVector};

use super::svd::{Svd, svd_jacobi};
use crate::Result;
use crate::scalar::Real;

/// The blocks of a reduced system: `R₁₁`, `R₁₂`, `R₁₃` for the lift and the SVD of `B`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Reduced<T: Real, const C: usize, const K: usize> {
    /// `R₁₁`, upper triangular.
    pub r11: SMatrix<T, K, K>,
    r12: SMatrix<T, K, K>,
    r13: SMatrix<T, K, K>,
    /// The SVD of `B = [R₂₂; R₂₃; R₃₃]`; its right singular vectors are the candidate `r`.
    pub b: Svd<T, C, K>,
}

impl<T: Real, const C: usize, const K: usize> Reduced<T, C, K> {
    /// The reduction of the `C x C` factor `r` (`C = 3K`) of the stacked rows
    /// `[aᵢᵀ, uᵢ aᵢᵀ, vᵢ aᵢᵀ]`. Errors as [`svd_jacobi`].
    pub fn new(r: &SMatrix<T, C, C>) -> Result<Self> {
        const { assert!(C == 3 * K && K > 0, "Reduced: C must be 3K") };
        // Copied block by block (`copy_from`): nalgebra's `into_owned` of a view goes through
        // an iterator whose length check the optimiser keeps (a panic path).
        let block = |i: usize, j: usize| {
            let mut m = SMatrix::<T, K, K>::zeros();
            m.copy_from(&r.fixed_view::<K, K>(i, j));
            m
        };
        let mut b = SMatrix::<T, C, K>::zeros();
        b.fixed_view_mut::<K, K>(0, 0).copy_from(&block(K, K));
        b.fixed_view_mut::<K, K>(K, 0).copy_from(&block(K, 2 * K));
        b.fixed_view_mut::<K, K>(2 * K, 0)
            .copy_from(&block(2 * K, 2 * K));
        Ok(Self {
            r11: block(0, 0),
            r12: block(0, K),
            r13: block(0, 2 * K),
            b: svd_jacobi(&b)?,
        })
    }

    /// The right singular vector of `B` of the `k`-th smallest singular value (`k = 0`: the
    /// least-squares `r`).
    pub fn r(&self, k: usize) -> SVector<T, K> {
        super::elementary::column(&self.b.v, K.saturating_sub(1).saturating_sub(k))
    }

    /// `(p, q) = (R₁₁⁻¹ R₁₂ r, R₁₁⁻¹ R₁₃ r)`. A zero on `R₁₁`'s diagonal gives non-finite
    /// entries: callers test `R₁₁`'s conditioning first, or the finiteness of the result.
    pub fn lift(&self, r: &SVector<T, K>) -> (SVector<T, K>, SVector<T, K>) {
        (
            solve_upper(&self.r11, self.r12 * r),
            solve_upper(&self.r11, self.r13 * r),
        )
    }
}

/// `U⁻ᵀ b` for an upper triangular `U` by forward substitution on `Uᵀ` (`b` overwritten in
/// place). A zero on the diagonal gives non-finite entries.
pub(crate) fn solve_lower_transposed<T: Real, const K: usize>(
    u: &SMatrix<T, K, K>,
    mut b: SVector<T, K>,
) -> SVector<T, K> {
    for i in 0..K {
        let mut s = b.get(i).copied().unwrap_or(T::zero());
        for j in 0..i {
            if let (Some(uji), Some(bj)) = (u.get((j, i)), b.get(j)) {
                s -= *uji * *bj;
            }
        }
        if let (Some(bi), Some(uii)) = (b.get_mut(i), u.get((i, i))) {
            *bi = s / *uii;
        }
    }
    b
}

/// `U⁻¹ b` for an upper triangular `U` by back substitution (`b` overwritten in place). A zero
/// on the diagonal gives non-finite entries.
pub(crate) fn solve_upper<T: Real, const K: usize>(
    u: &SMatrix<T, K, K>,
    mut b: SVector<T, K>,
) -> SVector<T, K> {
    for i in (0..K).rev() {
        let mut s = b.get(i).copied().unwrap_or(T::zero());
        for j in (i + 1)..K {
            if let (Some(uij), Some(bj)) = (u.get((i, j)), b.get(j)) {
                s -= *uij * *bj;
            }
        }
        if let (Some(bi), Some(uii)) = (b.get_mut(i), u.get((i, i))) {
            *bi = s / *uii;
        }
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::StreamingQr;
    use crate::rng::Pcg32;

    #[test]
    fn back_substitution_inverts_the_triangle() {
        let mut g = Pcg32::new(3);
        let mut u =
            SMatrix::<f64, 4, 4>::from_fn(|i, j| if j >= i { g.uniform(-1.0, 1.0) } else { 0.0 });
        for i in 0..4 {
            u[(i, i)] += 2.0;
        }
        let x = SVector::<f64, 4>::from_fn(|_, _| g.uniform(-1.0, 1.0));
        assert!((solve_upper(&u, u * x) - x).amax() < 1e-14);
        // A zero pivot: non-finite, no panic.
        u[(3, 3)] = 0.0;
        assert!(!solve_upper(&u, u * x).iter().all(|v| v.is_finite()));
    }

    #[test]
    fn exact_pairs_give_the_null_vector() {
        // Rows [a, u a, v a] of a random exact system with K = 4: the reduced null vector,
        // lifted, solves every equation.
        let mut g = Pcg32::new(4);
        let truth = SVector::<f64, 12>::from_fn(|_, _| g.uniform(-1.0, 1.0));
        let (p, q, r) = (
            truth.fixed_rows::<4>(0).into_owned(),
            truth.fixed_rows::<4>(4).into_owned(),
            truth.fixed_rows::<4>(8).into_owned(),
        );
        let mut qr = StreamingQr::<f64, 12>::new();
        for _ in 0..10 {
            let a = SVector::<f64, 4>::from_fn(|_, _| g.uniform(-1.0, 1.0));
            // u and v such that a·p = u a·r and a·q = v a·r.
            let (u, v) = (a.dot(&p) / a.dot(&r), a.dot(&q) / a.dot(&r));
            let mut row = [0.0; 12];
            for k in 0..4 {
                row[k] = a[k];
                row[4 + k] = u * a[k];
                row[8 + k] = v * a[k];
            }
            qr.push_row(&row).unwrap();
        }
        let red = Reduced::<f64, 12, 4>::new(qr.r()).unwrap();
        let z = red.r(0);
        let (pp, qq) = red.lift(&z);
        let scale = z.dot(&r) / r.norm_squared();
        assert!((z - r * scale).amax() < 1e-12);
        assert!((pp - p * scale).amax() < 1e-12 && (qq - q * scale).amax() < 1e-12);
        assert!(red.b.singular_values[3] < 1e-12 && red.b.singular_values[2] > 1e-3);
    }
}
