//! Camera calibration from views of a planar chessboard (Zhang's method, as OpenCV's
//! `calibrateCamera` and `fisheye::calibrate`).
//!
//! A [`Calibrator`] collects up to `V` views of a board of at most `P` corners into fixed
//! memory, one view at a time (so a board can add each detection as it comes, see
//! [`Calibrator::add_chessboard`]), then [`Calibrator::solve`] estimates the camera:
//!
//! 1. **Normalisation.** Pixels become `u' = (u - c₀) / s` with `c₀` the image centre and
//!    `s = max(width, height)`, board corners are `(i, j, 0)` in squares: every unknown and
//!    every residual is of order one, which keeps the `f32` solve accurate.
//! 2. **Initial intrinsics** by Zhang's closed form on the per-view homographies
//!    ([`crate::homography::dlt`]): each `H = K [r₁ r₂ t]` gives two linear constraints on
//!    `B = K⁻ᵀK⁻¹`. With [`CalibrationFlags::fix_principal_point`] (or when the closed form
//!    has no positive-definite solution) OpenCV's initialisation is used instead: principal
//!    point at the centre, focal lengths from the same constraints. Distortion starts at zero.
//! 3. **Initial poses** by [`crate::pose::solve_planar`] (IPPE + LM) through that camera; a
//!    view whose pose cannot be found is rejected (listed in the report).
//! 4. **Joint Levenberg-Marquardt** over the intrinsics (`fx fy cx cy`, lens coefficients) and
//!    every view's pose (rotation `exp([ω]ₓ) R`, translation), minimising the pixel
//!    reprojection error through the full lens model (Brown-Conrady or Kannala-Brandt, the
//!    same code: [`Camera::project_with_parameter_jacobian`]). The Jacobian has one dense
//!    6-column block per view and 9 shared columns; its structure is used without ever
//!    forming `JᵀJ`: each view's rows `[J_pose | J_cam | -r]` are folded into a 16-column
//!    streaming QR, whose lower right 10x10 block is that view's contribution to the reduced
//!    camera system in square-root form (the pose eliminated orthogonally: the Schur
//!    complement `U - W V⁻¹ Wᵀ` equals `R_ccᵀ R_cc`). Those blocks and the damping rows are
//!    stacked into a 10-column QR that gives the camera step; each pose step follows by back
//!    substitution in its own block. Marquardt's scaling (`D = diag |J columns|`), at most
//!    [`CalibrationConfig::max_iterations`] steps and 8 damping increases a step.
//! 5. **Quality.** RMS over all views and per view; the standard deviation of each camera
//!    parameter as OpenCV's `calibrateCameraExtended`: `σ² = SSE / (2N - n_params)` times the
//!    diagonal of `(JᵀJ)⁻¹` restricted to the camera block, which is the inverse of the
//!    reduced system (from its triangular factor, not by inverting `JᵀJ`); a typed
//!    [`CalibrationWarning`] when a parameter is not constrained by the views.
//!
//! Memory: [`Calibrator::MEMORY`] bytes, all in the struct (`V · P` observations, `V` poses
//! and `V` 16x16 triangular factors): 59,600 bytes for `f32`, 32 views of up to 100 corners
//! (118,864 for `f64`); 23,936 bytes for `f32`, 16 views of a 9x6 board.
//!
//! ```
//! use camgeom::calib::{CalibrationConfig, Calibrator};
//! use camgeom::camera::{Camera, Distortion, Intrinsics};
//! use camgeom::chessboard::BoardSize;
//! use camgeom::nalgebra::{Point3, Vector3};
//! use camgeom::transform::Pose;
//!
//! // Four synthetic views of a 6x4 board (25 mm squares) through a known camera.
//! let truth = Camera::new(
//!     Intrinsics::new(520.0f64, 515.0, 322.0, 241.0)?,
//!     Distortion::from_opencv([-0.2, 0.05, 0.0, 0.0, 0.0])?,
//! );
//! let board = BoardSize::new(6, 4)?;
//! let mut cal = Box::new(Calibrator::<f64, 8, 24>::new(board, 0.025, 640, 480)?);
//! for (r, t) in [
//!     ([0.3, -0.2, 0.1], [-0.06, -0.04, 0.3]),
//!     ([-0.3, 0.3, -0.2], [-0.05, -0.03, 0.28]),
//!     ([0.1, 0.4, 0.3], [-0.07, -0.02, 0.33]),
//!     ([-0.4, -0.1, 0.0], [-0.04, -0.05, 0.31]),
//! ] {
//!     let pose = Pose::from_rodrigues(Vector3::from(r), Vector3::from(t))?;
//!     let mut px = [Default::default(); 24];
//!     for (k, p) in px.iter_mut().enumerate() {
//!         let x = Point3::new(0.025 * (k % 6) as f64, 0.025 * (k / 6) as f64, 0.0);
//!         *p = truth.project(&pose, &x)?;
//!     }
//!     cal.add_view(640, 480, &px)?;
//! }
//! let mut cfg = CalibrationConfig::default();
//! cfg.flags.zero_tangent = true;
//! cfg.flags.fix_k3 = true;
//! let report = cal.solve(&cfg)?;
//! assert!(report.rms_px < 1e-6);
//! assert!((report.camera.intrinsics.fx() - 520.0).abs() < 1e-4);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod zhang;

use heapless::Vec;
use nalgebra::{Point2, Point3, SMatrix, SVector, Vector3};

use crate::camera::{CAMERA_PARAMETERS, Camera, Intrinsics, Lens, LensModel};
use crate::chessboard::{BoardSize, Chessboard};
use crate::homography::dlt;
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

/// The fixed aspect ratios [`CalibrationFlags::fix_aspect_ratio`] accepts, `1e-3 ..= 1e3`
/// (real pixels are within a few percent of square). The closed form divides by the ratio's
/// square: a ratio far outside this range (`8e-39` squares to zero in `f32`) made the
/// calibration fail with an undocumented `NonFinite` instead of a parameter error.
pub const ASPECT_RATIO_RANGE: core::ops::RangeInclusive<f64> = 1e-3..=1e3;

/// Which parameters stay fixed, as OpenCV's calibration flags.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationFlags {
    /// `Some(a)`: `fx = a fy` throughout (`CALIB_FIX_ASPECT_RATIO`, with the ratio given here
    /// rather than through an initial camera matrix). In [`ASPECT_RATIO_RANGE`].
    pub fix_aspect_ratio: Option<f64>,
    /// The principal point stays at the image centre `((w - 1)/2, (h - 1)/2)`
    /// (`CALIB_FIX_PRINCIPAL_POINT`).
    pub fix_principal_point: bool,
    /// Brown-Conrady only: `p1 = p2 = 0` (`CALIB_ZERO_TANGENT_DIST`).
    pub zero_tangent: bool,
    /// `k3 = 0` (`CALIB_FIX_K3`; for the fisheye model OpenCV's `fisheye::CALIB_FIX_K3`).
    pub fix_k3: bool,
    /// Fisheye only: `k4 = 0` (`fisheye::CALIB_FIX_K4`).
    pub fix_k4: bool,
}

/// Options of [`Calibrator::solve`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationConfig {
    /// The lens model to estimate: Brown-Conrady (OpenCV's `calibrateCamera`) or
    /// Kannala-Brandt (OpenCV's `fisheye::calibrate`, with `CALIB_FIX_SKEW`).
    pub model: LensModel,
    /// Fixed parameters.
    pub flags: CalibrationFlags,
    /// Levenberg-Marquardt steps at most (`1..=255`; OpenCV's default criteria stop at 30).
    pub max_iterations: u8,
    /// Warn when the standard deviation of `fx` or `fy` exceeds this fraction of its value.
    pub focal_warning: f64,
    /// Warn when the standard deviation of `cx` or `cy` exceeds this fraction of the image's
    /// width or height.
    pub principal_point_warning: f64,
    /// Warn when the standard deviation of a lens coefficient exceeds this.
    pub distortion_warning: f64,
}

impl Default for CalibrationConfig {
    /// Brown-Conrady, nothing fixed, 50 steps; warnings at 5 % of the focal length, 5 % of
    /// the image size and a coefficient standard deviation of 1. The bundled 13-view
    /// calibration has 0.09 % / 0.2 % / 0.24 (k3), well inside; fronto-parallel views alone
    /// give a focal-length deviation of tens of percent.
    fn default() -> Self {
        Self {
            model: LensModel::BrownConrady,
            flags: CalibrationFlags::default(),
            max_iterations: 50,
            focal_warning: 0.05,
            principal_point_warning: 0.05,
            distortion_warning: 1.0,
        }
    }
}

/// A parameter the views do not constrain (its standard deviation is beyond the configured
/// bound): add views at other angles or fix it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CalibrationWarning {
    /// `fx` or `fy` (typical of views all nearly fronto-parallel).
    FocalLengthUnconstrained,
    /// `cx` or `cy`.
    PrincipalPointUnconstrained,
    /// A lens coefficient.
    DistortionUnconstrained,
}

/// Everything a calibration found, for a report, a file or a JSON answer.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CalibrationReport<T: Real, const V: usize> {
    /// The calibrated camera (pixels of the calibration images).
    pub camera: Camera<T>,
    /// RMS reprojection error over every used corner, pixels (OpenCV's `rms`).
    pub rms_px: T,
    /// RMS before the joint refinement (from the closed-form start).
    pub initial_rms_px: T,
    /// Per view: `Some(rms)` for a used view, `None` for a rejected one (in the order added).
    pub per_view_rms_px: [Option<T>; V],
    /// Per view: the board's pose (board frame: corner `(i, j)` at `(i s, j s, 0)`, metres
    /// or whatever unit the square size was given in), `None` for a rejected view.
    pub poses: [Option<Pose<T>>; V],
    /// Views used.
    pub views_used: usize,
    /// Views added.
    pub views_added: usize,
    /// Standard deviation of `fx, fy, cx, cy` and the lens coefficients (OpenCV's order:
    /// `k1 k2 p1 p2 k3`, or fisheye `k1 k2 k3 k4` and a zero); zero for a fixed parameter.
    pub std: [T; CAMERA_PARAMETERS],
    /// Accepted Levenberg-Marquardt steps.
    pub iterations: u8,
    /// Parameters the views do not constrain.
    pub warnings: Vec<CalibrationWarning, 3>,
}

impl<T: Real, const V: usize> CalibrationReport<T, V> {
    /// Indices of the rejected views (in the order added).
    pub fn rejected(&self) -> impl Iterator<Item = usize> + '_ {
        self.per_view_rms_px
            .iter()
            .take(self.views_added)
            .enumerate()
            .filter_map(|(i, r)| r.is_none().then_some(i))
    }
}

/// Collects board views into fixed memory and calibrates: up to `V` views of a board of at
/// most `P` inner corners.
#[derive(Debug, Clone)]
pub struct Calibrator<T: Real, const V: usize, const P: usize> {
    cols: usize,
    rows: usize,
    square: T,
    width: usize,
    height: usize,
    views: usize,
    /// Normalised observations `(u - c₀) / s`, row-major board order.
    obs: [[Point2<T>; P]; V],
    poses: [Pose<T>; V],
    used: [bool; V],
    blocks: [StreamingQr<T, VB>; V],
}

/// The state of the joint refinement.
#[derive(Debug, Clone, Copy)]
struct Params<T: Real> {
    cam: [T; NC],
}

impl<T: Real, const V: usize, const P: usize> Calibrator<T, V, P> {
    /// Bytes of a calibrator (it holds everything; no scratch).
    pub const MEMORY: usize = core::mem::size_of::<Self>();

    /// A calibrator for `board` (inner corners) with squares of side `square` (any unit:
    /// the poses come out in it) seen in `width x height` images.
    ///
    /// Errors: `InvalidParameter("square")` for a zero, negative or non-finite square,
    /// `BufferTooSmall("corners")` when the board has more than `P` corners,
    /// [`Error::InvalidImage`] for a zero-sized image.
    pub fn new(board: BoardSize, square: T, width: usize, height: usize) -> Result<Self> {
        if !(square.finite() && above(square, T::zero())) {
            return Err(Error::InvalidParameter("square"));
        }
        if board.corners() > P {
            return Err(Error::BufferTooSmall("corners"));
        }
        if width == 0
            || height == 0
            || width > crate::image::MAX_DIM
            || height > crate::image::MAX_DIM
        {
            return Err(Error::InvalidImage);
        }
        Ok(Self {
            cols: board.cols(),
            rows: board.rows(),
            square,
            width,
            height,
            views: 0,
            obs: [[Point2::origin(); P]; V],
            poses: [Pose::identity(); V],
            used: [false; V],
            blocks: [StreamingQr::new(); V],
        })
    }

    /// Views added so far.
    pub fn views(&self) -> usize {
        self.views
    }

    /// Forgets every view (the board and image size stay).
    pub fn clear(&mut self) {
        self.views = 0;
    }

    fn corners(&self) -> usize {
        self.cols * self.rows
    }

    fn scale(&self) -> T {
        T::lit(self.width.max(self.height) as f64)
    }

    fn centre(&self) -> Point2<T> {
        Point2::new(
            T::lit((self.width as f64 - 1.0) * 0.5),
            T::lit((self.height as f64 - 1.0) * 0.5),
        )
    }

    /// Adds one view: the board's corners in pixels, row-major in the board's order (as
    /// [`crate::chessboard`] and OpenCV's `findChessboardCorners` give them), seen in an
    /// image of `width x height`. Returns the view's index.
    ///
    /// Errors: [`Error::InvalidImage`] when the size differs from the calibrator's,
    /// [`Error::LengthMismatch`] for a corner count other than the board's,
    /// [`Error::NonFinite`], `BufferTooSmall("views")` when `V` views are already held.
    pub fn add_view(
        &mut self,
        width: usize,
        height: usize,
        corners: &[Point2<T>],
    ) -> Result<usize> {
        if width != self.width || height != self.height {
            return Err(Error::InvalidImage);
        }
        if corners.len() != self.corners() {
            return Err(Error::LengthMismatch);
        }
        for c in corners {
            check_finite(&[c.x, c.y])?;
        }
        let (c0, s) = (self.centre(), self.scale());
        let slot = self
            .obs
            .get_mut(self.views)
            .ok_or(Error::BufferTooSmall("views"))?;
        for (o, c) in slot.iter_mut().zip(corners) {
            *o = Point2::from((c - c0) / s);
        }
        self.views += 1;
        Ok(self.views - 1)
    }

    /// [`Self::add_view`] of a detected board (its corners converted to `T`).
    pub fn add_chessboard<const N: usize>(
        &mut self,
        width: usize,
        height: usize,
        board: &Chessboard<N>,
    ) -> Result<usize> {
        if board.size.cols() != self.cols || board.size.rows() != self.rows {
            return Err(Error::LengthMismatch);
        }
        let mut pts = [Point2::origin(); P];
        let n = board.corners.len();
        for (o, c) in pts.iter_mut().zip(board.corners.iter()) {
            *o = Point2::new(T::lit(c.x as f64), T::lit(c.y as f64));
        }
        self.add_view(width, height, pts.get(..n).ok_or(Error::LengthMismatch)?)
    }

    /// Board corner `k` in squares, `(i, j, 0)`.
    fn board_point(&self, k: usize) -> Point3<T> {
        Point3::new(
            // `max(1)`: `BoardSize` has at least one column, but the optimiser cannot see it.
            T::lit((k % self.cols.max(1)) as f64),
            T::lit((k / self.cols.max(1)) as f64),
            T::zero(),
        )
    }

    fn view_obs(&self, v: usize) -> &[Point2<T>] {
        let n = self.corners();
        self.obs.get(v).and_then(|o| o.get(..n)).unwrap_or_default()
    }

    /// The camera of parameter vector `p` (normalised pixel units).
    fn camera(&self, model: LensModel, p: &[T; NC]) -> Result<Camera<T>> {
        let [fx, fy, cx, cy, c1, c2, c3, c4, c5] = *p;
        let k = Intrinsics::new(fx, fy, cx, cy)?;
        Ok(Camera::with_lens(
            k,
            Lens::from_coefficients(model, [c1, c2, c3, c4, c5])?,
        ))
    }

    /// Which camera parameters are free.
    fn free(&self, cfg: &CalibrationConfig) -> [bool; NC] {
        let f = &cfg.flags;
        let mut free = [true; NC];
        let set = |free: &mut [bool; NC], k: usize| {
            if let Some(x) = free.get_mut(k) {
                *x = false;
            }
        };
        if f.fix_aspect_ratio.is_some() {
            set(&mut free, 0);
        }
        if f.fix_principal_point {
            set(&mut free, 2);
            set(&mut free, 3);
        }
        match cfg.model {
            LensModel::BrownConrady => {
                if f.zero_tangent {
                    set(&mut free, 6);
                    set(&mut free, 7);
                }
                if f.fix_k3 {
                    set(&mut free, 8);
                }
            }
            LensModel::KannalaBrandt => {
                if f.fix_k3 {
                    set(&mut free, 6);
                }
                if f.fix_k4 {
                    set(&mut free, 7);
                }
                set(&mut free, 8);
            }
        }
        free
    }

    /// Sum of squared normalised residuals of the used views.
    fn cost(&self, cam: &Camera<T>, poses: &[Pose<T>; V]) -> Option<T> {
        let mut c = T::zero();
        for v in 0..self.views {
            if !self.used.get(v).copied().unwrap_or(false) {
                continue;
            }
            let pose = poses.get(v)?;
            for (k, o) in self.view_obs(v).iter().enumerate() {
                let u = cam.project(pose, &self.board_point(k)).ok()?;
                c += (u - o).norm_squared();
            }
        }
        c.finite().then_some(c)
    }

    /// The view blocks at the current estimate; `false` when a corner does not project.
    fn linearise(&mut self, cam: &Camera<T>, free: &[bool; NC], aspect: Option<T>) -> bool {
        for v in 0..self.views {
            if !self.used.get(v).copied().unwrap_or(false) {
                continue;
            }
            let Some(&pose) = self.poses.get(v) else {
                return false;
            };
            let mut qr = StreamingQr::<T, VB>::new();
            for k in 0..self.corners() {
                let Some(o) = self.obs.get(v).and_then(|o| o.get(k)).copied() else {
                    return false;
                };
                let x = self.board_point(k);
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
    fn reduced(
        &self,
        lambda: Option<T>,
        free: &[bool; NC],
        cam_scale: &[T; NC],
    ) -> Result<StreamingQr<T, CB>> {
        let mut g = StreamingQr::<T, CB>::new();
        for v in 0..self.views {
            if !self.used.get(v).copied().unwrap_or(false) {
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

    /// Calibrates from the views added (see the module documentation).
    ///
    /// Errors: [`Error::TooFewPoints`] with fewer than 3 usable views,
    /// [`Error::Degenerate`] when the views do not determine the camera (all parallel, e.g.
    /// fronto-parallel), `InvalidParameter("flags.fix_aspect_ratio")` / `("max_iterations")`
    /// for bad options, [`Error::NoConvergence`] when the refinement ends with a
    /// non-finite or non-physical camera.
    pub fn solve(&mut self, cfg: &CalibrationConfig) -> Result<CalibrationReport<T, V>> {
        let aspect = self.check(cfg)?;
        let p = self.closed_form(cfg, aspect)?;
        let first = self.refine(cfg, aspect, p);
        if cfg.model != LensModel::KannalaBrandt {
            return first;
        }
        // A fisheye lens is far from the pinhole the closed form assumes, and the lens
        // coefficients' cost has more than one valley: also start from OpenCV's fisheye
        // initialisation (`f = max(w, h) / π`, principal point at the centre) and keep the
        // lower minimum.
        let f = T::one() / T::pi();
        let ratio = aspect.unwrap_or(T::one());
        let z = T::zero();
        let alt = Params {
            cam: [f * ratio, f, z, z, z, z, z, z, z],
        };
        let keep_first = first.clone();
        let first_poses = self.poses;
        match (first, self.refine(cfg, aspect, alt)) {
            (Ok(a), Ok(b)) if a.rms_px <= b.rms_px => {
                self.poses = first_poses;
                Ok(a)
            }
            (_, Ok(b)) => Ok(b),
            (Ok(_), Err(_)) => {
                self.poses = first_poses;
                keep_first
            }
            (Err(e), Err(_)) => Err(e),
        }
    }

    /// [`Self::solve`] from a given camera instead of the closed form (OpenCV's
    /// `CALIB_USE_INTRINSIC_GUESS`): its intrinsics and lens coefficients start the joint
    /// refinement (the model of `cfg` is used; the coefficients of a lens of the other model are ignored).
    ///
    /// Errors: as [`Self::solve`]; [`Error::NonFinite`] for a non-finite guess,
    /// [`Error::InvalidIntrinsics`] for one whose focal lengths, in units of
    /// `max(width, height)`, are below [`Intrinsics::new`]'s `√ε` (a guess of a fraction of a
    /// pixel).
    pub fn solve_with_guess(
        &mut self,
        cfg: &CalibrationConfig,
        guess: &Camera<T>,
    ) -> Result<CalibrationReport<T, V>> {
        let aspect = self.check(cfg)?;
        let (s, c0) = (self.scale(), self.centre());
        let k = &guess.intrinsics;
        let c = if guess.lens.model() == cfg.model {
            guess.lens.coefficients()
        } else {
            [T::zero(); 5]
        };
        let [c1, c2, c3, c4, c5] = c;
        let mut cam = [
            k.fx() / s,
            k.fy() / s,
            (k.cx() - c0.x) / s,
            (k.cy() - c0.y) / s,
            c1,
            c2,
            c3,
            c4,
            c5,
        ];
        check_finite(&cam)?;
        if let Some(a) = aspect {
            cam[0] = a * cam[1];
        }
        if cfg.flags.fix_principal_point {
            cam[2] = T::zero();
            cam[3] = T::zero();
        }
        self.refine(cfg, aspect, Params { cam })
    }

    /// Validates the options; the fixed aspect ratio.
    fn check(&self, cfg: &CalibrationConfig) -> Result<Option<T>> {
        if cfg.max_iterations == 0 {
            return Err(Error::InvalidParameter("max_iterations"));
        }
        let aspect = match cfg.flags.fix_aspect_ratio {
            Some(a) if ASPECT_RATIO_RANGE.contains(&a) => Some(T::lit(a)),
            Some(_) => return Err(Error::InvalidParameter("flags.fix_aspect_ratio")),
            None => None,
        };
        if self.views < 3 {
            return Err(Error::TooFewPoints);
        }
        Ok(aspect)
    }

    /// Zhang's closed form (or OpenCV's with a known principal point), zero distortion.
    fn closed_form(&self, cfg: &CalibrationConfig, aspect: Option<T>) -> Result<Params<T>> {
        let n = self.corners();
        // Per-view homographies (board squares to normalised pixels).
        let mut model = [Point2::origin(); P];
        for (k, m) in model.iter_mut().take(n).enumerate() {
            let b = self.board_point(k);
            *m = Point2::new(b.x, b.y);
        }
        let model = model.get(..n).ok_or(Error::LengthMismatch)?;
        let mut homs: Vec<crate::homography::Homography<T>, V> = Vec::new();
        let mut hview = [usize::MAX; V];
        for v in 0..self.views {
            if let Ok(h) = dlt(model, self.view_obs(v)) {
                if let Some(slot) = hview.get_mut(homs.len()) {
                    *slot = v;
                }
                homs.push(h).map_err(|_| Error::BufferTooSmall("views"))?;
            }
        }
        if homs.len() < 3 {
            return Err(Error::TooFewPoints);
        }
        let zhang = if cfg.flags.fix_principal_point || aspect.is_some() {
            Err(Error::Degenerate)
        } else {
            zhang::zhang(homs.iter().copied())
        };
        let [fx, fy, cx, cy] = match zhang {
            Ok(k) => k,
            Err(Error::Degenerate) => {
                let [fx, fy] = zhang::focal_with_principal_point(homs.iter().copied(), aspect)?;
                [fx, fy, T::zero(), T::zero()]
            }
            Err(e) => return Err(e),
        };
        let fx = aspect.map_or(fx, |a| a * fy);
        let mut p = Params {
            cam: [
                fx,
                fy,
                cx,
                cy,
                T::zero(),
                T::zero(),
                T::zero(),
                T::zero(),
                T::zero(),
            ],
        };
        if cfg.flags.fix_principal_point {
            p.cam[2] = T::zero();
            p.cam[3] = T::zero();
        }
        Ok(p)
    }

    /// Initial poses, then the joint refinement from `p`.
    fn refine(
        &mut self,
        cfg: &CalibrationConfig,
        aspect: Option<T>,
        p: Params<T>,
    ) -> Result<CalibrationReport<T, V>> {
        if cfg.model != LensModel::KannalaBrandt {
            return self.refine_with(cfg, aspect, p, &self.free(cfg));
        }
        // Fisheye: the four coefficients of an odd polynomial in θ over the limited range
        // of angles a board covers are nearly dependent, and from a far start LM settles in
        // one of several shallow valleys. Continuation avoids that: k1 alone first, then
        // every coefficient from there.
        let mut stage = self.free(cfg);
        for k in 5..NC {
            if let Some(f) = stage.get_mut(k) {
                *f = false;
            }
        }
        let first = self.refine_with(cfg, aspect, p, &stage)?;
        let mut q = p;
        let [fx, fy, cx, cy, c1, ..] = self.normalised(&first.camera);
        q.cam = [
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
        self.refine_with(cfg, aspect, q, &self.free(cfg))
    }

    /// A camera as the normalised parameter vector.
    fn normalised(&self, camera: &Camera<T>) -> [T; NC] {
        let (s, c0) = (self.scale(), self.centre());
        let k = &camera.intrinsics;
        let [c1, c2, c3, c4, c5] = camera.lens.coefficients();
        [
            k.fx() / s,
            k.fy() / s,
            (k.cx() - c0.x) / s,
            (k.cy() - c0.y) / s,
            c1,
            c2,
            c3,
            c4,
            c5,
        ]
    }

    fn refine_with(
        &mut self,
        cfg: &CalibrationConfig,
        aspect: Option<T>,
        p: Params<T>,
        free: &[bool; NC],
    ) -> Result<CalibrationReport<T, V>> {
        let free = *free;
        let n = self.corners();
        let mut p = p;
        let mut model = [Point2::origin(); P];
        for (k, m) in model.iter_mut().take(n).enumerate() {
            let b = self.board_point(k);
            *m = Point2::new(b.x, b.y);
        }
        let model = model.get(..n).ok_or(Error::LengthMismatch)?;
        // Initial poses through the initial camera.
        let cam0 = self.camera(cfg.model, &p.cam)?;
        let mut scratch = [Point2::origin(); P];
        let mut used = 0usize;
        for v in 0..self.views {
            let obs = *self.obs.get(v).ok_or(Error::LengthMismatch)?;
            let pixels = obs.get(..n).ok_or(Error::LengthMismatch)?;
            let pose = solve_planar(&cam0, model, pixels, &mut scratch, &PlanarConfig::default());
            let ok = match pose {
                Ok(pp) => {
                    if let Some(slot) = self.poses.get_mut(v) {
                        *slot = pp.best.pose;
                    }
                    true
                }
                Err(_) => false,
            };
            if let Some(u) = self.used.get_mut(v) {
                *u = ok;
            }
            used += ok as usize;
        }
        if used < 3 {
            return Err(Error::TooFewPoints);
        }
        let mut cam = cam0;
        let mut poses = self.poses;
        let mut cost = self.cost(&cam, &poses).ok_or(Error::Degenerate)?;
        let initial_cost = cost;
        // Stop when a step gains less than the rounding of the cost itself: in the curved, narrow
        // valleys of the lens coefficients a small decrease does not mean the minimum is near.
        let tol = T::lit(16.0) * T::EPSILON;
        let mut lambda = T::lit(1e-3);
        let mut iterations = 0u8;
        for _ in 0..cfg.max_iterations {
            self.poses = poses;
            if !self.linearise(&cam, &free, aspect) {
                break;
            }
            // Marquardt scaling of the camera columns: their norms over every view.
            let mut cam_scale = [T::zero(); NC];
            for v in 0..self.views {
                if !self.used.get(v).copied().unwrap_or(false) {
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
                let candidate = self.step(&p, &poses, lambda, &free, &cam_scale, aspect, cfg);
                let next = candidate.ok().and_then(|(np, nposes)| {
                    let c = self.camera(cfg.model, &np.cam).ok()?;
                    let nc = self.cost(&c, &nposes)?;
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
        self.report(cfg, &p, &cam, cost, initial_cost, iterations, &free, aspect)
    }

    /// One damped Gauss-Newton step of every parameter.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &self,
        p: &Params<T>,
        poses: &[Pose<T>; V],
        lambda: T,
        free: &[bool; NC],
        cam_scale: &[T; NC],
        aspect: Option<T>,
        cfg: &CalibrationConfig,
    ) -> Result<(Params<T>, [Pose<T>; V])> {
        let g = self.reduced(Some(lambda), free, cam_scale)?;
        let r = g.r();
        let dc = r
            .fixed_view::<NC, NC>(0, 0)
            .solve_upper_triangular(&r.fixed_view::<NC, 1>(0, NC))
            .ok_or(Error::Degenerate)?;
        check_finite(dc.as_slice())?;
        let mut np = *p;
        for (x, d) in np.cam.iter_mut().zip(dc.iter()) {
            *x += *d;
        }
        if let Some(a) = aspect {
            np.cam[0] = a * np.cam[1];
        }
        if cfg.flags.fix_principal_point {
            np.cam[2] = T::zero();
            np.cam[3] = T::zero();
        }
        let mut nposes = *poses;
        for v in 0..self.views {
            if !self.used.get(v).copied().unwrap_or(false) {
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

    #[allow(clippy::too_many_arguments)]
    fn report(
        &mut self,
        cfg: &CalibrationConfig,
        p: &Params<T>,
        cam: &Camera<T>,
        cost: T,
        initial_cost: T,
        iterations: u8,
        free: &[bool; NC],
        aspect: Option<T>,
    ) -> Result<CalibrationReport<T, V>> {
        let s = self.scale();
        let c0 = self.centre();
        let n = self.corners();
        let used = self.used.iter().take(self.views).filter(|u| **u).count();
        let total = T::lit((used * n) as f64);
        let rms = |c: T, count: T| (c / count).sqrt() * s;
        // Per-view errors and the poses in the caller's units.
        let mut per_view = [None; V];
        let mut poses_out = [None; V];
        for v in 0..self.views {
            if !self.used.get(v).copied().unwrap_or(false) {
                continue;
            }
            let pose = *self.poses.get(v).ok_or(Error::LengthMismatch)?;
            let mut c = T::zero();
            for (k, o) in self.view_obs(v).iter().enumerate() {
                let u = cam.project(&pose, &self.board_point(k))?;
                c += (u - o).norm_squared();
            }
            if let Some(slot) = per_view.get_mut(v) {
                *slot = Some(rms(c, T::lit(n as f64)));
            }
            if let Some(slot) = poses_out.get_mut(v) {
                *slot = Some(Pose::new(
                    pose.rotation(),
                    pose.translation() * self.square,
                )?);
            }
        }
        // Standard deviations: σ² diag((JᵀJ)⁻¹) of the camera block = σ² diag(S⁻¹), with the
        // Schur complement S = R_cᵀ R_c of the undamped reduced system.
        self.linearise(cam, free, aspect);
        let g = self.reduced(None, free, &[T::one(); NC])?;
        let rc: SMatrix<T, NC, NC> = g.r().fixed_view::<NC, NC>(0, 0).into_owned();
        let n_free = free.iter().filter(|f| **f).count();
        let dof = T::lit((2 * used * n) as f64) - T::lit((n_free + 6 * used) as f64);
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
        let [fx, fy, cx, cy, c1, c2, c3, c4, c5] = p.cam;
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
        let (w, h) = (T::lit(self.width as f64), T::lit(self.height as f64));
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
            views_used: used,
            views_added: self.views,
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
