//! Nistér's hidden-variable solve of the ten cubics (the `f64` solver; module docs, steps
//! 3-6): `det B(z) = 0`, a degree-10 polynomial in `z`, its real roots, and `(x, y)` from the
//! null vector of `B(z)`.

use heapless::Vec;
use nalgebra::{Matrix3, Vector3};

use super::accept::{MAX_FIVE_POINT_SOLUTIONS, keep};
use super::monomial::{Poly, add_assign, constraints, gauss_jordan, linear_entries, sub};
use super::polish::polish;
use super::precision::Tolerances;
use crate::Result;
use crate::scalar::{Real, above};
use crate::twoview::Essential;
use crate::twoview::poly::{eval, real_roots};

/// A polynomial of degree ≤ 10 in `z`, ascending.
type Poly1<T> = [T; 11];

fn mul1<T: Real>(a: &Poly1<T>, b: &Poly1<T>) -> Poly1<T> {
    let mut out = [T::zero(); 11];
    for (i, ca) in a.iter().enumerate() {
        for (o, cb) in out.iter_mut().skip(i).zip(b.iter()) {
            *o += *ca * *cb;
        }
    }
    out
}

/// `a - z b`.
fn sub_shifted<T: Real>(a: &Poly1<T>, b: &Poly1<T>) -> Poly1<T> {
    let mut out = *a;
    out.iter_mut()
        .skip(1)
        .zip(b.iter())
        .for_each(|(o, b)| *o -= *b);
    out
}

/// The `x`, `y` and `1` coefficients (polynomials in `z`) of a reduced row: its trailing
/// monomials `xz² xz x yz² yz y z³ z² z 1`.
fn split<T: Real>(row: &Poly<T>) -> [Poly1<T>; 3] {
    let [.., b0, b1, b2, b3, b4, b5, b6, b7, b8, b9] = *row;
    let p = |c: &[T]| {
        let mut out = [T::zero(); 11];
        out.iter_mut().zip(c.iter()).for_each(|(o, c)| *o = *c);
        out
    };
    [p(&[b2, b1, b0]), p(&[b5, b4, b3]), p(&[b9, b8, b7, b6])]
}

/// The hidden-variable solve (module docs, steps 3-6) with `E = x X + y Y + z Z + W` for
/// `basis = [X, Y, Z, W]`, appending the solutions to `out`.
pub(super) fn hidden_variable<T: Real>(
    basis: &[Matrix3<T>; 4],
    rows5: &[[T; 9]; 5],
    tol: &Tolerances<T>,
    out: &mut Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>,
) -> Result<()> {
    let mut a = constraints(&linear_entries(basis));
    gauss_jordan(&mut a, tol.pivot)?;

    let [.., r4, r5, r6, r7, r8, r9] = &a;
    let b = |hi: &Poly<T>, lo: &Poly<T>| {
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
    let minor =
        |a: &Poly1<T>, b: &Poly1<T>, c: &Poly1<T>, d: &Poly1<T>| sub(&mul1(a, b), &mul1(c, d));
    let det = {
        let t1 = mul1(&kx, &minor(&ly, &m1, &l1, &my));
        let t2 = mul1(&ky, &minor(&lx, &m1, &l1, &mx));
        let t3 = mul1(&k1, &minor(&lx, &my, &ly, &mx));
        let mut d = sub(&t1, &t2);
        add_assign(&mut d, &t3);
        d
    };
    let [bx, by, bz, bw] = basis;
    // By reference: `heapless::Vec`'s by-value iterator slices on drop (a bounds check).
    for &z in real_roots(&det).iter() {
        let row = |p: &[Poly1<T>; 3]| {
            let [a, b, c] = p;
            Vector3::new(eval(a, z), eval(b, z), eval(c, z))
        };
        let (k, l, m) = (row(&[kx, ky, k1]), row(&[lx, ly, l1]), row(&[mx, my, m1]));
        let candidates = [k.cross(&l), k.cross(&m), l.cross(&m)];
        // The largest, the last of equal ones (as `max_by`).
        let Some(v) = candidates
            .iter()
            .fold(None, |best: Option<&Vector3<T>>, c| match best {
                Some(b) if b.norm_squared() > c.norm_squared() => Some(b),
                _ => Some(c),
            })
        else {
            continue;
        };
        if !above(v.z.abs(), tol.homogeneous * v.norm()) {
            continue;
        }
        let (x, y, z) = polish(&a, v.x / v.z, v.y / v.z, z);
        let m: Matrix3<T> = *bx * x + *by * y + *bz * z + *bw;
        // Projected onto the manifold; a near-double root that is not a solution (its
        // polish stalls) moves there, while true solutions stay at rounding level.
        let Ok(e) = Essential::<T>::from_matrix(&m) else {
            continue;
        };
        keep(e, rows5, tol, out);
    }
    Ok(())
}
