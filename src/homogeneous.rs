//! Points and lines of the projective plane.
//!
//! A point `p = (x, y, w)` and a line `l = (a, b, c)` are 3-vectors defined up to scale;
//! `p` lies on `l` iff `lᵀp = 0`. The cross product does everything else:
//!
//! - join of two points: `l = p₁ × p₂`; meet of two lines: `p = l₁ × l₂`;
//! - ideal points `(x, y, 0)` (directions) all lie on the line at infinity `l∞ = (0, 0, 1)`;
//!   parallel lines meet there, at their common direction `l × l∞ = (b, -a, 0)`.
//!
//! Scale-free tolerances: a vector is "zero" when its norm is below `16 ε` after its operands
//! were scaled to unit norm, and a point is ideal when `|w| ≤ 16 ε |(x, y, w)|`: beyond that its
//! Euclidean position would carry a relative error above 1/16 in the working precision, so
//! [`Point2h::to_euclidean`] returns [`Error::AtInfinity`] instead of dividing by ~0.
//!
//! ```
//! use camgeom::Error;
//! use camgeom::homogeneous::{Line2h, Point2h};
//! use camgeom::nalgebra::Point2;
//!
//! let p = |x: f32, y: f32| Point2h::from_euclidean(&Point2::new(x, y));
//! // The diagonals of the square (0, 0)-(2, 2) meet at its centre.
//! let d1 = p(0.0, 0.0)?.join(&p(2.0, 2.0)?)?;
//! let d2 = p(0.0, 2.0)?.join(&p(2.0, 0.0)?)?;
//! let centre = d1.meet(&d2)?.to_euclidean()?;
//! assert!((centre - Point2::new(1.0, 1.0)).norm() < 1e-6);
//! // Two of its parallel sides meet at infinity, in their common direction (0, 1).
//! let left = p(0.0, 0.0)?.join(&p(0.0, 2.0)?)?;
//! let right = p(2.0, 0.0)?.join(&p(2.0, 2.0)?)?;
//! let v = left.meet(&right)?;
//! assert!(v.is_ideal() && v.to_euclidean() == Err(Error::AtInfinity));
//! assert!(Line2h::at_infinity().contains(&v, 1e-6));
//! assert!(v.normalized().coords().x.abs() < 1e-6);
//! # Ok::<(), camgeom::Error>(())
//! ```

use nalgebra::{Point2, Vector3};

use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Relative tolerance factor of the module docs (`16 ε`).
fn tol<T: Real>() -> T {
    T::lit(16.0) * T::EPSILON
}

/// Unit-norm copy of a finite, non-zero vector.
fn unit<T: Real>(v: &Vector3<T>) -> Result<Vector3<T>> {
    check_finite(v.as_slice())?;
    // Scale by the largest entry first so the norm cannot overflow or underflow.
    let m = v.amax();
    if m == T::zero() {
        return Err(Error::Degenerate);
    }
    let s = v / m;
    Ok(s / s.norm())
}

/// Cross product of two unit vectors, rejected when it vanishes at working precision.
fn cross_checked<T: Real>(a: &Vector3<T>, b: &Vector3<T>) -> Result<Vector3<T>> {
    let c = unit(a)?.cross(&unit(b)?);
    if c.amax() <= tol::<T>() {
        return Err(Error::Degenerate);
    }
    unit(&c)
}

/// A point of the projective plane, `(x, y, w)` up to scale; ideal (a direction) when `w = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Point2h<T: Real = f32>(Vector3<T>);

/// A line of the projective plane, `(a, b, c)` up to scale: `a x + b y + c w = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Line2h<T: Real = f32>(Vector3<T>);

impl<T: Real> Point2h<T> {
    /// The ideal point of the x axis, `(1, 0, 0)` (a placeholder that needs no check).
    pub(crate) fn x_direction() -> Self {
        Self(Vector3::new(T::one(), T::zero(), T::zero()))
    }

    /// `(x, y, w)`. Errors: NaN/inf ([`Error::NonFinite`]), `(0, 0, 0)` ([`Error::Degenerate`]).
    pub fn new(x: T, y: T, w: T) -> Result<Self> {
        Self::from_vector(Vector3::new(x, y, w))
    }

    /// From homogeneous coordinates, validated as in [`Self::new`].
    pub fn from_vector(v: Vector3<T>) -> Result<Self> {
        unit(&v).map(|_| Self(v))
    }

    /// The finite point `(x, y, 1)`.
    pub fn from_euclidean(p: &Point2<T>) -> Result<Self> {
        Self::new(p.x, p.y, T::one())
    }

    /// The ideal point in direction `(dx, dy)`: `(dx, dy, 0)`.
    pub fn ideal(dx: T, dy: T) -> Result<Self> {
        Self::new(dx, dy, T::zero())
    }

    /// Homogeneous coordinates as given (not normalised).
    pub fn coords(&self) -> &Vector3<T> {
        &self.0
    }

    /// The same point with unit-norm coordinates and `w >= 0`.
    pub fn normalized(&self) -> Self {
        // Construction guarantees a finite non-zero vector, so `unit` cannot fail here.
        let u = unit(&self.0).unwrap_or(self.0);
        Self(if u.z < T::zero() { -u } else { u })
    }

    /// `true` when `|w| ≤ 16 ε |(x, y, w)|`: a direction rather than a position.
    pub fn is_ideal(&self) -> bool {
        let u = self.normalized().0;
        u.z <= tol::<T>()
    }

    /// `(x/w, y/w)`; [`Error::AtInfinity`] for an ideal point.
    pub fn to_euclidean(&self) -> Result<Point2<T>> {
        let u = self.normalized().0;
        if u.z <= tol::<T>() {
            return Err(Error::AtInfinity);
        }
        let p = Point2::new(u.x / u.z, u.y / u.z);
        check_finite(&[p.x, p.y])?;
        Ok(p)
    }

    /// The line through both points, `l = p × q`; [`Error::Degenerate`] when they coincide.
    pub fn join(&self, other: &Self) -> Result<Line2h<T>> {
        cross_checked(&self.0, &other.0).map(Line2h)
    }

    /// The dual line: the same coordinates read as `(a, b, c)`. `p ∈ l ⇔ l* ∈ p*`.
    pub fn dual(&self) -> Line2h<T> {
        Line2h(self.0)
    }
}

impl<T: Real> Line2h<T> {
    /// `(a, b, c)`. Errors: NaN/inf ([`Error::NonFinite`]), `(0, 0, 0)` ([`Error::Degenerate`]).
    pub fn new(a: T, b: T, c: T) -> Result<Self> {
        Self::from_vector(Vector3::new(a, b, c))
    }

    /// From homogeneous coordinates, validated as in [`Self::new`].
    pub fn from_vector(v: Vector3<T>) -> Result<Self> {
        unit(&v).map(|_| Self(v))
    }

    /// The line at infinity `l∞ = (0, 0, 1)`, home of every ideal point.
    pub fn at_infinity() -> Self {
        Self(Vector3::new(T::zero(), T::zero(), T::one()))
    }

    /// The line through two points (same as [`Point2h::join`]).
    pub fn through(p: &Point2h<T>, q: &Point2h<T>) -> Result<Self> {
        p.join(q)
    }

    /// Homogeneous coordinates as given (not normalised).
    pub fn coords(&self) -> &Vector3<T> {
        &self.0
    }

    /// The same line scaled so that `a² + b² = 1` (then `l·(x, y, 1)` is the signed distance);
    /// the line at infinity is returned with unit norm.
    pub fn normalized(&self) -> Self {
        let u = unit(&self.0).unwrap_or(self.0);
        let n = (u.x * u.x + u.y * u.y).sqrt();
        if n <= tol::<T>() {
            Self(u)
        } else {
            Self(u / n)
        }
    }

    /// `true` for the line at infinity (`|(a, b)| ≤ 16 ε |(a, b, c)|`).
    pub fn is_at_infinity(&self) -> bool {
        let u = unit(&self.0).unwrap_or(self.0);
        (u.x * u.x + u.y * u.y).sqrt() <= tol::<T>()
    }

    /// The common point, `p = l × m`: an ideal point when the lines are parallel;
    /// [`Error::Degenerate`] when they are the same line.
    pub fn meet(&self, other: &Self) -> Result<Point2h<T>> {
        cross_checked(&self.0, &other.0).map(Point2h)
    }

    /// The line's direction as an ideal point, `l × l∞ = (b, -a, 0)`;
    /// [`Error::Degenerate`] for the line at infinity.
    pub fn direction(&self) -> Result<Point2h<T>> {
        self.meet(&Self::at_infinity())
    }

    /// Whether `p` lies on the line: `|lᵀp| ≤ tol |l| |p|` (scale-free; `tol` ~ `1e-5` for f32).
    pub fn contains(&self, p: &Point2h<T>, tol: T) -> bool {
        match (unit(&self.0), unit(&p.0)) {
            (Ok(l), Ok(q)) => l.dot(&q).abs() <= tol,
            _ => false,
        }
    }

    /// Euclidean distance from a finite point, `|a x + b y + c| / √(a² + b²)`;
    /// [`Error::AtInfinity`] for the line at infinity.
    pub fn distance(&self, p: &Point2<T>) -> Result<T> {
        check_finite(&[p.x, p.y])?;
        if self.is_at_infinity() {
            return Err(Error::AtInfinity);
        }
        let l = self.normalized().0;
        Ok((l.x * p.x + l.y * p.y + l.z).abs())
    }

    /// The dual point.
    pub fn dual(&self) -> Point2h<T> {
        Point2h(self.0)
    }
}

/// The vanishing point of image lines that should be concurrent (images of parallel 3D
/// lines), in the least-squares sense: the unit `v` minimising `Σᵢ (l̂ᵢᵀ v)²`, where `l̂ᵢ` is
/// `lᵢ` with `(aᵢ, bᵢ)` of unit length after the coordinates are scaled by the lines' mean
/// distance from the origin (so each residual is a point-to-line distance and the system is
/// well conditioned). Solved by streaming QR and a Jacobi SVD, without forming `Σ l lᵀ`.
///
/// Returns an ideal point when the lines are parallel in the image. Errors:
/// [`Error::TooFewPoints`] for fewer than two lines, [`Error::Degenerate`] when the lines do
/// not determine a point (all the same line, or lines at infinity).
pub fn vanishing_point<T: Real>(lines: &[Line2h<T>]) -> Result<Point2h<T>> {
    vanishing_point_of(lines.iter().copied())
}

/// [`vanishing_point`] over the lines an iterator yields (walked twice: the scale, then the
/// rows), so that callers with lines in another shape (segments, a subset) need no buffer.
pub(crate) fn vanishing_point_of<T: Real, I>(lines: I) -> Result<Point2h<T>>
where
    I: Iterator<Item = Line2h<T>> + Clone,
{
    weighted_vanishing_point_of(lines.map(|l| (l, T::one())))
}

/// [`vanishing_point_of`] with a weight per line: the unit `v` minimising
/// `Σᵢ wᵢ² (l̂ᵢᵀ v)²` (a weight `wᵢ > 0`; each row of the system is scaled by `wᵢ`). For
/// the reweighted fit of [`crate::vanishing`], where `wᵢ` turns the distance of `v` from a
/// segment's line into that segment's endpoint residual.
pub(crate) fn weighted_vanishing_point_of<T: Real, I>(lines: I) -> Result<Point2h<T>>
where
    I: Iterator<Item = (Line2h<T>, T)> + Clone,
{
    // Lines with (a, b) ~ 0 are the line at infinity: they carry no constraint on a finite
    // vanishing point and would dominate the scale.
    let (mut count, mut sum_dist) = (0usize, T::zero());
    for (l, _) in lines.clone() {
        if l.is_at_infinity() {
            return Err(Error::Degenerate);
        }
        let n = l.normalized().0;
        sum_dist += n.z.abs();
        count += 1;
    }
    if count < 2 {
        return Err(Error::TooFewPoints);
    }
    let mean = sum_dist / T::lit(count as f64);
    let s = if mean > T::EPSILON { mean } else { T::one() };
    let mut qr = crate::linalg::StreamingQr::<T, 3>::new();
    for (l, w) in lines {
        let n = l.normalized().0;
        qr.push_row(&[w * n.x, w * n.y, w * n.z / s])?;
    }
    let svd = qr.svd()?;
    let sv = &svd.singular_values;
    // A second singular value near zero means a two-dimensional solution set: every line is
    // (numerically) the same line, so no single point is determined.
    if sv.y <= T::lit(64.0) * T::EPSILON * sv.x {
        return Err(Error::Degenerate);
    }
    let v = svd.null_vector();
    Point2h::new(v.x * s, v.y * s, v.z)
}

/// The vanishing line of a plane from two of its vanishing points (two directions in the
/// plane): `l = v₁ × v₂`.
pub fn vanishing_line<T: Real>(v1: &Point2h<T>, v2: &Point2h<T>) -> Result<Line2h<T>> {
    v1.join(v2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn p(x: f64, y: f64) -> Point2h<f64> {
        Point2h::from_euclidean(&Point2::new(x, y)).unwrap()
    }

    /// Same projective element: the normalised vectors agree up to sign.
    fn same(a: &Vector3<f64>, b: &Vector3<f64>, eps: f64) -> bool {
        let (a, b) = (a.normalize(), b.normalize());
        (a - b).amax() < eps || (a + b).amax() < eps
    }

    #[test]
    fn join_and_meet_are_dual() {
        let (a, b, c) = (p(1.0, 2.0), p(-3.0, 5.0), p(4.0, -1.0));
        let ab = a.join(&b).unwrap();
        let ac = a.join(&c).unwrap();
        // The join contains both points; the meet of two joins through a is a.
        assert!(ab.contains(&a, 1e-12) && ab.contains(&b, 1e-12));
        assert!(same(ab.meet(&ac).unwrap().coords(), a.coords(), 1e-12));
        // Duality: meet of the dual lines is the dual of the join of the points.
        let m = a.dual().meet(&b.dual()).unwrap();
        assert!(same(m.coords(), ab.coords(), 1e-12));
        // Incidence is symmetric under duality: p ∈ l ⇔ l* ∈ p*.
        assert!(a.dual().contains(&ab.dual(), 1e-12));
        // Cross-product identity: (p × q)·p = 0 and |p × q| = |p||q| sin θ.
        let (u, v) = (a.coords(), b.coords());
        assert_relative_eq!(u.cross(v).dot(u), 0.0, epsilon = 1e-12);
        let s = u.cross(v).norm() / (u.norm() * v.norm());
        assert_relative_eq!(
            s * s + (u.dot(v) / (u.norm() * v.norm())).powi(2),
            1.0,
            epsilon = 1e-12
        );
    }

    #[test]
    fn parallel_lines_meet_at_infinity() {
        // y = 2x + 1 and y = 2x - 3: direction (1, 2).
        let l1 = Line2h::new(2.0, -1.0, 1.0).unwrap();
        let l2 = Line2h::new(2.0, -1.0, -3.0).unwrap();
        let v = l1.meet(&l2).unwrap();
        assert!(v.is_ideal());
        assert_eq!(v.to_euclidean(), Err(Error::AtInfinity));
        assert!(same(v.coords(), &Vector3::new(1.0, 2.0, 0.0), 1e-12));
        assert!(Line2h::at_infinity().contains(&v, 1e-12));
        assert!(same(l1.direction().unwrap().coords(), v.coords(), 1e-12));
        assert!(Line2h::<f64>::at_infinity().is_at_infinity());
        assert_eq!(
            Line2h::<f64>::at_infinity().distance(&Point2::origin()),
            Err(Error::AtInfinity)
        );
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let a = p(1.0, 2.0);
        assert_eq!(a.join(&a), Err(Error::Degenerate));
        // Same point at another scale is still the same point.
        let a2 = Point2h::new(3.0, 6.0, 3.0).unwrap();
        assert_eq!(a.join(&a2), Err(Error::Degenerate));
        let l = Line2h::new(1.0, 1.0, 1.0).unwrap();
        assert_eq!(
            l.meet(&Line2h::new(-2.0, -2.0, -2.0).unwrap()),
            Err(Error::Degenerate)
        );
        assert_eq!(Point2h::new(0.0, 0.0, 0.0f32), Err(Error::Degenerate));
        assert_eq!(Point2h::new(f32::NAN, 0.0, 1.0), Err(Error::NonFinite));
        assert_eq!(Line2h::new(0.0, f32::INFINITY, 1.0), Err(Error::NonFinite));
        assert_eq!(
            Line2h::<f32>::at_infinity().direction(),
            Err(Error::Degenerate)
        );
        // A point so far away that w is below the tolerance is reported ideal, not divided.
        let far = Point2h::new(1.0f32, 1.0, 1e-9).unwrap();
        assert!(far.is_ideal());
        assert_eq!(far.to_euclidean(), Err(Error::AtInfinity));
        // Huge but representable coordinates do not overflow the normalisation.
        let huge = Point2h::new(1e38f32, 1e38, 1e34).unwrap();
        assert_relative_eq!(
            huge.to_euclidean().unwrap(),
            Point2::new(1e4, 1e4),
            epsilon = 1e-2
        );
    }

    #[test]
    fn vanishing_point_least_squares() {
        // Noisy images of lines through (400, -300): each line passes within ~0.5 px of it.
        let v = (400.0, -300.0);
        let mut lines = std::vec::Vec::new();
        for (k, angle) in [0.3f64, 0.5, 0.8, 1.1, 1.4].iter().enumerate() {
            let off = if k % 2 == 0 { 0.5 } else { -0.5 };
            let (dx, dy) = (angle.cos(), angle.sin());
            let a = p(v.0 + off * -dy, v.1 + off * dx);
            let b = p(v.0 + 200.0 * dx, v.1 + 200.0 * dy);
            lines.push(a.join(&b).unwrap());
        }
        let vp = vanishing_point(&lines).unwrap().to_euclidean().unwrap();
        // The residuals are ±0.5 px in alternating directions: the fit lands within 0.5 px.
        assert!((vp - Point2::new(v.0, v.1)).norm() < 0.5, "{vp}");
        // Exactly concurrent lines give the exact point, in f32 too.
        let lf: std::vec::Vec<Line2h<f32>> = [(1.0f32, 0.0f32), (0.0, 1.0), (1.0, 1.0)]
            .iter()
            .map(|&(dx, dy)| {
                let a = Point2h::from_euclidean(&Point2::new(100.0f32, 50.0)).unwrap();
                let b = Point2h::from_euclidean(&Point2::new(100.0 + 30.0 * dx, 50.0 + 30.0 * dy))
                    .unwrap();
                a.join(&b).unwrap()
            })
            .collect();
        let vf = vanishing_point(&lf).unwrap().to_euclidean().unwrap();
        assert!((vf - Point2::new(100.0, 50.0)).norm() < 1e-3);
        // Parallel image lines: the vanishing point is ideal, in their direction.
        let par = [
            Line2h::new(2.0, -1.0, 1.0).unwrap(),
            Line2h::new(2.0, -1.0, -3.0).unwrap(),
            Line2h::new(2.0, -1.0, 7.0).unwrap(),
        ];
        let vi = vanishing_point(&par).unwrap();
        assert!(vi.is_ideal());
        assert!(same(vi.coords(), &Vector3::new(1.0, 2.0, 0.0), 1e-9));
        // Degenerate sets are typed errors.
        assert_eq!(vanishing_point(&par[..1]), Err(Error::TooFewPoints));
        assert_eq!(
            vanishing_point(&[par[0], par[0], par[0]]),
            Err(Error::Degenerate)
        );
        assert_eq!(
            vanishing_point(&[par[0], Line2h::at_infinity()]),
            Err(Error::Degenerate)
        );
    }

    #[test]
    fn distance_is_euclidean() {
        let l = Line2h::new(3.0, 4.0, -10.0).unwrap(); // 3x + 4y = 10
        assert_relative_eq!(
            l.distance(&Point2::new(0.0, 0.0)).unwrap(),
            2.0,
            epsilon = 1e-12
        );
        assert_relative_eq!(
            l.distance(&Point2::new(2.0, 1.0)).unwrap(),
            0.0,
            epsilon = 1e-12
        );
    }
}
