//! The 5-point essential matrix solver (Nistér 2004), hidden-variable form.
//!
//! 1. The five rows `x̂₂ᵀ E x̂₁ = 0` leave a 4-dimensional null space:
//!    `E = x X + y Y + z Z + W` (last four right singular vectors).
//! 2. `det E = 0` and the trace constraint `2 E Eᵀ E - tr(E Eᵀ) E = 0` give ten cubics in
//!    `(x, y, z)` over twenty monomials, ordered
//!    `x³ y³ x²y xy² x²z x² y²z y² xyz xy | xz² xz x yz² yz y z³ z² z 1`.
//! 3. Gauss-Jordan elimination of the first ten columns (partial pivoting).
//! 4. With `⟨m⟩` the row whose leading monomial is `m`, the differences
//!    `⟨x²z⟩ - z ⟨x²⟩`, `⟨y²z⟩ - z ⟨y²⟩`, `⟨xyz⟩ - z ⟨xy⟩` are three equations linear in
//!    `(x, y, 1)` with coefficients polynomial in `z` (degrees 3, 3, 4): `B(z) (x, y, 1)ᵀ = 0`.
//! 5. `det B(z) = 0`, a degree-10 polynomial, has the (up to 10) real roots `z`, found by
//!    derivative isolation and safeguarded Newton ([`super::poly`]), not by an eigen-solver:
//!    no 10x10 non-symmetric eigenproblem (awkward without allocation), bounded work.
//! 6. For each root, `(x, y, 1) ∝` the null vector of `B(z)` (the largest cross product of two
//!    of its rows), then `E` is projected onto the essential manifold.
//!
//! The solver works in `f64` whatever `T`: the elimination and the degree-10 polynomial lose
//! too many digits in `f32` (the result is rounded back to `T`).

use heapless::Vec;
use nalgebra::{Matrix3, Point2};

use super::Essential;
use super::fundamental::{epipolar_row, unvec};
use super::poly::{eval, real_roots};
use crate::linalg::StreamingQr;
use crate::scalar::{Real, above, check_finite};
use crate::{Error, Result};

/// Most essential matrices [`five_point`] returns.
pub const MAX_FIVE_POINT_SOLUTIONS: usize = 10;

/// Largest `|x̂₂ᵀ E x̂₁| / (|E| |row|)` over the five pairs for a root to count as a solution.
const SOLUTION_TOLERANCE: f64 = 1e-9;

/// A polynomial of degree ≤ 3 in `(x, y, z)` over the monomials of [`EXPONENTS`].
type Poly = [f64; 20];
/// A polynomial of degree ≤ 10 in `z`, ascending.
type Poly1 = [f64; 11];

/// Exponents `(x, y, z)` of the twenty monomials, in elimination order (module docs).
const EXPONENTS: [[u8; 3]; 20] = [
    [3, 0, 0],
    [0, 3, 0],
    [2, 1, 0],
    [1, 2, 0],
    [2, 0, 1],
    [2, 0, 0],
    [0, 2, 1],
    [0, 2, 0],
    [1, 1, 1],
    [1, 1, 0],
    [1, 0, 2],
    [1, 0, 1],
    [1, 0, 0],
    [0, 1, 2],
    [0, 1, 1],
    [0, 1, 0],
    [0, 0, 3],
    [0, 0, 2],
    [0, 0, 1],
    [0, 0, 0],
];

/// The monomial index of each exponent triple (`u8::MAX` for degree > 3).
const INDEX: [[[u8; 4]; 4]; 4] = build_index();

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_index() -> [[[u8; 4]; 4]; 4] {
    let mut t = [[[u8::MAX; 4]; 4]; 4];
    let mut i = 0;
    while i < EXPONENTS.len() {
        let e = EXPONENTS[i];
        t[e[0] as usize][e[1] as usize][e[2] as usize] = i as u8;
        i += 1;
    }
    t
}

const ZERO: Poly = [0.0; 20];
const X: usize = 12;
const Y: usize = 15;
const Z: usize = 18;
const ONE: usize = 19;

fn index_of(e: [u8; 3]) -> Option<usize> {
    let [a, b, c] = e;
    let i = *INDEX
        .get(usize::from(a))?
        .get(usize::from(b))?
        .get(usize::from(c))?;
    (usize::from(i) < EXPONENTS.len()).then_some(usize::from(i))
}

/// `a b`, dropping terms of degree above 3 (never produced by the callers).
fn mul(a: &Poly, b: &Poly) -> Poly {
    let mut out = ZERO;
    for (ea, ca) in EXPONENTS.iter().zip(a.iter()).filter(|(_, c)| **c != 0.0) {
        for (eb, cb) in EXPONENTS.iter().zip(b.iter()).filter(|(_, c)| **c != 0.0) {
            let e = [ea[0] + eb[0], ea[1] + eb[1], ea[2] + eb[2]];
            if let Some(slot) = index_of(e).and_then(|i| out.get_mut(i)) {
                *slot += ca * cb;
            }
        }
    }
    out
}

fn axpy(acc: &mut Poly, s: f64, b: &Poly) {
    acc.iter_mut().zip(b.iter()).for_each(|(a, b)| *a += s * b);
}

/// `Σₖ aₖ bₖ` over three polynomial pairs.
fn dot3(a: &[Poly; 3], b: &[Poly; 3]) -> Poly {
    let mut out = ZERO;
    for (x, y) in a.iter().zip(b.iter()) {
        axpy(&mut out, 1.0, &mul(x, y));
    }
    out
}

fn mul1(a: &Poly1, b: &Poly1) -> Poly1 {
    let mut out = [0.0; 11];
    for (i, ca) in a.iter().enumerate() {
        for (o, cb) in out.iter_mut().skip(i).zip(b.iter()) {
            *o += ca * cb;
        }
    }
    out
}

fn sub1(a: &Poly1, b: &Poly1) -> Poly1 {
    let mut out = *a;
    out.iter_mut().zip(b.iter()).for_each(|(o, b)| *o -= b);
    out
}

/// `a - z b`.
fn sub_shifted(a: &Poly1, b: &Poly1) -> Poly1 {
    let mut out = *a;
    out.iter_mut()
        .skip(1)
        .zip(b.iter())
        .for_each(|(o, b)| *o -= b);
    out
}

/// The `x`, `y` and `1` coefficients (polynomials in `z`) of a reduced row: its trailing
/// monomials `xz² xz x yz² yz y z³ z² z 1`.
fn split(row: &Poly) -> [Poly1; 3] {
    let [.., b0, b1, b2, b3, b4, b5, b6, b7, b8, b9] = *row;
    let p = |c: &[f64]| {
        let mut out = [0.0; 11];
        out.iter_mut().zip(c.iter()).for_each(|(o, c)| *o = *c);
        out
    };
    [p(&[b2, b1, b0]), p(&[b5, b4, b3]), p(&[b9, b8, b7, b6])]
}

/// Every essential matrix `E` with `x̂₂ᵢᵀ E x̂₁ᵢ = 0` for five pairs of normalised coordinates
/// (`x̂ = K⁻¹ x`, undistorted): up to [`MAX_FIVE_POINT_SOLUTIONS`], unordered (see the module
/// docs for the method).
///
/// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when the five rows are dependent, the
/// elimination meets a zero pivot, or no real root gives an essential matrix.
pub fn five_point<T: Real>(
    x1: &[Point2<T>; 5],
    x2: &[Point2<T>; 5],
) -> Result<Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>> {
    let mut qr = StreamingQr::<f64, 9>::new();
    let mut rows5 = [[0.0f64; 9]; 5];
    for ((a, b), row) in x1.iter().zip(x2.iter()).zip(rows5.iter_mut()) {
        check_finite(&[a.x, a.y, b.x, b.y])?;
        let c = |p: &Point2<T>| Point2::new(p.x.to_f64(), p.y.to_f64());
        let r = epipolar_row(&c(a), &c(b));
        // Unit rows: the residual check below is then relative.
        let n = libm::sqrt(r.iter().map(|v| v * v).sum::<f64>());
        *row = r.map(|v| v / n);
        qr.push_row(&r)?;
    }
    let svd = qr.svd()?;
    let [s1, _, _, _, s5, ..]: [f64; 9] = svd.singular_values.into();
    if !above(s5, 1e-10 * s1) {
        return Err(Error::Degenerate);
    }
    let basis = |k: usize| unvec(&svd.v.column(k).into_owned());
    let (bx, by, bz, bw) = (basis(5), basis(6), basis(7), basis(8));

    // E as linear polynomials, row-major.
    let mut e = [[ZERO; 3]; 3];
    for (i, row) in e.iter_mut().enumerate() {
        for (j, p) in row.iter_mut().enumerate() {
            for (k, m) in [(X, &bx), (Y, &by), (Z, &bz), (ONE, &bw)] {
                if let (Some(slot), Some(v)) = (p.get_mut(k), m.get((i, j))) {
                    *slot = *v;
                }
            }
        }
    }
    let mut et = [[ZERO; 3]; 3]; // columns of E
    for (k, row) in e.iter().enumerate() {
        for (col, v) in et.iter_mut().zip(row.iter()) {
            if let Some(slot) = col.get_mut(k) {
                *slot = *v;
            }
        }
    }
    // E Eᵀ and its trace.
    let mut eet = [[ZERO; 3]; 3];
    for (out, ri) in eet.iter_mut().zip(e.iter()) {
        for (o, rj) in out.iter_mut().zip(e.iter()) {
            *o = dot3(ri, rj);
        }
    }
    let mut trace = ZERO;
    for (i, row) in eet.iter().enumerate() {
        if let Some(d) = row.get(i) {
            axpy(&mut trace, 1.0, d);
        }
    }
    // The ten cubic constraints.
    let mut a = [ZERO; 10];
    let mut rows = a.iter_mut();
    if let Some(r) = rows.next() {
        let [[e11, e12, e13], [e21, e22, e23], [e31, e32, e33]] = &e;
        let c1 = {
            let mut c = mul(e22, e33);
            axpy(&mut c, -1.0, &mul(e23, e32));
            c
        };
        let c2 = {
            let mut c = mul(e21, e33);
            axpy(&mut c, -1.0, &mul(e23, e31));
            c
        };
        let c3 = {
            let mut c = mul(e21, e32);
            axpy(&mut c, -1.0, &mul(e22, e31));
            c
        };
        *r = mul(e11, &c1);
        axpy(r, -1.0, &mul(e12, &c2));
        axpy(r, 1.0, &mul(e13, &c3));
    }
    for (eet_row, e_row) in eet.iter().zip(e.iter()) {
        for (col, e_ij) in et.iter().zip(e_row.iter()) {
            if let Some(r) = rows.next() {
                *r = ZERO;
                axpy(r, 2.0, &dot3(eet_row, col));
                axpy(r, -1.0, &mul(&trace, e_ij));
            }
        }
    }

    gauss_jordan(&mut a)?;

    let [.., r4, r5, r6, r7, r8, r9] = &a;
    let b = |hi: &Poly, lo: &Poly| {
        let (h, l) = (split(hi), split(lo));
        let [h0, h1, h2] = &h;
        let [l0, l1, l2] = &l;
        [
            sub_shifted(h0, l0),
            sub_shifted(h1, l1),
            sub_shifted(h2, l2),
        ]
    };
    let [kx, ky, k1] = b(r4, r5);
    let [lx, ly, l1] = b(r6, r7);
    let [mx, my, m1] = b(r8, r9);
    let minor = |a: &Poly1, b: &Poly1, c: &Poly1, d: &Poly1| sub1(&mul1(a, b), &mul1(c, d));
    let det = {
        let t1 = mul1(&kx, &minor(&ly, &m1, &l1, &my));
        let t2 = mul1(&ky, &minor(&lx, &m1, &l1, &mx));
        let t3 = mul1(&k1, &minor(&lx, &my, &ly, &mx));
        let mut d = sub1(&t1, &t2);
        d.iter_mut().zip(t3.iter()).for_each(|(a, b)| *a += b);
        d
    };

    let mut out = Vec::new();
    for z in real_roots(&det) {
        let row = |p: &[Poly1; 3]| {
            let [a, b, c] = p;
            nalgebra::Vector3::new(eval(a, z), eval(b, z), eval(c, z))
        };
        let (k, l, m) = (row(&[kx, ky, k1]), row(&[lx, ly, l1]), row(&[mx, my, m1]));
        let candidates = [k.cross(&l), k.cross(&m), l.cross(&m)];
        let Some(v) = candidates
            .iter()
            .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))
        else {
            continue;
        };
        if !above(v.z.abs(), 1e-12 * v.norm()) {
            continue;
        }
        let (x, y, z) = polish(&a, v.x / v.z, v.y / v.z, z);
        let m: Matrix3<f64> = bx * x + by * y + bz * z + bw;
        // Projected onto the manifold in f64; a near-double root that is not a solution (its
        // polish stalls) moves there, while true solutions stay at rounding level.
        let Ok(e) = Essential::<f64>::from_matrix(&m) else {
            continue;
        };
        let et = e.matrix().transpose();
        let worst = rows5.iter().fold(0.0f64, |w, r| {
            let v = r.iter().zip(et.iter()).map(|(a, b)| a * b).sum::<f64>();
            w.max(v.abs())
        });
        if above(SOLUTION_TOLERANCE, worst) {
            let _ = out.push(Essential {
                e: e.matrix().map(T::lit),
            });
        }
    }
    if out.is_empty() {
        return Err(Error::Degenerate);
    }
    Ok(out)
}

/// Gauss-Newton steps polishing a root on the ten cubics.
const POLISH_ITERATIONS: u8 = 4;

/// Polishes `(x, y, z)` by Gauss-Newton on the ten (reduced) cubics `A m(x, y, z) = 0`: the
/// degree-10 polynomial is ill-conditioned where its roots cluster (a root off by `1e-6`
/// there), while the cubics themselves are not. Keeps the start if a step does not help.
fn polish(a: &[Poly; 10], x: f64, y: f64, z: f64) -> (f64, f64, f64) {
    let residuals = |p: [f64; 3]| -> ([f64; 10], [[f64; 3]; 10]) {
        let [x, y, z] = p;
        let pw = |v: f64, e: u8| (0..e).fold(1.0, |acc, _| acc * v);
        let mut r = [0.0; 10];
        let mut j = [[0.0; 3]; 10];
        for ((ri, ji), row) in r.iter_mut().zip(j.iter_mut()).zip(a.iter()) {
            for (e, c) in EXPONENTS.iter().zip(row.iter()) {
                let [ex, ey, ez] = *e;
                let (px, py, pz) = (pw(x, ex), pw(y, ey), pw(z, ez));
                *ri += c * px * py * pz;
                let d = |k: u8, v: f64| {
                    if k == 0 {
                        0.0
                    } else {
                        f64::from(k) * pw(v, k - 1)
                    }
                };
                ji[0] += c * d(ex, x) * py * pz;
                ji[1] += c * px * d(ey, y) * pz;
                ji[2] += c * px * py * d(ez, z);
            }
        }
        (r, j)
    };
    let norm = |r: &[f64; 10]| r.iter().map(|v| v * v).sum::<f64>();
    let mut p = [x, y, z];
    let (mut r, mut j) = residuals(p);
    let mut cost = norm(&r);
    for _ in 0..POLISH_ITERATIONS {
        let mut qr = StreamingQr::<f64, 4>::new();
        for (ri, ji) in r.iter().zip(j.iter()) {
            if qr.push_row(&[ji[0], ji[1], ji[2], -ri]).is_err() {
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

/// Reduces the first ten columns of `a` to the identity (partial pivoting).
fn gauss_jordan(a: &mut [Poly; 10]) -> Result<()> {
    let scale = a
        .iter()
        .flat_map(|r| r.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    if !above(scale, 0.0) || !scale.is_finite() {
        return Err(Error::Degenerate);
    }
    for c in 0..10 {
        let Some((p, _)) = a
            .iter()
            .enumerate()
            .skip(c)
            .map(|(i, r)| (i, r.get(c).map_or(0.0, |v| v.abs())))
            .max_by(|x, y| x.1.total_cmp(&y.1))
        else {
            return Err(Error::Degenerate);
        };
        a.swap(c, p);
        let Some(mut pivot) = a.get(c).copied() else {
            return Err(Error::Degenerate);
        };
        let pv = pivot.get(c).copied().unwrap_or(0.0);
        if !above(pv.abs(), 1e-12 * scale) {
            return Err(Error::Degenerate);
        }
        pivot.iter_mut().for_each(|v| *v /= pv);
        for (i, row) in a.iter_mut().enumerate() {
            if i == c {
                *row = pivot;
            } else {
                let f = row.get(c).copied().unwrap_or(0.0);
                if f != 0.0 {
                    axpy(row, -f, &pivot);
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;
    use crate::twoview::RelativePose;
    use nalgebra::{Point3, Vector3};

    #[test]
    fn monomial_table_is_consistent() {
        for (i, e) in EXPONENTS.iter().enumerate() {
            assert_eq!(index_of(*e), Some(i));
        }
        assert_eq!(index_of([2, 2, 0]), None);
        // (x + 1)(y + z) = xy + xz + y + z.
        let mut a = ZERO;
        a[X] = 1.0;
        a[ONE] = 1.0;
        let mut b = ZERO;
        b[Y] = 1.0;
        b[Z] = 1.0;
        let p = mul(&a, &b);
        assert_eq!(p[9], 1.0);
        assert_eq!(p[11], 1.0);
        assert_eq!(p[Y], 1.0);
        assert_eq!(p[Z], 1.0);
        assert_eq!(p.iter().filter(|c| **c != 0.0).count(), 4);
    }

    #[test]
    fn recovers_the_true_essential_matrix() {
        let mut g = Pcg32::new(77);
        let mut found = 0;
        for _ in 0..50 {
            let pose = RelativePose::from_rodrigues(
                Vector3::new(
                    g.uniform(-0.3, 0.3),
                    g.uniform(-0.3, 0.3),
                    g.uniform(-0.3, 0.3),
                ),
                Vector3::new(
                    g.uniform(-1.0, 1.0),
                    g.uniform(-1.0, 1.0),
                    g.uniform(-0.5, 0.5),
                ),
            )
            .unwrap();
            let truth = Essential::from_pose(&pose).unwrap();
            let pts: [Point3<f64>; 5] = core::array::from_fn(|_| {
                Point3::new(
                    g.uniform(-2.0, 2.0),
                    g.uniform(-2.0, 2.0),
                    g.uniform(4.0, 8.0),
                )
            });
            let x1 = pts.map(|p| Point2::new(p.x / p.z, p.y / p.z));
            let x2 = pts.map(|p| {
                let q = pose.apply(&p);
                Point2::new(q.x / q.z, q.y / q.z)
            });
            let sols = five_point(&x1, &x2).unwrap();
            for e in &sols {
                let worst = x1
                    .iter()
                    .zip(x2.iter())
                    .map(|(a, b)| e.residual(a, b).abs())
                    .fold(0.0, f64::max);
                assert!(worst < 1e-12, "{worst:e}");
            }
            let best = sols
                .iter()
                .map(|e| {
                    (e.matrix() - truth.matrix())
                        .amax()
                        .min((e.matrix() + truth.matrix()).amax())
                })
                .fold(f64::INFINITY, f64::min);
            if best < 1e-8 {
                found += 1;
            }
        }
        assert!(found == 50, "{found} of 50");
    }
}
