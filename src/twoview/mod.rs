//! Two-view geometry: epipolar matrices, relative pose and triangulation.
//!
//! Two images of the same rigid scene are related by the epipolar constraint
//!
//! `x₂ᵀ F x₁ = 0` (pixels),  `x̂₂ᵀ E x̂₁ = 0` (normalised, `x̂ = K⁻¹ x`),  `E = K₂ᵀ F K₁ = [t]ₓ R`,
//!
//! where `X₂ = R X₁ + t` maps view-1 camera coordinates to view-2 ones (a [`RelativePose`]).
//!
//! - [`Fundamental`]: a validated rank-2 `F` with epipolar lines, epipoles and the Sampson
//!   error; [`eight_point`] (normalised, rank 2 enforced), [`seven_point`] (up to three
//!   solutions), [`find_fundamental`] (RANSAC) and [`refine_fundamental`] (LM on the Sampson
//!   error);
//! - [`Essential`]: `E` on the essential manifold (singular values `(1, 1, 0)`), from `F` and
//!   the intrinsics or from a pose; [`five_point()`] (Nistér), [`find_essential`] (RANSAC) and
//!   [`refine_essential`];
//! - [`Essential::decompose`] and [`recover_pose`]: the four `(R, t)` candidates and the
//!   cheirality test that picks one, with its number of supporting points;
//! - [`triangulate_dlt`], [`triangulate_midpoint`], [`triangulate_optimal`] (Lindstrom's
//!   two-iteration optimal correction) with depths and reprojection errors.
//!
//! Lens distortion is not modelled here: pass undistorted pixels
//! ([`crate::camera::Camera::undistort_pixel`]) or normalised coordinates.
//!
//! Relative pose from two synthetic views with outliers, [`find_essential`] then
//! [`recover_pose`]:
//!
//! ```
//! use camgeom::camera::Intrinsics;
//! use camgeom::nalgebra::{Point2, Point3, Vector2, Vector3};
//! use camgeom::ransac::RansacParams;
//! use camgeom::twoview::{RelativePose, find_essential, recover_pose};
//!
//! let k = Intrinsics::new(500.0f64, 500.0, 320.0, 240.0)?;
//! let (rvec, t) = (Vector3::new(0.05, -0.2, 0.03), Vector3::new(-1.0, 0.1, 0.05));
//! let truth = RelativePose::from_rodrigues(rvec, t)?;
//! // 40 scene points 4 to 6.5 units in front of view 1, imaged in both views.
//! let scene: [Point3<f64>; 40] = core::array::from_fn(|i| {
//!     let f = |m: usize, n: usize| ((i * m) % n) as f64 / n as f64 - 0.5;
//!     Point3::new(3.0 * f(37, 11), 2.0 * f(53, 7), 5.0 + 2.5 * f(29, 13))
//! });
//! let pixel = |p: Point3<f64>| k.normalized_to_pixel(&Point2::new(p.x / p.z, p.y / p.z));
//! let x1 = scene.map(pixel);
//! let mut x2 = scene.map(|p| pixel(truth.apply(&p)));
//! for q in x2.iter_mut().step_by(5) {
//!     *q += Vector2::new(25.0, -18.0); // every fifth match is wrong
//! }
//! let mut inliers = [false; 40];
//! let (e, _) = find_essential(&k, &k, &x1, &x2, &RansacParams::default(), &mut inliers)?;
//! assert!(inliers.iter().enumerate().all(|(i, &ok)| ok == (i % 5 != 0)));
//! let r = recover_pose(&e, &k, &k, &x1, &x2, 50.0, &mut inliers)?;
//! assert_eq!(r.supporting, 32);
//! // The rotation, and the direction of the translation (its length is not observable).
//! assert!((r.pose.rotation_vector() - truth.rotation_vector()).norm() < 1e-6);
//! assert!((r.pose.translation() - truth.translation().normalize()).norm() < 1e-6);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod decompose;
mod essential;
mod five_point;
mod fundamental;
mod poly;
mod refine;
mod triangulate;

pub use decompose::{RecoveredPose, recover_pose};
pub use essential::{EssentialEstimator, EssentialModel, find_essential};
pub use five_point::{MAX_FIVE_POINT_SOLUTIONS, five_point};
pub use fundamental::{
    FundamentalEstimator, MAX_SEVEN_POINT_SOLUTIONS, eight_point, eight_point_masked,
    find_fundamental, seven_point,
};
pub(crate) use refine::tangent_basis;
pub use refine::{EpipolarRefinement, refine_essential, refine_fundamental};
pub use triangulate::{
    Triangulated, correct_matches, triangulate_dlt, triangulate_midpoint, triangulate_optimal,
};

use nalgebra::{Matrix3, Point2, Rotation3, Vector3};

use crate::camera::Intrinsics;
use crate::homogeneous::{Line2h, Point2h};
use crate::linalg::{Svd, svd_jacobi};
use crate::scalar::{Real, above, check_finite};
use crate::transform::Transform;
use crate::{Error, Result};

crate::frame!(
    /// The camera frame of the first view of a pair (the reference of a [`RelativePose`]).
    View1
);
crate::frame!(
    /// The camera frame of the second view of a pair.
    View2
);

/// The pose of view 2 relative to view 1: `X₂ = R X₁ + t` for camera-frame coordinates.
pub type RelativePose<T = f32> = Transform<View1, View2, T>;

/// `[u₁ u₂ u₁ × u₂]`: the rotation completing the first two columns of an SVD factor (the
/// Jacobi SVD leaves the `U` column of an exactly zero singular value at zero).
pub(crate) fn complete_rotation<T: Real>(u: &Matrix3<T>) -> Matrix3<T> {
    let (a, b) = (u.column(0).into_owned(), u.column(1).into_owned());
    Matrix3::from_columns(&[a, b, a.cross(&b)])
}

/// `(x, y, 1)`.
pub(crate) fn lift<T: Real>(p: &Point2<T>) -> Vector3<T> {
    Vector3::new(p.x, p.y, T::one())
}

/// Whether pairs `x₁ ↔ x₂` meet the oriented epipolar constraint of `M` (Chum, Werner & Matas,
/// "Epipolar geometry estimation via RANSAC benefits from the oriented epipolar constraint",
/// ICPR 2004): with `e₂` spanning the left null space of `M` (`Mᵀ e₂ = 0`, the epipole in
/// image 2), the signs of `sᵢ = (e₂ × x₂ᵢ) · (M x₁ᵢ)` all agree.
///
/// Why: for `M = E = [t]ₓ R` and a scene point at depths `λ₁`, `λ₂` (`λ₂ x₂ = λ₁ R x₁ + t`),
/// `λ₂ (t × x₂) = λ₁ t × R x₁ = λ₁ E x₁`, so `(t × x₂) · (E x₁) = (λ₁/λ₂) |E x₁|²`: one sign
/// for every point in front of both cameras (and for every point behind both), whatever the
/// sign of `M` and of `e₂`. A model whose own minimal sample splits the signs puts some of
/// those points in front of one camera and behind the other, so it is not the true geometry of
/// an all-inlier sample and RANSAC need not score it. The same holds for `F` in pixels. A
/// pair with `sᵢ = 0` (at an epipole) votes neither way. `e₂` is the largest of the three
/// cross products of `M`'s columns (the columns are all orthogonal to `e₂`, so each product is
/// parallel to it for a rank-2 `M`); a rank-1 or zero `M` passes (nothing to test).
pub(crate) fn oriented_consistent<T: Real>(
    m: &Matrix3<T>,
    x1: &[Point2<T>],
    x2: &[Point2<T>],
) -> bool {
    let [c0, c1, c2] = <[[T; 3]; 3]>::from(*m).map(Vector3::from);
    let e2 = [c1.cross(&c2), c2.cross(&c0)]
        .into_iter()
        .fold(c0.cross(&c1), |best, c| {
            if c.norm_squared() > best.norm_squared() {
                c
            } else {
                best
            }
        });
    let (mut positive, mut negative) = (false, false);
    for (a, b) in x1.iter().zip(x2) {
        let s = e2.cross(&lift(b)).dot(&(m * lift(a)));
        positive |= s > T::zero();
        negative |= s < T::zero();
    }
    !(positive && negative)
}

/// The squared Sampson distance of a pair under a bilinear constraint `x₂ᵀ M x₁ = 0`:
///
/// `d² = (x₂ᵀ M x₁)² / ((M x₁)₁² + (M x₁)₂² + (Mᵀ x₂)₁² + (Mᵀ x₂)₂²)`,
///
/// the first-order approximation of `min |x̂₁ - x₁|² + |x̂₂ - x₂|²` over pairs that satisfy the
/// constraint (in the units of the points). `None` when the gradient vanishes (a point at an
/// epipole) or the result is not finite.
#[doc(alias = "sampsonDistance")]
pub fn sampson_distance_sq<T: Real>(m: &Matrix3<T>, x1: &Point2<T>, x2: &Point2<T>) -> Option<T> {
    // `l₂ = M x₁`, the first two entries of `l₁ = Mᵀ x₂` and `e = x₂ · l₂`, written out with
    // the sums in the order of nalgebra's products (column by column, then the dot product
    // left to right) and the exact `· 1` of the homogeneous coordinates left out: the same
    // value to the bit, without the transpose, the unused `l₁.z` and the nine temporaries.
    // This runs once per point and model in RANSAC scoring.
    let [[m00, m10, m20], [m01, m11, m21], [m02, m12, m22]]: [[T; 3]; 3] = (*m).into();
    let (u, v) = (x1.x, x1.y);
    let (p, q) = (x2.x, x2.y);
    let l2 = [
        m00 * u + m01 * v + m02,
        m10 * u + m11 * v + m12,
        m20 * u + m21 * v + m22,
    ];
    let l1 = [m00 * p + m10 * q + m20, m01 * p + m11 * q + m21];
    let [l20, l21, l22] = l2;
    let [l10, l11] = l1;
    let e = p * l20 + q * l21 + l22;
    let g = l20 * l20 + l21 * l21 + l10 * l10 + l11 * l11;
    if !above(g, T::zero()) {
        return None;
    }
    let d = e * e / g;
    d.finite().then_some(d)
}

/// The SVD of a 3x3 matrix of rank at least 2, with its two largest singular values `σ₁ ≥ σ₂`:
/// what projecting onto the fundamental or the essential matrices starts from. Errors:
/// [`Error::NonFinite`]; [`Error::Degenerate`] when `σ₂ ≤ √ε σ₁` (rank below 2).
fn rank_two_svd<T: Real>(m: &Matrix3<T>) -> Result<(Svd<T, 3, 3>, [T; 2])> {
    check_finite(m.as_slice())?;
    let svd = svd_jacobi(m)?;
    let [s1, s2, _]: [T; 3] = svd.singular_values.into();
    if !above(s2, T::EPSILON.sqrt() * s1) {
        return Err(Error::Degenerate);
    }
    Ok((svd, [s1, s2]))
}

/// A fundamental matrix: `x₂ᵀ F x₁ = 0` for every pair of pixels `x₁ ↔ x₂` imaging the same
/// scene point, rank 2, stored with unit Frobenius norm (`F` is defined up to scale).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fundamental<T: Real = f32> {
    f: Matrix3<T>,
}

impl<T: Real> Fundamental<T> {
    /// The closest rank-2 matrix to `m` (Frobenius), `U diag(σ₁, σ₂, 0) Vᵀ`, scaled to unit
    /// norm.
    ///
    /// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when `m` has rank below 2
    /// (`σ₂ ≤ √ε σ₁`, e.g. zero).
    ///
    /// Project well-scaled matrices (normalised coordinates): a pixel `F` has `σ₂/σ₁` of
    /// about `1/f²`, below `√ε` in `f32`, and is rejected there.
    pub fn from_matrix(m: &Matrix3<T>) -> Result<Self> {
        let (svd, [s1, s2]) = rank_two_svd(m)?;
        let d = Matrix3::from_diagonal(&Vector3::new(s1, s2, T::zero()));
        Self::from_rank2(&(svd.u * d * svd.v.transpose()))
    }

    /// A matrix already of rank 2 (to rounding), scaled to unit norm.
    pub(crate) fn from_rank2(m: &Matrix3<T>) -> Result<Self> {
        let n = m.norm();
        if !above(n, T::zero()) || !n.finite() {
            return Err(Error::Degenerate);
        }
        let f = m / n;
        check_finite(f.as_slice())?;
        Ok(Self { f })
    }

    /// `F`, unit Frobenius norm.
    pub fn matrix(&self) -> &Matrix3<T> {
        &self.f
    }

    /// The algebraic residual `x₂ᵀ F x₁` (0 for a perfect match; OpenCV's acceptance check).
    pub fn residual(&self, x1: &Point2<T>, x2: &Point2<T>) -> T {
        lift(x2).dot(&(self.f * lift(x1)))
    }

    /// The squared Sampson distance of a pair in pixels² ([`sampson_distance_sq`]).
    pub fn sampson_sq(&self, x1: &Point2<T>, x2: &Point2<T>) -> Option<T> {
        sampson_distance_sq(&self.f, x1, x2)
    }

    /// The epipolar line of `x₁` in image 2, `l₂ = F x₁` (every match of `x₁` lies on it).
    ///
    /// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when `x₁` is the epipole.
    #[doc(alias = "computeCorrespondEpilines")]
    pub fn line_in_second(&self, x1: &Point2<T>) -> Result<Line2h<T>> {
        check_finite(&[x1.x, x1.y])?;
        Line2h::from_vector(self.f * lift(x1))
    }

    /// The epipolar line of `x₂` in image 1, `l₁ = Fᵀ x₂`. Errors as [`Self::line_in_second`].
    #[doc(alias = "computeCorrespondEpilines")]
    pub fn line_in_first(&self, x2: &Point2<T>) -> Result<Line2h<T>> {
        check_finite(&[x2.x, x2.y])?;
        Line2h::from_vector(self.f.transpose() * lift(x2))
    }

    /// The epipoles `(e₁, e₂)`: `F e₁ = 0` (the image of camera 2's centre in image 1) and
    /// `Fᵀ e₂ = 0`; ideal points when the baseline is parallel to an image plane.
    pub fn epipoles(&self) -> Result<(Point2h<T>, Point2h<T>)> {
        let svd = svd_jacobi(&self.f)?;
        let ft = svd_jacobi(&self.f.transpose())?;
        Ok((
            Point2h::from_vector(svd.null_vector())?,
            Point2h::from_vector(ft.null_vector())?,
        ))
    }
}

/// An essential matrix `E = [t]ₓ R`: `x̂₂ᵀ E x̂₁ = 0` for normalised coordinates, stored on the
/// essential manifold with singular values `(1, 1, 0)` (so `|E|_F = √2`, `|t| = 1`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Essential<T: Real = f32> {
    e: Matrix3<T>,
}

impl<T: Real> Essential<T> {
    /// The projection of `m` onto the essential manifold, `U diag(1, 1, 0) Vᵀ` for
    /// `m = U Σ Vᵀ` (the closest essential matrix to `m / ((σ₁ + σ₂)/2)` in Frobenius norm).
    ///
    /// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when `σ₂ ≤ √ε σ₁` (rank below 2).
    pub fn from_matrix(m: &Matrix3<T>) -> Result<Self> {
        let (svd, _) = rank_two_svd(m)?;
        let d = Matrix3::from_diagonal(&Vector3::new(T::one(), T::one(), T::zero()));
        Ok(Self {
            e: svd.u * d * svd.v.transpose(),
        })
    }

    /// `E = K₂ᵀ F K₁`, projected onto the manifold. Errors as [`Self::from_matrix`].
    pub fn from_fundamental(
        f: &Fundamental<T>,
        k1: &Intrinsics<T>,
        k2: &Intrinsics<T>,
    ) -> Result<Self> {
        Self::from_matrix(&(k2.matrix().transpose() * f.matrix() * k1.matrix()))
    }

    /// `E = [t/|t|]ₓ R` of a relative pose. Errors: [`Error::Degenerate`] for `t = 0` (pure
    /// rotation has no epipolar geometry).
    pub fn from_pose(pose: &RelativePose<T>) -> Result<Self> {
        let t = pose.translation();
        let n = t.norm();
        if !above(n, T::zero()) {
            return Err(Error::Degenerate);
        }
        Ok(Self {
            e: (t / n).cross_matrix() * pose.rotation().matrix(),
        })
    }

    /// `E`.
    pub fn matrix(&self) -> &Matrix3<T> {
        &self.e
    }

    /// `F = K₂⁻ᵀ E K₁⁻¹`.
    pub fn to_fundamental(&self, k1: &Intrinsics<T>, k2: &Intrinsics<T>) -> Result<Fundamental<T>> {
        Fundamental::from_rank2(&(k2.inverse_matrix().transpose() * self.e * k1.inverse_matrix()))
    }

    /// The algebraic residual `x̂₂ᵀ E x̂₁` of normalised coordinates.
    pub fn residual(&self, x1: &Point2<T>, x2: &Point2<T>) -> T {
        lift(x2).dot(&(self.e * lift(x1)))
    }

    /// The four relative poses with this `E` (Hartley & Zisserman, result 9.19):
    ///
    /// `E = U diag(1, 1, 0) Vᵀ` with `det U = det V = +1` (`u₃ = u₁ × u₂`),
    /// `W = [0 -1 0; 1 0 0; 0 0 1]`,
    /// `R ∈ {U W Vᵀ, U Wᵀ Vᵀ}`, `t = ±u₃` (unit): in the order `(R₁, t)`, `(R₁, -t)`,
    /// `(R₂, t)`, `(R₂, -t)`. Only one puts the scene in front of both cameras
    /// ([`recover_pose`]).
    #[doc(alias = "decomposeEssentialMat")]
    pub fn decompose(&self) -> Result<[RelativePose<T>; 4]> {
        let svd = svd_jacobi(&self.e)?;
        let u = complete_rotation(&svd.u);
        let mut v = svd.v;
        if v.determinant() < T::zero() {
            v.column_mut(2).neg_mut();
        }
        let (z, o) = (T::zero(), T::one());
        let w = Matrix3::new(z, -o, z, o, z, z, z, z, o);
        let r1 = Rotation3::from_matrix_unchecked(u * w * v.transpose());
        let r2 = Rotation3::from_matrix_unchecked(u * w.transpose() * v.transpose());
        let t: Vector3<T> = u.column(2).into_owned();
        Ok([
            Transform::new(r1, t)?,
            Transform::new(r1, -t)?,
            Transform::new(r2, t)?,
            Transform::new(r2, -t)?,
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> RelativePose<f64> {
        Transform::from_rodrigues(Vector3::new(0.1, -0.2, 0.05), Vector3::new(-1.0, 0.1, 0.2))
            .unwrap()
    }

    #[test]
    fn sampson_is_the_matrix_form_to_the_bit() {
        // The written-out Sampson distance against the nalgebra expression it replaced, on
        // random matrices and points in both precisions: equal, not close.
        fn reference<T: Real>(m: &Matrix3<T>, x1: &Point2<T>, x2: &Point2<T>) -> Option<T> {
            let (a, b) = (lift(x1), lift(x2));
            let l2 = m * a;
            let l1 = m.transpose() * b;
            let e = b.dot(&l2);
            let g = l2.x * l2.x + l2.y * l2.y + l1.x * l1.x + l1.y * l1.y;
            if !above(g, T::zero()) {
                return None;
            }
            let d = e * e / g;
            d.finite().then_some(d)
        }
        let mut g = crate::rng::Pcg32::new(3);
        for _ in 0..2000 {
            let m = Matrix3::<f64>::from_fn(|_, _| g.uniform(-1.0, 1.0));
            let x1 = Point2::new(g.uniform(-500.0, 500.0), g.uniform(-500.0, 500.0));
            let x2 = Point2::new(g.uniform(-500.0, 500.0), g.uniform(-500.0, 500.0));
            assert_eq!(sampson_distance_sq(&m, &x1, &x2), reference(&m, &x1, &x2));
            let (m, x1, x2) = (m.cast::<f32>(), x1.cast::<f32>(), x2.cast::<f32>());
            assert_eq!(sampson_distance_sq(&m, &x1, &x2), reference(&m, &x1, &x2));
        }
    }

    #[test]
    fn oriented_constraint_follows_the_depth_signs() {
        use std::vec::Vec;
        // Random scene points sorted by the signs of their depths in the two cameras: five in
        // front of both (or behind both) pass under E, -E and F in pixels; four in front and
        // one in front of camera 1 only fail. Points within 0.05 of a zero depth are skipped
        // (their sign is then a matter of rounding, not of the test).
        let truth = pose();
        let e = Essential::from_pose(&truth).unwrap();
        let k = Intrinsics::new(500.0, 510.0, 320.0, 240.0).unwrap();
        let f = e.to_fundamental(&k, &k).unwrap();
        let mut g = crate::rng::Pcg32::new(11);
        let (mut front, mut behind, mut split) = (Vec::new(), Vec::new(), Vec::new());
        while front.len() < 40 || behind.len() < 40 || split.len() < 40 {
            let p = nalgebra::Point3::new(
                g.uniform(-4.0, 4.0),
                g.uniform(-4.0, 4.0),
                g.uniform(-3.0, 3.0),
            );
            let q = truth.apply(&p);
            if p.z.abs() < 0.05 || q.z.abs() < 0.05 {
                continue;
            }
            let pair = (
                Point2::new(p.x / p.z, p.y / p.z),
                Point2::new(q.x / q.z, q.y / q.z),
            );
            match (p.z > 0.0, q.z > 0.0) {
                (true, true) => front.push(pair),
                (false, false) => behind.push(pair),
                (true, false) => split.push(pair),
                _ => {}
            }
        }
        let check = |pairs: &[(Point2<f64>, Point2<f64>)]| {
            let (a, b): (Vec<_>, Vec<_>) = pairs.iter().copied().unzip();
            let (pa, pb): (Vec<_>, Vec<_>) = pairs
                .iter()
                .map(|(a, b)| (k.normalized_to_pixel(a), k.normalized_to_pixel(b)))
                .unzip();
            let under_e = oriented_consistent(e.matrix(), &a, &b);
            assert_eq!(under_e, oriented_consistent(&-e.matrix(), &a, &b));
            assert_eq!(under_e, oriented_consistent(f.matrix(), &pa, &pb));
            under_e
        };
        for i in 0..8 {
            let five = |set: &[(Point2<f64>, Point2<f64>)]| set[5 * i..5 * i + 5].to_vec();
            assert!(check(&five(&front)));
            assert!(check(&five(&behind)));
            let mut mixed = five(&front);
            mixed[i % 5] = split[i];
            assert!(!check(&mixed));
        }
    }

    #[test]
    fn essential_from_pose_and_back() {
        let e = Essential::from_pose(&pose()).unwrap();
        let s = svd_jacobi(e.matrix()).unwrap().singular_values;
        assert!((s - Vector3::new(1.0, 1.0, 0.0)).amax() < 1e-12);
        let cands = e.decompose().unwrap();
        let truth = pose();
        let tdir = truth.translation().normalize();
        let hits = cands
            .iter()
            .filter(|c| {
                (c.rotation().matrix() - truth.rotation().matrix()).amax() < 1e-12
                    && (c.translation() - tdir).amax() < 1e-12
            })
            .count();
        assert_eq!(hits, 1);
        // Every candidate reproduces E up to sign.
        for c in &cands {
            let ec = Essential::from_pose(c).unwrap();
            let d = (ec.matrix() - e.matrix())
                .amax()
                .min((ec.matrix() + e.matrix()).amax());
            assert!(d < 1e-12);
        }
        let zero = RelativePose::<f64>::identity();
        assert_eq!(Essential::from_pose(&zero), Err(Error::Degenerate));
    }

    #[test]
    fn fundamental_lines_and_epipoles() {
        let k = Intrinsics::new(500.0, 510.0, 320.0, 240.0).unwrap();
        let e = Essential::from_pose(&pose()).unwrap();
        let f = e.to_fundamental(&k, &k).unwrap();
        assert!((f.matrix().norm() - 1.0).abs() < 1e-12);
        let (e1, e2) = f.epipoles().unwrap();
        assert!((f.matrix() * e1.coords()).amax() < 1e-12);
        assert!((f.matrix().transpose() * e2.coords()).amax() < 1e-12);
        // The epipole in image 2 is the image of camera 1's centre: K t.
        let t = pose().translation();
        let expected = k.matrix() * t;
        let (a, b) = (e2.coords().normalize(), expected.normalize());
        assert!((a - b).amax() < 1e-9 || (a + b).amax() < 1e-9);
        // Back to E.
        let back = Essential::from_fundamental(&f, &k, &k).unwrap();
        let d = (back.matrix() - e.matrix())
            .amax()
            .min((back.matrix() + e.matrix()).amax());
        assert!(d < 1e-9, "{d}");
        assert_eq!(
            Fundamental::from_matrix(&Matrix3::<f64>::zeros()),
            Err(Error::Degenerate)
        );
        let x = Point2::new(100.0, 50.0);
        let l = f.line_in_second(&x).unwrap();
        assert!(l.coords().dot(e2.coords()).abs() < 1e-9 * l.coords().norm());
        assert!(f.line_in_first(&Point2::new(f64::NAN, 0.0)).is_err());
    }
}
