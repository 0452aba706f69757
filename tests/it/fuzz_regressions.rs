//! Inputs found by the fuzz targets (`fuzz/`, README "Fuzzing") that broke a contract, each
//! reduced to the smallest case that shows it. Every test is named for what it guards.

use camgeom::Error;
use camgeom::camera::{Camera, Intrinsics};
use camgeom::nalgebra::Point2;

/// `back_project` normalised `(x, y, 1)` directly: for a ray far off the axis `|v|²`
/// overflows f32 and the "unit" ray came back as the zero vector, `Ok`. (fuzz target `pose`)
#[test]
fn back_project_far_off_axis_is_a_unit_ray() {
    let cam = Camera::pinhole(Intrinsics::new(1.0f32, 1.0, 0.0, 0.0).unwrap());
    for p in [
        Point2::new(1e30f32, 1e30),
        Point2::new(-3e38, 1.0),
        Point2::new(1.0, 3e38),
    ] {
        let ray = cam.back_project(&p).unwrap();
        let r = ray.into_inner();
        assert!(r.iter().all(|v| v.is_finite()), "{r:?}");
        assert!(
            (r.norm() - 1.0).abs() < 1e-6,
            "|ray| = {} for {p:?}",
            r.norm()
        );
        // The direction is still right: mostly along x or y, z > 0.
        assert!(r.z > 0.0 && (r.x.abs() > 0.7 || r.y.abs() > 0.7));
    }
}

/// `pixel_to_normalized` returned `Ok(inf)` when `u - cx` overflowed (finite intrinsics and
/// pixel, e.g. `cx = -3e38`, `u = 3e38`); every caller then computed with infinities.
/// (fuzz target `pose`, `Intrinsics` with `fy = f32::MAX`)
#[test]
fn pixel_to_normalized_overflow_is_an_error() {
    let k = Intrinsics::new(1.0f32, 1.0, -3e38, 0.0).unwrap();
    assert_eq!(
        k.pixel_to_normalized(&Point2::new(3e38, 0.0)),
        Err(Error::NonFinite)
    );
    let k = Intrinsics::with_skew(1e-3f32, 1e-3, 0.0, 0.0, 3e38).unwrap();
    assert_eq!(
        k.pixel_to_normalized(&Point2::new(0.0, 1e3)),
        Err(Error::NonFinite)
    );
    let cam = Camera::pinhole(Intrinsics::new(1.0f32, 1.0, -3e38, 0.0).unwrap());
    assert_eq!(
        cam.back_project(&Point2::new(3e38, 0.0)),
        Err(Error::NonFinite)
    );
}

/// `distort_pixel` / `undistort_pixel` mapped back through `K` without checking: a finite
/// pixel with an extreme principal point and skew came back as `Ok(inf)`. (fuzz target
/// `pose`: `cx = f32::MAX`, `cy = 7.747e31`, skew 29812: `u = (0, 0)` maps to normalised
/// `(-1.14e34, -5.88e30)` and back to `-inf`)
#[test]
fn distort_pixel_overflow_is_an_error() {
    let k = Intrinsics::with_skew(29820.0f32, 13.17627, f32::MAX, 7.747_039_4e31, 29812.0).unwrap();
    let cam = Camera::pinhole(k);
    for p in [Point2::new(0.0f32, 0.0), Point2::new(-3e38, 3e38)] {
        for r in [cam.distort_pixel(&p), cam.undistort_pixel(&p)] {
            match r {
                Ok(u) => assert!(u.x.is_finite() && u.y.is_finite(), "{u:?}"),
                Err(e) => assert_eq!(e, Error::NonFinite),
            }
        }
    }
}

/// `Transform::new` took `UnitQuaternion::from_rotation_matrix` of a matrix only nearly
/// orthonormal (P3P accepts its rotation up to `64 √ε` off) without normalising: the pose's
/// "rotation" then scaled points by up to 0.5 %. (fuzz target `pose`, P3P on world points
/// spanning 1e-40 .. 3742 and bearings with subnormal components)
#[test]
fn poses_from_nearly_orthonormal_matrices_are_rotations() {
    use camgeom::nalgebra::{Matrix3, Point3, Rotation3, Vector3};
    use camgeom::pose::p3p;
    use camgeom::transform::Pose;

    let ortho = |p: &Pose<f32>| {
        let r = p.rotation();
        (r.matrix().transpose() * r.matrix() - Matrix3::identity()).amax()
    };
    let nearly = Rotation3::from_matrix_unchecked(Matrix3::from_diagonal_element(1.004f32));
    let pose = Pose::new(nearly, Vector3::new(0.0, 0.0, 1.0)).unwrap();
    assert!(ortho(&pose) < 1e-5, "{}", ortho(&pose));

    let bearings = [
        Vector3::new(1e-40f32, 29930.0 / 131_072.0, 1.0),
        Vector3::new(1e-40, -1.0, 1.0),
        Vector3::new(0.0, 0.0, 1.0),
    ];
    let world = [
        Point3::new(128.0f32, 1e-40, 1e-40),
        Point3::new(0.0, -3742.375, 0.0),
        Point3::new(-5.392_603e-32, -3419.875, 0.0),
    ];
    if let Ok(poses) = p3p(&bearings, &world) {
        for p in &poses {
            assert!(
                ortho(p) < 1e-5,
                "P3P rotation off orthonormal by {}",
                ortho(p)
            );
            assert!(p.translation().iter().all(|v| v.is_finite()));
        }
    }
}

/// `solve_planar` returned `Ok` with the alternative's RMS `inf` (`cargo xtask fuzz 240`, target
/// `pose`, after about 2.2 million runs): the unrefined second IPPE solution's residuals were
/// beyond `√f32::MAX` pixels and their sum of squares overflowed. With `fx = 1e22` a pixel is
/// 1e-22 of normalised error, so the second solution of a tilted target misses by ~1e21 px.
/// Without refinement (the fuzzer's `refine_iterations` was 0) the best pose is IPPE's own and
/// its error finite; with it, LM's Jacobian (1e22 px per unit) overflows first, a typed error.
#[test]
fn solve_planar_alternative_rms_is_finite_when_its_squares_overflow() {
    use camgeom::nalgebra::{Point3, Vector3};
    use camgeom::pose::{PlanarConfig, solve_planar};
    use camgeom::transform::Pose;
    let cam = Camera::pinhole(Intrinsics::new(1e22f32, 1e22, 0.0, 0.0).unwrap());
    let truth =
        Pose::from_rodrigues(Vector3::new(0.5f32, 0.2, 0.0), Vector3::new(0.0, 0.0, 2.0)).unwrap();
    let model: Vec<Point2<f32>> = (0..9)
        .map(|k| Point2::new((k % 3) as f32 * 0.1 - 0.1, (k / 3) as f32 * 0.1 - 0.1))
        .collect();
    let pixels: Vec<Point2<f32>> = model
        .iter()
        .map(|m| cam.project(&truth, &Point3::new(m.x, m.y, 0.0)).unwrap())
        .collect();
    let mut scratch = vec![Point2::origin(); model.len()];
    for ratio in [0, 4, u8::MAX] {
        let cfg = PlanarConfig {
            refine_iterations: 0,
            alternative_ratio: ratio,
        };
        match solve_planar(&cam, &model, &pixels, &mut scratch, &cfg) {
            Ok(p) => {
                for e in [p.best, p.alternative] {
                    assert!(e.rms_px.is_finite() && e.rms_px >= 0.0, "{ratio}: {p:?}");
                }
                // The second solution really is that far off: its error is not capped.
                assert!(p.alternative.rms_px > 1e18, "{ratio}: {p:?}");
            }
            Err(e) => panic!("{ratio}: {e:?}"),
        }
    }
    let refined = PlanarConfig::default();
    if let Ok(p) = solve_planar(&cam, &model, &pixels, &mut scratch, &refined) {
        assert!(p.best.rms_px.is_finite() && p.alternative.rms_px.is_finite());
    }
}

/// `Calibrator::solve` with `fix_aspect_ratio = 8.1e-39` (finite and positive, so accepted)
/// failed with `NonFinite`, an error its documentation does not list: the closed form divides
/// by the ratio's square, zero in `f32`. (fuzz target `calibrate`, three views of a 3x8 board,
/// fisheye model) Ratios outside `ASPECT_RATIO_RANGE` are now a parameter error; the same
/// views calibrate with a ratio in range.
#[test]
fn calibrate_with_an_extreme_aspect_ratio_is_a_parameter_error() {
    use camgeom::calib::{CalibrationConfig, Calibrator};
    use camgeom::camera::Distortion;
    use camgeom::camera::LensModel;
    use camgeom::chessboard::BoardSize;
    use camgeom::nalgebra::{Point3, Vector3};
    use camgeom::transform::Pose;
    let f = 100.0 + 4.0 * 255.0f32;
    let k = Intrinsics::new(f, f * (1.0 - 1.0 / 256.0), 318.5, 238.5).unwrap();
    let d = Distortion::from_opencv([-1.0f32, -1.0, -1.0, 2.0, 40.0].map(|v| v / 512.0)).unwrap();
    let cam = Camera::new(k, d);
    let (cols, rows, sq) = (3usize, 8usize, 0.025f32);
    let board = BoardSize::new(cols, rows).unwrap();
    let size = sq * 8.0;
    let mut cal = Box::new(Calibrator::<f32, 6, 42>::new(board, sq, 640, 480).unwrap());
    for (r, o, dist) in [
        ([2i8, 2, 2], [-33i8, -1], 255u8),
        ([-1, -1, -6], [72, -43], 25),
        ([25, 90, 57], [25, 90], 57),
    ] {
        let r = Vector3::new(r[0], r[1], r[2]).map(|a| f32::from(a) / 128.0);
        let rot = Pose::from_rodrigues(r, Vector3::zeros()).unwrap();
        let centre = Vector3::new(sq * 1.0, sq * 3.5, 0.0);
        let t = Vector3::new(
            size * f32::from(o[0]) / 16.0,
            size * f32::from(o[1]) / 16.0,
            size * (1.0 + f32::from(dist) / 32.0),
        ) - rot.rotation() * centre;
        let pose = Pose::from_rodrigues(r, t).unwrap();
        let px: Vec<Point2<f32>> = (0..cols * rows)
            .map(|i| {
                let x = Point3::new(sq * (i % cols) as f32, sq * (i / cols) as f32, 0.0);
                cam.project(&pose, &x).unwrap_or(Point2::new(-1.0, -1.0))
            })
            .collect();
        cal.add_view(640, 480, &px).unwrap();
    }
    let mut cfg = CalibrationConfig {
        model: LensModel::KannalaBrandt,
        max_iterations: 15,
        ..CalibrationConfig::default()
    };
    cfg.flags.fix_k3 = true;
    cfg.flags.fix_k4 = true;
    for ratio in [
        f64::from(8.113095e-39f32),
        1e-20,
        1e20,
        0.0,
        -1.0,
        f64::INFINITY,
    ] {
        cfg.flags.fix_aspect_ratio = Some(ratio);
        assert_eq!(
            cfg.check().and_then(|p| cal.solve(&p)).map(|r| r.rms_px),
            Err(Error::InvalidParameter("flags.fix_aspect_ratio")),
            "ratio {ratio}"
        );
    }
    // In range: a result or one of the documented errors, never `NonFinite`.
    cfg.flags.fix_aspect_ratio = Some(1.0);
    match cal.solve(&cfg.check().unwrap()) {
        Ok(r) => assert!(r.rms_px.is_finite() && r.rms_px >= 0.0, "{r:?}"),
        Err(e) => assert!(
            matches!(
                e,
                Error::Degenerate | Error::NoConvergence | Error::TooFewPoints
            ),
            "{e:?}"
        ),
    }
}

/// `saddle_subpix` and `corner_subpix` on a finite corner near `±f32::MAX`: the window's
/// integer origin (`as isize`, saturated) plus the window offsets overflowed `isize`, a panic
/// with overflow checks. (fuzz target `chessboard`, the refiners on arbitrary corners) Such a
/// window lies wholly beyond the frame, reads only its replicated border (a flat patch) and
/// the corner keeps its start, as for any flat patch.
#[test]
fn subpix_refiners_on_corners_near_f32_max_keep_them() {
    use camgeom::chessboard::{SaddleParams, SubPixParams, corner_subpix, saddle_subpix};
    use camgeom::image::ImageView;
    // A 32x32 frame with a corner in the middle: not flat, so the border pixels differ.
    let px: Vec<u8> = (0..32 * 32)
        .map(|i| {
            if (i % 32 < 16) == (i / 32 < 16) {
                30
            } else {
                220
            }
        })
        .collect();
    let img = ImageView::packed(&px, 32, 32).unwrap();
    let far = [
        Point2::new(f32::MAX, f32::MAX),
        Point2::new(f32::MIN, 3e38),
        Point2::new(-3e38, f32::MIN),
        Point2::new(16.0, f32::MAX),
    ];
    let mut a = far;
    saddle_subpix(&img, &mut a, &SaddleParams::default()).unwrap();
    assert_eq!(a, far);
    let mut b = far;
    corner_subpix(&img, &mut b, &SubPixParams::default()).unwrap();
    assert_eq!(b, far);
}

/// A triangulation whose point is finite but whose camera-frame coordinates in the second
/// view overflow (`R₂ X + t₂` with `t₂ = f32::MAX`) came back `Ok` with an infinite depth
/// and the reprojection error of `x/∞ = 0`. (fuzz target `twoview`, `triangulate_midpoint`)
#[test]
fn triangulation_with_a_depth_beyond_f32_is_an_error() {
    use camgeom::nalgebra::Vector3;
    use camgeom::transform::{Camera as View, Transform, World};
    use camgeom::twoview::{triangulate_dlt, triangulate_midpoint, triangulate_optimal};
    let p1 = Transform::<World, View, f32>::identity();
    let p2 = Transform::<World, View, f32>::from_rodrigues(
        Vector3::new(0.5, 0.5, 0.0),
        Vector3::new(0.0, 0.0, f32::MAX),
    )
    .unwrap();
    let (u1, u2) = (Point2::new(0.0f32, 0.0), Point2::new(0.5, 0.0));
    assert_eq!(
        triangulate_midpoint(&p1, &p2, &u1, &u2),
        Err(Error::NonFinite)
    );
    // The other two share the depth check; whatever they answer must be finite.
    for t in [
        triangulate_dlt(&p1, &p2, &u1, &u2),
        triangulate_optimal(&p1, &p2, &u1, &u2),
    ]
    .into_iter()
    .flatten()
    {
        assert!(t.depth1.is_finite() && t.depth2.is_finite(), "{t:?}");
    }
}

/// A PnP RANSAC with a threshold whose square overflows `f32` (`1.09e24`) took every point as
/// an inlier and came back `Ok` with an infinite RMS (the sum of the inliers' squared errors
/// overflowed). The threshold is now a parameter error, and the RMS a mean of terms each
/// below the threshold's square. (fuzz target `pose`, `solve_pnp_ransac`)
#[test]
fn a_ransac_threshold_whose_square_overflows_is_a_parameter_error() {
    use camgeom::nalgebra::Point3;
    use camgeom::pose::solve_pnp_ransac;
    use camgeom::ransac::RansacConfig;
    let cam = Camera::new(
        Intrinsics::new(500.0f32, 500.0, 320.0, 240.0).unwrap(),
        Default::default(),
    );
    let world: std::vec::Vec<Point3<f32>> = (0..8)
        .map(|i| Point3::new((i % 3) as f32, (i / 3) as f32, 4.0 + (i % 2) as f32))
        .collect();
    let pixels: std::vec::Vec<Point2<f32>> = (0..8)
        .map(|i| Point2::new(3e37 * i as f32, -3e37 * i as f32))
        .collect();
    let mut scratch = [Point2::origin(); 8];
    let mut mask = [false; 8];
    let cfg = RansacConfig {
        threshold: 1.0927741e24f32,
        ..RansacConfig::default()
    };
    assert_eq!(
        cfg.check().unwrap_err(),
        Error::InvalidParameter("ransac.threshold")
    );
    // The largest threshold allowed, pixels far away: whatever comes back is finite.
    let cfg = RansacConfig {
        threshold: 1.8e19f32,
        ..RansacConfig::default()
    }
    .check()
    .unwrap();
    if let Ok((est, _)) = solve_pnp_ransac(&cam, &world, &pixels, &mut scratch, &cfg, &mut mask) {
        assert!(est.rms_px.is_finite(), "{est:?}");
    }
}

/// The fixed-point warp's SIMD lanes past a row's end carry unclamped guesses (they are not
/// written); the cell gather formed `index + stride + 2` for them, which overflowed `usize`
/// for a negative index (a panic with overflow checks on). A 7-pixel-wide source through a
/// map that shrinks it to a few thousandths of a pixel. (fuzz target `image_pyramid_features`)
#[test]
fn warp_lanes_past_a_row_end_read_nothing() {
    use camgeom::arith::{Arithmetic, Fixed};
    use camgeom::homography::Homography;
    use camgeom::image::{ImageMut, ImageView};
    use camgeom::nalgebra::Matrix3;
    use camgeom::warp::{WarpConfig, warp_into_quad, warp_perspective_into};
    let buf = std::vec![55u8; 55 * 511 + 7];
    let view = ImageView::new(&buf, 7, 512, 55).unwrap();
    let quad = [
        (-0.0014246323, -0.0014246323),
        (-0.0014246323, -0.0014203705),
        (1.0920506e-5, 3.3651406e-38),
        (1.0920456e-5, 1.09205075e-5),
    ]
    .map(|(x, y)| Point2::new(x, y));
    let map = [
        -0.0014246162f32,
        1.83932e-40,
        0.0,
        0.0,
        -0.0014246323,
        1.5882e-40,
        0.0,
        1.0490883e-5,
        1.09206285e-5,
    ];
    fn go<A: Arithmetic>(view: &ImageView<'_, u8>, quad: &[Point2<f32>; 4], map: &[f32; 9]) {
        let cfg = WarpConfig { alpha: 55 };
        let mut frame = [0u8; 64 * 48];
        let mut dst = ImageMut::packed(&mut frame[..], 64, 48).unwrap();
        if let Ok(r) = warp_into_quad::<A>(view, &mut dst, quad, &cfg) {
            assert!(r.written <= 64 * 48);
        }
        let h = Homography::from_matrix(&Matrix3::from_row_slice(map)).unwrap();
        if let Ok(r) = warp_perspective_into::<A>(view, &mut dst, &h, &cfg) {
            assert!(r.written <= 64 * 48);
        }
    }
    go::<f32>(&view, &quad, &map);
    go::<Fixed>(&view, &quad, &map);
}
