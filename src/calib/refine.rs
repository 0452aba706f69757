//! The joint Levenberg-Marquardt refinement of a calibration over the intrinsics, the lens
//! coefficients and every view's pose, and the quality figures of its minimum (module docs,
//! steps 3-5).

use heapless::Vec;
use nalgebra::{Point2, Point3, SMatrix, SVector, Vector3};

use super::config::CalibrationParams;
use super::report::{CalibrationReport, CalibrationWarning, ViewRejection};
use super::views::Views;
use crate::camera::{CAMERA_PARAMETERS, Camera, Intrinsics, Lens, LensModel};
use crate::linalg::{StreamingQr, rotation_step};
use crate::pose::{PlanarConfig, solve_planar};
use crate::scalar::{Real, above, check_finite};
use crate::transform::Pose;
use crate::{Error, Result};

/// Camera parameters estimated: `fx fy cx cy` and five lens coefficients.
const NC: usize = CAMERA_PARAMETERS;
/// Columns of a view's block: 6 pose, the camera's, the right-hand side.
const VB: usize = 6 + NC + 1;
/// Columns of the reduced camera system: the camera's and the right-hand side.
const CB: usize = NC + 1;

/// Damping increases tried per iteration before giving up.
const MAX_DAMPING_TRIES: u8 = 8;

/// The state of the joint refinement of up to `V` views: each view's pose, whether it is
/// used, and its block of the linearised system (a 16-column triangular factor).
#[derive(Debug, Clone)]
pub(super) struct Refinement<T: Real, const V: usize> {
    pub(super) poses: [Pose<T>; V],
    used: [bool; V],
    /// Why each view not used was rejected.
    rejections: [Option<ViewRejection>; V],
    blocks: [StreamingQr<T, VB>; V],
}

/// The camera of parameter vector `p` (normalised pixel units) with a lens of `model`.
fn camera<T: Real>(model: LensModel, p: &[T; NC]) -> Result<Camera<T>> {
    let [fx, fy, cx, cy, c1, c2, c3, c4, c5] = *p;
    let k = Intrinsics::new(fx, fy, cx, cy)?;
    Ok(Camera::with_lens(
        k,
        Lens::from_coefficients(model, [c1, c2, c3, c4, c5])?,
    ))
}

/// A view's start pose through the start camera `cam`: [`solve_planar`] on its points. A start
/// camera is rough, and worst far from its axis (a fisheye start whose focal length is short
/// sends a wide view's outer corners towards 90 degrees, where the pose through them puts part
/// of the board behind the camera): when the pose of every point is not found, the pose of the
/// half of the points nearest the axis, then of the quarter, down to 4 points. The joint
/// refinement then uses every point.
fn start_pose<T: Real, const P: usize>(
    cam: &Camera<T>,
    plane: &[Point2<T>],
    pixels: &[Point2<T>],
    scratch: &mut [Point2<T>; P],
) -> Result<Pose<T>> {
    match solve_planar(cam, plane, pixels, scratch, &PlanarConfig::default()) {
        Ok(pp) => Ok(pp.best.pose),
        Err(e) => start_pose_near_axis(cam, plane, pixels, scratch).ok_or(e),
    }
}

/// [`start_pose`]'s fallback: the pose of the nearest half of the points to the axis of `cam`
/// (by their distorted normalised radius), then the nearest quarter, .., while at least 4.
#[inline(never)]
fn start_pose_near_axis<T: Real, const P: usize>(
    cam: &Camera<T>,
    plane: &[Point2<T>],
    pixels: &[Point2<T>],
    scratch: &mut [Point2<T>; P],
) -> Option<Pose<T>> {
    let n = pixels.len().min(plane.len()).min(P);
    let mut radius = [T::zero(); P];
    let mut order = [0usize; P];
    for (i, (r, o)) in radius.iter_mut().zip(order.iter_mut()).take(n).enumerate() {
        let d = pixels
            .get(i)
            .and_then(|u| cam.intrinsics.pixel_to_normalized(u).ok());
        // Not finite or not mapped: last.
        *r = d
            .map(|d| d.coords.norm())
            .filter(|r| r.is_finite())
            .unwrap_or(T::lit(f64::INFINITY));
        *o = i;
    }
    // Insertion sort by radius (bounded: n ≤ P).
    for i in 1..n {
        let mut j = i;
        while j > 0 {
            let (Some(&a), Some(&b)) = (order.get(j - 1), order.get(j)) else {
                break;
            };
            let (Some(&ra), Some(&rb)) = (radius.get(a), radius.get(b)) else {
                break;
            };
            if rb.partial_cmp(&ra) != Some(core::cmp::Ordering::Less) {
                break;
            }
            if let Some(x) = order.get_mut(j - 1) {
                *x = b;
            }
            if let Some(y) = order.get_mut(j) {
                *y = a;
            }
            j -= 1;
        }
    }
    let mut model = [Point2::origin(); P];
    let mut obs = [Point2::origin(); P];
    let mut k = n / 2;
    while k >= 4 {
        for ((m, u), &i) in model
            .iter_mut()
            .zip(obs.iter_mut())
            .zip(order.iter())
            .take(k)
        {
            (*m, *u) = (*plane.get(i)?, *pixels.get(i)?);
        }
        let pp = solve_planar(
            cam,
            model.get(..k)?,
            obs.get(..k)?,
            scratch,
            &PlanarConfig::default(),
        );
        if let Ok(pp) = pp {
            return Some(pp.best.pose);
        }
        k /= 2;
    }
    None
}

impl<T: Real, const V: usize> Refinement<T, V> {
    /// Nothing refined yet.
    pub(super) fn new() -> Self {
        Self {
            poses: [Pose::identity(); V],
            used: [false; V],
            rejections: [None; V],
            blocks: [StreamingQr::new(); V],
        }
    }

    fn is_used(&self, v: usize) -> bool {
        self.used.get(v).copied().unwrap_or(false)
    }

    /// Initial poses, then the joint refinement of the views from the normalised camera `p`.
    pub(super) fn refine<const P: usize>(
        &mut self,
        views: &Views<T, V, P>,
        params: &CalibrationParams,
        p: [T; NC],
    ) -> Result<CalibrationReport<T, V>> {
        if params.config().model != LensModel::KannalaBrandt {
            return self.refine_with(views, params, p, &params.free());
        }
        // Fisheye: the four coefficients of an odd polynomial in θ over the limited range
        // of angles a board covers are nearly dependent, and from a far start LM settles in
        // one of several shallow valleys. Continuation avoids that: k1 alone first, then
        // every coefficient from there.
        let mut stage = params.free();
        for k in 5..NC {
            if let Some(f) = stage.get_mut(k) {
                *f = false;
            }
        }
        let first = self.refine_with(views, params, p, &stage)?;
        let [fx, fy, cx, cy, c1, ..] = views.normalised(&first.camera);
        let q = [
            fx,
            fy,
            cx,
            cy,
            c1,
            T::zero(),
            T::zero(),
            T::zero(),
            T::zero(),
        ];
        self.refine_with(views, params, q, &params.free())
    }

    fn refine_with<const P: usize>(
        &mut self,
        views: &Views<T, V, P>,
        params: &CalibrationParams,
        p: [T; NC],
        free: &[bool; NC],
    ) -> Result<CalibrationReport<T, V>> {
        let free = *free;
        let model = params.config().model;
        let aspect = params.aspect::<T>();
        let mut p = p;
        // Initial poses through the initial camera.
        let cam0 = camera(model, &p)?;
        let mut scratch = [Point2::origin(); P];
        let mut used = 0usize;
        for v in 0..views.count {
            let rejection = match views.check_view(v) {
                Some(r) => Some(r),
                None => {
                    let (plane, pixels) = views.view_plane(v);
                    let plane = plane.get(..pixels.len()).ok_or(Error::LengthMismatch)?;
                    match start_pose(&cam0, plane, pixels, &mut scratch) {
                        Ok(pose) => {
                            if let Some(slot) = self.poses.get_mut(v) {
                                *slot = pose;
                            }
                            None
                        }
                        Err(_) => Some(ViewRejection::PoseNotFound),
                    }
                }
            };
            if let Some(u) = self.used.get_mut(v) {
                *u = rejection.is_none();
            }
            if let Some(r) = self.rejections.get_mut(v) {
                *r = rejection;
            }
            used += rejection.is_none() as usize;
        }
        if used < 3 {
            return Err(Error::TooFewPoints);
        }
        let mut cam = cam0;
        let mut poses = self.poses;
        let mut cost = self.cost(views, &cam, &poses).ok_or(Error::Degenerate)?;
        let initial_cost = cost;
        // Stop when a step gains less than the rounding of the cost itself: in the curved, narrow
        // valleys of the lens coefficients a small decrease does not mean the minimum is near.
        let tol = T::lit(16.0) * T::EPSILON;
        let mut lambda = T::lit(1e-3);
        let mut iterations = 0u8;
        for _ in 0..params.config().max_iterations {
            self.poses = poses;
            if !self.linearise(views, &cam, &free, aspect) {
                break;
            }
            // Marquardt scaling of the camera columns: their norms over every view.
            let mut cam_scale = [T::zero(); NC];
            for v in 0..views.count {
                if !self.is_used(v) {
                    continue;
                }
                let Some(b) = self.blocks.get(v) else {
                    continue;
                };
                for (k, s) in cam_scale.iter_mut().enumerate() {
                    let c = b.r().column(6 + k).norm();
                    *s += c * c;
                }
            }
            for s in cam_scale.iter_mut() {
                *s = s.sqrt();
            }
            let mut accepted = None;
            for _ in 0..MAX_DAMPING_TRIES {
                let candidate = self.step(views, params, &p, &poses, lambda, &free, &cam_scale);
                let next = candidate.ok().and_then(|(np, nposes)| {
                    let c = camera(model, &np).ok()?;
                    let nc = self.cost(views, &c, &nposes)?;
                    Some((np, nposes, c, nc))
                });
                match next {
                    Some((np, nposes, c, nc)) if nc < cost => {
                        accepted = Some((np, nposes, c, nc));
                        lambda = (lambda * T::lit(0.1)).max(T::lit(1e-12));
                        break;
                    }
                    _ => lambda *= T::lit(10.0),
                }
            }
            let Some((np, nposes, c, nc)) = accepted else {
                break;
            };

            let decrease = cost - nc;
            p = np;
            poses = nposes;
            cam = c;
            cost = nc;
            iterations = iterations.saturating_add(1);
            if decrease <= tol * cost {
                break;
            }
        }
        self.poses = poses;
        self.report(
            views,
            params,
            &p,
            &cam,
            (cost, initial_cost),
            iterations,
            &free,
        )
    }

    /// One damped Gauss-Newton step of every parameter.
    #[allow(clippy::too_many_arguments)]
    fn step<const P: usize>(
        &self,
        views: &Views<T, V, P>,
        params: &CalibrationParams,
        p: &[T; NC],
        poses: &[Pose<T>; V],
        lambda: T,
        free: &[bool; NC],
        cam_scale: &[T; NC],
    ) -> Result<([T; NC], [Pose<T>; V])> {
        let g = self.reduced(views, Some(lambda), free, cam_scale)?;
        let r = g.r();
        let dc = r
            .fixed_view::<NC, NC>(0, 0)
            .solve_upper_triangular(&r.fixed_view::<NC, 1>(0, NC))
            .ok_or(Error::Degenerate)?;
        check_finite(dc.as_slice())?;
        let mut np = *p;
        for (x, d) in np.iter_mut().zip(dc.iter()) {
            *x += *d;
        }
        if let Some(a) = params.aspect::<T>() {
            np[0] = a * np[1];
        }
        if params.config().flags.fix_principal_point {
            np[2] = T::zero();
            np[3] = T::zero();
        }
        let mut nposes = *poses;
        for v in 0..views.count {
            if !self.is_used(v) {
                continue;
            }
            let d = self.damped_block(v, Some(lambda))?;
            let rv = d.r();
            let rpp = rv.fixed_view::<6, 6>(0, 0);
            let rpc = rv.fixed_view::<6, NC>(0, 6);
            let cp = rv.fixed_view::<6, 1>(0, 6 + NC);
            let rhs: SVector<T, 6> = cp - rpc * dc;
            let dp = rpp.solve_upper_triangular(&rhs).ok_or(Error::Degenerate)?;
            check_finite(dp.as_slice())?;
            let pose = poses.get(v).ok_or(Error::LengthMismatch)?;
            let [w1, w2, w3, t1, t2, t3]: [T; 6] = dp.into();
            let rot = rotation_step(&Vector3::new(w1, w2, w3)) * pose.rotation();
            let t = pose.translation() + Vector3::new(t1, t2, t3);
            if let Some(slot) = nposes.get_mut(v) {
                *slot = Pose::new(rot, t)?;
            }
        }
        Ok((np, nposes))
    }

    /// Sum of squared normalised residuals of the used views.
    fn cost<const P: usize>(
        &self,
        views: &Views<T, V, P>,
        cam: &Camera<T>,
        poses: &[Pose<T>; V],
    ) -> Option<T> {
        let mut c = T::zero();
        for v in 0..views.count {
            if !self.is_used(v) {
                continue;
            }
            let pose = poses.get(v)?;
            for (x, o) in views.pairs(v) {
                let u = cam.project(pose, &x).ok()?;
                c += (u - o).norm_squared();
            }
        }
        c.finite().then_some(c)
    }

    /// The view blocks at the current estimate; `false` when a corner does not project.
    fn linearise<const P: usize>(
        &mut self,
        views: &Views<T, V, P>,
        cam: &Camera<T>,
        free: &[bool; NC],
        aspect: Option<T>,
    ) -> bool {
        for v in 0..views.count {
            if !self.is_used(v) {
                continue;
            }
            let Some(&pose) = self.poses.get(v) else {
                return false;
            };
            let mut qr = StreamingQr::<T, VB>::new();
            for (x, o) in views.pairs(v) {
                let rx = pose.apply_vector(&x.coords);
                let xc = Point3::from(rx + pose.translation());
                let Ok((u, jx, mut jp)) = cam.project_with_parameter_jacobian(&xc) else {
                    return false;
                };
                if let Some(a) = aspect {
                    // fx = a fy: the fy column carries both.
                    let jfx = jp.column(0).into_owned();
                    let mut jfy = jp.column_mut(1);
                    jfy += jfx * a;
                }
                for (mut col, f) in jp.column_iter_mut().zip(free.iter()) {
                    if !*f {
                        col.fill(T::zero());
                    }
                }
                let jw = jx * (-rx.cross_matrix());
                let r = u - o;
                for row in 0..2 {
                    let mut a = [T::zero(); VB];
                    for (c, slot) in a.iter_mut().enumerate() {
                        *slot = if c < 3 {
                            jw.get((row, c)).copied().unwrap_or(T::zero())
                        } else if c < 6 {
                            jx.get((row, c - 3)).copied().unwrap_or(T::zero())
                        } else if c < 6 + NC {
                            jp.get((row, c - 6)).copied().unwrap_or(T::zero())
                        } else if row == 0 {
                            -r.x
                        } else {
                            -r.y
                        };
                    }
                    if qr.push_row(&a).is_err() {
                        return false;
                    }
                }
            }
            if let Some(b) = self.blocks.get_mut(v) {
                *b = qr;
            }
        }
        true
    }

    /// The reduced camera system of the view blocks, each pose damped by `lambda` (`None`:
    /// undamped), with unit rows pinning the fixed parameters, and the camera damping rows.
    fn reduced<const P: usize>(
        &self,
        views: &Views<T, V, P>,
        lambda: Option<T>,
        free: &[bool; NC],
        cam_scale: &[T; NC],
    ) -> Result<StreamingQr<T, CB>> {
        let mut g = StreamingQr::<T, CB>::new();
        for v in 0..views.count {
            if !self.is_used(v) {
                continue;
            }
            let d = self.damped_block(v, lambda)?;
            let r = d.r();
            for i in 6..VB {
                let row: [T; CB] =
                    core::array::from_fn(|c| r.get((i, 6 + c)).copied().unwrap_or(T::zero()));
                g.push_row(&row)?;
            }
        }
        for (k, f) in free.iter().enumerate() {
            let mut row = [T::zero(); CB];
            if let Some(x) = row.get_mut(k) {
                *x = if *f {
                    match lambda {
                        Some(l) => l.sqrt() * cam_scale.get(k).copied().unwrap_or(T::one()),
                        None => T::zero(),
                    }
                } else {
                    T::one()
                };
            }
            g.push_row(&row)?;
        }
        Ok(g)
    }

    /// View `v`'s block with its pose columns damped (Marquardt's scaling).
    fn damped_block(&self, v: usize, lambda: Option<T>) -> Result<StreamingQr<T, VB>> {
        let mut d = *self.blocks.get(v).ok_or(Error::LengthMismatch)?;
        if let Some(l) = lambda {
            let sl = l.sqrt();
            let scales: [T; 6] = core::array::from_fn(|k| d.r().column(k).norm());
            for (k, s) in scales.iter().enumerate() {
                let mut row = [T::zero(); VB];
                if let Some(x) = row.get_mut(k) {
                    *x = sl * *s;
                }
                d.push_row(&row)?;
            }
        }
        Ok(d)
    }

    /// The report of the minimum `p` (camera `cam`) with its `(cost, initial cost)`: errors,
    /// poses in the caller's units, standard deviations and warnings (module docs, step 5).
    #[allow(clippy::too_many_arguments)]
    fn report<const P: usize>(
        &mut self,
        views: &Views<T, V, P>,
        params: &CalibrationParams,
        p: &[T; NC],
        cam: &Camera<T>,
        (cost, initial_cost): (T, T),
        iterations: u8,
        free: &[bool; NC],
    ) -> Result<CalibrationReport<T, V>> {
        let cfg = params.config();
        let aspect = params.aspect::<T>();
        let s = views.scale();
        let c0 = views.centre();
        let used = self.used.iter().take(views.count).filter(|u| **u).count();
        // Observations of the used views.
        let n: usize = (0..views.count)
            .filter(|&v| self.is_used(v))
            .map(|v| views.len(v))
            .sum();
        let total = T::lit(n as f64);
        let rms = |c: T, count: T| (c / count).sqrt() * s;
        // Per-view errors and the poses in the caller's units.
        let mut per_view = [None; V];
        let mut poses_out = [None; V];
        for v in 0..views.count {
            if !self.is_used(v) {
                continue;
            }
            let pose = *self.poses.get(v).ok_or(Error::LengthMismatch)?;
            let mut c = T::zero();
            for (x, o) in views.pairs(v) {
                let u = cam.project(&pose, &x)?;
                c += (u - o).norm_squared();
            }
            if let Some(slot) = per_view.get_mut(v) {
                *slot = Some(rms(c, T::lit(views.len(v) as f64)));
            }
            if let Some(slot) = poses_out.get_mut(v) {
                *slot = Some(Pose::new(
                    pose.rotation(),
                    pose.translation() * views.square,
                )?);
            }
        }
        // Standard deviations: σ² diag((JᵀJ)⁻¹) of the camera block = σ² diag(S⁻¹), with the
        // Schur complement S = R_cᵀ R_c of the undamped reduced system.
        self.linearise(views, cam, free, aspect);
        let g = self.reduced(views, None, free, &[T::one(); NC])?;
        let rc: SMatrix<T, NC, NC> = g.r().fixed_view::<NC, NC>(0, 0).into_owned();
        let n_free = free.iter().filter(|f| **f).count();
        let dof = T::lit((2 * n) as f64) - T::lit((n_free + 6 * used) as f64);
        let mut std = [T::zero(); NC];
        if above(dof, T::zero()) {
            let sigma2 = cost / dof;
            if let Some(inv) = rc.solve_upper_triangular(&SMatrix::<T, NC, NC>::identity()) {
                for (k, sd) in std.iter_mut().enumerate() {
                    if !free.get(k).copied().unwrap_or(false) {
                        continue;
                    }
                    let var = inv.row(k).norm_squared() * sigma2;
                    // Pixel-valued parameters scale back by s.
                    let unit = if k < 4 { s } else { T::one() };
                    *sd = var.sqrt() * unit;
                }
            } else {
                for sd in std.iter_mut() {
                    *sd = T::max_value().unwrap_or(T::one() / T::EPSILON);
                }
            }
        }
        if aspect.is_some() {
            // fx follows fy.
            std[0] = std[1] * aspect.unwrap_or(T::one());
        }
        let [fx, fy, cx, cy, c1, c2, c3, c4, c5] = *p;
        let k = Intrinsics::new(fx * s, fy * s, cx * s + c0.x, cy * s + c0.y)
            .map_err(|_| Error::NoConvergence)?;
        let camera =
            Camera::with_lens(k, Lens::from_coefficients(cfg.model, [c1, c2, c3, c4, c5])?);
        let mut warnings = Vec::new();
        let lim = |x: f64| T::lit(x);
        let [sfx, sfy, scx, scy, ..] = std;
        if sfx > lim(cfg.focal_warning) * k.fx() || sfy > lim(cfg.focal_warning) * k.fy() {
            let _ = warnings.push(CalibrationWarning::FocalLengthUnconstrained);
        }
        let (w, h) = (T::lit(views.width as f64), T::lit(views.height as f64));
        if scx > lim(cfg.principal_point_warning) * w || scy > lim(cfg.principal_point_warning) * h
        {
            let _ = warnings.push(CalibrationWarning::PrincipalPointUnconstrained);
        }
        if std.iter().skip(4).any(|x| *x > lim(cfg.distortion_warning)) {
            let _ = warnings.push(CalibrationWarning::DistortionUnconstrained);
        }
        let report = CalibrationReport {
            camera,
            rms_px: rms(cost, total),
            initial_rms_px: rms(initial_cost, total),
            per_view_rms_px: per_view,
            poses: poses_out,
            rejections: self.rejections,
            views_used: used,
            views_added: views.count,
            std,
            iterations,
            warnings,
        };
        if !report.rms_px.finite() {
            return Err(Error::NoConvergence);
        }
        Ok(report)
    }
}
