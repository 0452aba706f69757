//! The polish of a root of the ten cubics: Gauss-Newton on the reduced cubics (the `f64`
//! solver) and the chord method on the constraints evaluated from `E` itself (the `f32`
//! solver).

use nalgebra::Matrix3;

use super::monomial::{EXPONENTS, Poly};
use crate::linalg::StreamingQr;
use crate::scalar::{Real, above, larger};

/// Gauss-Newton steps polishing a root on the ten cubics.
const POLISH_ITERATIONS: u8 = 4;

/// `[1, v, v², v³]` and the derivatives `[0, 1, 2v, 3v²]`, as `Π v` and `k Π v` products
/// from `1`: the order of products the `f64` results depend on to the bit.
fn powers<T: Real>(v: T) -> ([T; 4], [T; 4]) {
    let one = T::one();
    let p = [one, one * v, one * v * v, one * v * v * v];
    let [p0, p1, p2, _] = p;
    (
        p,
        [
            T::zero(),
            T::lit(1.0) * p0,
            T::lit(2.0) * p1,
            T::lit(3.0) * p2,
        ],
    )
}

/// Polishes `(x, y, z)` by Gauss-Newton on the ten (reduced) cubics `A m(x, y, z) = 0`: the
/// degree-10 polynomial is ill-conditioned where its roots cluster (a root off by `1e-6`
/// there in `f64`, by far more in `f32`), while the cubics themselves are not. Keeps the start
/// if a step does not help.
pub(super) fn polish<T: Real>(a: &[Poly<T>; 10], x: T, y: T, z: T) -> (T, T, T) {
    let residuals = |p: [T; 3]| -> ([T; 10], [[T; 3]; 10]) {
        let [x, y, z] = p;
        let ((px, dx), (py, dy), (pz, dz)) = (powers(x), powers(y), powers(z));
        // Each monomial's power factors and their derivatives, then A times them.
        let g = |t: &[T; 4], k: u8| t.get(usize::from(k)).copied().unwrap_or(T::zero());
        let mono: [[T; 6]; 20] = EXPONENTS.map(|[ex, ey, ez]| {
            [
                g(&px, ex),
                g(&py, ey),
                g(&pz, ez),
                g(&dx, ex),
                g(&dy, ey),
                g(&dz, ez),
            ]
        });
        let mut r = [T::zero(); 10];
        let mut j = [[T::zero(); 3]; 10];
        for ((ri, ji), row) in r.iter_mut().zip(j.iter_mut()).zip(a.iter()) {
            for (c, m) in row.iter().zip(mono.iter()) {
                let [vx, vy, vz, wx, wy, wz] = *m;
                *ri += *c * vx * vy * vz;
                ji[0] += *c * wx * vy * vz;
                ji[1] += *c * vx * wy * vz;
                ji[2] += *c * vx * vy * wz;
            }
        }
        (r, j)
    };
    let norm = |r: &[T; 10]| r.iter().fold(T::zero(), |acc, v| acc + *v * *v);
    let mut p = [x, y, z];
    let (mut r, mut j) = residuals(p);
    let mut cost = norm(&r);
    for _ in 0..POLISH_ITERATIONS {
        let mut qr = StreamingQr::<T, 4>::new();
        for (ri, ji) in r.iter().zip(j.iter()) {
            if qr.push_row(&[ji[0], ji[1], ji[2], -*ri]).is_err() {
                return (p[0], p[1], p[2]);
            }
        }
        let rm = qr.r();
        let Some(step) = rm
            .fixed_view::<3, 3>(0, 0)
            .solve_upper_triangular(&rm.fixed_view::<3, 1>(0, 3))
        else {
            break;
        };
        let q = [p[0] + step.x, p[1] + step.y, p[2] + step.z];
        let (rq, jq) = residuals(q);
        let c = norm(&rq);
        if !above(cost, c) {
            break;
        }
        p = q;
        r = rq;
        j = jq;
        cost = c;
    }
    (p[0], p[1], p[2])
}

/// Steps of [`polish_direct`] in all (each a residual evaluation).
const CHORD_ITERATIONS: u8 = 8;

/// Jacobians [`polish_direct`] factors at most (one more each time a step is slow).
const POLISH_FACTORISATIONS: u8 = 3;

/// Relative step below which [`polish_direct`] stops: the chord iteration gains about four
/// digits a step from the polynomial's roots, so after a step this small the point is at the
/// rounding level of `f32`.
const POLISH_STEP: f64 = 1e-5;

/// The ten constraints of `E`: `r = (det E, vec(2 S E - tr(S) E))`, `S = E Eᵀ` (row-major
/// `vec`), with the cofactor matrix and `S`, `EᵀE`, `tr S` for [`constraint_jacobian`].
#[allow(clippy::type_complexity)]
// Inlined into the polish: its 152-byte result is otherwise copied out by a `memcpy` call on
// a Cortex-M (1.5 % of a solve there).
#[inline(always)]
fn constraint_residuals<T: Real>(
    e: &Matrix3<T>,
) -> ([T; 10], Matrix3<T>, Matrix3<T>, Matrix3<T>, T) {
    let et = e.transpose();
    let s = e * et;
    let tr = s.trace();
    let f = s * e * T::lit(2.0) - e * tr;
    // The cofactor matrix: column j of cof(E) is the cross product of the other two columns
    // of E (so ⟨cof E, E⟩ = 3 det E).
    let (c0, c1, c2) = (e.column(0), e.column(1), e.column(2));
    let cof = Matrix3::from_columns(&[c1.cross(&c2), c2.cross(&c0), c0.cross(&c1)]);
    let mut r = [T::zero(); 10];
    if let Some(r0) = r.first_mut() {
        *r0 = cof.dot(e) / T::lit(3.0);
    }
    for (slot, v) in r.iter_mut().skip(1).zip(f.transpose().iter()) {
        *slot = *v;
    }
    (r, cof, s, et * e, tr)
}

/// The derivatives of [`constraint_residuals`] along `D ∈ {X, Y, Z}` (the columns of the
/// Jacobian in `(x, y, z)`): `d det E = ⟨cof E, D⟩`,
/// `d(2 S E - tr(S) E) = 2 (D EᵀE + E DᵀE + S D) - 2 ⟨D, E⟩ E - tr(S) D`.
fn constraint_jacobian<T: Real>(
    e: &Matrix3<T>,
    directions: [&Matrix3<T>; 3],
    (cof, s, q, tr): (&Matrix3<T>, &Matrix3<T>, &Matrix3<T>, T),
) -> [[T; 10]; 3] {
    let two = T::lit(2.0);
    directions.map(|d| {
        let df = (d * q + e * (d.transpose() * e) + s * d) * two - e * (two * d.dot(e)) - d * tr;
        let mut col = [T::zero(); 10];
        if let Some(c0) = col.first_mut() {
            *c0 = cof.dot(d);
        }
        for (slot, v) in col.iter_mut().skip(1).zip(df.transpose().iter()) {
            *slot = *v;
        }
        col
    })
}

/// Polishes `(x, y, z)` on the ten constraints of `E = x X + y Y + z Z + W`
/// (`basis = [X, Y, Z, W]`) evaluated from `E` itself ([`constraint_residuals`]), by the chord
/// method: the Jacobian ([`constraint_jacobian`]) is factored ([`Mgs10x3`]) and each step is
/// the least-squares solution of `J s = r` with it, refactored where a step cuts `|r|²` by less
/// than 4 (at most [`POLISH_FACTORISATIONS`] times). From the polynomial's roots (a few `1e-5`
/// off in `f32`) a frozen Jacobian gains about four digits a step at a quarter of the cost of
/// a Gauss-Newton step. A step that does not lower `|r|²` is refused, one below
/// [`POLISH_STEP`] relative ends the iteration; at most [`CHORD_ITERATIONS`] steps.
/// Returns the point and its `|r|²`.
pub(super) fn polish_direct<T: Real>(basis: &[Matrix3<T>; 4], x: T, y: T, z: T) -> (T, T, T, T) {
    let [bx, by, bz, bw] = basis;
    let at = |p: &[T; 3]| *bx * p[0] + *by * p[1] + *bz * p[2] + *bw;
    let norm = |r: &[T; 10]| r.iter().fold(T::zero(), |acc, v| acc + *v * *v);
    let mut p = [x, y, z];
    let e = at(&p);
    let (mut r, mut cof, mut s, mut q, mut tr) = constraint_residuals(&e);
    let mut e = e;
    let mut cost = norm(&r);
    let quarter = T::lit(0.25);
    let mut steps = 0u8;
    'factor: for _ in 0..POLISH_FACTORISATIONS {
        let jac = constraint_jacobian(&e, [bx, by, bz], (&cof, &s, &q, tr));
        let Some(factor) = Mgs10x3::new(&jac) else {
            break;
        };
        while steps < CHORD_ITERATIONS {
            steps += 1;
            let Some([sx, sy, sz]) = factor.solve(&r) else {
                break 'factor;
            };
            let next = [p[0] - sx, p[1] - sy, p[2] - sz];
            let en = at(&next);
            let (rn, cn, sn, qn, tn) = constraint_residuals(&en);
            let c = norm(&rn);
            if !above(cost, c) {
                break 'factor;
            }
            let slow = !above(quarter * cost, c);
            (p, e, r, cof, s, q, tr) = (next, en, rn, cn, sn, qn, tn);
            let before = cost;
            cost = c;
            let size = T::one() + p[0].abs() + p[1].abs() + p[2].abs();
            if !above(
                larger(larger(sx.abs(), sy.abs()), sz.abs()),
                T::lit(POLISH_STEP) * size,
            ) {
                break 'factor;
            }
            // A step that did not cut |r|² by 4: the frozen Jacobian is too far off.
            if slow && above(before, T::zero()) {
                continue 'factor;
            }
        }
        break;
    }
    let [x, y, z] = p;
    (x, y, z, cost)
}

/// The thin QR `J = Q R` of a 10x3 matrix (given by its columns) by modified Gram-Schmidt, for
/// least squares `argmin |J s - r| = R⁻¹ Qᵀ r` with several right-hand sides (Björck 1967: MGS
/// least squares, with `Qᵀ r` formed by the same sequential projections, is backward stable).
struct Mgs10x3<T: Real> {
    q: [[T; 10]; 3],
    r: [[T; 3]; 3],
}

impl<T: Real> Mgs10x3<T> {
    /// `None` when a column falls below `√ε` of the largest after projection (rank < 3).
    fn new(columns: &[[T; 10]; 3]) -> Option<Self> {
        let dot = |a: &[T; 10], b: &[T; 10]| {
            a.iter()
                .zip(b.iter())
                .fold(T::zero(), |s, (x, y)| s + *x * *y)
        };
        let mut q = *columns;
        let mut r = [[T::zero(); 3]; 3];
        let first = q.iter().fold(T::zero(), |m, c| larger(m, dot(c, c)));
        if !above(first, T::zero()) || !first.finite() {
            return None;
        }
        for k in 0..3 {
            let (_, rest) = q.split_at_mut(k);
            let (col, later) = rest.split_first_mut()?;
            let n2 = dot(col, col);
            if !above(n2, T::EPSILON * first) {
                return None;
            }
            let n = n2.sqrt();
            col.iter_mut().for_each(|v| *v /= n);
            let row = r.get_mut(k)?;
            *row.get_mut(k)? = n;
            for (other, slot) in later.iter_mut().zip(row.iter_mut().skip(k + 1)) {
                let c = dot(col, other);
                other
                    .iter_mut()
                    .zip(col.iter())
                    .for_each(|(v, qv)| *v -= c * *qv);
                *slot = c;
            }
        }
        Some(Self { q, r })
    }

    /// `R⁻¹ Qᵀ b`, the projections taken one after the other (modified Gram-Schmidt).
    fn solve(&self, b: &[T; 10]) -> Option<[T; 3]> {
        let mut rhs = *b;
        let mut qtb = [T::zero(); 3];
        for (col, out) in self.q.iter().zip(qtb.iter_mut()) {
            let c = col
                .iter()
                .zip(rhs.iter())
                .fold(T::zero(), |s, (x, y)| s + *x * *y);
            rhs.iter_mut()
                .zip(col.iter())
                .for_each(|(v, qv)| *v -= c * *qv);
            *out = c;
        }
        let mut s = [T::zero(); 3];
        for k in (0..3).rev() {
            let row = self.r.get(k)?;
            let mut acc = *qtb.get(k)?;
            for (rv, sv) in row.iter().zip(s.iter()).skip(k + 1) {
                acc -= *rv * *sv;
            }
            *s.get_mut(k)? = acc / *row.get(k)?;
        }
        s.iter().all(|v| v.finite()).then_some(s)
    }
}
