//! Camera calibration from views of a planar chessboard (Zhang's method, as OpenCV's
//! `calibrateCamera` and `fisheye::calibrate`), or of any planar board of identified points
//! seen in part (ChArUco, AprilGrid: [`Calibrator::with_points`], [`Calibrator::add_points`]).
//!
//! **Partial views.** Each view holds the subset of the board's points it saw, as (point
//! index, pixel) pairs. Nothing below needs every point in every view: a view's homography
//! (step 2) and initial pose (step 3) come from its own points, and its residuals in step 4
//! are those of its points, so the normal equations are the same sums over fewer terms. A
//! view is rejected ([`ViewRejection`]) with fewer than 4 points or with its board points on
//! a line (no homography, no pose); the degrees of freedom of step 5 are
//! `2 Σᵥ nᵥ - 6 V_used - n_free`. A chessboard view is the subset of every corner in the
//! board's order, so the chessboard path computes exactly what it did.
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
//! The options are checked once ([`CalibrationConfig::check`] into [`CalibrationParams`]).
//! Step 1 is the calibrator's store of views (`views.rs`), step 2 the closed form
//! (`zhang.rs`), steps 3 to 5 the refinement (`refine.rs`).
//!
//! Memory: [`Calibrator::BYTES`] bytes, all in the struct (`V · P` observations and their
//! 16-bit point indices, the board's `P` points, `V` poses and `V` 16x16 triangular factors):
//! 66,888 bytes for `f32`, 32 views of up to 100 corners (126,960 for `f64`);
//! 26,136 bytes for `f32`, 16 views of a 9x6 board.
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
//! let report = cal.solve(&cfg.check()?)?;
//! assert!(report.rms_px < 1e-6);
//! assert!((report.camera.intrinsics.fx() - 520.0).abs() < 1e-4);
//! # Ok::<(), camgeom::Error>(())
//! ```

mod config;
mod refine;
mod report;
mod views;
mod zhang;

pub use config::{ASPECT_RATIO_RANGE, CalibrationConfig, CalibrationFlags, CalibrationParams};
pub use report::{CalibrationReport, CalibrationWarning, ViewRejection};

use nalgebra::Point2;

use crate::camera::{Camera, LensModel};
use crate::chessboard::{BoardSize, Chessboard};
use crate::scalar::{Real, check_finite};
use crate::{Error, Result};
use refine::Refinement;
use views::Views;

/// Collects board views into fixed memory and calibrates: up to `V` views of a board of at
/// most `P` inner corners.
#[derive(Debug, Clone)]
pub struct Calibrator<T: Real, const V: usize, const P: usize> {
    views: Views<T, V, P>,
    refinement: Refinement<T, V>,
}

impl<T: Real, const V: usize, const P: usize> Calibrator<T, V, P> {
    /// Bytes of a calibrator (it holds everything; no scratch).
    pub const BYTES: usize = core::mem::size_of::<Self>();

    /// A calibrator for `board` (inner corners) with squares of side `square` (any unit:
    /// the poses come out in it) seen in `width x height` images.
    ///
    /// Errors: `InvalidParameter("square")` for a zero, negative or non-finite square,
    /// `BufferTooSmall("corners")` when the board has more than `P` corners,
    /// [`Error::InvalidImage`] for a zero-sized image.
    pub fn new(board: BoardSize, square: T, width: usize, height: usize) -> Result<Self> {
        Ok(Self {
            views: Views::new(board, square, width, height)?,
            refinement: Refinement::new(),
        })
    }

    /// A calibrator for a planar board of identified points (ChArUco corners, AprilGrid tag
    /// corners...): `points[k]` is point `k` at `(x, y, 0)` in the board frame, in any unit
    /// (the poses come out in it); `scale` is a typical spacing of the points in that unit
    /// (the square side), by which they are held so that every unknown is of order one. Views
    /// are added with [`Self::add_points`], any subset of the points each.
    ///
    /// Errors: `InvalidParameter("square")` for a zero, negative or non-finite scale,
    /// `BufferTooSmall("corners")` for more than `P` points (or 65,535),
    /// [`Error::TooFewPoints`] for fewer than 4, [`Error::NonFinite`],
    /// [`Error::InvalidImage`] for a zero-sized image.
    #[doc(alias = "calibrateCameraCharuco")]
    pub fn with_points(
        points: &[Point2<T>],
        scale: T,
        width: usize,
        height: usize,
    ) -> Result<Self> {
        Ok(Self {
            views: Views::with_points(points, scale, width, height)?,
            refinement: Refinement::new(),
        })
    }

    /// Adds one view of some of the board's points: `pixels[i]` is board point `ids[i]` (an
    /// index into the calibrator's points; a chessboard's corners are numbered row-major), in
    /// an image of `width x height`. Any subset is accepted here; a view of fewer than 4
    /// points or of points on a line is rejected by [`Self::solve`] (see
    /// [`CalibrationReport::rejections`]). Returns the view's index.
    ///
    /// Errors: [`Error::InvalidImage`] when the size differs from the calibrator's,
    /// [`Error::LengthMismatch`] when `ids` and `pixels` differ in length,
    /// `InvalidParameter("ids")` for an id out of range or repeated, [`Error::NonFinite`],
    /// `BufferTooSmall("views")` when `V` views are already held.
    pub fn add_points(
        &mut self,
        width: usize,
        height: usize,
        ids: &[usize],
        pixels: &[Point2<T>],
    ) -> Result<usize> {
        self.views.add_points(width, height, ids, pixels)
    }

    /// Views added so far.
    pub fn views(&self) -> usize {
        self.views.count
    }

    /// Forgets every view (the board and image size stay).
    pub fn clear(&mut self) {
        self.views.count = 0;
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
        self.views.add(width, height, corners)
    }

    /// [`Self::add_view`] of a detected board (its corners converted to `T`).
    pub fn add_chessboard<const N: usize>(
        &mut self,
        width: usize,
        height: usize,
        board: &Chessboard<N>,
    ) -> Result<usize> {
        self.views.add_chessboard(width, height, board)
    }

    /// Calibrates from the views added (see the module documentation).
    ///
    /// Errors: [`Error::TooFewPoints`] with fewer than 3 usable views,
    /// [`Error::Degenerate`] when the views do not determine the camera (all parallel, e.g.
    /// fronto-parallel), [`Error::NoConvergence`] when the refinement ends with a
    /// non-finite or non-physical camera. (Bad options are refused by
    /// [`CalibrationConfig::check`].)
    #[doc(alias = "calibrateCamera")]
    #[doc(alias = "calibrate")]
    pub fn solve(&mut self, params: &CalibrationParams) -> Result<CalibrationReport<T, V>> {
        self.check_views()?;
        let p = zhang::closed_form(&self.views, params)?;
        let first = self.refinement.refine(&self.views, params, p);
        if params.config().model != LensModel::KannalaBrandt {
            return first;
        }
        // A fisheye lens is far from the pinhole the closed form assumes, and the lens
        // coefficients' cost has more than one valley: also start from OpenCV's fisheye
        // initialisation (`f = max(w, h) / π`, principal point at the centre) and keep the
        // lower minimum.
        let f = T::one() / T::pi();
        let ratio = params.aspect::<T>().unwrap_or(T::one());
        let z = T::zero();
        let alt = [f * ratio, f, z, z, z, z, z, z, z];
        let keep_first = first.clone();
        let first_poses = self.refinement.poses;
        match (first, self.refinement.refine(&self.views, params, alt)) {
            (Ok(a), Ok(b)) if a.rms_px <= b.rms_px => {
                self.refinement.poses = first_poses;
                Ok(a)
            }
            (_, Ok(b)) => Ok(b),
            (Ok(_), Err(_)) => {
                self.refinement.poses = first_poses;
                keep_first
            }
            (Err(e), Err(_)) => Err(e),
        }
    }

    /// [`Self::solve`] from a given camera instead of the closed form (OpenCV's
    /// `CALIB_USE_INTRINSIC_GUESS`): its intrinsics and lens coefficients start the joint
    /// refinement (the model of `params` is used; the coefficients of a lens of the other
    /// model are ignored).
    ///
    /// Errors: as [`Self::solve`]; [`Error::NonFinite`] for a non-finite guess,
    /// [`Error::InvalidIntrinsics`] for one whose focal lengths, in units of
    /// `max(width, height)`, are below [`crate::camera::Intrinsics::new`]'s `√ε` (a guess of a
    /// fraction of a pixel).
    #[doc(alias = "calibrateCamera")]
    pub fn solve_with_guess(
        &mut self,
        params: &CalibrationParams,
        guess: &Camera<T>,
    ) -> Result<CalibrationReport<T, V>> {
        self.check_views()?;
        let mut cam = self.views.normalised(guess);
        if guess.lens.model() != params.config().model {
            for c in cam.iter_mut().skip(4) {
                *c = T::zero();
            }
        }
        check_finite(&cam)?;
        if let Some(a) = params.aspect::<T>() {
            cam[0] = a * cam[1];
        }
        if params.config().flags.fix_principal_point {
            cam[2] = T::zero();
            cam[3] = T::zero();
        }
        self.refinement.refine(&self.views, params, cam)
    }

    /// At least three views. Errors: [`Error::TooFewPoints`].
    fn check_views(&self) -> Result<()> {
        if self.views.count < 3 {
            return Err(Error::TooFewPoints);
        }
        Ok(())
    }
}
