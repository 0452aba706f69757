//! The normalised direct linear transform (Hartley & Zisserman, algorithm 4.2).

use nalgebra::{Matrix3, Point2};

use super::normalize::Normalization;
use super::{Homography, above};
use crate::linalg::{StreamingQr, svd_jacobi};
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Relative singular-value tolerance of the DLT's degeneracy tests: `√ε` (`3.5e-4` in `f32`,
/// `1.5e-8` in `f64`).
///
/// In normalised coordinates a well-posed problem has `σ₈/σ₁` and `σ₃(H_n)/σ₁(H_n)` of order
/// `0.01..1`, while exact degeneracies leave rounding noise of order `ε` there. `√ε` splits
/// the two on a log scale, so configurations that are degenerate to within `~√ε` of their
/// spread are reported as such instead of returning an `H` that is mostly noise.
pub fn rank_tolerance<T: Real>() -> T {
    T::EPSILON.sqrt()
}

/// The homography minimising the algebraic error `Σ |x'_i × H x_i|²` in Hartley-normalised
/// coordinates, from `N ≥ 4` correspondences `dst_i ~ H src_i`.
///
/// Each pair gives the two equations (`h` = rows of `H_n`, normalised `x = (x, y, 1)`,
/// `x' = (u, v, 1)`)
///
/// `[0ᵀ  -xᵀ  v xᵀ] h = 0`,  `[xᵀ  0ᵀ  -u xᵀ] h = 0`,
///
/// which are streamed into a 9-column [`StreamingQr`] (constant memory, no `AᵀA`); `h` is the
/// last right singular vector of `R`, and `H = T_dst⁻¹ H_n T_src`.
///
/// Errors: [`Error::LengthMismatch`], [`Error::TooFewPoints`] (`N < 4`), [`Error::NonFinite`],
/// [`Error::Degenerate`] when either point set is coincident, when the solution is not unique
/// (`σ₈ ≤ tol σ₁`: e.g. all source points collinear, or three of four collinear), or when
/// `H_n` is close to singular (`σ₃ ≤ tol σ₁`: e.g. all destination points collinear), with
/// `tol` = [`rank_tolerance`]; [`Error::NoConvergence`] if the SVD does not converge.
pub fn dlt<T: Real>(src: &[Point2<T>], dst: &[Point2<T>]) -> Result<Homography<T>> {
    if src.len() != dst.len() {
        return Err(Error::LengthMismatch);
    }
    solve(src.iter().zip(dst.iter()).map(|(s, d)| (*s, *d, T::one())))
}

/// [`dlt`] on the pairs with `mask[i] == true` only (e.g. RANSAC inliers), without copying.
/// Masked-out points are not inspected.
pub fn dlt_masked<T: Real>(
    src: &[Point2<T>],
    dst: &[Point2<T>],
    mask: &[bool],
) -> Result<Homography<T>> {
    if src.len() != dst.len() || src.len() != mask.len() {
        return Err(Error::LengthMismatch);
    }
    solve(
        src.iter()
            .zip(dst.iter())
            .zip(mask.iter())
            .filter(|(_, m)| **m)
            .map(|((s, d), _)| (*s, *d, T::one())),
    )
}

/// [`dlt`] with each pair's two equations multiplied by `weights[i] ≥ 0`, so its squared
/// algebraic residual counts `weights[i]²` times (iteratively reweighted least squares).
/// Pairs of weight 0 are ignored (and not inspected); the normalisations use the others,
/// unweighted.
///
/// Errors as [`dlt`], plus [`Error::NonFinite`] for a NaN/inf weight and
/// [`Error::InvalidParameter`] for a negative one.
pub fn dlt_weighted<T: Real>(
    src: &[Point2<T>],
    dst: &[Point2<T>],
    weights: &[T],
) -> Result<Homography<T>> {
    if src.len() != dst.len() || src.len() != weights.len() {
        return Err(Error::LengthMismatch);
    }
    check_finite(weights)?;
    if weights.iter().any(|w| *w < T::zero()) {
        return Err(Error::InvalidParameter("weights"));
    }
    solve(
        src.iter()
            .zip(dst.iter())
            .zip(weights.iter())
            .filter(|(_, w)| **w > T::zero())
            .map(|((s, d), w)| (*s, *d, *w)),
    )
}

/// The DLT over `(src, dst, weight)` triples with positive weights (walked three times).
fn solve<T, I>(pairs: I) -> Result<Homography<T>>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>, T)> + Clone,
{
    if pairs.clone().take(4).count() < 4 {
        return Err(Error::TooFewPoints);
    }
    let ns = Normalization::from_points_iter(pairs.clone().map(|(s, _, _)| s))?;
    let nd = Normalization::from_points_iter(pairs.clone().map(|(_, d, _)| d))?;

    let mut qr = StreamingQr::<T, 9>::new();
    let (z, o) = (T::zero(), T::one());
    for (s, d, w) in pairs {
        let x = ns.apply(&s);
        let u = nd.apply(&d);
        qr.push_row_weighted(&[z, z, z, -x.x, -x.y, -o, u.y * x.x, u.y * x.y, u.y], w)?;
        qr.push_row_weighted(&[x.x, x.y, o, z, z, z, -u.x * x.x, -u.x * x.y, -u.x], w)?;
    }
    let svd = qr.svd()?;
    let tol = rank_tolerance::<T>();
    let sv = svd.singular_values.as_slice();
    let (Some(&s1), Some(&s8)) = (sv.first(), sv.get(7)) else {
        return Err(Error::Degenerate);
    };
    if !above(s8, tol * s1) {
        return Err(Error::Degenerate);
    }
    let [h11, h12, h13, h21, h22, h23, h31, h32, h33]: [T; 9] = svd.null_vector().into();
    let hn = Matrix3::new(h11, h12, h13, h21, h22, h23, h31, h32, h33);
    let shn = svd_jacobi(&hn)?;
    let shn = shn.singular_values;
    if !above(shn.z, tol * shn.x) {
        return Err(Error::Degenerate);
    }
    Homography::from_matrix(&(nd.inverse_matrix() * hn * ns.matrix()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn truth() -> Matrix3<f64> {
        Matrix3::new(0.9, -0.12, 35.0, 0.08, 1.05, -20.0, 1.5e-4, -2e-4, 1.0)
    }

    fn points<const N: usize>(g: &mut Pcg32) -> [Point2<f64>; N] {
        core::array::from_fn(|_| Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)))
    }

    fn map<const N: usize>(h: &Matrix3<f64>, p: &[Point2<f64>; N]) -> [Point2<f64>; N] {
        p.map(|p| Point2::from_homogeneous(h * p.to_homogeneous()).unwrap())
    }

    fn rel(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
        (a / a.m33 - b / b.m33).amax() / (b / b.m33).amax()
    }

    #[test]
    fn recovers_exact_homographies() {
        let mut g = Pcg32::new(21);
        let src = points::<30>(&mut g);
        let dst = map(&truth(), &src);
        let h = dlt(&src, &dst).unwrap();
        assert!(rel(h.matrix(), &truth()) < 1e-12);
        // Four points are enough, and agree with the exact solver.
        let s4 = [src[0], src[1], src[2], src[3]];
        let d4 = [dst[0], dst[1], dst[2], dst[3]];
        let h4 = dlt(&s4, &d4).unwrap();
        assert!(rel(h4.matrix(), &truth()) < 1e-11);
        let e4 = Homography::from_four_points(&s4, &d4).unwrap();
        assert!(rel(e4.matrix(), &truth()) < 1e-11);
    }

    #[test]
    fn masked_and_weighted_variants() {
        let mut g = Pcg32::new(22);
        let src = points::<20>(&mut g);
        let mut dst = map(&truth(), &src);
        // Corrupt every third point and mask it out (or give it weight 0).
        let mut mask = [true; 20];
        let mut w = [1.0; 20];
        for i in (0..20).step_by(3) {
            dst[i].x += 50.0;
            dst[i].y = f64::NAN; // masked-out points are not even read
            mask[i] = false;
            w[i] = 0.0;
        }
        let hm = dlt_masked(&src, &dst, &mask).unwrap();
        assert!(rel(hm.matrix(), &truth()) < 1e-12);
        let hw = dlt_weighted(&src, &dst, &w).unwrap();
        assert!(rel(hw.matrix(), &truth()) < 1e-12);
        assert_eq!(dlt(&src, &dst), Err(Error::NonFinite));
        w[1] = -1.0;
        assert_eq!(
            dlt_weighted(&src, &dst, &w),
            Err(Error::InvalidParameter("weights"))
        );
        w[1] = f64::NAN;
        assert_eq!(dlt_weighted(&src, &dst, &w), Err(Error::NonFinite));
        assert_eq!(
            dlt_masked(&src, &dst, &mask[..3]),
            Err(Error::LengthMismatch)
        );
        let few = [
            true, true, true, false, false, false, false, false, false, false,
        ];
        assert_eq!(
            dlt_masked(&src[..10], &dst[..10], &few),
            Err(Error::TooFewPoints)
        );
    }

    #[test]
    fn degenerate_configurations() {
        let line: [Point2<f64>; 8] = core::array::from_fn(|i| {
            let t = i as f64;
            Point2::new(10.0 + 3.0 * t, 20.0 - 2.0 * t)
        });
        let mut g = Pcg32::new(23);
        let spread = points::<8>(&mut g);
        assert_eq!(dlt(&line, &spread), Err(Error::Degenerate));
        assert_eq!(dlt(&spread, &line), Err(Error::Degenerate));
        let line32 = line.map(|p| p.cast::<f32>());
        let spread32 = spread.map(|p| p.cast::<f32>());
        assert_eq!(dlt(&line32, &spread32), Err(Error::Degenerate));
        assert_eq!(dlt(&spread32, &line32), Err(Error::Degenerate));
        // Three of four collinear.
        let s4 = [line[0], line[3], line[7], spread[0]];
        let d4 = map(&truth(), &s4);
        assert_eq!(dlt(&s4, &d4), Err(Error::Degenerate));
        // Coincident.
        let same = [Point2::new(4.0, 4.0); 6];
        assert_eq!(dlt(&same, &spread[..6]), Err(Error::Degenerate));
        assert_eq!(dlt(&spread[..3], &spread[..3]), Err(Error::TooFewPoints));
        assert_eq!(dlt(&spread[..5], &spread[..4]), Err(Error::LengthMismatch));
    }
}
