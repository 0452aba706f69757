//! Property tests: geometric invariants of camgeom on random inputs, well-conditioned (exact
//! recovery within rounding tolerances) and ill-conditioned (the answer is `Err` or finite,
//! never NaN). Case counts are set per block so that the whole file runs in a few seconds.
//!
//! Tolerances: the exact-recovery properties run in `f64` on noise-free data, where the
//! solvers' own rounding (SVD/QR on normalised coordinates, condition numbers ≲ 1e4 for the
//! ranges drawn here) stays below ~1e-9 relative; every bound below leaves two to three orders
//! of magnitude on top of that so that it flags a wrong formula, not rounding.

use camgeom::camera::{Camera, Distortion, Intrinsics};
use camgeom::homography::{Homography, dlt, find_homography};
use camgeom::linalg::svd_jacobi;
use camgeom::nalgebra::{Matrix3, Point2, Point3, Vector3};
use camgeom::pose::{PlanarConfig, solve_planar, solve_pnp};
use camgeom::ransac::RansacConfig;
use camgeom::transform::{Camera as CameraFrame, Pose, Target, Transform, World};
use camgeom::twoview::{
    Essential, RelativePose, eight_point, triangulate_dlt, triangulate_midpoint,
};
use proptest::prelude::*;

fn vec3(r: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-r..r, -r..r, -r..r).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

/// A homography close to a real camera's plane-to-image map: identity plus bounded affine and
/// perspective parts, on 640x480 pixel coordinates.
fn homography() -> impl Strategy<Value = Matrix3<f64>> {
    (
        proptest::array::uniform4(-0.3f64..0.3),
        (-100.0f64..100.0, -100.0f64..100.0),
        (-4e-4f64..4e-4, -4e-4f64..4e-4),
    )
        .prop_map(|(a, t, p)| {
            Matrix3::new(1.0 + a[0], a[1], t.0, a[2], 1.0 + a[3], t.1, p.0, p.1, 1.0)
        })
}

fn pixel() -> impl Strategy<Value = Point2<f64>> {
    (0.0f64..640.0, 0.0f64..480.0).prop_map(|(x, y)| Point2::new(x, y))
}

fn apply(h: &Matrix3<f64>, p: &Point2<f64>) -> Point2<f64> {
    let v = h * Vector3::new(p.x, p.y, 1.0);
    Point2::new(v.x / v.z, v.y / v.z)
}

/// A camera 640x480-ish with mild distortion (a real lens: |k1| ≤ 0.3 ...).
fn camera() -> impl Strategy<Value = Camera<f64>> {
    (
        400.0f64..900.0,
        0.9f64..1.1,
        280.0f64..360.0,
        200.0f64..280.0,
        (-0.3f64..0.3, -0.1f64..0.1, -1e-3f64..1e-3, -1e-3f64..1e-3),
    )
        .prop_map(|(f, aspect, cx, cy, (k1, k2, p1, p2))| {
            let k = Intrinsics::new(f, f * aspect, cx, cy).unwrap();
            let d = Distortion::from_opencv([k1, k2, p1, p2, 0.0]).unwrap();
            Camera::new(k, d)
        })
}

/// A world-to-camera pose looking at the origin region from 2..6 units away.
fn pose() -> impl Strategy<Value = Pose<f64>> {
    (vec3(0.4), -0.5f64..0.5, -0.5f64..0.5, 2.0f64..6.0)
        .prop_map(|(r, x, y, z)| Pose::from_rodrigues(r, Vector3::new(x, y, z)).unwrap())
}

/// Points in front of a camera at `pose`, spread over its central field of view
/// (normalised coordinates within ±0.35, so distortion stays in its monotonic range).
fn points_in_view(pose: &Pose<f64>, unit: &[(f64, f64, f64)]) -> Vec<Point3<f64>> {
    let inv = pose.inverse();
    unit.iter()
        .map(|&(u, v, d)| {
            let z = 1.5 + 5.0 * d;
            inv.apply(&Point3::new(0.35 * u * z, 0.35 * v * z, z))
        })
        .collect()
}

fn unit_points(n: std::ops::Range<usize>) -> impl Strategy<Value = Vec<(f64, f64, f64)>> {
    proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0, 0.0f64..1.0), n)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// `H⁻¹(H(p)) = p` and `(H₁ then H₂)(p) = H₂(H₁(p))`.
    #[test]
    fn homography_transfer_inverse_round_trip(m in homography(), m2 in homography(), p in pixel()) {
        let h = Homography::from_matrix(&m).unwrap();
        let q = h.transfer(&p).unwrap();
        let back = h.inverse().unwrap().transfer(&q).unwrap();
        prop_assert!((back - p).norm() < 1e-8, "round trip off by {}", (back - p).norm());
        let h2 = Homography::from_matrix(&m2).unwrap();
        let composed = h.then(&h2).unwrap().transfer(&p).unwrap();
        let chained = h2.transfer(&q).unwrap();
        prop_assert!((composed - chained).norm() < 1e-8);
    }

    /// The normalised DLT recovers `H` from exact correspondences (4..40 of them): every
    /// transfer agrees with the truth to 1e-6 px over the image.
    #[test]
    fn dlt_recovers_exact_homography(m in homography(), src in proptest::collection::vec(pixel(), 4..40)) {
        let dst: Vec<_> = src.iter().map(|p| apply(&m, p)).collect();
        // Nearly collinear draws are allowed to fail; they must say so.
        let Ok(h) = dlt(&src, &dst) else { return Ok(()); };
        for p in [Point2::new(0.0, 0.0), Point2::new(640.0, 480.0), Point2::new(320.0, 10.0)] {
            let e = (h.transfer(&p).unwrap() - apply(&m, &p)).norm();
            // Exact unless the draw is ill-conditioned (all points in a small region): then
            // extrapolating to the image corners amplifies rounding; 1e-4 px still shows any
            // formula error (those are pixels, not micro-pixels).
            prop_assert!(e < 1e-4, "transfer error {e}");
        }
        for (s, d) in src.iter().zip(&dst) {
            prop_assert!((h.transfer(s).unwrap() - d).norm() < 1e-6);
        }
    }

    /// Rigid transforms: `(a then b)(p) = b(a(p))`, `a⁻¹(a(p)) = p`, rotations stay orthonormal.
    #[test]
    fn transform_composition_and_inverse(r1 in vec3(3.0), t1 in vec3(10.0), r2 in vec3(3.0), t2 in vec3(10.0), p in vec3(10.0)) {
        let a = Transform::<World, CameraFrame, f64>::from_rodrigues(r1, t1).unwrap();
        let b = Transform::<CameraFrame, Target, f64>::from_rodrigues(r2, t2).unwrap();
        let p = Point3::from(p);
        let ab = a.then(&b);
        prop_assert!((ab.apply(&p) - b.apply(&a.apply(&p))).norm() < 1e-12 * (1.0 + p.coords.norm()) * 100.0);
        prop_assert!((a.inverse().apply(&a.apply(&p)) - p).norm() < 1e-11 * (10.0 + p.coords.norm()));
        let r = ab.rotation();
        prop_assert!((r.matrix().transpose() * r.matrix() - Matrix3::identity()).norm() < 1e-12);
    }

    /// `back_project(project(X))` is the ray through `X`, and `undistort(distort(u)) = u`.
    #[test]
    fn camera_round_trips(cam in camera(), pose in pose(), unit in unit_points(1..8)) {
        for x in points_in_view(&pose, &unit) {
            let u = cam.project(&pose, &x).unwrap();
            let ray = cam.back_project(&u).unwrap();
            let xc = pose.apply(&x).coords.normalize();
            // The Newton undistortion stops at ~1e-12 normalised units here (8 ε max(1, |x|)).
            prop_assert!((ray.into_inner() - xc).norm() < 1e-9, "ray off by {}", (ray.into_inner() - xc).norm());
            let ideal = cam.undistort_pixel(&u).unwrap();
            let again = cam.distort_pixel(&ideal).unwrap();
            prop_assert!((again - u).norm() < 1e-7);
        }
    }

    /// Project then solve: `solve_pnp` (6..20 general points) and `solve_planar` (a planar
    /// target) recover the pose from exact pixels.
    #[test]
    fn pose_round_trip(cam in camera(), pose in pose(), unit in unit_points(6..20)) {
        let world = points_in_view(&pose, &unit);
        let pixels: Vec<_> = world.iter().map(|x| cam.project(&pose, x).unwrap()).collect();
        let mut scratch = vec![Point2::origin(); world.len()];
        {
            let est = solve_pnp(&cam, &world, &pixels, &mut scratch).unwrap();
            prop_assert!(est.rms_px < 1e-6, "rms {}", est.rms_px);
            prop_assert!((est.pose.translation() - pose.translation()).norm() < 1e-6);
            let dr = (est.pose.rotation().matrix() - pose.rotation().matrix()).norm();
            prop_assert!(dr < 1e-6, "rotation off by {dr} (rms {})", est.rms_px);
        }
        // A planar target (z = 0 in the world) with the same pose.
        let model: Vec<Point2<f64>> = unit.iter().map(|&(u, v, _)| Point2::new(0.5 * u, 0.5 * v)).collect();
        let pix: Vec<_> = model.iter().map(|m| cam.project(&pose, &Point3::new(m.x, m.y, 0.0)).unwrap()).collect();
        {
            let pp = solve_planar(&cam, &model, &pix, &mut scratch, &PlanarConfig::default()).unwrap();
            prop_assert!(pp.best.rms_px < 1e-6, "planar rms {}", pp.best.rms_px);
            prop_assert!((pp.best.pose.translation() - pose.translation()).norm() < 1e-6);
        }
    }
}

/// A two-view scene: relative pose with a real baseline and points in front of both views,
/// in normalised coordinates.
fn two_view() -> impl Strategy<Value = (RelativePose<f64>, Vec<Point3<f64>>)> {
    (vec3(0.3), 0.3f64..1.0, vec3(0.3), unit_points(8..30)).prop_map(|(r, b, t, unit)| {
        let dir = Vector3::new(b, t.y, t.z);
        let pose = RelativePose::from_rodrigues(r, dir).unwrap();
        let pts = unit
            .iter()
            .map(|&(u, v, d)| {
                let z = 3.0 + 5.0 * d;
                Point3::new(0.35 * u * z, 0.35 * v * z, z)
            })
            .collect();
        (pose, pts)
    })
}

fn proj(p: &Point3<f64>) -> Point2<f64> {
    Point2::new(p.x / p.z, p.y / p.z)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// 8-point `F` on exact correspondences: `x₂ᵀ F x₁ = 0` on every pair (F normalised to
    /// `|F|_F = 1`, pixel coordinates of a 600 px camera) and rank 2 (`σ₃ / σ₁ ≈ 0`).
    #[test]
    fn fundamental_epipolar_constraint_and_rank((pose, world) in two_view()) {
        let k = Intrinsics::new(600.0, 600.0, 320.0, 240.0).unwrap();
        let px = |p: Point3<f64>| k.normalized_to_pixel(&proj(&p));
        let x1: Vec<_> = world.iter().map(|&p| px(p)).collect();
        let x2: Vec<_> = world.iter().map(|p| px(pose.apply(p))).collect();
        let f = eight_point(&x1, &x2).unwrap();
        let m = f.matrix() / f.matrix().norm();
        for (a, b) in x1.iter().zip(&x2) {
            let r = Vector3::new(b.x, b.y, 1.0).dot(&(m * Vector3::new(a.x, a.y, 1.0)));
            // |x| ~ 600: the algebraic residual of a 1e-6 px error is ~1e-6 · 600 · |F|.
            prop_assert!(r.abs() < 1e-6, "x2ᵀ F x1 = {r}");
        }
        let s = svd_jacobi(&m).unwrap().singular_values;
        let (smax, smin) = (s.max(), s.min());
        prop_assert!(smin <= 1e-10 * smax, "rank 2: singular values {s:?}");
    }

    /// `E` of a relative pose has singular values `(s, s, 0)` and satisfies the epipolar
    /// constraint on normalised coordinates; two-view triangulation reprojects exactly and
    /// recovers the points.
    #[test]
    fn essential_singular_values_and_triangulation((pose, world) in two_view()) {
        let e = Essential::from_pose(&pose).unwrap();
        let s = svd_jacobi(e.matrix()).unwrap().singular_values;
        let mut v: Vec<f64> = s.iter().copied().collect();
        v.sort_by(|a, b| b.total_cmp(a));
        prop_assert!((v[0] - v[1]).abs() < 1e-12 && v[2].abs() < 1e-12, "singular values {v:?}");
        let id = RelativePose::identity();
        for x in &world {
            let (a, b) = (proj(x), proj(&pose.apply(x)));
            let r = Vector3::new(b.x, b.y, 1.0).dot(&(e.matrix() * Vector3::new(a.x, a.y, 1.0)));
            prop_assert!(r.abs() < 1e-12);
            let t = triangulate_dlt(&id, &pose, &a, &b).unwrap();
            prop_assert!(t.max_error() < 1e-9, "reprojection {}", t.max_error());
            prop_assert!((t.point - x).norm() < 1e-7 * x.coords.norm());
            let m = triangulate_midpoint(&id, &pose, &a, &b).unwrap();
            prop_assert!((m.point - x).norm() < 1e-7 * x.coords.norm());
        }
    }
}

/// Ill-conditioned `f32` point sets: tiny or huge scales, all points nearly on a line,
/// duplicated points.
fn bad_points() -> impl Strategy<Value = (Vec<Point2<f32>>, Vec<Point2<f32>>)> {
    (
        proptest::collection::vec((-1.0f32..1.0, -1.0f32..1.0), 4..24),
        prop_oneof![Just(1e-30f32), Just(1e-6), Just(1.0), Just(1e6), Just(1e30)],
        prop_oneof![Just(0u8), Just(1), Just(2)],
        -1e-6f32..1e-6,
    )
        .prop_map(|(raw, scale, kind, eps)| {
            let src: Vec<Point2<f32>> = raw
                .iter()
                .enumerate()
                .map(|(i, &(x, y))| match kind {
                    // Nearly collinear: y = 2x + tiny.
                    0 => Point2::new(x * scale, (2.0 * x + eps * y) * scale),
                    // Two distinct points repeated.
                    1 => Point2::new(if i % 2 == 0 { 0.0 } else { scale }, scale * eps),
                    // General, at an extreme scale.
                    _ => Point2::new(x * scale, y * scale),
                })
                .collect();
            let dst = src
                .iter()
                .map(|p| Point2::new(p.y * 0.5 + p.x, p.x - p.y))
                .collect();
            (src, dst)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Degenerate or extreme-scale inputs give `Err` or a finite answer, never NaN/inf.
    #[test]
    fn ill_conditioned_inputs_give_err_or_finite((src, dst) in bad_points()) {
        if let Ok(h) = dlt(&src, &dst) {
            prop_assert!(h.matrix().iter().all(|v| v.is_finite()));
        }
        let mut mask = vec![false; src.len()];
        let cfg = RansacConfig { max_iterations: 50, ..RansacConfig::default() }.check().unwrap();
        if let Ok((h, _)) = find_homography(&src, &dst, &cfg, &mut mask) {
            prop_assert!(h.matrix().iter().all(|v| v.is_finite()));
        }
        if let (true, Ok(f)) = (src.len() >= 8, eight_point(&src, &dst)) {
            prop_assert!(f.matrix().iter().all(|v| v.is_finite()));
        }
        // The same points as a planar target seen by a camera.
        let cam = Camera::pinhole(Intrinsics::new(500.0f32, 500.0, 320.0, 240.0).unwrap());
        let mut scratch = vec![Point2::origin(); src.len()];
        if let Ok(pp) = solve_planar(&cam, &src, &dst, &mut scratch, &PlanarConfig::default()) {
            prop_assert!(pp.best.pose.translation().iter().all(|v| v.is_finite()));
            prop_assert!(pp.best.rms_px.is_finite());
        }
        let world: Vec<_> = src.iter().map(|p| Point3::new(p.x, p.y, p.x * p.y)).collect();
        if let Ok(est) = solve_pnp(&cam, &world, &dst, &mut scratch) {
            prop_assert!(est.pose.translation().iter().all(|v| v.is_finite()));
            prop_assert!(est.rms_px.is_finite());
        }
        let id = Transform::<World, CameraFrame, f32>::identity();
        let p2 = Transform::<World, CameraFrame, f32>::from_rodrigues(Vector3::zeros(), Vector3::new(src[0].x, 0.0, 0.0));
        if let Ok(t) = p2.and_then(|p2| triangulate_dlt(&id, &p2, &src[1], &dst[1])) {
            prop_assert!(t.point.coords.iter().all(|v| v.is_finite()));
            prop_assert!(t.depth1 > 0.0 && t.depth2 > 0.0);
        }
    }
}
