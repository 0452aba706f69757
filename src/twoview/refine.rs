//! Levenberg-Marquardt refinement of `F` and `E` on the Sampson distance, on their manifolds.
//!
//! Both minimise `C = Σᵢ rᵢ²` over the pairs, `rᵢ = x₂ᵀ F x₁ / √g` with
//! `g = (F x₁)₁² + (F x₁)₂² + (Fᵀ x₂)₁² + (Fᵀ x₂)₂²` (pixels), through [`lm::minimise`]. The
//! gradient of one residual with respect to the entries of `F` is
//!
//! `∂r/∂F = (x₂ x₁ᵀ - (r/√g) (P F x₁ x₁ᵀ + x₂ (P Fᵀ x₂)ᵀ)) / √g`,  `P = diag(1, 1, 0)`,
//!
//! chained into each parameterisation:
//!
//! - `F`: 7 parameters in Hartley-normalised coordinates, `F̂ = U diag(1, s, 0) Vᵀ` with
//!   `U ← U exp([a]ₓ)`, `V ← V exp([b]ₓ)`, `s ← s + δs` — rank 2 by construction
//!   (Bartoli & Sturm's orthonormal representation);
//! - `E = [t]ₓ R`: 5 parameters, `R ← exp([ω]ₓ) R` and `t ← (t + B τ) / |t + B τ|` with `B` a
//!   basis of the tangent plane of the unit sphere at `t`.

use nalgebra::{Matrix3, Point2, Rotation3, SVector, Vector3};

use super::{Essential, Fundamental, RelativePose, lift};
use crate::camera::Intrinsics;
use crate::homography::Normalization;
use crate::linalg::{StreamingQr, lm, rotation_step, svd_jacobi};
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Outcome of [`refine_fundamental`] / [`refine_essential`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EpipolarRefinement<M, T: Real = f32> {
    /// The refined matrix (the input when no step lowered the cost).
    pub model: M,
    /// RMS Sampson distance before, `√(C / N)`, pixels.
    pub initial_rms: T,
    /// RMS Sampson distance after.
    pub final_rms: T,
    /// Accepted Levenberg-Marquardt steps.
    pub iterations: u8,
}

/// `(r, ∂r/∂F)` of one pair (see the module docs); `None` at an epipole.
fn sampson_gradient<T: Real>(
    f: &Matrix3<T>,
    x1: &Vector3<T>,
    x2: &Vector3<T>,
) -> Option<(T, Matrix3<T>)> {
    let l2 = f * x1;
    let l1 = f.transpose() * x2;
    let e = x2.dot(&l2);
    let g = l2.x * l2.x + l2.y * l2.y + l1.x * l1.x + l1.y * l1.y;
    if !above(g, T::zero()) {
        return None;
    }
    let sg = g.sqrt();
    let r = e / sg;
    let pl2 = Vector3::new(l2.x, l2.y, T::zero());
    let pl1 = Vector3::new(l1.x, l1.y, T::zero());
    let grad =
        (x2 * x1.transpose() - (pl2 * x1.transpose() + x2 * pl1.transpose()) * (r / sg)) / sg;
    (r.finite() && grad.iter().all(|v| v.finite())).then_some((r, grad))
}

fn validate<T, I>(pairs: I, min: usize) -> Result<T>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    let mut n = 0usize;
    for (a, b) in pairs {
        check_finite(&[a.x, a.y, b.x, b.y])?;
        n += 1;
    }
    if n < min {
        return Err(Error::TooFewPoints);
    }
    Ok(T::lit(n as f64))
}

/// The pairs of `x1`, `x2` selected by `mask` (all when `None`).
pub(crate) fn masked_pairs<'a, T: Real>(
    x1: &'a [Point2<T>],
    x2: &'a [Point2<T>],
    mask: Option<&'a [bool]>,
) -> Result<impl Iterator<Item = (Point2<T>, Point2<T>)> + Clone + 'a> {
    if x1.len() != x2.len() || mask.is_some_and(|m| m.len() != x1.len()) {
        return Err(Error::LengthMismatch);
    }
    Ok(x1
        .iter()
        .zip(x2.iter())
        .enumerate()
        .filter(move |(i, _)| mask.is_none_or(|m| m.get(*i).copied().unwrap_or(false)))
        .map(|(_, (a, b))| (*a, *b)))
}

/// Minimises the Sampson distance of the pairs (`mask[i]`, or all when `None`) over rank-2
/// fundamental matrices, at most `max_iterations` LM steps from `f`.
///
/// Errors: [`Error::LengthMismatch`]; [`Error::TooFewPoints`] below 8 pairs (7 parameters);
/// [`Error::NonFinite`]; [`Error::Degenerate`] when the points cannot be normalised or a
/// pair sits at an epipole of `f` (the cost is undefined at the start).
pub fn refine_fundamental<T: Real>(
    f: &Fundamental<T>,
    x1: &[Point2<T>],
    x2: &[Point2<T>],
    mask: Option<&[bool]>,
    max_iterations: u8,
) -> Result<EpipolarRefinement<Fundamental<T>, T>> {
    refine_fundamental_iter(f, masked_pairs(x1, x2, mask)?, max_iterations)
}

pub(crate) fn refine_fundamental_iter<T, I>(
    f: &Fundamental<T>,
    pairs: I,
    max_iterations: u8,
) -> Result<EpipolarRefinement<Fundamental<T>, T>>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    let n = validate(pairs.clone(), 8)?;
    let n1 = Normalization::from_points_iter(pairs.clone().map(|(a, _)| a))?;
    let n2 = Normalization::from_points_iter(pairs.clone().map(|(_, b)| b))?;
    // F̂ = T₂⁻ᵀ F T₁⁻¹ in normalised coordinates, then its orthonormal representation.
    let fhat = n2.inverse_matrix().transpose() * f.matrix() * n1.inverse_matrix();
    let svd = svd_jacobi(&fhat)?;
    let [s1, s2, _]: [T; 3] = svd.singular_values.into();
    if !above(s1, T::zero()) {
        return Err(Error::Degenerate);
    }
    let rot = |m: &Matrix3<T>| {
        let mut m = *m;
        if m.determinant() < T::zero() {
            m.column_mut(2).neg_mut();
        }
        Rotation3::from_matrix_unchecked(m)
    };
    let start = FParams {
        u: rot(&super::complete_rotation(&svd.u)),
        v: rot(&svd.v),
        s: s2 / s1,
    };
    let problem = FProblem {
        t1: n1.matrix(),
        t2: n2.matrix(),
        pairs,
    };
    let Some(m) = lm::minimise(&problem, start, max_iterations)? else {
        return Err(Error::Degenerate);
    };
    Ok(EpipolarRefinement {
        model: Fundamental::from_rank2(&problem.pixel_matrix(&m.params))?,
        initial_rms: (m.initial_cost / n).sqrt(),
        final_rms: (m.final_cost / n).sqrt(),
        iterations: m.iterations,
    })
}

#[derive(Debug, Clone, Copy)]
struct FParams<T: Real> {
    u: Rotation3<T>,
    v: Rotation3<T>,
    s: T,
}

struct FProblem<T: Real, I> {
    t1: Matrix3<T>,
    t2: Matrix3<T>,
    pairs: I,
}

impl<T: Real, I> FProblem<T, I> {
    fn d(s: T) -> Matrix3<T> {
        Matrix3::from_diagonal(&Vector3::new(T::one(), s, T::zero()))
    }

    /// `F = T₂ᵀ U diag(1, s, 0) Vᵀ T₁` (pixels).
    fn pixel_matrix(&self, p: &FParams<T>) -> Matrix3<T> {
        self.t2.transpose() * p.u.matrix() * Self::d(p.s) * p.v.matrix().transpose() * self.t1
    }
}

fn sum_sq<T: Real, I>(f: &Matrix3<T>, pairs: I) -> Option<T>
where
    I: Iterator<Item = (Point2<T>, Point2<T>)>,
{
    let mut c = T::zero();
    for (a, b) in pairs {
        c += super::sampson_distance_sq(f, &a, &b)?;
    }
    c.finite().then_some(c)
}

impl<T, I> lm::LeastSquares<T, 7> for FProblem<T, I>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    type Params = FParams<T>;
    type System = StreamingQr<T, 8>;

    fn cost(&self, p: &FParams<T>) -> Option<T> {
        sum_sq(&self.pixel_matrix(p), self.pairs.clone())
    }

    fn linearise(&self, p: &FParams<T>) -> Option<StreamingQr<T, 8>> {
        let f = self.pixel_matrix(p);
        let (u, v) = (p.u.matrix(), p.v.matrix());
        let d = Self::d(p.s);
        let basis = [Vector3::x(), Vector3::y(), Vector3::z()].map(|e| e.cross_matrix());
        let mut qr = StreamingQr::new();
        for (a, b) in self.pairs.clone() {
            let (r, g) = sampson_gradient(&f, &lift(&a), &lift(&b))?;
            // ⟨G, T₂ᵀ dF̂ T₁⟩ = ⟨T₂ G T₁ᵀ, dF̂⟩, and ⟨G', U M Vᵀ⟩ = ⟨Uᵀ G' V, M⟩.
            let h = u.transpose() * self.t2 * g * self.t1.transpose() * v;
            let mut row = [T::zero(); 8];
            for (k, ek) in basis.iter().enumerate() {
                if let Some(x) = row.get_mut(k) {
                    *x = h.dot(&(ek * d));
                }
                if let Some(x) = row.get_mut(k + 3) {
                    *x = -h.dot(&(d * ek));
                }
            }
            row[6] = h.m22;
            row[7] = -r;
            qr.push_row(&row).ok()?;
        }
        Some(qr)
    }

    fn step(&self, p: &FParams<T>, delta: &SVector<T, 7>) -> Option<FParams<T>> {
        let [a1, a2, a3, b1, b2, b3, ds]: [T; 7] = (*delta).into();
        Some(FParams {
            u: p.u * rotation_step(&Vector3::new(a1, a2, a3)),
            v: p.v * rotation_step(&Vector3::new(b1, b2, b3)),
            s: p.s + ds,
        })
    }
}

/// Minimises the Sampson distance in pixels of the pairs (`mask[i]`, or all when `None`) over
/// essential matrices `E = [t]ₓ R` (5 parameters), with `F = K₂⁻ᵀ E K₁⁻¹`, at most
/// `max_iterations` LM steps from `e`.
///
/// Errors: as [`refine_fundamental`], with at least 5 pairs.
pub fn refine_essential<T: Real>(
    e: &Essential<T>,
    k1: &Intrinsics<T>,
    k2: &Intrinsics<T>,
    x1: &[Point2<T>],
    x2: &[Point2<T>],
    mask: Option<&[bool]>,
    max_iterations: u8,
) -> Result<EpipolarRefinement<Essential<T>, T>> {
    refine_essential_iter(e, k1, k2, masked_pairs(x1, x2, mask)?, max_iterations)
}

pub(crate) fn refine_essential_iter<T, I>(
    e: &Essential<T>,
    k1: &Intrinsics<T>,
    k2: &Intrinsics<T>,
    pairs: I,
    max_iterations: u8,
) -> Result<EpipolarRefinement<Essential<T>, T>>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    let n = validate(pairs.clone(), 5)?;
    // Any of the four decompositions reproduces E (up to sign): the cost does not care.
    let [start, ..] = e.decompose()?;
    let problem = EProblem {
        k1inv: k1.inverse_matrix(),
        k2inv: k2.inverse_matrix(),
        pairs,
    };
    let Some(m) = lm::minimise(&problem, start, max_iterations)? else {
        return Err(Error::Degenerate);
    };
    Ok(EpipolarRefinement {
        model: Essential::from_pose(&m.params)?,
        initial_rms: (m.initial_cost / n).sqrt(),
        final_rms: (m.final_cost / n).sqrt(),
        iterations: m.iterations,
    })
}

/// An orthonormal basis of the plane orthogonal to the unit vector `t`.
pub(crate) fn tangent_basis<T: Real>(t: &Vector3<T>) -> (Vector3<T>, Vector3<T>) {
    let (ax, ay, az) = (t.x.abs(), t.y.abs(), t.z.abs());
    let a = if ax <= ay && ax <= az {
        Vector3::x()
    } else if ay <= az {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let b1 = t.cross(&a);
    let b1 = b1 / b1.norm();
    (b1, t.cross(&b1))
}

struct EProblem<T: Real, I> {
    k1inv: Matrix3<T>,
    k2inv: Matrix3<T>,
    pairs: I,
}

impl<T: Real, I> EProblem<T, I> {
    fn pixel_matrix(&self, p: &RelativePose<T>) -> Matrix3<T> {
        self.k2inv.transpose() * p.translation().cross_matrix() * p.rotation().matrix() * self.k1inv
    }
}

impl<T, I> lm::LeastSquares<T, 5> for EProblem<T, I>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    type Params = RelativePose<T>;
    type System = StreamingQr<T, 6>;

    fn cost(&self, p: &RelativePose<T>) -> Option<T> {
        sum_sq(&self.pixel_matrix(p), self.pairs.clone())
    }

    fn linearise(&self, p: &RelativePose<T>) -> Option<StreamingQr<T, 6>> {
        let f = self.pixel_matrix(p);
        let r = *p.rotation().matrix();
        let t = p.translation();
        let tx = t.cross_matrix();
        let (b1, b2) = tangent_basis(&t);
        let basis = [Vector3::x(), Vector3::y(), Vector3::z()].map(|e| e.cross_matrix());
        let mut qr = StreamingQr::new();
        for (a, b) in self.pairs.clone() {
            let (res, g) = sampson_gradient(&f, &lift(&a), &lift(&b))?;
            // ⟨G, K₂⁻ᵀ dE K₁⁻¹⟩ = ⟨K₂⁻¹ G K₁⁻ᵀ, dE⟩.
            let ge = self.k2inv * g * self.k1inv.transpose();
            let mut row = [T::zero(); 6];
            for (x, ek) in row.iter_mut().zip(basis.iter()) {
                *x = ge.dot(&(tx * ek * r));
            }
            row[3] = ge.dot(&(b1.cross_matrix() * r));
            row[4] = ge.dot(&(b2.cross_matrix() * r));
            row[5] = -res;
            qr.push_row(&row).ok()?;
        }
        Some(qr)
    }

    fn step(&self, p: &RelativePose<T>, delta: &SVector<T, 5>) -> Option<RelativePose<T>> {
        let [w1, w2, w3, s1, s2]: [T; 5] = (*delta).into();
        let t = p.translation();
        let (b1, b2) = tangent_basis(&t);
        let moved = t + b1 * s1 + b2 * s2;
        let n = moved.norm();
        if !above(n, T::zero()) {
            return None;
        }
        let r = rotation_step(&Vector3::new(w1, w2, w3)) * p.rotation();
        RelativePose::new(r, moved / n).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    #[test]
    fn sampson_gradient_matches_finite_differences() {
        let f = Matrix3::<f64>::new(1e-6, -2e-5, 3e-3, 2.5e-5, 1e-6, -0.02, -4e-3, 0.021, 1.0);
        let x1 = Vector3::new(120.0, 300.0, 1.0);
        let x2 = Vector3::new(130.0, 290.0, 1.0);
        let (r, g) = sampson_gradient(&f, &x1, &x2).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let h = 1e-7 * f[(i, j)].abs().max(1e-6);
                let mut fp = f;
                fp[(i, j)] += h;
                let mut fm = f;
                fm[(i, j)] -= h;
                let rp = sampson_gradient(&fp, &x1, &x2).unwrap().0;
                let rm = sampson_gradient(&fm, &x1, &x2).unwrap().0;
                let fd = (rp - rm) / (2.0 * h);
                assert!(
                    (fd - g[(i, j)]).abs() < 1e-5 * (1.0 + g.amax()),
                    "{i}{j}: {fd} vs {} (r {r})",
                    g[(i, j)]
                );
            }
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        use lm::LeastSquares;
        let mut g = Pcg32::new(3);
        let pairs: [(Point2<f64>, Point2<f64>); 1] = [(
            Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)),
            Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)),
        )];
        let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0).unwrap();
        let pose =
            RelativePose::from_rodrigues(Vector3::new(0.1, 0.2, -0.1), Vector3::new(0.6, 0.0, 0.8))
                .unwrap();
        let ep = EProblem {
            k1inv: k.inverse_matrix(),
            k2inv: k.inverse_matrix(),
            pairs: pairs.iter().copied(),
        };
        let res = |p: &RelativePose<f64>| {
            let f = ep.pixel_matrix(p);
            sampson_gradient(&f, &lift(&pairs[0].0), &lift(&pairs[0].1))
                .unwrap()
                .0
        };
        let gram = ep.linearise(&pose).unwrap().gram();
        let mut jac = SVector::<f64, 5>::zeros();
        for k in 0..5 {
            let mut d = SVector::<f64, 5>::zeros();
            d[k] = 1e-6;
            jac[k] =
                (res(&ep.step(&pose, &d).unwrap()) - res(&ep.step(&pose, &(-d)).unwrap())) / 2e-6;
        }
        let jtj = jac * jac.transpose();
        let rel = (gram.fixed_view::<5, 5>(0, 0) - jtj).amax() / jtj.amax();
        assert!(rel < 1e-5, "E jacobian {rel}");

        let fp = FProblem {
            t1: Matrix3::new(0.01, 0.0, -3.0, 0.0, 0.01, -2.0, 0.0, 0.0, 1.0),
            t2: Matrix3::new(0.012, 0.0, -3.3, 0.0, 0.012, -2.5, 0.0, 0.0, 1.0),
            pairs: pairs.iter().copied(),
        };
        let start = FParams {
            u: Rotation3::new(Vector3::new(0.3, -0.2, 0.5)),
            v: Rotation3::new(Vector3::new(-0.1, 0.4, 0.2)),
            s: 0.7,
        };
        let resf = |p: &FParams<f64>| {
            sampson_gradient(&fp.pixel_matrix(p), &lift(&pairs[0].0), &lift(&pairs[0].1))
                .unwrap()
                .0
        };
        let gram = fp.linearise(&start).unwrap().gram();
        let mut jac = SVector::<f64, 7>::zeros();
        for k in 0..7 {
            let mut d = SVector::<f64, 7>::zeros();
            d[k] = 1e-6;
            jac[k] = (resf(&fp.step(&start, &d).unwrap()) - resf(&fp.step(&start, &(-d)).unwrap()))
                / 2e-6;
        }
        let jtj = jac * jac.transpose();
        let rel = (gram.fixed_view::<7, 7>(0, 0) - jtj).amax() / jtj.amax();
        assert!(rel < 1e-5, "F jacobian {rel}");
    }
}
