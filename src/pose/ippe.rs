//! IPPE: infinitesimal plane-based pose estimation (Collins & Bartoli, IJCV 2014).
//!
//! With the target centred on its centroid and `H` the homography from the target plane to
//! normalised image coordinates (`h₃₃ = 1`), the image of the centre is `v = (h₁₃, h₂₃)` and
//! the Jacobian of the map there is
//! `J = [h₁₁ - h₁₃h₃₁, h₁₂ - h₁₃h₃₂; h₂₁ - h₂₃h₃₁, h₂₂ - h₂₃h₃₂]`.
//! With `R_v` the rotation taking the optical axis to the ray `(v, 1)`,
//! `B = [1 0 -v₁; 0 1 -v₂] R_v[:, 0:2]` and `A = B⁻¹ J`, the rotation's upper-left block is
//! `R̃ = A / γ` (`γ` the largest singular value of `A`), completed to two rotations
//! `R₁,₂ = R_v [r̃₁ r̃₂ r̃₁ × r̃₂]` with `r̃ᵢ = (R̃ column i, ±bᵢ)`: the two poses a planar target
//! cannot tell apart at first order. Each gets its least-squares translation; they are returned
//! sorted by reprojection error.

use nalgebra::{Matrix2, Matrix3, Point2, Point3, Rotation3, Vector3};

use super::PoseEstimate;
use super::refine::refine_pose_with;
use crate::camera::Camera;
use crate::homography::{Homography, dlt};
use crate::linalg::{StreamingQr, closest_rotation};
use crate::scalar::{Real, above, check_finite};
use crate::transform::Pose;
use crate::{Error, Result};

/// Options of [`solve_planar`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlanarConfig {
    /// Levenberg-Marquardt iterations applied to each IPPE solution refined (0: none).
    pub refine_iterations: u8,
    /// The second IPPE solution is refined only when its unrefined RMS reprojection error is
    /// at most `alternative_ratio` times the best's (refined): when it could rival the best or
    /// make the target ambiguous. Otherwise it is reported unrefined, its error an upper bound
    /// of what refinement would give. `u8::MAX`: always refine it. Refining a far-off second
    /// solution into its own minimum took ~10 LM steps on the pose bench (the best: 1-2),
    /// three quarters of the solver's time.
    pub alternative_ratio: u8,
}

impl Default for PlanarConfig {
    fn default() -> Self {
        // LM from an IPPE start converges in 2..5 steps on real targets; 20 bounds the cost.
        Self {
            refine_iterations: 20,
            alternative_ratio: 4,
        }
    }
}

/// Two refined solutions closer than this (degrees of rotation) are one local minimum.
const MERGED_DEG: f64 = 0.5;

/// Both poses of a planar target, `best.rms_px <= alternative.rms_px`. The alternative is the
/// second local minimum of the reprojection error when there is one within
/// [`PlanarConfig::alternative_ratio`] of the best, else the unrefined second IPPE solution.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlanarPose<T: Real = f32> {
    /// The pose with the lower reprojection error.
    pub best: PoseEstimate<T>,
    /// The other solution of the planar ambiguity.
    pub alternative: PoseEstimate<T>,
}

impl<T: Real> PlanarPose<T> {
    /// `true` when the alternative explains the data almost as well
    /// (`alternative.rms_px ≤ ratio · best.rms_px`, e.g. `ratio = 1.5`): the target is close to
    /// fronto-parallel or small in the image, and the choice of `best` is not reliable.
    pub fn is_ambiguous(&self, ratio: T) -> bool {
        self.alternative.rms_px <= ratio * self.best.rms_px
    }
}

/// The two IPPE poses from target-plane points `model` (`Z = 0`) and their undistorted
/// normalised image points `normalized` (`x_n = K⁻¹ u`, distortion removed), each with its
/// RMS reprojection error in normalised units, sorted (best first).
///
/// Errors: [`Error::LengthMismatch`]; [`Error::TooFewPoints`] below 4 points; as
/// [`dlt`] for degenerate point sets; [`Error::Degenerate`] when the homography's Jacobian is
/// singular (the target is seen edge-on).
#[doc(alias = "SOLVEPNP_IPPE")]
pub fn ippe<T: Real>(model: &[Point2<T>], normalized: &[Point2<T>]) -> Result<[(Pose<T>, T); 2]> {
    if model.len() != normalized.len() {
        return Err(Error::LengthMismatch);
    }
    if model.len() < 4 {
        return Err(Error::TooFewPoints);
    }
    let n = T::lit(model.len() as f64);
    let mut c = Vector3::zeros();
    for p in model {
        check_finite(&[p.x, p.y])?;
        c += Vector3::new(p.x, p.y, T::zero());
    }
    c /= n;
    from_homography(&dlt(model, normalized)?, &c, model, normalized)
}

/// [`ippe`] from a homography `h` of the model plane to normalised image coordinates (the
/// DLT's, or any other estimate) and the model's centroid `c`: the two rotations of `h`, each
/// with its least-squares translation and error over the pairs, sorted.
pub(crate) fn from_homography<T: Real>(
    h: &Homography<T>,
    c: &Vector3<T>,
    model: &[Point2<T>],
    normalized: &[Point2<T>],
) -> Result<[(Pose<T>, T); 2]> {
    // H of the centred model: H_c = H T(c), T(c) shifting centred coordinates back.
    let (z, o) = (T::zero(), T::one());
    let shift = Matrix3::new(o, z, c.x, z, o, c.y, z, z, o);
    let hc = Homography::from_matrix(&(h.matrix() * shift))?;
    let hm = hc.matrix();
    if !above(hm.m33.abs(), T::EPSILON.sqrt() * hm.amax()) {
        return Err(Error::Degenerate);
    }
    let hm = hm / hm.m33;
    let (v1, v2) = (hm.m13, hm.m23);
    let j = Matrix2::new(
        hm.m11 - v1 * hm.m31,
        hm.m12 - v1 * hm.m32,
        hm.m21 - v2 * hm.m31,
        hm.m22 - v2 * hm.m32,
    );
    let rotations = ippe_rotations(v1, v2, &j)?;
    let mut out = rotations.map(|r| {
        let t = translation(&r, c, model, normalized);
        let pose = t.and_then(|t| Pose::new(r, t - r * c));
        let err = pose.and_then(|p| normalized_rms(&p, model, normalized));
        (pose, err)
    });
    out.sort_unstable_by(|a, b| match (&a.1, &b.1) {
        (Ok(x), Ok(y)) => x.partial_cmp(y).unwrap_or(core::cmp::Ordering::Equal),
        (Ok(_), Err(_)) => core::cmp::Ordering::Less,
        (Err(_), Ok(_)) => core::cmp::Ordering::Greater,
        _ => core::cmp::Ordering::Equal,
    });
    let [(p0, e0), (p1, e1)] = out;
    Ok([(p0?, e0?), (p1?, e1?)])
}

/// The two rotations of the module docs.
fn ippe_rotations<T: Real>(v1: T, v2: T, j: &Matrix2<T>) -> Result<[Rotation3<T>; 2]> {
    // R_v: the rotation about z × (v, 1) taking (0, 0, 1) to (v, 1)/|(v, 1)|. With
    // a = (-v2, v1, 0) (|a|² = s² - 1, s = |(v, 1)|), cos θ = 1/s and sin θ = |a|/s, so
    // Rodrigues' formula I + sin θ [k]ₓ + (1 - cos θ) [k]ₓ² is rational in a and s:
    // R_v = I + [a]ₓ / s + [a]ₓ² / (s (s + 1)) (no trigonometry; s ≥ 1, no cancellation).
    let s = Vector3::new(v1, v2, T::one()).norm();
    let ax = Vector3::new(-v2, v1, T::zero()).cross_matrix();
    let rv = Rotation3::from_matrix_unchecked(
        Matrix3::identity() + ax / s + ax * ax / (s * (s + T::one())),
    );
    let r = rv.matrix();
    let b = Matrix2::new(
        r.m11 - v1 * r.m31,
        r.m12 - v1 * r.m32,
        r.m21 - v2 * r.m31,
        r.m22 - v2 * r.m32,
    );
    let a = b.try_inverse().ok_or(Error::Degenerate)? * j;
    // Largest singular value of the 2x2 A from the eigenvalues of A Aᵀ.
    let (p, q, w) = (
        a.m11 * a.m11 + a.m12 * a.m12,
        a.m11 * a.m21 + a.m12 * a.m22,
        a.m21 * a.m21 + a.m22 * a.m22,
    );
    let gamma = (T::lit(0.5) * (p + w + ((p - w) * (p - w) + T::lit(4.0) * q * q).sqrt())).sqrt();
    if !above(gamma, T::EPSILON) || !gamma.finite() {
        return Err(Error::Degenerate);
    }
    let rt = a / gamma;
    let b0 = (T::one() - rt.m11 * rt.m11 - rt.m21 * rt.m21)
        .max(T::zero())
        .sqrt();
    let mut b1 = (T::one() - rt.m12 * rt.m12 - rt.m22 * rt.m22)
        .max(T::zero())
        .sqrt();
    // Orthogonality of the two columns fixes the sign of b₁ relative to b₀ ≥ 0.
    if -(rt.m11 * rt.m12 + rt.m21 * rt.m22) < T::zero() {
        b1 = -b1;
    }
    let build = |sign: T| -> Result<Rotation3<T>> {
        let c0 = Vector3::new(rt.m11, rt.m21, sign * b0);
        let c1 = Vector3::new(rt.m12, rt.m22, sign * b1);
        // Exact data gives orthonormal columns; noise does not: project onto SO(3).
        let m = Matrix3::from_columns(&[c0, c1, c0.cross(&c1)]);
        Ok(rv * closest_rotation(&m)?)
    };
    Ok([build(T::one())?, build(-T::one())?])
}

/// Least-squares `t` for a rotation: `[1 0 -uᵢ; 0 1 -vᵢ] t = (uᵢ r₃ - r₁, vᵢ r₃ - r₂)·Pᵢ` over
/// the centred model points `Pᵢ`, by QR of the augmented `2N x 4` system.
fn translation<T: Real>(
    r: &Rotation3<T>,
    c: &Vector3<T>,
    model: &[Point2<T>],
    normalized: &[Point2<T>],
) -> Result<Vector3<T>> {
    let m = r.matrix();
    let (r1, r2, r3) = (m.row(0), m.row(1), m.row(2));
    let (z, o) = (T::zero(), T::one());
    let mut qr = StreamingQr::<T, 4>::new();
    for (p, u) in model.iter().zip(normalized) {
        let pc = Vector3::new(p.x - c.x, p.y - c.y, z);
        let (a, b, d) = (
            r1.dot(&pc.transpose()),
            r2.dot(&pc.transpose()),
            r3.dot(&pc.transpose()),
        );
        qr.push_row(&[o, z, -u.x, u.x * d - a])?;
        qr.push_row(&[z, o, -u.y, u.y * d - b])?;
    }
    let rr = qr.r();
    rr.fixed_view::<3, 3>(0, 0)
        .solve_upper_triangular(&rr.fixed_view::<3, 1>(0, 3))
        .ok_or(Error::Degenerate)
}

fn normalized_rms<T: Real>(
    pose: &Pose<T>,
    model: &[Point2<T>],
    normalized: &[Point2<T>],
) -> Result<T> {
    let mut sum = T::zero();
    for (p, u) in model.iter().zip(normalized) {
        let x = pose.apply(&Point3::new(p.x, p.y, T::zero()));
        if !above(x.z, T::zero()) {
            return Err(Error::BehindCamera);
        }
        sum += (Point2::new(x.x / x.z, x.y / x.z) - u).norm_squared();
    }
    Ok((sum / T::lit(model.len() as f64)).sqrt())
}

/// The pose of a planar target seen through `camera`: both IPPE solutions from the
/// undistorted observations, refined by [`super::refine_pose`] (pixels, distortion included;
/// the second only when it is within [`PlanarConfig::alternative_ratio`] of the first), sorted
/// by reprojection error.
///
/// `scratch` holds the undistorted normalised points and must have at least `model.len()`
/// entries. Errors: as [`ippe`] and [`super::refine_pose`]; [`Error::LengthMismatch`] when
/// `scratch` is too short.
#[doc(alias = "solvePnP")]
#[doc(alias = "SOLVEPNP_IPPE")]
pub fn solve_planar<T: Real>(
    camera: &Camera<T>,
    model: &[Point2<T>],
    pixels: &[Point2<T>],
    scratch: &mut [Point2<T>],
    cfg: &PlanarConfig,
) -> Result<PlanarPose<T>> {
    if model.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    let normalized = scratch
        .get_mut(..pixels.len())
        .ok_or(Error::LengthMismatch)?;
    for (n, u) in normalized.iter_mut().zip(pixels) {
        *n = camera.undistort_to_normalized(u)?;
    }
    let [(p0, _), (p1, _)] = ippe(model, normalized)?;
    // The model lifted to Z = 0 on the fly: no storage for 3D points.
    let lifted = |i: usize| model.get(i).map(|p| Point3::new(p.x, p.y, T::zero()));
    let estimate = |p: Pose<T>| refine_pose_with(camera, &p, pixels, cfg.refine_iterations, lifted);
    let a = estimate(p0)?;
    // The second IPPE solution as it is, reported when it is not refined or when refinement
    // carries it into the best.
    let unrefined = PoseEstimate {
        pose: p1,
        rms_px: super::refine::rms_with(camera, &p1, pixels, lifted)?,
    };
    pick(a, unrefined, cfg, |p| estimate(*p))
}

/// The two poses of [`solve_planar`] from the refined first start `a` and the second start
/// `unrefined` with its error: the second is refined (by `refine`) only when it is within
/// [`PlanarConfig::alternative_ratio`] of `a`; sorted, and a second that refinement merged
/// into the first is reported unrefined. Shared by the float and the integer solvers.
pub(crate) fn pick<T: Real>(
    a: PoseEstimate<T>,
    unrefined: PoseEstimate<T>,
    cfg: &PlanarConfig,
    refine: impl FnOnce(&Pose<T>) -> Result<PoseEstimate<T>>,
) -> Result<PlanarPose<T>> {
    // `above` is false for NaN: such an error goes on to the refinement, which reports it.
    if above(
        unrefined.rms_px,
        T::lit(f64::from(cfg.alternative_ratio)) * a.rms_px,
    ) && cfg.alternative_ratio < u8::MAX
    {
        return Ok(PlanarPose {
            best: a,
            alternative: unrefined,
        });
    }
    let b = refine(&unrefined.pose)?;
    let (best, mut alternative) = if a.rms_px <= b.rms_px { (a, b) } else { (b, a) };
    // When the second solution is not a local minimum of its own, refinement carries it into
    // the first one; the planar ambiguity is then resolved, and the alternative reported is the
    // unrefined IPPE solution (with its own, larger, error) rather than a copy of the best.
    let merged = (best.pose.isometry().rotation.inverse() * alternative.pose.isometry().rotation)
        .angle()
        < T::lit(MERGED_DEG.to_radians());
    if merged {
        alternative = unrefined;
    }
    Ok(PlanarPose { best, alternative })
}
