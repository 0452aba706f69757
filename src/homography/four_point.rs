//! The exact homography of four correspondences, and the checks of a minimal sample.

use nalgebra::{Matrix3, Point2, Vector3};

use super::normalize::Normalization;
use super::{Homography, above, adjugate};
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Collinearity tolerance of [`check_sample`], dimensionless.
///
/// Three points `a, b, c` count as collinear when
///
/// `|(b - a) × (c - a)| ≤ tol (|b - a|² + |c - b|² + |a - c|²)`.
///
/// The left side is twice the triangle's area, the right side its squared size, so the test
/// is invariant to translation, rotation and scale. For a flat triangle of base `L` and height
/// `h` the ratio is about `h / 1.5 L` (equilateral: `1/(2√3) ≈ 0.29`), so `1e-4` rejects
/// triangles flatter than `h ≈ 1.5e-4 L` (0.015 px over 100 px). Such samples determine `H`
/// only to a relative accuracy of `ε / ratio`; anything above, noise permitting, is solved.
pub const COLLINEARITY_TOL: f64 = 1e-4;

/// The four triplets of a 4-point sample, with the point left out last.
const TRIPLETS: [(usize, usize, usize); 4] = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)];

/// `2 × signed area / squared size` of a triangle (see [`COLLINEARITY_TOL`]); `0` when the
/// three points coincide.
fn triangle_ratio<T: Real>(a: &Point2<T>, b: &Point2<T>, c: &Point2<T>) -> T {
    let (ab, ac, bc) = (b - a, c - a, c - b);
    let cross = ab.x * ac.y - ab.y * ac.x;
    let size = ab.norm_squared() + ac.norm_squared() + bc.norm_squared();
    if size > T::zero() {
        cross / size
    } else {
        T::zero()
    }
}

/// Signed area ratios of the four triplets; [`Error::Degenerate`] if any is collinear.
fn triplet_ratios<T: Real>(p: &[Point2<T>; 4]) -> Result<[T; 4]> {
    let tol = T::lit(COLLINEARITY_TOL);
    let mut out = [T::zero(); 4];
    for (o, &(i, j, k)) in out.iter_mut().zip(TRIPLETS.iter()) {
        let (Some(a), Some(b), Some(c)) = (p.get(i), p.get(j), p.get(k)) else {
            return Err(Error::Degenerate);
        };
        let r = triangle_ratio(a, b, c);
        if !above(r.abs(), tol) {
            return Err(Error::Degenerate);
        }
        *o = r;
    }
    Ok(out)
}

/// Checks that a 4-point sample determines a homography that does not fold the plane.
///
/// - finite coordinates, else [`Error::NonFinite`];
/// - no three points collinear (nor coincident) in either image, by the scale-invariant test of
///   [`COLLINEARITY_TOL`], else [`Error::Degenerate`];
/// - consistent orientation, else [`Error::Degenerate`]: for every triplet `(i, j, k)`,
///   `det[x'_i x'_j x'_k] = det H det[x_i x_j x_k] / (w_i w_j w_k)` with `w_i` the third
///   coordinate of `H x_i`. The sign ratio of the dst and src triangle areas is therefore the
///   same for all four triplets iff all `w_i` share a sign, i.e. no sample point is mapped
///   across the line `H` sends to infinity. A sample that fails is a folded (self-intersecting)
///   quadrilateral and cannot come from a plane seen by a camera. Mirror maps (`det H < 0`)
///   pass: all four ratios are then negative. (OpenCV's `checkSubset` in RANSAC does a similar
///   test; this one is written from the relation above.)
pub fn check_sample<T: Real>(src: &[Point2<T>; 4], dst: &[Point2<T>; 4]) -> Result<()> {
    for p in src.iter().chain(dst.iter()) {
        check_finite(&[p.x, p.y])?;
    }
    let rs = triplet_ratios(src)?;
    let rd = triplet_ratios(dst)?;
    let positive = rs
        .iter()
        .zip(rd.iter())
        .filter(|(s, d)| (**s > T::zero()) == (**d > T::zero()))
        .count();
    if positive == 0 || positive == 4 {
        Ok(())
    } else {
        Err(Error::Degenerate)
    }
}

/// `B = [p₁ p₂ p₃] diag(λ)`, `λ = adj[p₁ p₂ p₃] p₄`: the map (up to scale) sending the
/// canonical basis `e₁, e₂, e₃` to `p₁, p₂, p₃` and `(1, 1, 1)` to `p₄`.
fn basis<T: Real>(p: &[Point2<T>; 4]) -> Matrix3<T> {
    let [a, b, c, d] = p;
    let o = T::one();
    let m = Matrix3::from_columns(&[
        Vector3::new(a.x, a.y, o),
        Vector3::new(b.x, b.y, o),
        Vector3::new(c.x, c.y, o),
    ]);
    let lambda = adjugate(&m) * Vector3::new(d.x, d.y, o);
    m * Matrix3::from_diagonal(&lambda)
}

impl<T: Real> Homography<T> {
    /// The exact homography with `dst_i ~ H src_i` for a 4-point sample.
    ///
    /// The sample is first validated by [`check_sample`] (collinear triplets and folds give
    /// [`Error::Degenerate`], NaN/inf [`Error::NonFinite`]). Each set is Hartley-normalised,
    /// then `H_n = B_dst adj(B_src)` with the basis matrices `B = [p₁ p₂ p₃] diag(λ)`,
    /// `λ = adj[p₁ p₂ p₃] p₄`, which send the canonical frame `e₁, e₂, e₃, (1, 1, 1)` to the
    /// four points: no iteration and no division until the final `h33` normalisation, ~200
    /// flops. Finally `H = T_dst⁻¹ H_n T_src`.
    #[doc(alias = "getPerspectiveTransform")]
    pub fn from_four_points(src: &[Point2<T>; 4], dst: &[Point2<T>; 4]) -> Result<Self> {
        check_sample(src, dst)?;
        let ns = Normalization::from_points(src)?;
        let nd = Normalization::from_points(dst)?;
        let bs = basis(&src.map(|p| ns.apply(&p)));
        let bd = basis(&dst.map(|p| nd.apply(&p)));
        let hn = bd * adjugate(&bs);
        Self::from_matrix(&(nd.inverse_matrix() * hn * ns.matrix()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> [Point2<f64>; 4] {
        [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(1.0, 1.0),
            Point2::new(0.0, 1.0),
        ]
    }

    #[test]
    fn maps_the_sample_exactly() {
        let src = [
            Point2::new(12.0, 30.0),
            Point2::new(610.0, 25.0),
            Point2::new(630.0, 470.0),
            Point2::new(5.0, 460.0),
        ];
        let dst = [
            Point2::new(100.0, 80.0),
            Point2::new(520.0, 120.0),
            Point2::new(560.0, 400.0),
            Point2::new(60.0, 430.0),
        ];
        let h = Homography::from_four_points(&src, &dst).unwrap();
        for (s, d) in src.iter().zip(dst.iter()) {
            assert!((h.transfer(s).unwrap() - d).amax() < 1e-9);
        }
        let h32 =
            Homography::from_four_points(&src.map(|p| p.cast::<f32>()), &dst.map(|p| p.cast()))
                .unwrap();
        for (s, d) in src.iter().zip(dst.iter()) {
            let e = (h32.transfer(&s.cast()).unwrap().cast::<f64>() - d).amax();
            assert!(e < 2e-3, "{e}");
        }
    }

    #[test]
    fn mirror_is_allowed_fold_is_not() {
        let src = square();
        let mirror = src.map(|p| Point2::new(-p.x, p.y));
        let h = Homography::from_four_points(&src, &mirror).unwrap();
        assert!(h.matrix().determinant() < 0.0);
        // Swapping two corners makes a bow-tie: the quadrilateral is folded.
        let mut bow = src;
        bow.swap(2, 3);
        assert_eq!(
            Homography::from_four_points(&src, &bow),
            Err(Error::Degenerate)
        );
        // One point across the vanishing line: the dst quad is not convex-consistent.
        let dst = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(0.2, 0.3),
            Point2::new(0.0, 1.0),
        ];
        assert_eq!(
            Homography::from_four_points(&src, &dst),
            Err(Error::Degenerate)
        );
    }

    #[test]
    fn collinear_and_coincident_samples() {
        let src = square();
        let mut dst = square();
        dst[2] = Point2::new(2.0, 0.0); // 0, 1, 2 collinear
        assert_eq!(check_sample(&src, &dst), Err(Error::Degenerate));
        assert_eq!(check_sample(&dst, &src), Err(Error::Degenerate));
        // Nearly collinear: height 1e-5 over a base of 2 (ratio ~3e-6).
        dst[2] = Point2::new(2.0, 1e-5);
        assert_eq!(check_sample(&src, &dst), Err(Error::Degenerate));
        // Coincident points.
        let mut dup = square();
        dup[3] = dup[0];
        assert_eq!(check_sample(&src, &dup), Err(Error::Degenerate));
        let all = [Point2::new(5.0, 5.0); 4];
        assert_eq!(check_sample(&all, &src), Err(Error::Degenerate));
        // Scale invariance: a tiny, well-shaped sample is fine.
        let small = square().map(|p| Point2::new(1e-6 * p.x + 3.0, 1e-6 * p.y - 2.0));
        assert!(Homography::from_four_points(&small, &src).is_ok());
        let mut nan = square();
        nan[1].y = f64::NAN;
        assert_eq!(check_sample(&src, &nan), Err(Error::NonFinite));
        assert_eq!(
            Homography::from_four_points(&nan, &src),
            Err(Error::NonFinite)
        );
    }
}
