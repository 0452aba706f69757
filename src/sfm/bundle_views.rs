//! Bundle adjustment over any number of views: Levenberg-Marquardt on every registered pose and
//! every point, the points eliminated by the Schur complement, in caller-owned memory.
//!
//! Unknowns: each registered view's rotation and translation (6: `R ← exp([ω]ₓ) R`,
//! `t ← t + δt`) except the *anchor* (fixed: it is the world frame) and the *scale view*, whose
//! translation moves only on its sphere (`t ← (t + B τ) |t| / |t + B τ|`, 5 unknowns: the
//! scale is not observable and stays that of the initial pair); each point (3). Residuals are
//! pixel reprojection errors through the full camera model, `e = u(R X + t) - u_obs`, weighted
//! by Huber's loss with threshold `δ` (`ρ(e) = |e|²` for `|e| ≤ δ`, `2 δ |e| - δ²` beyond), so
//! that the few wrong observations left pull with a bounded force.
//!
//! The damped normal equations `[U W; Wᵀ V] [δc; δp] = -[g_c; g_p]` have one 3x3 block `Vᵢ`
//! per point, so the points are eliminated:
//!
//! `(U - Σᵢ Wᵢ Vᵢ⁻¹ Wᵢᵀ) δc = -g_c + Σᵢ Wᵢ Vᵢ⁻¹ gᵢ`,  `δpᵢ = Vᵢ⁻¹ (-gᵢ - Wᵢᵀ δc)`,
//!
//! a dense `6P x 6P` reduced camera system for `P` free views (solved by Cholesky in the
//! caller's memory: 50 views are 300 unknowns, 90,000 scalars), whose cost does not grow with
//! the points: tens of thousands of points cost one pass over the observations an iteration.
//! The blocks are tiny and the damping `A + λ diag(A)` keeps each positive definite, so forming
//! normal equations is acceptable here (see [`super::bundle`]). A point with fewer than two
//! used observations, or whose block cannot be inverted, stays fixed for the step.

use nalgebra::{Matrix3, Point3, SMatrix, SVector, Vector3};

use super::track_set::TrackSet;
use crate::camera::Camera;
use crate::linalg::{cholesky_solve, rotation_step};
use crate::scalar::{Real, above};
use crate::transform::Pose;
use crate::twoview::tangent_basis;
use crate::{Error, Result};

/// Per-point scratch of [`bundle_adjust_views`] (one per track).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointScratch<T: Real = f32> {
    v_inv: Matrix3<T>,
    g: Vector3<T>,
    candidate: Option<Point3<T>>,
    active: bool,
}

impl<T: Real> Default for PointScratch<T> {
    fn default() -> Self {
        Self {
            v_inv: Matrix3::zeros(),
            g: Vector3::zeros(),
            candidate: None,
            active: false,
        }
    }
}

/// The caller-owned memory of [`bundle_adjust_views`] for `views` views, `tracks` tracks and
/// `observations` observations (each field says its length) (in `f64`, 50 views, 20,000
/// tracks and 100,000 observations take about 0.7 MB for the reduced system, 2.2 MB for the
/// points and 14.4 MB for the camera-point blocks).
#[derive(Debug)]
pub struct BundleScratch<'a, T: Real = f32> {
    /// `6 views` squared scalars: the reduced camera system.
    pub system: &'a mut [T],
    /// `6 views` scalars: its right-hand side, then the camera step.
    pub rhs: &'a mut [T],
    /// `6 views` scalars: the camera gradient.
    pub gradient: &'a mut [T],
    /// One per view: the free-view index of each view.
    pub index: &'a mut [u16],
    /// One per view, set by the caller: which registered views may move (all of them for a
    /// global adjustment; a new view and its neighbours for a local one). The anchor never
    /// moves. Points that no free view sees used are left out entirely.
    pub free: &'a mut [bool],
    /// One per view: poses of the trial step.
    pub trial: &'a mut [Option<Pose<T>>],
    /// One per observation: its `W` block (camera-point coupling).
    pub coupling: &'a mut [SMatrix<T, 6, 3>],
    /// One per track.
    pub points: &'a mut [PointScratch<T>],
}

impl<T: Real> BundleScratch<'_, T> {
    /// Scalars of [`Self::system`] for `views` views.
    pub const fn system_len(views: usize) -> usize {
        36 * views * views
    }

    fn check(&self, views: usize, tracks: usize, observations: usize) -> Result<()> {
        let ok = self.system.len() >= Self::system_len(views)
            && self.rhs.len() >= 6 * views
            && self.gradient.len() >= 6 * views
            && self.index.len() >= views
            && self.free.len() >= views
            && self.trial.len() >= views
            && self.coupling.len() >= observations
            && self.points.len() >= tracks;
        if ok {
            Ok(())
        } else {
            Err(Error::BufferTooSmall("bundle scratch"))
        }
    }
}

/// Which poses are fixed (see the module docs). The anchor's pose is the world frame (the
/// identity), so the scale view's `|t|` is the distance between their centres.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Gauge {
    /// The fixed view (the world frame).
    pub anchor: u16,
    /// The view whose distance to the anchor is kept (the scale).
    pub scale: u16,
}

/// How [`bundle_adjust_views`] runs.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BundleSettings<T: Real = f32> {
    /// The fixed poses.
    pub gauge: Gauge,
    /// Huber threshold `δ`, pixels, `> 0`.
    pub loss_px: T,
    /// Most Levenberg-Marquardt steps.
    pub max_iterations: u8,
}

/// What [`bundle_adjust_views`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ViewsBundleReport<T: Real = f32> {
    /// RMS reprojection error over the used observations of the points the free views see,
    /// before, pixels.
    pub initial_rms_px: T,
    /// The same after.
    pub final_rms_px: T,
    /// Accepted Levenberg-Marquardt steps.
    pub iterations: u8,
    /// Observations in the problem.
    pub observations: usize,
    /// Free views.
    pub free_views: usize,
}

/// Huber's weight of a residual of squared norm `e2` for threshold `delta`.
fn huber_weight<T: Real>(e2: T, delta: T) -> T {
    let e = e2.sqrt();
    if e <= delta { T::one() } else { delta / e }
}

/// Huber's cost of a residual of squared norm `e2`.
fn huber_cost<T: Real>(e2: T, delta: T) -> T {
    let e = e2.sqrt();
    if e <= delta {
        e2
    } else {
        T::lit(2.0) * delta * e - delta * delta
    }
}

/// The robust cost and the squared-error sum of the used observations of active points, and
/// their count; `None` when a used observation does not project.
#[allow(clippy::too_many_arguments)]
fn cost<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    poses: &[Option<Pose<T>>],
    used: &[bool],
    index: &[u16],
    delta: T,
    point: impl Fn(usize) -> Option<Point3<T>>,
) -> Option<(T, T, usize)> {
    let (mut c, mut sq, mut n) = (T::zero(), T::zero(), 0usize);
    for i in 0..tracks.len() {
        let Some(x) = point(i) else { continue };
        let range = tracks.range(i);
        if !affected(tracks, i, used, index) {
            continue;
        }
        for (o, &u) in tracks.track(i).iter().zip(used.get(range)?) {
            let Some(Some(pose)) = poses.get(usize::from(o.view)) else {
                continue;
            };
            if !u {
                continue;
            }
            let e2 = (camera.project(pose, &x).ok()? - o.pixel).norm_squared();
            c += huber_cost(e2, delta);
            sq += e2;
            n += 1;
        }
    }
    (c.finite() && sq.finite()).then_some((c, sq, n))
}

/// Whether a free view sees track `i` in a used observation (else the step cannot move it).
fn affected<T: Real>(tracks: &TrackSet<'_, T>, i: usize, used: &[bool], index: &[u16]) -> bool {
    let range = tracks.range(i);
    tracks
        .track(i)
        .iter()
        .zip(used.get(range).unwrap_or(&[]))
        .any(|(o, &u)| {
            u && index
                .get(usize::from(o.view))
                .is_some_and(|&x| x != u16::MAX)
        })
}

fn rms<T: Real>(sq: T, n: usize) -> T {
    if n == 0 {
        T::zero()
    } else {
        (sq / T::lit(n as f64)).sqrt()
    }
}

/// Bundle adjustment of every registered view (`poses[v]` is `Some`) and every point
/// (`points[i]` is `Some`) on the used observations (`used`, one per observation of `tracks`):
/// at most `settings.max_iterations` Levenberg-Marquardt steps with Huber's loss of threshold
/// `settings.loss_px` pixels, `settings.gauge` fixed (see the module docs). Observations of unregistered views are ignored.
///
/// Only the views marked in `scratch.free` move (see [`BundleScratch::free`]), and the errors
/// reported are over the points they see.
///
/// Errors: [`Error::LengthMismatch`] for `poses`, `points` or `used` of the wrong length;
/// [`Error::BufferTooSmall`] for `scratch`; [`Error::InvalidParameter`]`("bundle.gauge")`
/// when the anchor or the scale view is not registered, they coincide, or the scale view sits
/// on the anchor; [`Error::InvalidParameter`]`("bundle.loss_px")` for a threshold that is not
/// positive; [`Error::BehindCamera`] when a used observation does not project at the start;
/// [`Error::TooFewPoints`] without any observation.
pub fn bundle_adjust_views<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    poses: &mut [Option<Pose<T>>],
    points: &mut [Option<Point3<T>>],
    used: &[bool],
    settings: &BundleSettings<T>,
    scratch: &mut BundleScratch<'_, T>,
) -> Result<ViewsBundleReport<T>> {
    let BundleSettings {
        gauge,
        loss_px,
        max_iterations,
    } = *settings;
    let (views, n_tracks, n_obs) = (tracks.views(), tracks.len(), tracks.observations().len());
    if poses.len() != views || points.len() != n_tracks || used.len() != n_obs {
        return Err(Error::LengthMismatch);
    }
    scratch.check(views, n_tracks, n_obs)?;
    if !above(loss_px, T::zero()) {
        return Err(Error::InvalidParameter("bundle.loss_px"));
    }
    let bad_gauge = Error::InvalidParameter("bundle.gauge");
    let (anchor, scale) = (usize::from(gauge.anchor), usize::from(gauge.scale));
    let (Some(Some(_)), Some(Some(ps))) = (poses.get(anchor), poses.get(scale)) else {
        return Err(bad_gauge);
    };
    if anchor == scale || !above(ps.translation().norm(), T::zero()) {
        return Err(bad_gauge);
    }
    // Free views and their index.
    let mut free = 0usize;
    for (v, ((idx, pose), &f)) in scratch
        .index
        .iter_mut()
        .zip(poses.iter())
        .zip(scratch.free.iter())
        .enumerate()
        .take(views)
    {
        *idx = if pose.is_some() && v != anchor && f {
            free += 1;
            (free - 1) as u16
        } else {
            u16::MAX
        };
    }
    let dim = 6 * free;
    let Some((mut current, sq0, count)) =
        cost(camera, tracks, poses, used, scratch.index, loss_px, |i| {
            points.get(i).copied().flatten()
        })
    else {
        return Err(Error::BehindCamera);
    };
    if count == 0 {
        return Err(Error::TooFewPoints);
    }
    let initial_rms_px = rms(sq0, count);
    let mut final_sq = sq0;
    let mut lambda = T::lit(1e-4);
    let mut iterations = 0u8;
    let eps = T::EPSILON.sqrt();
    'outer: for _ in 0..max_iterations {
        // Retries with more damping until a step lowers the cost (bounded).
        for _ in 0..8u8 {
            if !linearise_and_solve(
                camera, tracks, poses, points, used, scale, loss_px, lambda, dim, scratch,
            )? {
                lambda *= T::lit(10.0);
                continue;
            }
            // Trial poses.
            for v in 0..views {
                let (Some(idx), Some(trial), Some(pose)) =
                    (scratch.index.get(v), scratch.trial.get_mut(v), poses.get(v))
                else {
                    continue;
                };
                *trial = *pose;
                let (Some(p), true) = (pose, *idx != u16::MAX) else {
                    continue;
                };
                let k = 6 * usize::from(*idx);
                let d: [T; 6] =
                    core::array::from_fn(|j| scratch.rhs.get(k + j).copied().unwrap_or(T::zero()));
                let r = rotation_step(&Vector3::new(d[0], d[1], d[2])) * p.rotation();
                let t = if v == scale {
                    // On its sphere: the anchor is the world frame (identity pose), so `|t|`
                    // is the distance between the two centres, the scale.
                    let c = p.translation();
                    let (b1, b2) = tangent_basis(&c);
                    let moved = c + b1 * d[3] + b2 * d[4];
                    let n = moved.norm();
                    if !above(n, T::zero()) {
                        *trial = None;
                        continue;
                    }
                    moved * (c.norm() / n)
                } else {
                    p.translation() + Vector3::new(d[3], d[4], d[5])
                };
                *trial = Pose::new(r, t).ok();
            }
            let trial_cost = cost(
                camera,
                tracks,
                scratch.trial,
                used,
                scratch.index,
                loss_px,
                |i| scratch.points.get(i).and_then(|s| s.candidate),
            );
            match trial_cost {
                Some((c, sq, _)) if c < current => {
                    let gain = (current - c) / current.max(T::EPSILON);
                    current = c;
                    final_sq = sq;
                    for (p, t) in poses.iter_mut().zip(scratch.trial.iter()) {
                        *p = *t;
                    }
                    for (p, s) in points.iter_mut().zip(scratch.points.iter()) {
                        if p.is_some() {
                            *p = s.candidate;
                        }
                    }
                    iterations += 1;
                    lambda = (lambda / T::lit(10.0)).max(T::lit(1e-12));
                    if gain < eps {
                        break 'outer;
                    }
                    continue 'outer;
                }
                _ => lambda *= T::lit(10.0),
            }
        }
        break;
    }
    Ok(ViewsBundleReport {
        initial_rms_px,
        final_rms_px: rms(final_sq, count),
        iterations,
        observations: count,
        free_views: free,
    })
}

/// Builds the damped reduced camera system, solves it and back-substitutes the points into
/// `scratch.points[i].candidate` (the current point where it stays fixed). `Ok(false)` when
/// the system is not positive definite (more damping is needed).
#[allow(clippy::too_many_arguments)]
fn linearise_and_solve<T: Real>(
    camera: &Camera<T>,
    tracks: &TrackSet<'_, T>,
    poses: &[Option<Pose<T>>],
    points: &[Option<Point3<T>>],
    used: &[bool],
    scale: usize,
    delta: T,
    lambda: T,
    dim: usize,
    s: &mut BundleScratch<'_, T>,
) -> Result<bool> {
    let bad = Error::LengthMismatch;
    let system = s.system.get_mut(..dim * dim).ok_or(bad)?;
    let rhs = s.rhs.get_mut(..dim).ok_or(bad)?;
    let grad = s.gradient.get_mut(..dim).ok_or(bad)?;
    system.iter_mut().for_each(|x| *x = T::zero());
    grad.iter_mut().for_each(|x| *x = T::zero());
    let one = T::one();
    let damp = one + lambda;
    // Pass 1: U, g_c, each point's V, g, W.
    for i in 0..tracks.len() {
        let block = s.points.get_mut(i).ok_or(bad)?;
        *block = PointScratch {
            candidate: points.get(i).copied().flatten(),
            ..PointScratch::default()
        };
        let Some(x) = points.get(i).copied().flatten() else {
            continue;
        };
        let range = tracks.range(i);
        let obs = tracks.track(i);
        let u = used.get(range.clone()).ok_or(bad)?;
        let seen = obs
            .iter()
            .zip(u)
            .filter(|(o, u)| **u && matches!(poses.get(usize::from(o.view)), Some(Some(_))))
            .count();
        if seen < 2 || !affected(tracks, i, used, s.index) {
            continue;
        }
        let mut v = Matrix3::<T>::zeros();
        let mut g = Vector3::<T>::zeros();
        for (k, (o, &used)) in obs.iter().zip(u).enumerate() {
            let view = usize::from(o.view);
            let Some(Some(pose)) = poses.get(view) else {
                continue;
            };
            if !used {
                continue;
            }
            let rx = pose.rotation() * x.coords;
            let xc = Point3::from(rx + pose.translation());
            let Ok((proj, jp)) = camera.project_with_jacobian(&xc) else {
                return Ok(false);
            };
            let r = proj - o.pixel;
            let w = huber_weight(r.norm_squared(), delta);
            let jx = jp * pose.rotation().matrix();
            v += jx.transpose() * jx * w;
            g += jx.transpose() * r * w;
            let slot = s.coupling.get_mut(range.start + k).ok_or(bad)?;
            let idx = *s.index.get(view).ok_or(bad)?;
            if idx == u16::MAX {
                *slot = SMatrix::zeros();
                continue;
            }
            let jw = jp * (-rx.cross_matrix());
            let jt = if view == scale {
                let (b1, b2) = tangent_basis(&pose.translation());
                let mut m = nalgebra::Matrix2x3::<T>::zeros();
                m.set_column(0, &(jp * b1));
                m.set_column(1, &(jp * b2));
                m
            } else {
                jp
            };
            let mut jc = SMatrix::<T, 2, 6>::zeros();
            jc.fixed_view_mut::<2, 3>(0, 0).copy_from(&jw);
            jc.fixed_view_mut::<2, 3>(0, 3).copy_from(&jt);
            *slot = jc.transpose() * jx * w;
            let base = 6 * usize::from(idx);
            let ujj = jc.transpose() * jc * w;
            let gj = jc.transpose() * r * w;
            if let Some(gs) = grad.get_mut(base..base + 6) {
                gs.iter_mut().zip(gj.iter()).for_each(|(g, d)| *g += *d);
            }
            // `ujj` is symmetric: its column `a` is its row `a`.
            for (a, col) in ujj.column_iter().enumerate() {
                let row = (base + a) * dim + base;
                if let Some(ss) = system.get_mut(row..row + 6) {
                    ss.iter_mut().zip(col.iter()).for_each(|(s, d)| *s += *d);
                }
            }
        }
        for d in 0..3 {
            if let Some(x) = v.get_mut((d, d)) {
                *x = *x * damp + T::EPSILON;
            }
        }
        if let Some(vi) = v.try_inverse() {
            block.v_inv = vi;
            block.g = g;
            block.active = true;
        }
    }
    // Damping of U; the scale view's third translation unknown does not exist (identity row).
    for j in 0..dim {
        if let Some(d) = system.get_mut(j * dim + j) {
            *d = if *d == T::zero() {
                one
            } else {
                *d * damp + T::EPSILON
            };
        }
    }
    // Pass 2: the Schur complement and the reduced right-hand side.
    rhs.iter_mut().zip(grad.iter()).for_each(|(r, g)| *r = -*g);
    for i in 0..tracks.len() {
        let Some(block) = s.points.get(i).copied() else {
            continue;
        };
        if !block.active {
            continue;
        }
        let range = tracks.range(i);
        let obs = tracks.track(i);
        let u = used.get(range.clone()).ok_or(bad)?;
        let vg = block.v_inv * block.g;
        for (ka, (oa, &ua)) in obs.iter().zip(u).enumerate() {
            let ia = *s.index.get(usize::from(oa.view)).ok_or(bad)?;
            if !ua || ia == u16::MAX || !matches!(poses.get(usize::from(oa.view)), Some(Some(_))) {
                continue;
            }
            let wa = *s.coupling.get(range.start + ka).ok_or(bad)?;
            let wv = wa * block.v_inv;
            let ba = 6 * usize::from(ia);
            let add = wa * vg;
            if let Some(rs) = rhs.get_mut(ba..ba + 6) {
                rs.iter_mut().zip(add.iter()).for_each(|(r, d)| *r += *d);
            }
            for (kb, (ob, &ub)) in obs.iter().zip(u).enumerate() {
                let ib = *s.index.get(usize::from(ob.view)).ok_or(bad)?;
                if !ub
                    || ib == u16::MAX
                    || !matches!(poses.get(usize::from(ob.view)), Some(Some(_)))
                {
                    continue;
                }
                let wb = *s.coupling.get(range.start + kb).ok_or(bad)?;
                // Row `a` of `m = Wₐ V⁻¹ W_bᵀ` is column `a` of `mᵀ`.
                let mt = wb * wv.transpose();
                let bb = 6 * usize::from(ib);
                for (a, col) in mt.column_iter().enumerate() {
                    let row = (ba + a) * dim + bb;
                    if let Some(ss) = system.get_mut(row..row + 6) {
                        ss.iter_mut().zip(col.iter()).for_each(|(s, d)| *s -= *d);
                    }
                }
            }
        }
    }
    if dim > 0 && cholesky_solve(system, dim, rhs).is_err() {
        return Ok(false);
    }
    // Back-substitution: δpᵢ = Vᵢ⁻¹ (-gᵢ - Σ Wᵢᵥᵀ δcᵥ).
    for i in 0..tracks.len() {
        let Some(block) = s.points.get(i).copied() else {
            continue;
        };
        if !block.active {
            continue;
        }
        let Some(x) = points.get(i).copied().flatten() else {
            continue;
        };
        let range = tracks.range(i);
        let mut acc = -block.g;
        for (k, (o, &uk)) in tracks
            .track(i)
            .iter()
            .zip(used.get(range.clone()).ok_or(bad)?)
            .enumerate()
        {
            let idx = *s.index.get(usize::from(o.view)).ok_or(bad)?;
            if !uk || idx == u16::MAX || !matches!(poses.get(usize::from(o.view)), Some(Some(_))) {
                continue;
            }
            let w = *s.coupling.get(range.start + k).ok_or(bad)?;
            let base = 6 * usize::from(idx);
            let dc =
                SVector::<T, 6>::from_fn(|j, _| rhs.get(base + j).copied().unwrap_or(T::zero()));
            acc -= w.transpose() * dc;
        }
        let dp = block.v_inv * acc;
        if let Some(b) = s.points.get_mut(i) {
            b.candidate = Some(x + dp);
        }
    }
    Ok(true)
}
