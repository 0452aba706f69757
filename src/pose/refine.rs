//! Levenberg-Marquardt refinement of a pose on the reprojection error.

use nalgebra::{Point2, Point3, SVector, Vector3};

use super::PoseEstimate;
use crate::camera::Camera;
use crate::linalg::{StreamingQr, lm, rotation_step};
use crate::scalar::{Real, check_finite};
use crate::transform::Pose;
use crate::{Error, Result};

/// RMS reprojection error `√(Σ |u(Xᵢ) - uᵢ|² / N)` in pixels; [`Error::BehindCamera`] if a
/// point does not project.
pub fn reprojection_rms<T: Real>(
    camera: &Camera<T>,
    pose: &Pose<T>,
    world: &[Point3<T>],
    pixels: &[Point2<T>],
) -> Result<T> {
    if world.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    if world.is_empty() {
        return Err(Error::TooFewPoints);
    }
    rms_with(camera, pose, pixels, |i| world.get(i).copied())
}

/// Minimises `Σ |u(R Xᵢ + t) - uᵢ|²` (pixels, through the full camera model with distortion)
/// over the 6 pose parameters by at most `max_iterations` Levenberg-Marquardt steps
/// ([`lm::minimise`]), with the rotation updated on the manifold, `R ← exp([δω]ₓ) R`, so there
/// is no singular parameterisation. Each residual contributes the rows
/// `∂u/∂(δω, δt) = J_π [-[R X]ₓ | I]`.
///
/// When the squared error at `pose` overflows the float type (residuals beyond `√MAX`, e.g.
/// ~1.8e19 px in f32) LM cannot run; `pose` is returned with its error.
///
/// Errors: [`Error::LengthMismatch`]; [`Error::TooFewPoints`] below 3 points (6 unknowns);
/// [`Error::NonFinite`] for non-finite input or a residual that overflows;
/// [`Error::BehindCamera`] when the starting pose puts a point behind the camera.
#[doc(alias = "solvePnPRefineLM")]
pub fn refine_pose<T: Real>(
    camera: &Camera<T>,
    pose: &Pose<T>,
    world: &[Point3<T>],
    pixels: &[Point2<T>],
    max_iterations: u8,
) -> Result<PoseEstimate<T>> {
    if world.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    refine_pose_with(camera, pose, pixels, max_iterations, |i| {
        world.get(i).copied()
    })
}

/// [`refine_pose`] on the points with `mask[i]` only (e.g. RANSAC inliers), without copying.
///
/// Errors: as [`refine_pose`], counting only the selected points.
pub fn refine_pose_masked<T: Real>(
    camera: &Camera<T>,
    pose: &Pose<T>,
    world: &[Point3<T>],
    pixels: &[Point2<T>],
    mask: &[bool],
    max_iterations: u8,
) -> Result<PoseEstimate<T>> {
    if world.len() != pixels.len() || mask.len() != pixels.len() {
        return Err(Error::LengthMismatch);
    }
    refine_pose_with(camera, pose, pixels, max_iterations, |i| {
        mask.get(i)
            .copied()
            .unwrap_or(false)
            .then(|| world.get(i).copied())
            .flatten()
    })
}

/// [`refine_pose`] with the world points given by index: `world(i)` for `i < pixels.len()`,
/// `None` to leave point `i` out. Callers lift, transform or select points on the fly without
/// storing them.
pub(crate) fn refine_pose_with<T, W>(
    camera: &Camera<T>,
    pose: &Pose<T>,
    pixels: &[Point2<T>],
    max_iterations: u8,
    world: W,
) -> Result<PoseEstimate<T>>
where
    T: Real,
    W: Fn(usize) -> Option<Point3<T>>,
{
    let problem = Reprojection {
        camera,
        world,
        pixels,
    };
    let mut used = 0usize;
    for (x, u) in problem.pairs() {
        check_finite(&[x.x, x.y, x.z, u.x, u.y])?;
        used += 1;
    }
    if used < 3 {
        return Err(Error::TooFewPoints);
    }
    let n = T::lit(used as f64);
    let Some(m) = lm::minimise(&problem, *pose, max_iterations)? else {
        // The cost is undefined at the start: a point behind the camera (that error), or a sum
        // of squares beyond the float range, where LM cannot run in this precision: the start
        // pose is returned with its (overflow-safe) error.
        let rms_px = rms_with(camera, pose, pixels, &problem.world)?;
        return Ok(PoseEstimate {
            pose: *pose,
            rms_px,
        });
    };
    let rms_px = (m.final_cost / n).sqrt();
    let rms_px = if rms_px.finite() {
        rms_px
    } else {
        // The sum of squares overflowed: the overflow-safe RMS of the pose reached.
        rms_with(camera, &m.params, pixels, &problem.world)?
    };
    Ok(PoseEstimate {
        pose: m.params,
        rms_px,
    })
}

/// RMS reprojection error with the world points given by index, as [`refine_pose_with`].
///
/// Finite whenever every residual is: a residual of more than `√f32::MAX ≈ 1.8e19` px (a far-off
/// pose, or extreme intrinsics) would overflow the sum of squares, so that case is summed
/// again with the residuals scaled by the largest, `rms = m √(Σ (rᵢ / m)² / n)`. Errors:
/// [`Error::TooFewPoints`] without a point; as [`Camera::project`]; [`Error::NonFinite`] when a
/// residual itself overflows (a projection and its pixel of opposite signs near `f32::MAX`).
pub(crate) fn rms_with<T, W>(
    camera: &Camera<T>,
    pose: &Pose<T>,
    pixels: &[Point2<T>],
    world: W,
) -> Result<T>
where
    T: Real,
    W: Fn(usize) -> Option<Point3<T>>,
{
    let residuals = || {
        pixels
            .iter()
            .enumerate()
            .filter_map(|(i, u)| world(i).map(|x| camera.project(pose, &x).map(|p| p - u)))
    };
    let (mut sum, mut used) = (T::zero(), 0usize);
    for r in residuals() {
        sum += r?.norm_squared();
        used += 1;
    }
    if used == 0 {
        return Err(Error::TooFewPoints);
    }
    let n = T::lit(used as f64);
    if sum.finite() {
        return Ok((sum / n).sqrt());
    }
    let mut largest = T::zero();
    for r in residuals() {
        largest = largest.max(r?.amax());
    }
    if !largest.finite() {
        return Err(Error::NonFinite);
    }
    let mut scaled = T::zero();
    for r in residuals() {
        scaled += (r? / largest).norm_squared();
    }
    Ok(largest * (scaled / n).sqrt())
}

struct Reprojection<'a, T: Real, W> {
    camera: &'a Camera<T>,
    world: W,
    pixels: &'a [Point2<T>],
}

impl<T: Real, W: Fn(usize) -> Option<Point3<T>>> Reprojection<'_, T, W> {
    /// `(Xᵢ, uᵢ)` pairs (every index has a point: checked before the problem is built).
    fn pairs(&self) -> impl Iterator<Item = (Point3<T>, &Point2<T>)> + '_ {
        self.pixels
            .iter()
            .enumerate()
            .filter_map(|(i, u)| (self.world)(i).map(|x| (x, u)))
    }
}

impl<T: Real, W: Fn(usize) -> Option<Point3<T>>> lm::LeastSquares<T, 6> for Reprojection<'_, T, W> {
    type Params = Pose<T>;
    type System = StreamingQr<T, 7>;

    fn cost(&self, p: &Pose<T>) -> Option<T> {
        let mut c = T::zero();
        for (x, u) in self.pairs() {
            c += (self.camera.project(p, &x).ok()? - u).norm_squared();
        }
        c.finite().then_some(c)
    }

    fn linearise(&self, p: &Pose<T>) -> Option<StreamingQr<T, 7>> {
        let mut qr = StreamingQr::new();
        for (x, u) in self.pairs() {
            let rx = p.apply_vector(&x.coords);
            let xc = Point3::from(rx + p.translation());
            let (proj, jp) = self.camera.project_with_jacobian(&xc).ok()?;
            let r = proj - u;
            let jw = jp * (-rx.cross_matrix());
            let rows = [
                [jw.m11, jw.m12, jw.m13, jp.m11, jp.m12, jp.m13, -r.x],
                [jw.m21, jw.m22, jw.m23, jp.m21, jp.m22, jp.m23, -r.y],
            ];
            for row in &rows {
                qr.push_row(row).ok()?;
            }
        }
        Some(qr)
    }

    fn step(&self, p: &Pose<T>, d: &SVector<T, 6>) -> Option<Pose<T>> {
        let [w1, w2, w3, t1, t2, t3]: [T; 6] = (*d).into();
        let r = rotation_step(&Vector3::new(w1, w2, w3)) * p.rotation();
        let t = p.translation() + Vector3::new(t1, t2, t3);
        Pose::new(r, t).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rms_of_residuals_beyond_the_square_root_of_f32_max_is_finite() {
        // fx = 1e25: a unit of normalised error is 1e25 px, whose square overflows f32.
        let cam = Camera::pinhole(Intrinsics::new(1e25f32, 1e25, 0.0, 0.0).unwrap());
        let pose = Pose::identity();
        let world = [Point3::new(1.0f32, 0.0, 1.0), Point3::new(0.0, -2.0, 1.0)];
        let pixels = [Point2::new(0.0f32, 0.0); 2];
        let rms = rms_with(&cam, &pose, &pixels, |i| world.get(i).copied()).unwrap();
        // Residuals 1e25 and 2e25 px: RMS √((1 + 4) / 2) 1e25, to f32 rounding.
        assert!((rms / 1e25 - 2.5f32.sqrt()).abs() < 1e-5, "{rms}");
        // Residuals that overflow themselves are an error, not an infinite RMS.
        let far = [Point2::new(-f32::MAX, 0.0); 2];
        let big = Camera::pinhole(Intrinsics::new(f32::MAX, 1.0, 0.0, 0.0).unwrap());
        assert_eq!(
            rms_with(&big, &pose, &far, |i| world.get(i).copied()),
            Err(Error::NonFinite)
        );
    }
    use crate::camera::{Distortion, Intrinsics};
    use crate::rng::Pcg32;

    #[test]
    fn recovers_a_perturbed_pose_with_distortion() {
        let k = Intrinsics::new(535.9f64, 535.9, 342.3, 235.6).unwrap();
        let d = Distortion::from_opencv([-0.266, -0.0386, 1.78e-3, -2.81e-4, 0.238]).unwrap();
        let cam = Camera::new(k, d);
        let truth =
            Pose::from_rodrigues(Vector3::new(0.3, -0.2, 0.1), Vector3::new(-0.1, 0.05, 0.6))
                .unwrap();
        let mut g = Pcg32::new(5);
        let world: [Point3<f64>; 20] = core::array::from_fn(|_| {
            Point3::new(
                g.uniform(-0.1, 0.1),
                g.uniform(-0.1, 0.1),
                g.uniform(-0.05, 0.05),
            )
        });
        let pixels = world.map(|x| cam.project(&truth, &x).unwrap());
        let start = Pose::from_rodrigues(
            Vector3::new(0.35, -0.15, 0.12),
            Vector3::new(-0.08, 0.04, 0.65),
        )
        .unwrap();
        let est = refine_pose(&cam, &start, &world, &pixels, 30).unwrap();
        // Noise-free data: the minimum is the truth, to rounding.
        assert!(est.rms_px < 1e-8, "{est:?}");
        assert!((est.pose.translation() - truth.translation()).amax() < 1e-9);
        assert!((est.pose.rotation_vector() - truth.rotation_vector()).amax() < 1e-9);
        assert_eq!(
            refine_pose(&cam, &start, &world[..2], &pixels[..2], 10).err(),
            Some(Error::TooFewPoints)
        );
        assert_eq!(
            refine_pose(&cam, &start, &world, &pixels[..3], 10).err(),
            Some(Error::LengthMismatch)
        );
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        use lm::LeastSquares;
        let k = Intrinsics::new(500.0f64, 510.0, 320.0, 240.0).unwrap();
        let d = Distortion::from_opencv([-0.2, 0.05, 1e-3, -2e-3, 0.01]).unwrap();
        let cam = Camera::new(k, d);
        let pose = Pose::from_rodrigues(Vector3::new(0.2, 0.1, -0.3), Vector3::new(0.1, -0.1, 1.0))
            .unwrap();
        let world = [Point3::new(0.1, -0.05, 0.2)];
        let pixels = [Point2::new(300.0, 250.0)];
        let pr = Reprojection {
            camera: &cam,
            world: |i: usize| world.get(i).copied(),
            pixels: &pixels,
        };
        let gram = pr.linearise(&pose).unwrap().gram();
        let res = |p: &Pose<f64>| cam.project(p, &world[0]).unwrap() - pixels[0];
        let h = 1e-7;
        let mut jac = nalgebra::SMatrix::<f64, 2, 6>::zeros();
        for k in 0..6 {
            let mut d = SVector::<f64, 6>::zeros();
            d[k] = h;
            let plus = res(&pr.step(&pose, &d).unwrap());
            let minus = res(&pr.step(&pose, &(-d)).unwrap());
            jac.set_column(k, &((plus - minus) / (2.0 * h)));
        }
        let jtj = jac.transpose() * jac;
        let rel = (gram.fixed_view::<6, 6>(0, 0) - jtj).amax() / jtj.amax();
        assert!(rel < 1e-6, "relative Jacobian error {rel}");
    }
}
