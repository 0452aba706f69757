//! Triangulation of a point seen in two calibrated views.
//!
//! The views are world-to-camera transforms `Pₖ: X ↦ Rₖ X + tₖ` between any typed frames
//! (two [`crate::transform::Pose`]s in a world frame, or the identity of [`super::View1`] and a
//! [`super::RelativePose`]), and the observations normalised image coordinates `x̂ = K⁻¹ u`
//! (undistorted). Every method returns the point in the common source frame `W` with its
//! depths and reprojection errors (normalised units: multiply by `f` for pixels).

use nalgebra::{Matrix3, Point2, Point3, Vector2, Vector3};

use super::lift;
use crate::linalg::StreamingQr;
use crate::scalar::{Real, above, check_finite};
use crate::transform::{Frame, Transform};
use crate::{Error, Result};

/// A triangulated point.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Triangulated<T: Real = f32> {
    /// The point in the source frame of the two views.
    pub point: Point3<T>,
    /// Depth (camera-frame `z`) in view 1, `> 0`.
    pub depth1: T,
    /// Depth in view 2, `> 0`.
    pub depth2: T,
    /// Reprojection error in view 1, `|π(P₁ X) - x̂₁|` (normalised units).
    pub error1: T,
    /// Reprojection error in view 2.
    pub error2: T,
}

impl<T: Real> Triangulated<T> {
    /// The larger of the two reprojection errors.
    pub fn max_error(&self) -> T {
        self.error1.max(self.error2)
    }
}

/// Depths and reprojection errors of `x`; [`Error::BehindCamera`] unless in front of both,
/// [`Error::NonFinite`] when its coordinates in either view overflow.
fn finish<W: Frame, C1: Frame, C2: Frame, T: Real>(
    p1: &Transform<W, C1, T>,
    p2: &Transform<W, C2, T>,
    x: Point3<T>,
    x1: &Point2<T>,
    x2: &Point2<T>,
) -> Result<Triangulated<T>> {
    check_finite(x.coords.as_slice())?;
    let (c1, c2) = (p1.apply(&x), p2.apply(&x));
    // A finite point can still leave f32 in a camera frame (`R X + t` with `|t|` near
    // `f32::MAX`): an infinite depth would make the error `x/∞ = 0`, silently wrong.
    check_finite(c1.coords.as_slice())?;
    check_finite(c2.coords.as_slice())?;
    if !above(c1.z, T::zero()) || !above(c2.z, T::zero()) {
        return Err(Error::BehindCamera);
    }
    let err = |c: &Point3<T>, o: &Point2<T>| (Vector2::new(c.x / c.z, c.y / c.z) - o.coords).norm();
    let t = Triangulated {
        point: x,
        depth1: c1.z,
        depth2: c2.z,
        error1: err(&c1, x1),
        error2: err(&c2, x2),
    };
    check_finite(&[t.error1, t.error2])?;
    Ok(t)
}

fn check_inputs<T: Real>(x1: &Point2<T>, x2: &Point2<T>) -> Result<()> {
    check_finite(&[x1.x, x1.y, x2.x, x2.y])
}

/// The linear (DLT) triangulation: the homogeneous `X` minimising `|A X|`, `|X| = 1`, with
/// rows `x̂ P₃ - P₁`, `ŷ P₃ - P₂` per view (`Pᵢ` the rows of `[R t]`), via a 4-column
/// [`StreamingQr`] and its SVD (Hartley & Zisserman §12.2).
///
/// Errors: [`Error::NonFinite`]; [`Error::AtInfinity`] when the solution has `w ≈ 0` (parallel
/// rays); [`Error::BehindCamera`] when the point is not in front of both views.
#[doc(alias = "triangulatePoints")]
pub fn triangulate_dlt<W: Frame, C1: Frame, C2: Frame, T: Real>(
    p1: &Transform<W, C1, T>,
    p2: &Transform<W, C2, T>,
    x1: &Point2<T>,
    x2: &Point2<T>,
) -> Result<Triangulated<T>> {
    check_inputs(x1, x2)?;
    let mut qr = StreamingQr::<T, 4>::new();
    for (m, x) in [(p1.matrix(), x1), (p2.matrix(), x2)] {
        let r = |i: usize| -> [T; 4] {
            core::array::from_fn(|j| m.get((i, j)).copied().unwrap_or(T::zero()))
        };
        let (r1, r2, r3) = (r(0), r(1), r(2));
        let row = |a: &[T; 4], s: T| -> [T; 4] {
            let mut out = [T::zero(); 4];
            for ((o, p3), pa) in out.iter_mut().zip(r3.iter()).zip(a.iter()) {
                *o = s * *p3 - *pa;
            }
            out
        };
        qr.push_row(&row(&r1, x.x))?;
        qr.push_row(&row(&r2, x.y))?;
    }
    let (v, _) = qr.null_vector()?;
    let [a, b, c, w]: [T; 4] = v.into();
    if !above(w.abs(), T::EPSILON * (a.abs().max(b.abs()).max(c.abs()))) {
        return Err(Error::AtInfinity);
    }
    finish(p1, p2, Point3::new(a / w, b / w, c / w), x1, x2)
}

/// The midpoint method: the point halfway between the closest points of the two rays
/// `cₖ + λₖ dₖ` (`cₖ = -Rₖᵀ tₖ`, `dₖ = Rₖᵀ x̂ₖ`), from the 2x2 normal equations of
/// `min |c₁ + λ₁ d₁ - c₂ - λ₂ d₂|²`.
///
/// Errors: [`Error::NonFinite`]; [`Error::AtInfinity`] for parallel rays
/// (`|d₁ × d₂|² ≤ ε |d₁|² |d₂|²`); [`Error::BehindCamera`].
pub fn triangulate_midpoint<W: Frame, C1: Frame, C2: Frame, T: Real>(
    p1: &Transform<W, C1, T>,
    p2: &Transform<W, C2, T>,
    x1: &Point2<T>,
    x2: &Point2<T>,
) -> Result<Triangulated<T>> {
    check_inputs(x1, x2)?;
    let (i1, i2) = (p1.inverse(), p2.inverse());
    let (c1, c2) = (i1.origin_in_target_frame(), i2.origin_in_target_frame());
    let (d1, d2) = (i1.apply_vector(&lift(x1)), i2.apply_vector(&lift(x2)));
    let b = c2 - c1;
    let (a11, a12, a22) = (d1.dot(&d1), d1.dot(&d2), d2.dot(&d2));
    let (b1, b2) = (b.dot(&d1), b.dot(&d2));
    // λ₁ a11 - λ₂ a12 = b·d1, λ₁ a12 - λ₂ a22 = b·d2.
    let det = a12 * a12 - a11 * a22;
    if !above(det.abs(), T::EPSILON * a11 * a22) {
        return Err(Error::AtInfinity);
    }
    let l1 = (a12 * b2 - a22 * b1) / det;
    let l2 = (a11 * b2 - a12 * b1) / det;
    let q1 = c1 + d1 * l1;
    let q2 = c2 + d2 * l2;
    finish(
        p1,
        p2,
        Point3::from((q1.coords + q2.coords) * T::lit(0.5)),
        x1,
        x2,
    )
}

/// Lindstrom's optimal correction ("Triangulation made easy", CVPR 2010, `niter2`): the pair
/// `(x̂₁, x̂₂)` closest to `(x₁, x₂)` (sum of squared distances) with `x̂₂ᵀ M x̂₁ = 0`, for any
/// epipolar matrix `M` (`F` with pixels, `E` with normalised coordinates; OpenCV's
/// `correctMatches`). Two iterations of
///
/// `n₂ = S M x₁`, `n₁ = S Mᵀ x₂`, `a = n₂ᵀ M̃ n₁`, `b = (|n₁|² + |n₂|²)/2`, `c = x₂ᵀ M x₁`,
/// `d = √(b² - a c)`, `λ = c / (b + d)`, `Δ₂ = λ n₂`, `Δ₁ = λ n₁`, then
/// `n₂ ← n₂ - M̃ Δ₁`, `n₁ ← n₁ - M̃ᵀ Δ₂`, `λ ← 2 λ d / (|n₁|² + |n₂|²)`,
///
/// with `S = [I₂ 0]`, `M̃ = S M Sᵀ`; exact (to rounding) on the constraint.
///
/// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when both points sit at the epipoles.
#[doc(alias = "correctMatches")]
pub fn correct_matches<T: Real>(
    m: &Matrix3<T>,
    x1: &Point2<T>,
    x2: &Point2<T>,
) -> Result<(Point2<T>, Point2<T>)> {
    check_inputs(x1, x2)?;
    check_finite(m.as_slice())?;
    let s = |v: Vector3<T>| Vector2::new(v.x, v.y);
    let mt = m.fixed_view::<2, 2>(0, 0).into_owned();
    let (a1, a2) = (lift(x1), lift(x2));
    let mut n2 = s(m * a1);
    let mut n1 = s(m.transpose() * a2);
    let a = n2.dot(&(mt * n1));
    let b = (n1.norm_squared() + n2.norm_squared()) * T::lit(0.5);
    let c = a2.dot(&(m * a1));
    let d = (b * b - a * c).max(T::zero()).sqrt();
    if !above(b + d, T::zero()) {
        return Err(Error::Degenerate);
    }
    let mut lambda = c / (b + d);
    let (d2, d1) = (n2 * lambda, n1 * lambda);
    n2 -= mt * d1;
    n1 -= mt.transpose() * d2;
    let nn = n1.norm_squared() + n2.norm_squared();
    if !above(nn, T::zero()) {
        return Err(Error::Degenerate);
    }
    lambda = lambda * (d + d) / nn;
    let c1 = Point2::from(x1.coords - n1 * lambda);
    let c2 = Point2::from(x2.coords - n2 * lambda);
    check_finite(&[c1.x, c1.y, c2.x, c2.y])?;
    Ok((c1, c2))
}

/// Optimal two-view triangulation: [`correct_matches`] with `E = [t]ₓ R` of the relative
/// pose `P₂ P₁⁻¹` (the corrected rays intersect), then [`triangulate_midpoint`] of the
/// corrected pair. Minimises the reprojection error in normalised coordinates, which is the
/// pixel error up to the factor `f` when `fx = fy` in both views. The reported errors are
/// those of the original observations.
///
/// Errors: as [`triangulate_midpoint`]; [`Error::Degenerate`] for a zero baseline.
pub fn triangulate_optimal<W: Frame, C1: Frame, C2: Frame, T: Real>(
    p1: &Transform<W, C1, T>,
    p2: &Transform<W, C2, T>,
    x1: &Point2<T>,
    x2: &Point2<T>,
) -> Result<Triangulated<T>> {
    check_inputs(x1, x2)?;
    let rel = p1.inverse().then(p2);
    let t = rel.translation();
    if !above(t.norm(), T::zero()) {
        return Err(Error::Degenerate);
    }
    let e = (t / t.norm()).cross_matrix() * rel.rotation().matrix();
    let (c1, c2) = correct_matches(&e, x1, x2)?;
    let tri = triangulate_midpoint(p1, p2, &c1, &c2)?;
    finish(p1, p2, tri.point, x1, x2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use crate::transform::{Camera, Pose, World};

    fn views() -> (Pose<f64>, Pose<f64>) {
        (
            Pose::from_rodrigues(Vector3::new(0.05, -0.1, 0.0), Vector3::new(0.2, 0.0, 0.1))
                .unwrap(),
            Pose::from_rodrigues(Vector3::new(-0.1, 0.25, 0.05), Vector3::new(-0.8, 0.1, 0.3))
                .unwrap(),
        )
    }

    fn project(p: &Pose<f64>, x: &Point3<f64>) -> Point2<f64> {
        let c = p.apply(x);
        Point2::new(c.x / c.z, c.y / c.z)
    }

    #[test]
    fn exact_points_come_back_from_every_method() {
        let (p1, p2) = views();
        let mut g = Pcg32::new(8);
        for _ in 0..50 {
            let x = Point3::new(
                g.uniform(-1.0, 1.0),
                g.uniform(-1.0, 1.0),
                g.uniform(3.0, 8.0),
            );
            let (u1, u2) = (project(&p1, &x), project(&p2, &x));
            for t in [
                triangulate_dlt(&p1, &p2, &u1, &u2).unwrap(),
                triangulate_midpoint(&p1, &p2, &u1, &u2).unwrap(),
                triangulate_optimal(&p1, &p2, &u1, &u2).unwrap(),
            ] {
                assert!(
                    (t.point - x).norm() < 1e-9 * x.coords.norm(),
                    "{t:?} vs {x}"
                );
                assert!(t.max_error() < 1e-10);
                assert!((t.depth1 - p1.apply(&x).z).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn optimal_correction_satisfies_the_constraint_and_beats_sampson() {
        let (p1, p2) = views();
        let rel = p1.inverse().then(&p2);
        let e = rel.translation().cross_matrix() * rel.rotation().matrix();
        let mut g = Pcg32::new(9);
        for _ in 0..100 {
            let x = Point3::new(
                g.uniform(-1.0, 1.0),
                g.uniform(-1.0, 1.0),
                g.uniform(3.0, 8.0),
            );
            let n = |p: Point2<f64>, g: &mut Pcg32| {
                Point2::new(p.x + 2e-3 * g.normal(), p.y + 2e-3 * g.normal())
            };
            let (u1, u2) = (n(project(&p1, &x), &mut g), n(project(&p2, &x), &mut g));
            let (c1, c2) = correct_matches(&e, &u1, &u2).unwrap();
            let r = lift(&c2).dot(&(e * lift(&c1))).abs();
            assert!(
                r < 1e-15 + 1e-9 * lift(&u2).dot(&(e * lift(&u1))).abs(),
                "{r}"
            );
            let moved = (c1 - u1).norm_squared() + (c2 - u2).norm_squared();
            let sampson = super::super::sampson_distance_sq(&e, &u1, &u2).unwrap();
            // The optimum is at least as close as... (Sampson is a first-order estimate of it.)
            assert!(
                (moved - sampson).abs() <= 1e-3 * sampson + 1e-18,
                "{moved} {sampson}"
            );
            // Optimal triangulation reprojects no worse than DLT and midpoint (sum of squares).
            let sq = |t: &Triangulated<f64>| t.error1 * t.error1 + t.error2 * t.error2;
            let o = triangulate_optimal(&p1, &p2, &u1, &u2).unwrap();
            let d = triangulate_dlt(&p1, &p2, &u1, &u2).unwrap();
            let m = triangulate_midpoint(&p1, &p2, &u1, &u2).unwrap();
            assert!(sq(&o) <= sq(&d) * (1.0 + 1e-6) + 1e-20);
            assert!(sq(&o) <= sq(&m) * (1.0 + 1e-6) + 1e-20);
        }
    }

    #[test]
    fn errors_for_points_behind_parallel_rays_and_bad_input() {
        let (p1, p2) = views();
        let x = Point3::new(0.1, 0.2, -5.0);
        let behind = p1.inverse().apply(&Point3::new(0.1, 0.2, -4.0));
        let (u1, u2) = (project(&p1, &behind), project(&p2, &behind));
        let _ = x;
        assert_eq!(
            triangulate_dlt(&p1, &p2, &u1, &u2),
            Err(Error::BehindCamera)
        );
        assert_eq!(
            triangulate_midpoint(&p1, &p2, &u1, &u2),
            Err(Error::BehindCamera)
        );
        assert_eq!(
            triangulate_optimal(&p1, &p2, &u1, &u2),
            Err(Error::BehindCamera)
        );
        // Parallel rays: the same pure-translation camera looking along the baseline-normal.
        let a: Transform<World, Camera, f64> = Transform::identity();
        let b: Transform<World, Camera, f64> =
            Transform::from_rodrigues(Vector3::zeros(), Vector3::new(-1.0, 0.0, 0.0)).unwrap();
        let u = Point2::new(0.1, 0.2);
        assert_eq!(triangulate_midpoint(&a, &b, &u, &u), Err(Error::AtInfinity));
        assert_eq!(triangulate_dlt(&a, &b, &u, &u), Err(Error::AtInfinity));
        assert_eq!(triangulate_optimal(&a, &a, &u, &u), Err(Error::Degenerate));
        let nan = Point2::new(f64::NAN, 0.0);
        assert_eq!(triangulate_dlt(&p1, &p2, &nan, &u), Err(Error::NonFinite));
    }
}
