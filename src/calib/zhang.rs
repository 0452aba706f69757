//! The closed-form start of a calibration: intrinsics from the plane homographies of the
//! views (Zhang 2000), and OpenCV's fallback with a known principal point.

use heapless::Vec;
use nalgebra::{Matrix3, Vector3};

use super::config::CalibrationParams;
use super::views::Views;
use crate::camera::CAMERA_PARAMETERS;
use crate::homography::{Homography, dlt};
use crate::linalg::StreamingQr;
use crate::scalar::{Real, above};
use crate::{Error, Result};

/// The closed-form camera of `views` as the normalised parameter vector (module docs,
/// step 2): Zhang's closed form on the per-view homographies, or, with a fixed principal point
/// or aspect ratio, or when Zhang's has no positive-definite solution, OpenCV's
/// initialisation ([`focal_with_principal_point`]); zero distortion.
///
/// Errors: [`Error::TooFewPoints`] with fewer than 3 views whose homography is found, those
/// of [`focal_with_principal_point`] otherwise.
pub(super) fn closed_form<T: Real, const V: usize, const P: usize>(
    views: &Views<T, V, P>,
    params: &CalibrationParams,
) -> Result<[T; CAMERA_PARAMETERS]> {
    let fix_principal_point = params.config().flags.fix_principal_point;
    let aspect = params.aspect::<T>();
    // Per-view homographies (board units to normalised pixels), each from the board points
    // the view saw (at least 4, not all on a line, or `dlt` refuses the view).
    let mut homs: Vec<Homography<T>, V> = Vec::new();
    for v in 0..views.count {
        let (plane, obs) = views.view_plane(v);
        let plane = plane.get(..obs.len()).ok_or(Error::LengthMismatch)?;
        if let Ok(h) = dlt(plane, obs) {
            homs.push(h).map_err(|_| Error::BufferTooSmall("views"))?;
        }
    }
    if homs.len() < 3 {
        return Err(Error::TooFewPoints);
    }
    let closed = if fix_principal_point || aspect.is_some() {
        Err(Error::Degenerate)
    } else {
        zhang(homs.iter().copied())
    };
    let [fx, fy, cx, cy] = match closed {
        Ok(k) => k,
        Err(Error::Degenerate) => {
            let [fx, fy] = focal_with_principal_point(homs.iter().copied(), aspect)?;
            [fx, fy, T::zero(), T::zero()]
        }
        Err(e) => return Err(e),
    };
    let fx = aspect.map_or(fx, |a| a * fy);
    let z = T::zero();
    let mut p = [fx, fy, cx, cy, z, z, z, z, z];
    if fix_principal_point {
        p[2] = T::zero();
        p[3] = T::zero();
    }
    Ok(p)
}

/// Pinhole intrinsics `(fx, fy, cx, cy)`, zero skew.
type Pinhole<T> = [T; 4];

/// `vᵢⱼ(H)`: `hᵢᵀ B hⱼ = vᵢⱼᵀ b` for `b = (B11, B12, B22, B13, B23, B33)`.
fn v<T: Real>(hi: &Vector3<T>, hj: &Vector3<T>) -> [T; 6] {
    [
        hi.x * hj.x,
        hi.x * hj.y + hi.y * hj.x,
        hi.y * hj.y,
        hi.z * hj.x + hi.x * hj.z,
        hi.z * hj.y + hi.y * hj.z,
        hi.z * hj.z,
    ]
}

/// The first two columns of `H / |H|`.
fn columns<T: Real>(h: &Homography<T>) -> (Vector3<T>, Vector3<T>) {
    let m = h.matrix();
    let m: Matrix3<T> = m / m.norm();
    (
        Vector3::new(m.m11, m.m21, m.m31),
        Vector3::new(m.m12, m.m22, m.m32),
    )
}

/// Zhang's closed form: each homography `H = λ K [r₁ r₂ t]` gives `h₁ᵀ B h₂ = 0` and
/// `h₁ᵀ B h₁ = h₂ᵀ B h₂` on `B = K⁻ᵀ K⁻¹`; zero skew adds `B12 = 0`. The least-squares null
/// vector `b` of the stacked rows (streaming QR, then the SVD of its `R`: no `AᵀA`) gives
///
/// `v₀ = (B12 B13 - B11 B23) / (B11 B22 - B12²)`, `λ = B33 - (B13² + v₀ (B12 B13 - B11 B23)) / B11`,
/// `fx = √(λ / B11)`, `fy = √(λ B11 / (B11 B22 - B12²))`, `u₀ = -B13 fx² / λ`.
///
/// The homographies should map the board plane to pixel coordinates normalised to about unit
/// size. Errors with [`Error::Degenerate`] when the views do not fix `B` (fewer than three
/// distinct orientations, e.g. all parallel) or `B` is not positive definite (no camera fits).
fn zhang<T: Real>(hs: impl Iterator<Item = Homography<T>>) -> Result<Pinhole<T>> {
    let mut qr = StreamingQr::<T, 6>::new();
    let mut count = 0usize;
    for h in hs {
        // Each homography scaled to unit norm, so every view weighs alike.
        let (h1, h2) = columns(&h);
        let v12 = v(&h1, &h2);
        let (v11, v22) = (v(&h1, &h1), v(&h2, &h2));
        let diff: [T; 6] = core::array::from_fn(|k| {
            v11.get(k).copied().unwrap_or(T::zero()) - v22.get(k).copied().unwrap_or(T::zero())
        });
        qr.push_row(&v12)?;
        qr.push_row(&diff)?;
        count += 1;
    }
    if count < 3 {
        return Err(Error::TooFewPoints);
    }
    // Zero skew, weighted like one view's rows.
    let mut skew = [T::zero(); 6];
    if let Some(s) = skew.get_mut(1) {
        *s = T::one();
    }
    qr.push_row(&skew)?;
    let svd = qr.svd()?;
    let [s0, _, _, _, s4, _]: [T; 6] = svd.singular_values.into();
    // b is a 1-D null space: the second smallest singular value must stand clear of rounding.
    if !above(s4, T::lit(1e3) * T::EPSILON * s0) {
        return Err(Error::Degenerate);
    }
    let [b11, b12, b22, b13, b23, b33]: [T; 6] = svd.null_vector().into();
    // B is defined up to sign: make B11 positive.
    let sign = if b11 < T::zero() { -T::one() } else { T::one() };
    let (b11, b12, b22, b13, b23, b33) = (
        b11 * sign,
        b12 * sign,
        b22 * sign,
        b13 * sign,
        b23 * sign,
        b33 * sign,
    );
    let den = b11 * b22 - b12 * b12;
    if !above(b11, T::zero()) || !above(den, T::zero()) {
        return Err(Error::Degenerate);
    }
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let fx2 = lambda / b11;
    let fy2 = lambda * b11 / den;
    if !above(fx2, T::zero()) || !above(fy2, T::zero()) {
        return Err(Error::Degenerate);
    }
    let (fx, fy) = (fx2.sqrt(), fy2.sqrt());
    let u0 = -b13 * fx2 / lambda;
    let k = [fx, fy, u0, v0];
    if k.iter().all(|x| x.finite()) {
        Ok(k)
    } else {
        Err(Error::Degenerate)
    }
}

/// Focal lengths with the principal point known (at the origin of the homographies' image
/// coordinates), as OpenCV's `initIntrinsicParams2D`: `ω = diag(1/fx², 1/fy², 1)` and each
/// view's `h₁ᵀ ω h₂ = 0`, `h₁ᵀ ω h₁ = h₂ᵀ ω h₂`, linear in `(1/fx², 1/fy²)`, solved by least
/// squares (streaming QR). With `aspect = Some(a)`, `fx = a fy` and one unknown remains.
///
/// Errors with [`Error::Degenerate`] when the views do not fix the focal lengths (all nearly
/// fronto-parallel) or the solution is not positive.
fn focal_with_principal_point<T: Real>(
    hs: impl Iterator<Item = Homography<T>>,
    aspect: Option<T>,
) -> Result<[T; 2]> {
    let mut qr = StreamingQr::<T, 3>::new();
    let mut count = 0usize;
    for h in hs {
        let (h1, h2) = columns(&h);
        let rows = [
            [h1.x * h2.x, h1.y * h2.y, -h1.z * h2.z],
            [
                h1.x * h1.x - h2.x * h2.x,
                h1.y * h1.y - h2.y * h2.y,
                -(h1.z * h1.z - h2.z * h2.z),
            ],
        ];
        for [a, b, c] in rows {
            match aspect {
                // a = b / aspect²: one unknown in the second column.
                Some(r) => qr.push_row(&[T::zero(), a / (r * r) + b, c])?,
                None => qr.push_row(&[a, b, c])?,
            }
        }
        count += 1;
    }
    if count < 1 {
        return Err(Error::TooFewPoints);
    }
    let r = qr.r();
    let scale = r.amax();
    let tol = T::lit(1e3) * T::EPSILON * scale;
    let (wa, wb) = match aspect {
        Some(ar) => {
            if !above(r.m22.abs(), tol) {
                return Err(Error::Degenerate);
            }
            let wb = r.m23 / r.m22;
            (wb / (ar * ar), wb)
        }
        None => {
            if !above(r.m11.abs(), tol) || !above(r.m22.abs(), tol) {
                return Err(Error::Degenerate);
            }
            let wb = r.m23 / r.m22;
            ((r.m13 - r.m12 * wb) / r.m11, wb)
        }
    };
    if !above(wa, T::zero()) || !above(wb, T::zero()) {
        return Err(Error::Degenerate);
    }
    Ok([T::one() / wa.sqrt(), T::one() / wb.sqrt()])
}
