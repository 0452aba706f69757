//! The fundamental matrix from point correspondences: normalised 8-point, 7-point, RANSAC.

use heapless::Vec;
use nalgebra::{Matrix3, Point2, SVector};

use super::Fundamental;
use super::poly::real_roots;
use super::refine::refine_fundamental_iter;
use crate::homography::{Normalization, rank_tolerance};
use crate::linalg::{StreamingQr, null_space};
use crate::ransac::{Estimator, RansacParams, RansacReport, ransac};
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Most fundamental matrices [`seven_point`] returns (the real roots of a cubic).
pub const MAX_SEVEN_POINT_SOLUTIONS: usize = 3;

/// The epipolar row of a pair: `x₂ᵀ F x₁ = r · vec(F)` with `vec` row-major,
/// `r = (x₂x₁, x₂y₁, x₂, y₂x₁, y₂y₁, y₂, x₁, y₁, 1)`.
pub(crate) fn epipolar_row<T: Real>(x1: &Point2<T>, x2: &Point2<T>) -> [T; 9] {
    [
        x2.x * x1.x,
        x2.x * x1.y,
        x2.x,
        x2.y * x1.x,
        x2.y * x1.y,
        x2.y,
        x1.x,
        x1.y,
        T::one(),
    ]
}

/// The 3x3 matrix of a row-major 9-vector.
pub(crate) fn unvec<T: Real>(v: &SVector<T, 9>) -> Matrix3<T> {
    let [a, b, c, d, e, f, g, h, i]: [T; 9] = (*v).into();
    Matrix3::new(a, b, c, d, e, f, g, h, i)
}

/// The normalised 8-point algorithm (Hartley 1997) on `N ≥ 8` pairs `x₁ᵢ ↔ x₂ᵢ`:
///
/// `min |A f|`, `|f| = 1`, one row `(x₂x₁, x₂y₁, x₂, y₂x₁, y₂y₁, y₂, x₁, y₁, 1)` per
/// Hartley-normalised pair, streamed through a [`StreamingQr`]; then rank 2 by zeroing the
/// smallest singular value, and `F = T₂ᵀ F̂ T₁`.
///
/// Errors: [`Error::LengthMismatch`]; [`Error::TooFewPoints`] below 8 pairs;
/// [`Error::NonFinite`]; [`Error::Degenerate`] when the system has rank below 8
/// (`σ₈ ≤ √ε σ₁`: e.g. every point on a plane, or coincident points).
///
/// ```
/// use camgeom::camera::Intrinsics;
/// use camgeom::nalgebra::{Point2, Point3, Vector3};
/// use camgeom::twoview::{Essential, RelativePose, eight_point};
///
/// let k = Intrinsics::new(500.0f64, 500.0, 320.0, 240.0)?;
/// let (rvec, t) = (Vector3::new(0.1, 0.2, -0.05), Vector3::new(1.0, 0.2, 0.1));
/// let pose = RelativePose::from_rodrigues(rvec, t)?;
/// let scene: [Point3<f64>; 12] = core::array::from_fn(|i| {
///     let f = |m: usize, n: usize| ((i * m) % n) as f64 / n as f64 - 0.5;
///     Point3::new(3.0 * f(37, 11), 2.0 * f(53, 7), 5.0 + 2.5 * f(29, 13))
/// });
/// let pixel = |p: Point3<f64>| k.normalized_to_pixel(&Point2::new(p.x / p.z, p.y / p.z));
/// let (x1, x2) = (scene.map(pixel), scene.map(|p| pixel(pose.apply(&p))));
/// // Fitted on the first ten pairs: the other two satisfy x₂ᵀ F x₁ = 0 as well.
/// let f = eight_point(&x1[..10], &x2[..10])?;
/// assert!(f.sampson_sq(&x1[11], &x2[11]).is_some_and(|d| d < 1e-12));
/// // And F is K⁻ᵀ [t]ₓ R K⁻¹ of the true pose (both have unit norm; the sign is free).
/// let truth = Essential::from_pose(&pose)?.to_fundamental(&k, &k)?;
/// let (a, b) = (f.matrix(), truth.matrix());
/// assert!((a - b).amax().min((a + b).amax()) < 1e-6);
/// # Ok::<(), camgeom::Error>(())
/// ```
pub fn eight_point<T: Real>(x1: &[Point2<T>], x2: &[Point2<T>]) -> Result<Fundamental<T>> {
    if x1.len() != x2.len() {
        return Err(Error::LengthMismatch);
    }
    solve(x1.iter().zip(x2.iter()).map(|(a, b)| (*a, *b)))
}

/// [`eight_point`] on the pairs with `mask[i] == true` (e.g. RANSAC inliers).
pub fn eight_point_masked<T: Real>(
    x1: &[Point2<T>],
    x2: &[Point2<T>],
    mask: &[bool],
) -> Result<Fundamental<T>> {
    if x1.len() != x2.len() || x1.len() != mask.len() {
        return Err(Error::LengthMismatch);
    }
    solve(
        x1.iter()
            .zip(x2.iter())
            .zip(mask.iter())
            .filter(|(_, m)| **m)
            .map(|((a, b), _)| (*a, *b)),
    )
}

/// `F = T₂ᵀ F̂ T₁` of a rank-2 `F̂` in Hartley-normalised coordinates, rescaled only.
///
/// The rank is enforced on `F̂`, never again in pixels: a pixel `F` is badly scaled (its two
/// non-zero singular values differ by about `f²`, `σ₂/σ₁ ~ 1e-5` for `f = 600` px), so an SVD
/// of it in `f32` either rejects it as rank-deficient (`σ₂ ≤ √ε σ₁`) or, through the rounding
/// of `σ₁`-sized entries, moves the small singular directions that carry the epipolar
/// geometry. Multiplying by the invertible `Tᵢ` keeps the rank exactly, up to rounding.
fn denormalize<T: Real>(
    fhat: &Fundamental<T>,
    n1: &Normalization<T>,
    n2: &Normalization<T>,
) -> Result<Fundamental<T>> {
    Fundamental::from_rank2(&(n2.matrix().transpose() * fhat.matrix() * n1.matrix()))
}

pub(crate) fn solve<T, I>(pairs: I) -> Result<Fundamental<T>>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    if pairs.clone().take(8).count() < 8 {
        return Err(Error::TooFewPoints);
    }
    let n1 = Normalization::from_points_iter(pairs.clone().map(|(a, _)| a))?;
    let n2 = Normalization::from_points_iter(pairs.clone().map(|(_, b)| b))?;
    let mut qr = StreamingQr::<T, 9>::new();
    for (a, b) in pairs {
        qr.push_row(&epipolar_row(&n1.apply(&a), &n2.apply(&b)))?;
    }
    let f = qr.null_vector_of_rank(rank_tolerance::<T>())?;
    let fhat = Fundamental::from_matrix(&unvec(&f))?;
    denormalize(&fhat, &n1, &n2)
}

/// The 7-point algorithm: every rank-2 `F` through 7 pairs.
///
/// The 7 epipolar rows (Hartley-normalised) leave a 2-dimensional null space `F̂₁, F̂₂` (an
/// orthonormal basis by Gauss-Jordan elimination of the unit rows with full pivoting, a
/// tenth of the cost of a QR and SVD); `det(α F̂₁ + (1 - α) F̂₂) = 0` is a cubic
/// in `α` whose coefficients come from its values at `α = -1, 0, 1, 2`; each real root gives
/// one `F` (between one and [`MAX_SEVEN_POINT_SOLUTIONS`]).
///
/// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when the rows have rank below 7 (a
/// pivot below `√ε` of the largest) or no root gives a rank-2 matrix.
pub fn seven_point<T: Real>(
    x1: &[Point2<T>; 7],
    x2: &[Point2<T>; 7],
) -> Result<Vec<Fundamental<T>, MAX_SEVEN_POINT_SOLUTIONS>> {
    for p in x1.iter().chain(x2.iter()) {
        check_finite(&[p.x, p.y])?;
    }
    let n1 = Normalization::from_points(x1)?;
    let n2 = Normalization::from_points(x2)?;
    let mut rows = [[T::zero(); 9]; 7];
    for ((a, b), row) in x1.iter().zip(x2.iter()).zip(rows.iter_mut()) {
        let r = epipolar_row(&n1.apply(a), &n2.apply(b));
        // Unit rows, so that the pivot test of the elimination weighs each pair alike.
        let n = r.iter().fold(T::zero(), |acc, v| acc + *v * *v).sqrt();
        *row = r.map(|v| v / n);
    }
    check_finite(rows.as_flattened())?;
    let [f1, f2] = null_space(&rows, rank_tolerance::<T>())?.map(|v| unvec(&v.into()));
    // p(α) = det(α F₁ + (1 - α) F₂) = c₀ + c₁ α + c₂ α² + c₃ α³ from four samples.
    let d = |a: T| (f1 * a + f2 * (T::one() - a)).determinant();
    let (dm1, d0, d1, d2) = (d(-T::one()), d(T::zero()), d(T::one()), d(T::lit(2.0)));
    let six = T::lit(6.0);
    let two = T::lit(2.0);
    let c0 = d0;
    let c2 = (d1 + dm1) / two - d0;
    // Third difference: d(2) - 3 d(1) + 3 d(0) - d(-1) = 6 c₃.
    let c3 = (d2 - T::lit(3.0) * d1 + T::lit(3.0) * d0 - dm1) / six;
    let c1 = d1 - c0 - c2 - c3;
    let mut out = Vec::new();
    for a in real_roots(&[c0, c1, c2, c3]) {
        let fhat = f1 * a + f2 * (T::one() - a);
        if let Ok(f) = Fundamental::from_matrix(&fhat).and_then(|f| denormalize(&f, &n1, &n2)) {
            let _ = out.push(f);
        }
    }
    if out.is_empty() {
        return Err(Error::Degenerate);
    }
    Ok(out)
}

/// Fundamental-matrix estimation as a RANSAC [`Estimator`]: 7-point minimal samples (up to
/// three models each), Sampson residuals in pixels², 8-point refits, Sampson LM polish.
#[derive(Debug, Clone, Copy)]
pub struct FundamentalEstimator<'a, T: Real = f32> {
    x1: &'a [Point2<T>],
    x2: &'a [Point2<T>],
    /// Levenberg-Marquardt steps of [`Estimator::refine`].
    pub refine_iterations: u8,
}

impl<'a, T: Real> FundamentalEstimator<'a, T> {
    /// Pairs `(x1[i], x2[i])`; errors with [`Error::LengthMismatch`].
    pub fn new(x1: &'a [Point2<T>], x2: &'a [Point2<T>]) -> Result<Self> {
        if x1.len() != x2.len() {
            return Err(Error::LengthMismatch);
        }
        Ok(Self {
            x1,
            x2,
            refine_iterations: 10,
        })
    }
}

impl<T: Real> Estimator for FundamentalEstimator<'_, T> {
    type Model = Fundamental<T>;
    type Scalar = T;

    fn num_points(&self) -> usize {
        self.x1.len()
    }

    fn sample_size(&self) -> usize {
        7
    }

    fn fit_minimal(&self, sample: &[usize], emit: &mut dyn FnMut(Self::Model)) {
        let mut a = [Point2::origin(); 7];
        let mut b = [Point2::origin(); 7];
        if sample.len() != 7 {
            return;
        }
        for ((i, pa), pb) in sample.iter().zip(a.iter_mut()).zip(b.iter_mut()) {
            match (self.x1.get(*i), self.x2.get(*i)) {
                (Some(p), Some(q)) => {
                    *pa = *p;
                    *pb = *q;
                }
                _ => return,
            }
        }
        if let Ok(models) = seven_point(&a, &b) {
            models.into_iter().for_each(emit);
        }
    }

    fn residual_sq(&self, f: &Self::Model, i: usize) -> Option<T> {
        f.sampson_sq(self.x1.get(i)?, self.x2.get(i)?)
    }

    fn refit(&self, _: &Self::Model, inliers: &[bool]) -> Option<Self::Model> {
        eight_point_masked(self.x1, self.x2, inliers).ok()
    }

    /// The eight-point fit on the inliers: the model it starts from plays no part.
    fn refit_is_mask_only(&self) -> bool {
        true
    }

    fn refine(&self, f: &Self::Model, inliers: &[bool]) -> Option<Self::Model> {
        let pairs = self
            .x1
            .iter()
            .zip(self.x2.iter())
            .zip(inliers.iter())
            .filter(|(_, m)| **m)
            .map(|((a, b), _)| (*a, *b));
        refine_fundamental_iter(f, pairs, self.refine_iterations)
            .ok()
            .map(|r| r.model)
    }
}

/// Robust `F` from correspondences with outliers (OpenCV's
/// `findFundamentalMat(x1, x2, FM_RANSAC)` counterpart), writing the inlier mask.
///
/// 7-point samples, MSAC on the Sampson distance in pixels (the threshold of `params`), 8-point
/// local optimisation, Sampson Levenberg-Marquardt polish ([`super::refine_fundamental`]),
/// on the generic [`ransac`] loop. Errors: see [`ransac`].
#[doc(alias = "findFundamentalMat")]
pub fn find_fundamental<T: Real>(
    x1: &[Point2<T>],
    x2: &[Point2<T>],
    params: &RansacParams<T>,
    inliers: &mut [bool],
) -> Result<(Fundamental<T>, RansacReport<T>)> {
    let est = FundamentalEstimator::new(x1, x2)?;
    ransac(&est, params, inliers)
}
