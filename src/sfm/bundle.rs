//! A small bundle adjustment: Levenberg-Marquardt over three camera poses and the points,
//! with the Schur complement over the points.
//!
//! Unknowns: view 2's rotation and translation direction (5: `R ← exp([ω]ₓ) R`,
//! `t ← (t + B τ)/|t + B τ|`), view 3's rotation and translation (6), and every point (3).
//! View 1 is fixed (the world frame) and `|t₂| = 1` fixes the scale: the 7 gauge freedoms of
//! a similarity are gone. Residuals are the pixel reprojection errors through the full camera
//! model, `eᵢᵥ = u(Rᵥ Xᵢ + tᵥ) - uᵢᵥ`, with Jacobians
//! `∂e/∂ω = J_π (-[R X]ₓ)`, `∂e/∂t = J_π`, `∂e/∂τ = J_π B`, `∂e/∂X = J_π R`.
//!
//! The damped normal equations `[U W; Wᵀ V] [δc; δp] = -[g_c; g_p]` have a block-diagonal `V`
//! (one 3x3 block per point), so the points are eliminated:
//!
//! `(U - Σᵢ Wᵢ Vᵢ⁻¹ Wᵢᵀ) δc = -g_c + Σᵢ Wᵢ Vᵢ⁻¹ gᵢ`,  `δpᵢ = Vᵢ⁻¹ (-gᵢ - Wᵢᵀ δc)`,
//!
//! an 11x11 reduced camera system solved by Cholesky. Forming normal equations (rather than
//! the streaming QR the other refinements use) is acceptable here: the blocks are tiny (3x3
//! per point, 11x11 for the cameras), the residuals are in pixels with unit-scale point
//! coordinates (baseline 1), and Marquardt damping `A + λ diag(A)` keeps every block
//! positive definite; a point block that still cannot be inverted (a point seen once, or on
//! a ray through both centres) keeps the point fixed for that step.

use nalgebra::{Matrix2x3, Matrix3, Point2, Point3, SMatrix, SVector, Vector3};

use super::track::Track;
use crate::camera::Camera;
use crate::linalg::rotation_step;
use crate::scalar::{Real, above};
use crate::transform::Pose;
use crate::twoview::tangent_basis;
use crate::{Error, Result};

/// Camera parameters: view 2 (rotation 3, translation direction 2), view 3 (6).
const C: usize = 11;

/// Damping increases tried per iteration before giving up.
const MAX_DAMPING_TRIES: u8 = 8;

/// Per-point storage of the bundle adjustment (caller-provided, one per track).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointBlock<T: Real = f32> {
    v: Matrix3<T>,
    v_inv: Matrix3<T>,
    w: SMatrix<T, C, 3>,
    g: Vector3<T>,
    candidate: Point3<T>,
    active: bool,
}

impl<T: Real> Default for PointBlock<T> {
    fn default() -> Self {
        Self {
            v: Matrix3::zeros(),
            v_inv: Matrix3::zeros(),
            w: SMatrix::zeros(),
            g: Vector3::zeros(),
            candidate: Point3::origin(),
            active: false,
        }
    }
}

/// What [`bundle_adjust`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BundleReport<T: Real = f32> {
    /// RMS reprojection error over the used observations before, pixels.
    pub initial_rms_px: T,
    /// RMS after.
    pub final_rms_px: T,
    /// Accepted Levenberg-Marquardt steps.
    pub iterations: u8,
    /// Observations in the problem.
    pub observations: usize,
}

/// Squared reprojection error of one observation, `None` if it does not project.
fn obs_cost<T: Real>(
    camera: &Camera<T>,
    pose: &Pose<T>,
    x: &Point3<T>,
    u: &Point2<T>,
) -> Option<T> {
    camera.project(pose, x).ok().map(|p| (p - u).norm_squared())
}

/// The used observations of a track: `(view, pixel)`.
fn observations<'a, T: Real>(
    track: &'a Track<T>,
    used: &'a [bool; 3],
) -> impl Iterator<Item = (usize, &'a Point2<T>)> + 'a {
    track
        .iter()
        .zip(used.iter())
        .enumerate()
        .filter_map(|(v, (o, u))| if *u { o.as_ref().map(|p| (v, p)) } else { None })
}

fn total_cost<T: Real>(
    camera: &Camera<T>,
    poses: &[Pose<T>; 3],
    tracks: &[Track<T>],
    used: &[[bool; 3]],
    point: impl Fn(usize) -> Option<Point3<T>>,
) -> Option<(T, usize)> {
    let mut c = T::zero();
    let mut n = 0usize;
    for (i, (track, used)) in tracks.iter().zip(used.iter()).enumerate() {
        let Some(x) = point(i) else { continue };
        for (v, u) in observations(track, used) {
            c += obs_cost(camera, poses.get(v)?, &x, u)?;
            n += 1;
        }
    }
    c.finite().then_some((c, n))
}

/// Moves views 2 and 3 by a camera step (see the module docs).
fn step_poses<T: Real>(poses: &[Pose<T>; 3], d: &SVector<T, C>) -> Option<[Pose<T>; 3]> {
    let [p1, p2, p3] = poses;
    let [w1, w2, w3, s1, s2, a1, a2, a3, t1, t2, t3]: [T; C] = (*d).into();
    let t = p2.translation();
    let (b1, b2) = tangent_basis(&t);
    let moved = t + b1 * s1 + b2 * s2;
    let n = moved.norm();
    if !above(n, T::zero()) {
        return None;
    }
    let q2 = Pose::new(
        rotation_step(&Vector3::new(w1, w2, w3)) * p2.rotation(),
        moved / n,
    )
    .ok()?;
    let q3 = Pose::new(
        rotation_step(&Vector3::new(a1, a2, a3)) * p3.rotation(),
        p3.translation() + Vector3::new(t1, t2, t3),
    )
    .ok()?;
    Some([*p1, q2, q3])
}

/// Bundle adjustment of three views (see the module docs): at most `max_iterations`
/// Levenberg-Marquardt steps over `poses[1]`, `poses[2]` (with `poses[0]` fixed and
/// `|t₂| = 1` kept) and the points, on the observations `tracks[i][v]` with `used[i][v]`.
/// Points are `None` when not reconstructed (their observations are ignored); a point with
/// fewer than two used observations stays fixed. `blocks` is scratch, one per track.
///
/// Errors: [`Error::LengthMismatch`] (`points`, `used` or `blocks` shorter than `tracks`);
/// [`Error::InvalidParameter`] when `|t₂|` is not 1 (±1e-3); [`Error::BehindCamera`] when a
/// used observation does not project at the start; [`Error::TooFewPoints`] without any
/// observation.
pub fn bundle_adjust<T: Real>(
    camera: &Camera<T>,
    poses: &mut [Pose<T>; 3],
    points: &mut [Option<Point3<T>>],
    tracks: &[Track<T>],
    used: &[[bool; 3]],
    blocks: &mut [PointBlock<T>],
    max_iterations: u8,
) -> Result<BundleReport<T>> {
    let n = tracks.len();
    if points.len() < n || used.len() < n || blocks.len() < n {
        return Err(Error::LengthMismatch);
    }
    let (points, used, blocks) = (
        points.get_mut(..n).ok_or(Error::LengthMismatch)?,
        used.get(..n).ok_or(Error::LengthMismatch)?,
        blocks.get_mut(..n).ok_or(Error::LengthMismatch)?,
    );
    let [_, p2, _] = &*poses;
    if !above(T::lit(1e-3), (p2.translation().norm() - T::one()).abs()) {
        return Err(Error::InvalidParameter("poses"));
    }
    let Some((mut cost, count)) = total_cost(camera, poses, tracks, used, |i| {
        points.get(i).copied().flatten()
    }) else {
        return Err(Error::BehindCamera);
    };
    if count == 0 {
        return Err(Error::TooFewPoints);
    }
    let initial = cost;
    let tol = T::EPSILON.sqrt();
    let mut lambda = T::lit(1e-3);
    let mut iterations = 0u8;
    for _ in 0..max_iterations {
        // Linearise.
        let mut u = SMatrix::<T, C, C>::zeros();
        let mut gc = SVector::<T, C>::zeros();
        for ((track, used), (point, block)) in tracks
            .iter()
            .zip(used.iter())
            .zip(points.iter().zip(blocks.iter_mut()))
        {
            *block = PointBlock::default();
            let Some(x) = point else { continue };
            let seen = observations(track, used).count();
            for (v, obs) in observations(track, used) {
                let Some(pose) = poses.get(v) else { continue };
                let rx = pose.apply_vector(&x.coords);
                let xc = Point3::from(rx + pose.translation());
                let Ok((proj, jpi)) = camera.project_with_jacobian(&xc) else {
                    return Err(Error::BehindCamera);
                };
                let e = proj - obs;
                let jx: Matrix2x3<T> = jpi * pose.rotation().matrix();
                let jw: Matrix2x3<T> = jpi * (-rx.cross_matrix());
                let mut jc = SMatrix::<T, 2, C>::zeros();
                match v {
                    1 => {
                        let (b1, b2) = tangent_basis(&pose.translation());
                        jc.fixed_view_mut::<2, 3>(0, 0).copy_from(&jw);
                        jc.fixed_view_mut::<2, 1>(0, 3).copy_from(&(jpi * b1));
                        jc.fixed_view_mut::<2, 1>(0, 4).copy_from(&(jpi * b2));
                    }
                    2 => {
                        jc.fixed_view_mut::<2, 3>(0, 5).copy_from(&jw);
                        jc.fixed_view_mut::<2, 3>(0, 8).copy_from(&jpi);
                    }
                    _ => {}
                }
                u += jc.transpose() * jc;
                gc += jc.transpose() * e;
                if seen >= 2 {
                    block.active = true;
                    block.v += jx.transpose() * jx;
                    block.g += jx.transpose() * e;
                    block.w += jc.transpose() * jx;
                }
            }
        }
        // Damped steps until one lowers the cost.
        let mut accepted = None;
        for _ in 0..MAX_DAMPING_TRIES {
            let mut s = u;
            for k in 0..C {
                if let Some(d) = s.get_mut((k, k)) {
                    *d += lambda * *d;
                }
            }
            let mut rhs = -gc;
            for block in blocks.iter_mut().filter(|b| b.active) {
                let mut vl = block.v;
                for k in 0..3 {
                    if let Some(d) = vl.get_mut((k, k)) {
                        *d += lambda * *d;
                    }
                }
                match vl.try_inverse() {
                    Some(inv) if inv.iter().all(|v| v.finite()) => {
                        block.v_inv = inv;
                        let wv = block.w * inv;
                        s -= wv * block.w.transpose();
                        rhs += wv * block.g;
                    }
                    _ => block.v_inv = Matrix3::zeros(),
                }
            }
            let Some(dc) = s.cholesky().map(|ch| ch.solve(&rhs)) else {
                lambda *= T::lit(10.0);
                continue;
            };
            let Some(new_poses) = step_poses(poses, &dc) else {
                lambda *= T::lit(10.0);
                continue;
            };
            for (block, point) in blocks.iter_mut().zip(points.iter()) {
                if let Some(x) = point {
                    let dp = block.v_inv * (-block.g - block.w.transpose() * dc);
                    block.candidate = if block.active { x + dp } else { *x };
                }
            }
            let candidates = &*blocks;
            let new_cost = total_cost(camera, &new_poses, tracks, used, |i| {
                points
                    .get(i)
                    .copied()
                    .flatten()
                    .and(candidates.get(i).map(|b| b.candidate))
            });
            match new_cost {
                Some((nc, _)) if nc < cost => {
                    accepted = Some((new_poses, nc));
                    lambda = (lambda * T::lit(0.1)).max(T::lit(1e-12));
                    break;
                }
                _ => lambda *= T::lit(10.0),
            }
        }
        let Some((new_poses, nc)) = accepted else {
            break;
        };
        for (point, block) in points.iter_mut().zip(blocks.iter()) {
            if let Some(x) = point.as_mut() {
                *x = block.candidate;
            }
        }
        *poses = new_poses;
        let decrease = cost - nc;
        cost = nc;
        iterations = iterations.saturating_add(1);
        if decrease <= tol * cost {
            break;
        }
    }
    let nn = T::lit(count as f64);
    Ok(BundleReport {
        initial_rms_px: (initial / nn).sqrt(),
        final_rms_px: (cost / nn).sqrt(),
        iterations,
        observations: count,
    })
}
