//! Vanishing points and the horizon from image line segments: which segments share a
//! vanishing point (sequential RANSAC), each point by least squares over its segments, and the
//! horizon from two horizontal vanishing points, or from the vertical one and the camera.
//!
//! **Consistency of a segment with a candidate point** (Tardif 2009, Rother 2002): a segment
//! `ab` with midpoint `m` belongs to the vanishing point `v` when it lies along the line `m × v`;
//! its residual is the distance of its endpoint `a` from that line,
//! `r = |(m × v) · a| / ‖(m × v)₁,₂‖` (pixels; `b` is as far on the other side). This is
//! unbiased by where `v` is, finite or ideal, unlike the distance from `v` to the segment's line.
//!
//! **Search** ([`find_vanishing_points`]): up to `max_points` times, RANSAC ([`crate::ransac`])
//! over the segments not yet assigned, a minimal sample being two segments whose lines meet at
//! `v = l₁ × l₂`, inliers those with `r < threshold`; each refit is the least-squares point of
//! its segments' lines ([`crate::homogeneous::vanishing_point`]) reweighted, a few rounds, so
//! that each line's distance from `v` counts as the segment's residual `r` (the plain least
//! squares lets the scattered lines of short segments pull a far point by degrees). A point needs
//! `min_segments` inliers, else the search stops. Segments shorter than `min_length` are left
//! out (their direction is too uncertain to vote).
//!
//! **Horizon** ([`horizon`]): the vanishing line of the ground plane. A point whose segments
//! run within `atan(1/2) ≈ 26.6°` of the image's vertical axis is *vertical*; the others are
//! horizontal directions. Two horizontal points give the horizon `h = v₁ × v₂` (the two with
//! the most segments); with only the vertical point and the intrinsics `K`, the horizon is its
//! polar with respect to the image of the absolute conic, `h = ω v = K⁻ᵀ K⁻¹ v` (the vanishing
//! line of the planes orthogonal to the vertical direction; Hartley & Zisserman, 8.6.3).
//! Anything else does not determine it: [`Error::TooFewPoints`].
//!
//! Memory is the caller's: one label, one index and one mask entry per segment.
//!
//! ```
//! use camgeom::nalgebra::Point2;
//! use camgeom::vanishing::{
//!     Segment, VanishingConfig, VanishingPoint, find_vanishing_points, NO_POINT,
//! };
//!
//! // Eight segments towards (400, 100), eight towards an ideal point (vertical lines).
//! let mut segs = [Segment::new(Point2::new(0.0f32, 0.0), Point2::new(1.0, 1.0)); 16];
//! for (i, s) in segs.iter_mut().enumerate() {
//!     let k = (i % 8) as f32;
//!     *s = if i < 8 {
//!         let a = Point2::new(10.0 + 5.0 * k, 300.0 - 20.0 * k);
//!         let t = 0.3;
//!         Segment::new(a, a + (Point2::new(400.0, 100.0) - a) * t)
//!     } else {
//!         Segment::new(Point2::new(20.0 + 30.0 * k, 50.0), Point2::new(20.0 + 30.0 * k, 250.0))
//!     };
//! }
//! let params = VanishingConfig::default().check()?;
//! let (mut labels, mut index, mut mask) = ([0u8; 16], [0u32; 16], [false; 16]);
//! let mut found = [VanishingPoint::default(); 3];
//! let n = find_vanishing_points(&segs, &params, &mut labels, &mut index, &mut mask, &mut found)?;
//! assert_eq!(n, 2);
//! assert!(labels.iter().all(|&l| l != NO_POINT));
//! let finite = found[..n].iter().find(|v| !v.point.is_ideal()).unwrap();
//! let p = finite.point.to_euclidean()?;
//! assert!((p.x - 400.0).abs() < 1e-2 && (p.y - 100.0).abs() < 1e-2);
//! # Ok::<(), camgeom::Error>(())
//! ```

use nalgebra::{Point2, Vector2, Vector3};

use crate::camera::Intrinsics;
use crate::homogeneous::{Line2h, Point2h, vanishing_point_of, weighted_vanishing_point_of};
use crate::ransac::{Estimator, RansacConfig, RansacParams, ransac};
use crate::scalar::Real;
use crate::{Error, Result};

/// The label of a segment that belongs to no vanishing point.
pub const NO_POINT: u8 = u8::MAX;

/// Most vanishing points [`find_vanishing_points`] looks for.
pub const MAX_POINTS: usize = 8;

/// An image line segment from `a` to `b` (pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Segment<T: Real = f32> {
    /// One endpoint.
    pub a: Point2<T>,
    /// The other endpoint.
    pub b: Point2<T>,
}

impl<T: Real> Segment<T> {
    /// The segment from `a` to `b`.
    pub const fn new(a: Point2<T>, b: Point2<T>) -> Self {
        Self { a, b }
    }

    /// Its length `‖b - a‖`.
    pub fn length(&self) -> T {
        (self.b - self.a).norm()
    }

    /// The line through its endpoints, `a × b`.
    ///
    /// Errors: [`Error::NonFinite`], [`Error::Degenerate`] for coincident endpoints.
    pub fn line(&self) -> Result<Line2h<T>> {
        Point2h::from_euclidean(&self.a)?.join(&Point2h::from_euclidean(&self.b)?)
    }

    /// The distance of `a` from the line through the midpoint and `v` (the module's
    /// consistency residual, pixels); `None` when `v` is the midpoint itself or not finite.
    pub fn residual(&self, v: &Point2h<T>) -> Option<T> {
        let m = Vector3::new(
            (self.a.x + self.b.x) / T::lit(2.0),
            (self.a.y + self.b.y) / T::lit(2.0),
            T::one(),
        );
        // Scale v to unit norm first: an ideal or far point must not overflow the product.
        let vc = v.normalized();
        let l = m.cross(vc.coords());
        let n = (l.x * l.x + l.y * l.y).sqrt();
        if n <= T::zero() || !n.finite() {
            return None;
        }
        let r = (l.x * self.a.x + l.y * self.a.y + l.z).abs() / n;
        r.finite().then_some(r)
    }
}

/// A vanishing point found by [`find_vanishing_points`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VanishingPoint<T: Real = f32> {
    /// The point (ideal when its segments are parallel in the image).
    pub point: Point2h<T>,
    /// Segments assigned to it.
    pub segments: usize,
    /// Root mean square of their residuals, pixels.
    pub rms_px: T,
    /// Their mean direction, a unit vector with `y ≥ 0` (segments weighted by length, the
    /// mean taken over doubled angles since a segment's direction has no sign).
    pub direction: Vector2<T>,
}

impl<T: Real> Default for VanishingPoint<T> {
    /// The ideal point of the x axis, no segments.
    fn default() -> Self {
        Self {
            point: Point2h::x_direction(),
            segments: 0,
            rms_px: T::zero(),
            direction: Vector2::new(T::one(), T::zero()),
        }
    }
}

impl<T: Real> VanishingPoint<T> {
    /// Whether its segments run within `atan(1/2) ≈ 26.6°` of the image's vertical axis.
    pub fn is_vertical(&self) -> bool {
        self.direction.y.abs() > T::lit(2.0) * self.direction.x.abs()
    }
}

/// Parameters of [`find_vanishing_points`], as the user writes them; [`Self::check`] makes the
/// [`VanishingParams`] it takes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VanishingConfig<T: Real = f32> {
    /// RANSAC over segment pairs; its threshold is the largest residual of an inlier segment,
    /// pixels (default 1.5).
    pub ransac: RansacConfig<T>,
    /// Segments a point needs, `≥ 3` (default 8).
    pub min_segments: usize,
    /// Points looked for, `1..=MAX_POINTS` (default 3: a building's three directions).
    pub max_points: usize,
    /// Shortest segment that votes, pixels, `≥ 0` (default 10).
    pub min_length: T,
}

impl<T: Real> Default for VanishingConfig<T> {
    fn default() -> Self {
        Self {
            ransac: RansacConfig {
                threshold: T::lit(1.5),
                max_iterations: 1000,
                ..RansacConfig::default()
            },
            min_segments: 8,
            max_points: 3,
            min_length: T::lit(10.0),
        }
    }
}

impl<T: Real> VanishingConfig<T> {
    /// Checks every field once.
    ///
    /// Errors: [`Error::InvalidParameter`] naming the field (`ransac.*`, `min_segments`,
    /// `max_points`, `min_length`).
    pub fn check(&self) -> Result<VanishingParams<T>> {
        let ransac = self.ransac.check()?;
        if self.min_segments < 3 {
            return Err(Error::InvalidParameter("min_segments"));
        }
        if !(1..=MAX_POINTS).contains(&self.max_points) {
            return Err(Error::InvalidParameter("max_points"));
        }
        if !(self.min_length >= T::zero() && self.min_length.finite()) {
            return Err(Error::InvalidParameter("min_length"));
        }
        Ok(VanishingParams {
            config: *self,
            ransac,
        })
    }
}

/// A [`VanishingConfig`] that passed [`VanishingConfig::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct VanishingParams<T: Real = f32> {
    config: VanishingConfig<T>,
    ransac: RansacParams<T>,
}

impl<T: Real> VanishingParams<T> {
    /// The checked configuration.
    pub const fn config(&self) -> &VanishingConfig<T> {
        &self.config
    }
}

/// The RANSAC problem: the segments listed in `index`.
struct Search<'a, T: Real> {
    segments: &'a [Segment<T>],
    index: &'a [u32],
}

impl<T: Real> Search<'_, T> {
    fn segment(&self, i: usize) -> Option<&Segment<T>> {
        self.segments.get(*self.index.get(i)? as usize)
    }

    fn chosen<'s>(&'s self, inliers: &'s [bool]) -> impl Iterator<Item = &'s Segment<T>> + Clone {
        (0..self.index.len())
            .filter(|&i| inliers.get(i).copied().unwrap_or(false))
            .filter_map(|i| self.segment(i))
    }
}

impl<T: Real> Estimator for Search<'_, T> {
    type Model = Point2h<T>;
    type Scalar = T;

    fn num_points(&self) -> usize {
        self.index.len()
    }

    fn sample_size(&self) -> usize {
        2
    }

    fn fit_minimal(&self, sample: &[usize], emit: &mut dyn FnMut(Point2h<T>)) {
        let line = |k: usize| self.segment(*sample.get(k)?)?.line().ok();
        if let (Some(l1), Some(l2)) = (line(0), line(1))
            && let Ok(v) = l1.meet(&l2)
        {
            emit(v);
        }
    }

    fn residual_sq(&self, v: &Point2h<T>, i: usize) -> Option<T> {
        let r = self.segment(i)?.residual(v)?;
        Some(r * r)
    }

    fn refit(&self, v: &Point2h<T>, inliers: &[bool]) -> Option<Point2h<T>> {
        refit_segments(self.chosen(inliers), Some(*v)).ok()
    }

    fn refit_is_mask_only(&self) -> bool {
        true
    }

    fn refine(&self, v: &Point2h<T>, inliers: &[bool]) -> Option<Point2h<T>> {
        self.refit(v, inliers)
    }
}

/// Rounds of reweighting in [`refit_segments`]: the weights depend on `v` only through the
/// distances `|v - mᵢ|`, so the second round already moves `v` by a small fraction of the
/// first's step.
const REWEIGHT_ROUNDS: usize = 3;

/// The point minimising the module's residual over `chosen` (approximately: `Σ rᵢ²`), by
/// iteratively reweighted least squares on the segments' lines. For a unit `v` and a line
/// `l̂ᵢ` with `(a, b)` of unit length, `l̂ᵢᵀ v` is `w` times the distance of `v` from the
/// line, and the endpoint residual of the segment (half-length `hᵢ`, midpoint `mᵢ`) is, to
/// first order, that distance times `hᵢ / |v - mᵢ|`: so `rᵢ ≈ |l̂ᵢᵀ v| hᵢ / |v₁,₂ - w mᵢ|`,
/// which holds for an ideal `v` too. The plain least squares (`start` = `None`: the first
/// round's `v`) weighs every line alike, and far from short segments their lines scatter:
/// it lets them pull a far vanishing point by degrees. A round whose system is degenerate
/// keeps the previous `v`.
fn refit_segments<'s, T: Real + 's, I>(chosen: I, start: Option<Point2h<T>>) -> Result<Point2h<T>>
where
    I: Iterator<Item = &'s Segment<T>> + Clone,
{
    let mut v = match start {
        Some(v) => v,
        None => vanishing_point_of(chosen.clone().filter_map(|s| s.line().ok()))?,
    };
    for _ in 0..REWEIGHT_ROUNDS {
        let u = *v.normalized().coords();
        let weighted = chosen.clone().filter_map(move |s| {
            let l = s.line().ok()?;
            let half = s.length() / T::lit(2.0);
            let m = (s.a.coords + s.b.coords) / T::lit(2.0);
            let (dx, dy) = (u.x - m.x * u.z, u.y - m.y * u.z);
            let w = half / (dx * dx + dy * dy).sqrt();
            // v on the segment's midpoint, or overflow: the segment does not constrain v.
            (w.finite() && w > T::zero()).then_some((l, w))
        });
        match weighted_vanishing_point_of(weighted) {
            Ok(next) => v = next,
            Err(_) => break,
        }
    }
    Ok(v)
}

/// The vanishing point of the segments `i` with `member(i)`: the least-squares point of their
/// lines ([`crate::homogeneous::vanishing_point`]), reweighted to minimise their residuals
/// (module documentation), their residuals' RMS and their mean direction (of the doubled
/// angles: directions have no sign). For segments already grouped (by hand, or by another method).
///
/// Errors: as [`crate::homogeneous::vanishing_point`] ([`Error::TooFewPoints`] below two
/// segments, [`Error::Degenerate`] when they lie on one line), [`Error::NonFinite`] or
/// [`Error::Degenerate`] for a segment with non-finite or coincident endpoints.
pub fn fit_vanishing_point<T: Real>(
    segments: &[Segment<T>],
    member: impl Fn(usize) -> bool,
) -> Result<VanishingPoint<T>> {
    let chosen = || {
        segments
            .iter()
            .enumerate()
            .filter(|(i, _)| member(*i))
            .map(|(_, s)| s)
    };
    for s in chosen() {
        s.line()?;
    }
    let point = refit_segments(chosen(), None)?;
    let (mut sum_sq, mut count) = (T::zero(), 0usize);
    // Directions are sign-free: their mean is that of the doubled angles, each unit vector
    // `(cos θ, sin θ)` counted as `(cos 2θ, sin 2θ)` weighted by the segment's length,
    // `((dx² - dy²), 2 dx dy) / |d|`. (Folding each direction onto `y ≥ 0` first and adding
    // them cancels nearly horizontal segments that tilt either way.)
    let (mut c2, mut s2) = (T::zero(), T::zero());
    for s in chosen() {
        if let Some(r) = s.residual(&point) {
            sum_sq += r * r;
        }
        count += 1;
        let d = s.b - s.a;
        let len = d.norm();
        if len > T::zero() && len.finite() {
            let u = d / len;
            let (c, sn) = ((u.x * u.x - u.y * u.y) * len, T::lit(2.0) * u.x * u.y * len);
            if c.finite() && sn.finite() {
                c2 += c;
                s2 += sn;
            }
        }
    }
    let r = (c2 * c2 + s2 * s2).sqrt();
    let direction = if r > T::zero() && r.finite() {
        // The half angle: cos θ = √((1 + cos 2θ) / 2), sin θ = ±√((1 - cos 2θ) / 2), then
        // folded onto y ≥ 0.
        let c = c2 / r;
        let half = |x: T| {
            let h = x / T::lit(2.0);
            if h > T::zero() { h.sqrt() } else { T::zero() }
        };
        let (cos, sin) = (half(T::one() + c), half(T::one() - c));
        if s2 < T::zero() {
            Vector2::new(-cos, sin)
        } else {
            Vector2::new(cos, sin)
        }
    } else {
        Vector2::new(T::one(), T::zero())
    };
    Ok(VanishingPoint {
        point,
        segments: count,
        rms_px: (sum_sq / T::lit(count.max(1) as f64)).sqrt(),
        direction,
    })
}

/// Finds up to `max_points` vanishing points of `segments` (see the module documentation),
/// the best supported first, into `out`; `labels[i]` is the index in `out` of segment `i`'s
/// point, or [`NO_POINT`]. `index` and `mask` are scratch of one entry per segment. Returns
/// how many points were found (0 when no point has `min_segments` segments: not an error,
/// the image has no dominant direction).
///
/// Errors: [`Error::LengthMismatch`] when `labels`, `index` or `mask` is shorter than
/// `segments`, or `segments` has more than `u32::MAX` entries; [`Error::NonFinite`] for a
/// non-finite endpoint.
pub fn find_vanishing_points<T: Real>(
    segments: &[Segment<T>],
    params: &VanishingParams<T>,
    labels: &mut [u8],
    index: &mut [u32],
    mask: &mut [bool],
    out: &mut [VanishingPoint<T>],
) -> Result<usize> {
    let n = segments.len();
    let (Some(labels), Some(index), Some(mask)) =
        (labels.get_mut(..n), index.get_mut(..n), mask.get_mut(..n))
    else {
        return Err(Error::LengthMismatch);
    };
    if u32::try_from(n).is_err() {
        return Err(Error::LengthMismatch);
    }
    let c = params.config;
    for (l, s) in labels.iter_mut().zip(segments) {
        crate::scalar::check_finite(&[s.a.x, s.a.y, s.b.x, s.b.y])?;
        // A segment without a line (endpoints equal to working precision, though apart) would
        // pass the residual test and then fail the fit: left out with the short ones.
        let long = s.length() >= c.min_length && s.length() > T::zero() && s.line().is_ok();
        *l = if long { 0 } else { NO_POINT };
    }
    // Free segments carry label 0 until assigned; assigned ones carry their point's index
    // + 1 (shifted down at the end), left-out ones NO_POINT.
    let mut found = 0usize;
    let wanted = c.max_points.min(out.len()).min(usize::from(NO_POINT) - 1);
    while found < wanted {
        let mut m = 0usize;
        for (i, &l) in labels.iter().enumerate() {
            if l == 0
                && let Some(slot) = index.get_mut(m)
            {
                *slot = i as u32;
                m += 1;
            }
        }
        if m < c.min_segments {
            break;
        }
        let search = Search {
            segments,
            index: index.get(..m).unwrap_or(&[]),
        };
        let Some(mask) = mask.get_mut(..m) else { break };
        let Ok((_, report)) = ransac(&search, &params.ransac, mask) else {
            break;
        };
        if report.inliers < c.min_segments {
            break;
        }
        let tag = found as u8 + 1;
        for (k, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
            if let Some(l) = search
                .index
                .get(k)
                .and_then(|&i| labels.get_mut(i as usize))
            {
                *l = tag;
            }
        }
        let Ok(point) = fit_vanishing_point(segments, |i| labels.get(i) == Some(&tag)) else {
            // No point after all: its segments go back (unassigned at the end), so that no
            // label names a point that is not returned.
            labels
                .iter_mut()
                .filter(|l| **l == tag)
                .for_each(|l| *l = 0);
            break;
        };
        let Some(slot) = out.get_mut(found) else {
            break;
        };
        *slot = point;
        found += 1;
    }
    for l in labels.iter_mut() {
        *l = match *l {
            0 | NO_POINT => NO_POINT,
            k => k - 1,
        };
    }
    Ok(found)
}

/// Where [`horizon`] took the horizon from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HorizonSource {
    /// The join of two horizontal vanishing points.
    TwoHorizontal,
    /// The polar `K⁻ᵀ K⁻¹ v` of the vertical vanishing point.
    VerticalAndCamera,
}

/// The horizon (the ground plane's vanishing line) of vanishing points `points`, with the
/// intrinsics when known (see the module documentation); the line is scaled to
/// `a² + b² = 1` when it is not the line at infinity.
///
/// Errors: [`Error::TooFewPoints`] when the points do not determine it (fewer than two
/// horizontal points, and no vertical point or no camera), [`Error::Degenerate`] when the two
/// horizontal points coincide.
pub fn horizon<T: Real>(
    points: &[VanishingPoint<T>],
    camera: Option<&Intrinsics<T>>,
) -> Result<(Line2h<T>, HorizonSource)> {
    let mut horizontal = [None::<&VanishingPoint<T>>; 2];
    let mut vertical = None::<&VanishingPoint<T>>;
    for p in points {
        if p.is_vertical() {
            if vertical.is_none_or(|v| p.segments > v.segments) {
                vertical = Some(p);
            }
        } else if horizontal[0].is_none_or(|h| p.segments > h.segments) {
            horizontal[1] = horizontal[0];
            horizontal[0] = Some(p);
        } else if horizontal[1].is_none_or(|h| p.segments > h.segments) {
            horizontal[1] = Some(p);
        }
    }
    let line = match (horizontal, vertical, camera) {
        ([Some(a), Some(b)], _, _) => (a.point.join(&b.point)?, HorizonSource::TwoHorizontal),
        (_, Some(v), Some(k)) => {
            let ki = k.inverse_matrix();
            let h = ki.transpose() * (ki * v.point.coords());
            (Line2h::from_vector(h)?, HorizonSource::VerticalAndCamera)
        }
        _ => return Err(Error::TooFewPoints),
    };
    let c = line.0.coords();
    let n = (c.x * c.x + c.y * c.y).sqrt();
    if n > T::zero() && n.finite() {
        return Ok((Line2h::from_vector(c / n)?, line.1));
    }
    Ok(line)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use nalgebra::{Matrix3, Rotation3, Vector3};

    /// A camera `K [R | t]` with a small roll and a downward tilt, and segments of the three
    /// world axes' lines (x and z horizontal, y vertical in the world), endpoints perturbed by
    /// `noise` px, plus `clutter` random segments. Projection by plain matrix products.
    fn scene(noise: f64, clutter: usize) -> (Matrix3<f64>, Rotation3<f64>, [Segment<f64>; 120]) {
        let k = Matrix3::new(800.0, 0.0, 320.0, 0.0, 800.0, 240.0, 0.0, 0.0, 1.0);
        let r = Rotation3::from_euler_angles(0.25, 0.6, 0.05);
        let t = Vector3::new(0.3, -0.2, 12.0);
        let mut rng = Pcg32::new(7);
        let project = |x: Vector3<f64>| {
            let p = k * (r * x + t);
            Point2::new(p.x / p.z, p.y / p.z)
        };
        let mut segs = [Segment::new(Point2::origin(), Point2::new(1.0, 0.0)); 120];
        for (i, s) in segs.iter_mut().enumerate() {
            let axis = i % 3;
            let mut base = Vector3::new(
                rng.uniform(-3.0, 3.0),
                rng.uniform(-3.0, 3.0),
                rng.uniform(-3.0, 3.0),
            );
            let mut dir = Vector3::zeros();
            dir[axis] = rng.uniform(1.0, 2.5);
            if i >= 120 - clutter {
                base = Vector3::new(rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), 0.0);
                dir = Vector3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), 0.3);
            }
            let jitter = |rng: &mut Pcg32| noise * rng.normal();
            let (a, b) = (project(base), project(base + dir));
            *s = Segment::new(
                Point2::new(a.x + jitter(&mut rng), a.y + jitter(&mut rng)),
                Point2::new(b.x + jitter(&mut rng), b.y + jitter(&mut rng)),
            );
        }
        (k, r, segs)
    }

    fn find(segs: &[Segment<f64>]) -> ([VanishingPoint<f64>; 3], usize, [u8; 120]) {
        let params = VanishingConfig::default().check().unwrap();
        let (mut labels, mut index, mut mask) = ([0u8; 120], [0u32; 120], [false; 120]);
        let mut out = [VanishingPoint::default(); 3];
        let n = find_vanishing_points(segs, &params, &mut labels, &mut index, &mut mask, &mut out)
            .unwrap();
        (out, n, labels)
    }

    /// Angle between the direction `K⁻¹ v` of a found point and the true `R eᵢ`, degrees.
    fn angle_to_axis(k: &Matrix3<f64>, r: &Rotation3<f64>, v: &Point2h<f64>) -> f64 {
        let d = (k.try_inverse().unwrap() * v.coords()).normalize();
        (0..3)
            .map(|a| {
                let e = r * Vector3::ith(a, 1.0);
                d.dot(&e).abs().min(1.0).acos().to_degrees()
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn three_directions_of_a_box() {
        let (k, r, segs) = scene(0.3, 15);
        let (out, n, labels) = find(&segs);
        assert_eq!(n, 3);
        for v in &out {
            let e = angle_to_axis(&k, &r, &v.point);
            assert!(e < 0.5, "{e}° from the nearest axis");
            assert!(v.rms_px < 0.6, "{}", v.rms_px);
        }
        // The clutter is left out, the axis segments are assigned.
        let assigned = labels[..105].iter().filter(|&&l| l != NO_POINT).count();
        assert!(assigned >= 100, "{assigned}");
        let chance = labels[105..].iter().filter(|&&l| l != NO_POINT).count();
        assert!(chance <= 5, "{chance} of 15 random segments assigned");
    }

    #[test]
    fn the_horizon_two_ways() {
        let (k, r, segs) = scene(0.0, 0);
        let (out, n, _) = find(&segs);
        assert_eq!(n, 3);
        assert_eq!(out.iter().filter(|v| v.is_vertical()).count(), 1);
        // The truth: the vanishing line of the world's horizontal plane, K⁻ᵀ R e_y.
        let truth = k.try_inverse().unwrap().transpose() * (r * Vector3::y());
        let same = |l: &Line2h<f64>| {
            let (a, b) = (l.coords().normalize(), truth.normalize());
            (a - b).amax().min((a + b).amax())
        };
        let (h2, s2) = horizon(&out, None).unwrap();
        assert_eq!(s2, HorizonSource::TwoHorizontal);
        assert!(same(&h2) < 1e-3, "{}", same(&h2));
        let vertical: [VanishingPoint<f64>; 1] = [*out.iter().find(|v| v.is_vertical()).unwrap()];
        let intr = Intrinsics::new(800.0, 800.0, 320.0, 240.0).unwrap();
        let (h1, s1) = horizon(&vertical, Some(&intr)).unwrap();
        assert_eq!(s1, HorizonSource::VerticalAndCamera);
        assert!(same(&h1) < 1e-3, "{}", same(&h1));
        assert_eq!(horizon(&vertical, None), Err(Error::TooFewPoints));
        assert_eq!(horizon(&out[..0], Some(&intr)), Err(Error::TooFewPoints));
    }

    /// Nearly horizontal segments towards a point left of the image, tilting up and down:
    /// their mean direction is horizontal (folding each onto `y ≥ 0` before adding them made
    /// it vertical, and the horizon then took this point for the vertical one).
    #[test]
    fn nearly_horizontal_segments_are_not_vertical() {
        let v = Point2::new(-220.0f64, 267.0);
        let mut segs = [Segment::new(Point2::origin(), Point2::new(1.0, 0.0)); 12];
        for (k, s) in segs.iter_mut().enumerate() {
            let a = Point2::new(300.0 + 20.0 * k as f64, 150.0 + 20.0 * k as f64);
            *s = Segment::new(a, a + (v - a) * 0.1);
        }
        let p = fit_vanishing_point(&segs, |_| true).unwrap();
        assert!(!p.is_vertical(), "{:?}", p.direction);
        assert!(p.direction.x.abs() > 0.99, "{:?}", p.direction);
        let e = p.point.to_euclidean().unwrap();
        assert!((e - v).norm() < 1e-6, "{e}");
    }

    /// A far point (about 1900 px from the segments) seen through many short noisy segments
    /// and a few long ones: the reweighted fit, which minimises the endpoint residuals, is
    /// within 0.2° of the true direction; the plain least squares of the lines is pulled off by
    /// the short segments' scattered lines.
    #[test]
    fn the_refit_weighs_segments_by_their_residual() {
        let k = Matrix3::new(700.0, 0.0, 320.0, 0.0, 700.0, 240.0, 0.0, 0.0, 1.0);
        let v = Point2::new(2200.0f64, 500.0);
        let truth = (k.try_inverse().unwrap() * Vector3::new(v.x, v.y, 1.0)).normalize();
        let mut rng = Pcg32::new(3);
        let mut segs = [Segment::new(Point2::origin(), Point2::new(1.0, 0.0)); 48];
        for (i, s) in segs.iter_mut().enumerate() {
            let a = Point2::new(rng.uniform(0.0, 400.0), rng.uniform(0.0, 480.0));
            let len = if i < 6 {
                250.0
            } else {
                rng.uniform(15.0, 30.0)
            };
            let b = a + (v - a).normalize() * len;
            let mut jitter = || 0.5 * rng.normal();
            *s = Segment::new(
                Point2::new(a.x + jitter(), a.y + jitter()),
                Point2::new(b.x + jitter(), b.y + jitter()),
            );
        }
        let angle = |p: &Point2h<f64>| {
            let d = (k.try_inverse().unwrap() * p.coords()).normalize();
            d.dot(&truth).abs().min(1.0).acos().to_degrees()
        };
        let lines: [Line2h<f64>; 48] = segs.map(|s| s.line().unwrap());
        let plain = angle(&crate::homogeneous::vanishing_point(&lines).unwrap());
        let fitted = angle(&fit_vanishing_point(&segs, |_| true).unwrap().point);
        assert!(fitted < 0.2, "reweighted {fitted}°, plain {plain}°");
        assert!(plain > 2.0 * fitted, "reweighted {fitted}°, plain {plain}°");
    }

    /// Segments whose endpoints differ but coincide to working precision have no line: they
    /// are left out (label `NO_POINT`) instead of joining a point's inliers and failing its
    /// fit, which stopped the search and left them labelled with a point never returned (the
    /// fuzz target found it).
    #[test]
    fn segments_without_a_line_are_left_out() {
        let mut segs = [Segment::new(Point2::new(0.0f32, 0.0), Point2::new(1.0, 1.0)); 14];
        for (i, s) in segs.iter_mut().enumerate() {
            let k = i as f32;
            *s = if i < 10 {
                let a = Point2::new(10.0 + 5.0 * k, 300.0 - 20.0 * k);
                Segment::new(a, a + (Point2::new(400.0, 100.0) - a) * 0.3)
            } else {
                // One f32 step apart at 1000: a length, but no line.
                let a = Point2::new(1000.0f32, 1000.0 + k);
                Segment::new(a, Point2::new(f32::from_bits(a.x.to_bits() + 1), a.y))
            };
        }
        assert!(segs[12].length() > 0.0 && segs[12].line().is_err());
        let params = VanishingConfig {
            min_length: 0.0,
            ..VanishingConfig::default()
        }
        .check()
        .unwrap();
        let (mut labels, mut index, mut mask) = ([0u8; 14], [0u32; 14], [false; 14]);
        let mut out = [VanishingPoint::default(); 3];
        let n = find_vanishing_points(&segs, &params, &mut labels, &mut index, &mut mask, &mut out)
            .unwrap();
        assert_eq!(n, 1);
        assert!(labels[..10].iter().all(|&l| l == 0), "{labels:?}");
        assert!(labels[10..].iter().all(|&l| l == NO_POINT), "{labels:?}");
        assert_eq!(out[0].segments, 10);
    }

    #[test]
    fn too_little_support_and_bad_input() {
        let (_, _, segs) = scene(0.3, 0);
        // Five segments cannot make an 8-segment point: none found, no error.
        let (_, n, labels) = find(&segs[..5]);
        assert_eq!(n, 0);
        assert!(labels[..5].iter().all(|&l| l == NO_POINT));
        let params = VanishingConfig::default().check().unwrap();
        let mut out = [VanishingPoint::default(); 3];
        let (mut labels, mut index, mut mask) = ([0u8; 4], [0u32; 4], [false; 4]);
        assert_eq!(
            find_vanishing_points(
                &segs[..5],
                &params,
                &mut labels,
                &mut index,
                &mut mask,
                &mut out
            ),
            Err(Error::LengthMismatch)
        );
        let mut bad = [segs[0]; 4];
        bad[2].a.x = f64::NAN;
        assert_eq!(
            find_vanishing_points(&bad, &params, &mut labels, &mut index, &mut mask, &mut out),
            Err(Error::NonFinite)
        );
        for (c, name) in [
            (
                VanishingConfig {
                    min_segments: 2,
                    ..VanishingConfig::default()
                },
                "min_segments",
            ),
            (
                VanishingConfig {
                    max_points: 0,
                    ..VanishingConfig::default()
                },
                "max_points",
            ),
            (
                VanishingConfig {
                    min_length: f64::NAN,
                    ..VanishingConfig::default()
                },
                "min_length",
            ),
        ] {
            assert_eq!(c.check(), Err(Error::InvalidParameter(name)));
        }
    }
}
