//! The precision-dependent choices of the five-point solver: which null space, which solver
//! and which tolerances, one set for `f64` and one for `f32`.

use crate::scalar::Real;

/// How the null space of the five epipolar rows is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum NullSpace {
    /// Last four right singular vectors of the QR + Jacobi SVD.
    Svd,
    /// Gauss-Jordan with full pivoting, then modified Gram-Schmidt.
    GaussJordan,
}

/// How the ten cubics are solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Method {
    /// Nistér's hidden variable: the degree-10 polynomial `det B(z)`, its real roots, Gauss-Newton
    /// on the reduced cubics, SVD projection onto the manifold.
    HiddenVariable,
    /// Stewénius' action matrix: the real eigenvalues and eigenvectors of multiplication by
    /// `x` on the ten monomials of degree ≤ 2 (`action_matrix`), then the chord polish on
    /// `E` itself (`polish_direct`).
    ActionMatrix,
}

/// The precision-dependent choices of the solver.
#[derive(Debug, Clone, Copy)]
pub(super) struct Precision {
    pub(super) null_space: NullSpace,
    pub(super) method: Method,
    /// Smallest `σ₅ / σ₁` (SVD) or last pivot / first pivot (Gauss-Jordan) of the five rows.
    pub(super) rank: f64,
    /// Smallest pivot of the 10x20 elimination, relative to the largest entry.
    pub(super) pivot: f64,
    /// Smallest `|w| / |(x, y, z, w)|` of a solution's homogeneous coordinates in the basis
    /// (`w = 0`: at infinity in the parametrisation `E = x X + y Y + z Z + W`).
    pub(super) homogeneous: f64,
    /// Largest `|x̂₂ᵀ E x̂₁| / (|E| |row|)` over the five pairs for a root to count as a
    /// solution.
    pub(super) solution: f64,
    /// Two solutions closer than this (max entry, up to sign) are one.
    pub(super) duplicate: f64,
}

/// `f64`: the SVD null space and Nistér's hidden variable, with tight tolerances.
pub(super) const DOUBLE: Precision = Precision {
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
pub(super) const SINGLE: Precision = Precision {
    null_space: NullSpace::GaussJordan,
    method: Method::ActionMatrix,
    rank: 1e-4,
    pivot: 1e-6,
    homogeneous: 1e-6,
    solution: 1e-5,
    duplicate: 1e-3,
};

/// The tolerances of a [`Precision`] in `T`, converted where the precision is a constant
/// (inlined into `five_point`), so no `f64` survives to run time in the `f32` code.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tolerances<T> {
    pub(super) rank: T,
    pub(super) pivot: T,
    pub(super) homogeneous: T,
    pub(super) solution: T,
    pub(super) duplicate: T,
}

impl<T: Real> Tolerances<T> {
    #[inline(always)]
    pub(super) fn of(p: &Precision) -> Self {
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
pub(super) const fn single<T>() -> bool {
    core::mem::size_of::<T>() <= 4
}
