//! Levenberg-Marquardt refinement of a homography on the symmetric transfer error.

use nalgebra::{Matrix3, Point2, SVector, Vector2, Vector3};

use super::normalize::Normalization;
use super::{Homography, adjugate};
use crate::linalg::{StreamingQr, lm};
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};

/// Outcome of [`refine`] / [`refine_masked`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Refinement<T: Real = f32> {
    /// The refined homography (the input when no step lowered the cost).
    pub homography: Homography<T>,
    /// RMS symmetric transfer error before, `√(C / 2N)` with `C` as in [`refine`], in pixels.
    pub initial_rms: T,
    /// RMS symmetric transfer error after.
    pub final_rms: T,
    /// Accepted Levenberg-Marquardt steps.
    pub iterations: u8,
}

/// Minimises the symmetric transfer error over all pairs,
///
/// `C(H) = Σᵢ |dstᵢ - π(H srcᵢ)|² + |srcᵢ - π(H⁻¹ dstᵢ)|²`,  `π(x, y, w) = (x/w, y/w)`,
///
/// by at most `max_iterations` Levenberg-Marquardt steps, starting from `h` (e.g. a DLT).
///
/// The 8 parameters are the entries of `H_n = T_dst H T_src⁻¹ / (…)₃₃` in Hartley-normalised
/// coordinates, where fixing `h₃₃ = 1` is safe and the Jacobian well scaled. Each step streams
/// the `4N x 8` Jacobian rows, augmented with the residual, through a [`StreamingQr`] (no
/// normal equations), then solves `[R; √λ D] δ = [c; 0]` with Marquardt's scaling
/// `D = diag|J columns|`; a step is accepted if it lowers `C`, else `λ` grows tenfold (at most
/// 8 times per step). Stops when the relative decrease of `C` is below `√ε`.
///
/// Errors: as [`super::dlt()`] for the point sets; [`Error::AtInfinity`] when the starting `h`
/// sends a pair to infinity (it is not a plausible start); [`Error::Degenerate`] when
/// `h₃₃ ≈ 0` in normalised coordinates (the origin of the normalised frame, the centroid of
/// `src`, maps to infinity).
pub fn refine<T: Real>(
    h: &Homography<T>,
    src: &[Point2<T>],
    dst: &[Point2<T>],
    max_iterations: u8,
) -> Result<Refinement<T>> {
    if src.len() != dst.len() {
        return Err(Error::LengthMismatch);
    }
    lm(
        h,
        src.iter().zip(dst.iter()).map(|(s, d)| (*s, *d)),
        max_iterations,
    )
}

/// [`refine`] on the pairs with `mask[i] == true` (e.g. RANSAC inliers).
pub fn refine_masked<T: Real>(
    h: &Homography<T>,
    src: &[Point2<T>],
    dst: &[Point2<T>],
    mask: &[bool],
    max_iterations: u8,
) -> Result<Refinement<T>> {
    if src.len() != dst.len() || src.len() != mask.len() {
        return Err(Error::LengthMismatch);
    }
    lm(
        h,
        src.iter()
            .zip(dst.iter())
            .zip(mask.iter())
            .filter(|(_, m)| **m)
            .map(|((s, d), _)| (*s, *d)),
        max_iterations,
    )
}

/// The problem in normalised coordinates.
struct Problem<T: Real> {
    ns: Normalization<T>,
    nd: Normalization<T>,
    /// `1 / s_dst`, `1 / s_src`: back to pixels.
    to_px_dst: T,
    to_px_src: T,
}

impl<T: Real> Problem<T> {
    /// `H_n` from the 8 parameters (`h₃₃ = 1`).
    fn matrix(p: &SVector<T, 8>) -> Matrix3<T> {
        let [a, b, c, d, e, f, g, h]: [T; 8] = (*p).into();
        Matrix3::new(a, b, c, d, e, f, g, h, T::one())
    }

    /// Cost `C` in pixels², or `None` if `H_n` is singular or a point maps to infinity.
    fn cost<I>(&self, hn: &Matrix3<T>, pairs: I) -> Option<T>
    where
        I: Iterator<Item = (Point2<T>, Point2<T>)>,
    {
        let inv = inverse(hn)?;
        let mut c = T::zero();
        for (s, d) in pairs {
            let (x, u) = (self.ns.apply(&s), self.nd.apply(&d));
            let f = project(&(hn * x.to_homogeneous()))? - u.coords;
            let b = project(&(inv * u.to_homogeneous()))? - x.coords;
            c += f.norm_squared() * self.to_px_dst * self.to_px_dst
                + b.norm_squared() * self.to_px_src * self.to_px_src;
        }
        c.finite().then_some(c)
    }

    /// Pushes the 4 rows `[J | -r]` of every pair; `None` on a point at infinity.
    fn linearise<I>(&self, hn: &Matrix3<T>, pairs: I) -> Option<StreamingQr<T, 9>>
    where
        I: Iterator<Item = (Point2<T>, Point2<T>)>,
    {
        let z = inverse(hn)?;
        let zc: [Vector3<T>; 3] = [z.column(0).into(), z.column(1).into(), z.column(2).into()];
        let (o, zero) = (T::one(), T::zero());
        let mut qr = StreamingQr::<T, 9>::new();
        for (s, d) in pairs {
            let (x, u) = (self.ns.apply(&s), self.nd.apply(&d));
            // Forward: v = H_n x, residual π(v) - u; ∂π(v)/∂h_ij = (row i of dπ/dv) x_j.
            let v = hn * x.to_homogeneous();
            let q = project(&v)?;
            let (iw, k) = (o / v.z, self.to_px_dst);
            let r = (q - u.coords) * k;
            let (a, b) = (x.x * iw * k, x.y * iw * k);
            let c = iw * k;
            let rows = [
                [a, b, c, zero, zero, zero, -q.x * a, -q.x * b, -r.x],
                [zero, zero, zero, a, b, c, -q.y * a, -q.y * b, -r.y],
            ];
            for row in &rows {
                qr.push_row(row).ok()?;
            }
            // Backward: y = Z u, Z = H_n⁻¹, dy = -y_j Z e_i for parameter h_ij, so
            // ∂π(y)/∂h_ij = -y_j g_i with g_i = dπ/dy · (column i of Z).
            let y = z * u.to_homogeneous();
            let p = project(&y)?;
            let (iw, k) = (o / y.z, self.to_px_src);
            let r = (p - x.coords) * k;
            let g = zc.map(|col| {
                Vector2::new((col.x - p.x * col.z) * iw, (col.y - p.y * col.z) * iw) * k
            });
            let mut jx = [zero; 9];
            let mut jy = [zero; 9];
            let params = g.iter().flat_map(|gi| y.iter().map(move |yj| -*gi * *yj));
            for ((ex, ey), dj) in jx.iter_mut().zip(jy.iter_mut()).zip(params.take(8)) {
                *ex = dj.x;
                *ey = dj.y;
            }
            if let (Some(ex), Some(ey)) = (jx.last_mut(), jy.last_mut()) {
                *ex = -r.x;
                *ey = -r.y;
            }
            qr.push_row(&jx).ok()?;
            qr.push_row(&jy).ok()?;
        }
        Some(qr)
    }
}

/// `π(v) = (v₁/v₃, v₂/v₃)`, `None` when `|v₃| ≤ ε max(|v₁|, |v₂|)` or the result overflows.
fn project<T: Real>(v: &Vector3<T>) -> Option<Vector2<T>> {
    if !super::above(v.z.abs(), T::EPSILON * v.x.abs().max(v.y.abs())) {
        return None;
    }
    let p = Vector2::new(v.x / v.z, v.y / v.z);
    (p.x.finite() && p.y.finite()).then_some(p)
}

/// `M⁻¹ = adj(M) / det(M)`, `None` if singular or not finite.
fn inverse<T: Real>(m: &Matrix3<T>) -> Option<Matrix3<T>> {
    let det = m.determinant();
    if det == T::zero() {
        return None;
    }
    let inv = adjugate(m) / det;
    inv.iter().all(|v| v.finite()).then_some(inv)
}

fn lm<T, I>(h: &Homography<T>, pairs: I, max_iterations: u8) -> Result<Refinement<T>>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    if pairs.clone().take(4).count() < 4 {
        return Err(Error::TooFewPoints);
    }
    for (s, d) in pairs.clone() {
        check_finite(&[s.x, s.y, d.x, d.y])?;
    }
    let ns = Normalization::from_points_iter(pairs.clone().map(|(s, _)| s))?;
    let nd = Normalization::from_points_iter(pairs.clone().map(|(_, d)| d))?;
    let problem = Problem {
        ns,
        nd,
        to_px_dst: T::one() / nd.scale,
        to_px_src: T::one() / ns.scale,
    };
    let hn = nd.matrix() * h.matrix() * ns.inverse_matrix();
    if !super::above(hn.m33.abs(), T::EPSILON.sqrt() * hn.amax()) {
        return Err(Error::Degenerate);
    }
    let hn = hn / hn.m33;
    // The first eight entries, row-major (an array: `from_iterator` asserts the count).
    let start = SVector::<T, 8>::from([
        hn.m11, hn.m12, hn.m13, hn.m21, hn.m22, hn.m23, hn.m31, hn.m32,
    ]);
    let count = T::lit(pairs.clone().count() as f64);
    let rms = |c: T| (c / (count + count)).sqrt();
    let ls = Transfer { problem, pairs };
    let Some(m) = lm::minimise(&ls, start, max_iterations)? else {
        return Err(Error::AtInfinity);
    };
    let homography = Homography::from_matrix(
        &(ls.problem.nd.inverse_matrix() * Problem::matrix(&m.params) * ls.problem.ns.matrix()),
    )?;
    Ok(Refinement {
        homography,
        initial_rms: rms(m.initial_cost),
        final_rms: rms(m.final_cost),
        iterations: m.iterations,
    })
}

/// The symmetric transfer problem over a set of pairs, for [`lm::minimise`].
struct Transfer<T: Real, I> {
    problem: Problem<T>,
    pairs: I,
}

impl<T, I> lm::LeastSquares<T, 8> for Transfer<T, I>
where
    T: Real,
    I: Iterator<Item = (Point2<T>, Point2<T>)> + Clone,
{
    type Params = SVector<T, 8>;
    type System = StreamingQr<T, 9>;
    fn cost(&self, p: &Self::Params) -> Option<T> {
        self.problem.cost(&Problem::matrix(p), self.pairs.clone())
    }
    fn linearise(&self, p: &Self::Params) -> Option<StreamingQr<T, 9>> {
        self.problem
            .linearise(&Problem::matrix(p), self.pairs.clone())
    }
    fn step(&self, p: &Self::Params, delta: &SVector<T, 8>) -> Option<Self::Params> {
        Some(p + delta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::homography::dlt;
    use crate::rng::Pcg32;

    fn truth() -> Matrix3<f64> {
        Matrix3::new(0.9, -0.12, 35.0, 0.08, 1.05, -20.0, 1.5e-4, -2e-4, 1.0)
    }

    fn apply(h: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
        Point2::from_homogeneous(h * p.to_homogeneous()).unwrap()
    }

    /// Symmetric transfer cost computed directly in pixels.
    fn cost(h: &Matrix3<f64>, src: &[Point2<f64>], dst: &[Point2<f64>]) -> f64 {
        let inv = h.try_inverse().unwrap();
        src.iter()
            .zip(dst)
            .map(|(s, d)| (apply(h, s) - d).norm_squared() + (apply(&inv, d) - s).norm_squared())
            .sum()
    }

    fn noisy(g: &mut Pcg32) -> ([Point2<f64>; 40], [Point2<f64>; 40]) {
        let src: [Point2<f64>; 40] =
            core::array::from_fn(|_| Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)));
        let dst = src.map(|p| {
            let q = apply(&truth(), &p);
            Point2::new(q.x + 0.5 * g.normal(), q.y + 0.5 * g.normal())
        });
        (src, dst)
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let mut g = Pcg32::new(41);
        let (src, dst) = noisy(&mut g);
        let ns = Normalization::from_points(&src).unwrap();
        let nd = Normalization::from_points(&dst).unwrap();
        let problem = Problem {
            ns,
            nd,
            to_px_dst: 1.0 / nd.scale,
            to_px_src: 1.0 / ns.scale,
        };
        let hn = nd.matrix() * truth() * ns.inverse_matrix();
        let hn = hn / hn.m33;
        let p = SVector::<f64, 8>::from_iterator(hn.transpose().iter().copied().take(8));
        let pairs = || src.iter().zip(dst.iter()).map(|(s, d)| (*s, *d)).take(1);
        // With one pair, RᵀR = [J -r]ᵀ[J -r]: compare JᵀJ and Jᵀr with finite differences.
        let qr = problem.linearise(&Problem::matrix(&p), pairs()).unwrap();
        let gram = qr.gram();
        // Residual vector of the single pair, in the same order as the rows.
        let resid = |p: &SVector<f64, 8>| {
            let hn = Problem::matrix(p);
            let inv = hn.try_inverse().unwrap();
            let (s, d) = pairs().next().unwrap();
            let (x, u) = (ns.apply(&s), nd.apply(&d));
            let f = (project(&(hn * x.to_homogeneous())).unwrap() - u.coords) / nd.scale;
            let b = (project(&(inv * u.to_homogeneous())).unwrap() - x.coords) / ns.scale;
            nalgebra::Vector4::new(f.x, f.y, b.x, b.y)
        };
        let mut j = nalgebra::SMatrix::<f64, 4, 8>::zeros();
        for k in 0..8 {
            let mut dp = SVector::<f64, 8>::zeros();
            dp[k] = 1e-7;
            j.set_column(k, &((resid(&(p + dp)) - resid(&(p - dp))) / 2e-7));
        }
        let jtj = j.transpose() * j;
        let jtr = -(j.transpose() * resid(&p));
        assert!((gram.fixed_view::<8, 8>(0, 0) - jtj).amax() < 1e-6 * jtj.amax());
        assert!((gram.fixed_view::<8, 1>(0, 8) - jtr).amax() < 1e-6 * jtj.amax().sqrt());
    }

    #[test]
    fn lowers_the_symmetric_transfer_error() {
        let mut g = Pcg32::new(42);
        let (src, dst) = noisy(&mut g);
        let h0 = dlt(&src, &dst).unwrap();
        let r = refine(&h0, &src, &dst, 20).unwrap();
        let c0 = cost(h0.matrix(), &src, &dst);
        let c1 = cost(r.homography.matrix(), &src, &dst);
        assert!(c1 < c0, "{c1} !< {c0}");
        assert!(r.iterations >= 1);
        assert!((r.initial_rms - (c0 / 80.0).sqrt()).abs() < 1e-9);
        assert!((r.final_rms - (c1 / 80.0).sqrt()).abs() < 1e-9);
        // A stationary point: further refinement changes nothing measurable.
        let r2 = refine(&r.homography, &src, &dst, 20).unwrap();
        assert!((r2.final_rms - r.final_rms).abs() < 1e-6 * r.final_rms);
        // From a perturbed start it reaches the same minimum.
        let mut m = *h0.matrix();
        m.m13 += 3.0;
        m.m31 += 5e-5;
        let r3 = refine(&Homography::from_matrix(&m).unwrap(), &src, &dst, 50).unwrap();
        assert!((r3.final_rms - r.final_rms).abs() < 1e-6 * r.final_rms);
        // f32 reaches it too, within f32 precision.
        let s32 = src.map(|p| p.cast::<f32>());
        let d32 = dst.map(|p| p.cast::<f32>());
        let h32 = dlt(&s32, &d32).unwrap();
        let r32 = refine(&h32, &s32, &d32, 20).unwrap();
        assert!(((r32.final_rms as f64) - r.final_rms).abs() < 1e-3 * r.final_rms);
    }

    #[test]
    fn exact_data_and_errors() {
        let mut g = Pcg32::new(43);
        let src: [Point2<f64>; 10] =
            core::array::from_fn(|_| Point2::new(g.uniform(0.0, 640.0), g.uniform(0.0, 480.0)));
        let dst = src.map(|p| apply(&truth(), &p));
        let h = Homography::from_matrix(&truth()).unwrap();
        let r = refine(&h, &src, &dst, 10).unwrap();
        assert!(r.final_rms < 1e-9);
        assert!(r.final_rms <= r.initial_rms);
        let mut mask = [true; 10];
        mask[..7].iter_mut().for_each(|m| *m = false);
        assert_eq!(
            refine_masked(&h, &src, &dst, &mask, 10).unwrap_err(),
            Error::TooFewPoints
        );
        assert_eq!(
            refine(&h, &src, &dst[..9], 10).unwrap_err(),
            Error::LengthMismatch
        );
        let mut bad = dst;
        bad[2].x = f64::NAN;
        assert_eq!(refine(&h, &src, &bad, 10).unwrap_err(), Error::NonFinite);
    }
}
