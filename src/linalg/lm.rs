//! A bounded Levenberg-Marquardt driver over streamed Jacobians.
//!
//! Minimises `C(p) = |r(p)|²` for a problem that can, at any `p`, linearise itself into a
//! [`Linearised`] system: the rows `[Jᵢ | -rᵢ]` streamed into a [`StreamingQr`] with
//! `P + 1` columns (the default, well-conditioned in `f32`), or the normal equations of an
//! exactly (integer) accumulated Jacobian ([`GramSystem`]). A step solves the damped system
//! `min |J δ + r|² + λ |D δ|²` with Marquardt's scaling `D = diag|J columns|`; it is accepted
//! when it lowers `C`, else `λ` grows tenfold (at most [`MAX_DAMPING_TRIES`] times per
//! iteration). Iteration stops when the relative decrease of `C` is below the problem's
//! [`LeastSquares::tolerance`] (`√ε` by default), no step is accepted, or the bound is reached.

use nalgebra::SVector;

use super::StreamingQr;
use crate::Result;
use crate::scalar::Real;

/// Damping increases tried per iteration before giving up.
pub const MAX_DAMPING_TRIES: u8 = 8;

/// A linearisation `J δ ≈ -r` at one parameter point, solvable for damped steps.
pub trait Linearised<T: Real, const P: usize> {
    /// The `δ` minimising `|J δ + r|² + λ |D δ|²`, `D = diag|J columns|`; `None` when the
    /// damped system is singular.
    fn damped_step(&self, lambda: T) -> Result<Option<SVector<T, P>>>;
}

/// The rows `[J | -r]` in a QR factor (`A = P + 1` columns): the damping rows `√λ D` are
/// appended to a copy of `R` and the step is read off by back-substitution, never forming
/// `JᵀJ`.
impl<T: Real, const P: usize, const A: usize> Linearised<T, P> for StreamingQr<T, A> {
    fn damped_step(&self, lambda: T) -> Result<Option<SVector<T, P>>> {
        const { assert!(A == P + 1, "the QR of an LM system has P + 1 columns") };
        let mut damped = *self;
        let sl = lambda.sqrt();
        for k in 0..P {
            let mut row = [T::zero(); A];
            if let Some(x) = row.get_mut(k) {
                *x = sl * self.r().column(k).norm();
            }
            damped.push_row(&row)?;
        }
        let r = damped.r();
        Ok(r.fixed_view::<P, P>(0, 0)
            .solve_upper_triangular(&r.fixed_view::<P, 1>(0, P)))
    }
}

/// The normal equations `G = JᵀJ`, `g = Jᵀr` of a Jacobian accumulated exactly (in integers,
/// [`crate::pose::refine_planar_integer`]), solved in `f64`: `(G + λ diag G) δ = -g` by
/// Cholesky. Forming `JᵀJ` squares the condition number; with `G` exact and the solve in
/// `f64` (`ε = 1.1e-16`), a `J` conditioned up to ~1e6 still gives `δ` to 1e-4, no worse than an
/// `f32` QR's `ε = 6e-8` times the condition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GramSystem<const P: usize> {
    /// `JᵀJ` (rows).
    pub gram: [[f64; P]; P],
    /// `Jᵀr`.
    pub gradient: [f64; P],
}

impl<const P: usize> Linearised<f64, P> for GramSystem<P> {
    fn damped_step(&self, lambda: f64) -> Result<Option<SVector<f64, P>>> {
        let mut a = self.gram;
        for (k, row) in a.iter_mut().enumerate() {
            if let Some(d) = row.get_mut(k) {
                *d *= 1.0 + lambda;
            }
        }
        Ok(cholesky_solve(&a, &self.gradient.map(|g| -g)).map(SVector::from))
    }
}

/// Solves `A x = b` for a symmetric positive definite `A` by `A = L Lᵀ`; `None` when a pivot
/// is not positive (`A` singular or indefinite in `f64`) or the solution is not finite.
fn cholesky_solve<const P: usize>(a: &[[f64; P]; P], b: &[f64; P]) -> Option<[f64; P]> {
    // L below the diagonal, 1 / L_jj apart: one division a column (soft-float division is the
    // costliest operation on the cores this serves).
    let mut l = [[0.0f64; P]; P];
    let mut inv = [0.0f64; P];
    for (i, ai) in a.iter().enumerate() {
        let (done, rest) = l.split_at_mut(i);
        let li = rest.first_mut()?;
        for ((j, lj), ij) in done.iter().enumerate().zip(&inv) {
            let s: f64 = li.iter().zip(lj).take(j).map(|(x, y)| x * y).sum();
            *li.get_mut(j)? = (ai.get(j)? - s) * ij;
        }
        let d = ai.get(i)? - li.iter().take(i).map(|x| x * x).sum::<f64>();
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        *inv.get_mut(i)? = 1.0 / libm::sqrt(d);
    }
    // L y = b, then Lᵀ x = y.
    let mut y = [0.0f64; P];
    for ((i, li), ii) in l.iter().enumerate().zip(&inv) {
        let s: f64 = li.iter().zip(&y).take(i).map(|(a, b)| a * b).sum();
        *y.get_mut(i)? = (b.get(i)? - s) * ii;
    }
    let mut x = [0.0f64; P];
    for i in (0..P).rev() {
        let s: f64 = l
            .iter()
            .zip(&x)
            .skip(i + 1)
            .map(|(lk, xk)| lk.get(i).map_or(0.0, |v| v * xk))
            .sum();
        *x.get_mut(i)? = (y.get(i)? - s) * inv.get(i)?;
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// A least-squares problem in `P` parameters.
pub trait LeastSquares<T: Real, const P: usize> {
    /// The parameter point (e.g. a rotation and a translation).
    type Params: Copy;
    /// The linearisation [`LeastSquares::linearise`] returns.
    type System: Linearised<T, P>;
    /// `C(p) = |r(p)|²`, or `None` where the model is undefined (a point behind the camera).
    fn cost(&self, p: &Self::Params) -> Option<T>;
    /// `J` and `r` at `p`, or `None` where the model is undefined.
    fn linearise(&self, p: &Self::Params) -> Option<Self::System>;
    /// `p ⊞ δ`: the parameter point moved by a step (on a manifold where needed).
    fn step(&self, p: &Self::Params, delta: &SVector<T, P>) -> Option<Self::Params>;
    /// Iteration stops when an accepted step lowers `C` by less than this fraction of it.
    fn tolerance(&self) -> T {
        T::EPSILON.sqrt()
    }
}

/// What [`minimise`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Minimum<T: Real, Params> {
    /// The best parameters found (the start when no step lowered the cost).
    pub params: Params,
    /// `C` at the start.
    pub initial_cost: T,
    /// `C` at `params`.
    pub final_cost: T,
    /// Accepted steps.
    pub iterations: u8,
}

/// Runs at most `max_iterations` Levenberg-Marquardt iterations from `start`.
///
/// Returns `None` when the cost is undefined at `start`.
pub fn minimise<T, Pr, const P: usize>(
    problem: &Pr,
    start: Pr::Params,
    max_iterations: u8,
) -> Result<Option<Minimum<T, Pr::Params>>>
where
    T: Real,
    Pr: LeastSquares<T, P>,
{
    let Some(mut cost) = problem.cost(&start) else {
        return Ok(None);
    };
    let initial_cost = cost;
    let mut p = start;
    let tol = problem.tolerance();
    let mut lambda = T::lit(1e-3);
    let mut iterations = 0u8;
    for _ in 0..max_iterations {
        let Some(base) = problem.linearise(&p) else {
            break;
        };
        let mut accepted = None;
        for _ in 0..MAX_DAMPING_TRIES {
            let candidate = base
                .damped_step(lambda)?
                .filter(|d| d.iter().all(|v| v.finite()))
                .and_then(|d| problem.step(&p, &d));
            let new_cost = candidate.as_ref().and_then(|c| problem.cost(c));
            match (candidate, new_cost) {
                (Some(c), Some(nc)) if nc < cost => {
                    accepted = Some((c, nc));
                    lambda = (lambda * T::lit(0.1)).max(T::lit(1e-12));
                    break;
                }
                _ => lambda *= T::lit(10.0),
            }
        }
        let Some((np, nc)) = accepted else {
            break;
        };
        let decrease = cost - nc;
        p = np;
        cost = nc;
        iterations = iterations.saturating_add(1);
        if decrease <= tol * cost {
            break;
        }
    }
    Ok(Some(Minimum {
        params: p,
        initial_cost,
        final_cost: cost,
        iterations,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock as least squares: r = (10 (y - x²), 1 - x), minimum 0 at (1, 1).
    struct Rosenbrock;
    impl LeastSquares<f64, 2> for Rosenbrock {
        type Params = SVector<f64, 2>;
        type System = StreamingQr<f64, 3>;
        fn cost(&self, p: &Self::Params) -> Option<f64> {
            let (a, b) = (10.0 * (p.y - p.x * p.x), 1.0 - p.x);
            Some(a * a + b * b)
        }
        fn linearise(&self, p: &Self::Params) -> Option<StreamingQr<f64, 3>> {
            let mut qr = StreamingQr::new();
            qr.push_row(&[-20.0 * p.x, 10.0, -(10.0 * (p.y - p.x * p.x))])
                .ok()?;
            qr.push_row(&[-1.0, 0.0, -(1.0 - p.x)]).ok()?;
            Some(qr)
        }
        fn step(&self, p: &Self::Params, d: &SVector<f64, 2>) -> Option<Self::Params> {
            Some(p + d)
        }
    }

    #[test]
    fn cholesky_solves_and_refuses_indefinite() {
        let m = nalgebra::SMatrix::<f64, 4, 4>::new(
            4.0, 1.0, 0.5, 0.0, 1.0, 3.0, 0.2, 0.1, 0.5, 0.2, 2.0, 0.3, 0.0, 0.1, 0.3, 1.0,
        );
        let b = [1.0, -2.0, 0.5, 3.0];
        let a: [[f64; 4]; 4] = core::array::from_fn(|i| core::array::from_fn(|j| m[(i, j)]));
        let x = cholesky_solve(&a, &b).unwrap();
        let r = m * nalgebra::SVector::from(x) - nalgebra::SVector::from(b);
        assert!(r.amax() < 1e-14, "{r}");
        let mut bad = a;
        bad[2][2] = -1.0;
        assert_eq!(cholesky_solve(&bad, &b), None);
    }

    #[test]
    fn solves_rosenbrock_within_the_bound() {
        let m = minimise(&Rosenbrock, SVector::<f64, 2>::new(-1.2, 1.0), 100)
            .unwrap()
            .unwrap();
        assert!(
            (m.params - SVector::<f64, 2>::new(1.0, 1.0)).amax() < 1e-6,
            "{m:?}"
        );
        assert!(m.final_cost < 1e-12 && m.initial_cost > 1.0);
        // The bound is honoured.
        let m = minimise(&Rosenbrock, SVector::<f64, 2>::new(-1.2, 1.0), 3)
            .unwrap()
            .unwrap();
        assert!(m.iterations <= 3);
    }
}
