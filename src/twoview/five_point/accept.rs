//! Which candidates of a five-point solve are kept: the epipolar check and the removal of
//! duplicates, into the bounded list of solutions.

use heapless::Vec;

use super::precision::Tolerances;
use crate::scalar::{Real, above, larger};
use crate::twoview::Essential;

/// Most essential matrices [`five_point`](super::five_point) returns.
pub const MAX_FIVE_POINT_SOLUTIONS: usize = 10;

/// Appends `e` to `out` when it meets the five epipolar equations to `tol.solution` (unit
/// rows) and is not within `tol.duplicate` of a solution already there.
pub(super) fn keep<T: Real>(
    e: Essential<T>,
    rows5: &[[T; 9]; 5],
    tol: &Tolerances<T>,
    out: &mut Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>,
) {
    let et = e.matrix().transpose();
    let worst = rows5.iter().fold(T::zero(), |w, r| {
        let v = r
            .iter()
            .zip(et.iter())
            .fold(T::zero(), |acc, (a, b)| acc + *a * *b);
        larger(w, v.abs())
    });
    if !above(tol.solution, worst) {
        return;
    }
    let known = out.iter().any(|o| {
        let d = (o.matrix() - e.matrix())
            .amax()
            .min((o.matrix() + e.matrix()).amax());
        !above(d, tol.duplicate)
    });
    if !known || tol.duplicate == T::zero() {
        let _ = out.push(e);
    }
}
