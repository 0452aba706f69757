//! The plane geometry of a quad, shared by the quad fit (`quad.rs`) and the full-resolution
//! work on a quad (`decode.rs`): lines in point-normal form, their intersection, the line
//! fit's moments and 2x2 eigen-decomposition, corner indexing and the projection of tag
//! coordinates.

use nalgebra::{Matrix3, Point2};

use crate::scalar::{above, at_most, larger};

/// A line through `(ex, ey)` with unit normal `(nx, ny)` (AprilTag's `lines[i]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Line {
    pub(crate) ex: f32,
    pub(crate) ey: f32,
    pub(crate) nx: f32,
    pub(crate) ny: f32,
}

impl Line {
    /// The line through the origin with a zero normal (a placeholder before a fit).
    pub(crate) const ZERO: Self = Self {
        ex: 0.0,
        ey: 0.0,
        nx: 0.0,
        ny: 0.0,
    };
}

/// Lines whose normals span less than this, `|det| = |sin θ|` for the angle `θ` between
/// them, are parallel for [`intersect`].
pub(crate) const PARALLEL: f32 = 1e-3;

/// Intersection of lines `a` and `b` (AprilTag's 2x2 solve): with the directions
/// `u_a = (n_a.y, -n_a.x)`, `u_b = (n_b.y, -n_b.x)`, the point `e_a + l₀ u_a` where
/// `[u_a  -u_b] (l₀, l₁)ᵀ = e_b - e_a`, `det = n_a.y n_b.x - n_a.x n_b.y`.
///
/// `None` when `|det| < 0.001` ([`PARALLEL`]), the rule of AprilTag 3's quad fit
/// (`fit_quad`: `fabs(det) < 0.001` rejects the quad); its edge refinement rejects
/// `fabs(det) <= 0.001` instead, and both use this one rule here, so `|det| = 0.001` exactly
/// intersects.
pub(crate) fn intersect(a: &Line, b: &Line) -> Option<Point2<f32>> {
    let (a00, a01, a10, a11) = (a.ny, -b.ny, -a.nx, b.nx);
    let (b0, b1) = (b.ex - a.ex, b.ey - a.ey);
    let det = a00 * a11 - a10 * a01;
    if !at_most(PARALLEL, det.abs()) {
        return None;
    }
    let l0 = (a11 * b0 - a01 * b1) / det;
    Some(Point2::new(a.ex + l0 * a00, a.ey + l0 * a10))
}

/// `(λ_min, λ_max, n_x, n_y)` of the symmetric 2x2 matrix `[cxx cxy; cxy cyy]` (a covariance:
/// AprilTag's `fit_line`): [`eigenvalues`] and [`normal`].
#[inline]
pub(crate) fn eigen(cxx: f32, cxy: f32, cyy: f32) -> (f32, f32, f32, f32) {
    let (small, big) = eigenvalues(cxx, cxy, cyy);
    let (nx, ny) = normal(cxx, cxy, cyy, big);
    (small, big, nx, ny)
}

/// `(λ_min, λ_max)` of the symmetric 2x2 matrix `[cxx cxy; cxy cyy]`:
/// `λ = (cxx + cyy ∓ √((cxx - cyy)² + 4 cxy²)) / 2`, `λ_min` clamped at 0 (NaN gives 0).
#[inline]
pub(crate) fn eigenvalues(cxx: f32, cxy: f32, cyy: f32) -> (f32, f32) {
    let d = libm::sqrtf((cxx - cyy) * (cxx - cyy) + 4.0 * cxy * cxy);
    // `max(0)` without the library call (`fmaxf` on the M4/M7): the difference is never -0.
    let small = larger(0.0, 0.5 * (cxx + cyy - d));
    let big = 0.5 * (cxx + cyy + d);
    (small, big)
}

/// The unit eigenvector of `[cxx cxy; cxy cyy]` for the smaller eigenvalue, given the larger
/// `big` ([`eigenvalues`]): the normal of the fitted line, the longer of the two columns of
/// `C - λ_max I` normalised; `(0, 0)` when both vanish (an isotropic `C`).
#[inline]
pub(crate) fn normal(cxx: f32, cxy: f32, cyy: f32, big: f32) -> (f32, f32) {
    let (nx1, ny1) = (cxx - big, cxy);
    let (nx2, ny2) = (cxy, cyy - big);
    let (m1, m2) = (nx1 * nx1 + ny1 * ny1, nx2 * nx2 + ny2 * ny2);
    let (nx, ny, m) = if m1 > m2 {
        (nx1, ny1, m1)
    } else {
        (nx2, ny2, m2)
    };
    let len = libm::sqrtf(m);
    if len < 1e-12 {
        (0.0, 0.0)
    } else {
        (nx / len, ny / len)
    }
}

/// The first and second moments of points relative to an origin `o`, for a least-squares
/// line (AprilTag's `fit_line` on sums): the points are taken as `p - o`, so with `o` near
/// them the `f32` covariance `C = E[q qᵀ] - E[q] E[q]ᵀ` does not cancel the large squares of
/// image coordinates.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineMoments {
    ox: f32,
    oy: f32,
    mx: f32,
    my: f32,
    mxx: f32,
    mxy: f32,
    myy: f32,
    /// How many points were added.
    pub(crate) count: u32,
}

impl LineMoments {
    /// No points yet, relative to `(ox, oy)`.
    pub(crate) fn new(ox: f32, oy: f32) -> Self {
        Self {
            ox,
            oy,
            mx: 0.0,
            my: 0.0,
            mxx: 0.0,
            mxy: 0.0,
            myy: 0.0,
            count: 0,
        }
    }

    /// Adds the point `(x, y)`.
    #[inline]
    pub(crate) fn add(&mut self, x: f32, y: f32) {
        let (bx, by) = (x - self.ox, y - self.oy);
        self.mx += bx;
        self.my += by;
        self.mxx += bx * bx;
        self.mxy += bx * by;
        self.myy += by * by;
        self.count += 1;
    }

    /// The line through the points' mean along the covariance's major axis, with the mean
    /// squared distance of the points to it (`λ_min` of [`eigen`]); `None` with fewer than
    /// two points or an isotropic covariance (no direction).
    pub(crate) fn fit(&self) -> Option<(Line, f32)> {
        if self.count < 2 {
            return None;
        }
        let nf = self.count as f32;
        let (ex, ey) = (self.mx / nf, self.my / nf);
        let (cxx, cxy, cyy) = (
            self.mxx / nf - ex * ex,
            self.mxy / nf - ex * ey,
            self.myy / nf - ey * ey,
        );
        let (mse, _, nx, ny) = eigen(cxx, cxy, cyy);
        if nx == 0.0 && ny == 0.0 {
            return None;
        }
        let line = Line {
            ex: ex + self.ox,
            ey: ey + self.oy,
            nx,
            ny,
        };
        Some((line, mse))
    }
}

/// Element `i mod 4` of a quad's corners or lines (no bounds check needed).
#[inline]
pub(crate) fn at4<T: Copy>(a: &[T; 4], i: usize) -> T {
    let [a0, a1, a2, a3] = *a;
    match i & 3 {
        0 => a0,
        1 => a1,
        2 => a2,
        _ => a3,
    }
}

/// `H (x, y, 1)ᵀ` dehomogenised: the pixel of tag point `(x, y)`; `None` at or beyond the
/// horizon (`w ≤ 10⁻⁹`).
#[inline]
pub(crate) fn project(h: &Matrix3<f32>, x: f32, y: f32) -> Option<Point2<f32>> {
    let w = h.m31 * x + h.m32 * y + h.m33;
    if !above(w, 1e-9) {
        return None;
    }
    Some(Point2::new(
        (h.m11 * x + h.m12 * y + h.m13) / w,
        (h.m21 * x + h.m22 * y + h.m23) / w,
    ))
}
