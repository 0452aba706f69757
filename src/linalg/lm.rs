//! A bounded Levenberg-Marquardt driver over streamed Jacobians.
//!
//! Minimises `C(p) = |r(p)|²` for a problem that can, at any `p`, stream the rows
//! `[Jᵢ | -rᵢ]` of its linearisation into a [`StreamingQr`] with `A = P + 1` columns. A step
//! solves `[R; √λ D] δ = [c; 0]` (Marquardt's scaling `D = diag|J columns|`) by a second QR
//! of `R` and the damping rows, never forming `JᵀJ`; it is accepted when it lowers `C`, else
//! `λ` grows tenfold (at most [`MAX_DAMPING_TRIES`] times per iteration). Iteration stops when
//! the relative decrease of `C` is below `√ε`, no step is accepted, or the bound is reached.

use nalgebra::SVector;

use super::StreamingQr;
use crate::Result;
use crate::scalar::Real;

/// Damping increases tried per iteration before giving up.
pub const MAX_DAMPING_TRIES: u8 = 8;

/// A least-squares problem in `P` parameters; `A` must be `P + 1` (the augmented column).
pub trait LeastSquares<T: Real, const P: usize, const A: usize> {
    /// The parameter point (e.g. a rotation and a translation).
    type Params: Copy;
    /// `C(p) = |r(p)|²`, or `None` where the model is undefined (a point behind the camera).
    fn cost(&self, p: &Self::Params) -> Option<T>;
    /// The rows `[Jᵢ | -rᵢ]` at `p`, or `None` where the model is undefined.
    fn linearise(&self, p: &Self::Params) -> Option<StreamingQr<T, A>>;
    /// `p ⊞ δ`: the parameter point moved by a step (on a manifold where needed).
    fn step(&self, p: &Self::Params, delta: &SVector<T, P>) -> Option<Self::Params>;
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
pub fn minimise<T, Pr, const P: usize, const A: usize>(
    problem: &Pr,
    start: Pr::Params,
    max_iterations: u8,
) -> Result<Option<Minimum<T, Pr::Params>>>
where
    T: Real,
    Pr: LeastSquares<T, P, A>,
{
    let Some(mut cost) = problem.cost(&start) else {
        return Ok(None);
    };
    let initial_cost = cost;
    let mut p = start;
    let tol = T::EPSILON.sqrt();
    let mut lambda = T::lit(1e-3);
    let mut iterations = 0u8;
    for _ in 0..max_iterations {
        let Some(base) = problem.linearise(&p) else {
            break;
        };
        let scale: [T; P] = core::array::from_fn(|k| base.r().column(k).norm());
        let mut accepted = None;
        for _ in 0..MAX_DAMPING_TRIES {
            let mut damped = base;
            let sl = lambda.sqrt();
            for (k, d) in scale.iter().enumerate() {
                let mut row = [T::zero(); A];
                if let Some(x) = row.get_mut(k) {
                    *x = sl * *d;
                }
                damped.push_row(&row)?;
            }
            let r = damped.r();
            let step = r
                .fixed_view::<P, P>(0, 0)
                .solve_upper_triangular(&r.fixed_view::<P, 1>(0, P));
            let candidate = step
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
    impl LeastSquares<f64, 2, 3> for Rosenbrock {
        type Params = SVector<f64, 2>;
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
