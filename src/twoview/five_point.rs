//! The 5-point essential matrix solver in the precision of the caller's scalar: Nistér's
//! hidden variable (2004) in `f64`, the action matrix of Stewénius, Engels and Nistér (2006)
//! in `f32`.
//!
//! 1. The five rows `x̂₂ᵀ E x̂₁ = 0` leave a 4-dimensional null space:
//!    `E = x X + y Y + z Z + W`.
//! 2. `det E = 0` and the trace constraint `2 E Eᵀ E - tr(E Eᵀ) E = 0` give ten cubics in
//!    `(x, y, z)` over twenty monomials, ordered
//!    `x³ y³ x²y xy² x²z x² y²z y² xyz xy | xz² xz x yz² yz y z³ z² z 1`.
//!
//! Hidden variable (`f64`, [`hidden_variable`]):
//!
//! 3. Gauss-Jordan elimination of the first ten columns (partial pivoting).
//! 4. With `⟨m⟩` the row whose leading monomial is `m`, the differences
//!    `⟨x²z⟩ - z ⟨x²⟩`, `⟨y²z⟩ - z ⟨y²⟩`, `⟨xyz⟩ - z ⟨xy⟩` are three equations linear in
//!    `(x, y, 1)` with coefficients polynomial in `z` (degrees 3, 3, 4): `B(z) (x, y, 1)ᵀ = 0`.
//! 5. `det B(z) = 0`, a degree-10 polynomial, has the (up to 10) real roots `z`, found by
//!    derivative isolation and a safeguarded Newton iteration ([`super::poly`]).
//! 6. For each root, `(x, y, 1) ∝` the null vector of `B(z)` (the largest cross product of two
//!    of its rows), polished by Gauss-Newton on the reduced cubics (the constraints are well
//!    conditioned where the degree-10 polynomial, with clustered roots, is not), projected
//!    onto the manifold, then kept if it satisfies the five epipolar equations.
//!
//! Action matrix (`f32`, [`action_matrix`]):
//!
//! 3. The same cubics, the ten monomials of degree 3 eliminated (Gauss-Jordan), which leaves
//!    each as a combination of the ten of degree ≤ 2, `b`.
//! 4. Multiplication by `x` on `b` is then a 10x10 matrix `M` with `M b = x b` at every
//!    solution: its real eigenvalues ([`crate::linalg`]'s `real_eigenvalues`: balancing,
//!    Hessenberg, Francis QR, bounded) are the solutions' `x`, its eigenvectors (inverse
//!    iteration) give `(x : y : z : 1)`.
//! 5. Each is polished by the chord method on the ten constraints evaluated from `E` itself
//!    ([`polish_direct`]), accepted at `1e-5`, scaled to `|E| = √2`, and kept if it satisfies
//!    the five epipolar equations.
//!
//! `f32` never converts to `f64` (a board with a single-precision FPU, Cortex-M4F/M7 or
//! ESP32-S3, runs no software double). It does not use the hidden variable because the
//! degree-10 polynomial's roots cluster where solutions share a similar `z`, and a cluster's
//! roots move far more than `ε` when the coefficients are rounded to `f32`: one pass missed
//! the true solution in 232 of 2000 random problems, a second pass with another basis vector
//! as `W` (twice the cost) still in 32; the action matrix misses 19 ([`SINGLE`]). The null
//! space in `f32` comes from Gauss-Jordan with full pivoting, `[-B; I]` orthonormalised
//! ([`crate::linalg`]'s `null_space`), a fraction of the cost of `f64`'s QR and SVD. The `f64`
//! results are those of the first version, to the bit.

use heapless::Vec;
use nalgebra::{Matrix3, Point2, Vector3};

use super::Essential;
use super::fundamental::{epipolar_row, unvec};
use super::poly::{eval, real_roots};
use crate::linalg::{StreamingQr, null_space, null_vector, real_eigenvalues, swap_rows};
use crate::scalar::{Real, above, check_finite, larger};
use crate::{Error, Result};

/// Most essential matrices [`five_point`] returns.
pub const MAX_FIVE_POINT_SOLUTIONS: usize = 10;

/// How the null space of the five epipolar rows is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum NullSpace {
    /// Last four right singular vectors of the QR + Jacobi SVD.
    Svd,
    /// Gauss-Jordan with full pivoting, then modified Gram-Schmidt.
    GaussJordan,
}

/// How the ten cubics are solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Method {
    /// Nistér's hidden variable: the degree-10 polynomial `det B(z)`, its real roots, Gauss-Newton
    /// on the reduced cubics, SVD projection onto the manifold.
    HiddenVariable,
    /// Stewénius' action matrix: the real eigenvalues and eigenvectors of multiplication by
    /// `x` on the ten monomials of degree ≤ 2 ([`action_matrix`]), then the chord polish on
    /// `E` itself ([`polish_direct`]).
    ActionMatrix,
}

/// The precision-dependent choices of the solver.
#[derive(Debug, Clone, Copy)]
struct Precision {
    null_space: NullSpace,
    method: Method,
    /// Smallest `σ₅ / σ₁` (SVD) or last pivot / first pivot (Gauss-Jordan) of the five rows.
    rank: f64,
    /// Smallest pivot of the 10x20 elimination, relative to the largest entry.
    pivot: f64,
    /// Smallest `|w| / |(x, y, z, w)|` of a solution's homogeneous coordinates in the basis
    /// (`w = 0`: at infinity in the parametrisation `E = x X + y Y + z Z + W`).
    homogeneous: f64,
    /// Largest `|x̂₂ᵀ E x̂₁| / (|E| |row|)` over the five pairs for a root to count as a
    /// solution.
    solution: f64,
    /// Two solutions closer than this (max entry, up to sign) are one.
    duplicate: f64,
}

/// `f64`: the solver as first written (its results are kept to the bit).
const DOUBLE: Precision = Precision {
    null_space: NullSpace::Svd,
    method: Method::HiddenVariable,
    rank: 1e-10,
    pivot: 1e-12,
    homogeneous: 1e-12,
    solution: 1e-9,
    duplicate: 0.0,
};

/// `f32` (`ε = 1.2e-7`).
///
/// - Rank: a pivot ratio of `1e-4` leaves a null space accurate to `ε / 1e-4 ~ 1e-3`, which
///   the polish can still pull in.
/// - The action matrix, not the hidden variable: the degree-10 polynomial's roots cluster
///   where several solutions share a similar `z`, and roots in a cluster move by far more
///   than `ε` when the coefficients are rounded (rounding the coefficients of an exactly
///   computed polynomial to `f32` loses the true root in most of the problems where a single
///   `f32` pass misses it); an eigenvalue of the action matrix moves by `ε |A|` times its own
///   condition number whatever the spacing of the others. On 2000 random exact problems
///   (`tests::f32_agrees_with_f64`) the action matrix misses 19 of the true solutions `f64`
///   finds; the hidden variable missed 232 in one pass and 32 in two (with a second basis
///   vector as `W`), at twice the cost. What it still misses is mostly a close pair of real
///   eigenvalues that rounding makes a complex pair (two solutions with nearly the same
///   `x`); RANSAC draws another sample.
/// - Polish on the constraints evaluated from `E = x X + y Y + z Z + W` itself: at rounding
///   level at the true root, and a tenth of the cost of evaluating the reduced cubics.
/// - Solution: the ten constraints to `1e-5 |E|³` and the five epipolar ones to `1e-5`
///   relative; true roots polish to a few `1e-7`, a spurious one stays far above. No SVD
///   projection: the polished `E` is on the manifold to that accuracy (`σ₃ ~ 1e-5`), scaled
///   to `|E| = √2`.
const SINGLE: Precision = Precision {
    null_space: NullSpace::GaussJordan,
    method: Method::ActionMatrix,
    rank: 1e-4,
    pivot: 1e-6,
    homogeneous: 1e-6,
    solution: 1e-5,
    duplicate: 1e-3,
};

/// The tolerances of a [`Precision`] in `T`, converted where the precision is a constant
/// (inlined into [`five_point`]), so no `f64` survives to run time in the `f32` code.
#[derive(Debug, Clone, Copy)]
struct Tolerances<T> {
    rank: T,
    pivot: T,
    homogeneous: T,
    solution: T,
    duplicate: T,
}

impl<T: Real> Tolerances<T> {
    #[inline(always)]
    fn of(p: &Precision) -> Self {
        Self {
            rank: T::lit(p.rank),
            pivot: T::lit(p.pivot),
            homogeneous: T::lit(p.homogeneous),
            solution: T::lit(p.solution),
            duplicate: T::lit(p.duplicate),
        }
    }
}

/// Whether `T` is single precision (`f32`): a compile-time constant per instantiation, so
/// each precision keeps only its own branch.
const fn single<T>() -> bool {
    core::mem::size_of::<T>() <= 4
}

/// A polynomial of degree ≤ 3 in `(x, y, z)` over the monomials of [`EXPONENTS`].
type Poly<T> = [T; 20];
/// A polynomial of degree ≤ 10 in `z`, ascending.
type Poly1<T> = [T; 11];
/// A linear polynomial `a x + b y + c z + d`: `[a, b, c, d]`.
type Linear<T> = [T; 4];
/// A quadratic over the monomials [`QUADRATIC`] (the degree-2-or-less ones of
/// [`EXPONENTS`], in that order).
type Quadratic<T> = [T; 10];

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

/// Exponents of the four monomials of a [`Linear`]: `x y z 1`.
const LINEAR: [[u8; 3]; 4] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0]];

/// The monomial index of each exponent triple (`u8::MAX` for degree > 3).
const INDEX: [[[u8; 4]; 4]; 4] = build_index();

/// Where each [`Quadratic`] monomial sits in [`EXPONENTS`].
const QUADRATIC: [u8; 10] = build_quadratic();

/// `LL[i][j]`: the [`Quadratic`] slot of `LINEAR[i] · LINEAR[j]`.
const LL: [[u8; 4]; 4] = build_ll();

/// `QL[i][j]`: the [`EXPONENTS`] slot of `QUADRATIC[i] · LINEAR[j]`.
const QL: [[u8; 4]; 10] = build_ql();

/// The monomials of [`action_matrix`]'s elimination, as exponents `(x, y, z)`: the ten of
/// degree 3, eliminated, then its basis `b`, the ten of degree ≤ 2.
const ACTION_MONOMIALS: [[u8; 3]; 20] = [
    [3, 0, 0],
    [2, 1, 0],
    [2, 0, 1],
    [1, 2, 0],
    [1, 1, 1],
    [1, 0, 2],
    [0, 3, 0],
    [0, 2, 1],
    [0, 1, 2],
    [0, 0, 3],
    [2, 0, 0],
    [1, 1, 0],
    [1, 0, 1],
    [0, 2, 0],
    [0, 1, 1],
    [0, 0, 2],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [0, 0, 0],
];

/// Where each of [`ACTION_MONOMIALS`] sits in [`EXPONENTS`] (the column order of
/// [`constraints`]).
const ACTION_COLUMNS: [u8; 20] = build_action_columns();

/// `x b_j` for each monomial `b_j` of the action basis: `(true, i)` for the eliminated
/// monomial `i`, `(false, k)` for the basis monomial `k`.
const X_TIMES_BASIS: [(bool, u8); 10] = build_x_times_basis();

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_action_columns() -> [u8; 20] {
    let mut t = [u8::MAX; 20];
    let mut i = 0;
    while i < 20 {
        let e = ACTION_MONOMIALS[i];
        t[i] = INDEX[e[0] as usize][e[1] as usize][e[2] as usize];
        assert!(t[i] != u8::MAX);
        i += 1;
    }
    t
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_x_times_basis() -> [(bool, u8); 10] {
    let mut t = [(false, u8::MAX); 10];
    let mut j = 0;
    while j < 10 {
        let e = ACTION_MONOMIALS[10 + j];
        let mut k = 0;
        while k < 20 {
            let f = ACTION_MONOMIALS[k];
            if f[0] == e[0] + 1 && f[1] == e[1] && f[2] == e[2] {
                t[j] = if k < 10 {
                    (true, k as u8)
                } else {
                    (false, (k - 10) as u8)
                };
            }
            k += 1;
        }
        assert!(t[j].1 != u8::MAX);
        j += 1;
    }
    t
}

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

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_quadratic() -> [u8; 10] {
    let mut q = [u8::MAX; 10];
    let (mut i, mut k) = (0, 0);
    while i < EXPONENTS.len() {
        let e = EXPONENTS[i];
        if e[0] + e[1] + e[2] <= 2 {
            q[k] = i as u8;
            k += 1;
        }
        i += 1;
    }
    assert!(k == 10);
    q
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_ll() -> [[u8; 4]; 4] {
    let mut t = [[u8::MAX; 4]; 4];
    let mut i = 0;
    while i < 4 {
        let mut j = 0;
        while j < 4 {
            let (a, b) = (LINEAR[i], LINEAR[j]);
            let slot =
                INDEX[(a[0] + b[0]) as usize][(a[1] + b[1]) as usize][(a[2] + b[2]) as usize];
            let mut k = 0;
            while k < 10 {
                if QUADRATIC[k] == slot {
                    t[i][j] = k as u8;
                }
                k += 1;
            }
            assert!(t[i][j] != u8::MAX);
            j += 1;
        }
        i += 1;
    }
    t
}

#[allow(clippy::indexing_slicing)] // Evaluated at compile time: a bad index fails the build.
const fn build_ql() -> [[u8; 4]; 10] {
    let mut t = [[u8::MAX; 4]; 10];
    let mut i = 0;
    while i < 10 {
        let mut j = 0;
        while j < 4 {
            let (a, b) = (EXPONENTS[QUADRATIC[i] as usize], LINEAR[j]);
            t[i][j] = INDEX[(a[0] + b[0]) as usize][(a[1] + b[1]) as usize][(a[2] + b[2]) as usize];
            assert!(t[i][j] != u8::MAX);
            j += 1;
        }
        i += 1;
    }
    t
}

#[cfg(test)]
fn index_of(e: [u8; 3]) -> Option<usize> {
    let [a, b, c] = e;
    let i = *INDEX
        .get(usize::from(a))?
        .get(usize::from(b))?
        .get(usize::from(c))?;
    (usize::from(i) < EXPONENTS.len()).then_some(usize::from(i))
}

/// `a b` of two linear polynomials.
///
/// Every product of this module accumulates its terms in the order of the operands' monomials
/// in [`EXPONENTS`] (first operand outer): the order of the generic 20x20 product it
/// replaces, so the `f64` results are unchanged to the bit.
fn mul_ll<T: Real>(a: &Linear<T>, b: &Linear<T>) -> Quadratic<T> {
    let mut out = [T::zero(); 10];
    for (ca, slots) in a.iter().zip(LL.iter()) {
        for (cb, k) in b.iter().zip(slots.iter()) {
            if let Some(o) = out.get_mut(usize::from(*k)) {
                *o += *ca * *cb;
            }
        }
    }
    out
}

/// `a b` of a quadratic and a linear polynomial (first operand outer, see [`mul_ll`]).
fn mul_ql<T: Real>(a: &Quadratic<T>, b: &Linear<T>) -> Poly<T> {
    let mut out = [T::zero(); 20];
    for (ca, slots) in a.iter().zip(QL.iter()) {
        for (cb, k) in b.iter().zip(slots.iter()) {
            if let Some(o) = out.get_mut(usize::from(*k)) {
                *o += *ca * *cb;
            }
        }
    }
    out
}

/// `a b` of a linear and a quadratic polynomial (first operand outer, see [`mul_ll`]).
fn mul_lq<T: Real>(a: &Linear<T>, b: &Quadratic<T>) -> Poly<T> {
    let mut out = [T::zero(); 20];
    for (ca, j) in a.iter().zip(0..4) {
        for (cb, slots) in b.iter().zip(QL.iter()) {
            if let Some(o) = slots.get(j).and_then(|k| out.get_mut(usize::from(*k))) {
                *o += *ca * *cb;
            }
        }
    }
    out
}

fn sub<T: Real, const N: usize>(a: &[T; N], b: &[T; N]) -> [T; N] {
    let mut out = *a;
    out.iter_mut().zip(b.iter()).for_each(|(o, b)| *o -= *b);
    out
}

fn add_assign<T: Real, const N: usize>(acc: &mut [T; N], b: &[T; N]) {
    acc.iter_mut().zip(b.iter()).for_each(|(a, b)| *a += *b);
}

fn axpy<T: Real>(acc: &mut Poly<T>, s: T, b: &Poly<T>) {
    acc.iter_mut().zip(b.iter()).for_each(|(a, b)| *a += s * *b);
}

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

/// Every essential matrix `E` with `x̂₂ᵢᵀ E x̂₁ᵢ = 0` for five pairs of normalised coordinates
/// (`x̂ = K⁻¹ x`, undistorted): up to [`MAX_FIVE_POINT_SOLUTIONS`], unordered (see the module
/// docs for the method). Computes in `T` throughout: `f32` on a single-precision FPU never
/// touches software `f64`.
///
/// Errors: [`Error::NonFinite`]; [`Error::Degenerate`] when the five rows are dependent, the
/// elimination meets a zero pivot, or no real root gives an essential matrix.
///
/// ```
/// use camgeom::nalgebra::{Point2, Point3, Vector3};
/// use camgeom::twoview::{Essential, RelativePose, five_point};
///
/// let pose = RelativePose::<f32>::from_rodrigues(
///     Vector3::new(0.05, -0.1, 0.02),
///     Vector3::new(-1.0, 0.1, 0.2),
/// )?;
/// let scene = [[0.3, -0.2, 5.0], [-0.6, 0.4, 6.0], [0.8, 0.7, 4.5], [-0.2, -0.9, 7.0], [0.1, 0.2, 5.5]];
/// let x1 = scene.map(|[x, y, z]| Point2::new(x / z, y / z));
/// let x2 = scene.map(|p| {
///     let q = pose.apply(&Point3::from(p));
///     Point2::new(q.x / q.z, q.y / q.z)
/// });
/// let truth = Essential::from_pose(&pose)?;
/// let best = five_point(&x1, &x2)?
///     .iter()
///     .map(|e| (e.matrix() - truth.matrix()).amax().min((e.matrix() + truth.matrix()).amax()))
///     .fold(f32::INFINITY, f32::min);
/// assert!(best < 1e-3);
/// # Ok::<(), camgeom::Error>(())
/// ```
pub fn five_point<T: Real>(
    x1: &[Point2<T>; 5],
    x2: &[Point2<T>; 5],
) -> Result<Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>> {
    if single::<T>() {
        solve(x1, x2, &SINGLE, &Tolerances::of(&SINGLE))
    } else {
        solve(x1, x2, &DOUBLE, &Tolerances::of(&DOUBLE))
    }
}

fn solve<T: Real>(
    x1: &[Point2<T>; 5],
    x2: &[Point2<T>; 5],
    precision: &Precision,
    tol: &Tolerances<T>,
) -> Result<Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>> {
    let mut raw = [[T::zero(); 9]; 5];
    let mut rows5 = [[T::zero(); 9]; 5];
    for (((a, b), row), unit) in x1
        .iter()
        .zip(x2.iter())
        .zip(raw.iter_mut())
        .zip(rows5.iter_mut())
    {
        check_finite(&[a.x, a.y, b.x, b.y])?;
        *row = epipolar_row(a, b);
        // Unit rows: the residual check below is then relative.
        let n = row.iter().fold(T::zero(), |acc, v| acc + *v * *v).sqrt();
        *unit = row.map(|v| v / n);
    }
    let basis: [Matrix3<T>; 4] = match precision.null_space {
        NullSpace::Svd => {
            let mut qr = StreamingQr::<T, 9>::new();
            for r in &raw {
                qr.push_row(r)?;
            }
            let svd = qr.svd()?;
            let [s1, _, _, _, s5, ..]: [T; 9] = svd.singular_values.into();
            if !above(s5, tol.rank * s1) {
                return Err(Error::Degenerate);
            }
            let basis = |k: usize| unvec(&crate::linalg::column(&svd.v, k));
            [basis(5), basis(6), basis(7), basis(8)]
        }
        NullSpace::GaussJordan => null_space(&rows5, tol.rank)?.map(|v| unvec(&v.into())),
    };
    let mut out = Vec::new();
    match precision.method {
        Method::HiddenVariable => hidden_variable(&basis, &rows5, tol, &mut out)?,
        Method::ActionMatrix => action_matrix(&basis, &rows5, tol, &mut out)?,
    }
    if out.is_empty() {
        Err(Error::Degenerate)
    } else {
        Ok(out)
    }
}

/// The hidden-variable solve (module docs, steps 3-6) with `E = x X + y Y + z Z + W` for
/// `basis = [X, Y, Z, W]`, appending the solutions to `out`.
fn hidden_variable<T: Real>(
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

/// The action-matrix solve with `E = x X + y Y + z Z + W` for `basis = [X, Y, Z, W]`,
/// appending the solutions to `out`.
///
/// 1. The ten cubics (module docs, step 2), their columns ordered as [`ACTION_COLUMNS`]: the
///    ten monomials of degree 3 first, then the basis `b = (x², xy, xz, y², yz, z², x, y,
///    z, 1)`. Gauss-Jordan elimination of the first ten columns gives each cubic monomial as
///    a combination of `b` at every solution.
/// 2. Multiplication by `x` maps each monomial of `b` to a cubic one (six of them: a row of
///    the eliminated system) or to one of `b` (four: a unit row): `M b = x b` at every
///    solution, so the solutions' `x` are the real eigenvalues of the 10x10 `M`, and `b` its
///    eigenvectors (Stewénius, Engels and Nistér 2006).
/// 3. For each real eigenvalue `x`: `(x : y : z : 1)` from the eigenvector
///    ([`eigenvector_point`]), then the chord polish on `E` ([`polish_direct`]) and the checks
///    of [`keep`].
fn action_matrix<T: Real>(
    basis: &[Matrix3<T>; 4],
    rows5: &[[T; 9]; 5],
    tol: &Tolerances<T>,
    out: &mut Vec<Essential<T>, MAX_FIVE_POINT_SOLUTIONS>,
) -> Result<()> {
    let a = constraints(&linear_entries(basis));
    let mut p: [Poly<T>; 10] =
        a.map(|row| ACTION_COLUMNS.map(|c| row.get(usize::from(c)).copied().unwrap_or(T::zero())));
    gauss_jordan(&mut p, tol.pivot)?;
    // Row j of M: x b_j as a combination of b.
    let m: [[T; 10]; 10] = X_TIMES_BASIS.map(|(eliminated, i)| {
        let i = usize::from(i);
        if eliminated {
            let row = p.get(i).copied().unwrap_or([T::zero(); 20]);
            core::array::from_fn(|k| -row.get(10 + k).copied().unwrap_or(T::zero()))
        } else {
            core::array::from_fn(|k| if k == i { T::one() } else { T::zero() })
        }
    });
    let Some(eigenvalues) = real_eigenvalues(&m) else {
        return Err(Error::Degenerate);
    };
    let [bx, by, bz, bw] = basis;
    for &lambda in eigenvalues.iter() {
        let Some(h) = eigenvector_point(&m, lambda) else {
            continue;
        };
        let [hx, hy, hz, hw] = h;
        let size = (hx * hx + hy * hy + hz * hz + hw * hw).sqrt();
        if !above(hw.abs(), tol.homogeneous * size) {
            continue;
        }
        // The polished E meets the ten constraints to rounding: it is on the manifold to
        // that accuracy, scaled to |E| = √2 (unit translation); a root whose constraint
        // residual stays above `solution` |E|³ is not a solution.
        let (x, y, z, cost) = polish_direct(basis, hx / hw, hy / hw, hz / hw);
        let e: Matrix3<T> = *bx * x + *by * y + *bz * z + *bw;
        let n = e.norm();
        let bound = tol.solution * n * n * n;
        if !above(bound * bound, cost) || !above(n, T::zero()) {
            continue;
        }
        let e = e * (T::lit(core::f64::consts::SQRT_2) / n);
        if !e.iter().all(|v| v.finite()) {
            continue;
        }
        keep(Essential { e }, rows5, tol, out);
    }
    Ok(())
}

/// `(x, y, z, 1)` up to scale at the solution whose `x` is the eigenvalue `lambda` of the
/// action matrix `m` ([`action_matrix`]), from its eigenvector `b`.
///
/// The four unit rows of `M b = x b` say `b₀ = x b₆`, `b₁ = x b₇`, `b₂ = x b₈`, `b₆ = x b₉`
/// (`x² = x·x`, `xy = x·y`, `xz = x·z`, `x = x·1`); substituted into the six other rows they
/// leave a 6x6 system whose null vector ([`crate::linalg`]'s `null_vector`: LU, inverse
/// iteration) costs about a fifth of the 10x10 one. For `|x| ≤ 1` the unknowns are the low
/// monomials `(y², yz, z², y, z, 1)` (factors `x`, `x²` in the substitution); above, the
/// high ones `(x², xy, xz, y², yz, z²)` (factors `1/x`, `1/x²`), as partial pivoting would
/// choose: one way only, the `x²`, `x³` of a solution far from the origin cost its digits
/// (noise-study misses 0.4-0.6 % against 0.2-0.45 %). The point is read from the multiple of
/// `(y, z, 1)` or of `(x, y, z)` with the largest factor; `x` itself is the eigenvalue.
fn eigenvector_point<T: Real>(m: &[[T; 10]; 10], lambda: T) -> Option<[T; 4]> {
    let l = lambda;
    // Entry (r, k) of M - λ I.
    let d = |r: usize, k: usize| {
        let v = m
            .get(r)
            .and_then(|row| row.get(k))
            .copied()
            .unwrap_or(T::zero());
        if k == r { v - l } else { v }
    };
    if l.abs() <= T::one() {
        // Unknowns (y², yz, z², y, z, 1): b₀ = x² b₉, b₁ = x b₇, b₂ = x b₈, b₆ = x b₉.
        let a: [[T; 6]; 6] = core::array::from_fn(|r| {
            [
                d(r, 3),
                d(r, 4),
                d(r, 5),
                d(r, 7) + l * d(r, 1),
                d(r, 8) + l * d(r, 2),
                d(r, 9) + l * (d(r, 6) + l * d(r, 0)),
            ]
        });
        let [y2, yz, z2, y, z, one] = null_vector(&a)?;
        // (y, z, 1) times 1, y or z: the one with the largest factor (its last entry).
        let [hy, hz, hw] = largest_at([[y, z, one], [y2, yz, y], [yz, z2, z]], 2);
        Some([l * hw, hy, hz, hw])
    } else {
        // |x| > 1, the substitution the other way (as partial pivoting would take it):
        // unknowns (x², xy, xz, y², yz, z²) with b₆ = b₀ / x, b₇ = b₁ / x, b₈ = b₂ / x,
        // b₉ = b₀ / x².
        let u = T::one() / l;
        let a: [[T; 6]; 6] = core::array::from_fn(|r| {
            [
                d(r, 0) + u * (d(r, 6) + u * d(r, 9)),
                d(r, 1) + u * d(r, 7),
                d(r, 2) + u * d(r, 8),
                d(r, 3),
                d(r, 4),
                d(r, 5),
            ]
        });
        let [x2, xy, xz, y2, yz, z2] = null_vector(&a)?;
        // (x, y, z) times x, y or z: the one with the largest factor (its first entry over x).
        let [hx, hy, hz] = largest_at([[x2, xy, xz], [xy, y2, yz], [xz, yz, z2]], 0);
        // (hx, hy, hz) = s (x, y, z) with s = hx / x.
        Some([hx, hy, hz, hx * u])
    }
}

/// The candidate with the largest `|c[at]|` (the first of equal ones).
fn largest_at<T: Real>(candidates: [[T; 3]; 3], at: usize) -> [T; 3] {
    let key = |c: &[T; 3]| c.get(at).map_or(T::zero(), |v| v.abs());
    candidates.into_iter().fold(
        [T::zero(); 3],
        |best, c| if key(&c) > key(&best) { c } else { best },
    )
}

/// `E` as linear polynomials in `(x, y, z, 1)`, row-major, for `basis = [X, Y, Z, W]`.
fn linear_entries<T: Real>(basis: &[Matrix3<T>; 4]) -> [[Linear<T>; 3]; 3] {
    let [bx, by, bz, bw] = basis;
    core::array::from_fn(|i| {
        core::array::from_fn(|j| {
            let at = |m: &Matrix3<T>| m.get((i, j)).copied().unwrap_or(T::zero());
            [at(bx), at(by), at(bz), at(bw)]
        })
    })
}

/// Appends `e` to `out` when it meets the five epipolar equations to `tol.solution` (unit
/// rows) and is not within `tol.duplicate` of a solution already there.
fn keep<T: Real>(
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

/// The ten cubics (module docs, step 2) of `E` given as linear polynomials: `det E` and the
/// nine entries of `2 E Eᵀ E - tr(E Eᵀ) E`.
fn constraints<T: Real>(e: &[[Linear<T>; 3]; 3]) -> [Poly<T>; 10] {
    // E Eᵀ (symmetric: a sum of three two-term products per monomial is exact in either
    // operand order) and its trace.
    let mut eet = [[[T::zero(); 10]; 3]; 3];
    for i in 0..3 {
        for j in i..3 {
            let (Some(ri), Some(rj)) = (e.get(i), e.get(j)) else {
                continue;
            };
            let mut acc = [T::zero(); 10];
            for (a, b) in ri.iter().zip(rj.iter()) {
                add_assign(&mut acc, &mul_ll(a, b));
            }
            for (r, c) in [(i, j), (j, i)] {
                if let Some(slot) = eet.get_mut(r).and_then(|row| row.get_mut(c)) {
                    *slot = acc;
                }
            }
        }
    }
    let mut trace = [T::zero(); 10];
    for (i, row) in eet.iter().enumerate() {
        if let Some(d) = row.get(i) {
            add_assign(&mut trace, d);
        }
    }
    let mut a = [[T::zero(); 20]; 10];
    let mut rows = a.iter_mut();
    if let Some(r) = rows.next() {
        let [[e11, e12, e13], [e21, e22, e23], [e31, e32, e33]] = e;
        let c1 = sub(&mul_ll(e22, e33), &mul_ll(e23, e32));
        let c2 = sub(&mul_ll(e21, e33), &mul_ll(e23, e31));
        let c3 = sub(&mul_ll(e21, e32), &mul_ll(e22, e31));
        *r = sub(&mul_lq(e11, &c1), &mul_lq(e12, &c2));
        add_assign(r, &mul_lq(e13, &c3));
    }
    let two = T::lit(2.0);
    for (eet_row, e_row) in eet.iter().zip(e.iter()) {
        for (j, e_ij) in e_row.iter().enumerate() {
            if let Some(r) = rows.next() {
                // (E Eᵀ E)_ij = Σₖ (E Eᵀ)_ik E_kj.
                let mut d = [T::zero(); 20];
                for (q, e_k) in eet_row.iter().zip(e.iter()) {
                    if let Some(l) = e_k.get(j) {
                        add_assign(&mut d, &mul_ql(q, l));
                    }
                }
                *r = [T::zero(); 20];
                axpy(r, two, &d);
                axpy(r, -T::one(), &mul_ql(&trace, e_ij));
            }
        }
    }
    a
}

/// Gauss-Newton steps polishing a root on the ten cubics.
const POLISH_ITERATIONS: u8 = 4;

/// `[1, v, v², v³]` and the derivatives `[0, 1, 2v, 3v²]`, as `Π v` and `k Π v` products
/// from `1` (the order of the original power loops, so the `f64` results are unchanged).
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
fn polish<T: Real>(a: &[Poly<T>; 10], x: T, y: T, z: T) -> (T, T, T) {
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
fn polish_direct<T: Real>(basis: &[Matrix3<T>; 4], x: T, y: T, z: T) -> (T, T, T, T) {
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

/// Reduces the first ten columns of `a` to the identity (partial pivoting). Errors with
/// [`Error::Degenerate`] when a pivot is below `tol` times the largest entry.
fn gauss_jordan<T: Real>(a: &mut [Poly<T>; 10], tol: T) -> Result<()> {
    let scale = a
        .iter()
        .flat_map(|r| r.iter())
        .fold(T::zero(), |m, v| larger(m, v.abs()));
    if !above(scale, T::zero()) || !scale.finite() {
        return Err(Error::Degenerate);
    }
    for c in 0..10 {
        let mut p = c;
        let mut pmax = T::zero();
        for (i, r) in a.iter().enumerate().skip(c) {
            let v = r.get(c).map_or(T::zero(), |v| v.abs());
            // `>=`: the last of equal maxima, as the original `max_by`.
            if v >= pmax {
                p = i;
                pmax = v;
            }
        }
        // In place: whole-row copies of these 80-byte rows are `memcpy` calls on a Cortex-M.
        swap_rows(a, c, p);
        let Some((before, rest)) = a.split_at_mut_checked(c) else {
            return Err(Error::Degenerate);
        };
        let Some((pivot, after)) = rest.split_first_mut() else {
            return Err(Error::Degenerate);
        };
        let pv = pivot.get(c).copied().unwrap_or(T::zero());
        if !above(pv.abs(), tol * scale) {
            return Err(Error::Degenerate);
        }
        pivot.iter_mut().for_each(|v| *v /= pv);
        for row in before.iter_mut().chain(after.iter_mut()) {
            let f = row.get(c).copied().unwrap_or(T::zero());
            if f != T::zero() {
                axpy(row, -f, pivot);
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
        let p = mul_ll(&[1.0, 0.0, 0.0, 1.0], &[0.0, 1.0, 1.0, 0.0]);
        let at = |e: [u8; 3]| {
            let i = index_of(e).unwrap() as u8;
            p[QUADRATIC.iter().position(|q| *q == i).unwrap()]
        };
        assert_eq!(at([1, 1, 0]), 1.0);
        assert_eq!(at([1, 0, 1]), 1.0);
        assert_eq!(at([0, 1, 0]), 1.0);
        assert_eq!(at([0, 0, 1]), 1.0);
        assert_eq!(p.iter().filter(|c| **c != 0.0).count(), 4);
        // (x² + 2 yz + 3)(z - 1) and (z - 1)(x² + 2 yz + 3), term by term.
        let mut q = [0.0; 10];
        q[QUADRATIC.iter().position(|i| *i == 5).unwrap()] = 1.0; // x²
        q[QUADRATIC.iter().position(|i| *i == 14).unwrap()] = 2.0; // yz
        q[9] = 3.0; // 1
        let l = [0.0, 0.0, 1.0, -1.0];
        let (a, b) = (mul_ql(&q, &l), mul_lq(&l, &q));
        assert_eq!(a, b);
        let expect = [
            ([2, 0, 1], 1.0),
            ([2, 0, 0], -1.0),
            ([0, 1, 2], 2.0),
            ([0, 1, 1], -2.0),
            ([0, 0, 1], 3.0),
            ([0, 0, 0], -3.0),
        ];
        for (e, c) in expect {
            assert_eq!(a[index_of(e).unwrap()], c, "{e:?}");
        }
        assert_eq!(a.iter().filter(|c| **c != 0.0).count(), 6);
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

    /// An exact two-view problem: normalised points of five scene points in front of both
    /// cameras of a random relative pose, and the true `E`.
    fn random_problem(g: &mut Pcg32) -> ([Point2<f64>; 5], [Point2<f64>; 5], Essential<f64>) {
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
        (x1, x2, Essential::from_pose(&pose).unwrap())
    }

    /// `min |E - E_true|` (max entry, up to sign) over the solutions; infinity for none.
    fn closest<T: Real>(sols: &Result<Vec<Essential<T>, 10>>, truth: &Matrix3<f64>) -> f64 {
        sols.iter()
            .flatten()
            .map(|e| {
                let m = e.matrix().map(|v| v.to_f64());
                (m - truth).amax().min((m + truth).amax())
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn f32_agrees_with_f64() {
        let mut g = Pcg32::new(5);
        let (mut both, mut f64_only, mut solutions) = (0, 0, 0);
        let mut worst_residual = 0.0f32;
        let trials = 2000;
        for _ in 0..trials {
            let (x1, x2, truth) = random_problem(&mut g);
            let (a, b) = (x1.map(|p| p.cast::<f32>()), x2.map(|p| p.cast::<f32>()));
            let s32 = five_point(&a, &b);
            let s64 = five_point(&x1, &x2);
            // 1e-3 on a unit-norm E: a pose within ~0.05°, well inside what a RANSAC
            // hypothesis needs (its refit and polish follow).
            let hit32 = closest(&s32, truth.matrix()) < 1e-3;
            let hit64 = closest(&s64, truth.matrix()) < 1e-3;
            both += usize::from(hit32 && hit64);
            f64_only += usize::from(hit64 && !hit32);
            solutions += s32.as_ref().map_or(0, |v| v.len());
            // What the solver guarantees: |x̂₂ᵀ E x̂₁| below 1e-5 |row| (SINGLE.solution).
            for e in s32.iter().flatten() {
                for (p, q) in a.iter().zip(b.iter()) {
                    let row = epipolar_row(p, q);
                    let n = row.iter().map(|v| v * v).sum::<f32>().sqrt();
                    worst_residual = worst_residual.max(e.residual(p, q).abs() / n);
                }
            }
        }
        std::println!(
            "f32 five-point: true E found in {both} of {trials} problems, missed in {f64_only} that f64 solves; {solutions} solutions; worst residual {worst_residual:e}"
        );
        // 19 misses measured (the action matrix; two hidden-variable passes: 32): at most
        // 1.5 %, room for other rounding on other targets.
        assert!(f64_only * 200 <= trials * 3, "{f64_only} misses");
        // The acceptance bound, with a few ulps for recomputing the rows here.
        assert!(worst_residual < 1.001e-5, "{worst_residual:e}");
    }

    #[test]
    fn bad_input_gets_typed_errors() {
        let mut g = Pcg32::new(9);
        let (x1, x2, _) = random_problem(&mut g);
        let (a, b) = (x1.map(|p| p.cast::<f32>()), x2.map(|p| p.cast::<f32>()));
        for bad in [f32::NAN, f32::INFINITY] {
            let mut c = a;
            c[3].y = bad;
            assert_eq!(five_point(&c, &b), Err(Error::NonFinite));
            assert_eq!(five_point(&b, &c), Err(Error::NonFinite));
        }
        let mut c = x1;
        c[0].x = f64::NAN;
        assert_eq!(five_point(&c, &x2), Err(Error::NonFinite));
        // Five copies of one pair: one row, rank 1.
        let one = [a[0]; 5];
        let two = [b[0]; 5];
        assert_eq!(five_point(&one, &two), Err(Error::Degenerate));
        assert_eq!(
            five_point(&one.map(|p| p.cast::<f64>()), &two.map(|p| p.cast::<f64>())),
            Err(Error::Degenerate)
        );
        // All zeros.
        let z = [Point2::<f32>::origin(); 5];
        assert_eq!(five_point(&z, &z), Err(Error::Degenerate));
        // Four distinct pairs and a repeat: rank 4.
        let mut c = a;
        let mut d = b;
        c[4] = c[1];
        d[4] = d[1];
        assert_eq!(five_point(&c, &d), Err(Error::Degenerate));
    }

    #[test]
    fn f32_bench_input_matches_f64() {
        // The bench's exact five pairs (host-tests/data/fixtures/twoview_bench/five.csv, the
        // camera f = 600, c = (320, 240)): f64 finds four solutions; f32 finds each of them
        // to 1e-4 (a few hundred f32 ulps of a unit-norm E, from the polish's rounding).
        let px = [
            [
                395.6215826733664,
                257.7826090368998,
                261.78273261414415,
                242.64705933954954,
            ],
            [
                438.3366437757332,
                161.42522338084143,
                302.05165621110893,
                151.59034354621886,
            ],
            [
                575.1772192176197,
                102.07258249756234,
                391.27309833544234,
                108.43227676164781,
            ],
            [
                191.20062785350527,
                262.9048275077793,
                25.49502566821053,
                246.37867117848415,
            ],
            [
                444.8422694538728,
                369.54239333648275,
                258.56726282485647,
                353.7895241974363,
            ],
        ];
        let n = |x: f64, y: f64| Point2::new((x - 320.0) / 600.0, (y - 240.0) / 600.0);
        let x1: [Point2<f64>; 5] = core::array::from_fn(|i| n(px[i][0], px[i][1]));
        let x2: [Point2<f64>; 5] = core::array::from_fn(|i| n(px[i][2], px[i][3]));
        let s64 = five_point(&x1, &x2).unwrap();
        let s32 = five_point(&x1.map(|p| p.cast::<f32>()), &x2.map(|p| p.cast::<f32>())).unwrap();
        assert_eq!(s32.len(), s64.len());
        for e in &s64 {
            let d = closest(&Ok(s32.clone()), e.matrix());
            assert!(d < 1e-4, "{d:e}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

        /// Whatever f32 returns is an essential matrix through the five pairs: on the
        /// manifold (σ₁ = σ₂ = 1, σ₃ = 0 to 1e-4: the ten constraints hold to 1e-5 |E|³,
        /// which bounds det E and so σ₃ to a few 1e-5) and satisfying every epipolar
        /// constraint to the acceptance bound.
        #[test]
        fn f32_solutions_are_essential(seed in 0u64..u64::MAX) {
            let mut g = Pcg32::new(seed);
            let (x1, x2, _) = random_problem(&mut g);
            let (a, b) = (x1.map(|p| p.cast::<f32>()), x2.map(|p| p.cast::<f32>()));
            if let Ok(sols) = five_point(&a, &b) {
                for e in &sols {
                    let s = crate::linalg::svd_jacobi(e.matrix()).unwrap().singular_values;
                    proptest::prop_assert!((s[0] - 1.0).abs() < 1e-4 && (s[1] - 1.0).abs() < 1e-4, "{s:?}");
                    proptest::prop_assert!(s[2] < 1e-4, "{s:?}");
                    for (p, q) in a.iter().zip(b.iter()) {
                        let row = epipolar_row(p, q);
                        let n = row.iter().map(|v| v * v).sum::<f32>().sqrt();
                        proptest::prop_assert!(e.residual(p, q).abs() <= 1.001e-5 * n);
                    }
                }
            }
        }
    }
}
